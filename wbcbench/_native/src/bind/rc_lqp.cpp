#include "controllers/rc_lqp.hpp"

#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "bind/level_solver.hpp"

namespace wbcbench {

WBCBENCH_BIND(rc_lqp, kController, m) {
  using ConstVec = Eigen::Ref<const Vector>;
  nb::enum_<Assembly>(m, "Assembly")
      .value("exact", Assembly::kExact)
      .value("paper", Assembly::kPaper);
  nb::enum_<CentroidPreview>(m, "CentroidPreview")
      .value("priority", CentroidPreview::kPriority)
      .value("energy", CentroidPreview::kEnergy)
      .value("off", CentroidPreview::kOff);
  nb::enum_<Lqp2Energy>(m, "Lqp2Energy")
      .value("whole", Lqp2Energy::kWhole)
      .value("chain", Lqp2Energy::kChain);
  nb::enum_<InfeasibleCoupling>(m, "InfeasibleCoupling")
      .value("replan", InfeasibleCoupling::kReplan)
      .value("fail", InfeasibleCoupling::kFail);

  nb::class_<RcLqpSettings>(m, "RcLqpSettings")
      .def(nb::init<>())
      .def_rw("assembly", &RcLqpSettings::assembly)
      .def_rw("coupling_priority", &RcLqpSettings::coupling_priority)
      .def_rw("centroid_preview", &RcLqpSettings::centroid_preview)
      .def_rw("lqp2_energy", &RcLqpSettings::lqp2_energy)
      .def_rw("diagnostics", &RcLqpSettings::diagnostics)
      .def_rw("coupling_tol", &RcLqpSettings::coupling_tol)
      .def_rw("wrench_tol", &RcLqpSettings::wrench_tol)
      .def_rw("infeasible_coupling", &RcLqpSettings::infeasible_coupling);

  nb::class_<RcLqpTick, Tick>(m, "RcLqpTick", "The reduced-centroidal LQP's tick.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&, const std::vector<SplitSpec>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"),
           nb::arg("stances"),
           "stances: the chain split of each contact set the tick may hold, the first for "
           "every contact frame; a reduced model is built for each and kept")
      .def("add_stance", &RcLqpTick::add_stance, nb::arg("split"),
           "The chain split of a contact set first met after set-up (nothing if it has one)")
      .def("configure", &RcLqpTick::configure, nb::arg("settings"), nb::arg("rc"))
      .def("set_row_split", &RcLqpTick::set_row_split, nb::arg("lqp1_rows"))
      .def(
          "run",
          [](RcLqpTick& tick, ConstVec q, ConstVec v, double t, nb::callable fn,
             NativeSolvers* natives) {
            PyLevelSolver solver(std::move(fn), natives);
            return tick.run(q, v, t, solver);
          },
          nb::arg("q").noconvert(), nb::arg("v").noconvert(), nb::arg("t"), nb::arg("solve"),
          nb::arg("natives").none() = nb::none())
      .def("handles", &RcLqpTick::handles, nb::arg("pool"))
      .def(
          "slot",
          [](const RcLqpTick& t, int pool, int i) -> QpBuffers& {
            return const_cast<QpBuffers&>(t.slot(pool, i));
          },
          nb::arg("pool"), nb::arg("i"), kView)
      // the tick's own results (no copy), valid until its next run
      .def_prop_ro("lqp1", &RcLqpTick::lqp1, nb::rv_policy::reference_internal)
      .def_prop_ro("lqp2", &RcLqpTick::lqp2, nb::rv_policy::reference_internal)
      .def_prop_ro("has_lqp2", &RcLqpTick::has_lqp2)
      .def_prop_ro("retries", &RcLqpTick::retries)
      .def_prop_ro("replanned", &RcLqpTick::replanned)
      .def_prop_ro("fell_back", &RcLqpTick::fell_back)
      .def_prop_ro("base_residual", &RcLqpTick::base_residual)
      .def_prop_ro("wrench_residual", &RcLqpTick::wrench_residual)
      .def_prop_ro("coupling_residual", &RcLqpTick::coupling_residual)
      .def_prop_ro("assembly_diff", &RcLqpTick::assembly_diff)
      .def_prop_ro("coupling_violation", &RcLqpTick::coupling_violation)
      .def_prop_ro("message", &RcLqpTick::message)
      .def_prop_ro("level_failed", &RcLqpTick::level_failed)
      .def_prop_ro("failed_level", &RcLqpTick::failed_level)
      .def_prop_ro("failed_reason", &RcLqpTick::failed_reason)
      .def_prop_ro("reduced_time", &RcLqpTick::reduced_time)
      .def_prop_ro("lqp1_time", &RcLqpTick::lqp1_time)
      .def_prop_ro("lqp2_time", &RcLqpTick::lqp2_time)
      .def_prop_ro("fallback_time", &RcLqpTick::fallback_time)
      .def_prop_ro("lqp1_rows", &RcLqpTick::lqp1_rows)
      .def_prop_ro("lqp2_rows", &RcLqpTick::lqp2_rows)
      .def_prop_ro("chain_priority", &RcLqpTick::chain_priority)
      .def_prop_ro("preview_D", &RcLqpTick::preview_D, kView)
      .def_prop_ro("preview_d0", &RcLqpTick::preview_d0, kView)
      .def_prop_ro("tau", &RcLqpTick::tau, kView)
      .def_prop_ro("qdd", &RcLqpTick::qdd, kView)
      .def_prop_ro("wrench", &RcLqpTick::wrench, kView);
}

}  // namespace wbcbench
