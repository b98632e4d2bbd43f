#include "controllers/hqp.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <limits>
#include <memory>
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

void HqpTick::contacts_switched(int set) {
  const auto i = static_cast<size_t>(set);
  w_ = i < work_.size() ? work_[i].get() : nullptr;
}

HqpTick::Workspace& HqpTick::work() {
  if (w_ == nullptr)
    throw std::logic_error("hqp: the tick's contact set is not configured (configure first)");
  return *w_;
}

const Vector& HqpTick::wrench() const {
  static const Vector none;
  return w_ == nullptr ? none : w_->wrench;
}

const HierarchyResult& HqpTick::result() const {
  static const HierarchyResult none;
  return solved_ ? hierarchy_.result() : none;
}

int HqpTick::handles() const {
  if (w_ == nullptr) return 0;
  return w_->s.strategy == Strategy::kWeighted ? 1 : static_cast<int>(w_->soft.size());
}

void HqpTick::configure(const HqpSettings& settings) {
  n_ = nv();
  k_ = k();
  const int nc = static_cast<int>(dyn_.contact_jacobian().rows());
  const int nx = n_ + k_ + nc;
  const int nw = static_cast<int>(settings.Cw.rows());
  if (settings.tau_max.size() != k_) throw std::invalid_argument("hqp: tau_max of wrong size");
  if (settings.Cw.cols() != nc || settings.lw.size() != nw || settings.uw.size() != nw)
    throw std::invalid_argument("hqp: wrench constraints of wrong size");
  if (settings.priorities.size() != settings.groups.size())
    throw std::invalid_argument("hqp: one priority per task group");
  if (static_cast<int>(settings.force_level.size()) != tasks_.size())
    throw std::invalid_argument("hqp: one force_level flag per task");
  if (settings.finals.empty() || settings.level_weights.empty() ||
      (settings.wrench_weights.size() != 6 && settings.wrench_weights.size() != nc))
    throw std::invalid_argument(
        "hqp: finals, level_weights and 6 wrench_weights (or one per wrench row) needed");
  const auto set = static_cast<size_t>(set_);
  if (work_.size() <= set) work_.resize(set + 1);
  if (!work_[set]) work_[set] = std::make_unique<Workspace>();
  Workspace& w = *(w_ = work_[set].get());
  w.s = settings;
  w.nc = nc;
  const HqpSettings& s = w.s;
  // hard: M q̈ + h = Sᵀ Γ + J_cᵀ f, J_c q̈ + J̇_c q̇ = 0, the wrench inequalities, |Γ| ≤ Γ_max
  // (J_c on the rows independent by construction: a point set's T J_c)
  const int nk = static_cast<int>(dyn_.constraint_jacobian().rows());
  HardConstraints& hard = w.hard;
  hard.A.setZero(n_ + nk, nx);
  hard.A.block(6, n_, k_, k_).diagonal().setConstant(-1.0);
  hard.b.setZero(n_ + nk);
  hard.C.setZero(nw, nx);
  hard.C.rightCols(nc) = s.Cw;
  hard.l = s.lw;
  hard.u = s.uw;
  hard.lb.setConstant(nx, -kInf);
  hard.ub.setConstant(nx, kInf);
  hard.lb.segment(n_, k_) = -s.tau_max;
  hard.ub.segment(n_, k_) = s.tau_max;
  w.soft.clear();
  for (size_t i = 0; i < s.groups.size(); ++i) {
    PriorityLevel lv;
    lv.name = "L" + std::to_string(s.priorities[i]);
    int rows = 0;
    for (int task : s.groups[i]) rows += tasks_.dim(task);
    lv.A.setZero(rows, nx);
    lv.b.setZero(rows);
    lv.C.setZero(0, nx);
    lv.weight = s.level_weights[std::min(i, s.level_weights.size() - 1)];
    w.soft.push_back(lv);
  }
  w.n_levels = static_cast<int>(w.soft.size());
  for (HqpFinal kind : s.finals) {
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
        f.A.setZero(nc, nx);
        for (int j = 0; j < nc; ++j)
          f.A(j, n_ + k_ + j) = s.wrench_weights(j % s.wrench_weights.size());
        f.b.setZero(nc);
        break;
      case HqpFinal::kAccelerationEnergy:  // ‖Lᵀ q̈‖² = q̈ᵀ M q̈, filled every tick
      case HqpFinal::kZeroTorqueEnergy:    // ‖Lᵀ (q̈ − q̈₀)‖²
        f.name = kind == HqpFinal::kAccelerationEnergy ? "acceleration_energy"
                                                       : "zero_torque_energy";
        f.A.setZero(n_, nx);
        f.b.setZero(n_);
        break;
    }
    w.soft.push_back(f);
  }
  w.K.setZero(n_ + nc, n_ + nc);
  w.kkt = Eigen::CompleteOrthogonalDecomposition<Matrix>(n_ + nc, n_ + nc);
  w.rhs.setZero(n_ + nc);
  w.qdd0.setZero(n_ + nc);
  w.wrench.setZero(nc);
  llt_ = Eigen::LLT<Matrix>(n_);
  tau_.setZero(k_);
  qdd_.setZero(n_);
}

void HqpTick::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                const Eigen::Ref<const Vector>& uw) {
  Workspace& w = work();
  store_wrench_bounds("hqp", w.s, lw, uw);
  w.hard.l = lw;
  w.hard.u = uw;
}

bool HqpTick::run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
                  LevelSolver& solver) {
  const auto t0 = Clock::now();
  Workspace& w = work();
  const HqpSettings& s = w.s;
  const int nc = w.nc;
  HardConstraints& hard = w.hard;
  evaluate(q, v, t);
  solved_ = false;
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
  hard.A.topLeftCorner(n_, n_) = M;
  hard.A.block(0, n_ + k_, n_, nc) = -Jc.transpose();
  hard.b.head(n_) = -h;
  hard.A.bottomLeftCorner(hard.A.rows() - n_, n_) = dyn_.constraint_jacobian();
  hard.b.tail(hard.b.size() - n_) = -dyn_.constraint_drift();
  const Matrix& J = tasks_.J();
  for (int i = 0; i < w.n_levels; ++i) {
    PriorityLevel& lv = w.soft[i];
    lv.A.setZero();
    int r = 0;
    for (int task : s.groups[i]) {
      const int o = tasks_.offset(task), m = tasks_.dim(task);
      if (s.force_level[task]) {
        // torque-level joint task on top of its joints' bias compensation: S_j (Γ − h_a) = ref
        const auto sel = J.block(o, 6, m, k_);
        lv.A.block(r, n_, m, k_) = sel;
        lv.b.segment(r, m) = tasks_.acc_ref().segment(o, m);
        lv.b.segment(r, m).noalias() += sel * h.tail(k_);
      } else {
        lv.A.block(r, 0, m, n_) = J.middleRows(o, m);
        lv.b.segment(r, m) = tasks_.acc_ref().segment(o, m) - tasks_.drift().segment(o, m);
      }
      r += m;
    }
  }
  bool factored = false;
  for (size_t j = 0; j < s.finals.size(); ++j) {
    const HqpFinal kind = s.finals[j];
    if (kind != HqpFinal::kAccelerationEnergy && kind != HqpFinal::kZeroTorqueEnergy) continue;
    if (!factored) {
      llt_.compute(M);
      if (llt_.info() != Eigen::Success) return done(false);
      factored = true;
    }
    PriorityLevel& f = w.soft[w.n_levels + j];
    f.A.leftCols(n_) = llt_.matrixU();
    if (kind == HqpFinal::kZeroTorqueEnergy) {
      // q̈₀: the rigid-contact motion under zero torque, [M −J_cᵀ; J_c 0] (q̈, f) = (−h, −J̇_c q̇)
      // (least squares: redundant contacts make the matrix singular yet consistent)
      w.K.topLeftCorner(n_, n_) = M;
      w.K.topRightCorner(n_, nc) = -Jc.transpose();
      w.K.bottomLeftCorner(nc, n_) = Jc;
      w.rhs.head(n_) = -h;
      w.rhs.tail(nc) = -dJc;
      w.kkt.compute(w.K);
      w.qdd0 = w.kkt.solve(w.rhs);
      f.b.noalias() = llt_.matrixU() * w.qdd0.head(n_);
    }
  }
  HierarchyOptions options;
  options.strategy = s.strategy;
  options.prox = s.prox;
  options.accept_tol = s.accept_tol;
  options.handles = handles();
  const HierarchyResult& result =
      hierarchy_.solve(hard, w.soft, static_cast<int>(s.finals.size()), options, solver);
  solver_seconds = hierarchy_.solver_seconds();
  solved_ = true;
  if (!result.ok) return done(false);
  const Vector& x = result.x;
  qdd_ = x.head(n_);
  tau_ = x.segment(n_, k_);
  w.wrench = x.tail(nc);
  return done(true);
}

}  // namespace wbcbench
