#include "qp/solver.hpp"

#include <chrono>
#include <cstring>
#include <exception>

namespace wbcbench {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// the bytes of a and b are equal (the Python handle's snapshot compares tobytes())
template <typename T>
bool same_bytes(const T& a, const T& b) {
  return a.size() == b.size() &&
         (a.size() == 0 ||
          std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0);
}

bool same_structure(const QpBuffers& a, const QpBuffers& b) {
  return a.H.rows() == b.H.rows() && a.A.rows() == b.A.rows() && a.C.rows() == b.C.rows() &&
         a.has_box == b.has_box;
}

}  // namespace

const char* status_name(QpStatus status) {
  switch (status) {
    case QpStatus::kSolved:
      return "solved";
    case QpStatus::kInfeasible:
      return "infeasible";
    case QpStatus::kMaxIter:
      return "max_iter";
    case QpStatus::kNumerical:
      return "numerical";
    case QpStatus::kFailed:
      break;
  }
  return "failed";
}

void QpSolver::reset() {
  has_previous_ = false;
  has_last_ = false;
  drop_native();
}

void QpSolver::prepare(const QpBuffers& qp) {
  const auto n = qp.H.rows();
  for (QpSolution* s : {&solution_, &previous_}) {
    s->x.resize(n);
    s->y.resize(qp.A.rows());
    s->z.resize(qp.C.rows());
    s->z_box.resize(qp.has_box ? n : 0);
  }
  if (mode_ == SolveMode::kHot && !has_last_) last_ = qp;  // (has_last_ stays false)
  prepare_native(qp);
}

// QPSolver._guess without an explicit x0: the previous solution, its duals where their shapes fit
bool QpSolver::guess_from_previous(const QpBuffers& qp, Guess& guess) const {
  const auto n = qp.H.rows();
  if (mode_ == SolveMode::kCold || !has_previous_ || previous_.x.size() != n) return false;
  guess.x = &previous_.x;
  guess.y = previous_.has_y && previous_.y.size() == qp.A.rows() ? &previous_.y : nullptr;
  guess.z = previous_.has_z && previous_.z.size() == qp.C.rows() ? &previous_.z : nullptr;
  guess.z_box = previous_.has_z_box && qp.has_box ? &previous_.z_box : nullptr;
  return true;
}

unsigned QpSolver::changed_fields(const QpBuffers& qp) const {
  unsigned changed = 0;
  if (!same_bytes(qp.H, last_.H)) changed |= kFieldH;
  if (!same_bytes(qp.g, last_.g)) changed |= kFieldG;
  if (!same_bytes(qp.A, last_.A)) changed |= kFieldA;
  if (!same_bytes(qp.b, last_.b)) changed |= kFieldB;
  if (!same_bytes(qp.C, last_.C)) changed |= kFieldC;
  if (!same_bytes(qp.l, last_.l)) changed |= kFieldL;
  if (!same_bytes(qp.u, last_.u)) changed |= kFieldU;
  if (qp.has_box && !same_bytes(qp.lb, last_.lb)) changed |= kFieldLb;
  if (qp.has_box && !same_bytes(qp.ub, last_.ub)) changed |= kFieldUb;
  return changed;
}

const QpOutcome& QpSolver::solve(const QpBuffers& qp) {
  const auto t_call = Clock::now();
  outcome_ = QpOutcome();
  solution_.has_y = solution_.has_z = solution_.has_z_box = false;
  try {
    Guess guess;
    const bool guessed = guess_from_previous(qp, guess);
    if (mode_ == SolveMode::kHot) {
      // QPSolver._solve_hot: update in place when the structure is the kept object's
      if (has_native() && has_last_ && same_structure(qp, last_) && can_update(qp)) {
        solve_update(qp, changed_fields(qp));
      } else {
        drop_native();
        solve_fresh(qp, guessed ? &guess : nullptr, true);
        outcome_.rebuilt = true;
        ++builds_;
      }
      last_ = qp;  // (the copy is the snapshot; the buffers keep their memory between calls)
      has_last_ = true;
    } else {
      solve_fresh(qp, guessed ? &guess : nullptr, false);
    }
  } catch (const std::exception& e) {  // a failed solve, never a crashed tick
    outcome_.status = QpStatus::kFailed;
    outcome_.message = e.what();
  }
  if (outcome_.success() && !solution_.x.allFinite()) {
    outcome_.status = QpStatus::kNumerical;
    outcome_.message =
        "reported " + (outcome_.message.empty() ? std::string("solved") : outcome_.message) +
        " without a finite x";
  }
  if (outcome_.success()) {
    previous_.x = solution_.x;
    previous_.has_y = solution_.has_y;
    previous_.has_z = solution_.has_z;
    previous_.has_z_box = solution_.has_z_box;
    if (solution_.has_y) previous_.y = solution_.y;
    if (solution_.has_z) previous_.z = solution_.z;
    if (solution_.has_z_box) previous_.z_box = solution_.z_box;
    has_previous_ = true;
  } else if (mode_ == SolveMode::kHot) {
    // the kept object's iterate is the failed one: the next call rebuilds it from the last
    // solution that succeeded
    drop_native();
  }
  outcome_.call = seconds_since(t_call);
  return outcome_;
}

}  // namespace wbcbench
