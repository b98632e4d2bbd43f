#include "qp/daqp_solver.hpp"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <utility>

extern "C" {
#include <api.h>
#include <utils.h>
}

namespace wbcbench {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

constexpr int kEqualitySense = 5;  // wbcbench.qp.backends.daqp.EQUALITY_SENSE

using Setter = std::function<void(DAQPSettings&, double)>;

// DAQPSettings' fields by the names daqp.Model.settings uses
const std::vector<std::pair<std::string, Setter>>& setters() {
  static const std::vector<std::pair<std::string, Setter>> table = {
      {"primal_tol", [](DAQPSettings& s, double v) { s.primal_tol = v; }},
      {"dual_tol", [](DAQPSettings& s, double v) { s.dual_tol = v; }},
      {"zero_tol", [](DAQPSettings& s, double v) { s.zero_tol = v; }},
      {"pivot_tol", [](DAQPSettings& s, double v) { s.pivot_tol = v; }},
      {"progress_tol", [](DAQPSettings& s, double v) { s.progress_tol = v; }},
      {"cycle_tol", [](DAQPSettings& s, double v) { s.cycle_tol = static_cast<int>(v); }},
      {"iter_limit", [](DAQPSettings& s, double v) { s.iter_limit = static_cast<int>(v); }},
      {"fval_bound", [](DAQPSettings& s, double v) { s.fval_bound = v; }},
      {"eps_prox", [](DAQPSettings& s, double v) { s.eps_prox = v; }},
      {"eta_prox", [](DAQPSettings& s, double v) { s.eta_prox = v; }},
      {"rho_soft", [](DAQPSettings& s, double v) { s.rho_soft = v; }},
      {"w_soft", [](DAQPSettings& s, double v) { s.w_soft = v; }},
      {"rel_subopt", [](DAQPSettings& s, double v) { s.rel_subopt = v; }},
      {"abs_subopt", [](DAQPSettings& s, double v) { s.abs_subopt = v; }},
      {"sing_tol", [](DAQPSettings& s, double v) { s.sing_tol = v; }},
      {"refactor_tol", [](DAQPSettings& s, double v) { s.refactor_tol = v; }},
      {"time_limit", [](DAQPSettings& s, double v) { s.time_limit = v; }},
      {"eq_reduction", [](DAQPSettings& s, double v) { s.eq_reduction = static_cast<int>(v); }},
      {"presolve", [](DAQPSettings& s, double v) { s.presolve = static_cast<int>(v); }},
  };
  return table;
}

// wbcbench.qp.backends.daqp._STATUS and _FLAG_TEXT
QpStatus status_of(int flag) {
  switch (flag) {
    case DAQP_EXIT_OPTIMAL:
    case DAQP_EXIT_SOFT_OPTIMAL:
      return QpStatus::kSolved;
    case DAQP_EXIT_INFEASIBLE:
    case DAQP_EXIT_UNBOUNDED:
      return QpStatus::kInfeasible;
    case DAQP_EXIT_ITERLIMIT:
      return QpStatus::kMaxIter;
    case DAQP_EXIT_CYCLE:
    case DAQP_EXIT_NONCONVEX:
    case DAQP_EXIT_OVERDETERMINED_INITIAL:
      return QpStatus::kNumerical;
    default:
      return QpStatus::kFailed;
  }
}

std::string flag_text(int flag) {
  switch (flag) {
    case DAQP_EXIT_OPTIMAL:
      return "optimal";
    case DAQP_EXIT_SOFT_OPTIMAL:
      return "soft optimal";
    case DAQP_EXIT_INFEASIBLE:
      return "primal infeasible";
    case DAQP_EXIT_CYCLE:
      return "cycling detected";
    case DAQP_EXIT_UNBOUNDED:
      return "unbounded";
    case DAQP_EXIT_ITERLIMIT:
      return "iteration limit";
    case DAQP_EXIT_NONCONVEX:
      return "non-convex problem";
    case DAQP_EXIT_OVERDETERMINED_INITIAL:
      return "overdetermined initial active set";
    default:
      return "exitflag " + std::to_string(flag);
  }
}

}  // namespace

const std::vector<std::string>& daqp_setting_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const auto& [name, set] : setters()) out.push_back(name);
    return out;
  }();
  return names;
}

struct DaqpSolver::Impl {
  DAQPSettings settings{};
  DAQPProblem problem{};
  DAQPWorkspace* work = nullptr;    // the workspace in use (null: none)
  DAQPWorkspace* storage = nullptr;  // its struct, kept from one workspace to the next

  ~Impl() {
    free_workspace();
    std::free(storage);
  }
  // the workspace's struct, made once (prepare, or the first set-up)
  void make_storage() {
    if (storage != nullptr) return;
    storage = static_cast<DAQPWorkspace*>(std::calloc(1, sizeof(DAQPWorkspace)));
    if (storage == nullptr) throw std::bad_alloc();
  }
  // a zeroed workspace with its own copy of the settings (daqp.Model: allocate_daqp_settings,
  // then the user's values)
  void make_workspace() {
    make_storage();
    std::memset(storage, 0, sizeof(DAQPWorkspace));
    work = storage;
    allocate_daqp_settings(work);
    *work->settings = settings;
  }
  void free_workspace() {
    if (work == nullptr) return;
    free_daqp_workspace(work);  // frees the settings too
    free_daqp_ldp(work);
    work = nullptr;
  }
};

DaqpSolver::DaqpSolver(SolveMode mode, const DaqpOptions& options)
    : QpSolver(mode), impl_(std::make_unique<Impl>()) {
  daqp_default_settings(&impl_->settings);
  for (const auto& [name, value] : options) {
    bool known = false;
    for (const auto& [field, set] : setters()) {
      if (field == name) {
        set(impl_->settings, value);
        known = true;
      }
    }
    if (!known) throw std::invalid_argument("daqp has no setting '" + name + "'");
  }
}

DaqpSolver::~DaqpSolver() = default;

void DaqpSolver::prepare_native(const QpBuffers& qp) {
  load(qp, kAllFields);
  impl_->make_storage();
}

bool DaqpSolver::has_native() const { return impl_->work != nullptr; }

void DaqpSolver::drop_native() {
  impl_->free_workspace();
  solved_ = false;
}

void DaqpSolver::load(const QpBuffers& qp, unsigned changed) {
  const int n = static_cast<int>(qp.H.rows());
  const int n_eq = static_cast<int>(qp.A.rows()), n_in = static_cast<int>(qp.C.rows());
  const int k = qp.has_box ? n : 0;
  const int m = k + n_eq + n_in;
  if (changed == kAllFields) {
    H_.resize(n, n);
    M_.resize(n_eq + n_in, n);
    f_.resize(n);
    bupper_.resize(m);
    blower_.resize(m);
    lam_.resize(m);
    sense_.assign(static_cast<size_t>(m), 0);
    for (int i = k; i < k + n_eq; ++i) sense_[static_cast<size_t>(i)] = kEqualitySense;
  }
  if (changed & kFieldH) H_ = qp.H;
  if (changed & kFieldG) f_ = qp.g;
  if (changed & kFieldA) M_.topRows(n_eq) = qp.A;
  if (changed & kFieldC) M_.bottomRows(n_in) = qp.C;
  if (changed & ~(kFieldH | kFieldG)) {
    if (qp.has_box) {
      bupper_.head(k) = qp.ub;
      blower_.head(k) = qp.lb;
    }
    bupper_.segment(k, n_eq) = qp.b;
    blower_.segment(k, n_eq) = qp.b;
    bupper_.tail(n_in) = qp.u;
    blower_.tail(n_in) = qp.l;
  }
  DAQPProblem& p = impl_->problem;
  p.n = n;
  p.m = m;
  p.ms = k;
  p.H = H_.data();
  p.f = f_.data();
  p.A = n_eq + n_in == 0 ? nullptr : M_.data();
  p.bupper = m == 0 ? nullptr : bupper_.data();
  p.blower = m == 0 ? nullptr : blower_.data();
  p.sense = m == 0 ? nullptr : sense_.data();
  p.break_points = nullptr;
  p.nh = 0;
  p.problem_type = 0;
}

void DaqpSolver::solve_fresh(const QpBuffers& qp, const Guess* guess, bool keep) {
  const auto t0 = Clock::now();
  drop_native();
  load(qp, kAllFields);
  Impl& d = *impl_;
  d.make_workspace();
  DAQPSettings* own = d.work->settings;
  Vector x0;
  if (guess != nullptr && guess->x != nullptr) {
    // primal only, as the Python backend (DAQP derives the initial active set from x; the
    // sense array it marks is this object's copy)
    x0 = *guess->x;
    if (d.problem.m > 0) daqp_primal_init_active(&d.problem, x0.data());
  }
  c_float setup_time = 0.0;
  const int flag = setup_daqp_main(&d.problem, d.work, &setup_time, 0);
  if (flag < 0) {
    // on failure DAQP releases its workspace but leaves settings it did not allocate
    if (d.work->settings == nullptr) std::free(own);
    d.free_workspace();
    outcome_.status = status_of(flag);
    outcome_.setup = seconds_since(t0);
    outcome_.message = "setup failed: " + flag_text(flag);
    return;
  }
  if (x0.size() > 0) daqp_set_primal_start(d.work, x0.data());
  call(qp, seconds_since(t0));
  if (!keep) drop_native();
}

void DaqpSolver::solve_update(const QpBuffers& qp, unsigned changed) {
  const auto t0 = Clock::now();
  load(qp, changed);
  Impl& d = *impl_;
  int mask = 0;
  if (changed & kFieldH) mask |= DAQP_UPDATE_Rinv;
  if (changed & (kFieldA | kFieldC)) mask |= DAQP_UPDATE_M;
  if (changed & kFieldG) mask |= DAQP_UPDATE_v;
  if (changed & ~(kFieldH | kFieldG)) mask |= DAQP_UPDATE_d;
  if (mask & (DAQP_UPDATE_Rinv | DAQP_UPDATE_M)) {
    // a new H or M keeps the working set DAQP holds (daqp.Model.update without a sense)
    if (solved_) d.problem.sense = d.work->sense;
    mask |= DAQP_UPDATE_sense;
  }
  const int flag = mask == 0 ? 0 : daqp_update_ldp(mask, d.work, &d.problem);
  if (flag < 0) {
    drop_native();
    outcome_.status = status_of(flag);
    outcome_.setup = seconds_since(t0);
    outcome_.message = "update failed: " + flag_text(flag);
    return;
  }
  call(qp, seconds_since(t0));
  if (outcome_.success() && !solution_.x.allFinite()) {
    // DAQP can flag a non-finite x optimal when a hot update follows a very different problem:
    // set up afresh once, from the previous solution, and say so
    const QpOutcome first = outcome_;
    Guess guess;
    const bool guessed = guess_from_previous(qp, guess);
    solve_fresh(qp, guessed ? &guess : nullptr, true);
    outcome_.rebuilt = true;
    outcome_.wall += first.wall;
    outcome_.setup += first.setup;
    outcome_.message += "; rebuilt after a non-finite hot result";
  }
}

void DaqpSolver::call(const QpBuffers& qp, double setup_seconds) {
  Impl& d = *impl_;
  const int n = d.problem.n, k = d.problem.ms;
  const int n_eq = static_cast<int>(qp.A.rows()), n_in = static_cast<int>(qp.C.rows());
  solution_.x.resize(n);
  DAQPResult res{};
  res.x = solution_.x.data();
  res.lam = lam_.size() == 0 ? nullptr : lam_.data();
  const auto t0 = Clock::now();
  daqp_solve(&res, d.work);
  outcome_.wall = seconds_since(t0);
  outcome_.setup = setup_seconds;
  solved_ = true;
  outcome_.status = status_of(res.exitflag);
  outcome_.iterations = res.iter;
  outcome_.internal = res.solve_time;
  outcome_.message = flag_text(res.exitflag);
  if (outcome_.status != QpStatus::kSolved && outcome_.status != QpStatus::kMaxIter) return;
  solution_.z_box = lam_.head(k);
  solution_.y = lam_.segment(k, n_eq);
  solution_.z = lam_.tail(n_in);
  solution_.has_z_box = qp.has_box;
  solution_.has_y = solution_.has_z = true;
}

}  // namespace wbcbench
