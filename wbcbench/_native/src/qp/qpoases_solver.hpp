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
// The profile `libdwbc_task` / `libdwbc_wrench` is the named setting qpoases_libdwbc instead:
// qpOASES as the OSF-HQP authors' library (libdwbc, CQuadraticProgram::SolveQPoases) runs it:
//   * always one SQProblem(n, n_eq + n_in) per QP, kept between calls with its working set
//     (rebuilt only when a size changes); Options::setToMPC() for a task QP, setToReliable()
//     for the contact-wrench QP, printLevel none; no box bounds passed when the QP has none;
//   * nWSR capped at 1000 (task) / 300 (wrench) working-set changes per call;
//   * the first call is init, every later one a hotstart from the kept working set: the
//     matrix hotstart when H or [A; C] changed since the last call, else the vector hotstart
//     (qpOASES keeps its factorisations);
//   * the first init alone starts the (absent) box bounds inactive, where setToReliable()
//     starts them at their lower bounds: that homotopy cycles on the contact-wrench QP
//     (docs/qpoases.md); the object then runs libdwbc's options from its first hotstart on;
//   * a failed hotstart is followed, in the same call, by a fresh SQProblem with
//     setToReliable() and ten times the nWSR cap, initialised from scratch (libdwbc's fallback).
// Option names of qpOASES' Options (a number each: enableRamping, terminationTolerance, ...)
// may override a profile's settings (the measurements of docs/qpoases.md).
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
class Options;
class QProblemB;
class SQProblem;
}  // namespace qpOASES

namespace wbcbench {

// The settings the Python handle passes (its tier caps: {"CPUtime": seconds}), and any of the
// qpOASES Options fields by name.
using QpOasesOptions = std::map<std::string, double>;

// How the object is used: as CasADi does, or as libdwbc does for a task / contact-wrench QP.
enum class QpOasesProfile { kCasadi, kLibdwbcTask, kLibdwbcWrench };
QpOasesProfile qpoases_profile(const std::string& name);

class QpOasesSolver : public QpSolver {
 public:
  // Throws std::invalid_argument on an unknown setting name (the Python handle then solves
  // through CasADi itself).
  QpOasesSolver(SolveMode mode, const QpOasesOptions& options,
                QpOasesProfile profile = QpOasesProfile::kCasadi);
  // what the last call did: "init", "hotstart", "hotstart_matrices" or "reinit" (libdwbc's
  // fallback after a failed hotstart)
  const std::string& last_call() const { return last_call_; }
  // the qpOASES Options a new object of this solver gets (a reinit's: setToReliable), by field
  // name (booleans 0 / 1; initialStatusBounds -1 lower, 0 inactive, 1 upper); a libdwbc
  // profile's first init differs in initialStatusBounds only (inactive)
  QpOasesOptions settings() const;
  // the working-set changes of the last call (nWSR on return, both calls' on a reinit)
  int last_nwsr() const { return last_nwsr_; }
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
  void call(const QpBuffers& qp, double setup_seconds, unsigned changed);
  // the qpOASES options of the profile (setToReliable() when `reliable`, for the wrench QP and
  // libdwbc's fallback) with this object's overrides; `first_init`: a libdwbc profile's first
  // init, which starts the bounds inactive
  qpOASES::Options make_options(bool reliable, bool first_init = false) const;
  void set_options(bool reliable, bool first_init = false);
  bool libdwbc() const { return profile_ != QpOasesProfile::kCasadi; }

  QpOasesProfile profile_;
  QpOasesOptions overrides_;
  std::string last_call_;
  int last_nwsr_ = 0;

  std::unique_ptr<qpOASES::QProblemB> problem_;
  qpOASES::SQProblem* sq_ = nullptr;  // problem_ when it has constraint rows
  bool called_once_ = false;
  int n_ = 0, n_eq_ = 0, n_in_ = 0;
  // qpOASES keeps pointers to H and A between calls: these live as long as the object
  std::vector<double> h_, a_, g_, lbx_, ubx_, lba_, uba_, dual_;
};

}  // namespace wbcbench
