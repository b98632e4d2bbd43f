#include "qp/osqp_solver.hpp"

#include <algorithm>
#include <chrono>
#include <functional>
#include <stdexcept>

namespace wbcbench {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// OSQPSettings' numeric fields by name (what osqp.OSQP.update_settings accepts, as the Python
// backend passes them), each with how to set it
using Setter = std::function<void(OSQPSettings&, double)>;
const std::map<std::string, Setter>& setters() {
  static const std::map<std::string, Setter> table = [] {
    std::map<std::string, Setter> t;
    auto integer = [](OSQPInt OSQPSettings::*field) {
      return [field](OSQPSettings& s, double v) { s.*field = static_cast<OSQPInt>(v); };
    };
    auto real = [](OSQPFloat OSQPSettings::*field) {
      return [field](OSQPSettings& s, double v) { s.*field = v; };
    };
    t["verbose"] = integer(&OSQPSettings::verbose);
    t["warm_starting"] = integer(&OSQPSettings::warm_starting);
    t["scaling"] = integer(&OSQPSettings::scaling);
    t["polishing"] = integer(&OSQPSettings::polishing);
    t["rho"] = real(&OSQPSettings::rho);
    t["sigma"] = real(&OSQPSettings::sigma);
    t["alpha"] = real(&OSQPSettings::alpha);
    t["adaptive_rho"] = integer(&OSQPSettings::adaptive_rho);
    t["adaptive_rho_interval"] = integer(&OSQPSettings::adaptive_rho_interval);
    t["adaptive_rho_fraction"] = real(&OSQPSettings::adaptive_rho_fraction);
    t["adaptive_rho_tolerance"] = real(&OSQPSettings::adaptive_rho_tolerance);
    t["max_iter"] = integer(&OSQPSettings::max_iter);
    t["eps_abs"] = real(&OSQPSettings::eps_abs);
    t["eps_rel"] = real(&OSQPSettings::eps_rel);
    t["eps_prim_inf"] = real(&OSQPSettings::eps_prim_inf);
    t["eps_dual_inf"] = real(&OSQPSettings::eps_dual_inf);
    t["scaled_termination"] = integer(&OSQPSettings::scaled_termination);
    t["check_termination"] = integer(&OSQPSettings::check_termination);
    t["check_dualgap"] = integer(&OSQPSettings::check_dualgap);
    t["time_limit"] = real(&OSQPSettings::time_limit);
    t["delta"] = real(&OSQPSettings::delta);
    t["polish_refine_iter"] = integer(&OSQPSettings::polish_refine_iter);
    return t;
  }();
  return table;
}

QpStatus status_of(OSQPInt value) {
  switch (value) {
    case OSQP_SOLVED:
      return QpStatus::kSolved;
    case OSQP_SOLVED_INACCURATE:
      return QpStatus::kNumerical;
    case OSQP_PRIMAL_INFEASIBLE:
    case OSQP_PRIMAL_INFEASIBLE_INACCURATE:
    case OSQP_DUAL_INFEASIBLE:
    case OSQP_DUAL_INFEASIBLE_INACCURATE:
      return QpStatus::kInfeasible;
    case OSQP_MAX_ITER_REACHED:
    case OSQP_TIME_LIMIT_REACHED:
      return QpStatus::kMaxIter;
    default:
      return QpStatus::kFailed;
  }
}

}  // namespace

const std::vector<std::string>& osqp_setting_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const auto& [name, setter] : setters()) out.push_back(name);
    return out;
  }();
  return names;
}

OsqpSolver::OsqpSolver(SolveMode mode, const OsqpOptions& options, bool send_all)
    : QpSolver(mode), options_(options), send_all_(send_all) {
  for (const auto& [name, value] : options_)
    if (setters().count(name) == 0) throw std::invalid_argument("osqp has no setting '" + name + "'");
}

OsqpSolver::~OsqpSolver() { drop_native(); }

void OsqpSolver::drop_native() {
  if (solver_ != nullptr) osqp_cleanup(solver_);
  solver_ = nullptr;
}

double OsqpSolver::stacked(const QpBuffers& qp, int row, int col) const {
  const int n_eq = static_cast<int>(qp.A.rows()), n_in = static_cast<int>(qp.C.rows());
  if (row < n_eq) return qp.A(row, col);
  if (row < n_eq + n_in) return qp.C(row - n_eq, col);
  return row - n_eq - n_in == col ? 1.0 : 0.0;
}

// _stack's lo, hi; osqp.OSQP clips them to ±OSQP_INFTY
void OsqpSolver::stack(const QpBuffers& qp) {
  const auto n_eq = qp.A.rows(), n_in = qp.C.rows(), n = qp.H.rows();
  const auto m = n_eq + n_in + (qp.has_box ? n : 0);
  lo_.resize(m);
  hi_.resize(m);
  lo_.head(n_eq) = qp.b;
  hi_.head(n_eq) = qp.b;
  lo_.segment(n_eq, n_in) = qp.l;
  hi_.segment(n_eq, n_in) = qp.u;
  if (qp.has_box) {
    lo_.tail(n) = qp.lb;
    hi_.tail(n) = qp.ub;
  }
  lo_ = lo_.cwiseMax(-OSQP_INFTY);
  hi_ = hi_.cwiseMin(OSQP_INFTY);
}

// upper_mask(H) (triu of the nonzeros, plus the whole diagonal) and M != 0, in CSC order
void OsqpSolver::make_patterns(const QpBuffers& qp) {
  const int n = static_cast<int>(qp.H.rows());
  const int m = static_cast<int>(lo_.size());
  P_ = Pattern{n, n, {0}, {}, {}};
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i <= j; ++i)
      if (i == j || qp.H(i, j) != 0.0) P_.i.push_back(i);
    P_.p.push_back(static_cast<OSQPInt>(P_.i.size()));
  }
  M_ = Pattern{m, n, {0}, {}, {}};
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < m; ++i)
      if (stacked(qp, i, j) != 0.0) M_.i.push_back(i);
    M_.p.push_back(static_cast<OSQPInt>(M_.i.size()));
  }
  P_.x.resize(P_.i.size());
  M_.x.resize(M_.i.size());
}

// pattern_values: the matrices' values on the patterns
void OsqpSolver::fill_values(const QpBuffers& qp) {
  for (int j = 0; j < P_.cols; ++j)
    for (auto k = P_.p[j]; k < P_.p[j + 1]; ++k) P_.x[k] = qp.H(P_.i[k], j);
  for (int j = 0; j < M_.cols; ++j)
    for (auto k = M_.p[j]; k < M_.p[j + 1]; ++k) M_.x[k] = stacked(qp, M_.i[k], j);
}

// _can_update: every nonzero of triu(H) and of M lies on the stored patterns
bool OsqpSolver::fits(const QpBuffers& qp) const {
  const int n = static_cast<int>(qp.H.rows());
  const int m_data = static_cast<int>(qp.A.rows() + qp.C.rows());
  // count the nonzeros on each pattern and compare with all of them (a zero on the pattern is
  // allowed, a nonzero off it is not)
  long long on = 0, all = 0;
  for (int j = 0; j < n; ++j) {
    for (auto k = P_.p[j]; k < P_.p[j + 1]; ++k) on += qp.H(P_.i[k], j) != 0.0;
    for (int i = 0; i <= j; ++i) all += qp.H(i, j) != 0.0;
  }
  if (on != all) return false;
  on = all = 0;
  for (int j = 0; j < n; ++j)
    for (auto k = M_.p[j]; k < M_.p[j + 1]; ++k)
      if (M_.i[k] < m_data) on += stacked(qp, static_cast<int>(M_.i[k]), j) != 0.0;
  all = (qp.A.array() != 0.0).count() + (qp.C.array() != 0.0).count();
  return on == all;
}

bool OsqpSolver::can_update(const QpBuffers& qp) { return fits(qp); }

void OsqpSolver::solve_fresh(const QpBuffers& qp, const Guess* guess, bool keep) {
  const auto t0 = Clock::now();
  const int n = static_cast<int>(qp.H.rows());
  stack(qp);
  make_patterns(qp);
  fill_values(qp);
  const int m = static_cast<int>(lo_.size());
  OSQPSettings settings;
  osqp_set_default_settings(&settings);
  settings.verbose = 0;
  for (const auto& [name, value] : options_) setters().at(name)(settings, value);
  OSQPCscMatrix P, A;
  OSQPCscMatrix_set_data(&P, n, n, static_cast<OSQPInt>(P_.x.size()), P_.x.data(), P_.i.data(),
                         P_.p.data());
  OSQPCscMatrix_set_data(&A, m, n, static_cast<OSQPInt>(M_.x.size()), M_.x.data(), M_.i.data(),
                         M_.p.data());
  drop_native();
  const OSQPInt err =
      osqp_setup(&solver_, &P, qp.g.data(), &A, lo_.data(), hi_.data(), m, n, &settings);
  if (err != 0) {
    drop_native();
    throw std::runtime_error("osqp_setup failed (OSQP error " + std::to_string(err) + ")");
  }
  if (options_.count("rho")) osqp_update_rho(solver_, options_.at("rho"));
  if (guess != nullptr) {
    // OSQPSolver._stacked_duals: y only when every part of the duals is known
    const bool duals = guess->y != nullptr && guess->z != nullptr &&
                       (!qp.has_box || guess->z_box != nullptr);
    if (duals) {
      y_guess_.resize(m);
      y_guess_ << *guess->y, *guess->z;
      if (qp.has_box) y_guess_.tail(n) = *guess->z_box;
    }
    osqp_warm_start(solver_, guess->x->data(), duals ? y_guess_.data() : nullptr);
  }
  const double setup = seconds_since(t0);
  solve_and_read(qp, setup);
  if (!keep) drop_native();
}

void OsqpSolver::solve_update(const QpBuffers& qp, unsigned changed) {
  const auto t0 = Clock::now();
  if (send_all_) changed = kAllFields;
  const bool vectors = changed & (kFieldB | kFieldL | kFieldU | kFieldLb | kFieldUb);
  const bool matrix = changed & (kFieldA | kFieldC);
  if (vectors || matrix) stack(qp);
  if (changed & kFieldH)
    for (int j = 0; j < P_.cols; ++j)
      for (auto k = P_.p[j]; k < P_.p[j + 1]; ++k) P_.x[k] = qp.H(P_.i[k], j);
  if (matrix)
    for (int j = 0; j < M_.cols; ++j)
      for (auto k = M_.p[j]; k < M_.p[j + 1]; ++k) M_.x[k] = stacked(qp, M_.i[k], j);
  const double* q = (changed & kFieldG) ? qp.g.data() : nullptr;
  if (q != nullptr || vectors)
    osqp_update_data_vec(solver_, q, vectors ? lo_.data() : nullptr,
                         vectors ? hi_.data() : nullptr);
  if ((changed & kFieldH) || matrix)
    osqp_update_data_mat(solver_, (changed & kFieldH) ? P_.x.data() : nullptr, nullptr,
                         static_cast<OSQPInt>(P_.x.size()), matrix ? M_.x.data() : nullptr,
                         nullptr, static_cast<OSQPInt>(M_.x.size()));
  solve_and_read(qp, seconds_since(t0));
}

void OsqpSolver::solve_and_read(const QpBuffers& qp, double setup_seconds) {
  const auto t0 = Clock::now();
  osqp_solve(solver_);
  outcome_.wall = seconds_since(t0);
  outcome_.setup = setup_seconds;
  const OSQPInfo& info = *solver_->info;
  outcome_.status = status_of(info.status_val);
  outcome_.iterations = static_cast<int>(info.iter);
  outcome_.internal = info.solve_time;
  outcome_.message = info.status;
  const bool ok = outcome_.status == QpStatus::kSolved ||
                  outcome_.status == QpStatus::kNumerical ||
                  outcome_.status == QpStatus::kMaxIter;
  if (!ok) return;
  const auto n = qp.H.rows(), n_eq = qp.A.rows(), n_in = qp.C.rows();
  solution_.x = Eigen::Map<const Vector>(solver_->solution->x, n);
  const Eigen::Map<const Vector> y(solver_->solution->y, lo_.size());
  solution_.y = y.head(n_eq);
  solution_.z = y.segment(n_eq, n_in);
  solution_.has_y = solution_.has_z = true;
  if (qp.has_box) {
    solution_.z_box = y.tail(n);
    solution_.has_z_box = true;
  }
}

}  // namespace wbcbench
