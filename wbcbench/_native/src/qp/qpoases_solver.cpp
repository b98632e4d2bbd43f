#include "qp/qpoases_solver.hpp"

#include <qpOASES.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

namespace wbcbench {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// CasADi's return_status text of a qpOASES return value
std::string casadi_message(qpOASES::returnValue flag) {
  switch (flag) {
#include "qp/qpoases_messages.inc"
    default:
      break;
  }
  std::ostringstream ss;
  ss << "Unknown error flag: " << static_cast<int>(flag) << ". Consult qpOASES documentation.";
  return ss.str();
}

bool contains(const std::string& text, const char* part) {
  return text.find(part) != std::string::npos;
}

// wbcbench.qp.backends.qpoases._status: success, else the lower-cased message's words
QpStatus status_of(qpOASES::returnValue flag, const std::string& message) {
  if (flag == qpOASES::SUCCESSFUL_RETURN) return QpStatus::kSolved;
  std::string text = message;
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (contains(text, "infeasib") || contains(text, "unbounded")) return QpStatus::kInfeasible;
  if (contains(text, "working set") || contains(text, "nwsr") || contains(text, "iteration"))
    return QpStatus::kMaxIter;
  return QpStatus::kFailed;
}

// CasADi's str(double)
std::string str(double v) {
  std::ostringstream ss;
  ss << v;
  return ss.str();
}

// Conic::check_inputs (CasADi raises; the Python backend's solve then fails with its text)
void check_bounds(const std::vector<double>& lo, const std::vector<double>& hi, const char* l,
                  const char* u, const char* eq) {
  const double inf = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < lo.size(); ++i) {
    if (lo[i] <= hi[i] && lo[i] != inf && hi[i] != -inf) continue;
    const std::string k = std::to_string(i);
    throw std::runtime_error(std::string("Ill-posed problem detected: ") + l + "[" + k + "] <= " +
                             u + "[" + k + "] was violated. Got " + l + "[" + k + "]" + eq +
                             str(lo[i]) + " and " + u + "[" + k + "] = " + str(hi[i]) + ".");
  }
}

}  // namespace

namespace {

using BoolField = qpOASES::BooleanType qpOASES::Options::*;
using IntField = qpOASES::int_t qpOASES::Options::*;
using RealField = qpOASES::real_t qpOASES::Options::*;

const std::map<std::string, BoolField>& bool_fields() {
  static const std::map<std::string, BoolField> f = {
      {"enableRamping", &qpOASES::Options::enableRamping},
      {"enableFarBounds", &qpOASES::Options::enableFarBounds},
      {"enableFlippingBounds", &qpOASES::Options::enableFlippingBounds},
      {"enableRegularisation", &qpOASES::Options::enableRegularisation},
      {"enableFullLITests", &qpOASES::Options::enableFullLITests},
      {"enableNZCTests", &qpOASES::Options::enableNZCTests},
      {"enableEqualities", &qpOASES::Options::enableEqualities},
      {"enableInertiaCorrection", &qpOASES::Options::enableInertiaCorrection},
  };
  return f;
}

const std::map<std::string, IntField>& int_fields() {
  static const std::map<std::string, IntField> f = {
      {"enableDriftCorrection", &qpOASES::Options::enableDriftCorrection},
      {"enableCholeskyRefactorisation", &qpOASES::Options::enableCholeskyRefactorisation},
      {"numRegularisationSteps", &qpOASES::Options::numRegularisationSteps},
      {"numRefinementSteps", &qpOASES::Options::numRefinementSteps},
  };
  return f;
}

const std::map<std::string, RealField>& real_fields() {
  static const std::map<std::string, RealField> f = {
      {"terminationTolerance", &qpOASES::Options::terminationTolerance},
      {"boundTolerance", &qpOASES::Options::boundTolerance},
      {"boundRelaxation", &qpOASES::Options::boundRelaxation},
      {"epsNum", &qpOASES::Options::epsNum},
      {"epsDen", &qpOASES::Options::epsDen},
      {"maxPrimalJump", &qpOASES::Options::maxPrimalJump},
      {"maxDualJump", &qpOASES::Options::maxDualJump},
      {"initialRamping", &qpOASES::Options::initialRamping},
      {"finalRamping", &qpOASES::Options::finalRamping},
      {"initialFarBounds", &qpOASES::Options::initialFarBounds},
      {"growFarBounds", &qpOASES::Options::growFarBounds},
      {"epsFlipping", &qpOASES::Options::epsFlipping},
      {"epsRegularisation", &qpOASES::Options::epsRegularisation},
      {"epsIterRef", &qpOASES::Options::epsIterRef},
      {"epsLITests", &qpOASES::Options::epsLITests},
      {"epsNZCTests", &qpOASES::Options::epsNZCTests},
      {"rcondSMin", &qpOASES::Options::rcondSMin},
  };
  return f;
}

// wbcbench's names of the settings outside Options: CPUtime (no effect), nWSR (the cap per
// call), initialStatusBounds (-1 lower, 0 inactive, 1 upper)
bool known_setting(const std::string& name) {
  return name == "CPUtime" || name == "nWSR" || name == "initialStatusBounds" ||
         bool_fields().count(name) || int_fields().count(name) || real_fields().count(name);
}

// libdwbc's nWSR per call: CalcSingleTaskTorqueWithQP passes 1000, CalcContactRedistribute 300
constexpr int kLibdwbcTaskNwsr = 1000;
constexpr int kLibdwbcWrenchNwsr = 300;

}  // namespace

QpOasesProfile qpoases_profile(const std::string& name) {
  if (name == "casadi") return QpOasesProfile::kCasadi;
  if (name == "libdwbc_task") return QpOasesProfile::kLibdwbcTask;
  if (name == "libdwbc_wrench") return QpOasesProfile::kLibdwbcWrench;
  throw std::invalid_argument("unknown qpOASES profile '" + name +
                              "'; valid choices: casadi, libdwbc_task, libdwbc_wrench");
}

QpOasesSolver::QpOasesSolver(SolveMode mode, const QpOasesOptions& options,
                             QpOasesProfile profile)
    : QpSolver(mode), profile_(profile) {
  for (const auto& [name, value] : options) {
    if (!known_setting(name))
      throw std::invalid_argument("qpoases (native) takes no setting '" + name + "'");
    if (name != "CPUtime") overrides_[name] = value;
  }
}

qpOASES::Options QpOasesSolver::make_options(bool reliable, bool first_init) const {
  qpOASES::Options options;
  if (profile_ == QpOasesProfile::kCasadi) {
    options.setToDefault();
    options.enableEqualities = qpOASES::BT_TRUE;
  } else if (reliable) {
    options.setToReliable();
  } else {
    options.setToMPC();
  }
  options.printLevel = qpOASES::PL_NONE;
  // libdwbc passes no box bounds to a QP that has none: qpOASES stands ±INFTY in for them, and
  // with far bounds on (setToReliable) they count as bounds. setToReliable's initialStatusBounds
  // (lower) starts the first homotopy with every variable at a bound the QP does not have, and on
  // the contact-wrench QP that homotopy cycles (docs/qpoases.md). The first init starts them
  // inactive, as setToMPC does; call() sets libdwbc's options back for every later call.
  if (first_init && libdwbc()) options.initialStatusBounds = qpOASES::ST_INACTIVE;
  for (const auto& [name, value] : overrides_) {
    if (auto b = bool_fields().find(name); b != bool_fields().end())
      options.*(b->second) = value != 0.0 ? qpOASES::BT_TRUE : qpOASES::BT_FALSE;
    else if (auto i = int_fields().find(name); i != int_fields().end())
      options.*(i->second) = static_cast<qpOASES::int_t>(value);
    else if (auto r = real_fields().find(name); r != real_fields().end())
      options.*(r->second) = value;
    else if (name == "initialStatusBounds")
      options.initialStatusBounds = value < 0   ? qpOASES::ST_LOWER
                                    : value > 0 ? qpOASES::ST_UPPER
                                                : qpOASES::ST_INACTIVE;
  }
  return options;
}

void QpOasesSolver::set_options(bool reliable, bool first_init) {
  problem_->setOptions(make_options(reliable, first_init));
}

QpOasesOptions QpOasesSolver::settings() const {
  const qpOASES::Options o = make_options(profile_ == QpOasesProfile::kLibdwbcWrench);
  QpOasesOptions out;
  for (const auto& [name, field] : bool_fields()) out[name] = o.*field == qpOASES::BT_TRUE;
  for (const auto& [name, field] : int_fields()) out[name] = static_cast<double>(o.*field);
  for (const auto& [name, field] : real_fields()) out[name] = o.*field;
  out["initialStatusBounds"] = o.initialStatusBounds == qpOASES::ST_LOWER   ? -1.0
                               : o.initialStatusBounds == qpOASES::ST_UPPER ? 1.0
                                                                            : 0.0;
  out["printLevel"] = static_cast<double>(o.printLevel);
  return out;
}

QpOasesSolver::~QpOasesSolver() { drop_native(); }

void QpOasesSolver::drop_native() {
  problem_.reset();
  sq_ = nullptr;
  called_once_ = false;
}

// QpoasesInterface::init and init_mem
void QpOasesSolver::build(const QpBuffers& qp) {
  drop_native();
  n_ = static_cast<int>(qp.H.rows());
  n_eq_ = static_cast<int>(qp.A.rows());
  n_in_ = static_cast<int>(qp.C.rows());
  const int na = n_eq_ + n_in_;
  if (na == 0 && !libdwbc()) {
    problem_ = std::make_unique<qpOASES::QProblemB>(n_, qpOASES::HST_UNKNOWN);
  } else {
    auto sq = std::make_unique<qpOASES::SQProblem>(n_, na, qpOASES::HST_UNKNOWN);
    sq_ = sq.get();
    problem_ = std::move(sq);
  }
  set_options(profile_ == QpOasesProfile::kLibdwbcWrench);
  // (the buffers qpOASES points into are resized only here, with no object holding them)
  h_.resize(static_cast<size_t>(n_) * n_);
  a_.resize(static_cast<size_t>(na) * n_);
  g_.resize(n_);
  lbx_.resize(n_);
  ubx_.resize(n_);
  lba_.resize(na);
  uba_.resize(na);
  dual_.resize(static_cast<size_t>(n_) + na);
}

void QpOasesSolver::load(const QpBuffers& qp) {
  const double inf = std::numeric_limits<double>::infinity();
  const int na = n_eq_ + n_in_;
  Eigen::Map<Vector>(g_.data(), n_) = qp.g;
  if (qp.has_box) {
    Eigen::Map<Vector>(lbx_.data(), n_) = qp.lb;
    Eigen::Map<Vector>(ubx_.data(), n_) = qp.ub;
  } else {  // Problem.box(): ±inf
    std::fill(lbx_.begin(), lbx_.end(), -inf);
    std::fill(ubx_.begin(), ubx_.end(), inf);
  }
  Eigen::Map<Vector> lba(lba_.data(), na), uba(uba_.data(), na);
  lba.head(n_eq_) = qp.b;
  uba.head(n_eq_) = qp.b;
  lba.tail(n_in_) = qp.l;
  uba.tail(n_in_) = qp.u;
  check_bounds(lbx_, ubx_, "LBX", "UBX", "=");
  check_bounds(lba_, uba_, "LBA", "UBA", " = ");
  // casadi_densify(H, tr=false): column-major; casadi_densify(A, tr=true): row-major
  Eigen::Map<Matrix>(h_.data(), n_, n_) = qp.H;
  Eigen::Map<RowMatrix> a(a_.data(), na, n_);
  a.topRows(n_eq_) = qp.A;
  a.bottomRows(n_in_) = qp.C;
}

void QpOasesSolver::solve_fresh(const QpBuffers& qp, const Guess* /*guess*/, bool keep) {
  // qpOASES through CasADi takes no initial guess: warm runs as cold
  const auto t0 = Clock::now();
  build(qp);
  load(qp);
  call(qp, seconds_since(t0), kAllFields);
  if (!keep) drop_native();
}

void QpOasesSolver::solve_update(const QpBuffers& qp, unsigned changed) {
  // CasADi sends every field on every call (a matrix hotstart); libdwbc's matrices go again
  // only when they changed
  const auto t0 = Clock::now();
  load(qp);
  call(qp, seconds_since(t0), libdwbc() ? changed : kAllFields);
}

// QpoasesInterface::solve, dense branch (libdwbc: CQuadraticProgram::SolveQPoases)
void QpOasesSolver::call(const QpBuffers& qp, double setup_seconds, unsigned changed) {
  const int na = n_eq_ + n_in_;
  int cap = 5 * (n_ + na);
  if (profile_ == QpOasesProfile::kLibdwbcTask) cap = kLibdwbcTaskNwsr;
  if (profile_ == QpOasesProfile::kLibdwbcWrench) cap = kLibdwbcWrenchNwsr;
  if (auto it = overrides_.find("nWSR"); it != overrides_.end()) cap = static_cast<int>(it->second);
  qpOASES::int_t nwsr = cap;
  // libdwbc passes no box bounds to a QP that has none
  const double* lbx = libdwbc() && !qp.has_box ? nullptr : lbx_.data();
  const double* ubx = libdwbc() && !qp.has_box ? nullptr : ubx_.data();
  // ~QProblemB() resets qpOASES' global message handler to print errors; hide them again
  problem_->setPrintLevel(qpOASES::PL_NONE);
  qpOASES::returnValue flag;
  const auto t0 = Clock::now();
  if (sq_ == nullptr) {
    if (called_once_) problem_->reset();  // CasADi never hotstarts a QProblemB
    flag = problem_->init(h_.data(), g_.data(), lbx, ubx, nwsr, nullptr);
    last_call_ = "init";
  } else if (!called_once_) {
    const bool reliable = profile_ == QpOasesProfile::kLibdwbcWrench;
    if (libdwbc()) set_options(reliable, true);
    flag = sq_->init(h_.data(), g_.data(), a_.data(), lbx, ubx, lba_.data(), uba_.data(), nwsr,
                     nullptr);
    if (libdwbc()) set_options(reliable);
    last_call_ = "init";
  } else if (changed & (kFieldH | kFieldA | kFieldC)) {
    flag = sq_->hotstart(h_.data(), g_.data(), a_.data(), lbx, ubx, lba_.data(), uba_.data(),
                         nwsr, nullptr);
    last_call_ = "hotstart_matrices";
  } else {
    // the same matrices: qpOASES keeps its factorisations and moves along the homotopy in the
    // vectors only
    flag = sq_->qpOASES::QProblem::hotstart(g_.data(), lbx, ubx, lba_.data(), uba_.data(), nwsr,
                                             nullptr);
    last_call_ = "hotstart";
  }
  last_nwsr_ = static_cast<int>(nwsr);
  if (libdwbc() && flag != qpOASES::SUCCESSFUL_RETURN && sq_ != nullptr) {
    // libdwbc: a fresh SQProblem, setToReliable(), ten times the cap, initialised from scratch
    auto sq = std::make_unique<qpOASES::SQProblem>(n_, na, qpOASES::HST_UNKNOWN);
    sq_ = sq.get();
    problem_ = std::move(sq);
    set_options(true);
    problem_->setPrintLevel(qpOASES::PL_NONE);
    nwsr = 10 * cap;
    flag = sq_->init(h_.data(), g_.data(), a_.data(), lbx, ubx, lba_.data(), uba_.data(), nwsr,
                     nullptr);
    last_nwsr_ += static_cast<int>(nwsr);
    last_call_ = "reinit";
    outcome_.rebuilt = true;
  }
  outcome_.wall = seconds_since(t0);
  called_once_ = true;  // also after a failed call
  outcome_.setup = setup_seconds;
  outcome_.internal = outcome_.wall;  // CasADi's t_wall_solver: the same call
  outcome_.iterations = last_nwsr_;
  outcome_.message = casadi_message(flag);
  outcome_.status = status_of(flag, outcome_.message);
  if (outcome_.status != QpStatus::kSolved && outcome_.status != QpStatus::kMaxIter) return;
  // CasADi's outputs start at zero; qpOASES leaves x untouched unless its QP is solved
  solution_.x.setZero(n_);
  problem_->getPrimalSolution(solution_.x.data());
  problem_->getDualSolution(dual_.data());
  const Eigen::Map<const Vector> dual(dual_.data(), n_ + na);
  solution_.y = -dual.segment(n_, n_eq_);
  solution_.z = -dual.tail(n_in_);
  solution_.has_y = solution_.has_z = true;
  if (qp.has_box) {
    solution_.z_box = -dual.head(n_);
    solution_.has_z_box = true;
  }
}

}  // namespace wbcbench
