"""Prioritized kinematic control by regularised reduced QR (RQR-HQP paper, §II–IV).

A velocity-level controller: each tick it returns the generalized velocity q̇ (n = 6 + k, the
floating base included) that the kinematic runner integrates. Every task regulates its error to
zero through the first-order law of the paper's eq. (2),

    J q̇ = ẋ_d + λ e,    λ = the scenario task's ``kp`` [1/s],

with ``‖ẋ_d + λ e‖`` optionally capped per task (``speed_limits``; the paper caps the hand at
0.25 m/s). The levels handed to :func:`wbcbench.qp.hls.solve_hls`, highest first:

1. ``contacts`` — every contact frame's 6-D velocity is zero (LOCAL frame). With
   ``base: support_foot`` the first contact is the kinematic root instead (paper §IV-B: "a foot
   is conveniently considered as the base link"): the floating-base velocity is eliminated through
   it, v_base = −B⁻¹ J_joints q̇_j, the variables are the k joint rates and only the other contacts
   are rows.
2. ``constraints`` — the inequalities, kept by every lower level (§III): joint limits
   ξ (q_min − q) ≤ q̇ ≤ ξ (q_max − q) (eq. 48–50, ξ = 0.5 s⁻¹) intersected with the velocity
   bounds; the CoM inside the support polygon, a_eᵀ ċ_xy ≤ ξ_c (b_e − margin − a_eᵀ c_xy)
   (``com: polygon``); self-collision between capsule pairs and capsule–box obstacle avoidance,
   ḋ ≥ −ξ_d (d − d_safe) (eq. 51–53). With ``com: fixed`` the horizontal CoM is regulated to its
   initial value instead (ċ_xy = −ξ_c (c_xy − c0_xy), the paper's 2 CoM equalities), as a task of
   this level so that the inequalities bound it.
3. the scenario's tasks, one level per priority (tasks of equal priority stacked), damped by
   Tikhonov regularisation (``damping``), and the optional gaze task (eq. 54–55).

``hierarchy: svd | full_qr`` runs the paper's baselines (Fig. 1) in closed loop; they take
equality levels only, so they need ``inequalities: false``.

``impl: native`` runs the whole tick in C++ (``wbcbench/_native/src/controllers/kin_hqp.cpp``,
the mirror of :meth:`KinHqp.build` and :meth:`KinHqp.solve`): the Pinocchio pass, the tasks'
references, the gaze, the root map, the collision pairs (``src/tasks/collision.cpp``, the mirror
of :mod:`wbcbench.tasks.collision`), the levels written in place into the native hierarchy solver
(:mod:`wbcbench.qp.hls_native`) and q̇. What the tick needs is handed over once, by
:meth:`KinHqp.configure_tick` at start; per tick only (q, v, t) cross. :meth:`KinHqp.build` stays
the reference formulation, and :meth:`KinHqp.solve` solves its levels with either impl.

A velocity-level controller computes no torque, acceleration or wrench: ``ControlOutput.tau``,
``qdd`` and ``wrench`` are zero-size arrays and ``qd`` holds the command.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, PositiveFloat, model_validator
from scipy.spatial import ConvexHull

from wbcbench import _native
from wbcbench.controllers.base import (
    ControllerConfig,
    ControllerContext,
    ControlOutput,
    NativeImplConfig,
    StageTimer,
)
from wbcbench.controllers.native import NativeController, NativeTimer, priority_groups
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import SolverError, UnknownNameError, WbcBenchError
from wbcbench.qp.hls import HlsResult, Level
from wbcbench.qp.hls_baselines import get_algorithm
from wbcbench.qp.hls_native import NativeHls, hls_result
from wbcbench.robots.loader import Robot
from wbcbench.scenarios.schema import Scenario
from wbcbench.tasks.collision import Box, CollisionModel, CollisionTerms, robot_capsules
from wbcbench.tasks.tasks import Task, TaskTerm

Array = NDArray[np.float64]

# Default collision pairs of the generated robots: hands and forearms against each other, the
# torso, the head, the pelvis and the thighs (16 pairs, paper §IV-B), and the arms' distal
# capsules against obstacles.
_ARM = {
    "comanplus_like": ("Elbow_link", "ForearmPlate_link", "Wrist1_link", "Wrist2_link"),
    "tocabi_like": ("Elbow_link", "Forearm_link", "Wrist1_link", "Wrist2_link"),
}
_THIGH = {"comanplus_like": "HipYaw_link", "tocabi_like": "HipPitch_link"}


def default_self_pairs(robot_name: str) -> list[tuple[str, str]]:
    """The 16 self-collision pairs of a generated robot (empty for other robots)."""
    if robot_name not in _ARM:
        return []
    _, forearm, _, hand = _ARM[robot_name]
    thigh = _THIGH[robot_name]
    pairs = [
        (f"L_{hand}", f"R_{hand}"),
        (f"L_{forearm}", f"R_{forearm}"),
        (f"L_{hand}", f"R_{forearm}"),
        (f"R_{hand}", f"L_{forearm}"),
        (f"L_{hand}", f"L_{thigh}"),
        (f"R_{hand}", f"R_{thigh}"),
    ]
    for side in "LR":
        pairs += [
            (f"{side}_{hand}", "torso"),
            (f"{side}_{forearm}", "torso"),
            (f"{side}_{hand}", "head"),
            (f"{side}_{hand}", "pelvis"),
            (f"{side}_{_ARM[robot_name][0]}", "pelvis"),
        ]
    return pairs


def default_obstacle_bodies(robot_name: str) -> list[str]:
    """Bodies checked against obstacles: both arms from the elbow down (empty for others)."""
    return [f"{s}_{b}" for s in "LR" for b in _ARM.get(robot_name, ())]


# --------------------------------------------------------------------------------------------
# Settings
# --------------------------------------------------------------------------------------------


class GazeSpec(BaseModel):
    """Keep a frame axis pointed at a world point (paper eq. 54–55)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = "gaze"
    frame: str = "head"
    axis: Literal["x", "y", "z"] = Field("x", description="the optical axis, in the frame")
    target: tuple[float, float, float] = Field(description="world point to look at [m]")
    priority: int = Field(2, ge=1, description="level, counted like the scenario tasks")
    gain: float = Field(1.0, gt=0, description="λ [1/s]")
    speed_limit: float | None = Field(None, gt=0, description="cap on ‖λ (v × p)‖ [m/s]")


def velocity_bounds(limit: float | None, robot: Robot) -> Array:
    """The joints' velocity bounds (k,) [rad/s]: one ``limit`` for all, else the model's."""
    if limit is not None:
        return np.full(robot.k, limit)
    return np.asarray(robot.v_max, dtype=float)


def gaze_task(spec: GazeSpec | None, robot: Robot) -> GazeTask | None:
    """The gaze row the settings ask for (None without one); an unknown frame fails here."""
    if spec is None:
        return None
    robot.frame_id(spec.frame)
    return GazeTask(
        name=spec.name,
        priority=spec.priority,
        kp=spec.gain,
        frame=spec.frame,
        axis="xyz".index(spec.axis),
        target=np.asarray(spec.target, dtype=float),
    )


def collision_bodies(
    self_collision: list[tuple[str, str]] | None,
    obstacle_bodies: list[str] | None,
    robot: Robot,
) -> tuple[list[tuple[str, str]], list[str]]:
    """The capsule pairs checked against each other and the bodies checked against obstacles:
    the settings', else the robot's defaults."""
    pairs = self_collision if self_collision is not None else default_self_pairs(robot.name)
    bodies = obstacle_bodies if obstacle_bodies is not None else default_obstacle_bodies(robot.name)
    return pairs, bodies


def name_errors(
    spec: Scenario,
    robot: Robot,
    speed_limits: dict[str, float],
    self_collision: list[tuple[str, str]] | None,
    obstacle_bodies: list[str] | None,
) -> list[tuple[str, str]]:
    """``(key, message)`` for each speed limit that names no task of the scenario and each
    collision body without a capsule (the settings kin_hqp and its peers share)."""
    out: list[tuple[str, str]] = []
    tasks = [t.name for t in spec.tasks]
    for name in speed_limits:
        if name not in tasks:
            out.append((f"speed_limits.{name}", str(UnknownNameError("task", name, tasks))))
    capsules = sorted(robot_capsules(robot))
    for i, pair in enumerate(self_collision or []):
        for j, body in enumerate(pair):
            if body not in capsules:
                error = UnknownNameError("capsule body", body, capsules)
                out.append((f"self_collision[{i}][{j}]", str(error)))
    for i, body in enumerate(obstacle_bodies or []):
        if body not in capsules:
            error = UnknownNameError("capsule body", body, capsules)
            out.append((f"obstacle_bodies[{i}]", str(error)))
    return out


class KinHqpConfig(NativeImplConfig):
    """Settings of the prioritized kinematic controller (defaults: the paper's values)."""

    hierarchy: Literal["rqr", "svd", "full_qr"] = Field(
        "rqr", description="reduced regularised QR with active sets, or the Fig. 1 baselines"
    )
    inequalities: bool = Field(True, description="joint, CoM-polygon and collision inequalities")
    base: Literal["floating", "support_foot"] = Field(
        "floating",
        description="variables q̇ (6 + k), or k joint rates with the first contact "
        "as the kinematic root (the paper's choice)",
    )
    com: Literal["polygon", "fixed", "free"] = Field(
        "polygon", description="CoM kept inside the support polygon, held horizontally, or free"
    )
    com_gain: float = Field(1.0, gt=0, description="ξ_c [1/s]")
    com_margin: float = Field(0.02, ge=0, description="polygon shrink [m]")
    joint_limit_gain: float = Field(0.5, gt=0, description="ξ of eq. 48–50 [1/s]")
    velocity_limit: float | None = Field(
        None, gt=0, description="|q̇_j| bound on every joint [rad/s]; default: the robot's"
    )
    collision_gain: float = Field(0.5, gt=0, description="ξ_d of eq. 52 [1/s]")
    collision_margin: float = Field(0.005, ge=0, description="d_safe [m]")
    self_collision: list[tuple[str, str]] | None = Field(
        None, description="body pairs; default: 16 pairs for the generated robots"
    )
    obstacle_bodies: list[str] | None = Field(
        None, description="bodies checked against every obstacle; default: arms below the elbow"
    )
    speed_limits: dict[str, PositiveFloat] = Field(
        default_factory=dict, description="task name → cap on ‖ẋ_d + λ e‖ [m/s or rad/s], > 0"
    )
    damping: float = Field(1e-3, ge=0, description="Tikhonov factor of the task levels")
    gaze: GazeSpec | None = None

    def robot_errors(self, spec: Scenario, robot: Robot) -> list[tuple[str, str]]:
        """Speed limits name the scenario's tasks; collision bodies have capsules."""
        return name_errors(
            spec, robot, self.speed_limits, self.self_collision, self.obstacle_bodies
        )

    @model_validator(mode="after")
    def _baselines_take_equalities(self) -> KinHqpConfig:
        if self.hierarchy != "rqr" and self.inequalities:
            raise ValueError(
                f"hierarchy {self.hierarchy!r} handles equality levels only; "
                "set inequalities: false (or hierarchy: rqr)"
            )
        return self


# --------------------------------------------------------------------------------------------
# The gaze task (velocity level only)
# --------------------------------------------------------------------------------------------


@dataclass
class GazeTerm(TaskTerm):
    """A gaze term; ``angle`` is the angle between the axis and the target direction [rad]."""

    angle: float = 0.0


@dataclass
class GazeTask(Task):
    """f = v × p = 0 with v the frame's unit axis and p = target − origin (paper eq. 54).

    ḟ = ([p]× [v]× J_ω − [v]× J_o) q̇ (eq. 55), J_o and J_ω the frame's world linear and angular
    Jacobians. The reported error is the angle between v and p [rad]. Only velocity-level
    controllers use it (it has no acceleration-level drift).
    """

    frame: str = "head"
    axis: int = 0
    target: Array = field(default_factory=lambda: np.zeros(3))
    kind: ClassVar[str] = "orientation"

    def _full_jacobian(self, state: RobotState) -> np.ndarray:
        raise TypeError("GazeTask.evaluate builds its Jacobian directly; this is never called")

    def _full_drift(self, state: RobotState) -> np.ndarray:
        return np.zeros(3)

    def _value(self, state: RobotState) -> np.ndarray:
        return np.zeros(3)

    def evaluate(self, state: RobotState, t: float) -> TaskTerm:
        M = state.placement(self.frame)
        v = M.rotation[:, self.axis]
        p = self.target - M.translation
        J6 = state.jacobian(self.frame)
        vx, px = pin.skew(v), pin.skew(p)
        J = px @ vx @ J6[3:] - vx @ J6[:3]
        f = np.cross(v, p)
        angle = float(np.arctan2(np.linalg.norm(f), v @ p))
        zeros = np.zeros(3)
        return GazeTerm(self, J, zeros, zeros, -f, zeros, angle=angle)

    def error_norms(self, term: TaskTerm) -> dict[str, float]:
        return {"rot": float(getattr(term, "angle", np.nan))}


# --------------------------------------------------------------------------------------------
# The problem of one tick
# --------------------------------------------------------------------------------------------


@dataclass
class KinematicProblem:
    """Everything one tick hands to the hierarchy solver.

    Attributes:
        levels: the hierarchy, in the solver's variables.
        T: (n, nx) map from the solver's variables to q̇ (identity for a floating base).
        terms: evaluated tasks (scenario tasks and the gaze).
        n_eq: equality rows (contacts and CoM hold).
        n_ineq: one-sided inequality rows (finite bounds).
        n_task: task rows.
        collisions: distances and gradients of the collision pairs.
    """

    levels: list[Level]
    T: Array
    terms: list[TaskTerm]
    n_eq: int
    n_ineq: int
    n_task: int
    collisions: CollisionTerms


def _cap(b: Array, limit: float | None) -> Array:
    """Scale ``b`` down so that ‖b‖ ≤ limit (the paper's bounded regulation, eq. 47)."""
    if limit is None:
        return b
    norm = float(np.linalg.norm(b))
    return b if norm <= limit else b * (limit / norm)


def support_polygon(state: RobotState, contacts: list) -> tuple[Array, Array]:
    """Outward normals (E, 2) and offsets (E,) of the feet's convex hull: a p ≤ b inside."""
    pts = []
    for c in contacts:
        M = state.placement(c.frame)
        for x in c.x_range:
            for y in c.y_range:
                pts.append(M.act(np.array([x, y, 0.0]))[:2])
    hull = ConvexHull(np.asarray(pts))
    # qhull's equations are [a, −b] with a unit outward normals: a·p − b ≤ 0 inside.
    eq = hull.equations
    return eq[:, :2].copy(), -eq[:, 2].copy()


class KinHqp(NativeController):
    """Prioritized inverse kinematics: regularised reduced QR with active sets."""

    name = "kin_hqp"
    summary = "prioritized kinematic control (RQR-HQP): velocity-level HLS, inequalities"
    kind = "velocity"
    tick_type = "KinHqpTick"
    #: the hierarchy is solved by wbcbench.qp.hls, not by a QP backend
    own_solver = "hls"
    Config = KinHqpConfig
    config: KinHqpConfig

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        cfg = self.config
        robot = ctx.robot
        self.frames = ctx.contact_frames
        if cfg.base == "support_foot" and not self.frames:
            raise WbcBenchError("kin_hqp: base 'support_foot' needs at least one contact")
        if cfg.com == "polygon" and cfg.inequalities and not ctx.contacts:
            raise WbcBenchError("kin_hqp: com 'polygon' needs contacts (or com: free)")
        self.v_max = velocity_bounds(cfg.velocity_limit, robot)
        self.gaze = gaze_task(cfg.gaze, robot)
        self._pairs, self._obstacle_bodies = collision_bodies(
            cfg.self_collision, cfg.obstacle_bodies, robot
        )
        self.collision = CollisionModel(robot, self._pairs)
        self._com0 = np.zeros(2)
        self._polygon: tuple[Array, Array] | None = None
        #: the algorithm's name in ``hls_baselines.ALGORITHMS``
        self.algorithm = "reduced_qr" if cfg.hierarchy == "rqr" else cfg.hierarchy
        self._solve = get_algorithm(self.algorithm)
        self._native: NativeHls | None = NativeHls() if self.impl == "native" else None

    # -- environment and start --------------------------------------------------------------

    def use_environment(self, obstacles: list[Box]) -> None:
        """Fixed boxes to avoid (the scenario's ``environment.obstacles``)."""
        self.collision = CollisionModel(
            self.ctx.robot, self._pairs, self._obstacle_bodies if obstacles else (), obstacles
        )
        self.native_tick = None  # the next start() hands the new pairs over

    def on_start(self, state: RobotState) -> None:
        """The gaze's start, the CoM to hold and the support polygon."""
        if self.gaze is not None:
            self.gaze.start(state)
        self._com0 = state.com[:2].copy()
        if self.ctx.contacts:
            # The feet are held, so their support polygon is fixed for the run.
            self._polygon = support_polygon(state, self.ctx.contacts)

    def configure_tick(self, tick: Any) -> None:
        """Once the tasks, the CoM hold and the support polygon are fixed: the settings, the
        collision pairs, the gaze and the task levels."""
        cfg, robot = self.config, self.ctx.robot
        core = _native.core()
        tasks = list(self.ctx.tasks)
        s = core.KinHqpSettings()
        s.algorithm = getattr(core.HlsAlgorithm, self.algorithm)
        s.inequalities = cfg.inequalities
        s.support_foot = cfg.base == "support_foot"
        s.com = getattr(core.KinCom, cfg.com)
        s.com_gain, s.com_margin = cfg.com_gain, cfg.com_margin
        s.joint_limit_gain = cfg.joint_limit_gain
        s.collision_gain, s.collision_margin = cfg.collision_gain, cfg.collision_margin
        s.damping = cfg.damping
        s.q_min = np.asarray(robot.q_min, dtype=float)
        s.q_max = np.asarray(robot.q_max, dtype=float)
        s.v_max = np.asarray(self.v_max, dtype=float)
        s.com0 = self._com0
        a, b = self._polygon if self._polygon is not None else (np.zeros((0, 2)), np.zeros(0))
        s.polygon_a, s.polygon_b = a, b
        s.speed_limits = np.array([cfg.speed_limits.get(t.name, np.inf) for t in tasks])
        # the frames read by id: the capsules' bodies, then the gaze's frame
        frames = [cap.frame_id for cap in self.collision.bodies]
        terms: list[Task] = list(tasks)
        if self.gaze is not None and cfg.gaze is not None:
            gaze = core.KinGaze()
            gaze.on = True
            gaze.frame = len(frames)
            gaze.axis = self.gaze.axis
            gaze.target = np.asarray(self.gaze.target, dtype=float)
            gaze.gain = cfg.gaze.gain
            gaze.speed_limit = np.inf if cfg.gaze.speed_limit is None else cfg.gaze.speed_limit
            s.gaze = gaze
            frames.append(robot.frame_id(self.gaze.frame))
            terms.append(self.gaze)
        _, groups = priority_groups(terms)
        s.task_levels = groups
        s.task_level_names = ["+".join(terms[i].name for i in group) for group in groups]
        capsules = []
        for i, cap in enumerate(self.collision.bodies):
            spec = core.CapsuleSpec()
            spec.frame, spec.p0, spec.p1, spec.radius = i, cap.p0, cap.p1, cap.radius
            capsules.append(spec)
        boxes = []
        for box in self.collision.obstacles:
            spec = core.BoxSpec()
            spec.center, spec.R, spec.half = box.center, box.R, box.half
            boxes.append(spec)
        self_pairs, obstacle_pairs = self.collision.index_pairs
        tick.configure(s, frames, capsules, self_pairs, boxes, obstacle_pairs)

    def native_region(
        self, q: np.ndarray, v: np.ndarray, t: float, timer: NativeTimer
    ) -> str | None:
        """The timed region: the whole tick (dynamics, build, solve, q̇)."""
        tick = self.native_tick
        return None if tick.run(q, v, t) else f"kin_hqp: {tick.solver.message}"

    def native_terms(self) -> list[TaskTerm]:
        """The tasks' terms, then the gaze's."""
        terms = super().native_terms()
        if self.gaze is not None:
            tick = self.native_tick
            error, zeros = tick.gaze_error.copy(), np.zeros(3)
            J = tick.gaze_jacobian.copy()
            terms.append(GazeTerm(self.gaze, J, zeros, zeros, error, zeros, tick.gaze_angle))
        return terms

    def native_output(
        self, state: RobotState, timer: NativeTimer, message: str | None
    ) -> ControlOutput:
        """q̇ and the same diagnostics as :meth:`step`'s; the solve stage is the algorithm,
        timed inside the module (nothing crosses for it)."""
        tick = self.native_tick
        collisions = tick.collisions
        diag = _counts(tick.n_eq, tick.n_ineq, tick.n_task, collisions.d)
        terms = self.native_terms()
        if message is not None:
            return _failed(state.n, terms, timer.finish(tick), message, diag)
        res = hls_result(tick.solver, tick.level_names)
        timer.solve += res.time
        timer.solve_native += res.time
        timer.solve_internal += res.time
        iterations = _level_diagnostics(res, timer, diag)
        return ControlOutput(
            tau=np.zeros(0),
            qdd=np.zeros(0),
            wrench=np.zeros(0),
            terms=terms,
            timings=timer.finish(tick),
            qd=tick.qd.copy(),
            iterations=float(iterations),
            diagnostics=diag,
        )

    # -- formulation ------------------------------------------------------------------------

    def _root_map(self, state: RobotState) -> Array:
        """(n, nx): q̇ = T x. Identity, or the support-foot elimination of the base."""
        n = state.n
        if self.config.base == "floating":
            return np.eye(n)
        Jc = state.jacobian(self.frames[0], local=True)
        T = np.empty((n, state.k))
        T[:6] = -np.linalg.solve(Jc[:, :6], Jc[:, 6:])
        T[6:] = np.eye(state.k)
        return T

    def _task_rows(self, state: RobotState, t: float) -> tuple[list[TaskTerm], list[Array]]:
        """Evaluated tasks and their velocity references ẋ_d + λ e (capped)."""
        terms: list[TaskTerm] = []
        refs: list[Array] = []
        for task in self.ctx.tasks:
            term = task.evaluate(state, t)
            # ẋ_d from the term: error_vel = ẋ_d − J v
            xd_d = term.error_vel + term.J @ state.v
            ref = xd_d + task.kp * term.error
            refs.append(_cap(ref, self.config.speed_limits.get(task.name)))
            terms.append(term)
        if self.gaze is not None:
            g = self.config.gaze
            assert g is not None
            term = self.gaze.evaluate(state, t)
            refs.append(_cap(g.gain * term.error, g.speed_limit))  # error = −(v × p)
            terms.append(term)
        return terms, refs

    def build(self, state: RobotState, t: float) -> KinematicProblem:
        """The hierarchy of this tick (no solving)."""
        cfg = self.config
        T = self._root_map(state)
        nx = T.shape[1]
        levels: list[Level] = []
        n_eq = 0

        # 1. contacts
        frames = self.frames[1:] if cfg.base == "support_foot" else self.frames
        if frames:
            Ac = state.contact_jacobian(frames) @ T
            levels.append(Level(Ac, np.zeros(Ac.shape[0]), name="contacts"))
            n_eq += Ac.shape[0]

        # 2. inequalities (and the CoM hold, bounded by them)
        A_com = b_com = None
        if cfg.com == "fixed":
            A_com = state.J_com[:2] @ T
            b_com = -cfg.com_gain * (state.com[:2] - self._com0)
            n_eq += 2
        collisions = self.collision.evaluate(state)
        C_rows: list[Array] = []
        lo: list[Array] = []
        hi: list[Array] = []
        if cfg.inequalities:
            q = state.q[7:]
            xi = cfg.joint_limit_gain
            lower = np.maximum(xi * (self.ctx.robot.q_min - q), -self.v_max)
            upper = np.minimum(xi * (self.ctx.robot.q_max - q), self.v_max)
            # Outside a limit, the limit's pull wins over the velocity bound.
            lower = np.minimum(lower, upper)
            C_rows.append(T[6:])
            lo.append(lower)
            hi.append(upper)
            if cfg.com == "polygon" and self._polygon is not None:
                a, b = self._polygon
                C_rows.append(a @ (state.J_com[:2] @ T))
                hi.append(cfg.com_gain * (b - cfg.com_margin - a @ state.com[:2]))
                lo.append(np.full(a.shape[0], -np.inf))
            if collisions.d.size:
                C_rows.append(collisions.grad @ T)
                lo.append(-cfg.collision_gain * (collisions.d - cfg.collision_margin))
                hi.append(np.full(collisions.d.size, np.inf))
        n_ineq = 0
        if C_rows or A_com is not None:
            C = np.vstack(C_rows) if C_rows else None
            lo_v = np.concatenate(lo) if lo else None
            hi_v = np.concatenate(hi) if hi else None
            if lo_v is not None and hi_v is not None:
                n_ineq = int(np.isfinite(lo_v).sum() + np.isfinite(hi_v).sum())
            levels.append(Level(A_com, b_com, C, lo_v, hi_v, name="constraints"))

        # 3. tasks, one level per priority
        terms, refs = self._task_rows(state, t)
        prios = sorted({term.task.priority for term in terms})
        n_task = 0
        for p in prios:
            idx = [i for i, term in enumerate(terms) if term.task.priority == p]
            A = np.vstack([terms[i].J for i in idx]) @ T
            b = np.concatenate([refs[i] for i in idx])
            name = "+".join(terms[i].task.name for i in idx)
            levels.append(Level(A, b, name=name, damping=cfg.damping))
            n_task += A.shape[0]
        if not levels:
            levels.append(Level(np.zeros((0, nx)), np.zeros(0), name="empty"))
        return KinematicProblem(levels, T, terms, n_eq, n_ineq, n_task, collisions)

    # -- the step ---------------------------------------------------------------------------

    def solve(self, problem: KinematicProblem) -> HlsResult:
        """Solve the hierarchy with the configured algorithm and impl (raises SolverError); with
        ``impl: native`` the levels are copied into the native solver (the native step builds
        them natively instead)."""
        if self._native is not None:
            self._native.load(problem.levels)
            return self._native.solve(self.algorithm)
        return self._solve(problem.levels)

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        timer = StageTimer(state)
        problem = self.build(state, t)
        diag = _counts(problem.n_eq, problem.n_ineq, problem.n_task, problem.collisions.d)
        t0 = time.perf_counter()
        try:
            res = self.solve(problem)
        except SolverError as exc:
            return _failed(state.n, problem.terms, timer.finish(), f"kin_hqp: {exc}", diag)
        # solve: the whole call; solve_internal: the algorithm itself
        timer.solve += time.perf_counter() - t0
        timer.solve_internal += res.time
        iterations = _level_diagnostics(res, timer, diag)
        return ControlOutput(
            tau=np.zeros(0),
            qdd=np.zeros(0),
            wrench=np.zeros(0),
            terms=problem.terms,
            timings=timer.finish(),
            qd=problem.T @ res.x,
            iterations=float(iterations),
            diagnostics=diag,
        )


def _counts(n_eq: int, n_ineq: int, n_task: int, distances: Array) -> dict[str, float]:
    """The step's row counts and its smallest collision distance (when it checks pairs)."""
    diag = {"n_eq": float(n_eq), "n_ineq": float(n_ineq), "n_task": float(n_task)}
    if distances.size:
        diag["min_distance"] = float(distances.min())
    return diag


def _level_diagnostics(res: HlsResult, timer: Any, diag: dict[str, float]) -> int:
    """Per level: ``solve.<level>`` time, iterations, active rows and residual; returns the
    total iterations."""
    iterations = 0
    for lv in res.levels:
        timer.levels[f"solve.{lv.name}"] = lv.time
        diag[f"iter.{lv.name}"] = float(lv.iterations)
        diag[f"active.{lv.name}"] = float(lv.n_active)
        diag[f"residual.{lv.name}"] = lv.residual
        iterations += lv.iterations
    diag["active"] = float(sum(lv.n_active for lv in res.levels))
    return iterations


def _failed(
    n: int, terms: list[TaskTerm], timings: dict[str, float], message: str, diag: dict[str, float]
) -> ControlOutput:
    """A failed step: q̇ = 0 (the runner holds the posture) and why."""
    empty = np.zeros(0)
    return ControlOutput(
        tau=empty,
        qdd=empty,
        wrench=empty,
        terms=terms,
        timings=timings,
        qd=np.zeros(n),
        ok=False,
        message=message,
        diagnostics=diag,
    )
