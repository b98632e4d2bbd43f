// The binding layer: conversion and ownership only, no mathematics.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "dynamics/state.hpp"

namespace nb = nanobind;
using wbcbench::RobotDynamics;

NB_MODULE(_core, m) {
  m.doc() = "wbcbench's native real-time tick (C++17, Eigen, Pinocchio)";
  m.attr("compiler") = WBCBENCH_COMPILER;
  m.attr("cxx_flags") = WBCBENCH_CXX_FLAGS;

  // Results are returned as read-only NumPy views of the object's buffers (no copy): they
  // hold until the next update().
  constexpr auto view = nb::rv_policy::reference_internal;
  nb::class_<RobotDynamics>(m, "RobotDynamics",
                            "Per-tick dynamics, the native mirror of RobotState.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"))
      .def("update", &RobotDynamics::update, nb::arg("q").noconvert(), nb::arg("v").noconvert(),
           nb::call_guard<nb::gil_scoped_release>(),
           "One Pinocchio pass at (q, v); returns its duration [s].")
      .def_prop_ro("nq", &RobotDynamics::nq)
      .def_prop_ro("nv", &RobotDynamics::nv)
      .def_prop_ro("mass", &RobotDynamics::mass)
      .def_prop_ro("joint_names", &RobotDynamics::joint_names)
      .def_prop_ro("M", &RobotDynamics::M, view)
      .def_prop_ro("Minv", &RobotDynamics::Minv, view)
      .def_prop_ro("h", &RobotDynamics::h, view)
      .def_prop_ro("g", &RobotDynamics::g, view)
      .def_prop_ro("com", &RobotDynamics::com, view)
      .def_prop_ro("J_com", &RobotDynamics::J_com, view)
      .def_prop_ro("com_drift", &RobotDynamics::com_drift, view)
      .def_prop_ro("cmm", &RobotDynamics::cmm, view)
      .def("task_jacobian", &RobotDynamics::task_jacobian, nb::arg("i"), view)
      .def("task_drift", &RobotDynamics::task_drift, nb::arg("i"), view)
      .def_prop_ro("contact_jacobian", &RobotDynamics::contact_jacobian, view)
      .def_prop_ro("contact_drift", &RobotDynamics::contact_drift, view);
}
