// kin_hqp's tick (src/controllers/kin_hqp.hpp) and the collision pairs it evaluates
// (src/tasks/collision.hpp); wbcbench/controllers/kin_hqp.py holds their Python half.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "controllers/kin_hqp.hpp"
#include "tasks/collision.hpp"

namespace wbcbench {

namespace {

using Vec3 = Eigen::Vector3d;

// closest_segment_segment / closest_segment_box of one pair (for tests)
nb::tuple segment_segment(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  Vec3 pa, pb;
  closest_segment_segment(a0, a1, b0, b1, pa, pb);
  return nb::make_tuple(pa, pb);
}

nb::tuple segment_box(const Vec3& a0, const Vec3& a1, const Vec3& center,
                      const Eigen::Matrix3d& R, const Vec3& half) {
  Vec3 pa, pb;
  closest_segment_box(a0, a1, center, R, half, pa, pb);
  return nb::make_tuple(pa, pb);
}

// the names of the tick's levels, highest first
std::vector<std::string> level_names(KinHqpTick& tick) {
  std::vector<std::string> out;
  for (int i = 0; i < tick.solver().n_levels(); ++i) out.push_back(tick.solver().level(i).name);
  return out;
}

// the levels of the last tick as (name, A, b, C, l, u, damping, has_task, has_ineq) copies
nb::list levels(KinHqpTick& tick) {
  nb::list out;
  HlsSolver& s = tick.solver();
  for (int i = 0; i < s.n_levels(); ++i) {
    const HlsLevel& lv = s.level(i);
    out.append(nb::make_tuple(lv.name, Matrix(lv.A), Vector(lv.b), Matrix(lv.C), Vector(lv.l),
                              Vector(lv.u), lv.damping, lv.has_task, lv.has_ineq));
  }
  return out;
}

}  // namespace

WBCBENCH_BIND(kin_hqp, kController, m) {
  m.def("closest_segment_segment", &segment_segment, nb::arg("a0"), nb::arg("a1"),
        nb::arg("b0"), nb::arg("b1"), "Closest points (pa, pb) of two segments.");
  m.def("closest_segment_box", &segment_box, nb::arg("a0"), nb::arg("a1"), nb::arg("center"),
        nb::arg("R"), nb::arg("half"), "Closest points (pa, pb) of a segment and a box.");

  nb::class_<CapsuleSpec>(m, "CapsuleSpec", "A capsule fixed to a body (collision.Capsule).")
      .def(nb::init<>())
      .def_rw("frame", &CapsuleSpec::frame)
      .def_rw("p0", &CapsuleSpec::p0)
      .def_rw("p1", &CapsuleSpec::p1)
      .def_rw("radius", &CapsuleSpec::radius);

  nb::class_<BoxSpec>(m, "BoxSpec", "A fixed box obstacle (collision.Box).")
      .def(nb::init<>())
      .def_rw("center", &BoxSpec::center)
      .def_rw("R", &BoxSpec::R)
      .def_rw("half", &BoxSpec::half);

  nb::class_<CollisionPairs>(m, "CollisionPairs", "The pairs of a collision model.")
      .def_prop_ro("size", &CollisionPairs::size)
      .def_prop_ro("d", &CollisionPairs::d, kView)
      .def_prop_ro("grad", &CollisionPairs::grad, kView)
      .def_prop_ro("points", &CollisionPairs::points, kView)
      .def_prop_ro("min_distance", &CollisionPairs::min_distance);

  nb::enum_<KinCom>(m, "KinCom")
      .value("polygon", KinCom::kPolygon)
      .value("fixed", KinCom::kFixed)
      .value("free", KinCom::kFree);

  nb::class_<KinGaze>(m, "KinGaze")
      .def(nb::init<>())
      .def_rw("on", &KinGaze::on)
      .def_rw("frame", &KinGaze::frame)
      .def_rw("axis", &KinGaze::axis)
      .def_rw("target", &KinGaze::target)
      .def_rw("gain", &KinGaze::gain)
      .def_rw("speed_limit", &KinGaze::speed_limit);

  nb::class_<KinHqpSettings>(m, "KinHqpSettings")
      .def(nb::init<>())
      .def_rw("algorithm", &KinHqpSettings::algorithm)
      .def_rw("inequalities", &KinHqpSettings::inequalities)
      .def_rw("support_foot", &KinHqpSettings::support_foot)
      .def_rw("com", &KinHqpSettings::com)
      .def_rw("com_gain", &KinHqpSettings::com_gain)
      .def_rw("com_margin", &KinHqpSettings::com_margin)
      .def_rw("joint_limit_gain", &KinHqpSettings::joint_limit_gain)
      .def_rw("collision_gain", &KinHqpSettings::collision_gain)
      .def_rw("collision_margin", &KinHqpSettings::collision_margin)
      .def_rw("damping", &KinHqpSettings::damping)
      .def_rw("q_min", &KinHqpSettings::q_min)
      .def_rw("q_max", &KinHqpSettings::q_max)
      .def_rw("v_max", &KinHqpSettings::v_max)
      .def_rw("com0", &KinHqpSettings::com0)
      .def_rw("polygon_a", &KinHqpSettings::polygon_a)
      .def_rw("polygon_b", &KinHqpSettings::polygon_b)
      .def_rw("speed_limits", &KinHqpSettings::speed_limits)
      .def_rw("gaze", &KinHqpSettings::gaze)
      .def_rw("task_levels", &KinHqpSettings::task_levels)
      .def_rw("task_level_names", &KinHqpSettings::task_level_names);

  nb::class_<KinHqpTick, Tick>(m, "KinHqpTick", "kin_hqp's tick: levels built and solved.")
      .def(nb::init<const std::string&, const std::vector<std::string>&,
                    const std::vector<std::string>&>(),
           nb::arg("model"), nb::arg("task_frames"), nb::arg("contact_frames"))
      .def("configure", &KinHqpTick::configure, nb::arg("settings"),
           nb::arg("kinematic_frames"), nb::arg("capsules"), nb::arg("self_pairs"),
           nb::arg("boxes"), nb::arg("obstacle_pairs"))
      .def("run", &KinHqpTick::run, nb::arg("q").noconvert(), nb::arg("v").noconvert(),
           nb::arg("t"), nb::call_guard<nb::gil_scoped_release>(), "The tick; returns ok.")
      .def_prop_ro("qd", &KinHqpTick::qd, kView)
      .def_prop_ro("root_map", &KinHqpTick::root_map, kView)
      .def_prop_ro("collisions", &KinHqpTick::collisions, kView)
      .def_prop_ro("references", &KinHqpTick::references, kView)
      .def_prop_ro("gaze_jacobian", &KinHqpTick::gaze_jacobian, kView)
      .def_prop_ro("gaze_error", &KinHqpTick::gaze_error, kView)
      .def_prop_ro("gaze_angle", &KinHqpTick::gaze_angle)
      .def_prop_ro("solve_time", &KinHqpTick::solve_time)
      .def_prop_ro("n_eq", &KinHqpTick::n_eq)
      .def_prop_ro("n_ineq", &KinHqpTick::n_ineq)
      .def_prop_ro("n_task", &KinHqpTick::n_task)
      .def_prop_ro("n_x", &KinHqpTick::n_x)
      .def_prop_ro(
          "solver", [](KinHqpTick& t) -> HlsSolver& { return t.solver(); }, kView,
          "The hierarchy solver: the last tick's result (x, stats(), time, ok, message).")
      .def_prop_ro("level_names", &level_names)
      .def("levels", &levels,
           "The last tick's levels, copies: (name, A, b, C, l, u, damping, has_task, "
           "has_ineq).");
}

}  // namespace wbcbench
