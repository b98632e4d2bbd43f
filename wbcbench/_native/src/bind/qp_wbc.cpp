// qp_wbc's tick (src/controllers/qp_wbc.hpp); wbcbench/controllers/qp_wbc.py holds its Python
// half.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "controllers/qp_wbc.hpp"

namespace wbcbench {

WBCBENCH_BIND(qp_wbc, kController, m) {
  nb::class_<QpWbcSettings>(m, "QpWbcSettings")
      .def(nb::init<>())
      .def_rw("eliminated", &QpWbcSettings::eliminated)
      .def_rw("row_weights", &QpWbcSettings::row_weights)
      .def_rw("acceleration_weight", &QpWbcSettings::acceleration_weight)
      .def_rw("torque_weight", &QpWbcSettings::torque_weight)
      .def_rw("wrench_weight", &QpWbcSettings::wrench_weight)
      .def_rw("tau_max", &QpWbcSettings::tau_max)
      .def_rw("Cw", &QpWbcSettings::Cw)
      .def_rw("lw", &QpWbcSettings::lw)
      .def_rw("uw", &QpWbcSettings::uw);

  nb::class_<QpWbcTick, Tick>(m, "QpWbcTick", "The weighted QP-WBC's tick.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"))
      .def("configure", &QpWbcTick::configure, nb::arg("settings"))
      .def("build", &QpWbcTick::build, nb::arg("q").noconvert(), nb::arg("v").noconvert(),
           nb::arg("t"), nb::call_guard<nb::gil_scoped_release>())
      .def("finish", &QpWbcTick::finish, nb::arg("x").noconvert(),
           nb::call_guard<nb::gil_scoped_release>())
      .def_prop_ro("qp", &QpWbcTick::qp, kView)
      .def_prop_ro("tau", &QpWbcTick::tau, kView)
      .def_prop_ro("qdd", &QpWbcTick::qdd, kView)
      .def_prop_ro("wrench", &QpWbcTick::wrench, kView);
}

}  // namespace wbcbench
