// to_osf's tick (src/controllers/to_osf.hpp); wbcbench/controllers/to_osf.py holds its Python
// half.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "controllers/to_osf.hpp"

namespace wbcbench {

WBCBENCH_BIND(to_osf, kController, m) {
  nb::class_<ToOsfSettings, OsfSettings>(m, "ToOsfSettings")
      .def(nb::init<>())
      .def_rw("row_weights", &ToOsfSettings::row_weights)
      .def_rw("wrench_weight", &ToOsfSettings::wrench_weight)
      .def_rw("wrench_total", &ToOsfSettings::wrench_total)
      .def_rw("regularization", &ToOsfSettings::regularization)
      .def_rw("Sf", &ToOsfSettings::Sf)
      .def_rw("internal_basis", &ToOsfSettings::internal_basis);

  nb::class_<ToOsfTick, OsfTick>(m, "ToOsfTick", "The task-oriented OSF's tick.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"))
      .def("configure", &ToOsfTick::configure, nb::arg("settings"))
      .def("build", &ToOsfTick::build, nb::arg("q").noconvert(), nb::arg("v").noconvert(),
           nb::arg("t"), nb::call_guard<nb::gil_scoped_release>())
      .def("finish", &ToOsfTick::finish, nb::arg("x").noconvert(),
           nb::call_guard<nb::gil_scoped_release>())
      .def_prop_ro("qp", &ToOsfTick::qp, kView)
      .def_prop_ro("rho", &ToOsfTick::rho, kView);
}

}  // namespace wbcbench
