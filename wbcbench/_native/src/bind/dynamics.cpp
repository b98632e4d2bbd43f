#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "dynamics/state.hpp"

namespace wbcbench {

WBCBENCH_BIND(dynamics, kCore, m) {
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
      .def_prop_ro("contact_frames", &RobotDynamics::contact_frames)
      .def_prop_ro("M", &RobotDynamics::M, kView)
      .def_prop_ro("Minv", &RobotDynamics::Minv, kView)
      .def_prop_ro("h", &RobotDynamics::h, kView)
      .def_prop_ro("g", &RobotDynamics::g, kView)
      .def_prop_ro("com", &RobotDynamics::com, kView)
      .def_prop_ro("J_com", &RobotDynamics::J_com, kView)
      .def_prop_ro("com_drift", &RobotDynamics::com_drift, kView)
      .def_prop_ro("cmm", &RobotDynamics::cmm, kView)
      .def("task_jacobian", &RobotDynamics::task_jacobian, nb::arg("i"), kView)
      .def("task_drift", &RobotDynamics::task_drift, nb::arg("i"), kView)
      .def("task_position", &RobotDynamics::task_position, nb::arg("i"), kView)
      .def("task_rotation", &RobotDynamics::task_rotation, nb::arg("i"), kView)
      .def_prop_ro("contact_jacobian", &RobotDynamics::contact_jacobian, kView)
      .def_prop_ro("contact_drift", &RobotDynamics::contact_drift, kView);
}

}  // namespace wbcbench
