#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "controllers/osf.hpp"

namespace wbcbench {

void bind_osf(nb::module_& m) {
  nb::class_<OsfSettings>(m, "OsfSettings", "What both OSF ticks take once.")
      .def(nb::init<>())
      .def_rw("level_dims", &OsfSettings::level_dims)
      .def_rw("force_level", &OsfSettings::force_level)
      .def_rw("inverse", &OsfSettings::inverse)
      .def_rw("exact", &OsfSettings::exact)
      .def_rw("rcond", &OsfSettings::rcond)
      .def_rw("period", &OsfSettings::period)
      .def_rw("asynchronous", &OsfSettings::asynchronous)
      .def_rw("tau_max", &OsfSettings::tau_max)
      .def_rw("Cw", &OsfSettings::Cw)
      .def_rw("lw", &OsfSettings::lw)
      .def_rw("uw", &OsfSettings::uw)
      .def_rw("acc_bound", &OsfSettings::acc_bound);

  nb::class_<ToOsfSettings, OsfSettings>(m, "ToOsfSettings")
      .def(nb::init<>())
      .def_rw("row_weights", &ToOsfSettings::row_weights)
      .def_rw("wrench_weight", &ToOsfSettings::wrench_weight)
      .def_rw("wrench_total", &ToOsfSettings::wrench_total)
      .def_rw("regularization", &ToOsfSettings::regularization)
      .def_rw("Sf", &ToOsfSettings::Sf);

  nb::class_<OsfHqpSettings, OsfSettings>(m, "OsfHqpSettings")
      .def(nb::init<>())
      .def_rw("regularization", &OsfHqpSettings::regularization)
      .def_rw("carry_tolerance", &OsfHqpSettings::carry_tolerance)
      .def_rw("WtW", &OsfHqpSettings::WtW);

  nb::class_<OsfTick, Tick>(m, "OsfTick", "The operational-space parameters of a tick.")
      .def_prop_ro("staleness", &OsfTick::staleness)
      .def_prop_ro("params_time", [](const OsfTick& t) { return t.times().params; })
      .def_prop_ro("params_compute_time",
                   [](const OsfTick& t) { return t.params().compute_time; })
      .def_prop_ro("message", &OsfTick::message)
      .def_prop_ro("worker_sets", &OsfTick::worker_sets)
      .def("close", &OsfTick::close, "Stop the parameter worker thread (params: async).",
           nb::call_guard<nb::gil_scoped_release>())
      .def_prop_ro("partial", &OsfTick::partial, kView)
      .def_prop_ro("tau", &OsfTick::tau, kView)
      .def_prop_ro("qdd", &OsfTick::qdd, kView)
      .def_prop_ro("wrench", &OsfTick::wrench, kView);

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
