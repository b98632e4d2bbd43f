#include "qp/eiquadprog_solver.hpp"

#include <eiquadprog/eiquadprog-fast.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace wbcbench {

namespace {

using Clock = std::chrono::steady_clock;
using eiquadprog::solvers::EiquadprogFast;
using eiquadprog::solvers::EiquadprogFast_status;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// wbcbench.qp.backends._common.REGULARISATION and the number of times positive_definite
// multiplies the shift by 100
constexpr double kRegularisation = 1e-12;
constexpr int kShiftTries = 8;

QpStatus status_of(EiquadprogFast_status status) {
  switch (status) {
    case eiquadprog::solvers::EIQUADPROG_FAST_OPTIMAL:
      return QpStatus::kSolved;
    case eiquadprog::solvers::EIQUADPROG_FAST_INFEASIBLE:
    case eiquadprog::solvers::EIQUADPROG_FAST_UNBOUNDED:
      return QpStatus::kInfeasible;
    case eiquadprog::solvers::EIQUADPROG_FAST_MAX_ITER_REACHED:
      return QpStatus::kMaxIter;
    case eiquadprog::solvers::EIQUADPROG_FAST_REDUNDANT_EQUALITIES:
      break;
  }
  return QpStatus::kFailed;
}

std::string message_of(EiquadprogFast_status status) {
  switch (status) {
    case eiquadprog::solvers::EIQUADPROG_FAST_OPTIMAL:
      return "optimal";
    case eiquadprog::solvers::EIQUADPROG_FAST_INFEASIBLE:
      return "infeasible";
    case eiquadprog::solvers::EIQUADPROG_FAST_UNBOUNDED:
      return "unbounded: no step in primal or dual space (infeasible constraints)";
    case eiquadprog::solvers::EIQUADPROG_FAST_MAX_ITER_REACHED:
      return "iteration limit";
    case eiquadprog::solvers::EIQUADPROG_FAST_REDUNDANT_EQUALITIES:
      return "redundant equalities (linearly dependent rows of A)";
  }
  return "unknown status " + std::to_string(static_cast<int>(status));
}

void finite_sides(const Vector& lo, const Vector& hi, std::vector<int>& lower,
                  std::vector<int>& upper) {
  lower.clear();
  upper.clear();
  for (Eigen::Index i = 0; i < hi.size(); ++i)
    if (std::isfinite(hi[i])) upper.push_back(static_cast<int>(i));
  for (Eigen::Index i = 0; i < lo.size(); ++i)
    if (std::isfinite(lo[i])) lower.push_back(static_cast<int>(i));
}

bool same_sides(const Vector& lo, const Vector& hi, const std::vector<int>& lower,
                const std::vector<int>& upper) {
  size_t n_lo = 0, n_up = 0;
  for (Eigen::Index i = 0; i < hi.size(); ++i) {
    if (!std::isfinite(hi[i])) continue;
    if (n_up == upper.size() || upper[n_up] != i) return false;
    ++n_up;
  }
  for (Eigen::Index i = 0; i < lo.size(); ++i) {
    if (!std::isfinite(lo[i])) continue;
    if (n_lo == lower.size() || lower[n_lo] != i) return false;
    ++n_lo;
  }
  return n_up == upper.size() && n_lo == lower.size();
}

}  // namespace

EiquadprogSolver::EiquadprogSolver(SolveMode mode, const EiquadprogOptions& options)
    : QpSolver(mode) {
  for (const auto& [name, value] : options) {
    if (name != "max_iter")
      throw std::invalid_argument("eiquadprog has no setting '" + name + "' (only max_iter)");
    if (!(value >= 0.0)) throw std::invalid_argument("eiquadprog's max_iter must be >= 0");
    max_iter_ = static_cast<int>(value);
  }
}

EiquadprogSolver::~EiquadprogSolver() { drop_native(); }

void EiquadprogSolver::drop_native() { solver_.reset(); }

void EiquadprogSolver::find_rows(const QpBuffers& qp) {
  finite_sides(qp.l, qp.u, lo_, up_);
  if (qp.has_box) {
    finite_sides(qp.lb, qp.ub, lb_, ub_);
  } else {
    lb_.clear();
    ub_.clear();
  }
}

bool EiquadprogSolver::can_update(const QpBuffers& qp) {
  return same_sides(qp.l, qp.u, lo_, up_) &&
         (!qp.has_box || same_sides(qp.lb, qp.ub, lb_, ub_));
}

// wbcbench.qp.backends._common.positive_definite
void EiquadprogSolver::load_hessian(const QpBuffers& qp) {
  H_ = qp.H;
  delta_ = 0.0;
  llt_.compute(H_);
  if (llt_.info() == Eigen::Success) return;
  const double scale = std::max(1.0, qp.H.diagonal().cwiseAbs().maxCoeff());
  double delta = kRegularisation * scale;
  for (int i = 0; i < kShiftTries; ++i, delta *= 100.0) {
    H_ = qp.H;
    H_.diagonal().array() += delta;
    delta_ = delta;
    llt_.compute(H_);
    if (llt_.info() == Eigen::Success) return;
  }
  H_ = qp.H;
  H_.diagonal().array() += delta;
  delta_ = delta;
}

void EiquadprogSolver::load(const QpBuffers& qp, unsigned changed) {
  const auto n = qp.H.rows();
  if (changed & kFieldH) load_hessian(qp);
  if (changed & kFieldG) g_ = qp.g;
  if (changed & kFieldA) CE_ = qp.A;
  if (changed & kFieldB) ce0_ = -qp.b;
  const auto n_up = static_cast<Eigen::Index>(up_.size());
  const auto n_lo = static_cast<Eigen::Index>(lo_.size());
  const auto n_ub = static_cast<Eigen::Index>(ub_.size());
  const auto n_lb = static_cast<Eigen::Index>(lb_.size());
  const auto rows = n_up + n_lo + n_ub + n_lb;
  if (CI_.rows() != rows || CI_.cols() != n) {  // a new object: every row
    CI_.setZero(rows, n);
    ci0_.resize(rows);
    changed |= kFieldC | kFieldL | kFieldU | kFieldLb | kFieldUb;
    for (Eigen::Index k = 0; k < n_ub; ++k) CI_(n_up + n_lo + k, ub_[k]) = -1.0;
    for (Eigen::Index k = 0; k < n_lb; ++k) CI_(n_up + n_lo + n_ub + k, lb_[k]) = 1.0;
  }
  if (changed & kFieldC) {
    for (Eigen::Index k = 0; k < n_up; ++k) CI_.row(k) = -qp.C.row(up_[k]);
    for (Eigen::Index k = 0; k < n_lo; ++k) CI_.row(n_up + k) = qp.C.row(lo_[k]);
  }
  if (changed & kFieldU)
    for (Eigen::Index k = 0; k < n_up; ++k) ci0_[k] = qp.u[up_[k]];
  if (changed & kFieldL)
    for (Eigen::Index k = 0; k < n_lo; ++k) ci0_[n_up + k] = -qp.l[lo_[k]];
  if (changed & kFieldUb)
    for (Eigen::Index k = 0; k < n_ub; ++k) ci0_[n_up + n_lo + k] = qp.ub[ub_[k]];
  if (changed & kFieldLb)
    for (Eigen::Index k = 0; k < n_lb; ++k) ci0_[n_up + n_lo + n_ub + k] = -qp.lb[lb_[k]];
}

void EiquadprogSolver::solve_fresh(const QpBuffers& qp, const Guess* /*guess*/, bool keep) {
  // the library takes no initial guess: warm runs as cold
  const auto t0 = Clock::now();
  drop_native();
  find_rows(qp);
  CI_.resize(0, 0);
  load(qp, kAllFields);
  solver_ = std::make_unique<EiquadprogFast>();
  if (max_iter_ >= 0) solver_->setMaxIter(max_iter_);
  solver_->reset(static_cast<size_t>(qp.H.rows()), static_cast<size_t>(CE_.rows()),
                 static_cast<size_t>(CI_.rows()));
  call(qp, seconds_since(t0));
  if (!keep) drop_native();
}

void EiquadprogSolver::solve_update(const QpBuffers& qp, unsigned changed) {
  const auto t0 = Clock::now();
  load(qp, changed);
  call(qp, seconds_since(t0));
}

void EiquadprogSolver::call(const QpBuffers& qp, double setup_seconds) {
  const auto n = qp.H.rows();
  x_.resize(n);
  const auto t0 = Clock::now();
  const EiquadprogFast_status status = solver_->solve_quadprog(H_, g_, CE_, ce0_, CI_, ci0_, x_);
  outcome_.wall = seconds_since(t0);
  outcome_.setup = setup_seconds;
  outcome_.iterations = solver_->getIteratios();
  outcome_.status = status_of(status);
  outcome_.message = message_of(status);
  if (delta_ != 0.0) {
    std::ostringstream ss;
    ss.precision(1);
    ss << std::scientific << delta_;
    outcome_.message += "; H not positive definite: solved with H + " + ss.str() +
                        "·I (eiquadprog needs a positive definite Hessian)";
  }
  if (outcome_.status != QpStatus::kSolved) return;
  solution_.x = x_;
  const auto n_eq = CE_.rows();
  const auto n_up = static_cast<Eigen::Index>(up_.size());
  const auto n_lo = static_cast<Eigen::Index>(lo_.size());
  const auto n_ub = static_cast<Eigen::Index>(ub_.size());
  solution_.y.setZero(n_eq);
  solution_.z.setZero(qp.C.rows());
  solution_.z_box.setZero(qp.has_box ? n : 0);
  const auto& active = solver_->getActiveSet();
  const auto& lambda = solver_->getLagrangeMultipliers();
  const auto q = static_cast<Eigen::Index>(solver_->getActiveSetSize());
  for (Eigen::Index k = 0; k < q; ++k) {
    const int i = active[k];
    const double u = lambda[k];
    if (i < 0) {  // equality -i - 1
      solution_.y[-i - 1] = -u;
    } else if (i < n_up) {
      solution_.z[up_[i]] += u;
    } else if (i < n_up + n_lo) {
      solution_.z[lo_[i - n_up]] -= u;
    } else if (i < n_up + n_lo + n_ub) {
      solution_.z_box[ub_[i - n_up - n_lo]] += u;
    } else {
      solution_.z_box[lb_[i - n_up - n_lo - n_ub]] -= u;
    }
  }
  solution_.has_y = solution_.has_z = true;
  solution_.has_z_box = qp.has_box;
}

}  // namespace wbcbench
