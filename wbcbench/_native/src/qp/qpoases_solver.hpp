// qpOASES called from C++: the mirror of wbcbench.qp.backends.qpoases, which runs qpOASES
// through CasADi's dense conic interface. The library is cmeel-qpoases' libqpOASES (3.2.2);
// this class does what CasADi's QpoasesInterface does with the options the Python backend
// passes (printLevel none, enableEqualities, error_on_fail off):
//   * one SQProblem(n, n_eq + n_in, HST_UNKNOWN) per object, a QProblemB(n) when there is no
//     constraint row; Options::setToDefault(), printLevel none, enableEqualities on;
//   * the first call on an object is init(H, g, [A; C], lb, ub, [b; l], [b; u]), every later
//     one the matrix hotstart (a QProblemB is reset and initialised again instead), with
//     nWSR = 5 (n + n_eq + n_in) reset before each call;
//   * the status is CasADi's: solved on SUCCESSFUL_RETURN, else wbcbench's reading of CasADi's
//     return_status text (the message); iterations = nWSR on return; the duals are the negated
//     qpOASES ones (the shared sign convention), x and duals reported when solved or max_iter;
//   * bounds that CasADi's input check rejects (lower > upper, lower = +inf, upper = -inf) are
//     a failed solve, as its exception is on the Python side.
// No time cap: the Python backend passes CPUtime, but CasADi's bundled qpOASES has no clock
// (its getCPUtime returns -1), so the cap never fires there; the option is accepted and not
// passed on, and neither side stops a long solve.
// Results equal CasADi's to round-off only: CasADi's qpOASES calls OpenBLAS' dgemm/dpotrf,
// cmeel's its own reference loops (bit-identical with the same BLAS).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "qp/solver.hpp"

namespace qpOASES {
class QProblemB;
class SQProblem;
}  // namespace qpOASES

namespace wbcbench {

// The settings the Python handle passes (its tier caps: {"CPUtime": seconds}).
using QpOasesOptions = std::map<std::string, double>;

class QpOasesSolver : public QpSolver {
 public:
  // Throws std::invalid_argument on a setting other than CPUtime (the Python handle then
  // solves through CasADi itself).
  QpOasesSolver(SolveMode mode, const QpOasesOptions& options);
  ~QpOasesSolver() override;

 protected:
  void solve_fresh(const QpBuffers& qp, const Guess* guess, bool keep) override;
  void solve_update(const QpBuffers& qp, unsigned changed) override;
  void drop_native() override;
  bool has_native() const override { return problem_ != nullptr; }

 private:
  // a new qpOASES object for qp's sizes (never called once)
  void build(const QpBuffers& qp);
  // CasADi's input check, then the data into the buffers qpOASES reads (H column-major, which
  // is H for a symmetric H; [A; C] row-major)
  void load(const QpBuffers& qp);
  // init or hotstart, then the outcome and the solution
  void call(const QpBuffers& qp, double setup_seconds);

  std::unique_ptr<qpOASES::QProblemB> problem_;
  qpOASES::SQProblem* sq_ = nullptr;  // problem_ when it has constraint rows
  bool called_once_ = false;
  int n_ = 0, n_eq_ = 0, n_in_ = 0;
  // qpOASES keeps pointers to H and A between calls: these live as long as the object
  std::vector<double> h_, a_, g_, lbx_, ubx_, lba_, uba_, dual_;
};

}  // namespace wbcbench
