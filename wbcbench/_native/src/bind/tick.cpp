// What every controller's tick shares (src/controllers/tick.hpp): the task references, the tasks,
// the QP buffers and the tick's dynamics, tasks and stage times.
#include <nanobind/eigen/dense.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bind/bind.hpp"
#include "controllers/tick.hpp"
#include "tasks/tasks.hpp"
#include "tasks/trajectory.hpp"

namespace wbcbench {

WBCBENCH_BIND(tick, kCore, m) {
  nb::class_<Trajectory>(m, "Trajectory", "A task reference, sampled every tick.")
      .def_static("constant", &Trajectory::constant, nb::arg("value"))
      .def_static("sinusoid", &Trajectory::sinusoid, nb::arg("amplitude"), nb::arg("frequency"),
                  nb::arg("t0"), nb::arg("phase"))
      .def_static("cubic", &Trajectory::cubic, nb::arg("breaks"), nb::arg("coef"),
                  nb::arg("first"), nb::arg("last"))
      .def_static(
          "minimum_jerk",
          [](const std::vector<double>& times, const Matrix& values) {
            return Trajectory::waypoints(Trajectory::Kind::kMinimumJerk, times, values);
          },
          nb::arg("times"), nb::arg("values"))
      .def_static(
          "linear",
          [](const std::vector<double>& times, const Matrix& values) {
            return Trajectory::waypoints(Trajectory::Kind::kLinear, times, values);
          },
          nb::arg("times"), nb::arg("values"))
      .def_static("sampled", &Trajectory::sampled, nb::arg("dim"),
                  "A reference whose (x, ẋ, ẍ) the Python side sets before each tick "
                  "(TaskSet.set_sample)")
      .def_prop_ro("dim", &Trajectory::dim)
      .def(
          "sample",
          [](const Trajectory& traj, double t) {
            Vector x(traj.dim()), xd(traj.dim()), xdd(traj.dim());
            traj.sample(t, x, xd, xdd);
            return std::make_tuple(x, xd, xdd);
          },
          nb::arg("t"), "(x, ẋ, ẍ) at t (copies; for tests)");

  nb::enum_<TaskType>(m, "TaskType")
      .value("com", TaskType::kCom)
      .value("frame_position", TaskType::kFramePosition)
      .value("frame_orientation", TaskType::kFrameOrientation)
      .value("frame_pose", TaskType::kFramePose)
      .value("joint_posture", TaskType::kPosture)
      .value("joint_damping", TaskType::kDamping);

  nb::class_<TaskSpec>(m, "TaskSpec", "One task as handed over once it is started.")
      .def(nb::init<>())
      .def_rw("type", &TaskSpec::type)
      .def_rw("frame", &TaskSpec::frame)
      .def_rw("rows", &TaskSpec::rows)
      .def_rw("kp", &TaskSpec::kp)
      .def_rw("kv", &TaskSpec::kv)
      .def_rw("absolute", &TaskSpec::absolute)
      .def_rw("x0", &TaskSpec::x0)
      .def_rw("R0", &TaskSpec::R0)
      .def_rw("reference", &TaskSpec::reference);

  nb::class_<TaskSet>(m, "TaskSet", "The tasks of a controller, stacked.")
      .def("add", &TaskSet::add, nb::arg("spec"))
      .def("evaluate", &TaskSet::evaluate, nb::arg("dynamics"), nb::arg("q").noconvert(),
           nb::arg("v").noconvert(), nb::arg("t"))
      .def("set_sample", &TaskSet::set_sample, nb::arg("i"), nb::arg("x"), nb::arg("xd"),
           nb::arg("xdd"), "task i's sampled reference (x, ẋ, ẍ) for the next ticks")
      .def_prop_ro("size", &TaskSet::size)
      .def_prop_ro("rows", &TaskSet::rows)
      .def("offset", &TaskSet::offset, nb::arg("i"))
      .def("dim", &TaskSet::dim, nb::arg("i"))
      .def_prop_ro("J", &TaskSet::J, kView)
      .def_prop_ro("drift", &TaskSet::drift, kView)
      .def_prop_ro("acc_ref", &TaskSet::acc_ref, kView)
      .def_prop_ro("error", &TaskSet::error, kView)
      .def_prop_ro("error_vel", &TaskSet::error_vel, kView);

  nb::class_<QpBuffers>(m, "QpBuffers", "One QP's buffers, refilled in place every tick.")
      .def(nb::init<>())
      .def("resize", &QpBuffers::resize, nb::arg("n"), nb::arg("n_eq"), nb::arg("n_in"),
           nb::arg("box"))
      .def_prop_ro("H", [](QpBuffers& b) -> RowMatrix& { return b.H; }, kView)
      .def_prop_ro("g", [](QpBuffers& b) -> Vector& { return b.g; }, kView)
      .def_prop_ro("A", [](QpBuffers& b) -> RowMatrix& { return b.A; }, kView)
      .def_prop_ro("b", [](QpBuffers& b) -> Vector& { return b.b; }, kView)
      .def_prop_ro("C", [](QpBuffers& b) -> RowMatrix& { return b.C; }, kView)
      .def_prop_ro("l", [](QpBuffers& b) -> Vector& { return b.l; }, kView)
      .def_prop_ro("u", [](QpBuffers& b) -> Vector& { return b.u; }, kView)
      .def_prop_ro("lb", [](QpBuffers& b) -> Vector& { return b.lb; }, kView)
      .def_prop_ro("ub", [](QpBuffers& b) -> Vector& { return b.ub; }, kView)
      .def_ro("has_box", &QpBuffers::has_box);

  nb::class_<Tick>(m, "Tick", "Dynamics, tasks and stage times of a native controller.")
      .def_prop_ro("dynamics", &Tick::dynamics, kView)
      .def("set_contact_points", &Tick::set_contact_points, nb::arg("points"), nb::arg("bases"),
           "Contacts made of points: one (N, 3) array per contact frame, (0, 3) for a flat one, "
           "and each one's (r, 3N) row basis, (0, 0) for a flat one; before configure()")
      .def("select_contacts", &Tick::select_contacts, nb::arg("active"),
           "The contacts the tick holds (increasing indices into the contact frames); a change "
           "re-sizes the dynamics' contact buffers, and the controller's settings for the new "
           "set are handed over next (configure). Returns whether the set changed.")
      .def("switch_contacts", &Tick::switch_contacts, nb::arg("set"),
           "select_contacts of the contact set held before under number `set` (contact_set "
           "after it was selected), without crossing a list; allocates nothing")
      .def_prop_ro("contact_set", &Tick::contact_set,
                   "The number of the contact set the tick holds (0: every contact, then the "
                   "sets in the order first held)")
      .def("set_wrench_bounds", &Tick::set_wrench_bounds, nb::arg("lw").noconvert(),
           nb::arg("uw").noconvert(),
           "This tick's bounds on the active contacts' wrench rows (the normal-force ramps)")
      .def_prop_ro("active_contacts",
                   [](Tick& t) { return t.dynamics().active_contacts(); })
      .def_prop_ro("tasks", &Tick::tasks, kView)
      .def_prop_ro("dynamics_time", [](const Tick& t) { return t.times().dynamics; })
      .def_prop_ro("build_time", [](const Tick& t) { return t.times().build; });
}

}  // namespace wbcbench
