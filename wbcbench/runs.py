"""The one owner of a run: a frozen, validated description of each run, built only here.

Every entry point (the command line, sweeps, timing runs, the executors and the Python API)
describes a run as a :class:`Run`, made by :func:`plan_run` or a :class:`Planner`:

- the scenario and its robot, loaded once and checked against each other (frames, joints,
  keyframe, and the controllers' settings, which the controller registry validates);
- the controller's class and its validated settings (the scenario's, then the run's);
- the resolved solver, accuracy tier and mode (``default`` resolved by :func:`default_solver`, a
  controller that solves with its own solver given that one, :func:`solver_runs`), and the
  implementation (native or python) the controller runs;
- the runner it takes: ``closed_loop`` (MuJoCo), ``kinematic`` (integration of q̇) or ``timing``
  (open-loop replay of recorded states).

The runners in :mod:`wbcbench.sim` take a :class:`Run` and neither load a robot nor look up a
registry. A :class:`Run` pickles without its robot (which holds native models) and loads the
robot again where it is unpickled (a guarded child, a Dask worker), from the cache of
:func:`wbcbench.robots.loader.load_robot`.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal

from wbcbench.controllers.base import (
    Controller,
    ControllerConfig,
    ControllerContext,
    native_schedule_refusal,
)
from wbcbench.controllers.registry import (
    check_scenario_settings,
    controller_class,
    validated_config,
)
from wbcbench.errors import WbcBenchError
from wbcbench.qp.registry import DEFAULT_SOLVER, default_solver, solver_class
from wbcbench.qp.settings import check_mode, check_tier
from wbcbench.robots.loader import Robot
from wbcbench.robots.model_error import with_model_error
from wbcbench.scenarios.initial import initial_state
from wbcbench.scenarios.load import (
    LoadedScenario,
    build_contacts,
    build_tasks,
    check_against_robot,
    load_scenario,
    load_scenario_robot,
    torque_limits,
)
from wbcbench.scenarios.walk import expand
from wbcbench.tasks.collision import Box

__all__ = [
    "Planner",
    "Run",
    "RunSettings",
    "default_solver",
    "plan_run",
    "solver_runs",
]

Runner = Literal["closed_loop", "kinematic", "timing"]


@dataclass(frozen=True)
class RunSettings:
    """What varies between runs of one scenario: the names as given, ``solver`` resolved."""

    controller: str = "qp_wbc"
    solver: str = DEFAULT_SOLVER
    tier: str = "default"
    mode: str = "cold"
    controller_config: dict[str, Any] = field(default_factory=dict)

    @property
    def config_json(self) -> str:
        return json.dumps(self.controller_config, sort_keys=True)


def solver_runs(
    cls: type[Controller], runs: Sequence[tuple[str, str, str]], mode: str
) -> list[tuple[str, str, str]]:
    """The ``(solver, tier, mode)`` runs of a controller for the asked ones: a controller that
    solves with its own solver (``own_solver``, e.g. kin_hqp's ``hls``) runs once, with it, at
    the default tier and ``mode``; any other runs each asked one."""
    if cls.own_solver:
        return [(cls.own_solver, "default", mode)]
    return list(runs)


@dataclass(frozen=True, eq=False)
class Run:
    """One run, validated: see the module docstring. Build it with :func:`plan_run`."""

    scenario: LoadedScenario
    robot: Robot = field(repr=False)
    settings: RunSettings
    controller_cls: type[Controller]
    config: ControllerConfig
    impl: str
    runner: Runner

    @property
    def name(self) -> str:
        """The scenario's name."""
        return self.scenario.name

    @property
    def controller(self) -> str:
        return self.settings.controller

    @property
    def label(self) -> str:
        """``scenario · controller {config} · solver · mode``, for progress lines."""
        s = self.settings
        cfg = f" {s.config_json}" if s.controller_config else ""
        return f"{self.name} · {s.controller}{cfg} · {s.solver} · {s.mode}"

    def controller_robot(self) -> Robot:
        """The robot the controller is built on: the simulated one, or a copy whose Pinocchio
        model carries the scenario's model error (``perturbations.model``)."""
        m = self.scenario.spec.perturbations.model
        return with_model_error(self.robot, m.mass_scale, m.inertia_scale, m.com_offset)

    def context(
        self, context_cls: type[ControllerContext] = ControllerContext, **options: Any
    ) -> ControllerContext:
        """A fresh controller context: the scenario's tasks, contacts, torque limits and period,
        the run's solver, tier and mode; ``options`` are further fields of ``context_cls``."""
        s = self.settings
        return scenario_context(
            self.scenario,
            self.controller_robot(),
            context_cls,
            solver=s.solver,
            tier=s.tier,
            mode=s.mode,
            **options,
        )

    def make_controller(
        self, wrap_solver: Callable[[Any], Any] | None = None, **context_options: Any
    ) -> Controller:
        """A fresh controller of the run, its solver handles passed through ``wrap_solver``
        when given (e.g. to check their answers); ``context_options``: further context fields
        (``keep_problems``). The scenario's obstacles go to controllers that avoid them."""
        if wrap_solver is not None:
            ctx = self.context(WrappingContext, wrap=wrap_solver, **context_options)
        else:
            ctx = self.context(**context_options)
        controller = self.controller_cls(ctx, self.config)
        use_environment = getattr(controller, "use_environment", None)
        if use_environment is not None:
            use_environment(scenario_obstacles(self.scenario))
        return controller

    def __getstate__(self) -> dict[str, Any]:
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        state["robot"] = None  # native models: loaded again where the run is unpickled
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        for key, value in state.items():
            object.__setattr__(self, key, value)
        object.__setattr__(self, "robot", load_scenario_robot(self.scenario))


@dataclass
class WrappingContext(ControllerContext):
    """A context whose solver handles pass through ``wrap`` (e.g. to record their solutions)."""

    wrap: Callable[[Any], Any] | None = None

    def new_solver(self, kind: str = "task") -> Any:
        handle = super().new_solver(kind)
        return self.wrap(handle) if self.wrap is not None else handle


def scenario_context(
    loaded: LoadedScenario,
    robot: Robot,
    context_cls: type[ControllerContext] = ControllerContext,
    **options: Any,
) -> ControllerContext:
    """A controller context with the scenario's tasks, contacts, torque limits and period;
    ``options`` are further fields of ``context_cls`` (``solver``, ``tier``, ...). A scenario
    whose contacts change gets its schedule, and a walk its swing tasks and references
    (:func:`wbcbench.scenarios.walk.expand`, planned from the scenario's initial state)."""
    spec = loaded.spec
    tasks = build_tasks(spec, robot)
    schedule = None
    if spec.has_schedule:
        q0, _ = initial_state(loaded, robot)
        expansion = expand(spec, robot, tasks, q0)
        tasks, schedule = expansion.tasks, expansion.schedule
    return context_cls(
        robot=robot,
        tasks=tasks,
        contacts=build_contacts(spec, robot),
        tau_max=torque_limits(spec, robot),
        dt=spec.dt,
        schedule=schedule,
        **options,
    )


def scenario_obstacles(loaded: LoadedScenario) -> list[Box]:
    """The scenario's fixed boxes (``environment.obstacles``)."""
    return [Box.from_rpy(o.name, o.pos, o.size, o.rpy) for o in loaded.spec.environment.obstacles]


class Planner:
    """Builds runs, loading each scenario (name or path, overrides) once, each robot once, and
    checking each scenario against its robot once."""

    def __init__(self) -> None:
        self._scenarios: dict[tuple[str, tuple[str, ...]], LoadedScenario] = {}
        self._checked: set[tuple[str, tuple[str, ...]]] = set()

    def scenario(
        self, scenario: str | Path | LoadedScenario, overrides: Sequence[str] = ()
    ) -> tuple[LoadedScenario, Robot]:
        """The scenario (loaded with ``overrides``, or as given) and its robot, checked against
        each other.

        Raises:
            ScenarioError: the file, a key and what is wrong with it.
        """
        if isinstance(scenario, LoadedScenario):
            loaded = scenario
            key = (str(loaded.path), loaded.overrides)
        else:
            key = (str(scenario), tuple(overrides))
            if key not in self._scenarios:
                self._scenarios[key] = load_scenario(str(scenario), list(overrides))
            loaded = self._scenarios[key]
        robot = load_scenario_robot(loaded)
        if key not in self._checked:
            check_scenario(loaded, robot)
            self._checked.add(key)
        return loaded, robot

    def run(
        self,
        scenario: str | Path | LoadedScenario,
        controller: str,
        solver: str = "default",
        *,
        tier: str = "default",
        mode: str = "cold",
        config: dict[str, Any] | None = None,
        overrides: Sequence[str] = (),
        timing: bool = False,
        where: tuple[str, str] | tuple[()] = (),
    ) -> Run:
        """One run, validated; see :func:`plan_run`. ``where``: the file and key a rejected
        ``config`` is reported at (a sweep file's), else the scenario's ``controllers.<name>``."""
        loaded, robot = self.scenario(scenario, overrides)
        cls = controller_class(controller)
        reason = cls.applies_to(loaded.spec)
        if reason:
            raise WbcBenchError(f"{loaded.path}: {reason}")
        if loaded.spec.environment.obstacles and not hasattr(cls, "use_environment"):
            raise WbcBenchError(
                f"{loaded.path}: environment.obstacles: {controller} cannot avoid obstacles"
            )
        check_tier(tier)
        check_mode(mode)
        if cls.own_solver:
            solver, tier = cls.own_solver, "default"
        else:
            solver = default_solver() if solver == "default" else solver
            solver_class(solver)
        variant = dict(config or {})
        validated = validated_config(cls, loaded, variant, *where)
        native = cls.impl_for(validated) == "native"
        if loaded.spec.has_schedule and native and not cls.native_schedule:
            raise WbcBenchError(f"{loaded.path}: {native_schedule_refusal(controller)}")
        settings = RunSettings(controller, solver, tier, mode, variant)
        velocity = cls.kind == "velocity" or loaded.spec.kind == "kinematic"
        runner: Runner = "timing" if timing else "kinematic" if velocity else "closed_loop"
        return Run(loaded, robot, settings, cls, validated, cls.impl_for(validated), runner)


def plan_run(
    scenario: str | Path | LoadedScenario,
    controller: str,
    solver: str = "default",
    *,
    tier: str = "default",
    mode: str = "cold",
    config: dict[str, Any] | None = None,
    overrides: Sequence[str] = (),
    timing: bool = False,
) -> Run:
    """A run of ``controller`` on a scenario, validated before any simulation step.

    Args:
        scenario: a scenario name (``wbcbench list``), a path to a YAML file, or a loaded one.
        controller: a registered controller name.
        solver: a QP backend name, or ``default`` (:func:`default_solver`); a controller that
            solves with its own solver takes that one whatever this says.
        tier, mode: the backend's accuracy tier and mode.
        config: the controller's settings on top of the scenario's (e.g. ``{"impl": "python"}``).
        overrides: ``KEY=VALUE`` scenario overrides, as ``wbcbench run --set``.
        timing: the run replays recorded states open loop (``timing``), not in closed loop.

    Raises:
        WbcBenchError: a name that is not registered (naming the valid ones), a scenario key
            the robot contradicts, a setting the controller's config rejects, or a controller
            that does not apply to the scenario.
    """
    return Planner().run(
        scenario,
        controller,
        solver,
        tier=tier,
        mode=mode,
        config=config,
        overrides=overrides,
        timing=timing,
    )


def plan_matrix(
    scenarios: Sequence[str | Path],
    controllers: Sequence[str],
    solvers: Sequence[str] = ("default",),
    tier: str = "default",
    mode: str = "cold",
    overrides: Sequence[str] = (),
) -> tuple[list[Run], list[str]]:
    """Every scenario × controller × solver run, validated before the first simulation step,
    and notes on what was left out: a controller that solves with its own solver runs once,
    with it, and one that does not apply to a scenario (a velocity controller on a dynamic
    one) is not planned.

    Raises:
        WbcBenchError: as :func:`plan_run`, or when no controller applies to any scenario.
    """
    planner = Planner()
    loaded = [planner.scenario(name, overrides)[0] for name in scenarios]
    default = default_solver()
    names = [default if s == "default" else s for s in solvers]
    notes: list[str] = []
    runs_of: dict[str, list[tuple[str, str, str]]] = {}
    for c in controllers:
        cls = controller_class(c)
        if cls.own_solver and names != [default]:
            notes.append(f"{c} solves with its own {cls.own_solver}; the solvers do not apply")
        runs_of[c] = solver_runs(cls, [(s, tier, mode) for s in names], mode)
    runs: list[Run] = []
    for scenario in loaded:
        for c in controllers:
            reason = controller_class(c).applies_to(scenario.spec)
            if reason:
                notes.append(f"{scenario.name} · {c} not run: {reason}")
                continue
            runs += [planner.run(scenario, c, s, tier=t, mode=m) for s, t, m in runs_of[c]]
    if not runs:
        raise WbcBenchError("none of the controllers applies to any of the scenarios")
    return runs, notes


def check_scenario(loaded: LoadedScenario, robot: Robot) -> None:
    """Everything a scenario names must exist in its robot, and its controllers' settings
    must validate (by the controller registry)."""
    check_against_robot(loaded, robot)
    check_scenario_settings(loaded, robot)
