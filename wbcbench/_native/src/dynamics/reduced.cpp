// The reduced-centroidal model (RC-LQP eq. 8–17): mirrors wbcbench/dynamics/reduced.py.
// Eigen only; the Pinocchio passes it needs are RobotDynamics' (state.cpp).
#include "dynamics/reduced.hpp"

#include <algorithm>
#include <chrono>
#include <limits>
#include <stdexcept>

namespace wbcbench {

namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string out = "[";
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
  return out + "]";
}

void check_joint(int joint, int njoints, const char* what) {
  // joint 0 is the universe: no chain hangs from it or starts there
  if (joint < 1 || joint >= njoints)
    throw std::invalid_argument("reduced dynamics: " + std::string(what) + " " +
                                std::to_string(joint) + " is not a joint id in [1, " +
                                std::to_string(njoints) + ")");
}

// A no-copy view of an index list for Eigen's indexed views (given a std::vector, an indexed
// view holds a copy of it: one allocation per use)
Eigen::Map<const Eigen::ArrayXi> indices(const std::vector<int>& idx) {
  return {idx.data(), static_cast<Eigen::Index>(idx.size())};
}

// the frames of the contacts `active` of dyn
std::vector<std::string> active_frames(const RobotDynamics& dyn, const std::vector<int>& active) {
  std::vector<std::string> out;
  for (int i : active) out.push_back(dyn.contact_frames().at(i));
  return out;
}

// [v]ₓ: [v]ₓ w = v × w
Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

}  // namespace

// ReducedDynamics.__init__: the split checked, every buffer sized, the plain rows of J_r set.
ReducedDynamics::ReducedDynamics(RobotDynamics& dyn, SplitSpec split)
    : dyn_(dyn), split_(std::move(split)), n_(dyn.nv()) {
  active_ = dyn.active_contacts();
  if (split_.contact_frames != active_frames(dyn, active_))
    throw std::invalid_argument("reduced dynamics: the split is for the contact frames " +
                                joined(split_.contact_frames) + " but the dynamics has " +
                                joined(active_frames(dyn, active_)));
  // every velocity index exactly once: in the plain coordinates or in one chain
  std::vector<int> seen(n_, 0);
  auto mark = [&](int k, const std::string& where) {
    if (k < 0 || k >= n_)
      throw std::invalid_argument("reduced dynamics: " + where + " velocity index " +
                                  std::to_string(k) + " out of range [0, " +
                                  std::to_string(n_) + ")");
    ++seen[k];
  };
  for (int k : split_.plain) mark(k, "plain");
  n_uc_ = 0;
  for (size_t i = 0; i < split_.chains.size(); ++i) {
    const ChainSpec& c = split_.chains[i];
    const std::string where = "chain " + std::to_string(i);
    if (c.idx.empty() || c.root_joints.empty())
      throw std::invalid_argument("reduced dynamics: " + where +
                                  " has no velocity index or no root joint");
    for (int r : c.root_joints) check_joint(r, dyn.njoints(), "root joint");
    check_joint(c.parent_joint, dyn.njoints(), "parent joint");
    for (int k : c.idx) mark(k, where);
    uc_offset_.push_back(n_uc_);
    uc_.insert(uc_.end(), c.idx.begin(), c.idx.end());
    n_uc_ += static_cast<int>(c.idx.size());
  }
  for (int k = 0; k < n_; ++k)
    if (seen[k] != 1)
      throw std::invalid_argument(
          "reduced dynamics: velocity index " + std::to_string(k) + " is in " +
          (seen[k] ? "more than one part of the split" : "neither the plain coordinates nor a "
                                                         "chain"));

  n_p_ = static_cast<int>(split_.plain.size());
  const int n_ch = static_cast<int>(split_.chains.size());
  n_r_ = n_p_ + 6 * n_ch;
  const int nc = static_cast<int>(dyn.contact_jacobian().rows());
  for (const ChainSpec& c : split_.chains) {
    const int n_u = static_cast<int>(c.idx.size());
    ChainCentroid centroid;
    centroid.A_G.setZero(6, n_u);
    centroid.J_G.setZero(6, n_u);
    centroid.I_G.setZero();
    centroid.drift.setZero();
    centroid.com.setZero();
    centroid.R.setIdentity();
    chains_.push_back(std::move(centroid));
    A_world_.push_back(Matrix::Zero(6, n_u));
    gathered_rows_.push_back(Matrix::Zero(n_u, n_));
    gathered_cols_.push_back(Matrix::Zero(n_p_ + 6 * n_ch, n_u));
  }
  v_rel_.setZero(n_);
  llt_r_ = Eigen::LLT<Matrix>(n_r_);
  llt_uc_ = Eigen::LLT<Matrix>(n_uc_);
  // eq. (13): J_r = [S_vc; S_cc; S_kept; J_G,1 S_1; …]; the selection rows never change
  J_r_.setZero(n_r_, n_);
  for (int k = 0; k < n_p_; ++k) J_r_(k, split_.plain[k]) = 1.0;
  M_r_.setZero(n_r_, n_r_);
  Jbar_r_.setZero(n_, n_r_);
  J_cr_.setZero(nc, n_r_);
  J_G_.setZero(6 * n_ch, n_uc_);
  M_uc_.setZero(n_uc_, n_uc_);
  U_uc_.setZero(n_uc_, n_uc_);
  JMinv_.setZero(n_r_, n_);
  Lambda_inv_.setZero(n_r_, n_r_);
  dJr_v_.setZero(n_r_);
  b_r_.setZero(n_r_);
  g_r_.setZero(n_r_);
  dJG_v_.setZero(6 * n_ch);
  b_uc_.setConstant(n_uc_, std::numeric_limits<double>::quiet_NaN());
  g_uc_.setZero(n_uc_);
  coriolis_.setZero(n_);
  work_r_.setZero(n_r_);
  row_r_.setZero(n_r_);
  row_n_.setZero(n_);
}

// Chain i's centroid (ChainCentroid) from dh, the rate of its momentum about the whole
// robot's CoM at zero q̈ with only the chain moving; then its rows of J_r and J̇_r q̇.
void ReducedDynamics::chain_centroid(int i, const Vector6& dh) {
  const ChainSpec& spec = split_.chains[i];
  ChainCentroid& c = chains_[i];
  Eigen::Matrix3d Ic;  // about the chain's CoM, world axes
  dyn_.subtree_inertia(spec.root_joints, c.mass, c.com, Ic);
  c.R = dyn_.joint_rotation(spec.parent_joint);
  const Eigen::Matrix3d Rt = c.R.transpose();

  // eq. (8): h_G,u = A_G,u q̇_u; the robot's CMM restricted to the chain's columns gives the
  // chain's momentum about the whole robot's CoM C. k about c = k about C + (C − c) × l
  const Eigen::Matrix3d S = skew(dyn_.com() - c.com);
  Matrix& A = A_world_[i];
  A = dyn_.cmm()(Eigen::all, indices(spec.idx));
  A.bottomRows<3>().noalias() += S * A.topRows<3>();
  Vector6 rate = dh;
  rate.tail<3>() += S * dh.head<3>();
  // in the parent body's axes (the paper's ᵇ)
  c.A_G.topRows<3>().noalias() = Rt * A.topRows<3>();
  c.A_G.bottomRows<3>().noalias() = Rt * A.bottomRows<3>();
  rate.head<3>() = (Rt * rate.head<3>()).eval();
  rate.tail<3>() = (Rt * rate.tail<3>()).eval();
  const Eigen::Matrix3d Ic_local = Rt * Ic * c.R;
  c.I_G.setZero();
  c.I_G.topLeftCorner<3, 3>().diagonal().setConstant(c.mass);
  c.I_G.bottomRightCorner<3, 3>() = Ic_local;

  // eq. (10): J_G,u = I_G,u⁻¹ A_G,u; the drift J̇_G,u q̇ is I_G,u⁻¹ times the momentum rate
  // (see reduced.py: the rate of relative momentum at zero q̈, the base and other chains
  // frozen)
  const Eigen::LLT<Eigen::Matrix3d> Ic_llt(Ic_local);
  c.J_G.topRows<3>() = c.A_G.topRows<3>() / c.mass;
  c.J_G.bottomRows<3>() = Ic_llt.solve(c.A_G.bottomRows<3>());
  c.drift.head<3>() = rate.head<3>() / c.mass;
  c.drift.tail<3>() = Ic_llt.solve(rate.tail<3>());

  // eq. (13): the chain's rows of J_r are J_G,u S_u
  const int row = n_p_ + 6 * i;
  J_r_(Eigen::seqN(row, 6), indices(spec.idx)) = c.J_G;
  dJr_v_.segment<6>(row) = c.drift;
  J_G_.block(6 * i, uc_offset_[i], 6, c.J_G.cols()) = c.J_G;
  dJG_v_.segment<6>(6 * i) = c.drift;
}

// ReducedDynamics.compute
double ReducedDynamics::compute(bool fixed_base) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!dyn_.inverse())
    throw std::logic_error("reduced dynamics: the RobotDynamics must compute M⁻¹ "
                           "(set_inverse(true))");
  if (dyn_.active_contacts() != active_)
    throw std::logic_error("reduced dynamics: the split is for the contacts " +
                           joined(active_frames(dyn_, active_)) + " but the dynamics holds " +
                           joined(active_frames(dyn_, dyn_.active_contacts())));
  const Vector& v = dyn_.v();
  // the chains' relative motion: one pass per chain with only its velocities (the base and
  // constraint chain frozen); with one chain this is the Python's single pass
  for (int i = 0; i < n_chains(); ++i) {
    const auto idx = indices(split_.chains[i].idx);
    v_rel_.setZero();
    v_rel_(idx) = v(idx);
    chain_centroid(i, dyn_.momentum_rate(v_rel_));
  }

  // eq. (14a): M_r = (J_r M⁻¹ J_rᵀ)⁻¹, by Cholesky, made exactly symmetric. J_r is a
  // selection on the plain rows and J_G,u S_u on a chain's: both products go block by block
  // (the chain's rows of M⁻¹ and columns of J_r M⁻¹ gathered first, so that the products run
  // on contiguous blocks).
  const Matrix& Minv = dyn_.Minv();
  const auto plain = indices(split_.plain);
  JMinv_.topRows(n_p_) = Minv(plain, Eigen::all);
  for (int i = 0; i < n_chains(); ++i) {
    gathered_rows_[i] = Minv(indices(split_.chains[i].idx), Eigen::all);
    JMinv_.middleRows<6>(n_p_ + 6 * i).noalias() = chains_[i].J_G * gathered_rows_[i];
  }
  Lambda_inv_.leftCols(n_p_) = JMinv_(Eigen::all, plain);
  for (int i = 0; i < n_chains(); ++i) {
    gathered_cols_[i] = JMinv_(Eigen::all, indices(split_.chains[i].idx));
    Lambda_inv_.middleCols<6>(n_p_ + 6 * i).noalias() =
        gathered_cols_[i] * chains_[i].J_G.transpose();
  }
  llt_r_.compute(Lambda_inv_);
  if (llt_r_.info() != Eigen::Success)
    throw std::runtime_error("reduced dynamics: J_r M⁻¹ J_rᵀ is not positive definite");
  M_r_.setIdentity();
  llt_r_.solveInPlace(M_r_);
  M_r_.triangularView<Eigen::StrictlyLower>() =
      M_r_.transpose().triangularView<Eigen::StrictlyLower>();
  // eq. (14b): b_r = M_r (J_r M⁻¹ b − J̇_r q̇), with b = h − g
  coriolis_ = dyn_.h() - dyn_.g();
  work_r_.noalias() = JMinv_ * coriolis_;
  work_r_ -= dJr_v_;
  b_r_.noalias() = M_r_ * work_r_;
  // eq. (14c): g_r = M_r J_r M⁻¹ g
  work_r_.noalias() = JMinv_ * dyn_.g();
  g_r_.noalias() = M_r_ * work_r_;
  // eq. (14d): J̄_r = M⁻¹ J_rᵀ M_r
  Jbar_r_.noalias() = JMinv_.transpose() * M_r_;
  // eq. (15): J_c,rᵀ = [S_vcᵀ S_ccᵀ 0]ᵀ J_cᵀ, i.e. J_c's plain columns and zeros for the
  // chains' coordinates (J_c has no column in a chain)
  const Matrix& Jc = dyn_.contact_jacobian();
  if (J_cr_.rows() != Jc.rows()) J_cr_.setZero(Jc.rows(), n_r_);  // points set after set-up
  J_cr_.leftCols(n_p_) = Jc(Eigen::all, indices(split_.plain));

  // eq. (17): M_uc = M[uc, uc], g_uc = g[uc]; b_uc from one RNEA with only the chains'
  // velocities (the chains on their parent bodies held still)
  const auto uc = indices(uc_);
  M_uc_ = dyn_.M()(uc, uc);
  g_uc_ = dyn_.g()(uc);
  if (n_uc_ > 0) {
    llt_uc_.compute(M_uc_);
    if (llt_uc_.info() != Eigen::Success)
      throw std::runtime_error("reduced dynamics: M_uc is not positive definite");
    U_uc_.triangularView<Eigen::Upper>() = llt_uc_.matrixU();
  }
  if (fixed_base && n_uc_ > 0) {
    v_rel_.setZero();
    v_rel_(uc) = v(uc);
    b_uc_ = dyn_.nonlinear_effects(v_rel_)(uc) - g_uc_;
  } else {
    b_uc_.setConstant(std::numeric_limits<double>::quiet_NaN());
  }
  time_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return time_;
}

// ReducedModel.task
void ReducedDynamics::task(const Eigen::Ref<const Matrix>& J,
                           const Eigen::Ref<const Vector>& drift, Eigen::Ref<Matrix> Jr,
                           Eigen::Ref<Vector> drift_r) const {
  if (J.cols() != n_ || drift.size() != J.rows())
    throw std::invalid_argument("reduced task: J must be (m, " + std::to_string(n_) +
                                ") and drift (m,); got J (" + std::to_string(J.rows()) + ", " +
                                std::to_string(J.cols()) + "), drift (" +
                                std::to_string(drift.size()) + ",)");
  if (Jr.rows() != J.rows() || Jr.cols() != n_r_ || drift_r.size() != J.rows())
    throw std::invalid_argument("reduced task: the outputs must be (m, n_r) and (m,)");
  // eq. (22): J q̈ + J̇ q̇ = J J̄_r q̈_r + (J̇ q̇ − J J̄_r J̇_r q̇) when J N_r = 0
  Jr.noalias() = J * Jbar_r_;
  drift_r = drift;
  drift_r.noalias() -= Jr * dJr_v_;
}

// ReducedModel.reducible_rows
void ReducedDynamics::reducible_rows(const Eigen::Ref<const Matrix>& J, double tol,
                                     Eigen::Ref<Eigen::Matrix<bool, Eigen::Dynamic, 1>> out) const {
  if (J.cols() != n_ || out.size() != J.rows())
    throw std::invalid_argument("reducible rows: J must be (m, " + std::to_string(n_) +
                                ") and the mask (m,); got J (" + std::to_string(J.rows()) +
                                ", " + std::to_string(J.cols()) + ")");
  // row by row, so that the scratch is sized once: the residual of J against J J̄_r J_r
  for (Eigen::Index i = 0; i < J.rows(); ++i) {
    row_r_.noalias() = Jbar_r_.transpose() * J.row(i).transpose();
    row_n_ = J.row(i).transpose();
    row_n_.noalias() -= J_r_.transpose() * row_r_;
    const double scale = std::max(1.0, J.row(i).cwiseAbs().maxCoeff());
    out(i) = row_n_.cwiseAbs().maxCoeff() <= tol * scale;
  }
}

}  // namespace wbcbench
