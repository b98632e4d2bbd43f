"""The Python half of a controller's native tick (``impl: native``).

Set-up stays in Python: the robot's model, the tasks (once started), the limits and the
controller's settings are handed to a native tick object once. Per tick only ``(q, v, t)``
cross; the native object computes the dynamics, the task terms and the QP into buffers it owns,
and the QP reaches the solver as a :class:`~wbcbench.qp.Problem` whose arrays are views of those
buffers (built once, refilled in place). The solver's answer goes back for the torque.

Stages reported, as the Python path's :class:`~wbcbench.controllers.base.StageTimer` does:
``dynamics`` and ``build`` (timed natively), ``solve`` (the call into the QP layer, with
``solve_setup`` / ``solve_native`` / ``solve_internal`` inside), ``total``, and ``crossing``:
what is left of ``total``, i.e. the calls between Python and the module and the step's own
Python lines.

:class:`NativeController` holds all of that once: a controller with a native tick declares only
what is its own (the tick's type, its settings, its QPs or hierarchy, its diagnostics).
"""

from __future__ import annotations

import time
from abc import abstractmethod
from collections.abc import Sequence
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np

from wbcbench import _native
from wbcbench.controllers.base import (
    Controller,
    ControlOutput,
    NativeImplConfig,
    SolveTimes,
)
from wbcbench.dynamics.state import RobotState, contact_basis
from wbcbench.errors import ControllerError
from wbcbench.qp import Problem, Solution, SolutionStatus
from wbcbench.qp.hierarchy import accept_tol_for
from wbcbench.qp.registry import solver_class
from wbcbench.tasks.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    JointDampingTask,
    JointPostureTask,
    Task,
    TaskTerm,
)
from wbcbench.tasks.trajectories import (
    Constant,
    MinimumJerk,
    PiecewiseCubic,
    PiecewiseLinear,
    Sinusoid,
    Trajectory,
)

#: the reference trajectories the native side computes itself (handed over once); any other
#: (a walk's CoM plan, heading or swing path) is sampled in Python every tick
NATIVE_TRAJECTORIES = (Constant, Sinusoid, PiecewiseCubic, MinimumJerk, PiecewiseLinear)


def native_trajectory(traj: Trajectory, dim: int) -> Any:
    """The native form of a reference trajectory of ``dim`` rows: the same numbers, handed
    over once; a trajectory with no native form becomes a sampled one, whose value
    :meth:`NativeController.native_step` sets before every tick (``TaskSet.set_sample``)."""
    c = _native.core().Trajectory
    if isinstance(traj, Constant):
        return c.constant(np.asarray(traj.value, dtype=float))
    if isinstance(traj, Sinusoid):
        return c.sinusoid(
            np.asarray(traj.amplitude, dtype=float), traj.frequency, traj.t0, traj.phase
        )
    if isinstance(traj, PiecewiseCubic):
        coef = np.asarray(traj._coef)  # (4, segments, dim), highest power first
        stacked = np.ascontiguousarray(coef.transpose(1, 0, 2).reshape(-1, coef.shape[2]))
        return c.cubic(traj._breaks, stacked, traj._first, traj._last)
    if isinstance(traj, MinimumJerk):
        return c.minimum_jerk(traj._times, np.asarray(traj._values, dtype=float))
    if isinstance(traj, PiecewiseLinear):
        return c.linear(traj._times, np.asarray(traj._values, dtype=float))
    return c.sampled(dim)


#: the native task type of each task class (subclasses first)
_TASK_TYPES: list[tuple[type[Task], str]] = [
    (JointDampingTask, "joint_damping"),
    (JointPostureTask, "joint_posture"),
    (ComTask, "com"),
    (FramePositionTask, "frame_position"),
    (FrameOrientationTask, "frame_orientation"),
    (FramePoseTask, "frame_pose"),
]


def task_frames(tasks: list[Task]) -> list[str]:
    """The frames the tasks read, each once, in order of first use."""
    out: list[str] = []
    for task in tasks:
        frame = getattr(task, "frame", "")
        if frame and frame not in out:
            out.append(frame)
    return out


def task_spec(task: Task, frames: list[str]) -> Any:
    """A started task as the native side takes it."""
    kind = next((name for cls, name in _TASK_TYPES if isinstance(task, cls)), None)
    if kind is None:
        raise ControllerError(f"task {task.name!r} ({type(task).__name__}) has no native form")
    m = task.dim
    module = _native.core()
    spec = module.TaskSpec()
    spec.type = getattr(module.TaskType, kind)
    frame = getattr(task, "frame", "")
    spec.frame = frames.index(frame) if frame else -1
    spec.rows = [int(r) for r in task._rows]
    spec.kp = np.broadcast_to(np.asarray(task.kp, dtype=float), (m,)).copy()
    spec.kv = np.broadcast_to(np.asarray(task.kv, dtype=float), (m,)).copy()
    spec.absolute = bool(task.absolute)
    if task._x0 is None:
        raise ControllerError(f"task {task.name!r} was not started")
    spec.x0 = np.asarray(task._x0, dtype=float).copy()
    rotation = getattr(task, "_R0", None)
    if rotation is not None:
        spec.R0 = np.asarray(rotation, dtype=float)
    assert task.reference is not None
    spec.reference = native_trajectory(task.reference, m)
    return spec


def qp_view(qp: Any, name: str) -> Problem:
    """A Problem over a native QP's buffers: no copy, refilled by every tick."""
    return Problem(
        qp.H,
        qp.g,
        qp.A,
        qp.b,
        qp.C,
        qp.l,
        qp.u,
        qp.lb if qp.has_box else None,
        qp.ub if qp.has_box else None,
        name=name,
    )


def frozen(problem: Problem) -> Problem:
    """A copy of a view Problem that the next tick will not overwrite."""
    return Problem(
        problem.H.copy(),
        problem.g.copy(),
        problem.A.copy(),
        problem.b.copy(),
        problem.C.copy(),
        problem.l.copy(),
        problem.u.copy(),
        None if problem.lb is None else problem.lb.copy(),
        None if problem.ub is None else problem.ub.copy(),
        name=problem.name,
    )


def task_terms(tasks: list[Task], native_tasks: Any) -> list[TaskTerm]:
    """The tick's task terms, copied out of the native task set (for logs and metrics)."""
    J, drift, ref = native_tasks.J, native_tasks.drift, native_tasks.acc_ref
    err, err_vel = native_tasks.error, native_tasks.error_vel
    out = []
    for i, task in enumerate(tasks):
        rows = slice(native_tasks.offset(i), native_tasks.offset(i) + native_tasks.dim(i))
        out.append(
            TaskTerm(
                task,
                J[rows].copy(),
                drift[rows].copy(),
                ref[rows].copy(),
                err[rows].copy(),
                err_vel[rows].copy(),
            )
        )
    return out


def set_limits(settings: Any, tau_max: Any, Cw: Any, lw: Any, uw: Any, n_wrench: int) -> None:
    """The torque limits and wrench inequalities every native tick takes."""
    settings.tau_max = np.asarray(tau_max, dtype=float)
    settings.Cw = np.asarray(Cw, dtype=float).reshape(-1, n_wrench)
    settings.lw = np.asarray(lw, dtype=float)
    settings.uw = np.asarray(uw, dtype=float)


def accept_tol(ctx: Any) -> float:
    """The tolerance a native hierarchy holds its level answers to: the Python reference's
    (:func:`wbcbench.qp.hierarchy.accept_tol`) for the context's backend and tier."""
    return accept_tol_for(float(solver_class(ctx.solver).accuracy(ctx.tier)))


#: why a tick whose build found a NaN failed
NAN_MESSAGE = "the QP holds a NaN (state or references not finite)"


class QpCall:
    """One QP of a native tick that Python steps through (``qp_wbc``, ``to_osf``, each level of
    ``osf_hqp``) and the solver handle that solves it: in C++ through the handle's counterpart
    (:meth:`~wbcbench.qp.QPSolver.native_solver`) with ``solver_calls="native"``, where the
    module links the backend, else through the handle's lean path. ``problem`` is the Problem
    view of the buffers either way."""

    def __init__(self, buffers: Any, name: str, handle: Any, solver_calls: str = "python") -> None:
        self.buffers = buffers
        self.problem = qp_view(buffers, name)
        self.handle = handle
        self.cpp = handle.native_solver() if solver_calls == "native" else None
        # a handle whose answers are checked after the step (bench.checks.SolverCapture)
        self.sink: list[tuple[Problem, Solution]] | None = getattr(handle, "sink", None)
        self._last: Solution | None = None

    def prepare(self) -> None:
        """Set-up: size the C++ solver's buffers for this QP's shape, so that its first solve
        allocates only inside the backend's library (nothing with Python solver calls)."""
        if self.cpp is not None:
            self.cpp.prepare(self.buffers)

    def rebind(self) -> None:
        """Re-make the Problem view after the tick re-sized the buffers (a new contact set):
        the old view's arrays point at memory the buffers no longer use."""
        self.problem = qp_view(self.buffers, self.problem.name)

    def solve(self, timer: SolveTimes, level: str | None = None) -> tuple[Any, Solution]:
        """Solve the QP the tick has built; ``(x, solution)``, x None when it failed."""
        if self.cpp is None:
            sol = self.handle.solve(self.problem, lean=True)
            timer.add_solution(sol, level)
            return (sol.x if sol.success and sol.x is not None else None), sol
        sol = solution_of(self.handle, self.cpp.solve(self.buffers))
        timer.add_solution(sol, level)
        if self.sink is not None and isinstance(timer, NativeTimer):
            self._last = sol
            timer.pending.append(self)
        return (self.cpp.x if sol.success else None), sol

    def flush(self, timer: SolveTimes) -> float:
        """After the timed region: the C++ solve's QP and answer (copies) to the check's sink.
        The buffers and the C++ solver still hold both: nothing re-solves them in a tick."""
        if self._last is not None and self.sink is not None:
            self.sink.append((frozen(self.problem), answered(self._last, self.cpp)))
        self._last = None
        return 0.0


class LevelSolve:
    """The solve callback of a native hierarchy: the native side assembles a level's QP into
    one of its slots and calls this with ``(pool, handle, slot, reshaped, level)``; the QP goes
    through the lean path of handle ``handle`` of pool ``pool`` (each of the controller's
    hierarchies has its own handles), its solution is recorded in the tick's timer, and
    ``(x, z)`` (None on failure) goes back.

    The slot's Problem view is made once and re-made only when the native side re-made the
    slot's buffers (a size changed: ``reshaped``).

    With ``solver_calls="native"``, the handles whose backend the module links
    (:meth:`~wbcbench.qp.QPSolver.native_solver`) are solved in C++ instead (``natives``): the
    tick never comes back here for them, and their records reach the timer after the tick
    (with ``keep``, copies of their QPs too).

    ``origin``: the hierarchy's QPs are null-space levels, over coordinates made afresh every
    tick; warm and hot handles start them at the origin (``origin`` in
    :meth:`~wbcbench.qp.QPSolver.solve`), as the Python hierarchy does, except the handles whose
    backend the module links: their C++ solver starts from its own last iterate, and the same
    handle called through Python does too, so that the two ways of calling a backend agree.
    """

    def __init__(
        self,
        slots: Any,
        pools: list[list[Any]],
        keep: bool = False,
        solver_calls: str = "python",
        origin: bool = False,
    ) -> None:
        self.slots = slots  # (pool, slot) -> the native QpBuffers
        self.pools = pools
        self.keep = keep
        self.origin = origin
        self.views: dict[tuple[int, int], Problem] = {}
        self.timer: SolveTimes | None = None
        self.failed: Any = None
        self._kept: list[Problem] = []
        self.natives: Any = None
        self._linked_handles: dict[tuple[int, int], bool] = {}
        # the pools' handles whose answers are checked after the step (SolverCapture)
        self.sinks = {
            (p, i): handle.sink
            for p, handles in enumerate(pools)
            for i, handle in enumerate(handles)
            if getattr(handle, "sink", None) is not None
        }
        if solver_calls == "native":
            self.natives = _native.core().NativeSolvers()
            # the check needs each C++ solve's QP and answer: copies, their time taken out of
            # the tick's (keep_seconds)
            self.natives.set_keep(keep or bool(self.sinks))
            for p, handles in enumerate(pools):
                for i, handle in enumerate(handles):
                    solver = handle.native_solver()
                    if solver is not None:
                        self.natives.set(p, i, solver)

    def _linked(self, pool: int, handle: int) -> bool:
        """Whether the module links the handle's backend (a C++ solver exists for it)."""
        key = (pool, handle)
        linked = self._linked_handles.get(key)
        if linked is None:
            linked = self.pools[pool][handle].native_solver() is not None
            self._linked_handles[key] = linked
        return linked

    def start(self, timer: NativeTimer) -> None:
        """Before a tick: the timer its solutions go to."""
        self.timer = timer
        self.failed = None
        self._kept = []
        if self.natives is not None:
            self.natives.clear()
            timer.pending.append(self)

    def run(self, tick: Any, q: Any, v: Any, t: float) -> bool:
        """The tick's ``run`` with this callback and the C++ solvers."""
        return bool(tick.run(q, v, t, self, self.natives))

    @property
    def kept(self) -> list[Problem]:
        """Copies of the last tick's QPs, in the order solved (with ``keep``)."""
        if self.natives is None or not self.keep:
            return self._kept
        copies = [frozen(qp_view(k[3], k[2])) for k in self.natives.kept()]
        return copies or self._kept

    def flush(self, timer: SolveTimes) -> float:
        """The C++ solves of the last tick into ``timer`` (after the timed region), and to the
        check's sinks; the seconds the tick spent copying them, to take out of its time."""
        records = self.natives.records()
        for rec in records:
            timer.add_solution(native_solution(self.pools, rec), rec[2])
        if self.sinks:
            for rec, (pool, handle, level, qp, *answer) in zip(
                records, self.natives.kept(), strict=True
            ):
                sink = self.sinks.get((pool, handle))
                if sink is not None:
                    sol = native_solution(self.pools, rec)
                    x, y, z, z_box = answer
                    sink.append(
                        (frozen(qp_view(qp, level)), replace(sol, x=x, y=y, z=z, z_box=z_box))
                    )
        return float(self.natives.keep_seconds)

    def __call__(
        self, pool: int, handle: int, slot: int, reshaped: bool, level: str
    ) -> tuple[Any, Any] | None:
        problem = self.views.get((pool, slot))
        if problem is None or reshaped:
            problem = qp_view(self.slots(pool, slot), level)
            self.views[(pool, slot)] = problem
        sol = self.pools[pool][handle].solve(
            problem, lean=True, origin=self.origin and not self._linked(pool, handle)
        )
        if self.timer is not None:
            self.timer.add_solution(sol, level)
        if self.keep:
            self._kept.append(frozen(problem))
        if not sol.success or sol.x is None:
            self.failed = sol
            return None
        return sol.x, sol.z

    def message(self, level: str, refusal: str = "") -> str:
        """Why the level's QP failed, as the Python hierarchy says it; ``refusal``: why the
        hierarchy refused an answer the backend reported solved (``HierarchyResult.message``)."""
        if refusal:
            names = {handle.name for handles in self.pools for handle in handles}
            solver = f"{names.pop()}: " if len(names) == 1 else ""
            if level == "weighted":
                return f"weighted: failed: {refusal}"
            return f"level {level!r}: {solver}failed: {refusal}"
        sol = self.failed
        if sol is None and self.natives is not None:
            record = self.natives.failure()
            sol = None if record is None else native_solution(self.pools, record)
        if sol is None:
            return NAN_MESSAGE
        if level == "weighted":
            return f"weighted: {sol.status}: {sol.message}"
        return f"level {level!r}: {sol.solver}: {sol.status}: {sol.message}"


def native_solution(pools: list[list[Any]], record: tuple[Any, ...]) -> Solution:
    """A C++ level solve's record ``(pool, handle, level, *outcome)`` as a Solution."""
    pool, handle, _, *outcome = record
    return solution_of(pools[pool][handle], tuple(outcome))


def answered(sol: Solution, cpp: Any) -> Solution:
    """``sol`` with copies of the C++ solver's last answer: x and the duals it gives."""

    def copy(v: Any) -> Any:
        return None if v is None else np.array(v, dtype=float)

    return replace(sol, x=copy(cpp.x), y=copy(cpp.y), z=copy(cpp.z), z_box=copy(cpp.z_box))


def solution_of(handle: Any, outcome: tuple[Any, ...]) -> Solution:
    """A C++ solve's outcome ``(status, iterations, setup, wall, internal, call, rebuilt,
    message)`` by ``handle``'s counterpart, as the Solution the handle would have reported (no
    x: the tick reads the C++ solver's)."""
    status, iterations, setup, wall, internal, call, rebuilt, message = outcome
    return Solution(
        status=SolutionStatus(status),
        iterations=None if iterations < 0 else iterations,
        wall_time=wall,
        setup_time=setup,
        call_time=call,
        internal_time=None if internal != internal else internal,
        internal_time_covers=handle.internal_time_covers,
        solver=handle.name,
        mode=handle.mode,
        message=message,
        tier=handle.tier,
        rebuilt=rebuilt,
    )


def priority_groups(
    tasks: list[Task], active: list[Task] | None = None
) -> tuple[list[int], list[list[int]]]:
    """The distinct priorities, highest (1) first, and the indices of each one's tasks (in the
    scenario's order): the levels of a hierarchical controller, handed to its native tick.

    ``active``: the tasks of the tick (:attr:`Controller.active_tasks`; all by default): only
    theirs are grouped, and a priority none of whose tasks is active has no level."""
    held = {id(task) for task in (tasks if active is None else active)}
    priorities = sorted({task.priority for task in tasks if id(task) in held})
    groups = [
        [i for i, task in enumerate(tasks) if task.priority == p and id(task) in held]
        for p in priorities
    ]
    return priorities, groups


class NativeTimer(SolveTimes):
    """Stage times of a native tick (see the module docstring)."""

    def __init__(self) -> None:
        super().__init__()
        self.t0 = time.perf_counter()
        self.total: float | None = None
        # level solvers whose C++ solves reach the stages at finish()
        self.pending: list[LevelSolve | QpCall] = []

    def stop(self) -> None:
        """End the timed region (what follows, e.g. diagnostics, is not part of the tick)."""
        self.total = time.perf_counter() - self.t0

    def finish(self, tick: Any) -> dict[str, float]:
        """The stages of the tick; ``params`` for ticks that have operational-space parameters."""
        total = time.perf_counter() - self.t0 if self.total is None else self.total
        for solve in self.pending:
            total -= solve.flush(self)
        self.pending = []
        dynamics, build = tick.dynamics_time, tick.build_time
        params = getattr(tick, "params_time", None)
        out = {
            "dynamics": dynamics,
            "build": build,
            **self.solve_stages(),
            "crossing": max(0.0, total - dynamics - build - (params or 0.0) - self.solve),
            "total": total,
        }
        if params is not None:
            out["params"] = params
        return out


class NativeController(Controller):
    """A controller that also has a native tick (``impl: native``).

    Written here once: the tick made from the started tasks (:meth:`make_native`), the timed
    region (:meth:`native_region`), the output read after it (:meth:`native_output`), and the
    QPs' hand-off to the solution check (through :class:`QpCall` and :class:`LevelSolve`). A
    controller declares its ``tick_type``, its settings (:meth:`configure_tick`) and its QPs
    (:meth:`qp_calls`) or hierarchy (:meth:`level_solve`); the other hooks are for what differs.
    Its :meth:`step` stays the Python reference and hands over to :meth:`native_step`.
    """

    has_native = True
    #: the tick's class in the module, e.g. ``"QpWbcTick"``
    tick_type: ClassVar[str] = ""
    config: NativeImplConfig
    #: the native tick, made by :meth:`make_native` (None until then)
    native_tick: Any = None
    #: the QPs the tick hands to Python one at a time (:meth:`qp_calls`)
    native_calls: Sequence[QpCall] = ()
    #: the callback of a tick that runs a whole hierarchy (:meth:`level_solve`)
    native_solve: LevelSolve | None = None
    #: the contact set the tick holds (None: every contact, as it was made)
    tick_contacts: tuple[int, ...] | None = None
    #: the tick keeps a workspace per contact set (its settings and QP buffers): every set of
    #: the schedule is configured when the tick is made, and a change of contacts switches to
    #: the set's workspace and to its QPs' calls (each with a C++ solver of its own) instead of
    #: configuring the tick again
    contact_workspaces: ClassVar[bool] = False
    #: per contact set configured (contact_workspaces): the tick's number of it, its QPs' calls
    workspaces: dict[tuple[int, ...], tuple[int, Sequence[QpCall]]]
    #: the tick's tasks whose reference has no native form (index in the tick, task): sampled
    #: here before every tick, those of :attr:`Controller.active_tasks` only
    sampled_tasks: list[tuple[int, Task]]

    # -- what a controller declares --------------------------------------------------------------

    @abstractmethod
    def configure_tick(self, tick: Any) -> None:
        """Fill the tick's settings from the controller's and hand them over
        (``tick.configure``)."""

    def tick_tasks(self) -> list[Task]:
        """The started tasks in the order the tick stacks their rows (the scenario's here)."""
        return self.ctx.tasks

    def tick_args(self) -> tuple[Any, ...]:
        """The tick's constructor arguments after the model and the frames (none here)."""
        return ()

    def qp_calls(self, tick: Any) -> list[QpCall]:
        """The QPs the tick hands to Python one at a time, each with its solver handle."""
        return []

    def rebind_calls(self, tick: Any) -> None:
        """After :meth:`configure_tick` for a new contact set: re-make the Problem views of the
        QPs it re-sized (here: the same QPs, new buffers)."""
        for call in self.native_calls:
            call.rebind()

    def level_solve(self, tick: Any) -> LevelSolve | None:
        """The callback through which a tick that runs a whole hierarchy solves its levels."""
        return None

    def on_start(self, state: RobotState) -> None:
        """What the controller fixes for the run at the first state, after its tasks are started
        and before the native tick is made from them (both impls; nothing here)."""

    # -- the start and the step ------------------------------------------------------------------

    def start(self, state: RobotState) -> None:
        super().start(state)
        self.on_start(state)
        if self.impl == "native":
            self.make_native()

    def make_native(self) -> None:
        """The native tick from the started tasks (made by start(), or by the first step of a
        controller whose tasks another one started): the model, the tasks and the settings
        cross once."""
        tasks = self.tick_tasks()
        frames = task_frames(tasks)
        model = self.ctx.robot.pin_model.saveToString()
        tick_class = getattr(_native.core(), self.tick_type)
        tick = tick_class(model, frames, self.ctx.contact_frames, *self.tick_args())
        if any(c.points is not None for c in self.ctx.contacts):
            # points and row bases as the Python path's (RobotState.contact_constraint)
            tick.set_contact_points(
                [np.asarray(c.points or np.zeros((0, 3)), dtype=float) for c in self.ctx.contacts],
                [
                    np.zeros((0, 0)) if c.points is None else contact_basis(c.points)
                    for c in self.ctx.contacts
                ],
            )
        for task in tasks:
            tick.tasks.add(task_spec(task, frames))
        self.tick_contacts = None
        if self.ctx.schedule is not None and -1 not in self.active_contacts:
            # made again after steps (a new start): the set the Python side holds, whose
            # inequalities configure_tick hands over
            tick.select_contacts(list(self.active_contacts))
            self.tick_contacts = self.active_contacts
        self.configure_tick(tick)
        self.native_tick = tick
        self.sampled_tasks = self.held_sampled(tasks)
        self.native_calls = self.qp_calls(tick)
        self.native_solve = self.level_solve(tick)
        self.workspaces = {}
        if self.contact_workspaces and self.ctx.schedule is not None:
            self.configure_workspaces(tick)

    def configure_workspaces(self, tick: Any) -> None:
        """Configure the tick for every contact set of the schedule (``contact_workspaces``),
        each one's settings as :meth:`~Controller.select_contacts` makes them for the set (its
        unscaled wrench bounds: every tick sets its own), then return to the set it held."""
        assert self.ctx.schedule is not None
        held = self.tick_contacts
        keep = ("frames", "contacts", "active_tasks", "Cw", "nc", "lw", "uw", "active_contacts")
        saved = {name: getattr(self, name) for name in keep if hasattr(self, name)}
        try:
            for active in self.ctx.schedule.contact_sets():
                self.hold_contacts(active)
                tick.select_contacts(list(active))
                self.configure_tick(tick)
                calls = self.qp_calls(tick)
                for call in calls:
                    call.prepare()
                self.workspaces[active] = (tick.contact_set, calls)
        finally:
            self.__dict__.update(saved)
        target = tuple(range(len(self.ctx.contacts))) if held is None else held
        tick.select_contacts(list(target))
        if target in self.workspaces:
            self.native_calls = self.workspaces[target][1]
        else:  # configured by make_native, not since
            self.workspaces[target] = (tick.contact_set, self.native_calls)

    def held_sampled(self, tasks: list[Task]) -> list[tuple[int, Task]]:
        """The tasks of the tick whose references are sampled here, among the active ones."""
        active = {id(task) for task in self.active_tasks}
        return [
            (i, task)
            for i, task in enumerate(tasks)
            if id(task) in active and not isinstance(task.reference, NATIVE_TRAJECTORIES)
        ]

    def native_contacts(self, t: float) -> None:
        """Hand the tick the contacts of ``t`` (with a schedule), the one place the Python side
        does: :meth:`~Controller.select_contacts` picks them; when the set differs from the
        tick's, the tick re-sizes its contact buffers and takes the controller's settings for
        the new set (:meth:`configure_tick`, which sizes its QPs), and the Problem views of its
        QPs are re-made. Every tick, the set's ramped normal-force bounds."""
        self.select_contacts(t)
        tick = self.native_tick
        active = self.active_contacts
        if active != self.tick_contacts:
            workspace = self.workspaces.get(active)
            if workspace is not None:  # configured when the tick was made
                tick.switch_contacts(workspace[0])
                self.native_calls = workspace[1]
            else:
                tick.select_contacts(list(active))
                self.configure_tick(tick)
                if self.contact_workspaces:  # a set the schedule did not foresee
                    self.native_calls = self.qp_calls(tick)
                    self.workspaces[active] = (tick.contact_set, self.native_calls)
                else:
                    self.rebind_calls(tick)
            self.tick_contacts = active
            self.sampled_tasks = self.held_sampled(self.tick_tasks())
        tick.set_wrench_bounds(self.lw, self.uw)

    def native_step(self, state: RobotState, t: float) -> ControlOutput:
        """:meth:`step` on the native tick: the timed region, then the output read after it.
        The region includes choosing the contacts and sampling the references that have no
        native form."""
        if self.native_tick is None:
            self.make_native()
        timer = NativeTimer()
        if self.ctx.schedule is not None:
            self.native_contacts(t)
        if self.sampled_tasks:
            native_tasks = self.native_tick.tasks
            for i, task in self.sampled_tasks:
                assert task.reference is not None
                native_tasks.set_sample(i, *task.reference.sample(t))
        message = self.native_region(state.q, state.v, t, timer)
        timer.stop()
        return self.native_output(state, timer, message)

    def native_region(
        self, q: np.ndarray, v: np.ndarray, t: float, timer: NativeTimer
    ) -> str | None:
        """The timed region of a native step; None, or the message of a failed tick. Here: a
        tick with one QP (build, the QP's solve, finish), or a tick that runs a whole hierarchy,
        its level QPs through :attr:`native_solve`."""
        tick = self.native_tick
        if self.native_solve is not None:
            self.native_solve.start(timer)
            if self.native_solve.run(tick, q, v, t):
                return None
            return self.native_solve.message(tick.result.failed_level, tick.result.message)
        (call,) = self.native_calls
        if not tick.build(q, v, t):
            return NAN_MESSAGE
        x, sol = call.solve(timer)
        if x is None:
            return f"{sol.solver}: {sol.status.value}: {sol.message}"
        tick.finish(x)
        return None

    def native_terms(self) -> list[TaskTerm]:
        """The last tick's task terms (copies), in the order of the scenario's tasks: those the
        tick holds (:attr:`Controller.active_tasks`)."""
        by_task = {
            id(term.task): term for term in task_terms(self.tick_tasks(), self.native_tick.tasks)
        }
        return [by_task[id(task)] for task in self.active_tasks]

    def native_diagnostics(
        self, state: RobotState, terms: list[TaskTerm], ok: bool
    ) -> dict[str, float]:
        """The step's diagnostics, read after the timed region (none here)."""
        return {}

    def native_problems(self) -> list[Problem]:
        """The QPs of the last tick: the level QPs the hierarchy kept, else the tick's QPs."""
        if self.native_solve is not None:
            return self.native_solve.kept
        return [call.problem for call in self.native_calls]

    def native_output(
        self, state: RobotState, timer: NativeTimer, message: str | None
    ) -> ControlOutput:
        """The step's output from the tick's τ, q̈ and wrench, or a failed one when ``message``
        is set (zeros of the same sizes), with copies of its QPs when the context keeps them."""
        tick, ok = self.native_tick, message is None
        terms = self.native_terms()
        diagnostics = self.native_diagnostics(state, terms, ok)
        problems = self.native_problems() if self.ctx.keep_problems else []
        tau, qdd, wrench = tick.tau, tick.qdd, tick.wrench
        return ControlOutput(
            tau=tau.copy() if ok else np.zeros_like(tau),
            qdd=qdd.copy() if ok else np.zeros_like(qdd),
            wrench=wrench.copy() if ok else np.zeros_like(wrench),
            terms=terms,
            timings=timer.finish(tick),
            ok=ok,
            message=message or "",
            iterations=timer.iterations,
            diagnostics=diagnostics,
            problems=[frozen(p) for p in problems],
        )
