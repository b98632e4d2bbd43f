"""What the two peers share: settings, the tasks' velocity references, the step and its timing.

Both libraries solve **one weighted least-squares QP** a tick over the displacement Δq = q̇ dt
(``build_ik``, then ``qpsolvers.solve_problem``)::

    min_Δq  Σ_i ‖W_i (J_i Δq + α_i e_i)‖² + damping ‖Δq‖²
    s.t.    G Δq ≤ h      (the limits)
            A Δq = b      (the tasks given as ``constraints``)

with e_i the library's task error, J_i its Jacobian, α_i its gain and W_i = diag(cost). Strict
priorities do not exist there: the scenario's priority p becomes the cost factor
``priority_ratio^-(p-1)`` (a task's own ``weight`` w, when set, the factor √w), so a lower task
that conflicts with a higher one pulls it off its reference by an amount the ratio sets.

**The velocity references.** ``kin_hqp`` regulates every task by J q̇ = r, r = ẋ_d + λ e
(λ = the task's ``kp`` [1/s], ‖r‖ capped by ``speed_limits``). The peers compute the same r
and hand it to the library's own task as a target one control period ahead, x ⊕ dt·r, with
the library's gain 1: its law J Δq = −(x ⊖ target) then asks J q̇ = r, exactly for the CoM
and joints, and to first order in dt for frames, whose error the libraries take through SE(3)'s
logarithm and its Jacobian (pink's frame Jacobian −Jlog6(T_tb) J_b at a target δ = dt·r away
couples in the frame's angular velocity ω: J q̇ − r of about ½ ‖δ‖ ‖ω‖, 4e-4 m/s on
rqr_reach's hand; mink's meets r to the QP's accuracy there). The feed-forward ẋ_d and the
caps (the paper's bounded regulation) are so expressed as kin_hqp expresses them, on the
reference.

**What maps to the libraries' tasks and limits** (the details per library in
:mod:`~wbcbench.peers.pink_ik` and :mod:`~wbcbench.peers.mink_ik`):

====================================  =====================================================
wbcbench                              pink / mink
====================================  =====================================================
``com`` (world axes, any subset)      ``ComTask``, cost 0 on the axes not selected
``frame_position``                    ``FrameTask``, orientation cost 0
``frame_orientation``                 ``FrameTask``, position cost 0
``frame_pose``                        ``FrameTask``; axis selection only of whole parts
                                      (all of x y z, all of rx ry rz): the libraries'
                                      costs weigh the frame's own axes, not the world's
``joint_posture`` (any joints)        ``PostureTask``, cost 0 on the joints not selected
``joint_damping``                     not expressed (the scenario is refused)
held contact frames                   ``FrameTask`` of each sole in ``constraints`` with gain
                                      0: J Δq = 0, hard, as kin_hqp's ``contacts`` level
joint position limits                 ``ConfigurationLimit``, gain ξ dt (ξ = 0.5 s⁻¹): the
                                      same bound ξ (q_max − q) as kin_hqp
velocity limits                       ``VelocityLimit`` (the robot's, or ``velocity_limit``)
``com: fixed``                        a ``ComTask`` on x, y with cost ``com_cost`` and the
                                      rate −ξ_c (c − c0): a cost, not kin_hqp's equality (the
                                      libraries' ``constraints`` take whole tasks, so a
                                      ComTask there would hold the CoM's height too)
``speed_limits``                      the same cap on r, before the target is set
====================================  =====================================================

What neither expresses: strict priorities (above); ``base: support_foot`` (the variables are
q̇ of the floating base and both soles are held by equalities, which fixes the same motions;
the damping also weighs the base's six rates); ``com: polygon`` (no CoM inequality in either
library; the scenario's CoM then moves only as its tasks ask); ``hierarchy`` and
``inequalities`` (one QP).

Collision distances are measured for every peer with kin_hqp's capsule model and pairs
(:class:`~wbcbench.tasks.collision.CollisionModel`, after the timed region, diagnostic
``min_distance``), so the three controllers report one measure; only ``mink`` also avoids them.
"""

from __future__ import annotations

import importlib
import importlib.util
import time
from abc import abstractmethod
from dataclasses import dataclass
from types import ModuleType
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from wbcbench.controllers.base import (
    Controller,
    ControllerConfig,
    ControllerContext,
    ControlOutput,
    StageTimer,
)
from wbcbench.controllers.kin_hqp import (
    GazeSpec,
    collision_bodies,
    gaze_task,
    name_errors,
    velocity_bounds,
)
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError, UnknownNameError
from wbcbench.robots.loader import Robot
from wbcbench.scenarios.schema import Scenario
from wbcbench.tasks.collision import Box, CollisionModel
from wbcbench.tasks.tasks import (
    JointDampingTask,
    JointPostureTask,
    Task,
    TaskTerm,
)

Array = NDArray[np.float64]

#: the command that installs the peer libraries
INSTALL = "pip install 'wbcbench[peers]'"

#: the QP backends qpsolvers offers that the lock installs
QP_SOLVERS = ("daqp", "proxqp", "quadprog", "osqp", "clarabel", "piqp", "highs")


def missing_library(module: str, distribution: str) -> str:
    """Why the peer library cannot be used ("" when it is importable)."""
    if importlib.util.find_spec(module) is not None:
        return ""
    return f"{distribution} (module {module!r}) is not installed: {INSTALL}"


def import_library(controller: str, module: str, distribution: str) -> ModuleType:
    """The library's module, imported now.

    Raises:
        ControllerError: naming the controller, the distribution and the install command.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ControllerError(
            f"{controller}: needs {distribution} (module {module!r}), which cannot be imported "
            f"({exc}); install the peers extra: {INSTALL}"
        ) from None


class PeerConfig(ControllerConfig):
    """Settings shared by the peers (defaults: kin_hqp's where both have the setting)."""

    solver: Literal["daqp", "proxqp", "quadprog", "osqp", "clarabel", "piqp", "highs"] = Field(
        "daqp", description="the qpsolvers backend that solves the library's QP"
    )
    damping: float = Field(
        1e-6, ge=0, description="Tikhonov weight on ‖Δq‖² beside the tasks' squared residuals"
    )
    priority_ratio: float = Field(
        10.0, ge=1, description="cost of priority p: priority_ratio^-(p-1) (of the residual)"
    )
    limits: bool = Field(True, description="joint position and velocity limits")
    joint_limit_gain: float = Field(0.5, gt=0, description="ξ of kin_hqp's joint limits [1/s]")
    velocity_limit: float | None = Field(
        None, gt=0, description="|q̇_j| bound on every joint [rad/s]; default: the robot's"
    )
    com: Literal["fixed", "free"] = Field(
        "free", description="hold the horizontal CoM (a weighted task) or leave it free"
    )
    com_gain: float = Field(1.0, gt=0, description="ξ_c of the CoM hold [1/s]")
    com_cost: float = Field(
        10.0, gt=0, description="cost of the CoM hold, relative to a priority-1 task"
    )
    speed_limits: dict[str, float] = Field(
        default_factory=dict, description="task name → cap on ‖ẋ_d + λ e‖ [m/s or rad/s]"
    )
    gaze: GazeSpec | None = None
    self_collision: list[tuple[str, str]] | None = Field(
        None, description="capsule body pairs measured; default: kin_hqp's 16 pairs"
    )
    obstacle_bodies: list[str] | None = Field(
        None, description="capsule bodies measured against obstacles; default: kin_hqp's"
    )

    def robot_errors(self, spec: Scenario, robot: Robot) -> list[tuple[str, str]]:
        """Speed limits name the scenario's tasks; collision bodies have capsules."""
        out = name_errors(spec, robot, self.speed_limits, self.self_collision, self.obstacle_bodies)
        if self.gaze is not None and not robot.has_frame(self.gaze.frame):
            error = UnknownNameError("frame", self.gaze.frame, robot.frame_names)
            out.append(("gaze.frame", str(error)))
        return out


@dataclass
class Reference:
    """One scenario task at one tick, in its full dimension (the axes it does not select are
    zero, with cost 0).

    Attributes:
        task: the scenario's task.
        term: its evaluation (for the logs).
        rate: r = ẋ_d + λ e on the selected axes, capped (full dim,) [m/s, rad/s].
        cost: the cost of each axis (full dim,): the priority's factor, 0 off the selection.
        rows: the selected axes' indices into the full dimension (m,).
    """

    task: Task
    term: TaskTerm
    rate: Array
    cost: Array
    rows: NDArray[np.intp]


@dataclass
class GazeReference:
    """The gaze at one tick.

    Attributes:
        term: its evaluation (error −(v × p) [m], for the logs).
        rate: −λ (v × p), capped [m/s].
        gain: λ [1/s].
    """

    term: TaskTerm
    rate: Array
    gain: float


def cap(b: Array, limit: float | None) -> Array:
    """``b`` scaled down so that ‖b‖ ≤ limit (kin_hqp's bounded regulation)."""
    if limit is None:
        return b
    norm = float(np.linalg.norm(b))
    return b if norm <= limit else b * (limit / norm)


def unsupported_task(spec: Scenario) -> str:
    """Why the libraries' tasks cannot express one of the scenario's tasks ("" when they can)."""
    for i, task in enumerate(spec.tasks):
        if task.type == "joint_damping":
            return f"tasks[{i}] ({task.name}): joint_damping has no velocity-level counterpart"
        if task.type == "frame_pose" and task.axes is not None:
            axes = set(task.axes)
            for part in ({"x", "y", "z"}, {"rx", "ry", "rz"}):
                if axes & part and not part <= axes:
                    return (
                        f"tasks[{i}] ({task.name}): axes {task.axes} select part of a frame's "
                        "position or orientation in world axes; the libraries' frame tasks "
                        "weigh the frame's own axes"
                    )
        if task.type in ("frame_position", "frame_orientation") and task.axes is not None:
            if len(task.axes) != 3:
                return (
                    f"tasks[{i}] ({task.name}): axes {task.axes} select world axes of a frame "
                    "task; the libraries' frame tasks weigh the frame's own axes"
                )
    return ""


class PeerController(Controller):
    """The step both peers share; a peer supplies its library's model, targets and QP.

    A subclass sets ``name``, ``summary``, ``Config``, ``library`` and ``distribution``, and
    implements :meth:`_setup`, :meth:`_update`, :meth:`_set_targets`, :meth:`_extra_tasks` and
    :meth:`_velocity`; its ``_setup`` makes the library's ``configuration``, ``tasks``,
    ``contacts`` (held as constraints) and ``limits``.
    """

    kind = "velocity"
    #: the library's QP goes to qpsolvers with the config's ``solver``, not to the run's backend
    own_solver = "qpsolvers"
    Config = PeerConfig
    config: PeerConfig
    #: the module to import and the distribution that provides it
    library: ClassVar[str] = ""
    distribution: ClassVar[str] = ""
    #: the library's objects, made by ``_setup``
    configuration: Any
    tasks: list[Any]
    contacts: list[Any]
    limits: list[Any]

    @classmethod
    def applies_to(cls, scenario: Scenario) -> str:
        """Kinematic scenarios whose tasks the library expresses, with the library installed."""
        return (
            super().applies_to(scenario)
            or missing_library(cls.library, cls.distribution)
            or unsupported_task(scenario)
        )

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.lib = import_library(self.name, self.library, self.distribution)
        self.qpsolvers = import_library(self.name, "qpsolvers", "qpsolvers")
        cfg, robot = self.config, ctx.robot
        if cfg.solver not in self.qpsolvers.available_solvers:
            raise ControllerError(
                f"{self.name}: solver {cfg.solver!r} is not installed for qpsolvers; valid "
                f"choices here: {', '.join(sorted(self.qpsolvers.available_solvers))}"
            )
        for task in ctx.tasks:
            if isinstance(task, JointDampingTask):
                raise ControllerError(f"{self.name}: task {task.name!r}: joint_damping")
        self.v_max = velocity_bounds(cfg.velocity_limit, robot)
        self.gaze = gaze_task(cfg.gaze, robot)
        self._pairs, self._obstacle_bodies = collision_bodies(
            cfg.self_collision, cfg.obstacle_bodies, robot
        )
        self.obstacles: list[Box] = []
        self.collision = CollisionModel(robot, self._pairs)
        self._com0 = np.zeros(3)
        self._setup()

    # -- what a peer supplies ----------------------------------------------------------------

    @abstractmethod
    def _setup(self) -> None:
        """Build the library's model, tasks and limits (once)."""

    @abstractmethod
    def _update(self, state: RobotState) -> None:
        """Run the library's kinematics at the state's configuration."""

    @abstractmethod
    def _set_targets(self, refs: list[Reference], gaze: GazeReference | None) -> None:
        """Set each library task's target one period ahead (and the CoM hold's, the gaze's)."""

    @abstractmethod
    def _extra_tasks(self) -> list[Any]:
        """The library tasks beside the scenario's (the CoM hold, the gaze), when configured."""

    @abstractmethod
    def _velocity(self, delta_q: Array, state: RobotState) -> Array:
        """q̇ (n,) in Pinocchio's convention from the library's displacement over one period."""

    def _build(self) -> Any:
        """The library's QP of this tick (a ``qpsolvers.Problem``), from its ``build_ik``."""
        return self.lib.build_ik(
            self.configuration,
            [*self.tasks, *self._extra_tasks()],
            self.ctx.dt,
            damping=self.config.damping,
            limits=self.limits,
            constraints=self.contacts,
        )

    # -- environment and start --------------------------------------------------------------

    def use_environment(self, obstacles: list[Box]) -> None:
        """The scenario's fixed boxes: measured against ``obstacle_bodies`` (by every peer;
        mink also avoids them)."""
        self.obstacles = list(obstacles)
        bodies = self._obstacle_bodies if obstacles else ()
        self.collision = CollisionModel(self.ctx.robot, self._pairs, bodies, self.obstacles)

    def start(self, state: RobotState) -> None:
        super().start(state)
        if self.gaze is not None:
            self.gaze.start(state)
        self._com0 = state.com.copy()
        self._start(state)

    def _start(self, state: RobotState) -> None:
        """Fix what the library holds from the initial state (the soles' targets)."""

    # -- references --------------------------------------------------------------------------

    def priority_cost(self, task: Task) -> float:
        """The cost factor of a task: √weight when it sets one, else by its priority."""
        if task.weight is not None:
            return float(np.sqrt(task.weight))
        return float(self.config.priority_ratio ** -(task.priority - 1))

    def references(self, state: RobotState, t: float) -> list[Reference]:
        """The scenario tasks' capped rates r = ẋ_d + λ e in their full dimension."""
        out = []
        for task in self.ctx.tasks:
            term = task.evaluate(state, t)
            xd_d = term.error_vel + term.J @ state.v
            rate = cap(xd_d + task.kp * term.error, self.config.speed_limits.get(task.name))
            if isinstance(task, JointPostureTask):
                # rows of J pick joint columns: the full dimension is the k joints
                rows = np.argmax(np.abs(term.J), axis=1) - 6
                full = np.zeros(self.ctx.robot.k)
            else:
                rows = np.array([task.full_axes.index(a) for a in task.axes], dtype=int)
                full = np.zeros(len(task.full_axes))
            r, c = full.copy(), full.copy()
            r[rows] = rate
            c[rows] = self.priority_cost(task)
            out.append(Reference(task, term, r, c, rows))
        return out

    def gaze_reference(self, state: RobotState, t: float) -> GazeReference | None:
        """The gaze's term and its capped rate −λ (v × p) (eq. 54) [m/s]."""
        if self.gaze is None or self.config.gaze is None:
            return None
        g = self.config.gaze
        term = self.gaze.evaluate(state, t)
        return GazeReference(term, cap(g.gain * term.error, g.speed_limit), g.gain)

    def com_hold_rate(self, com: Array) -> Array:
        """The CoM hold's rate −ξ_c (c − c0) on x, y (0 on z) [m/s]."""
        rate = -self.config.com_gain * (com - self._com0)
        rate[2] = 0.0
        return rate

    # -- the step ----------------------------------------------------------------------------

    def step(self, state: RobotState, t: float) -> ControlOutput:
        timer = StageTimer(state)
        refs = self.references(state, t)
        gaze = self.gaze_reference(state, t)
        t0 = time.perf_counter()
        self._update(state)
        kinematics = time.perf_counter() - t0
        self._set_targets(refs, gaze)
        problem = self._build()
        t0 = time.perf_counter()
        result = self.qpsolvers.solve_problem(problem, solver=self.config.solver)
        timer.solve += time.perf_counter() - t0
        found = bool(result.found) and result.x is not None
        qd = self._velocity(result.x, state) if found else np.zeros(state.n)
        timings = timer.finish()
        # the library's own kinematics pass counts as dynamics, as the RobotState's does
        timings["dynamics"] += kinematics
        timings["build"] = max(0.0, timings["build"] - kinematics)
        timings["solve_internal"] = float("nan")

        terms = [ref.term for ref in refs] + ([gaze.term] if gaze is not None else [])
        diag = problem_counts(problem)
        if found:
            diag.update(level_residuals(refs, gaze, qd))
        distances = self.collision.evaluate(state).d
        if distances.size:
            diag["min_distance"] = float(distances.min())
        empty = np.zeros(0)
        return ControlOutput(
            tau=empty,
            qdd=empty,
            wrench=empty,
            terms=terms,
            timings=timings,
            qd=qd,
            ok=found,
            message=""
            if found
            else f"{self.name}: {self.config.solver} found no solution of the IK QP",
            diagnostics=diag,
        )


def level_residuals(
    refs: list[Reference], gaze: GazeReference | None, qd: Array
) -> dict[str, float]:
    """``residual.<level>``: ‖J q̇ − r‖ of the tasks of each priority, named as kin_hqp names
    its levels (the task names joined by ``+``), so that the top level's residual shows how far
    the lower ones pulled it [m/s, rad/s]."""
    rows: list[tuple[int, str, Array, Array]] = [
        (ref.task.priority, ref.task.name, ref.term.J, ref.rate[ref.rows]) for ref in refs
    ]
    if gaze is not None:
        rows.append((gaze.term.task.priority, gaze.term.task.name, gaze.term.J, gaze.rate))
    out = {}
    for p in sorted({row[0] for row in rows}):
        level = [row for row in rows if row[0] == p]
        J = np.vstack([row[2] for row in level])
        r = np.concatenate([row[3] for row in level])
        name = "+".join(row[1] for row in level)
        out[f"residual.{name}"] = float(np.linalg.norm(J @ qd - r))
    return out


def problem_counts(problem: Any) -> dict[str, float]:
    """Row counts of a ``qpsolvers.Problem``: equalities, finite inequalities, variables."""
    n_eq = 0 if problem.A is None else int(problem.A.shape[0])
    n_ineq = 0 if problem.h is None else int(np.isfinite(problem.h).sum())
    return {"n_eq": float(n_eq), "n_ineq": float(n_ineq), "n_var": float(problem.P.shape[0])}
