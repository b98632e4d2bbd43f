// What both OSF ticks share (src/controllers/osf.hpp): their settings' common part and the
// operational-space parameters of a tick.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "controllers/osf.hpp"

namespace wbcbench {

WBCBENCH_BIND(osf, kBase, m) {
  nb::class_<OsfSettings>(m, "OsfSettings", "What both OSF ticks take once.")
      .def(nb::init<>())
      .def_rw("tasks", &OsfSettings::tasks)
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

  nb::class_<OsfTick, Tick>(m, "OsfTick", "The operational-space parameters of a tick.")
      .def_prop_ro("staleness", &OsfTick::staleness)
      .def_prop_ro("params_time", [](const OsfTick& t) { return t.times().params; })
      .def_prop_ro("params_compute_time",
                   [](const OsfTick& t) { return t.params().compute_time; })
      .def_prop_ro("message", &OsfTick::message)
      .def_prop_ro("worker_sets", &OsfTick::worker_sets)
      .def("close", &OsfTick::close, "Stop the parameter worker threads (params: async).",
           nb::call_guard<nb::gil_scoped_release>())
      .def("prepare", &OsfTick::prepare, nb::arg("q").noconvert(), nb::arg("v").noconvert(),
           nb::arg("t"),
           "Size the held contact set's parameters at (q, v, t) (after configure; the result is "
           "dropped), so that a change to the set allocates nothing in the tick",
           nb::call_guard<nb::gil_scoped_release>())
      .def_prop_ro("partial", &OsfTick::partial, kView)
      .def_prop_ro("tau", &OsfTick::tau, kView)
      .def_prop_ro("qdd", &OsfTick::qdd, kView)
      .def_prop_ro("wrench", &OsfTick::wrench, kView)
      .def_prop_ro("level_ref", &OsfTick::level_ref, kView);
}

}  // namespace wbcbench
