// osf_hqp's tick (src/controllers/osf_hqp.hpp); wbcbench/controllers/osf_hqp.py holds its Python
// half.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "controllers/osf_hqp.hpp"

namespace wbcbench {

WBCBENCH_BIND(osf_hqp, kController, m) {
  nb::class_<OsfHqpSettings, OsfSettings>(m, "OsfHqpSettings")
      .def(nb::init<>())
      .def_rw("regularization", &OsfHqpSettings::regularization)
      .def_rw("carry_tolerance", &OsfHqpSettings::carry_tolerance)
      .def_rw("WtW", &OsfHqpSettings::WtW)
      .def_rw("distribution", &OsfHqpSettings::distribution);

  nb::class_<OsfHqpTick, OsfTick>(m, "OsfHqpTick", "The OSF-HQP's tick.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"))
      .def("configure", &OsfHqpTick::configure, nb::arg("settings"))
      .def("build", &OsfHqpTick::build, nb::arg("q").noconvert(), nb::arg("v").noconvert(),
           nb::arg("t"), nb::call_guard<nb::gil_scoped_release>())
      .def("level", &OsfHqpTick::level, nb::arg("i"), nb::arg("x").noconvert(),
           nb::call_guard<nb::gil_scoped_release>())
      .def("finish", &OsfHqpTick::finish, nb::arg("x").noconvert(),
           nb::call_guard<nb::gil_scoped_release>())
      .def_prop_ro("n_qps", &OsfHqpTick::n_qps)
      .def("qp", &OsfHqpTick::qp, nb::arg("i"), kView)
      .def_prop_ro("slack_norms", &OsfHqpTick::slack_norms, kView);
}

}  // namespace wbcbench
