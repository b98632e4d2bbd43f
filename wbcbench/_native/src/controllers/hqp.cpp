#include "controllers/hqp.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <limits>
#include <stdexcept>

#include "controllers/lqp.hpp"

namespace wbcbench {

namespace {
constexpr double kFinalWeight = 1e-6;
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

HqpTick::HqpTick(const std::string& model, const std::vector<std::string>& task_frames,
                 const std::vector<std::string>& contact_frames)
    : Tick(model, task_frames, contact_frames) {
  dyn_.set_inverse(false);  // the HQP reads M, never M⁻¹
}

int HqpTick::handles() const {
  return s_.strategy == Strategy::kWeighted ? 1 : static_cast<int>(soft_.size());
}

void HqpTick::configure(const HqpSettings& settings) {
  s_ = settings;
  n_ = nv();
  k_ = k();
  nc_ = static_cast<int>(dyn_.contact_jacobian().rows());
  const int nx = n_ + k_ + nc_;
  const int nw = static_cast<int>(s_.Cw.rows());
  if (s_.tau_max.size() != k_) throw std::invalid_argument("hqp: tau_max of wrong size");
  if (s_.Cw.cols() != nc_ || s_.lw.size() != nw || s_.uw.size() != nw)
    throw std::invalid_argument("hqp: wrench constraints of wrong size");
  if (s_.priorities.size() != s_.groups.size())
    throw std::invalid_argument("hqp: one priority per task group");
  if (static_cast<int>(s_.force_level.size()) != tasks_.size())
    throw std::invalid_argument("hqp: one force_level flag per task");
  if (s_.finals.empty() || s_.level_weights.empty() ||
      (s_.wrench_weights.size() != 6 && s_.wrench_weights.size() != nc_))
    throw std::invalid_argument(
        "hqp: finals, level_weights and 6 wrench_weights (or one per wrench row) needed");
  // hard: M q̈ + h = Sᵀ Γ + J_cᵀ f, J_c q̈ + J̇_c q̇ = 0, the wrench inequalities, |Γ| ≤ Γ_max
  // (J_c on the rows independent by construction: a point set's T J_c)
  const int nk = static_cast<int>(dyn_.constraint_jacobian().rows());
  hard_.A.setZero(n_ + nk, nx);
  hard_.A.block(6, n_, k_, k_).diagonal().setConstant(-1.0);
  hard_.b.setZero(n_ + nk);
  hard_.C.setZero(nw, nx);
  hard_.C.rightCols(nc_) = s_.Cw;
  hard_.l = s_.lw;
  hard_.u = s_.uw;
  hard_.lb.setConstant(nx, -kInf);
  hard_.ub.setConstant(nx, kInf);
  hard_.lb.segment(n_, k_) = -s_.tau_max;
  hard_.ub.segment(n_, k_) = s_.tau_max;
  soft_.clear();
  for (size_t i = 0; i < s_.groups.size(); ++i) {
    PriorityLevel lv;
    lv.name = "L" + std::to_string(s_.priorities[i]);
    lv.C.setZero(0, nx);
    lv.weight = s_.level_weights[std::min(i, s_.level_weights.size() - 1)];
    soft_.push_back(lv);
  }
  n_levels_ = static_cast<int>(soft_.size());
  for (HqpFinal kind : s_.finals) {
    PriorityLevel f;
    f.C.setZero(0, nx);
    f.weight = kFinalWeight;
    switch (kind) {
      case HqpFinal::kTorque:  // ‖Γ‖²
        f.name = "torque";
        f.A.setZero(k_, nx);
        f.A.block(0, n_, k_, k_).setIdentity();
        f.b.setZero(k_);
        break;
      case HqpFinal::kWrench:  // ‖W_c f‖²
        f.name = "wrench";
        f.A.setZero(nc_, nx);
        for (int j = 0; j < nc_; ++j) f.A(j, n_ + k_ + j) = s_.wrench_weights(j % s_.wrench_weights.size());
        f.b.setZero(nc_);
        break;
      case HqpFinal::kAccelerationEnergy:  // ‖Lᵀ q̈‖² = q̈ᵀ M q̈, filled every tick
      case HqpFinal::kZeroTorqueEnergy:    // ‖Lᵀ (q̈ − q̈₀)‖²
        f.name = kind == HqpFinal::kAccelerationEnergy ? "acceleration_energy"
                                                       : "zero_torque_energy";
        f.A.setZero(n_, nx);
        f.b.setZero(n_);
        break;
    }
    soft_.push_back(f);
  }
  K_.setZero(n_ + nc_, n_ + nc_);
  rhs_.setZero(n_ + nc_);
  tau_.setZero(k_);
  qdd_.setZero(n_);
  wrench_.setZero(nc_);
}

void HqpTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("hqp", s_, lw, uw);
  hard_.l = lw;
  hard_.u = uw;
}

bool HqpTick::run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
                  LevelSolver& solver) {
  const auto t0 = Clock::now();
  evaluate(q, v, t);
  result_ = HierarchyResult();
  double solver_seconds = 0.0;
  const auto done = [&](bool ok) {
    times_.build = seconds_since(t0) - times_.dynamics - solver_seconds;
    return ok;
  };
  if (!dynamics_finite(dyn_, tasks_)) return done(false);
  const Matrix& M = dyn_.M();
  const Vector& h = dyn_.h();
  const Matrix& Jc = dyn_.contact_jacobian();
  const Vector& dJc = dyn_.contact_drift();
  hard_.A.topLeftCorner(n_, n_) = M;
  hard_.A.block(0, n_ + k_, n_, nc_) = -Jc.transpose();
  hard_.b.head(n_) = -h;
  hard_.A.bottomLeftCorner(hard_.A.rows() - n_, n_) = dyn_.constraint_jacobian();
  hard_.b.tail(hard_.b.size() - n_) = -dyn_.constraint_drift();
  const Matrix& J = tasks_.J();
  for (int i = 0; i < n_levels_; ++i) {
    PriorityLevel& lv = soft_[i];
    int rows = 0;
    for (int task : s_.groups[i]) rows += tasks_.dim(task);
    lv.A.setZero(rows, n_ + k_ + nc_);
    lv.b.resize(rows);
    int r = 0;
    for (int task : s_.groups[i]) {
      const int o = tasks_.offset(task), m = tasks_.dim(task);
      if (s_.force_level[task]) {
        // torque-level joint task on top of its joints' bias compensation: S_j (Γ − h_a) = ref
        const auto sel = J.block(o, 6, m, k_);
        lv.A.block(r, n_, m, k_) = sel;
        lv.b.segment(r, m) = tasks_.acc_ref().segment(o, m) + sel * h.tail(k_);
      } else {
        lv.A.block(r, 0, m, n_) = J.middleRows(o, m);
        lv.b.segment(r, m) = tasks_.acc_ref().segment(o, m) - tasks_.drift().segment(o, m);
      }
      r += m;
    }
  }
  bool factored = false;
  Eigen::LLT<Matrix> llt;
  for (size_t j = 0; j < s_.finals.size(); ++j) {
    const HqpFinal kind = s_.finals[j];
    if (kind != HqpFinal::kAccelerationEnergy && kind != HqpFinal::kZeroTorqueEnergy) continue;
    if (!factored) {
      llt.compute(M);
      if (llt.info() != Eigen::Success) return done(false);
      factored = true;
    }
    PriorityLevel& f = soft_[n_levels_ + j];
    f.A.leftCols(n_) = llt.matrixU();
    if (kind == HqpFinal::kZeroTorqueEnergy) {
      // q̈₀: the rigid-contact motion under zero torque, [M −J_cᵀ; J_c 0] (q̈, f) = (−h, −J̇_c q̇)
      // (least squares: redundant contacts make the matrix singular yet consistent)
      K_.topLeftCorner(n_, n_) = M;
      K_.topRightCorner(n_, nc_) = -Jc.transpose();
      K_.bottomLeftCorner(nc_, n_) = Jc;
      rhs_.head(n_) = -h;
      rhs_.tail(nc_) = -dJc;
      const Vector qdd0 = K_.completeOrthogonalDecomposition().solve(rhs_).head(n_);
      f.b.noalias() = llt.matrixU() * qdd0;
    }
  }
  HierarchyOptions options;
  options.strategy = s_.strategy;
  options.prox = s_.prox;
  options.accept_tol = s_.accept_tol;
  options.handles = handles();
  result_ = hierarchy_.solve(hard_, soft_, static_cast<int>(s_.finals.size()), options, solver);
  solver_seconds = hierarchy_.solver_seconds();
  if (!result_.ok) return done(false);
  const Vector& x = result_.x;
  qdd_ = x.head(n_);
  tau_ = x.segment(n_, k_);
  wrench_ = x.tail(nc_);
  return done(true);
}

}  // namespace wbcbench
