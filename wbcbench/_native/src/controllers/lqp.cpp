#include "controllers/lqp.hpp"

#include <Eigen/Cholesky>
#include <stdexcept>

namespace wbcbench {

bool dynamics_finite(const RobotDynamics& dyn, const TaskSet& tasks) {
  return dyn.M().allFinite() && dyn.h().allFinite() && dyn.contact_jacobian().allFinite() &&
         dyn.contact_drift().allFinite() && tasks.J().allFinite() &&
         tasks.drift().allFinite() && tasks.acc_ref().allFinite();
}

void FullLqp::configure(const LexicographicSettings& settings, int n, int nc, int nk) {
  s_ = settings;
  n_ = n;
  k_ = n - 6;
  nc_ = nc;
  nk_ = nk;
  const int nx = n + nc;
  const int nw = static_cast<int>(s_.Cw.rows());
  if (s_.tau_max.size() != k_) throw std::invalid_argument("lqp: tau_max of wrong size");
  if (s_.Cw.cols() != nc_ || s_.lw.size() != nw || s_.uw.size() != nw)
    throw std::invalid_argument("lqp: wrench constraints of wrong size");
  if (s_.priorities.size() != s_.groups.size())
    throw std::invalid_argument("lqp: one priority per task group");
  if (s_.weights.empty()) throw std::invalid_argument("lqp: weights must not be empty");
  // priority 1 (hard): the floating-base rows and the torque limits, Γ = G x + γ
  hard_.A.setZero(6, nx);
  hard_.b.setZero(6);
  hard_.C.setZero(k_, nx);
  hard_.l.setZero(k_);
  hard_.u.setZero(k_);
  hard_.lb.resize(0);
  hard_.ub.resize(0);
  G_.setZero(k_, nx);
  gamma_.setZero(k_);
  levels_.clear();
  // priority 2: stationary contacts, the wrench inequalities and the q̈ limits
  PriorityLevel contacts;
  contacts.name = prefix_ + "contacts";
  contacts.A.setZero(nk_, nx);
  contacts.b.setZero(nk_);
  contacts.C.setZero(nw + k_, nx);
  contacts.C.block(0, n_, nw, nc_) = s_.Cw;
  contacts.C.block(nw, 6, k_, k_).setIdentity();
  contacts.l.resize(nw + k_);
  contacts.u.resize(nw + k_);
  contacts.l << s_.lw, Vector::Constant(k_, -s_.qdd_limit);
  contacts.u << s_.uw, Vector::Constant(k_, s_.qdd_limit);
  contacts.hard_if_feasible = true;
  levels_.push_back(contacts);
  for (size_t p = 0; p < s_.groups.size(); ++p) {
    PriorityLevel lv;
    lv.name = prefix_ + "p" + std::to_string(s_.priorities[p]);
    lv.C.setZero(0, nx);
    levels_.push_back(lv);
  }
  for (size_t i = 0; i < levels_.size(); ++i)
    levels_[i].weight = s_.weights[std::min(i, s_.weights.size() - 1)];
  // the acceleration energy ‖Lᵀ q̈‖² + reg ‖f‖² = q̈ᵀ M q̈ + reg ‖f‖² (eq. 27), merged into the
  // last level's cost
  PriorityLevel energy;
  energy.name = prefix_ + "energy";
  energy.A.setZero(nx, nx);
  energy.A.bottomRightCorner(nc_, nc_).diagonal().setConstant(std::sqrt(s_.wrench_regularization));
  energy.b.setZero(nx);
  energy.C.setZero(0, nx);
  energy.weight = s_.final_weight;
  levels_.push_back(energy);
  tau_.setZero(k_);
  qdd_.setZero(n_);
  wrench_.setZero(nc_);
}

void FullLqp::set_wrench_bounds(const Eigen::Ref<const Vector>& lw,
                                const Eigen::Ref<const Vector>& uw) {
  store_wrench_bounds("lqp", s_, lw, uw);
  const auto nw = lw.size();
  levels_[0].l.head(nw) = lw;
  levels_[0].u.head(nw) = uw;
}

bool FullLqp::solve(const RobotDynamics& dyn, const TaskSet& tasks, LevelSolver& solver) {
  const Matrix& M = dyn.M();
  const Vector& h = dyn.h();
  const Matrix& Jc = dyn.contact_jacobian();
  result_ = HierarchyResult();
  solver_seconds_ = 0.0;
  if (!dynamics_finite(dyn, tasks)) return false;
  G_.leftCols(n_) = M.bottomRows(k_);
  G_.rightCols(nc_) = -Jc.rightCols(k_).transpose();
  gamma_ = h.tail(k_);
  hard_.A.leftCols(n_) = M.topRows(6);
  hard_.A.rightCols(nc_) = -Jc.leftCols(6).transpose();
  hard_.b = -h.head(6);
  hard_.C = G_;
  hard_.l = -s_.tau_max - gamma_;
  hard_.u = s_.tau_max - gamma_;
  PriorityLevel& contacts = levels_[0];
  contacts.A.leftCols(n_) = dyn.constraint_jacobian();
  contacts.b = -dyn.constraint_drift();
  for (size_t p = 0; p < s_.groups.size(); ++p) {
    PriorityLevel& lv = levels_[p + 1];
    int rows = 0;
    for (int task : s_.groups[p]) rows += tasks.dim(task);
    lv.A.setZero(rows, n_ + nc_);
    lv.b.resize(rows);
    int r = 0;
    for (int task : s_.groups[p]) {
      const int o = tasks.offset(task), m = tasks.dim(task);
      lv.A.block(r, 0, m, n_) = tasks.J().middleRows(o, m);
      lv.b.segment(r, m) = tasks.acc_ref().segment(o, m) - tasks.drift().segment(o, m);
      r += m;
    }
  }
  Eigen::LLT<Matrix> llt(M);
  if (llt.info() != Eigen::Success) return false;
  levels_.back().A.topLeftCorner(n_, n_) = llt.matrixU();
  HierarchyOptions options;
  options.strategy = s_.strategy;
  options.prox = s_.prox;
  options.accept_tol = s_.accept_tol;
  options.merge_finals = true;
  options.slack_free_first = true;
  options.handles = handles();
  result_ = hierarchy_.solve(hard_, levels_, 1, options, solver);
  solver_seconds_ = hierarchy_.solver_seconds();
  if (!result_.ok) return false;
  const Vector& x = result_.x;
  qdd_ = x.head(n_);
  wrench_ = x.tail(nc_);
  tau_.noalias() = G_ * x + gamma_;
  return true;
}

LqpTick::LqpTick(const std::string& model, const std::vector<std::string>& task_frames,
                 const std::vector<std::string>& contact_frames)
    : Tick(model, task_frames, contact_frames) {
  dyn_.set_inverse(false);  // the LQP reads M, never M⁻¹
}

void LqpTick::configure(const LexicographicSettings& settings) {
  lqp_.configure(settings, nv(), static_cast<int>(dyn_.contact_jacobian().rows()),
                 static_cast<int>(dyn_.constraint_jacobian().rows()));
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
