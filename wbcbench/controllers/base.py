"""What every controller plugin receives and returns.

A controller is built once per run from a :class:`ControllerContext` (robot, tasks, contacts,
limits and the solver choice) and its own validated config, then called once per control tick
with a fresh :class:`~wbcbench.dynamics.state.RobotState`. It never calls a QP library: it builds
:class:`wbcbench.qp.Problem` objects and solves them through the solver handles the context gives
(one handle per QP it solves, so hot / warm modes keep their state per level).
"""

from __future__ import annotations

import os
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from wbcbench import _native
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.qp import Problem, make_solver
from wbcbench.qp.base import QP_KINDS
from wbcbench.qp.registry import DEFAULT_SOLVER
from wbcbench.qp.solution import SolveTimes
from wbcbench.robots.loader import Robot
from wbcbench.scenarios.schema import Scenario
from wbcbench.tasks.contacts import (
    PlaneContact,
    contacts_dim,
    frame_wrenches,
    stack_wrench_constraints,
)
from wbcbench.tasks.schedule import ContactPhase, ContactSchedule
from wbcbench.tasks.tasks import Task, TaskTerm


class ControllerConfig(BaseModel):
    """Base of every controller's settings: unknown keys are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    impl: Literal["python"] | None = Field(
        None, description="implementation: python (this controller has no native tick yet)"
    )

    def robot_errors(self, spec: Scenario, robot: Robot) -> list[tuple[str, str]]:
        """``(key, message)`` for each name in the settings the scenario or its robot lacks
        (a task, a body); the key is relative to the controller's settings."""
        return []


class NativeImplConfig(ControllerConfig):
    """Settings of a controller that also has a native implementation."""

    impl: Literal["native", "python"] | None = Field(  # type: ignore[assignment]
        None,
        description="native (the C++ tick) or python (the reference); by default native "
        "where the module is built",
    )


class NativeConfig(NativeImplConfig):
    """Settings of a controller that also has a native tick whose QPs go to a QP backend."""

    solver_calls: Literal["native", "python"] = Field(
        "native",
        description="impl native: call the QP backend from C++ where the module links its "
        "library (daqp, osqp, osqp_libdwbc, qpoases, qpoases_libdwbc, eiquadprog), or every QP "
        "through the Python solver handle's lean path; backends the module does not link "
        "always go through Python",
    )


#: the environment variable that sets the default impl of every controller that has a native
#: tick (``WBCBENCH_IMPL=python make bench`` runs the Python references throughout)
IMPL_ENV = "WBCBENCH_IMPL"


def default_impl() -> str | None:
    """``native``, ``python`` or None (unset): the default that ``WBCBENCH_IMPL`` asks for."""
    value = os.environ.get(IMPL_ENV, "").strip()
    if value in ("", "native", "python"):
        return value or None
    raise ControllerError(f"{IMPL_ENV}={value!r}; valid choices: native, python (or unset)")


def resolve_impl(cls: type[Controller], requested: str | None) -> str:
    """The implementation a controller runs: the requested one, else ``WBCBENCH_IMPL``'s where
    it is set, else native where the controller has a native tick and the module is built, else
    python."""
    if requested is not None:
        return requested
    if not cls.has_native:
        return "python"
    # asked for by WBCBENCH_IMPL, native fails at construction when the module is not built
    return default_impl() or ("native" if _native.BUILT else "python")


def native_schedule_refusal(controller: str) -> str:
    """Why ``controller``'s native tick does not run a scenario whose contacts change."""
    return (
        f"{controller}: the native tick holds a fixed contact set and this scenario's contacts "
        "change (a contact schedule or a walk); run the Python reference: impl python "
        f"(--set controllers.{controller}.impl=python, or controllers: {{{controller}: "
        "{impl: python}} in the scenario)"
    )


def stance_tasks(tasks: list[Task], frames: set[str]) -> list[Task]:
    """The tasks of a tick whose active contacts are on ``frames``: those that drive none of
    them (a swing task leaves the QPs while its foot stands)."""
    return [task for task in tasks if getattr(task, "frame", None) not in frames]


@dataclass
class ControllerContext:
    """Everything a controller may use besides its own settings.

    Attributes:
        robot: the loaded robot.
        tasks: started-or-not tasks, in priority order (1 first).
        contacts: the plane contacts to hold.
        tau_max: torque limits after scenario overrides (k,) [N·m].
        solver, tier, mode: the QP backend and its accuracy tier and mode.
        dt: control period [s].
        keep_problems: keep every QP of the last step in ``ControlOutput.problems`` (for dumps).
        schedule: when the contacts change over the run, which are active at each tick (None:
            every contact is held throughout).
    """

    robot: Robot
    tasks: list[Task]
    contacts: list[PlaneContact]
    tau_max: np.ndarray
    solver: str = DEFAULT_SOLVER
    tier: str = "default"
    mode: str = "cold"
    dt: float = 1e-3
    keep_problems: bool = False
    schedule: ContactSchedule | None = None

    @property
    def contact_frames(self) -> list[str]:
        return [c.frame for c in self.contacts]

    def new_solver(self, kind: str = "task") -> Any:
        """A fresh solver handle for one QP of the controller (one per hierarchy level);
        ``kind`` is what the QP is (:data:`wbcbench.qp.base.QP_KINDS`)."""
        if kind not in QP_KINDS:
            raise ValueError(f"unknown QP kind {kind!r}; valid choices: {', '.join(QP_KINDS)}")
        handle = make_solver(self.solver, tier=self.tier, mode=self.mode)
        handle.qp_kind = kind
        return handle


@dataclass
class ControlOutput:
    """One control tick's result.

    Attributes:
        tau: joint torques (k,) [N·m], Pinocchio actuated order.
        qdd: the joint acceleration the controller predicts (n,).
        wrench: the stacked contact force variable it predicts, reaction on the robot: 6 per
            flat contact (its wrench), 3 per point of a point set (``full_wrench`` gives the
            frame wrenches, 6 per contact).
        qd: the joint velocity command (n,) of velocity-level (kinematic) controllers, else None.
        terms: the evaluated tasks (errors for the logs).
        timings: seconds per stage: ``dynamics``, ``build``, ``solve`` (the whole call into the
            QP layer), within it ``solve_setup`` (building or updating the solver's object) and
            ``solve_native`` (the native solve call), ``solve_internal`` (solver-reported, NaN if
            none), ``total``; and per level ``solve.<level>``.
        ok: every QP solved.
        message: failure message when not ok.
        iterations: total solver iterations (NaN if unreported).
        diagnostics: controller-specific scalars (amendments, residuals, ...).
        problems: the QPs of this step when the context asks to keep them.
    """

    tau: np.ndarray
    qdd: np.ndarray
    wrench: np.ndarray
    terms: list[TaskTerm]
    timings: dict[str, float]
    qd: np.ndarray | None = None
    ok: bool = True
    message: str = ""
    iterations: float = float("nan")
    diagnostics: dict[str, float] = field(default_factory=dict)
    problems: list[Problem] = field(default_factory=list)


class StageTimer(SolveTimes):
    """Splits a step's wall time into dynamics / build / solve.

    ``dynamics`` is what the RobotState spent in Pinocchio during the step (its quantities are
    lazy, so they are computed wherever the controller first asks for them); ``solve`` is the
    wall time of the calls into the QP layer (validation, the solver object's set-up or update,
    the native call); ``build`` is the rest: evaluating tasks and formulating the QPs.
    """

    def __init__(self, state: RobotState) -> None:
        super().__init__()
        self.state = state
        self._t0 = time.perf_counter()
        self._dyn0 = state.compute_time

    def finish(self) -> dict[str, float]:
        total = time.perf_counter() - self._t0
        dynamics = self.state.compute_time - self._dyn0
        return {
            "dynamics": dynamics,
            "build": max(0.0, total - dynamics - self.solve),
            **self.solve_stages(),
            "total": total,
        }


class Controller(ABC):
    """Base class of controller plugins.

    Subclasses set ``name``, ``Config`` (a :class:`ControllerConfig`) and ``summary``, and
    implement :meth:`step`. :meth:`applies_to` may reject scenarios the formulation cannot
    handle (e.g. a kinematic controller on a torque scenario) with a reason.
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    Config: ClassVar[type[ControllerConfig]] = ControllerConfig
    #: "torque" controllers drive the MuJoCo simulation; "velocity" controllers command q̇ and
    #: are integrated kinematically
    kind: ClassVar[str] = "torque"
    #: backends the formulation is validated with (the registry sweep requires them to succeed)
    reference_solvers: ClassVar[tuple[str, ...]] = ("proxqp", "daqp")
    #: the controller has a native tick (``impl: native``; its Config is a NativeImplConfig)
    has_native: ClassVar[bool] = False
    #: its native tick follows a changing contact set (a contact schedule or a walk); the
    #: others are refused on such a scenario (:func:`native_schedule_refusal`)
    native_schedule: ClassVar[bool] = False
    #: the name of the solver the controller brings itself ("" when its QPs go through the
    #: run's backend); such a controller runs once per scenario and settings, recorded under
    #: this name at tier ``default``, whatever backends and tiers a sweep asks for
    own_solver: ClassVar[str] = ""

    @classmethod
    def applies_to(cls, scenario: Scenario) -> str:
        """Why this controller cannot run ``scenario`` ("" when it can).

        Sweeps use it to build the "every controller that applies" matrix; the default accepts
        dynamic scenarios for torque controllers and kinematic ones for velocity controllers.
        """
        wanted = "kinematic" if cls.kind == "velocity" else "dynamic"
        if scenario.kind != wanted:
            return f"{cls.name} is a {cls.kind} controller; the scenario is {scenario.kind}"
        return ""

    @classmethod
    def impl_for(cls, config: ControllerConfig) -> str:
        """The implementation an instance with ``config`` runs (see :func:`resolve_impl`)."""
        return resolve_impl(cls, config.impl)

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        self.ctx = ctx
        self.config = config if config is not None else self.Config()
        #: ``native`` or ``python``: which implementation this instance runs
        self.impl = self.impl_for(self.config)
        if self.impl == "native":
            _native.core()  # fails here, with why, where the module is not built
            if ctx.schedule is not None and not self.native_schedule:
                raise ControllerError(native_schedule_refusal(self.name))
        # with a schedule, the first tick selects (and rebuilds what depends on the set)
        self.active_contacts = (-1,) if ctx.schedule else tuple(range(len(ctx.contacts)))
        self.contacts = list(ctx.contacts)
        self.active_tasks = list(ctx.tasks)

    def start(self, state: RobotState) -> None:
        """Called once with the initial state: fixes the tasks' initial values."""
        for task in self.ctx.tasks:
            task.start(state)

    @abstractmethod
    def step(self, state: RobotState, t: float) -> ControlOutput:
        """Compute the torque for this tick."""

    # -- a contact set that changes (ctx.schedule)

    #: the active contacts' frames, stacked wrench inequalities ``lw ≤ Cw f ≤ uw`` and the size
    #: of the force variable (6 per flat contact, 3 per point): the whole context's unless a
    #: schedule selects (:meth:`select_contacts`)
    frames: list[str]
    contacts: list[PlaneContact]
    Cw: np.ndarray
    lw: np.ndarray
    uw: np.ndarray
    nc: int
    #: the active contacts' indices into ``ctx.contacts`` (all of them without a schedule)
    active_contacts: tuple[int, ...] = ()
    #: the tasks of the tick: the context's, but for those that drive the frame of a scheduled
    #: contact while it is active (a swing task leaves the QPs while its foot stands)
    active_tasks: list[Task]

    def select_contacts(self, t: float) -> ContactPhase | None:
        """Make the contacts active at ``t`` the ones this tick holds (with a schedule).

        Sets ``frames``, ``Cw``, ``lw``, ``uw`` and ``nc`` to the active subset (its wrench
        rows built once per subset and kept), scales the normal-force bounds of a contact that
        is unloading or just landed (:class:`~wbcbench.tasks.schedule.ContactSchedule`), and
        calls :meth:`contacts_changed` when the subset differs from the last tick's.
        """
        schedule = self.ctx.schedule
        if schedule is None:
            return None
        phase = schedule.phase(t)
        changed = self.hold_contacts(phase.active)
        _, _, lw, uw, rows, fmax = self.contact_set(phase.active)
        schedule.scale_bounds(phase, rows, fmax, lw, uw, self.lw, self.uw)
        if changed:
            self.contacts_changed()
        return phase

    def hold_contacts(self, active: tuple[int, ...]) -> bool:
        """:meth:`select_contacts`'s choice of ``active`` without a time: ``frames``, ``Cw``,
        ``lw``, ``uw`` (unscaled), ``nc`` and the tasks of that set; whether it changed."""
        contacts, Cw, lw, uw, _, _ = self.contact_set(active)
        changed = active != self.active_contacts
        if changed:  # (the same set again: frames, Cw, nc and tasks are already its own)
            self.frames = [c.frame for c in contacts]
            self.contacts = contacts
            self.active_tasks = stance_tasks(self.ctx.tasks, set(self.frames))
            self.Cw, self.nc = Cw, contacts_dim(contacts)
            self.active_contacts = active
        # fresh arrays every tick: a Python QP of the last tick may still hold views of them
        self.lw, self.uw = lw.copy(), uw.copy()
        return changed

    def contact_set(self, active: tuple[int, ...]) -> tuple[Any, ...]:
        """The contacts ``active`` (indices into the context's), their stacked wrench rows
        ``(Cw, lw, uw)``, the rows of each one's normal-force bounds and its f_max: built on
        first use and kept."""
        cache: dict[tuple[int, ...], Any] = self.__dict__.setdefault("_contact_sets", {})
        entry = cache.get(active)
        if entry is None:
            contacts = [self.ctx.contacts[i] for i in active]
            Cw, lw, uw = stack_wrench_constraints(contacts)
            starts = np.cumsum([0] + [c.n_constraints for c in contacts])[:-1].tolist()
            rows = [[s + r for r in c.normal_rows()] for s, c in zip(starts, contacts, strict=True)]
            fmax = [c.fmax for c in contacts]
            entry = cache[active] = (contacts, Cw, lw, uw, rows, fmax)
        return entry

    def contacts_changed(self) -> None:  # noqa: B027 - a hook: most controllers need nothing
        """Rebuild what depends on the contact set, after :meth:`select_contacts` changed it."""

    def full_wrench(self, wrench: np.ndarray) -> np.ndarray:
        """The active contacts' frame wrenches (6 per contact, from the force variable
        ``wrench``) spread over every contact of the context (zeros for the inactive ones), as
        the runners log it."""
        if self.ctx.schedule is None:
            return frame_wrenches(self.ctx.contacts, wrench)
        wrench = frame_wrenches([self.ctx.contacts[i] for i in self.active_contacts], wrench)
        out = np.zeros(6 * len(self.ctx.contacts))
        for j, i in enumerate(self.active_contacts):
            out[6 * i : 6 * i + 6] = wrench[6 * j : 6 * j + 6]
        return out

    def evaluate_tasks(self, state: RobotState, t: float) -> list[TaskTerm]:
        return [task.evaluate(state, t) for task in self.active_tasks]

    def close(self) -> None:  # noqa: B027 - an optional hook: most controllers hold nothing
        """Release what the controller holds beyond memory (worker processes, shared memory).

        The runners call it when a run ends, however it ends; the default holds nothing.
        """
