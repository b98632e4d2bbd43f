#include "qp/hierarchy.hpp"

#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "bind/level_solver.hpp"
#include "controllers/hqp.hpp"
#include "controllers/lqp.hpp"

namespace wbcbench {

namespace {

using ConstVec = Eigen::Ref<const Vector>;

QpBuffers& slot_of(const Hierarchy& h, int i) {
  if (i < 0 || i >= h.n_slots()) throw nb::index_error("no such QP slot");
  return const_cast<QpBuffers&>(h.slot(i));
}

}  // namespace

void bind_hierarchy(nb::module_& m) {
  nb::enum_<Strategy>(m, "Strategy")
      .value("cascade", Strategy::kCascade)
      .value("nullspace", Strategy::kNullspace)
      .value("weighted", Strategy::kWeighted);

  nb::class_<HardConstraints>(m, "HardConstraints", "A x = b, l ≤ C x ≤ u, lb ≤ x ≤ ub.")
      .def(nb::init<>())
      .def_rw("A", &HardConstraints::A)
      .def_rw("b", &HardConstraints::b)
      .def_rw("C", &HardConstraints::C)
      .def_rw("l", &HardConstraints::l)
      .def_rw("u", &HardConstraints::u)
      .def_rw("lb", &HardConstraints::lb)
      .def_rw("ub", &HardConstraints::ub);

  nb::class_<PriorityLevel>(m, "PriorityLevel", "min ‖A x − b‖² + ‖v‖², l ≤ C x − v ≤ u.")
      .def(nb::init<>())
      .def_rw("name", &PriorityLevel::name)
      .def_rw("A", &PriorityLevel::A)
      .def_rw("b", &PriorityLevel::b)
      .def_rw("C", &PriorityLevel::C)
      .def_rw("l", &PriorityLevel::l)
      .def_rw("u", &PriorityLevel::u)
      .def_rw("weight", &PriorityLevel::weight)
      .def_rw("hard_if_feasible", &PriorityLevel::hard_if_feasible);

  nb::class_<HierarchyOptions>(m, "HierarchyOptions")
      .def(nb::init<>())
      .def_rw("strategy", &HierarchyOptions::strategy)
      .def_rw("prox", &HierarchyOptions::prox)
      .def_rw("merge_finals", &HierarchyOptions::merge_finals)
      .def_rw("slack_free_first", &HierarchyOptions::slack_free_first)
      .def_rw("handles", &HierarchyOptions::handles)
      .def_rw("accept_tol", &HierarchyOptions::accept_tol);

  nb::class_<LevelResult>(m, "LevelResult")
      .def_ro("name", &LevelResult::name)
      .def_ro("w", &LevelResult::w)
      .def_ro("v", &LevelResult::v);

  nb::class_<HierarchyResult>(m, "HierarchyResult")
      .def_ro("x", &HierarchyResult::x)
      .def_ro("ok", &HierarchyResult::ok)
      .def_ro("failed_level", &HierarchyResult::failed_level)
      .def_ro("message", &HierarchyResult::message)
      .def_ro("levels", &HierarchyResult::levels)
      .def_ro("retries", &HierarchyResult::retries);

  nb::class_<Hierarchy>(m, "Hierarchy", "The level QPs of a hierarchy, solved in turn.")
      .def(nb::init<int>(), nb::arg("pool") = 0)
      .def(
          "solve",
          [](Hierarchy& h, const HardConstraints& hard, const std::vector<PriorityLevel>& soft,
             int n_finals, const HierarchyOptions& options, nb::callable fn) {
            PyLevelSolver solver(std::move(fn), nullptr);
            return h.solve(hard, soft, n_finals, options, solver);
          },
          nb::arg("hard"), nb::arg("soft"), nb::arg("n_finals"), nb::arg("options"),
          nb::arg("solve"))
      .def("slot", &slot_of, nb::arg("i"), kView)
      .def_prop_ro("solver_seconds", &Hierarchy::solver_seconds);

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
      .def_prop_ro("result", [](const LqpTick& t) { return t.lqp().result(); })
      .def_prop_ro("tau", [](const LqpTick& t) -> const Vector& { return t.lqp().tau(); }, kView)
      .def_prop_ro("qdd", [](const LqpTick& t) -> const Vector& { return t.lqp().qdd(); }, kView)
      .def_prop_ro("wrench", [](const LqpTick& t) -> const Vector& { return t.lqp().wrench(); },
                   kView);

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
      .def_prop_ro("result", [](const HqpTick& t) { return t.result(); })
      .def_prop_ro("tau", &HqpTick::tau, kView)
      .def_prop_ro("qdd", &HqpTick::qdd, kView)
      .def_prop_ro("wrench", &HqpTick::wrench, kView);
}

}  // namespace wbcbench
