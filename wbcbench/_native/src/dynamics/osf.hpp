// Contact-consistent operational-space parameters (TO-OSF §II and §III-B1, OSF-HQP eq. 16–17):
// the native mirror of wbcbench/dynamics/osf.py, with the same names and conventions (f is the
// contact wrench on the robot, M q̈ + h = Sᵀ Γ + J_cᵀ f). See that module for the equations.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/QR>
#include <string>
#include <vector>

#include "dynamics/state.hpp"

namespace wbcbench {

enum class OsfInverse { kCod, kSvd, kPinv };

// Y† and the null spaces of a wide (k, n) matrix Y of rank r.
struct Decomposition {
  Matrix pinv;        // (n, k)
  Matrix right_null;  // (n, n − r): TO-OSF's v₂
  Matrix left_null;   // (k, k − r)
  int rank = 0;
};

// Y = Q [T 0; 0 0] Vᵀ by pivoted Householder QR and a QR of the trapezoidal factor (cod in
// Python). The factorisations and results are members, computed in place: once sized, compute()
// allocates nothing while Y keeps its shape.
class Cod {
 public:
  void compute(const Matrix& Y, double rcond, Decomposition& out);

 private:
  Eigen::ColPivHouseholderQR<Matrix> qr_;
  Eigen::HouseholderQR<Matrix> qz_;
  Matrix Q_, Z_, trap_, q1t_, Zq_;
  Vector work_q_, work_z_;
};

// The same quantities from a full SVD.
Decomposition svd(const Matrix& Y, double rcond);

// X⁺ of a symmetric PSD X and its rank (psd_pinv in Python): ranks count the values above
// rcond · max(largest, scale). The pivoted QR that decides the rank, the Cholesky factors and the
// buffers are members: once sized, compute() allocates nothing (the SVD path does).
class PsdPinv {
 public:
  int compute(const Matrix& X, bool by_svd, double rcond, double scale, Matrix& out);

 private:
  Eigen::ColPivHouseholderQR<Matrix> qr_;
  Eigen::LLT<Matrix> llt_;
  Matrix Q1_, XQ1_, C_, S_;
  Vector work_;
};

// One priority level's parameters (m stacked task rows).
struct LevelParams {
  Matrix Jhat;   // Ĵ = J Φ Sᵀ (m, k)
  Vector bias;   // b = J q̈₀ + J̇ q̇ (m,)
  Matrix Jstar;  // J*_{i|<i} (m, k)
  Matrix Lam;    // Λ_{i|<i} (m, m)
  Matrix B;      // J*ᵀ Λ (k, m)
  Matrix E;      // B (acceleration level) or J*ᵀ (force level)
};

// Everything the OSF controllers read each tick (OsfParams in Python).
struct OsfParams {
  std::vector<LevelParams> levels;
  Matrix Phi_a, F, W, Nw, Yc, Qf, Yw, G, K;
  Vector qdd0, f0, gamma0;
  bool exact = true;  // coupling: exact (else literal)
  long tick = 0;
  double compute_time = 0.0;

  // Γ_{≤i} from Γ_{<i} and level i's reference; out may not alias prev; work is scratch of the
  // level's rows (m,): allocates nothing once out is sized
  void level_step(int i, const Vector& prev, const Eigen::Ref<const Vector>& ref, Vector& out,
                  Eigen::Ref<Vector> work) const;
};

// The levels (row blocks of the stacked task Jacobian) and contacts the parameters are for.
struct OsfModelSpec {
  std::vector<int> level_dims;
  std::vector<bool> force_level;  // per level: a force-level (operational force) reference
  OsfInverse inverse = OsfInverse::kCod;
  bool exact = true;
  double rcond = 1e-9;
  bool affine = false;  // also Γ = K ρ + γ₀ over all levels (TO-OSF's single QP)
};

// Computes OsfParams from one tick's dynamics and stacked task Jacobian / drift. The
// factorisations and intermediate products are members reused call to call: once sized, compute()
// allocates nothing until a shape changes (a contact made or broken) — one model per thread.
class OsfModel {
 public:
  explicit OsfModel(OsfModelSpec spec) : spec_(std::move(spec)) {}
  const OsfModelSpec& spec() const { return spec_; }
  // dyn must hold M⁻¹ (RobotDynamics::set_inverse(true)); J (Σm, n) and drift (Σm,) are the
  // tasks' rows in level order; out's buffers are reused as well
  void compute(const RobotDynamics& dyn, const Matrix& J, const Vector& drift, long tick,
               OsfParams& out);

 private:
  OsfModelSpec spec_;
  // contact-constrained dynamics
  Eigen::LLT<Matrix> llt_c_;
  PsdPinv psd_c_;  // redundant contacts
  Matrix Bc_, JcB_, Lc_, Xt_, Phi_, Y_;
  // Ȳ and N_w
  Cod cod_;
  Decomposition dec_;
  Eigen::LLT<Matrix> llt_v_;
  Matrix Ybar_, Mv2_, vMv_, alpha_;
  // the levels: buffers per level, whose sizes differ
  struct LevelWork {
    PsdPinv psd;
    Matrix a, aW, X, Jbar, NJ, JK;
    Vector jg;
  };
  std::vector<LevelWork> lw_;
  Matrix JPhi_, JY_, JMinv_, N_;
  Vector inertia_;
  // the wrench distribution
  Eigen::HouseholderQR<Matrix> qr_f_;
  Matrix FNw_, YcT_;
  Vector work_;
};

}  // namespace wbcbench
