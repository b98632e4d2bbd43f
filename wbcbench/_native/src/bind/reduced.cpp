#include <nanobind/eigen/dense.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "dynamics/reduced.hpp"

namespace wbcbench {

WBCBENCH_BIND(reduced, kCore, m) {
  nb::class_<ChainSpec>(m, "ChainSpec", "One unconstrained chain of a ChainSplit.")
      .def(nb::init<>())
      .def_rw("idx", &ChainSpec::idx)
      .def_rw("root_joints", &ChainSpec::root_joints)
      .def_rw("parent_joint", &ChainSpec::parent_joint);

  nb::class_<SplitSpec>(m, "SplitSpec", "What the reduced model needs of a ChainSplit.")
      .def(nb::init<>())
      .def_rw("contact_frames", &SplitSpec::contact_frames)
      .def_rw("plain", &SplitSpec::plain)
      .def_rw("chains", &SplitSpec::chains);

  nb::class_<ChainCentroid>(m, "ChainCentroid",
                            "Centroidal quantities of one chain, in its parent body's axes.")
      .def_ro("A_G", &ChainCentroid::A_G)
      .def_ro("I_G", &ChainCentroid::I_G)
      .def_ro("J_G", &ChainCentroid::J_G)
      .def_ro("drift", &ChainCentroid::drift)
      .def_ro("mass", &ChainCentroid::mass)
      .def_ro("com", &ChainCentroid::com)
      .def_ro("R", &ChainCentroid::R);

  using BoolVector = Eigen::Matrix<bool, Eigen::Dynamic, 1>;
  nb::class_<ReducedDynamics>(m, "ReducedDynamics",
                              "The reduced-centroidal model, the native mirror of "
                              "ReducedDynamics / ReducedModel.")
      .def(nb::init<RobotDynamics&, SplitSpec>(), nb::arg("dynamics"), nb::arg("split"),
           nb::keep_alive<1, 2>())
      .def("compute", &ReducedDynamics::compute, nb::arg("fixed_base") = true,
           nb::call_guard<nb::gil_scoped_release>(),
           "Every quantity at the dynamics' last update; returns its duration [s].")
      .def(
          "task",
          [](const ReducedDynamics& r, const Eigen::Ref<const Matrix>& J,
             const Eigen::Ref<const Vector>& drift) {
            Matrix Jr(J.rows(), r.n_reduced());
            Vector drift_r(J.rows());
            r.task(J, drift, Jr, drift_r);
            return std::make_pair(std::move(Jr), std::move(drift_r));
          },
          nb::arg("J"), nb::arg("drift"), "(J J̄_r, drift − J J̄_r J̇_r q̇) (eq. 22).")
      .def(
          "reducible_rows",
          [](const ReducedDynamics& r, const Eigen::Ref<const Matrix>& J, double tol) {
            BoolVector out(J.rows());
            r.reducible_rows(J, tol, out);
            return out;
          },
          nb::arg("J"), nb::arg("tol") = 1e-9, "Mask of the rows with J N_r = 0.")
      .def_prop_ro(
          "dynamics", [](ReducedDynamics& r) -> RobotDynamics& { return r.dynamics(); },
          nb::rv_policy::reference_internal)
      .def_prop_ro("n_plain", &ReducedDynamics::n_plain)
      .def_prop_ro("n_reduced", &ReducedDynamics::n_reduced)
      .def_prop_ro("n_chains", &ReducedDynamics::n_chains)
      .def_prop_ro("time", &ReducedDynamics::time)
      .def_prop_ro("unconstrained", &ReducedDynamics::unconstrained)
      .def("chain", &ReducedDynamics::chain, nb::arg("i"), kView)
      .def_prop_ro("J_r", &ReducedDynamics::J_r, kView)
      .def_prop_ro("dJr_v", &ReducedDynamics::dJr_v, kView)
      .def_prop_ro("M_r", &ReducedDynamics::M_r, kView)
      .def_prop_ro("b_r", &ReducedDynamics::b_r, kView)
      .def_prop_ro("g_r", &ReducedDynamics::g_r, kView)
      .def_prop_ro("Jbar_r", &ReducedDynamics::Jbar_r, kView)
      .def_prop_ro("J_cr", &ReducedDynamics::J_cr, kView)
      .def_prop_ro("J_G", &ReducedDynamics::J_G, kView)
      .def_prop_ro("dJG_v", &ReducedDynamics::dJG_v, kView)
      .def_prop_ro("M_uc", &ReducedDynamics::M_uc, kView)
      .def_prop_ro("M_uc_factor", &ReducedDynamics::M_uc_factor, kView)
      .def_prop_ro("b_uc", &ReducedDynamics::b_uc, kView)
      .def_prop_ro("g_uc", &ReducedDynamics::g_uc, kView);
}

}  // namespace wbcbench
