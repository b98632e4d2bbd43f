// The hierarchical least-squares solver (src/qp/hls.hpp); wbcbench/qp/hls_native.py is its
// Python half.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>

#include "bind/bind.hpp"
#include "qp/hls.hpp"

namespace wbcbench {

namespace {

using ConstRows = Eigen::Ref<const RowMatrix>;
using ConstVec = Eigen::Ref<const Vector>;

void set_level(HlsSolver& s, int i, const std::string& name, const ConstRows& A,
               const ConstVec& b, const ConstRows& C, const ConstVec& l, const ConstVec& u,
               double damping, bool has_task, bool has_ineq) {
  if (i < 0 || i >= s.n_levels()) throw nb::index_error("no such level");
  if (A.cols() != s.n() || C.cols() != s.n() || b.size() != A.rows() || l.size() != C.rows() ||
      u.size() != C.rows())
    throw nb::value_error("level arrays of inconsistent sizes");
  HlsLevel& lv = s.level(i);
  lv.name = name;
  lv.A = A;
  lv.b = b;
  lv.C = C;
  lv.l = l;
  lv.u = u;
  lv.damping = damping;
  lv.has_task = has_task;
  lv.has_ineq = has_ineq;
}

// (time, iterations, n_active, n_saturated, residual, violation, rank, dof_left, x) per level
nb::list stats_list(const HlsSolver& s) {
  nb::list out;
  for (const HlsLevelStats& st : s.stats())
    out.append(nb::make_tuple(st.time, st.iterations, st.n_active, st.n_saturated, st.residual,
                              st.violation, st.rank, st.dof_left, Vector(st.x)));
  return out;
}

}  // namespace

WBCBENCH_BIND(hls, kCore, m) {
  nb::enum_<HlsAlgorithm>(m, "HlsAlgorithm")
      .value("reduced_qr", HlsAlgorithm::kReducedQr)
      .value("full_qr", HlsAlgorithm::kFullQr)
      .value("svd", HlsAlgorithm::kSvd);

  nb::class_<HlsOptions>(m, "HlsOptions")
      .def(nb::init<>())
      .def_rw("rank_tol", &HlsOptions::rank_tol)
      .def_rw("feas_tol", &HlsOptions::feas_tol)
      .def_rw("max_iter", &HlsOptions::max_iter);

  nb::class_<HlsSolver>(m, "HlsSolver",
                        "A stack of least-squares levels and the three hierarchy algorithms.")
      .def(nb::init<>())
      .def("resize", &HlsSolver::resize, nb::arg("n_levels"), nb::arg("n"))
      .def_prop_ro("n_levels", &HlsSolver::n_levels)
      .def_prop_ro("n", &HlsSolver::n)
      .def("set_level", &set_level, nb::arg("i"), nb::arg("name"), nb::arg("A"), nb::arg("b"),
           nb::arg("C"), nb::arg("l"), nb::arg("u"), nb::arg("damping"), nb::arg("has_task"),
           nb::arg("has_ineq"))
      .def(
          "solve",
          [](HlsSolver& s, HlsAlgorithm algorithm, const ConstVec& x0, const HlsOptions& o) {
            if (x0.size() != s.n()) throw nb::value_error("x0 has the wrong size");
            return s.solve(algorithm, x0, o);
          },
          nb::arg("algorithm"), nb::arg("x0"), nb::arg("options"),
          nb::call_guard<nb::gil_scoped_release>(), "Solves the stack; returns ok.")
      .def_prop_ro("x", &HlsSolver::x, kView)
      .def_prop_ro("time", &HlsSolver::time)
      .def_prop_ro("ok", &HlsSolver::ok)
      .def_prop_ro("message", &HlsSolver::message)
      .def("stats", &stats_list,
           "Per level: (time, iterations, n_active, n_saturated, residual, violation, rank, "
           "dof_left, x).");
}

}  // namespace wbcbench
