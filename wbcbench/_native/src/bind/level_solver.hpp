// The LevelSolver of every native hierarchy tick: the handles with a solver of their own
// (NativeSolvers) solve in C++, the others through a Python callable (controllers/native.py's
// LevelSolve) that solves a slot's QP through the registry's lean path.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>

#include "bind/bind.hpp"
#include "qp/hierarchy.hpp"
#include "qp/native_solvers.hpp"

namespace wbcbench {

// A LevelSolver over a Python callable fn(pool, handle, slot, reshaped, level) that solves the
// slot's QP and returns None (failed) or (x, z), z None when the backend gives no duals; the
// handles `natives` covers (when given) never reach it.
class PyLevelSolver : public LevelSolver {
 public:
  PyLevelSolver(nb::callable fn, NativeSolvers* natives) : fn_(std::move(fn)), natives_(natives) {}
  bool solve(int pool, int handle, int slot, bool reshaped, const std::string& level,
             const QpBuffers& qp, Vector& x, Vector& z, bool& has_z) override {
    if (natives_ != nullptr && natives_->covers(pool, handle))
      return natives_->solve(pool, handle, level, qp, x, z, has_z);
    nb::object answer = fn_(pool, handle, slot, reshaped, level);
    if (answer.is_none()) return false;
    nb::tuple pair = nb::cast<nb::tuple>(answer);
    x = nb::cast<Vector>(pair[0]);
    has_z = !pair[1].is_none();
    if (has_z) z = nb::cast<Vector>(pair[1]);
    return true;
  }

 private:
  nb::callable fn_;
  NativeSolvers* natives_;
};

// Slot i of a hierarchy, as a tick's `slot(i)` returns it (an IndexError past the last).
inline QpBuffers& slot_of(const Hierarchy& h, int i) {
  if (i < 0 || i >= h.n_slots()) throw nb::index_error("no such QP slot");
  return const_cast<QpBuffers&>(h.slot(i));
}

}  // namespace wbcbench
