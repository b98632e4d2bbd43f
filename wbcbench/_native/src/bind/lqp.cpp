// lqp's tick (src/controllers/lqp.hpp) and the settings both lexicographic QPs take (lqp and
// rc_lqp); wbcbench/controllers/lqp.py holds their Python half.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "bind/level_solver.hpp"
#include "controllers/lqp.hpp"

namespace wbcbench {

WBCBENCH_BIND(lqp, kController, m) {
  using ConstVec = Eigen::Ref<const Vector>;

  nb::class_<LexicographicSettings>(m, "LexicographicSettings")
      .def(nb::init<>())
      .def_rw("strategy", &LexicographicSettings::strategy)
      .def_rw("qdd_limit", &LexicographicSettings::qdd_limit)
      .def_rw("wrench_regularization", &LexicographicSettings::wrench_regularization)
      .def_rw("prox", &LexicographicSettings::prox)
      .def_rw("accept_tol", &LexicographicSettings::accept_tol)
      .def_rw("final_weight", &LexicographicSettings::final_weight)
      .def_rw("weights", &LexicographicSettings::weights)
      .def_rw("groups", &LexicographicSettings::groups)
      .def_rw("priorities", &LexicographicSettings::priorities)
      .def_rw("tau_max", &LexicographicSettings::tau_max)
      .def_rw("Cw", &LexicographicSettings::Cw)
      .def_rw("lw", &LexicographicSettings::lw)
      .def_rw("uw", &LexicographicSettings::uw);

  nb::class_<LqpTick, Tick>(m, "LqpTick", "The conventional LQP's tick.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"))
      .def("configure", &LqpTick::configure, nb::arg("settings"))
      .def(
          "run",
          [](LqpTick& tick, ConstVec q, ConstVec v, double t, nb::callable fn,
             NativeSolvers* natives) {
            PyLevelSolver solver(std::move(fn), natives);
            return tick.run(q, v, t, solver);
          },
          nb::arg("q").noconvert(), nb::arg("v").noconvert(), nb::arg("t"), nb::arg("solve"),
          nb::arg("natives").none() = nb::none())
      .def_prop_ro("handles", [](const LqpTick& t) { return t.lqp().handles(); })
      .def("slot", [](const LqpTick& t, int i) -> QpBuffers& { return slot_of(t.lqp().hierarchy(), i); },
           nb::arg("i"), kView)
      // a view of the tick's result, overwritten by the next run (read it before)
      .def_prop_ro(
          "result", [](const LqpTick& t) -> const HierarchyResult& { return t.lqp().result(); },
          kView)
      .def_prop_ro("tau", [](const LqpTick& t) -> const Vector& { return t.lqp().tau(); }, kView)
      .def_prop_ro("qdd", [](const LqpTick& t) -> const Vector& { return t.lqp().qdd(); }, kView)
      .def_prop_ro("wrench", [](const LqpTick& t) -> const Vector& { return t.lqp().wrench(); },
                   kView);
}

}  // namespace wbcbench
