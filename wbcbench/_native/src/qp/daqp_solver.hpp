// DAQP called from C++: the mirror of wbcbench.qp.backends.daqp, which drives the same library
// through its Python binding (daqp.Model). The library is compiled into the module from the C
// sources of the daqp release the Python backend runs (see CMakeLists.txt), with that wheel's
// compiler flags.
//   * The QP goes to DAQP as the Python backend sends it:
//       min ½xᵀHx + gᵀx  s.t.  blower ≤ [I; M] x ≤ bupper,  M = [A; C],
//     the box first when there is one, then the equalities (flagged with sense 5, l = u = b),
//     then the inequalities.
//   * Modes: cold sets up a fresh workspace per solve; warm sets one up from the previous x
//     (daqp_primal_init_active derives the initial active set from it, then
//     daqp_set_primal_start); hot keeps the workspace and sends what changed through
//     daqp_update_ldp, starting from the previous working set (a new H or M keeps DAQP's own
//     sense array, as daqp.Model.update does).
//   * A hot result flagged optimal with a non-finite x is solved again on a fresh workspace,
//     once, and the message says so (the Python backend does the same).
//   * Status and message: the backend's table (_STATUS, _FLAG_TEXT). x and the multipliers
//     are reported when solved or at the iteration limit; DAQP's lam is already in the shared
//     sign convention and is split into z_box, y and z.
//   * Timing: setup is the copy of the data and DAQP's setup or update; wall the daqp_solve
//     call; internal DAQP's own solve_time.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "qp/solver.hpp"

namespace wbcbench {

// DAQP's settings as the Python handle passes them (name -> value, every one a number); the
// names are DAQPSettings' fields (daqp_setting_names()).
using DaqpOptions = std::map<std::string, double>;
const std::vector<std::string>& daqp_setting_names();

class DaqpSolver : public QpSolver {
 public:
  // Throws std::invalid_argument on an unknown setting name.
  DaqpSolver(SolveMode mode, const DaqpOptions& options);
  ~DaqpSolver() override;

 protected:
  void solve_fresh(const QpBuffers& qp, const Guess* guess, bool keep) override;
  void solve_update(const QpBuffers& qp, unsigned changed) override;
  void prepare_native(const QpBuffers& qp) override;
  void drop_native() override;
  bool has_native() const override;

 private:
  struct Impl;  // DAQP's workspace, problem and settings
  // the QP's data into DAQP's layout (every field, or those in `changed`)
  void load(const QpBuffers& qp, unsigned changed);
  // daqp_solve, then the outcome and the solution
  void call(const QpBuffers& qp, double setup_seconds);

  std::unique_ptr<Impl> impl_;
  // DAQP's data: H, f, M = [A; C] row-major, the bounds and the sense of every row
  RowMatrix H_, M_;
  Vector f_, bupper_, blower_, lam_;
  std::vector<int> sense_;
  bool solved_ = false;  // the kept workspace has been solved (its sense array is current)
};

}  // namespace wbcbench
