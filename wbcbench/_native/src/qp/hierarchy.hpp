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
#include <Eigen/QR>
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
  // n_eq equality and n_in inequality rows over n variables, all zero, and no box
  void zero(Eigen::Index n_eq, Eigen::Index n_in, Eigen::Index n) {
    A.setZero(n_eq, n);
    b.setZero(n_eq);
    C.setZero(n_in, n);
    l.setZero(n_in);
    u.setZero(n_in);
    lb.resize(0);
    ub.resize(0);
  }
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

// Orthonormal bases of the row space and null space of E (p, n) and the minimum-norm solution
// of E x = b, from a column-pivoted Householder QR of Eᵀ held with its workspace: factor()
// computes in place, so that repeated calls of the same sizes allocate nothing.
class Bases {
 public:
  // Eᵀ P = Q R of rank r (|R_ii| > tol · max(1, |R_00|)); the row-space basis R = Q₁ᵀ (r, n)
  // (as its transpose Q₁) and the null-space basis Z = Q₂ (n, n − r) formed where asked for
  void factor(const Eigen::Ref<const Matrix>& E, bool want_R, bool want_Z,
              double tol = 1e-10);
  // after factor(E, ...): the minimum-norm solution of E x = b into x
  void min_norm(const Eigen::Ref<const Matrix>& E, const Eigen::Ref<const Vector>& b, Vector& x);
  int rank() const { return rank_; }
  const Matrix& Q1() const { return Q1_; }  // Rᵀ (n, r)
  const Matrix& Z() const { return Z_; }

 private:
  Eigen::ColPivHouseholderQR<Matrix> qr_;
  Eigen::CompleteOrthogonalDecomposition<Matrix> cod_;  // (a rank-deficient E only)
  Matrix Q1_, Z_;
  Vector work_, rhs_;
  int rank_ = 0;
  bool empty_ = true;  // E had no rows (or no columns)
};

class Hierarchy {
 public:
  // the finals merged into a level's cost (pointers into the caller's levels: no copies)
  using Merged = std::vector<const PriorityLevel*>;

  explicit Hierarchy(int pool = 0) : pool_(pool) {}
  Hierarchy(const Hierarchy&) = delete;  // owns the buffers the Python views read
  Hierarchy& operator=(const Hierarchy&) = delete;
  // soft: the levels, then the finals (as levels with no inequalities): n_finals of them.
  // The result is this object's, valid until the next solve. What a solve needs is kept per
  // shape of the problem (the sizes of the hard constraints and of every level): a solve of a
  // shape solved before, and whose level QPs keep their sizes, allocates nothing.
  const HierarchyResult& solve(const HardConstraints& hard,
                               const std::vector<PriorityLevel>& soft, int n_finals,
                               const HierarchyOptions& options, LevelSolver& solver);
  // the result of the last solve (empty before the first)
  const HierarchyResult& result() const;

  // the QP slots, one per (handle, kind, sizes) assembled so far, numbered in order
  int n_slots() const { return static_cast<int>(slots_.size()); }
  const QpBuffers& slot(int i) const { return slots_.at(i)->qp; }
  // seconds spent inside LevelSolver::solve during the last solve() (the rest is assembly)
  double solver_seconds() const { return solver_seconds_; }

 private:
  // one QP's buffers and the backend's answer to it (sized with it)
  struct Slot {
    int handle = 0, kind = 0, n = 0, n_eq = 0, n_in = 0;
    bool box = false;
    QpBuffers qp;
    Vector x, z;  // the QP's primal solution and the duals of its C rows
  };
  struct Answer {
    bool solved = false;    // a QP was solved (false: nothing to solve, x is given)
    bool success = false;   // the backend solved it
    bool accepted = false;  // x is the level's optimum (a slack-free try may be refused)
    const Vector* qp_x = nullptr;  // the slot's primal solution and duals of its C rows
    const Vector* z = nullptr;
    bool has_z = false;
    std::string refusal;    // why a reported solution was refused (see check)
  };
  // an inequality held for the levels below: the level's rows and its bounds
  struct Held {
    const Matrix* C = nullptr;  // the caller's level (it outlives the solve)
    Vector lo, hi;
  };
  // what one level needs, sized by the first solve of a shape and kept
  struct LevelWork {
    Matrix E, EQ, Ep;  // the held rows, their part the hard equalities fix, the rest
    Matrix AZ, Z;      // A Z of the level and the null space left after it
    // a level held hard inside the next one's QP: the null space Z_l left after it, and
    // A Z_l of the next level (kind 1's QP)
    Matrix pAZ, pZ;
    Vector e, x_l, y, rhs;
    Bases bases, pbases;
    // the proximal retry's projector
    Matrix stack, AZf, N, ZN, P;
    Bases fbases, nbases;
  };
  // what a solve of one shape needs (see solve)
  struct Workspace {
    std::vector<int> shape;
    std::vector<LevelWork> levels;
    Bases hard;  // of the hard equalities
    HierarchyResult result;
    int n_results = 0;  // entries of result.levels filled
    std::vector<Held> held;
    int n_held = 0;
    Vector x, x_p, a_x;  // the optimum so far, the particular solution, a level's answer
  };
  // the workspace of the shape of (hard, soft, options), made when new
  Workspace& workspace(const HardConstraints& hard, const std::vector<PriorityLevel>& soft,
                       const HierarchyOptions& options);
  // the slot a QP of handle `handle` is assembled into: kind 0 the level's own QP, 1 the QP of
  // a level held hard inside the next one's (same handle, another structure); one per size
  QpBuffers& prepare(int handle, int kind, int n, int n_eq, int n_in, bool box);
  void call(LevelSolver& solver, const std::string& level, Answer& a);
  // the largest relative violation x leaves on the hard constraints and the held inequalities
  double held_violation(const HardConstraints& hard, const Eigen::Ref<const Vector>& x);
  // whether x, the answer of a QP whose held bounds were widened by relax, meets them to
  // accept_tol_ relative to the problem's scale; if not, a is marked failed with the reason
  // (see _checked)
  bool check(const HardConstraints& hard, const Eigen::Ref<const Vector>& x, double relax,
             Answer& a);

  void solve_weighted(const HardConstraints& hard, const std::vector<PriorityLevel>& soft,
                      LevelSolver& solver);
  // soft[0, n_levels) are solved in turn; the rest (finals) are merged into the last one's cost
  void solve_sequential(const HardConstraints& hard, const std::vector<PriorityLevel>& soft,
                        int n_levels, int n_handles, bool nullspace, double prox,
                        bool slack_free_first, LevelSolver& solver);
  // the cascade's level QP over z = (x, w, v) (see _cascade_level); the held equalities
  // E x = e given as Eᵀ (n, p)
  void cascade_level(const HardConstraints& hard, const PriorityLevel& lv, const Matrix& Et,
                     const Vector& e, LevelWork& w, int handle, double relax,
                     const Vector& center, double prox, const Merged& merged, bool hard_own,
                     LevelSolver& solver, Answer& a);
  // the null-space method's level QP over (y, v), x = x_p + Z y (see _nullspace_level)
  void nullspace_level(const HardConstraints& hard, const PriorityLevel& lv, const Vector& x_p,
                       const Matrix& Z, LevelWork& w, int handle, int kind, double relax,
                       double prox, const Merged& merged, bool hard_own, LevelSolver& solver,
                       Answer& a);
  // the finals merged into a level's cost: H += w FᵀF, g −= w Fᵀ f over x (Z null), or over
  // y with x = x_p + Z y
  void add_merged(Eigen::Ref<RowMatrix> H, Eigen::Ref<Vector> g, const Merged& merged,
                  const Matrix* Z, const Vector* x_p);
  // the slacks of level lv at x into the result's next entry
  void add_result(const PriorityLevel& lv, const Vector& x);
  // hold a level's inequalities for the levels below: rows C, bounds [lo, hi] (+ shift)
  void hold(const Matrix& C, const Vector& lo, const Vector& hi, const Vector* shift);

  int pool_;
  std::vector<std::unique_ptr<Slot>> slots_;
  Slot* current_ = nullptr;      // what prepare() filled last
  int slot_ = -1;
  bool reshaped_ = false;        // whether prepare() made it
  double solver_seconds_ = 0.0;
  double accept_tol_ = 1e-5;  // of the solve in progress (HierarchyOptions::accept_tol)
  std::vector<std::unique_ptr<Workspace>> spaces_;
  Workspace* ws_ = nullptr;  // the solve's
  Answer answer_;
  Merged merged_;
  const Merged none_;
  std::vector<const Matrix*> held_rows_;  // equalities held so far, the hard ones excluded
  std::vector<Eigen::Index> box_rows_;
  Matrix fz_;  // F Z of a merged final (grown, never shrunk)
  Vector cx_;  // C x of one block of rows (grown, never shrunk)
};

// Orthonormal bases (R (rank, n), Z (n, n − rank)) of the row space and null space of E (p, n),
// from a column-pivoted Householder QR of Eᵀ; rank counts |R_ii| > tol · max(1, |R_00|).
void row_space_and_null_space(const Matrix& E, Matrix& R, Matrix& Z, double tol = 1e-10);
// The same, forming only the bases asked for (nullptr: not needed).
void row_space_and_null_space(const Matrix& E, Matrix* R, Matrix* Z, double tol = 1e-10);

}  // namespace wbcbench
