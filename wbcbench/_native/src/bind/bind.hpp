// Declarations of the binding functions, one per part of the native tick.
#pragma once

#include <nanobind/nanobind.h>

namespace wbcbench {

namespace nb = nanobind;

// Results are returned as read-only NumPy views of an object's buffers (no copy): they hold
// until the object's next update.
constexpr auto kView = nb::rv_policy::reference_internal;

void bind_dynamics(nb::module_& m);
void bind_reduced(nb::module_& m);
void bind_controllers(nb::module_& m);
void bind_osf(nb::module_& m);
void bind_hierarchy(nb::module_& m);
void bind_rc_lqp(nb::module_& m);
void bind_solvers(nb::module_& m);
void bind_hls(nb::module_& m);
void bind_kin_hqp(nb::module_& m);

}  // namespace wbcbench
