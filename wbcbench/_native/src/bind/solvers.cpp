// The QP solvers the module calls from C++ (src/qp/solver.hpp) and the set of them a hierarchy
// tick's level solves use (src/qp/native_solvers.hpp).
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>

#include "bind/bind.hpp"
#include "qp/daqp_solver.hpp"
#include "qp/eiquadprog_solver.hpp"
#include "qp/native_solvers.hpp"
#include "qp/osqp_solver.hpp"
#include "qp/qpoases_solver.hpp"

namespace wbcbench {

namespace {

SolveMode mode_of(const std::string& mode) {
  if (mode == "cold") return SolveMode::kCold;
  if (mode == "warm") return SolveMode::kWarm;
  if (mode == "hot") return SolveMode::kHot;
  throw std::invalid_argument("unknown mode '" + mode + "'; valid choices: cold, warm, hot");
}

// a record as the Python timer takes it
nb::tuple record_tuple(const NativeSolvers::Record& r) {
  const QpOutcome& o = r.outcome;
  return nb::make_tuple(r.pool, r.handle, r.level, status_name(o.status), o.iterations, o.setup,
                        o.wall, o.internal, o.call, o.rebuilt, o.message);
}

}  // namespace

WBCBENCH_BIND(solvers, kCore, m) {
  nb::class_<QpSolver>(m, "QpSolver", "A QP solver called from C++ (the lean path's mirror).")
      .def(
          "solve",
          [](QpSolver& s, const QpBuffers& qp) {
            const QpOutcome& o = s.solve(qp);
            return nb::make_tuple(status_name(o.status), o.iterations, o.setup, o.wall,
                                  o.internal, o.call, o.rebuilt, o.message);
          },
          nb::arg("qp"))
      .def_prop_ro("x", [](const QpSolver& s) -> const Vector& { return s.solution().x; }, kView)
      .def_prop_ro(
          "y", [](const QpSolver& s) { return s.solution().has_y ? nb::cast(s.solution().y) : nb::none(); })
      .def_prop_ro(
          "z", [](const QpSolver& s) { return s.solution().has_z ? nb::cast(s.solution().z) : nb::none(); })
      .def_prop_ro("z_box",
                   [](const QpSolver& s) {
                     return s.solution().has_z_box ? nb::cast(s.solution().z_box) : nb::none();
                   })
      .def_prop_ro("builds", &QpSolver::builds)
      .def("reset", &QpSolver::reset)
      .def("prepare", &QpSolver::prepare, nb::arg("qp"),
           "Set-up: size the buffers that solves of QPs shaped as qp use, so that the first "
           "solve allocates only inside the backend's library (no data is kept)");

  nb::class_<OsqpSolver, QpSolver>(m, "OsqpSolver", "OSQP (C API), as wbcbench.qp's osqp.")
      .def(
          "__init__",
          [](OsqpSolver* self, const std::string& mode, const OsqpOptions& options,
             bool send_all) { new (self) OsqpSolver(mode_of(mode), options, send_all); },
          nb::arg("mode"), nb::arg("options"), nb::arg("send_all") = false);
  m.def("osqp_setting_names", &osqp_setting_names);

  nb::class_<QpOasesSolver, QpSolver>(m, "QpOasesSolver",
                                      "qpOASES (cmeel-qpoases), as wbcbench.qp's qpoases (CasADi).")
      .def(
          "__init__",
          [](QpOasesSolver* self, const std::string& mode, const QpOasesOptions& options,
             const std::string& profile) {
            new (self) QpOasesSolver(mode_of(mode), options, qpoases_profile(profile));
          },
          nb::arg("mode"), nb::arg("options") = QpOasesOptions(),
          nb::arg("profile") = "casadi",
          "profile: casadi (CasADi's usage), libdwbc_task / libdwbc_wrench (qpoases_libdwbc)")
      .def_prop_ro("last_call", &QpOasesSolver::last_call,
                   "init, hotstart, hotstart_matrices or reinit")
      .def_prop_ro("last_nwsr", &QpOasesSolver::last_nwsr)
      .def("settings", &QpOasesSolver::settings,
           "the qpOASES Options a new object gets, by field name");

  nb::class_<EiquadprogSolver, QpSolver>(
      m, "EiquadprogSolver",
      "eiquadprog (the eiquadprog wheel's library), as TSID calls it; wbcbench.qp's eiquadprog.")
      .def(
          "__init__",
          [](EiquadprogSolver* self, const std::string& mode, const EiquadprogOptions& options) {
            new (self) EiquadprogSolver(mode_of(mode), options);
          },
          nb::arg("mode"), nb::arg("options") = EiquadprogOptions());

  nb::class_<DaqpSolver, QpSolver>(m, "DaqpSolver",
                                   "DAQP (its C library), as wbcbench.qp's daqp (daqp.Model).")
      .def(
          "__init__",
          [](DaqpSolver* self, const std::string& mode, const DaqpOptions& options) {
            new (self) DaqpSolver(mode_of(mode), options);
          },
          nb::arg("mode"), nb::arg("options") = DaqpOptions());
  m.def("daqp_setting_names", &daqp_setting_names);

  nb::class_<NativeSolvers>(m, "NativeSolvers",
                            "The level solves of a hierarchy tick that stay in C++.")
      .def(nb::init<>())
      .def("set", &NativeSolvers::set, nb::arg("pool"), nb::arg("handle"), nb::arg("solver"))
      .def("covers", &NativeSolvers::covers, nb::arg("pool"), nb::arg("handle"))
      .def("clear", &NativeSolvers::clear)
      .def("set_keep", &NativeSolvers::set_keep, nb::arg("keep"))
      .def(
          "kept",
          [](const NativeSolvers& s) {
            nb::list out;
            for (const auto& r : s.records()) {
              if (!r.qp) continue;
              const QpSolution& x = *r.sol;
              auto copy = [](const Vector& d) { return nb::cast(d, nb::rv_policy::copy); };
              auto dual = [&](bool has, const Vector& d) { return has ? copy(d) : nb::none(); };
              out.append(nb::make_tuple(r.pool, r.handle, r.level, QpBuffers(*r.qp), copy(x.x),
                                        dual(x.has_y, x.y), dual(x.has_z, x.z),
                                        dual(x.has_z_box, x.z_box)));
            }
            return out;
          },
          "(pool, handle, level, qp, x, y, z, z_box) of every solve of the last tick, copies "
          "(with set_keep; a dual the backend does not give is None)")
      .def_prop_ro("keep_seconds", &NativeSolvers::keep_seconds)
      .def("reset", &NativeSolvers::reset)
      .def("records",
           [](const NativeSolvers& s) {
             nb::list out;
             for (const auto& r : s.records()) out.append(record_tuple(r));
             return out;
           })
      .def("failure", [](const NativeSolvers& s) -> nb::object {
        const auto* r = s.failure();
        return r == nullptr ? nb::none() : nb::object(record_tuple(*r));
      });
}

}  // namespace wbcbench
