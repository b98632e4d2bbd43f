// What every file of src/bind/ shares. Each file binds one part of the native tick and
// registers itself with WBCBENCH_BIND; the module (src/bindings.cpp) binds every registered
// part, so a new file needs no edit anywhere else (CMake compiles every .cpp under src/).
#pragma once

#include <nanobind/nanobind.h>

namespace wbcbench {

namespace nb = nanobind;

// Results are returned as read-only NumPy views of an object's buffers (no copy): they hold
// until the object's next update.
constexpr auto kView = nb::rv_policy::reference_internal;

// The order parts are bound in: a class is bound after the class it derives from, so a part
// comes after the layers it builds on; within a layer, parts are bound in the order of their
// names.
enum class Layer {
  kCore,        // what every tick reads: dynamics, tasks, QP buffers, solvers, hierarchies
  kBase,        // a tick's base class that several controllers share (the OSF parameters)
  kController,  // one controller's tick and settings (src/controllers/<name>.hpp)
};

using BindFunction = void (*)(nb::module_&);

// Adds a part to the module's list (called by WBCBENCH_BIND when the module is loaded); a name
// must be unique.
bool register_binding(const char* name, Layer layer, BindFunction bind);

}  // namespace wbcbench

// WBCBENCH_BIND(name, layer, m) { ... } defines the function that binds the part `name` into the
// module m, and registers it at `layer` (kCore, kBase or kController). A controller's part is
// named after the controller (bind/qp_wbc.cpp: WBCBENCH_BIND(qp_wbc, kController, m)).
#define WBCBENCH_BIND(name, layer, m)                                                      \
  static void wbcbench_bind_##name(::wbcbench::nb::module_& m);                            \
  [[maybe_unused]] static const bool wbcbench_registered_##name =                          \
      ::wbcbench::register_binding(#name, ::wbcbench::Layer::layer, &wbcbench_bind_##name); \
  static void wbcbench_bind_##name(::wbcbench::nb::module_& m)
