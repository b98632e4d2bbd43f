// The hierarchy engine (src/qp/hierarchy.hpp) that the hierarchical controllers' ticks run: its
// levels, options and result, and the engine itself (for tests against the Python reference).
#include "qp/hierarchy.hpp"

#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "bind/level_solver.hpp"

namespace wbcbench {

WBCBENCH_BIND(hierarchy, kCore, m) {
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
}

}  // namespace wbcbench
