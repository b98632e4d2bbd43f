// Lexicographic (prioritised) least squares over one decision vector: the native mirror of
// wbcbench/qp/hierarchy.py, strategies cascade, nullspace and weighted, with the same shortcuts
// (merged finals, levels held hard when feasible, slack-free first tries, widened carried
// bounds, proximal retry). The module docstring there states the mathematics; the functions
// here keep its names, so the two read side by side.
//
// The level QPs are assembled into buffers this object owns ("slots") and handed to a solver
// through LevelSolver, which the Python side implements with the registry's backends (the lean
// path): every backend works with the native hierarchy.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "qp/buffers.hpp"

namespace wbcbench {

// Hard constraints (hold at every level): A x = b, l ≤ C x ≤ u, lb ≤ x ≤ ub (no box: size 0).
struct HardConstraints {
  Matrix A, C;
  Vector b, l, u, lb, ub;
  int n() const { return static_cast<int>(A.cols()); }
  bool has_box() const { return lb.size() > 0; }
};

// One soft level: minimise ‖A x − b‖² + ‖v‖² with l ≤ C x − v ≤ u. Finals are levels with
// no inequalities.
struct PriorityLevel {
  std::string name;
  Matrix A, C;
  Vector b, l, u;
  double weight = 1.0;
  // null-space strategy: held as hard constraints inside the next level's QP when that QP is
  // feasible with them hard (their optimal slacks are then zero)
  bool hard_if_feasible = false;
};

// Optimal slacks of one level: w = A x − b, v = its inequalities' violation.
struct LevelResult {
  std::string name;
  Vector w, v;
};

struct HierarchyResult {
  Vector x;
  bool ok = false;
  std::string failed_level;  // the level whose QP failed ("" if none)
  // why the failed level's answer was refused although the backend reported it solved ("" when
  // the backend itself failed)
  std::string message;
  std::vector<LevelResult> levels;
  int retries = 0;  // levels re-solved with the proximal term
};

enum class Strategy { kCascade, kNullspace, kWeighted };

struct HierarchyOptions {
  Strategy strategy = Strategy::kCascade;
  double prox = 0.0;
  bool merge_finals = false;
  bool slack_free_first = false;
  // solver handles the caller holds: one per level then per final; with slack_free_first and
  // twice as many, the second half solves the slack QPs (as in the Python reference)
  int handles = 0;
  // how far (relative to 1 + |bound|) a level's answer may lie outside the bounds its QP held
  // hard: ACCEPT_FACTOR × the accuracy of the handles' tier (accept_tol in
  // wbcbench/qp/hierarchy.py; this default is the default tier's of most backends)
  double accept_tol = 1e-5;
};

// Solves the QP of a slot with one of the caller's solver handles.
class LevelSolver {
 public:
  virtual ~LevelSolver() = default;
  // Solve qp (slot `slot`, whose buffers were re-made when `reshaped`) with handle `handle`
  // for level `level`; `pool` names the Hierarchy (a controller may have several, each with its
  // own handles). On success fill x (primal) and z (the duals of C's rows, has_z false
  // when the backend gives none) and return true.
  virtual bool solve(int pool, int handle, int slot, bool reshaped, const std::string& level,
                     const QpBuffers& qp, Vector& x, Vector& z, bool& has_z) = 0;
};

class Hierarchy {
 public:
  // the finals merged into a level's cost (pointers into the caller's levels: no copies)
  using Merged = std::vector<const PriorityLevel*>;

  explicit Hierarchy(int pool = 0) : pool_(pool) {}
  Hierarchy(const Hierarchy&) = delete;  // owns the buffers the Python views read
  Hierarchy& operator=(const Hierarchy&) = delete;
  // soft: the levels, then the finals (as levels with no inequalities): n_finals of them
  HierarchyResult solve(const HardConstraints& hard, const std::vector<PriorityLevel>& soft,
                        int n_finals, const HierarchyOptions& options, LevelSolver& solver);

  int n_slots() const { return static_cast<int>(slots_.size()); }
  const QpBuffers& slot(int i) const { return *slots_.at(i); }
  // seconds spent inside LevelSolver::solve during the last solve() (the rest is assembly)
  double solver_seconds() const { return solver_seconds_; }

 private:
  struct Answer {
    bool solved = false;    // a QP was solved (false: nothing to solve, x is given)
    bool success = false;   // the backend solved it
    bool accepted = false;  // x is the level's optimum (a slack-free try may be refused)
    Vector x;               // the level's optimum over the hierarchy's variable
    Vector qp_x, z;         // the QP's primal solution and the duals of its C rows
    bool has_z = false;
    std::string refusal;    // why a reported solution was refused (see check)
  };
  // the slot a QP of handle `handle` is assembled into: kind 0 the level's own QP, 1 the QP of
  // a level held hard inside the next one's (same handle, another structure)
  QpBuffers& prepare(int handle, int kind, int n, int n_eq, int n_in, bool box);
  Answer call(LevelSolver& solver, const std::string& level);
  // the largest relative violation x leaves on the hard constraints and the held inequalities
  double held_violation(const HardConstraints& hard, const Vector& x) const;
  // whether x, the answer of a QP whose held bounds were widened by relax, meets them to
  // accept_tol_ relative to the problem's scale; if not, a is marked failed with the reason
  // (see _checked)
  bool check(const HardConstraints& hard, const Vector& x, double relax, Answer& a) const;

  HierarchyResult solve_weighted(const HardConstraints& hard,
                                 const std::vector<PriorityLevel>& soft, LevelSolver& solver);
  // soft[0, n_levels) are solved in turn; the rest (finals) are merged into the last one's cost
  HierarchyResult solve_sequential(const HardConstraints& hard,
                                   const std::vector<PriorityLevel>& soft, int n_levels,
                                   int n_handles, bool nullspace, double prox,
                                   bool slack_free_first, LevelSolver& solver);
  // the cascade's level QP over z = (x, w, v) (see _cascade_level)
  Answer cascade_level(const HardConstraints& hard, const PriorityLevel& lv, const Matrix& E,
                       const Vector& e, int handle, double relax, const Vector& center,
                       double prox, const Merged& merged, bool hard_own,
                       LevelSolver& solver);
  // the null-space method's level QP over (y, v), x = x_p + Z y (see _nullspace_level)
  Answer nullspace_level(const HardConstraints& hard, const PriorityLevel& lv, const Vector& x_p,
                         const Matrix& Z, int handle, int kind, double relax,
                         double prox, const Merged& merged, bool hard_own,
                         LevelSolver& solver);

  int pool_;
  std::vector<std::unique_ptr<QpBuffers>> slots_;
  int handle_ = -1, slot_ = -1;  // what prepare() filled last
  bool reshaped_ = false;        // whether prepare() re-made it
  double solver_seconds_ = 0.0;
  double accept_tol_ = 1e-5;  // of the solve in progress (HierarchyOptions::accept_tol)
  // the inequalities the levels solved so far pass on, their slacks fixed (prev_C, prev_lo,
  // prev_hi of the reference)
  std::vector<Matrix> prev_C_;
  std::vector<Vector> prev_lo_, prev_hi_;
};

// Orthonormal bases (R (rank, n), Z (n, n − rank)) of the row space and null space of E (p, n),
// from a column-pivoted Householder QR of Eᵀ; rank counts |R_ii| > tol · max(1, |R_00|).
void row_space_and_null_space(const Matrix& E, Matrix& R, Matrix& Z, double tol = 1e-10);
// The same, forming only the bases asked for (nullptr: not needed).
void row_space_and_null_space(const Matrix& E, Matrix* R, Matrix* Z, double tol = 1e-10);

}  // namespace wbcbench
