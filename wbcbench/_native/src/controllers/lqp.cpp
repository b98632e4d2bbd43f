#include "controllers/lqp.hpp"

#include <Eigen/Cholesky>
#include <memory>
#include <stdexcept>

namespace wbcbench {

bool dynamics_finite(const RobotDynamics& dyn, const TaskSet& tasks) {
  return dyn.M().allFinite() && dyn.h().allFinite() && dyn.contact_jacobian().allFinite() &&
         dyn.contact_drift().allFinite() && tasks.J().allFinite() &&
         tasks.drift().allFinite() && tasks.acc_ref().allFinite();
}

void FullLqp::select(int set) {
  const auto i = static_cast<size_t>(set);
  w_ = i < work_.size() ? work_[i].get() : nullptr;
}

FullLqp::Workspace& FullLqp::work() {
  if (w_ == nullptr)
    throw std::logic_error("lqp: the contact set is not configured (configure first)");
  return *w_;
}

const Vector& FullLqp::wrench() const {
  static const Vector none;
  return w_ == nullptr ? none : w_->wrench;
}

const HierarchyResult& FullLqp::result() const {
  static const HierarchyResult none;
  return solved_ ? hierarchy_.result() : none;
}

void FullLqp::configure(const LexicographicSettings& settings, int n, int nc, int nk, int set) {
  const int k = n - 6;
  const int nx = n + nc;
  const int nw = static_cast<int>(settings.Cw.rows());
  if (settings.tau_max.size() != k) throw std::invalid_argument("lqp: tau_max of wrong size");
  if (settings.Cw.cols() != nc || settings.lw.size() != nw || settings.uw.size() != nw)
    throw std::invalid_argument("lqp: wrench constraints of wrong size");
  if (settings.priorities.size() != settings.groups.size())
    throw std::invalid_argument("lqp: one priority per task group");
  if (settings.weights.empty()) throw std::invalid_argument("lqp: weights must not be empty");
  n_ = n;
  k_ = k;
  const auto i = static_cast<size_t>(set);
  if (work_.size() <= i) work_.resize(i + 1);
  if (!work_[i]) work_[i] = std::make_unique<Workspace>();
  Workspace& w = *(w_ = work_[i].get());
  w.s = settings;
  w.nc = nc;
  w.nk = nk;
  const LexicographicSettings& s = w.s;
  // priority 1 (hard): the floating-base rows and the torque limits, Γ = G x + γ
  HardConstraints& hard = w.hard;
  hard.zero(6, k_, nx);
  w.G.setZero(k_, nx);
  w.gamma.setZero(k_);
  w.levels.clear();
  // priority 2: stationary contacts, the wrench inequalities and the q̈ limits
  PriorityLevel contacts;
  contacts.name = prefix_ + "contacts";
  contacts.A.setZero(nk, nx);
  contacts.b.setZero(nk);
  contacts.C.setZero(nw + k_, nx);
  contacts.C.block(0, n_, nw, nc) = s.Cw;
  contacts.C.block(nw, 6, k_, k_).setIdentity();
  contacts.l.resize(nw + k_);
  contacts.u.resize(nw + k_);
  contacts.l << s.lw, Vector::Constant(k_, -s.qdd_limit);
  contacts.u << s.uw, Vector::Constant(k_, s.qdd_limit);
  contacts.hard_if_feasible = true;
  w.levels.push_back(contacts);
  for (size_t p = 0; p < s.groups.size(); ++p) {
    PriorityLevel lv;
    lv.name = prefix_ + "p" + std::to_string(s.priorities[p]);
    lv.A.setZero(0, nx);  // (its rows are the tasks': sized by the first solve)
    lv.C.setZero(0, nx);
    w.levels.push_back(lv);
  }
  for (size_t j = 0; j < w.levels.size(); ++j)
    w.levels[j].weight = s.weights[std::min(j, s.weights.size() - 1)];
  // the acceleration energy ‖Lᵀ q̈‖² + reg ‖f‖² = q̈ᵀ M q̈ + reg ‖f‖² (eq. 27), merged into the
  // last level's cost
  PriorityLevel energy;
  energy.name = prefix_ + "energy";
  energy.A.setZero(nx, nx);
  energy.A.bottomRightCorner(nc, nc).diagonal().setConstant(std::sqrt(s.wrench_regularization));
  energy.b.setZero(nx);
  energy.C.setZero(0, nx);
  energy.weight = s.final_weight;
  w.levels.push_back(energy);
  w.wrench.setZero(nc);
  llt_ = Eigen::LLT<Matrix>(n_);
  tau_.setZero(k_);
  qdd_.setZero(n_);
}

void FullLqp::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                const Eigen::Ref<const Vector>& uw) {
  Workspace& w = work();
  store_wrench_bounds("lqp", w.s, lw, uw);
  const auto nw = lw.size();
  w.levels[0].l.head(nw) = lw;
  w.levels[0].u.head(nw) = uw;
}

bool FullLqp::solve(const RobotDynamics& dyn, const TaskSet& tasks, LevelSolver& solver) {
  Workspace& w = work();
  const LexicographicSettings& s = w.s;
  const int nc = w.nc;
  HardConstraints& hard = w.hard;
  const Matrix& M = dyn.M();
  const Vector& h = dyn.h();
  const Matrix& Jc = dyn.contact_jacobian();
  solved_ = false;
  solver_seconds_ = 0.0;
  if (!dynamics_finite(dyn, tasks)) return false;
  w.G.leftCols(n_) = M.bottomRows(k_);
  w.G.rightCols(nc) = -Jc.rightCols(k_).transpose();
  w.gamma = h.tail(k_);
  hard.A.leftCols(n_) = M.topRows(6);
  hard.A.rightCols(nc) = -Jc.leftCols(6).transpose();
  hard.b = -h.head(6);
  hard.C = w.G;
  hard.l = -s.tau_max - w.gamma;
  hard.u = s.tau_max - w.gamma;
  PriorityLevel& contacts = w.levels[0];
  contacts.A.leftCols(n_) = dyn.constraint_jacobian();
  contacts.b = -dyn.constraint_drift();
  for (size_t p = 0; p < s.groups.size(); ++p) {
    PriorityLevel& lv = w.levels[p + 1];
    int rows = 0;
    for (int task : s.groups[p]) rows += tasks.dim(task);
    if (lv.A.rows() != rows) {  // (sized by the first solve: configure has no tasks)
      lv.A.setZero(rows, n_ + nc);
      lv.b.setZero(rows);
    }
    int r = 0;
    for (int task : s.groups[p]) {
      const int o = tasks.offset(task), m = tasks.dim(task);
      lv.A.block(r, 0, m, n_) = tasks.J().middleRows(o, m);
      lv.b.segment(r, m) = tasks.acc_ref().segment(o, m) - tasks.drift().segment(o, m);
      r += m;
    }
  }
  llt_.compute(M);
  if (llt_.info() != Eigen::Success) return false;
  w.levels.back().A.topLeftCorner(n_, n_) = llt_.matrixU();
  HierarchyOptions options;
  options.strategy = s.strategy;
  options.prox = s.prox;
  options.accept_tol = s.accept_tol;
  options.merge_finals = true;
  options.slack_free_first = true;
  options.handles = handles();
  const HierarchyResult& result = hierarchy_.solve(hard, w.levels, 1, options, solver);
  solver_seconds_ = hierarchy_.solver_seconds();
  solved_ = true;
  if (!result.ok) return false;
  const Vector& x = result.x;
  qdd_ = x.head(n_);
  w.wrench = x.tail(nc);
  tau_.noalias() = w.G * x;
  tau_ += w.gamma;
  return true;
}

LqpTick::LqpTick(const std::string& model, const std::vector<std::string>& task_frames,
                 const std::vector<std::string>& contact_frames)
    : Tick(model, task_frames, contact_frames) {
  dyn_.set_inverse(false);  // the LQP reads M, never M⁻¹
}

void LqpTick::configure(const LexicographicSettings& settings) {
  lqp_.configure(settings, nv(), static_cast<int>(dyn_.contact_jacobian().rows()),
                 static_cast<int>(dyn_.constraint_jacobian().rows()), set_);
}

bool LqpTick::run(const Eigen::Ref<const Vector>& q, const Eigen::Ref<const Vector>& v, double t,
                  LevelSolver& solver) {
  const auto t0 = Clock::now();
  evaluate(q, v, t);
  const bool ok = lqp_.solve(dyn_, tasks_, solver);
  times_.build = seconds_since(t0) - times_.dynamics - lqp_.solver_seconds();
  return ok;
}

}  // namespace wbcbench
