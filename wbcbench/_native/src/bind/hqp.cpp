// hqp's tick (src/controllers/hqp.hpp); wbcbench/controllers/hqp.py holds its Python half.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "bind/level_solver.hpp"
#include "controllers/hqp.hpp"

namespace wbcbench {

WBCBENCH_BIND(hqp, kController, m) {
  using ConstVec = Eigen::Ref<const Vector>;

  nb::enum_<HqpFinal>(m, "HqpFinal")
      .value("torque", HqpFinal::kTorque)
      .value("wrench", HqpFinal::kWrench)
      .value("acceleration_energy", HqpFinal::kAccelerationEnergy)
      .value("zero_torque_energy", HqpFinal::kZeroTorqueEnergy);

  nb::class_<HqpSettings>(m, "HqpSettings")
      .def(nb::init<>())
      .def_rw("strategy", &HqpSettings::strategy)
      .def_rw("finals", &HqpSettings::finals)
      .def_rw("wrench_weights", &HqpSettings::wrench_weights)
      .def_rw("prox", &HqpSettings::prox)
      .def_rw("accept_tol", &HqpSettings::accept_tol)
      .def_rw("level_weights", &HqpSettings::level_weights)
      .def_rw("groups", &HqpSettings::groups)
      .def_rw("priorities", &HqpSettings::priorities)
      .def_rw("force_level", &HqpSettings::force_level)
      .def_rw("tau_max", &HqpSettings::tau_max)
      .def_rw("Cw", &HqpSettings::Cw)
      .def_rw("lw", &HqpSettings::lw)
      .def_rw("uw", &HqpSettings::uw);

  nb::class_<HqpTick, Tick>(m, "HqpTick", "The conventional HQP's tick.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"))
      .def("configure", &HqpTick::configure, nb::arg("settings"))
      .def(
          "run",
          [](HqpTick& tick, ConstVec q, ConstVec v, double t, nb::callable fn,
             NativeSolvers* natives) {
            PyLevelSolver solver(std::move(fn), natives);
            return tick.run(q, v, t, solver);
          },
          nb::arg("q").noconvert(), nb::arg("v").noconvert(), nb::arg("t"), nb::arg("solve"),
          nb::arg("natives").none() = nb::none())
      .def_prop_ro("handles", &HqpTick::handles)
      .def("slot", [](const HqpTick& t, int i) -> QpBuffers& { return slot_of(t.hierarchy(), i); },
           nb::arg("i"), kView)
      // a view of the tick's result, overwritten by the next run (read it before)
      .def_prop_ro(
          "result", [](const HqpTick& t) -> const HierarchyResult& { return t.result(); }, kView)
      .def_prop_ro("tau", &HqpTick::tau, kView)
      .def_prop_ro("qdd", &HqpTick::qdd, kView)
      .def_prop_ro("wrench", &HqpTick::wrench, kView);
}

}  // namespace wbcbench
