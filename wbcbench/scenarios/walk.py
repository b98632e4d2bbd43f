"""A scenario's changing contacts: its contact schedule and ``walk:`` block as runtime objects.

:func:`schedule_times` reads the intervals from the file alone (for ``validate``, before a robot
is loaded); :func:`expand` plans the walk from the robot's starting state and turns the scenario
into a :class:`~wbcbench.tasks.schedule.ContactSchedule`, swing-foot tasks, the CoM task's
LIPM / DCM reference and the heading of the tasks that turn with the walk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from wbcbench.scenarios.schema import Scenario, WalkSpec
from wbcbench.tasks.schedule import ContactSchedule, ScheduledContact
from wbcbench.tasks.tasks import FramePoseTask, Task
from wbcbench.tasks.trajectories import Sample, Trajectory
from wbcbench.tasks.walking import (
    GRAVITY,
    Footstep,
    FootTrajectory,
    HeadingTrajectory,
    WalkPlan,
    WalkTiming,
    footsteps_from_walk,
    plan_walk,
)

INF = math.inf


def walk_timing(walk: WalkSpec) -> WalkTiming:
    return WalkTiming(
        single=walk.single,
        double=walk.double,
        start=walk.start,
        end=walk.end,
        unload=walk.unload,
        swing_height=walk.swing_height,
        touchdown_velocity=walk.touchdown_velocity,
    )


def plan_from_feet(walk: WalkSpec, start: dict[str, Footstep], com: np.ndarray) -> WalkPlan:
    """The walk planned from the two starting feet and the starting CoM (3,) [m].

    Raises:
        ValueError: footsteps the pattern cannot time (feet that do not alternate, …).
    """
    if walk.footsteps is not None:
        landings = [(f.foot, f.position, f.yaw) for f in walk.footsteps]
    else:
        assert walk.steps is not None
        landings = footsteps_from_walk(
            start, walk.first_foot, walk.steps, walk.length, walk.width, walk.turn
        )
    return plan_walk(start, landings, com, walk_timing(walk))


def nominal_plan(walk: WalkSpec) -> WalkPlan:
    """The walk's timing on nominal feet (±0.1 m, CoM at 1 m): its schedule without a robot."""
    a, b = walk.feet
    start = {a: Footstep(a, (0.0, 0.1, 0.0), 0.0), b: Footstep(b, (0.0, -0.1, 0.0), 0.0)}
    return plan_from_feet(walk, start, np.array([0.0, 0.0, 1.0]))


def schedule_times(spec: Scenario) -> list[list[tuple[float, float]]]:
    """Each contact's activity intervals [s], from the file alone (a walk's feet from its
    timing; a contact held throughout has ``[(0, inf)]``). The last interval of a walk's foot
    lasts to the end of the run."""
    walk = spec.walk
    walked = nominal_plan(walk).schedule() if walk is not None else {}
    out: list[list[tuple[float, float]]] = []
    for c in spec.contacts:
        if c.frame in walked:
            intervals = [tuple(i) for i in walked[c.frame]]
            intervals[-1] = (intervals[-1][0], INF)
            out.append([(float(a), float(b)) for a, b in intervals])
        elif c.schedule is not None:
            out.append([(float(a), float(b)) for a, b in c.schedule])
        else:
            out.append([(0.0, INF)])
    return out


@dataclass
class Expansion:
    """What a scenario's changing contacts turn into for one run."""

    schedule: ContactSchedule | None
    tasks: list[Task]
    plan: WalkPlan | None


def _yaw(R: np.ndarray) -> float:
    return math.atan2(float(R[1, 0]), float(R[0, 0]))


def starting_feet(walk: WalkSpec, robot: Any, q0: np.ndarray) -> tuple[dict[str, Footstep], Any]:
    """The two feet's frames at ``q0`` as footsteps, and the Pinocchio data at q0."""
    model = robot.pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q0)
    start = {}
    for foot in walk.feet:
        placement = data.oMf[robot.frame_id(foot)]
        p = placement.translation
        start[foot] = Footstep(
            foot, (float(p[0]), float(p[1]), float(p[2])), _yaw(placement.rotation)
        )
    return start, data


def expand(spec: Scenario, robot: Any, tasks: list[Task], q0: np.ndarray) -> Expansion:
    """The schedule, tasks and walk plan of a run that starts at ``q0`` (Pinocchio order).

    ``tasks`` are the scenario's (:func:`~wbcbench.scenarios.load.build_tasks`); a walk gives
    its CoM task an absolute LIPM / DCM reference and its heading tasks a yaw that follows the
    path, and adds one ``frame_pose`` task ``swing.<foot>`` per foot (held where the foot
    stands between its swings). Without a schedule or a walk, nothing changes.
    """
    if not spec.has_schedule:
        return Expansion(None, tasks, None)
    plan = None
    targets: dict[str, list[np.ndarray | None]] = {}
    walk = spec.walk
    if walk is not None:
        start, _ = starting_feet(walk, robot, q0)
        com = pin.centerOfMass(robot.pin_model, robot.pin_model.createData(), q0)
        plan = plan_from_feet(walk, start, np.asarray(com, dtype=float))
        for foot in walk.feet:
            landings = [np.array(f.position) for f in plan.swings if f.foot == foot]
            targets[foot] = [None, *landings]
        tasks = walk_tasks(walk, plan, tasks, start)
    contacts = []
    for c, intervals in zip(spec.contacts, schedule_times(spec), strict=True):
        unload = walk.unload if walk is not None and c.frame in walk.feet else c.unload
        contacts.append(
            ScheduledContact(c.frame, intervals, targets.get(c.frame, []), unload=unload)
        )
    mass = pin.computeTotalMass(robot.pin_model)
    sim = spec.sim
    schedule = ContactSchedule(
        contacts,
        ramp_force=mass * GRAVITY,
        touchdown_tolerance=sim.touchdown_tolerance,
        touchdown_load=sim.touchdown_load,
        landing_tolerance=sim.landing_tolerance,
        plan=plan,
    )
    return Expansion(schedule, tasks, plan)


def walk_tasks(
    walk: WalkSpec, plan: WalkPlan, tasks: list[Task], start: dict[str, Footstep]
) -> list[Task]:
    """The scenario's tasks with the walk's references, and a swing task per foot."""
    heading = plan.heading()
    out = list(tasks)
    for task in out:
        if task.name == walk.com_task:
            task.reference = PlanCom(plan, task._rows)
            task.absolute = True
        elif task.name in walk.heading_tasks:
            task.reference = HeadingOffset(heading, task._rows, len(task.full_axes))
            task.absolute = False
    sw = walk.swing
    for foot in walk.feet:
        out.append(
            FramePoseTask(
                name=f"swing.{foot}",
                priority=sw.priority,
                kp=sw.kp,
                kv=sw.kv,
                weight=sw.weight,
                frame=foot,
                reference=SwingOffset(plan.foot_trajectory(foot), start[foot]),
            )
        )
    return sorted(out, key=lambda t: t.priority)


class PlanCom(Trajectory):
    """The plan's CoM (x, y, z) [m] on the task's selected rows (an absolute reference)."""

    def __init__(self, plan: WalkPlan, rows: np.ndarray) -> None:
        self.plan, self.rows = plan, rows
        self.dim = rows.size

    def sample(self, t: float) -> Sample:
        x, dx, ddx = self.plan.com(t)
        return x[self.rows], dx[self.rows], ddx[self.rows]


class HeadingOffset(Trajectory):
    """A yaw turn about the world z axis, as the offset of an orientation (rx, ry, rz) or pose
    (x … rz) task from its starting value, on the task's selected rows."""

    def __init__(self, heading: HeadingTrajectory, rows: np.ndarray, full: int) -> None:
        self.heading, self.rows, self.full = heading, rows, full
        self.dim = rows.size
        self.yaw0 = float(heading.sample(0.0)[0][0])

    def sample(self, t: float) -> Sample:
        y, dy, ddy = self.heading.sample(t)
        out = np.zeros((3, self.full))
        out[:, -1] = (float(y[0]) - self.yaw0, float(dy[0]), float(ddy[0]))
        return out[0, self.rows], out[1, self.rows], out[2, self.rows]


class SwingOffset(Trajectory):
    """A foot's (x, y, z, yaw) path as the offset (x, y, z, rx, ry, rz) of a ``frame_pose`` task
    from where the foot starts: the yaw is a rotation about the world z axis."""

    dim = 6

    def __init__(self, foot: FootTrajectory, start: Footstep) -> None:
        self.foot = foot
        self.origin = np.array([*start.position, start.yaw])

    def sample(self, t: float) -> Sample:
        x, dx, ddx = self.foot.sample(t)
        pos, vel, acc = np.zeros(6), np.zeros(6), np.zeros(6)
        pos[:3], pos[5] = x[:3] - self.origin[:3], x[3] - self.origin[3]
        vel[:3], vel[5] = dx[:3], dx[3]
        acc[:3], acc[5] = ddx[:3], ddx[3]
        return pos, vel, acc
