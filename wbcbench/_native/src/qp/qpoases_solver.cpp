#include "qp/qpoases_solver.hpp"

#include <qpOASES.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <limits>
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

QpOasesSolver::QpOasesSolver(SolveMode mode, const QpOasesOptions& options) : QpSolver(mode) {
  for (const auto& [name, value] : options)
    if (name != "CPUtime")
      throw std::invalid_argument("qpoases (native) takes no setting '" + name +
                                  "' (only CPUtime, which has no effect)");
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
  if (na == 0) {
    problem_ = std::make_unique<qpOASES::QProblemB>(n_, qpOASES::HST_UNKNOWN);
  } else {
    auto sq = std::make_unique<qpOASES::SQProblem>(n_, na, qpOASES::HST_UNKNOWN);
    sq_ = sq.get();
    problem_ = std::move(sq);
  }
  qpOASES::Options options;
  options.setToDefault();
  options.printLevel = qpOASES::PL_NONE;
  options.enableEqualities = qpOASES::BT_TRUE;
  problem_->setOptions(options);
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
  call(qp, seconds_since(t0));
  if (!keep) drop_native();
}

void QpOasesSolver::solve_update(const QpBuffers& qp, unsigned /*changed*/) {
  // CasADi sends every field on every call (a matrix hotstart)
  const auto t0 = Clock::now();
  load(qp);
  call(qp, seconds_since(t0));
}

// QpoasesInterface::solve, dense branch
void QpOasesSolver::call(const QpBuffers& qp, double setup_seconds) {
  const int na = n_eq_ + n_in_;
  qpOASES::int_t nwsr = 5 * (n_ + na);
  // ~QProblemB() resets qpOASES' global message handler to print errors; hide them again
  problem_->setPrintLevel(qpOASES::PL_NONE);
  qpOASES::returnValue flag;
  const auto t0 = Clock::now();
  if (sq_ == nullptr) {
    if (called_once_) problem_->reset();  // CasADi never hotstarts a QProblemB
    flag = problem_->init(h_.data(), g_.data(), lbx_.data(), ubx_.data(), nwsr, nullptr);
  } else if (called_once_) {
    flag = sq_->hotstart(h_.data(), g_.data(), a_.data(), lbx_.data(), ubx_.data(), lba_.data(),
                         uba_.data(), nwsr, nullptr);
  } else {
    flag = sq_->init(h_.data(), g_.data(), a_.data(), lbx_.data(), ubx_.data(), lba_.data(),
                     uba_.data(), nwsr, nullptr);
  }
  outcome_.wall = seconds_since(t0);
  called_once_ = true;  // also after a failed call
  outcome_.setup = setup_seconds;
  outcome_.internal = outcome_.wall;  // CasADi's t_wall_solver: the same call
  outcome_.iterations = static_cast<int>(nwsr);
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
