// A QP solver called from C++: the mirror of wbcbench.qp.base.QPSolver's lean path (the one
// native ticks take), for the backends whose library the module links. A tick whose level QPs
// go to one of these never leaves C++ for a solve.
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include "qp/buffers.hpp"
#include "types.hpp"

namespace wbcbench {

// wbcbench.qp.SolutionStatus
enum class QpStatus { kSolved, kInfeasible, kMaxIter, kNumerical, kFailed };
const char* status_name(QpStatus status);

// wbcbench.qp.settings.MODES: cold (a fresh object, no guess), warm (a fresh object started
// from the previous solution), hot (one object kept and updated in place)
enum class SolveMode { kCold, kWarm, kHot };

// What wbcbench.qp.Solution reports of one solve (times in seconds).
struct QpOutcome {
  QpStatus status = QpStatus::kFailed;
  int iterations = -1;  // < 0: not reported
  double setup = 0.0;   // building or updating the native object
  double wall = 0.0;    // the native solve call
  double internal = std::numeric_limits<double>::quiet_NaN();  // the solver's own timer
  double call = 0.0;    // the whole solve() (what a controller pays)
  bool rebuilt = false; // hot: the object was (re)built on this call
  std::string message;
  bool success() const { return status == QpStatus::kSolved; }
};

// The solution, duals in the shared sign convention (wbcbench.qp.solution.Solution).
struct QpSolution {
  Vector x, y, z, z_box;
  bool has_y = false, has_z = false, has_z_box = false;
};

// Bit per field of QpBuffers an in-place update may change (wbcbench.qp.base.DATA_FIELDS).
enum QpField : unsigned {
  kFieldH = 1u << 0,
  kFieldG = 1u << 1,
  kFieldA = 1u << 2,
  kFieldB = 1u << 3,
  kFieldC = 1u << 4,
  kFieldL = 1u << 5,
  kFieldU = 1u << 6,
  kFieldLb = 1u << 7,
  kFieldUb = 1u << 8,
  kAllFields = (1u << 9) - 1,
};

class QpSolver {
 public:
  explicit QpSolver(SolveMode mode) : mode_(mode) {}
  virtual ~QpSolver() = default;
  QpSolver(const QpSolver&) = delete;
  QpSolver& operator=(const QpSolver&) = delete;

  // QPSolver.solve(problem, lean=True): solve qp in the handle's mode; the answer is in
  // solution() when the outcome is a success. Never throws: a backend error is a failed outcome.
  const QpOutcome& solve(const QpBuffers& qp);
  const QpSolution& solution() const { return solution_; }
  const QpOutcome& outcome() const { return outcome_; }
  SolveMode mode() const { return mode_; }
  // native objects built by a hot solve (QPSolver.builds)
  int builds() const { return builds_; }
  // QPSolver.reset
  void reset();
  // Set-up: size the buffers that solves of QPs shaped as qp use (the solution, the previous
  // one, the hot snapshot, the backend's copies of the data), so that the first solve
  // allocates only inside the backend's library. Keeps no data: the first solve is cold.
  void prepare(const QpBuffers& qp);

 protected:
  // an initial guess: pointers to the previous solution's parts (null when absent)
  struct Guess {
    const Vector* x = nullptr;
    const Vector* y = nullptr;
    const Vector* z = nullptr;
    const Vector* z_box = nullptr;
  };
  // build a native object for qp and solve it; keep the object when `keep` (hot)
  virtual void solve_fresh(const QpBuffers& qp, const Guess* guess, bool keep) = 0;
  // update the kept object with the fields in `changed` (QpField bits) and solve
  virtual void solve_update(const QpBuffers& qp, unsigned changed) = 0;
  // an extra test before an in-place update (e.g. a sparsity pattern still fits)
  virtual bool can_update(const QpBuffers& qp) { return true; }
  // prepare(): size the backend's own copies of qp's data (nothing by default)
  virtual void prepare_native(const QpBuffers& qp) {}
  // forget the kept native object
  virtual void drop_native() = 0;
  virtual bool has_native() const = 0;
  // the initial guess a warm or hot solve of qp starts from: the previous solution, with its
  // duals where their shapes fit (false in cold mode or when there is none)
  bool guess_from_previous(const QpBuffers& qp, Guess& guess) const;

  QpOutcome outcome_;
  QpSolution solution_;

 private:
  unsigned changed_fields(const QpBuffers& qp) const;

  SolveMode mode_;
  int builds_ = 0;
  // the previous successful solution (QPSolver.previous)
  QpSolution previous_;
  bool has_previous_ = false;
  // the data of the last hot call, to find what changed (QPSolver._last), and its structure
  QpBuffers last_;
  bool has_last_ = false;
};

}  // namespace wbcbench
