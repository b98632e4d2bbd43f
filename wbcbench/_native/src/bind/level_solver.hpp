// The LevelSolver of every native hierarchy tick: a Python callable (controllers/native.py's
// LevelSolve) that solves a slot's QP through the registry's lean path.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>

#include "bind/bind.hpp"
#include "qp/hierarchy.hpp"

namespace wbcbench {

// A LevelSolver over a Python callable fn(pool, handle, slot, reshaped, level) that solves the
// slot's QP and returns None (failed) or (x, z), z None when the backend gives no duals.
class PyLevelSolver : public LevelSolver {
 public:
  explicit PyLevelSolver(nb::callable fn) : fn_(std::move(fn)) {}
  bool solve(int pool, int handle, int slot, bool reshaped, const std::string& level,
             const QpBuffers& /*qp*/, Vector& x, Vector& z, bool& has_z) override {
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
};

}  // namespace wbcbench
