// OSQP (v1 C API) called from C++: the mirror of wbcbench.qp.backends.osqp (and of its named
// setting osqp_libdwbc, which sends every field on every update). The library is the OSQP the
// Python backend runs (C OSQP 1.0.0), linked from the casadi wheel's static build.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <osqp.h>

#include "qp/solver.hpp"

namespace wbcbench {

// OSQP's settings as the Python handle passes them (name -> value, every one a number); the
// names are the OSQPSettings fields (osqp_setting_names()).
using OsqpOptions = std::map<std::string, double>;
const std::vector<std::string>& osqp_setting_names();

class OsqpSolver : public QpSolver {
 public:
  // send_all: every in-place update sends q, l, u, P and A whether they changed or not
  // (osqp_libdwbc); else only what changed (osqp). Throws std::invalid_argument on an unknown
  // setting name.
  OsqpSolver(SolveMode mode, const OsqpOptions& options, bool send_all);
  ~OsqpSolver() override;

 protected:
  void solve_fresh(const QpBuffers& qp, const Guess* guess, bool keep) override;
  void solve_update(const QpBuffers& qp, unsigned changed) override;
  bool can_update(const QpBuffers& qp) override;
  void drop_native() override;
  bool has_native() const override { return solver_ != nullptr; }

 private:
  // a fixed sparsity pattern in CSC order (wbcbench.qp.backends._common.pattern_csc)
  struct Pattern {
    int rows = 0, cols = 0;
    std::vector<OSQPInt> p, i;  // column pointers, row indices
    std::vector<double> x;        // values
  };
  // M = [A; C; I (with a box)], lo, hi (the backend's _stack), bounds clipped to ±OSQP_INFTY
  void stack(const QpBuffers& qp);
  double stacked(const QpBuffers& qp, int row, int col) const;
  void make_patterns(const QpBuffers& qp);
  void fill_values(const QpBuffers& qp);
  bool fits(const QpBuffers& qp) const;
  void solve_and_read(const QpBuffers& qp, double setup_seconds);

  OsqpOptions options_;
  bool send_all_;
  OSQPSolver* solver_ = nullptr;
  Pattern P_, M_;
  Vector lo_, hi_, y_guess_;
};

}  // namespace wbcbench
