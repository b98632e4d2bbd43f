// eiquadprog called from C++ as TSID calls it (tsid::solvers::SolverHQuadProgFast): the solver
// behind wbcbench.qp.backends.eiquadprog, whose Python handle solves through this class too (the
// library has no Python binding). The library is the eiquadprog wheel's libeiquadprog (1.3.x):
//   * one eiquadprog::solvers::EiquadprogFast per object, sized by reset(n, n_eq, n_rows) and
//     reset again only when a size changes (solve_quadprog resets itself on a new size);
//   * solve_quadprog(H, g, CE, ce0, CI, ci0, x) solves
//       min ½ xᵀHx + gᵀx  s.t.  CE x + ce0 = 0,  CI x + ci0 ≥ 0,
//     with CE = A, ce0 = −b, and one row of CI per finite side of l ≤ Cx ≤ u and lb ≤ x ≤ ub:
//     [−C[up]; C[lo]; −I[ub]; I[lb]], ci0 = [u[up]; −l[lo]; ub; −lb] (TSID writes two rows for
//     every inequality, an infinite side being a row that never binds; here, as in wbcbench's
//     quadprog backend, only the finite sides are rows);
//   * the status is the library's (EiquadprogFast_status), read as TSID reads it: optimal is
//     solved; unbounded (no step in primal or dual space: the constraints are infeasible) and
//     infeasible are infeasible; the iteration limit is max_iter; redundant (linearly dependent)
//     equalities are a failed solve. x and the duals are reported when solved: the library's
//     multipliers of its active set (Hx + g = CEᵀλ_E + CIᵀλ_I, λ_I ≥ 0) mapped to the shared
//     sign convention (y = −λ_E, z = λ_up − λ_lo, z_box likewise);
//   * iterations: the library's active-set iterations (getIteratios()).
// The library needs a positive definite H: its Cholesky factorisation (Eigen's LLT, whose
// failure it does not check) of a semidefinite H gives NaNs or a wrong x reported optimal. As
// wbcbench's quadprog backend does, a positive definite H is passed unchanged and any other is
// shifted to H + δI, δ = 1e-12 · max(1, max |H_ii|), multiplied by 100 until the factorisation
// succeeds (the message says so); TSID instead adds 1e-8 to every diagonal entry of every H.
// Modes: cold builds an object per solve; the library takes no initial guess (its warm start is
// compiled out), so warm runs as cold; hot keeps the object (and this class's copies of the
// data, updated with what changed), as TSID keeps one per solver. Every solve starts from the
// unconstrained minimum whatever the mode: hot saves the allocations only. (The library's
// supplied-factor path, is_inverse_provided_ with m_J = L⁻ᵀ, starts from +H⁻¹g instead of
// −H⁻¹g in 1.3.x, so the factor is not reused.)
// Timing: setup is the copy of the data and the positive-definiteness check, wall the
// solve_quadprog call; the library has no timer of its own (internal is NaN).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "qp/solver.hpp"

namespace eiquadprog {
namespace solvers {
class EiquadprogFast;
}  // namespace solvers
}  // namespace eiquadprog

namespace wbcbench {

// The settings the Python handle passes: {"max_iter": n} at most (the library's default: 1000).
using EiquadprogOptions = std::map<std::string, double>;

class EiquadprogSolver : public QpSolver {
 public:
  // Throws std::invalid_argument on a setting other than max_iter, or a negative max_iter.
  EiquadprogSolver(SolveMode mode, const EiquadprogOptions& options);
  ~EiquadprogSolver() override;

 protected:
  void solve_fresh(const QpBuffers& qp, const Guess* guess, bool keep) override;
  void solve_update(const QpBuffers& qp, unsigned changed) override;
  // the kept object's rows are those of the same finite sides
  bool can_update(const QpBuffers& qp) override;
  void drop_native() override;
  bool has_native() const override { return solver_ != nullptr; }

 private:
  // the finite sides of qp's inequalities and bounds (the rows of CI)
  void find_rows(const QpBuffers& qp);
  // the data of the fields in `changed` (QpField bits) into H_, g_, CE_, ce0_, CI_, ci0_
  void load(const QpBuffers& qp, unsigned changed);
  // H_ = H, shifted when it is not positive definite (delta_)
  void load_hessian(const QpBuffers& qp);
  // solve_quadprog, then the outcome and the solution
  void call(const QpBuffers& qp, double setup_seconds);

  int max_iter_ = -1;  // < 0: the library's default
  std::unique_ptr<eiquadprog::solvers::EiquadprogFast> solver_;
  // indices of the finite sides: upper and lower sides of C's rows, of the bounds
  std::vector<int> up_, lo_, ub_, lb_;
  Matrix H_, CE_, CI_;
  Vector g_, ce0_, ci0_, x_;
  double delta_ = 0.0;
  Eigen::LLT<Matrix> llt_;
};

}  // namespace wbcbench
