"""Closed-loop runs: a controller drives the robot in MuJoCo.

Each control tick (``control_rate``, 1 kHz by default) the runner reads (qpos, qvel), converts
them to Pinocchio's convention, builds one :class:`RobotState`, asks the controller for torques,
applies them through the motors (zero-order hold) and advances the physics by
``control_period / sim.timestep`` steps.

Solver failures: the documented fallback is to **hold the previous tick's torque** and count the
failure; a step that commands a torque beyond its limit (by more than ``TORQUE_TOL`` of it) is a
failed tick too, with the same fallback; after ``sim.max_consecutive_failures`` failed ticks in a
row the run stops with status ``failed``. A run stops with status ``fell`` when the base drops
below ``sim.fall_height`` of its initial height, or a held contact frame slips more than
``sim.contact_slip`` or carries no load for 50 ms.

A scenario whose contacts change (a contact schedule or a walk) holds a contact to these limits
only while it is active and fully loaded (not while it unloads before lift-off or loads after
touchdown). Each tick the runner reports the feet's simulated normal forces to the schedule,
which confirms touchdowns; a touchdown that does not happen within ``sim.touchdown_tolerance``
of its time, or lands farther than ``sim.landing_tolerance`` from its footstep, ends the run
``failed`` with a message that names the contact and the time or target
(:meth:`~wbcbench.tasks.schedule.ContactSchedule.observe`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from wbcbench.controllers.base import ControlOutput
from wbcbench.dynamics.state import RobotState
from wbcbench.robots.convert import mj_to_pin, torque_to_ctrl
from wbcbench.robots.loader import Robot, simulation_model, welded_bodies
from wbcbench.runs import Run
from wbcbench.scenarios.initial import initial_state
from wbcbench.scenarios.load import LoadedScenario, sole_boxes, torque_limits
from wbcbench.sim.perturbations import Pushes, Sensing
from wbcbench.tasks.schedule import ContactSchedule

STAGES = ("dynamics", "build", "solve", "solve_internal", "total")
LOST_CONTACT_TICKS = 50
#: a commanded torque beyond (1 + TORQUE_TOL) × its limit fails the tick (solver accuracy)
TORQUE_TOL = 1e-3


@dataclass
class RunLog:
    """Per-tick arrays of one run (rows = control ticks that were executed)."""

    columns: dict[str, list[float]] = field(default_factory=dict)
    rows: int = 0

    def add(self, row: dict[str, float]) -> None:
        """Append one tick; a column a tick does not report is NaN there (e.g. a diagnostic
        that only failed or only successful steps give)."""
        for key, value in row.items():
            column = self.columns.get(key)
            if column is None:
                column = self.columns[key] = [float("nan")] * self.rows
            column.append(value)
        self.rows += 1
        for column in self.columns.values():
            if len(column) < self.rows:
                column.append(float("nan"))

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v, dtype=float) for k, v in self.columns.items()}


@dataclass
class RunResult:
    status: str  # ok | fell | failed
    message: str
    log: RunLog
    ticks: int
    failures: int
    wall_time: float
    robot: Robot
    contact_frames: list[str]
    tau_max: np.ndarray
    task_parts: dict[str, list[str]]
    #: the walk the run followed, as plain data (:meth:`WalkPlan.to_dict`), if any
    walk: dict[str, Any] | None = None

    @property
    def fell(self) -> bool:
        return self.status == "fell"


class ContactSensor:
    """Contact wrenches MuJoCo applies on the bodies that carry the robot's contact frames.

    A frame's body counts together with the bodies welded to it
    (:func:`~wbcbench.robots.loader.welded_bodies`), so a contact frame on a link with no
    geometry of its own reads the forces on its foot.
    Returned per frame as [f; m] in the contact frame, moments about its origin, reaction on the
    robot (the same convention as the controllers' predicted wrench).
    """

    def __init__(self, model: mujoco.MjModel, robot: Robot, frames: list[str]) -> None:
        self.model = model
        self.frames = frames
        self._site_or_body: list[tuple[str, int]] = []
        self.bodies: list[set[int]] = []
        for f in frames:
            sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f)
            if sid >= 0:
                self._site_or_body.append(("site", sid))
                body = int(model.site_bodyid[sid])
            else:
                body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f)
                self._site_or_body.append(("body", body))
            self.bodies.append(welded_bodies(model, body))
        self._f6 = np.zeros(6)
        # feet that touch the world with a mesh (its convex hull in MuJoCo)
        colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        meshes = {
            int(model.geom_bodyid[g])
            for g in np.flatnonzero(colliding & (model.geom_type == mujoco.mjtGeom.mjGEOM_MESH))
        }
        self.mesh_foot = [bool(b & meshes) for b in self.bodies]

    def frame_pose(self, data: mujoco.MjData, i: int) -> tuple[np.ndarray, np.ndarray]:
        kind, idx = self._site_or_body[i]
        if kind == "site":
            return data.site_xpos[idx].copy(), data.site_xmat[idx].reshape(3, 3).copy()
        return data.xpos[idx].copy(), data.xmat[idx].reshape(3, 3).copy()

    def wrenches(self, data: mujoco.MjData) -> np.ndarray:
        """Stacked wrenches (6 × frames,)."""
        out = np.zeros(6 * len(self.frames))
        if not self.frames:
            return out
        geom_body = self.model.geom_bodyid
        poses = [self.frame_pose(data, i) for i in range(len(self.frames))]
        for ci in range(data.ncon):
            con = data.contact[ci]
            b1, b2 = geom_body[con.geom1], geom_body[con.geom2]
            for i, group in enumerate(self.bodies):
                if (b1 in group) == (b2 in group):  # neither, or a contact inside the group
                    continue
                mujoco.mj_contactForce(self.model, data, ci, self._f6)
                frame = con.frame.reshape(3, 3)  # rows: normal, tangent1, tangent2
                force = frame.T @ self._f6[:3]  # on geom2, world axes
                torque = frame.T @ self._f6[3:]
                if b1 in group:
                    force, torque = -force, -torque
                p, R = poses[i]
                moment = torque + cross3(con.pos - p, force)
                out[6 * i : 6 * i + 3] += R.T @ force
                out[6 * i + 3 : 6 * i + 6] += R.T @ moment
        return out


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors, as ``np.cross`` computes it (the same products and differences),
    without its axis handling, which costs ~20 µs per call: the simulation calls it per contact
    point and tick."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def output_row(t: float, out: ControlOutput, task_parts: dict[str, list[str]]) -> dict[str, float]:
    """The log columns every runner writes for a tick: time, status, stage timings and each
    task's error norms (``task_parts`` collects the parts each task reports)."""
    row: dict[str, float] = {"t": t, "ok": float(out.ok), "iterations": out.iterations}
    for stage, value in out.timings.items():
        row[f"time.{stage}"] = value
    for term in out.terms:
        norms = term.task.error_norms(term)
        task_parts.setdefault(term.task.name, list(norms))
        for part, value in norms.items():
            row[f"err.{term.task.name}.{part}"] = value
    return row


class Rejections:
    """Ticks whose successful step an independent check rejected (see ``run_closed_loop``)."""

    def __init__(self) -> None:
        self.count = 0
        self.first = ""
        self.last = ""

    def add(self, t: float, message: str) -> None:
        self.count += 1
        self.last = message
        if not self.first:
            self.first = f"{message} at t = {t:.3f} s"

    def outcome(self, status: str, message: str, ticks: int) -> tuple[str, str]:
        """The run's status and message with the rejected ticks accounted for.

        A run that would have ended ``ok`` ends ``failed`` with the first rejection's message
        (the check's own words first, e.g. ``reported solved but ...``); a run that fell or
        failed for another reason keeps its status and gets the rejections appended.
        """
        if not self.count:
            return status, message
        counted = f"({self.count} of {ticks} ticks rejected)"
        if status == "ok":
            return "failed", f"{self.first} {counted}"
        if message.endswith(self.last):  # stopped by consecutive rejections: said already
            return status, f"{message} {counted}"
        return status, f"{message}; {self.first} {counted}"


def prepare_model(robot: Robot, loaded: LoadedScenario) -> mujoco.MjModel:
    """A copy of the robot's MuJoCo model with the scenario's simulation settings applied."""
    sim, pert = loaded.spec.sim, loaded.spec.perturbations
    payload = pert.model.payload
    model = simulation_model(
        robot,
        sole_boxes(loaded.spec, robot),
        sim.excluded_pairs,
        payloads=[(payload.body, payload.mass, payload.offset)] if payload else [],
        actuator_lag=pert.actuation.lag,
    )
    model.opt.timestep = sim.timestep
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{sim.integrator.upper()}")
    if not sim.joint_friction:
        model.dof_frictionloss[:] = 0.0
        model.dof_damping[:] = 0.0
    # the scenario's torque limits are the motors' limits too
    tau = torque_limits(loaded.spec, robot)
    act = robot.actuator_ids
    model.actuator_ctrlrange[act, 0] = -tau
    model.actuator_ctrlrange[act, 1] = tau
    if not sim.self_collision:
        world_contacts_only(model)
    return model


def world_contacts_only(model: mujoco.MjModel) -> None:
    """Collision masks so that the robot's geoms collide with the world's and not each other.

    A pair collides when ``contype_a & conaffinity_b`` or ``contype_b & conaffinity_a``: robot
    geoms get (2, 1), world geoms (1, 2); geoms that collided with nothing stay so.
    """
    active = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    world = model.geom_bodyid == 0
    model.geom_contype[active & ~world] = 2
    model.geom_conaffinity[active & ~world] = 1
    model.geom_contype[active & world] = 1
    model.geom_conaffinity[active & world] = 2


def friction_torque(robot: Robot, model: mujoco.MjModel, qd: np.ndarray) -> np.ndarray:
    """The model's viscous + Coulomb joint friction at joint velocity qd (k,) [N·m].

    The sign of the Coulomb term is smoothed over 0.01 rad/s so the compensation does not chatter
    around zero velocity.
    """
    dof = robot.mj_dof_adr
    return model.dof_damping[dof] * qd + model.dof_frictionloss[dof] * np.tanh(qd / 0.01)


def run_closed_loop(
    run: Run,
    progress: Callable[[int, int], None] | None = None,
    on_step: Callable[[RobotState, ControlOutput], None] | None = None,
    wrap_solver: Callable[[Any], Any] | None = None,
    check: Callable[[ControlOutput], str] | None = None,
) -> RunResult:
    """Simulate one run (:func:`wbcbench.runs.plan_run`); never raises for a failed QP.

    ``wrap_solver`` wraps every solver handle the controller makes; ``check(out)`` runs after
    each successful step (outside the controller's timed stages) and may return a message that
    marks the tick failed like a failed QP: the previous torque is held, and a run with such
    ticks ends ``failed`` with that message (see :meth:`Rejections.outcome`).

    A run whose runner is ``kinematic`` (velocity-level controllers, kinematic scenarios) runs
    without physics: :func:`wbcbench.sim.kinematic.run_kinematic`.
    """
    if run.runner == "kinematic":
        from wbcbench.sim.kinematic import run_kinematic  # it imports this module

        return run_kinematic(
            run, progress=progress, on_step=on_step, wrap_solver=wrap_solver, check=check
        )
    loaded, robot = run.scenario, run.robot
    spec = loaded.spec
    model = prepare_model(robot, loaded)
    data = mujoco.MjData(model)
    q0, v0 = initial_state(loaded, robot)
    qpos, qvel = robot.pin_to_mj(q0, v0)
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    mujoco.mj_forward(model, data)

    controller = run.make_controller(wrap_solver)
    schedule = controller.ctx.schedule
    own_robot = controller.ctx.robot  # the simulated one, or one with the model error
    pert = spec.perturbations
    perturbed = pert.active
    pushes = Pushes(model, pert.pushes)
    sensing = Sensing(pert, robot.k)
    contacts = controller.ctx.contacts
    tau_max = controller.ctx.tau_max
    frames = [c.frame for c in contacts]
    sensor = ContactSensor(model, robot, frames)
    substeps = max(1, round(spec.dt / model.opt.timestep))
    n_ticks = round(spec.duration * spec.control_rate)
    pin_data = own_robot.pin_model.createData()
    true_data = robot.pin_model.createData() if perturbed else None
    unloaded = np.zeros(len(frames), dtype=int)
    log = RunLog()
    task_parts: dict[str, list[str]] = {}
    last_tau = np.zeros(robot.k)
    failures = consecutive = 0
    status, message = "ok", ""
    compensate = spec.sim.friction_compensation and spec.sim.joint_friction
    rejections = Rejections()
    wall0 = time.perf_counter()
    tick = 0
    try:
        q, v = mj_to_pin(robot, data.qpos, data.qvel)
        controller.start(RobotState(own_robot, *sensing.measure(q, v), pin_data))
        if spec.initial.settle > 0:
            ticks = round(spec.initial.settle * spec.control_rate)
            last_tau = settle(
                controller, own_robot, model, data, pin_data, tau_max, ticks, substeps, check
            )
        base_z0 = float(data.qpos[2])
        contact_p0 = [sensor.frame_pose(data, i)[0] for i in range(len(frames))]
        sim_w = sensor.wrenches(data)
        held = np.ones(len(frames), dtype=bool)
        confirmed_before: dict[tuple[int, int], float] = {}
        positions: list[np.ndarray] = []
        yaws: list[float] = []
        for tick in range(n_ticks):
            t = tick * spec.dt
            if schedule is not None:
                poses = [sensor.frame_pose(data, i) for i in range(len(frames))]
                positions = [p for p, _ in poses]
                yaws = [math.atan2(r[1, 0], r[0, 0]) for _, r in poses]
                why = schedule.observe(t, sim_w[2::6], positions)
                if why:
                    status, message = "failed", why
                    break
                for i, _ in set(schedule.confirmed) - set(confirmed_before):
                    contact_p0[i] = positions[i]  # a foot landed: held from where it is
                confirmed_before = dict(schedule.confirmed)
                phase = schedule.phase(t)
                held[:] = False
                for j, i in enumerate(phase.active):
                    held[i] = phase.lower[j] >= 1.0 and phase.upper[j] >= 1.0
            q, v = mj_to_pin(robot, data.qpos, data.qvel)
            state = RobotState(own_robot, *sensing.measure(q, v), pin_data)
            out = controller.step(state, t)
            if on_step is not None:
                on_step(state, out)
            rejected = check(out) if check is not None else ""
            rejected = rejected if out.ok else ""  # a failed step is a failed tick already
            if rejected:
                rejections.add(t, rejected)
            over = torque_excess(out.tau, tau_max, robot.joint_names) if out.ok else ""
            if out.ok and not rejected and not over:
                tau = out.tau
                consecutive = 0
            else:
                failures += 1
                consecutive += 1
                tau = last_tau
                if consecutive >= spec.sim.max_consecutive_failures:
                    status, message = (
                        "failed",
                        f"{consecutive} failed ticks in a row: {rejected or over or out.message}",
                    )
            last_tau = tau
            sent = sensing.command(tau)
            applied = sent + friction_torque(robot, model, v[6:]) if compensate else sent
            data.ctrl[:] = torque_to_ctrl(robot, applied)
            if tick == 0 and spec.initial.settle == 0:
                start_motors(model, data)
            for step in range(substeps):
                pushes.apply(data, t + step * model.opt.timestep)
                mujoco.mj_step(model, data)

            row = output_row(t, out, task_parts)
            if rejected or over:
                row["ok"] = 0.0
            for j, name in enumerate(robot.joint_names):
                row[f"tau.{name}"] = tau[j]
            sim_w = sensor.wrenches(data)
            wrench = controller.full_wrench(out.wrench) if out.ok else None
            for i, f in enumerate(frames):
                for c, comp in enumerate(("fx", "fy", "fz", "mx", "my", "mz")):
                    row[f"wrench_pred.{f}.{comp}"] = np.nan if wrench is None else wrench[6 * i + c]
                    row[f"wrench_sim.{f}.{comp}"] = sim_w[6 * i + c]
            if schedule is not None:
                active = dict(zip(phase.active, phase.upper, strict=True))
                for i, f in enumerate(frames):
                    row[f"active.{f}"] = active.get(i, 0.0)
                    pos = positions[i]
                    row[f"foot.{f}.x"], row[f"foot.{f}.y"], row[f"foot.{f}.z"] = (
                        float(x) for x in pos
                    )
                    row[f"foot.{f}.yaw"] = yaws[i]
                row["touchdowns"] = float(len(schedule.confirmed))
            row["base_z"] = float(data.qpos[2])
            # the simulated joints' smallest distance to a position limit [rad]: the torque-level
            # controllers do not hold position limits, so a task that drives a joint into one
            # gives way while every QP is solved
            joints = q[7:]
            row["joint_margin"] = float(
                np.min(np.minimum(joints - robot.q_min, robot.q_max - joints), initial=np.inf)
            )
            # the robot's own CoM and task errors: with perturbations the controller's state
            # (noisy, on its model) is not the robot's; measure it on the simulated one
            true_state = RobotState(robot, q, v, true_data) if perturbed else state
            if perturbed:
                for task in controller.ctx.tasks:
                    norms = task.error_norms(task.evaluate(true_state, t))
                    for part, value in norms.items():
                        row[f"true_err.{task.name}.{part}"] = value
            row["com.x"], row["com.y"], row["com.z"] = (float(x) for x in true_state.com)
            if schedule is not None:  # the measured DCM's velocity part, for the walk metrics
                row["com.vx"], row["com.vy"] = (float(x) for x in true_state.com_velocity[:2])
            for name, value in out.diagnostics.items():
                row[f"diag.{name}"] = value
            log.add(row)
            if progress is not None:
                progress(tick + 1, n_ticks)
            if status != "ok":
                break

            if data.qpos[2] < spec.sim.fall_height * base_z0:
                status, message = "fell", f"base height {data.qpos[2]:.3f} m at t = {t:.3f} s"
                break
            lost = _lost_contact(
                sensor, data, contact_p0, sim_w, unloaded, spec.sim.contact_slip, held
            )
            if lost:
                status, message = "fell", f"{lost} at t = {t:.3f} s"
                break
    finally:
        controller.close()  # stop parameter workers however the run ends

    status, message = rejections.outcome(status, message, tick + 1)
    return RunResult(
        status=status,
        message=message,
        log=log,
        ticks=tick + 1,
        failures=failures,
        wall_time=time.perf_counter() - wall0,
        robot=robot,
        contact_frames=frames,
        tau_max=tau_max,
        task_parts=task_parts,
        walk=walk_record(schedule),
    )


def walk_record(schedule: ContactSchedule | None) -> dict[str, Any] | None:
    """The walk a run followed as plain data: the plan (:meth:`WalkPlan.to_dict`) and its
    confirmed touchdowns ``landings``: frame, time [s], and the landed frame's distance to its
    footstep [m] in 3-D (``error``), in the floor plane (``error_xy``) and along z (``error_z``)."""
    if schedule is None or schedule.plan is None:
        return None
    out = schedule.plan.to_dict()
    out["landings"] = [
        {
            "foot": foot,
            "t": t,
            "error": float(np.linalg.norm(offset)),
            "error_xy": float(np.hypot(offset[0], offset[1])),
            "error_z": float(abs(offset[2])),
        }
        for foot, t, offset in schedule.landings
    ]
    return out


def torque_excess(tau: np.ndarray, tau_max: np.ndarray, joints: tuple[str, ...]) -> str:
    """Why commanded torques ``tau`` (k,) break the limits ``tau_max`` (k,) [N·m], or ""."""
    if tau.size == 0:
        return ""
    excess = np.abs(tau) - tau_max * (1 + TORQUE_TOL)
    j = int(np.argmax(excess))
    if not excess[j] > 0:
        return ""
    return f"commanded torque {tau[j]:.4g} N·m on {joints[j]} beyond its limit {tau_max[j]:.4g} N·m"


def settle(
    controller: Any,
    robot: Robot,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    pin_data: Any,
    tau_max: np.ndarray,
    ticks: int,
    substeps: int,
    check: Callable[[ControlOutput], str] | None = None,
) -> np.ndarray:
    """``ticks`` control ticks of the run's own controller with time held at t = 0 (every
    reference at its start), before the run's time starts: a robot placed a little above or
    into the floor comes to rest before it is judged. Nothing is logged; a failed tick, one
    beyond the torque limits or one ``check`` rejects holds the previous torque as in the run.
    Returns the last torque applied (k,) [N·m]."""
    tau = np.zeros(robot.k)
    started = False
    for _ in range(ticks):
        q, v = mj_to_pin(robot, data.qpos, data.qvel)
        out = controller.step(RobotState(robot, q, v, pin_data), 0.0)
        rejected = check(out) if check is not None else ""  # also clears what the check holds
        if out.ok and not rejected and not torque_excess(out.tau, tau_max, robot.joint_names):
            tau = out.tau
        data.ctrl[:] = torque_to_ctrl(robot, tau)
        if not started:
            start_motors(model, data)
            started = True
        for _ in range(substeps):
            mujoco.mj_step(model, data)
    data.time = 0.0
    return tau


def start_motors(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Motors with a lag (an activation state each) start at their first command, not at
    zero: the run judges the lag's effect on control, not a start from zero torque."""
    if model.na:
        stateful = model.actuator_actadr >= 0
        data.act[model.actuator_actadr[stateful]] = data.ctrl[stateful]


def _lost_contact(
    sensor: ContactSensor,
    data: mujoco.MjData,
    p0: list[np.ndarray],
    wrench: np.ndarray,
    unloaded: np.ndarray,
    slip: float,
    held: np.ndarray,
) -> str:
    """Why a contact the robot holds (``held``: active and fully loaded) was lost, or ""."""
    for i, frame in enumerate(sensor.frames):
        if not held[i]:
            unloaded[i] = 0
            continue
        p, _ = sensor.frame_pose(data, i)
        if np.linalg.norm(p - p0[i]) > slip:
            hint = (
                " (the foot is simulated with its mesh, whose hull may rest on a few points: "
                "'contact_geometry: box' simulates it as its sole box)"
                if sensor.mesh_foot[i]
                else ""
            )
            return f"contact {frame!r} moved {1e3 * np.linalg.norm(p - p0[i]):.1f} mm{hint}"
        unloaded[i] = unloaded[i] + 1 if wrench[6 * i + 2] <= 1e-6 else 0
        if unloaded[i] >= LOST_CONTACT_TICKS:
            return f"contact {frame!r} carried no load for {LOST_CONTACT_TICKS} ticks"
    return ""
