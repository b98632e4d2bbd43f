// Reduced-dimension whole-body dynamics through the unconstrained chains' centroidal dynamics
// (RC-LQP §3.2–3.4, eq. 8–17, and the task map of eq. 22): the native mirror of
// wbcbench/dynamics/reduced.py (ReducedDynamics and ReducedModel), with the same names,
// shapes and conventions. That module derives the equations; the short version:
//
//   v_G,u = I_G,u⁻¹ A_G,u q̇_u = J_G,u q̇_u                              (eq. 8–10)
//   q̇_r = J_r q̇ = [q̇_vc; q̇_cc; q̇_kept; v_G,1; …]                       (eq. 11–13)
//   M_r = (J_r M⁻¹ J_rᵀ)⁻¹,   b_r = M_r (J_r M⁻¹ b − J̇_r q̇),   g_r = M_r J_r M⁻¹ g,
//   J̄_r = M⁻¹ J_rᵀ M_r,       J_c,r = J_c restricted to the plain coordinates  (eq. 14–15)
//   M_uc q̈_uc + b_uc + g_uc = Γ_uc   (each chain on its parent body held still)    (eq. 17)
//
// with A_G,u, I_G,u, J_G,u and J̇_G,u q̇ in the axes of the body the chain hangs from, rows
// [linear; angular] (Pinocchio's order), b = h − g the Coriolis and centrifugal forces.
//
// Use: build once from a RobotDynamics and the chain split (computed in Python by
// wbcbench.dynamics.chains.split_chains); each tick, after RobotDynamics::update(q, v), call
// compute() and read the accessors. compute() allocates nothing.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <string>
#include <vector>

#include "dynamics/state.hpp"

namespace wbcbench {

using Vector6 = Eigen::Matrix<double, 6, 1>;

// One unconstrained chain of a ChainSplit (UnconstrainedChain in chains.py).
struct ChainSpec {
  std::vector<int> idx;          // velocity indices of the chain's joints (n_u,)
  std::vector<int> root_joints;  // Pinocchio joint ids of its subtrees' roots
  int parent_joint = 1;          // Pinocchio joint id of the body it hangs from (1 = base)
};

// What the reduced model needs of a ChainSplit, handed over once.
struct SplitSpec {
  std::vector<std::string> contact_frames;  // must be the RobotDynamics' contact frames
  std::vector<int> plain;                   // ChainSplit.plain: virtual, constraint, kept
  std::vector<ChainSpec> chains;            // the chains compressed into centroids
};

// Centroidal quantities of one chain, in its parent body's axes (ChainCentroid in Python).
struct ChainCentroid {
  Matrix A_G;                         // centroidal momentum matrix (6, n_u)
  Eigen::Matrix<double, 6, 6> I_G;    // centroidal inertia blkdiag(m I₃, I_c)
  Matrix J_G;                         // centroidal inertial Jacobian I_G⁻¹ A_G (6, n_u)
  Vector6 drift;                      // J̇_G q̇ [m/s², rad/s²]
  double mass = 0.0;                  // [kg]
  Eigen::Vector3d com;                // the chain's CoM in the world [m]
  Eigen::Matrix3d R;                  // world rotation of the parent body
};

// Mirrors ReducedDynamics + ReducedModel. n_r = n_plain + 6 · n_chains; n_uc = Σ n_u.
class ReducedDynamics {
 public:
  // dyn must outlive this object and hold the split's contact frames as its active contacts
  // (RobotDynamics::select_contacts; a stance of a changing contact set); split must be a
  // partition of dyn's velocity indices with valid joint ids. Throws std::invalid_argument
  // otherwise.
  ReducedDynamics(RobotDynamics& dyn, SplitSpec split);

  // Every quantity below at dyn's last update(); fixed_base adds eq. (17)'s b_uc (one more
  // RNEA), else b_uc is NaN. Returns the time it took [s] (also time()). Throws
  // std::logic_error when dyn does not compute M⁻¹ (set_inverse(false)) or holds other
  // contacts than the split's (active_contacts()), and
  // std::runtime_error when J_r M⁻¹ J_rᵀ or M_uc is not positive definite (e.g. before the
  // first update()).
  double compute(bool fixed_base);

  // A task J q̈ + J̇ q̇ in the reduced space (eq. 22): Jr = J J̄_r (m, n_r) and
  // drift_r = drift − J J̄_r J̇_r q̇ (m,). Valid for rows with J N_r = 0 (reducible_rows).
  // J (m, nv), drift (m,); Jr and drift_r must be sized (m, n_r) and (m,).
  void task(const Eigen::Ref<const Matrix>& J, const Eigen::Ref<const Vector>& drift,
            Eigen::Ref<Matrix> Jr, Eigen::Ref<Vector> drift_r) const;
  // Rows of J (m, nv) with J N_r = 0, i.e. expressible through q̇_r (§3.4.1): row i is when
  // max |J − J J̄_r J_r| over it ≤ tol · max(1, max |J| over it). out must be sized (m,).
  void reducible_rows(const Eigen::Ref<const Matrix>& J, double tol,
                      Eigen::Ref<Eigen::Matrix<bool, Eigen::Dynamic, 1>> out) const;

  RobotDynamics& dynamics() const { return dyn_; }
  const SplitSpec& split() const { return split_; }
  // the contacts of the split: indices into dyn's contact frames
  const std::vector<int>& active_contacts() const { return active_; }
  int n_plain() const { return n_p_; }
  int n_reduced() const { return n_r_; }
  int n_chains() const { return static_cast<int>(chains_.size()); }
  double time() const { return time_; }  // [s] of the last compute()

  const Matrix& J_r() const { return J_r_; }          // (n_r, nv)
  const Vector& dJr_v() const { return dJr_v_; }      // J̇_r q̇ (n_r,), zero on plain rows
  const Matrix& M_r() const { return M_r_; }          // (n_r, n_r), exactly symmetric
  const Vector& b_r() const { return b_r_; }          // (n_r,)
  const Vector& g_r() const { return g_r_; }          // (n_r,)
  const Matrix& Jbar_r() const { return Jbar_r_; }    // M⁻¹ J_rᵀ M_r (nv, n_r)
  const Matrix& J_cr() const { return J_cr_; }        // (6c, n_r)
  const Matrix& J_G() const { return J_G_; }          // block-diagonal (6 · n_chains, n_uc)
  const Vector& dJG_v() const { return dJG_v_; }      // (6 · n_chains,)
  const Matrix& M_uc() const { return M_uc_; }        // (n_uc, n_uc)
  const Matrix& M_uc_factor() const { return U_uc_; } // upper Lᵀ of M_uc = L Lᵀ, zeros below
  const Vector& b_uc() const { return b_uc_; }        // (n_uc,) [N·m]; NaN without fixed_base
  const Vector& g_uc() const { return g_uc_; }        // (n_uc,) [N·m]
  const std::vector<int>& unconstrained() const { return uc_; }  // chain after chain (n_uc,)
  const ChainCentroid& chain(int i) const { return chains_.at(i); }

 private:
  void chain_centroid(int i, const Vector6& dh);

  RobotDynamics& dyn_;
  SplitSpec split_;
  std::vector<int> active_;
  int n_, n_p_, n_r_, n_uc_;
  std::vector<int> uc_;          // ChainSplit.unconstrained
  std::vector<int> uc_offset_;   // column of each chain in q̈_uc
  std::vector<ChainCentroid> chains_;
  std::vector<Matrix> A_world_;  // per chain: A_G about the chain's CoM, world axes (6, n_u)
  Vector v_rel_;                 // the chains' velocities, base and constraint chain frozen
  Eigen::LLT<Matrix> llt_r_, llt_uc_;
  Matrix J_r_, M_r_, Jbar_r_, J_cr_, J_G_, M_uc_, U_uc_;
  Matrix JMinv_, Lambda_inv_;  // J_r M⁻¹ (n_r, nv) and its product with J_rᵀ (n_r, n_r)
  std::vector<Matrix> gathered_rows_, gathered_cols_;  // per chain: M⁻¹[idx, :], (J_r M⁻¹)[:, idx]
  Vector dJr_v_, b_r_, g_r_, dJG_v_, b_uc_, g_uc_;
  Vector coriolis_, work_r_;   // h − g (nv,), scratch (n_r,)
  mutable Vector row_r_, row_n_;  // reducible_rows' scratch (n_r,), (nv,)
  double time_ = 0.0;
};

}  // namespace wbcbench
