"""Sweep files: a validated matrix of scenarios × controllers × solvers × settings.

A sweep file (YAML, ``version: 1``) holds lists of *matrices*. Each ``tracking`` matrix expands
into closed-loop runs, each ``timing`` matrix into open-loop replay timing runs on recorded states;
``solver_comparison`` compares every QP backend on the dumped QPs of replayed steps and
``hls_scaling`` times the hierarchical least-squares algorithms against the problem size, and
``push_recovery`` bisects the largest push each controller × solver survives
(:mod:`wbcbench.bench.push_recovery`)::

    version: 1
    tracking:
      - scenarios: ["*"]            # names, paths or globs over the scenarios/ folder
        controllers: ["*"]          # "*" = every controller that applies to the scenario
        solvers: [default]          # default | native | all | names | globs
                                    # (native: every library once; all: also qpsolvers:<name>
                                    # and named settings such as osqp_libdwbc)
        configs: {to_osf: [{}, {inverse: pinv}]}    # controller-config variants
        impls: [native, python]     # both impls of the controllers that have a native tick
        set: ["duration=3"]         # scenario overrides for every scenario of the matrix
        robots: [tocabi_dof20, tocabi_dof45]    # one run per robot (override robot=<name>)
    timing:
      - solvers: [native]
        modes: [cold, hot]
        ticks: 300
        record_with: [lqp, to_osf]  # whose closed-loop run is replayed: the first that applies
                                    # and does not fall or fail inside the window
        skip: [{solver: piqp, mode: cold, reason: "interior point, 15 ms per solve"}]

:func:`plan_sweep` validates everything (every scenario against its robot, every controller,
solver, tier, mode and config override) before the first simulation step and returns the list of
jobs; :func:`run_sweep` runs them. Every error names the sweep file and the key path.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from wbcbench.bench.checks import CHECK_FACTOR
from wbcbench.bench.provenance import BUSY_LOAD_PER_CORE, other_work, other_work_per_core
from wbcbench.errors import ScenarioError, UnknownNameError, WbcBenchError
from wbcbench.qp.registry import default_solver
from wbcbench.runs import Planner, Run, RunSettings, solver_runs

Tier = Literal["default", "low", "mid", "high"]
Mode = Literal["cold", "warm", "hot"]
Impl = Literal["default", "native", "python"]
SWEEP_DIR = Path(__file__).resolve().parents[2] / "sweeps"


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SkipRule(Strict):
    """Combinations not to run, recorded as ``skipped`` rows with the reason (fnmatch patterns)."""

    scenario: str = "*"
    controller: str = "*"
    solver: str = "*"
    mode: str = "*"
    tier: str = "*"
    reason: str = Field(min_length=1)

    def matches(self, scenario: str, settings: RunSettings) -> bool:
        return all(
            fnmatch.fnmatchcase(value, pattern)
            for value, pattern in (
                (scenario, self.scenario),
                (settings.controller, self.controller),
                (settings.solver, self.solver),
                (settings.mode, self.mode),
                (settings.tier, self.tier),
            )
        )


class MatrixSpec(Strict):
    """Scenarios × controllers × solvers × tiers × modes × config variants × override sets."""

    scenarios: list[str] = ["*"]
    controllers: list[str] = ["*"]
    solvers: list[str] = ["default"]
    tiers: list[Tier] = ["default"]
    modes: list[Mode] = ["cold"]
    configs: dict[str, list[dict[str, Any]]] = Field(
        default_factory=dict,
        description="controller → list of config overrides; each is one run (replaces {})",
    )
    set: list[str] = Field(default_factory=list, description="KEY=VALUE for every scenario")
    impls: list[Impl] = Field(
        ["default"],
        description="one run per impl of each controller that has a native tick (default: the "
        "controller's own choice); a Python-only controller runs once",
    )
    variants: list[list[str]] = Field([[]], description="further override sets, one run each")
    robots: list[str] = Field(
        default_factory=list,
        description="run every scenario on each of these robots (override robot=<name>, one "
        "scenario hash each); empty: the scenario's own robot",
    )
    skip: list[SkipRule] = Field(default_factory=list)
    wall_limit_s: float | None = Field(
        None,
        gt=0,
        description="wall-clock guard of each run [s]: a run still going then (a hung solver) "
        "is stopped and recorded as failed; default from the scenario's duration",
    )


class TrackingSpec(MatrixSpec):
    """Closed-loop runs in MuJoCo."""

    log_every: int = Field(1, ge=1, description="keep every N-th tick of the per-tick log")
    max_duration: float | None = Field(
        None,
        gt=0,
        description="shorten longer scenarios to this [s] (their metrics window moves inside "
        "the run); for quick sweeps, never for reproducing a paper's window",
    )
    check_factor: float | None = Field(
        CHECK_FACTOR,
        gt=0,
        description="after each step, QPs reported solved must meet their KKT conditions "
        "(relative to the problem's scale) to check_factor × the accuracy the tier asks of the "
        "backend, else the tick fails (None: no check)",
    )


#: who records the replayed states when nothing says otherwise: the default sweep's chain
DEFAULT_RECORDERS: tuple[str, ...] = ("qp_wbc", "lqp", "to_osf")


class TimingSpec(MatrixSpec):
    """Open-loop replay timing on the states of one recorded closed-loop run per scenario."""

    solvers: list[str] = ["native"]
    modes: list[Mode] = ["hot"]
    ticks: int = Field(300, ge=1, description="replayed ticks, warm-up included")
    warmup: int = Field(50, ge=0, description="first ticks discarded from the statistics")
    start: float | None = Field(
        None, ge=0, description="replay from this time [s]; default: the metrics window start"
    )
    record_with: list[str] = Field(
        default_factory=lambda: list(DEFAULT_RECORDERS),
        description="controllers to record the states with, in order: the first that applies "
        "and whose closed-loop run covers the window (does not fall or fail before its end)",
    )
    max_step_ms: float = Field(
        50.0, gt=0, description="abandon (skip) a combination slower than this per tick"
    )
    probe_ticks: int = Field(20, ge=1, description="ticks after which max_step_ms is checked")
    interleave: int = Field(
        10,
        ge=0,
        description="the rows of one scenario, solver, tier, mode and impl (the controllers and "
        "their configurations) are timed together, each stepping this many ticks in turn, so "
        "that a change in the machine's speed falls on all alike; 0: each row alone",
    )
    keep_log: bool = Field(True, description="save the per-tick stage times of each run")
    check_factor: float | None = Field(
        CHECK_FACTOR,
        gt=0,
        description="after each timed step, QPs reported solved must meet their KKT conditions "
        "(relative to the problem's scale) to check_factor × the accuracy the tier asks of the "
        "backend (None: no check)",
    )


class SolverComparisonSpec(Strict):
    """Every backend on the dumped QPs of replayed steps (qpbenchmark style)."""

    scenarios: list[str] = ["*"]
    controllers: list[str] = ["*"]
    solvers: list[str] = ["all"]
    tiers: list[Tier] = ["default", "low", "mid", "high"]
    modes: list[Mode] = ["cold", "warm", "hot"]
    dump_ticks: int = Field(4, ge=1, description="consecutive ticks dumped per pair")
    dump_after: int = Field(20, ge=0, description="replayed ticks before the first dump")
    reference_solver: str = "clarabel"
    dump_solver: str = Field(
        "default",
        description="the backend the controllers replay with while their QPs are dumped (a "
        "hierarchy's lower levels depend on the solutions of the higher ones)",
    )
    max_solve_ms: float = Field(
        250.0, gt=0, description="a solver × tier × mode slower than this once is skipped"
    )
    skip: list[SkipRule] = Field(default_factory=list)
    solve_limit_s: float = Field(
        10.0,
        gt=0,
        description="deadline of each solve [s]: a solve still going then (a hung solver) is "
        "stopped and recorded as failed, the rest of its solver × tier × mode skipped, and the "
        "comparison goes on",
    )
    wall_limit_s: float = Field(
        3600.0,
        gt=0,
        description="wall-clock guard of the whole comparison [s] (the rows written so far "
        "stay) and the sweep goes on",
    )


class HlsScalingSpec(Strict):
    """RQR-HQP Fig. 1: reduced QR vs full-size QR vs SVD hierarchies against the size N."""

    sizes: list[int] = [10, 20, 40, 60, 80, 100]
    repeats: int = Field(50, ge=1)
    impls: list[Literal["native", "python"]] = Field(
        ["native", "python"],
        min_length=1,
        description="the C++ mirror (timed inside the module) and the Python reference",
    )


class PushRecoverySpec(Strict):
    """The push-recovery study (:mod:`wbcbench.bench.push_recovery`): per scenario ×
    controller × solver and direction, the largest survived impulse, bracketed."""

    scenarios: list[str] = ["tocabi_stand_sway"]
    controllers: list[str] = ["*"]
    solvers: list[str] = ["daqp"]
    directions: list[Literal["+x", "-x", "+y", "-y"]] = Field(
        ["+x", "-x", "+y", "-y"], min_length=1, description="world axes"
    )
    body: str | dict[str, str] = Field(
        "pelvis", description="the pushed body, or scenario name → body (robots name it apart)"
    )
    start: float = Field(0.5, ge=0, le=60, description="when the push starts [s]")
    duration: float = Field(0.1, gt=0, le=5, description="how long it lasts [s]")
    recover_time: float = Field(
        1.0, gt=0, le=60, description="after the push, when the CoM is judged [s]"
    )
    recover_distance: float = Field(
        0.02, gt=0, le=1, description="how close to its reference the CoM must be then [m]"
    )
    max_impulse: float = Field(80.0, gt=0, le=1e4, description="the search's upper end [N·s]")
    resolution: float = Field(5.0, gt=0, description="the widest reported bracket [N·s]")
    wall_limit_s: float = Field(
        14_400.0, gt=0, description="wall-clock guard of the whole study [s]"
    )

    @model_validator(mode="after")
    def _resolution(self) -> PushRecoverySpec:
        if not self.resolution < self.max_impulse:
            raise ValueError(
                f"resolution ({self.resolution:g} N·s) must be below max_impulse "
                f"({self.max_impulse:g} N·s)"
            )
        return self


class SweepSpec(Strict):
    """A sweep file."""

    version: Literal[1]
    description: str = ""
    tracking: list[TrackingSpec] = Field(default_factory=list)
    timing: list[TimingSpec] = Field(default_factory=list)
    solver_comparison: SolverComparisonSpec | None = None
    hls_scaling: HlsScalingSpec | None = None
    push_recovery: PushRecoverySpec | None = None


# -- the expanded plan


@dataclass
class Job:
    """One run of the plan (a row of the results table)."""

    kind: str  # tracking | timing
    run: Run
    options: dict[str, Any] = field(default_factory=dict)
    skip_reason: str = ""

    @property
    def label(self) -> str:
        return f"{self.kind} {self.run.label}"

    @property
    def extra(self) -> dict[str, Any]:
        """Settings beyond RunSettings that make the row distinct (part of the run id)."""
        if self.kind == "tracking":
            return {}
        return {"kind": self.kind, **self.options}


@dataclass
class SweepPlan:
    """Validated jobs, the combinations that do not apply, and the report settings."""

    file: str
    spec: SweepSpec
    jobs: list[Job]
    not_applicable: list[str]
    comparison: SolverComparisonSpec | None
    #: (run, recording options) whose QPs the comparison dumps
    comparison_targets: list[tuple[Run, dict[str, Any]]]
    comparison_solvers: list[str]
    timing_by_scenario: dict[str, dict[str, Any]]  # scenario key → recording options
    #: (scenario, controller, solver, pushed body) of the push-recovery study
    push_targets: list[tuple[str, str, str, str]] = field(default_factory=list)


def load_sweep_file(path: str | Path) -> tuple[str, SweepSpec]:
    """Read and validate a sweep file (a path, or a name in the top-level ``sweeps/``)."""
    p = Path(path)
    if not p.exists() and (SWEEP_DIR / f"{path}.yaml").exists():
        p = SWEEP_DIR / f"{path}.yaml"
    file = str(p)
    if not p.exists():
        valid = sorted(x.stem for x in SWEEP_DIR.glob("*.yaml"))
        raise UnknownNameError("sweep file", file, valid, hint="or give a path to a YAML file")
    from wbcbench.scenarios.load import UniqueKeyLoader

    try:
        raw = yaml.load(p.read_text(), Loader=UniqueKeyLoader)
    except yaml.YAMLError as exc:
        raise ScenarioError(file, "", f"not valid YAML: {exc}") from None
    if not isinstance(raw, dict):
        raise ScenarioError(file, "", "a sweep file must be a mapping of keys to values")
    from wbcbench.scenarios.load import validation_error

    try:
        return file, SweepSpec.model_validate(raw)
    except ValidationError as exc:
        raise validation_error(file, exc, SweepSpec) from None


# -- name resolution


def _is_glob(text: str) -> bool:
    return any(ch in text for ch in "*?[")


def _installed(name: str) -> bool:
    """Whether the robot of shipped scenario ``name`` can be loaded (a third-party robot's
    distribution is installed); an unreadable file counts as installed, to fail later by name."""
    from wbcbench.robots.loader import third_party_robots
    from wbcbench.scenarios.load import SCENARIO_DIR, read_yaml_mapping

    try:
        robot = read_yaml_mapping(SCENARIO_DIR / f"{name}.yaml", "a scenario file").get("robot")
    except WbcBenchError:
        return True
    return not (isinstance(robot, str) and third_party_robots().get(robot))


def resolve_scenarios(patterns: Sequence[str], file: str, key: str) -> list[str]:
    """Scenario names or paths: globs over the scenarios/ folder, names, or file paths."""
    from wbcbench.scenarios.load import available_scenarios, resolve_scenario_path

    out: list[str] = []
    for i, pattern in enumerate(patterns):
        if _is_glob(pattern):
            # a glob leaves out the shipped scenarios of third-party robots that are not
            # installed (`wbcbench[robots]`, `wbcbench[icub]`); named explicitly, one is an
            # error saying so
            names = [n for n in fnmatch.filter(available_scenarios(), pattern) if _installed(n)]
            if not names:  # a file glob, e.g. my_scenarios/*.yaml
                names = sorted(str(p) for p in Path().glob(pattern) if p.suffix == ".yaml")
            out += [n for n in names if n not in out]
            continue
        try:
            path = resolve_scenario_path(pattern)
        except (UnknownNameError, ScenarioError) as exc:  # not a scenario, or no such file
            raise ScenarioError(file, f"{key}[{i}]", str(exc)) from None
        name = pattern if pattern in available_scenarios() else str(path)
        if name not in out:
            out.append(name)
    return out


def resolve_controllers(patterns: Sequence[str], file: str, key: str) -> list[tuple[str, bool]]:
    """(name, explicit) pairs; globs expand over the registry."""
    from wbcbench.controllers.registry import available_controllers, controller_class

    out: list[tuple[str, bool]] = []
    for i, pattern in enumerate(patterns):
        if _is_glob(pattern):
            out += [(n, False) for n in fnmatch.filter(available_controllers(), pattern)]
            continue
        try:
            controller_class(pattern)
        except UnknownNameError as exc:
            raise ScenarioError(file, f"{key}[{i}]", str(exc)) from None
        out.append((pattern, True))
    unique: dict[str, bool] = {}
    for n, e in out:
        unique.setdefault(n, e)
    return list(unique.items())


def native_solvers() -> list[str]:
    """Installed backends that call their library directly (not through qpsolvers), each once:
    named settings of a backend (``osqp_libdwbc``) are chosen by name or by ``all``."""
    from wbcbench.qp import available_backends

    return available_backends()


def resolve_solvers(patterns: Sequence[str], file: str, key: str) -> list[str]:
    """``default``, ``native``, ``all``, globs over the installed names, or names."""
    from wbcbench.qp import available_solvers, solver_class

    out: list[str] = []
    for i, pattern in enumerate(patterns):
        if pattern == "default":
            names = [default_solver()]
        elif pattern == "native":
            names = native_solvers()
        elif pattern == "all":
            names = available_solvers()
        elif _is_glob(pattern):
            names = fnmatch.filter(available_solvers(), pattern)
        else:
            try:
                solver_class(pattern)
            except UnknownNameError as exc:
                raise ScenarioError(
                    file, f"{key}[{i}]", f"{exc}; or one of default, native, all"
                ) from None
            names = [pattern]
        out += [n for n in names if n not in out]
    return out


def check_solver_choices(
    patterns: Sequence[str], tiers: Sequence[str], modes: Sequence[str], file: str, key: str
) -> None:
    """A solver named explicitly must run at one of the matrix's tiers × modes at least (a
    named setting runs at its own only); the other combinations are dropped by the plan.

    Raises:
        ScenarioError: at ``{key}.solvers[i]``, naming the tiers and modes it runs at.
    """
    from wbcbench.qp import solver_class

    for i, pattern in enumerate(patterns):
        if pattern in ("default", "native", "all") or _is_glob(pattern):
            continue
        cls = solver_class(pattern)
        if not any(cls.offers(t, m) for t in tiers for m in modes):
            raise ScenarioError(
                file,
                f"{key}.solvers[{i}]",
                f"{pattern} runs at tier {', '.join(cls.tiers)} and mode {', '.join(cls.modes)} "
                f"only, and this matrix asks for tiers {', '.join(tiers)} × modes "
                f"{', '.join(modes)}" + (f" ({cls.choice_hint})" if cls.choice_hint else ""),
            )


def offered_choices(
    solvers: Sequence[str], tiers: Sequence[str], modes: Sequence[str], key: str
) -> tuple[dict[tuple[str, str, str], bool], list[str]]:
    """Which solver × tier × mode of a matrix the solvers run at, and one not-applicable line
    per solver that does not run at all of them (a named setting)."""
    from wbcbench.qp import solver_class

    offered: dict[tuple[str, str, str], bool] = {}
    notes: list[str] = []
    for solver in solvers:
        cls = solver_class(solver)
        for tier in tiers:
            for mode in modes:
                offered[(solver, tier, mode)] = cls.offers(tier, mode)
        if not all(offered[(solver, t, m)] for t in tiers for m in modes):
            notes.append(
                f"{key} · {solver}: runs at tier {', '.join(cls.tiers)}, mode "
                f"{', '.join(cls.modes)} only; the matrix's other tiers × modes are not planned"
            )
    return offered, notes


# -- planning


def _scenario(planner: Planner, name: str, overrides: tuple[str, ...], file: str, key: str) -> Any:
    """The scenario with its overrides, checked against its robot (once per plan)."""
    try:
        return planner.scenario(name, overrides)[0]
    except WbcBenchError as exc:
        raise ScenarioError(file, key, f"scenario {name!r}: {exc}") from None


def _config_variants(
    matrix: MatrixSpec | SolverComparisonSpec, controller: str, loaded: Any, file: str, key: str
) -> list[dict[str, Any]]:
    """The config overrides of a controller, each validated by the controller registry."""
    from wbcbench.controllers.registry import controller_class, validated_config

    variants = getattr(matrix, "configs", {}).get(controller, [{}]) or [{}]
    cls = controller_class(controller)
    for i, variant in enumerate(variants):
        validated_config(cls, loaded, variant, file, f"{key}.configs.{controller}[{i}]")
    return variants


def _impl_configs(
    impls: Sequence[str], controller: str, scheduled: bool = False
) -> list[dict[str, str]]:
    """The ``impl`` overrides of a controller for a matrix's ``impls`` (each once); on a
    scenario whose contacts change (``scheduled``) without native where the controller's native
    tick holds a fixed set."""
    from wbcbench.controllers.registry import controller_class

    cls = controller_class(controller)
    has_native = cls.has_native
    out: list[dict[str, str]] = []
    for impl in impls:
        if scheduled and impl == "native" and not cls.native_schedule:
            continue
        config = {"impl": impl} if impl != "default" and has_native else {}
        if config not in out:
            out.append(config)
    return out


def _check_config_keys(matrix: MatrixSpec, file: str, key: str) -> None:
    from wbcbench.controllers.registry import controller_class

    for name in matrix.configs:
        try:
            controller_class(name)
        except UnknownNameError as exc:
            raise ScenarioError(file, f"{key}.configs.{name}", str(exc)) from None


def _robot_overrides(matrix: MatrixSpec, file: str, key: str) -> list[tuple[str, ...]]:
    """One ``robot=<name>`` override per entry of ``robots`` (checked); ``[()]`` when empty."""
    from wbcbench.robots.loader import available_robots, plugin_robots, third_party_robots

    if not matrix.robots:
        return [()]
    valid = [*available_robots(), *third_party_robots(), *plugin_robots()[0]]
    for i, name in enumerate(matrix.robots):
        if name not in valid:
            raise ScenarioError(
                file, f"{key}.robots[{i}]", str(UnknownNameError("robot", name, valid))
            )
    return [(f"robot={name}",) for name in dict.fromkeys(matrix.robots)]


def _timing_start(matrix: TimingSpec, loaded: Any) -> float:
    """The window start: given, else the metrics window's, moved earlier to fit the run."""
    if matrix.start is not None:
        start = matrix.start
    else:
        window = loaded.spec.metrics.window
        start = float(window[0]) if window else 0.0
    latest = loaded.spec.duration - matrix.ticks * loaded.spec.dt
    return round(max(0.0, min(start, latest)), 6)


def _recorders(matrix: TimingSpec, loaded: Any, file: str, key: str) -> list[str]:
    """The controllers that may record the states, in order: those of record_with that apply
    (the first whose run covers the window is used), else the first registered that applies."""
    from wbcbench.controllers.registry import available_controllers, controller_class

    listed = []
    for i, name in enumerate(matrix.record_with):
        try:
            cls = controller_class(name)
        except UnknownNameError as exc:
            raise ScenarioError(file, f"{key}.record_with[{i}]", str(exc)) from None
        if not cls.applies_to(loaded.spec):
            listed.append(name)
    if listed:
        return listed
    for name in available_controllers():
        if not controller_class(name).applies_to(loaded.spec):
            return [name]
    raise ScenarioError(file, key, f"no registered controller applies to {loaded.name!r}")


def _shorten(spec: Any, cap: float) -> tuple[str, ...]:
    """Overrides that cut a scenario to ``cap`` seconds, moving its metrics window inside."""
    if spec.duration <= cap:
        return ()
    out = [f"duration={cap:g}"]
    window = spec.metrics.window
    if window is not None and window[1] > cap:
        out.append(f"metrics.window=[{min(window[0], cap / 2):g}, {cap:g}]")
    return tuple(out)


def _recorder_options(recorders: list[str]) -> dict[str, Any]:
    """``recorder`` (the first choice) and, when there are more, ``fallback_recorders``."""
    out: dict[str, Any] = {"recorder": recorders[0]}
    if recorders[1:]:
        out["fallback_recorders"] = recorders[1:]
    return out


def _timing_options(matrix: TimingSpec, loaded: Any, file: str, key: str) -> dict[str, Any]:
    return dict(
        ticks=matrix.ticks,
        warmup=matrix.warmup,
        start=_timing_start(matrix, loaded),
        **_recorder_options(_recorders(matrix, loaded, file, key)),
        max_step_ms=matrix.max_step_ms,
        probe_ticks=matrix.probe_ticks,
        interleave=matrix.interleave,
        check_factor=matrix.check_factor,
        **({} if matrix.keep_log else {"keep_log": False}),
    )


def plan_sweep(file: str, spec: SweepSpec) -> SweepPlan:
    """Expand and validate the whole matrix; nothing is simulated.

    A solver × tier × mode the solver does not run at (a named setting runs at its own only) is
    not planned; the plan's ``not_applicable`` says so once per solver and matrix.
    """
    from wbcbench.controllers.registry import controller_class
    from wbcbench.qp import solver_class

    planner = Planner()
    jobs: list[Job] = []
    not_applicable: list[str] = []
    timing_opts: dict[str, dict[str, Any]] = {}
    groups: list[tuple[str, str, MatrixSpec]] = [
        *(("tracking", f"tracking[{i}]", m) for i, m in enumerate(spec.tracking)),
        *(("timing", f"timing[{i}]", m) for i, m in enumerate(spec.timing)),
    ]
    for kind, key, matrix in groups:
        _check_config_keys(matrix, file, key)
        names = resolve_scenarios(matrix.scenarios, file, f"{key}.scenarios")
        controllers = resolve_controllers(matrix.controllers, file, f"{key}.controllers")
        solvers = resolve_solvers(matrix.solvers, file, f"{key}.solvers")
        check_solver_choices(matrix.solvers, matrix.tiers, matrix.modes, file, key)
        offered, notes = offered_choices(solvers, matrix.tiers, matrix.modes, key)
        not_applicable += notes
        backend_runs: list[tuple[str, str, str]] = [
            (solver, tier, mode)
            for solver in solvers
            for tier in matrix.tiers
            for mode in matrix.modes
            if offered[(solver, tier, mode)]
        ]
        runs_of: dict[str, list[tuple[str, str, str]]] = {}
        for controller, explicit in controllers:
            cls = controller_class(controller)
            runs_of[controller] = solver_runs(cls, backend_runs, matrix.modes[0])
            own = cls.own_solver
            if own and explicit and matrix.solvers != ["default"]:
                not_applicable.append(
                    f"{key} · {controller}: solves with its own {own}; solvers do not apply"
                )
        robots = _robot_overrides(matrix, file, key)
        combos = [
            (robot, variant, f"{key}.robots[{r}]" if robot else f"{key}.variants[{v}]")
            for r, robot in enumerate(robots)
            for v, variant in enumerate(matrix.variants)
        ]
        for name in names:
            for robot, variant, where in combos:
                overrides = (*robot, *matrix.set, *variant)
                loaded = _scenario(planner, name, overrides, file, where)
                if isinstance(matrix, TrackingSpec) and matrix.max_duration is not None:
                    extra = _shorten(loaded.spec, matrix.max_duration)
                    if extra:
                        overrides = (*overrides, *extra)
                        loaded = _scenario(planner, name, overrides, file, f"{key}.max_duration")
                options: dict[str, Any] = {}
                if isinstance(matrix, TimingSpec):
                    options = _timing_options(matrix, loaded, file, key)
                    timing_opts[f"{loaded.name}@{loaded.hash}"] = options
                    if overrides:  # in the row's settings, so a report can rebuild the scenario
                        options = {**options, "overrides": list(overrides)}
                elif isinstance(matrix, TrackingSpec):
                    options = dict(check_factor=matrix.check_factor)
                    if matrix.log_every != 1:
                        options["log_every"] = matrix.log_every
                if matrix.wall_limit_s is not None:
                    options["wall_limit_s"] = matrix.wall_limit_s
                for controller, explicit in controllers:
                    reason = controller_class(controller).applies_to(loaded.spec)
                    if reason:
                        if explicit:
                            not_applicable.append(f"{loaded.name} · {controller}: {reason}")
                        continue
                    scheduled = loaded.spec.has_schedule
                    fixed_set = not controller_class(controller).native_schedule
                    if scheduled and fixed_set and "native" in matrix.impls:
                        not_applicable.append(
                            f"{loaded.name} · {controller} impl native: the native tick holds a "
                            "fixed contact set"
                        )
                    for config in [
                        {**variant, **impl}
                        for variant in _config_variants(matrix, controller, loaded, file, key)
                        for impl in _impl_configs(matrix.impls, controller, scheduled)
                    ]:
                        for solver, tier, mode in runs_of[controller]:
                            run = planner.run(
                                loaded,
                                controller,
                                solver,
                                tier=tier,
                                mode=mode,
                                config=dict(config),
                                timing=kind == "timing",
                            )
                            skip = next(
                                (
                                    r.reason
                                    for r in matrix.skip
                                    if r.matches(loaded.name, run.settings)
                                ),
                                "",
                            )
                            jobs.append(Job(kind, run, dict(options), skip))
    comparison = spec.solver_comparison
    targets: list[tuple[Run, dict[str, Any]]] = []
    comp_solvers: list[str] = []
    if comparison is not None:
        key = "solver_comparison"
        comp_solvers = resolve_solvers(comparison.solvers, file, f"{key}.solvers")
        check_solver_choices(comparison.solvers, comparison.tiers, comparison.modes, file, key)
        not_applicable += offered_choices(comp_solvers, comparison.tiers, comparison.modes, key)[1]
        resolve_solvers([comparison.reference_solver], file, f"{key}.reference_solver")
        dump_solver = resolve_solvers([comparison.dump_solver], file, f"{key}.dump_solver")[0]
        if not solver_class(comparison.reference_solver).offers("high", "cold"):
            raise ScenarioError(
                file,
                f"{key}.reference_solver",
                f"{comparison.reference_solver} does not run at tier high: the reference "
                "solutions are high-tier solves of a backend (e.g. clarabel, proxqp)",
            )
        names = resolve_scenarios(comparison.scenarios, file, f"{key}.scenarios")
        controllers = resolve_controllers(comparison.controllers, file, f"{key}.controllers")
        for name in names:
            loaded = _scenario(planner, name, (), file, f"{key}.scenarios")
            options = timing_opts.get(f"{loaded.name}@{loaded.hash}") or _timing_options(
                TimingSpec(), loaded, file, key
            )
            for controller, _ in controllers:
                if not controller_class(controller).applies_to(loaded.spec):
                    run = planner.run(loaded, controller, dump_solver, mode="hot", timing=True)
                    targets.append((run, options))
    pushes = _push_targets(planner, spec.push_recovery, file, not_applicable)
    return SweepPlan(
        file, spec, jobs, not_applicable, comparison, targets, comp_solvers, timing_opts, pushes
    )


def _push_targets(
    planner: Planner, study: PushRecoverySpec | None, file: str, notes: list[str]
) -> list[tuple[str, str, str, str]]:
    """The study's scenario × controller × solver with the body each scenario's robot is pushed
    on, each trial's scenario checked once (the pushed body, the controller's settings) before
    any simulation step."""
    from wbcbench.bench.push_recovery import DIRECTIONS, push_overrides
    from wbcbench.controllers.registry import controller_class

    if study is None:
        return []
    key = "push_recovery"
    names = resolve_scenarios(study.scenarios, file, f"{key}.scenarios")
    controllers = resolve_controllers(study.controllers, file, f"{key}.controllers")
    solvers = resolve_solvers(study.solvers, file, f"{key}.solvers")
    out: list[tuple[str, str, str, str]] = []
    bodies = study.body if isinstance(study.body, dict) else {}
    for name in bodies:
        if name not in names:
            raise ScenarioError(
                file, f"{key}.body.{name}", f"not one of the study's scenarios: {', '.join(names)}"
            )
    for name in names:
        body = bodies.get(name, "pelvis") if bodies else str(study.body)
        settings = dataclasses.replace(push_study(study), body=body)
        overrides = tuple(push_overrides(settings, next(iter(DIRECTIONS)), study.max_impulse))
        where = f"{key}.body.{name}" if bodies else f"{key}.body"
        loaded = _scenario(planner, name, overrides, file, where)
        if not any(t.type == "com" for t in loaded.spec.tasks):
            raise ScenarioError(
                file, f"{key}.scenarios", f"scenario {name!r} has no com task to judge by"
            )
        for controller, explicit in controllers:
            cls = controller_class(controller)
            reason = cls.applies_to(loaded.spec) or (
                "velocity-level: no physics to push" if cls.kind == "velocity" else ""
            )
            if reason:
                if explicit:
                    notes.append(f"{key} · {loaded.name} · {controller}: {reason}")
                continue
            for solver in [cls.own_solver] if cls.own_solver else solvers:
                planner.run(loaded, controller, solver)
                if (name, controller, solver, body) not in out:
                    out.append((name, controller, solver, body))
    # controller by controller (in the study's order, each on every scenario), so that an
    # interrupted study holds its first controllers on every robot
    order = [c for c, _ in controllers]
    return sorted(out, key=lambda t: order.index(t[1]))


def push_study(spec: PushRecoverySpec) -> Any:
    """The study's settings (:class:`wbcbench.bench.push_recovery.PushStudy`)."""
    from wbcbench.bench.push_recovery import PushStudy

    return PushStudy(
        body=spec.body if isinstance(spec.body, str) else "pelvis",
        start=spec.start,
        duration=spec.duration,
        recover_time=spec.recover_time,
        recover_distance=spec.recover_distance,
        max_impulse=spec.max_impulse,
        resolution=spec.resolution,
    )


def plan_from_names(
    scenarios: Sequence[str],
    controllers: Sequence[str],
    solvers: Sequence[str],
    tiers: Sequence[str] = ("default",),
    modes: Sequence[str] = ("cold",),
    overrides: Sequence[str] = (),
    kind: Literal["tracking", "timing"] = "tracking",
    record_with: Sequence[str] = DEFAULT_RECORDERS,
) -> SweepPlan:
    """A one-matrix plan from command-line names and globs (validated like a file).

    ``record_with``: for timing plans, the controllers that record the replayed states, in
    order (the first that applies and covers the window).
    """
    matrix: dict[str, Any] = {
        "scenarios": list(scenarios),
        "controllers": list(controllers),
        "solvers": list(solvers),
        "tiers": list(tiers),
        "modes": list(modes),
        "set": list(overrides),
    }
    if kind == "timing":
        matrix["record_with"] = list(record_with)
    raw: dict[str, Any] = {"version": 1, kind: [matrix]}
    from wbcbench.scenarios.load import validation_error

    try:
        spec = SweepSpec.model_validate(raw)
    except ValidationError as exc:
        raise validation_error("command line", exc, SweepSpec) from None
    return plan_sweep("command line", spec)


# -- running

#: row statuses that make a sweep exit non-zero (a fall is a measurement, not a failure)
NOT_OK = ("failed", "error")


@dataclass
class SweepReport:
    """What a sweep did: rows computed, skipped as already done, and failures.

    ``failed`` lists the rows computed now whose status is ``failed`` or ``error``;
    ``not_ok`` the statuses of every planned row (computed or resumed) that is one of those.
    """

    computed: int = 0
    resumed: int = 0
    #: rows copied from another results folder of the same code (``reuse``)
    reused: int = 0
    failed: list[str] = field(default_factory=list)
    not_ok: dict[str, int] = field(default_factory=dict)
    #: timing rows computed now: how many, and the machine conditions of those timed busy
    timed: int = 0
    busy: list[dict[str, Any]] = field(default_factory=list)

    def busy_line(self) -> str:
        """One line for every timing row timed on a busy machine, with the worst load (or "")."""
        if not self.busy:
            return ""
        worst = max(self.busy, key=other_work_per_core)
        return (
            f"warning: {len(self.busy)} of {self.timed} timing rows were timed on a busy machine "
            f"(worst: load {worst.get('load_1min', float('nan')):g}, {other_work(worst)}, above "
            f"{BUSY_LOAD_PER_CORE:g}): compare their times only within this run; the paper "
            "verdicts resting on them say inconclusive"
        )


def run_sweep(
    plan: SweepPlan,
    out: str | Path,
    executor: str = "serial",
    scheduler: str | None = None,
    show_progress: bool = True,
    max_jobs: int | None = None,
    on_row: Callable[[Job, dict[str, Any]], None] | None = None,
    rerun: Literal["none", "failed", "all"] = "none",
    reuse: str | Path | None = None,
) -> SweepReport:
    """Run every job of the plan, appending each row to the store in ``out`` as it finishes.

    Tracking jobs go to ``executor`` (``serial`` or ``dask``); timing jobs, the QP dumps, the
    solver comparison and the hierarchy scaling always run serially in this process with one
    BLAS thread. A rerun skips the rows already in ``out``, except those ``rerun`` names:
    ``failed`` recomputes the planned rows stored as ``failed`` or ``error``, ``all`` every
    planned row (their old rows, metrics and logs are removed first). ``max_jobs`` stops
    after that many computed rows (to test interruption).

    ``reuse`` names another results folder (e.g. ``make bench``'s) whose closed-loop and timing
    rows with the same run id (the same scenario, settings and code) are copied instead of
    computed again (:meth:`~wbcbench.bench.results.ResultsStore.reuse`); not with ``rerun="all"``.

    The sweep holds ``out`` for its whole run (:class:`~wbcbench.bench.lock.SweepLock`): it
    starts only once no earlier sweep on the folder, nor any process one started, is alive.
    """
    from wbcbench.bench.lock import SweepLock

    with SweepLock(out):
        return _run_sweep(
            plan, out, executor, scheduler, show_progress, max_jobs, on_row, rerun, reuse
        )


def _run_sweep(
    plan: SweepPlan,
    out: str | Path,
    executor: str,
    scheduler: str | None,
    show_progress: bool,
    max_jobs: int | None,
    on_row: Callable[[Job, dict[str, Any]], None] | None,
    rerun: Literal["none", "failed", "all"],
    reuse: str | Path | None = None,
) -> SweepReport:
    from threadpoolctl import threadpool_limits
    from tqdm import tqdm

    from wbcbench.bench.executors import make_executor
    from wbcbench.bench.results import ResultsStore
    from wbcbench.bench.runner import code_version, run_id
    from wbcbench.bench.timing import (
        guarded_timing_group,
        run_hls_scaling,
        skipped_record,
        timing_groups,
    )

    store = ResultsStore(out)
    version = code_version(store)
    planned_ids = {run_id(job.run, version, extra=job.extra) for job in plan.jobs}
    if rerun != "none":
        statuses = store.run_statuses()
        store.forget(
            {
                rid
                for rid in planned_ids
                if rid in statuses and (rerun == "all" or statuses[rid] in NOT_OK)
            }
        )
    report = SweepReport()
    if reuse is not None and rerun != "all":  # --force recomputes; it copies nothing
        copyable = {
            run_id(job.run, version, extra=job.extra): job
            for job in plan.jobs
            if job.kind in ("tracking", "timing") and not job.skip_reason
        }
        wanted = {
            rid: (int(job.options.get("log_every", 1)), float(job.run.scenario.spec.dt))
            for rid, job in copyable.items()
        }
        for rid in store.reuse(reuse, wanted):
            loaded = copyable[rid].run.scenario
            store.record_scenario(loaded.name, loaded.hash, str(loaded.path))
            report.reused += 1
    done = store.done_run_ids()
    pending: list[tuple[Job, str]] = []
    planned: set[str] = set()
    for job in plan.jobs:
        rid = run_id(job.run, version, extra=job.extra)
        if rid in done:
            report.resumed += 1
        elif rid not in planned:  # two matrices may name the same combination: run it once
            planned.add(rid)
            pending.append((job, rid))
    budget = [max_jobs if max_jobs is not None else len(pending) + 1]

    def finished(job: Job, record: Any) -> None:
        from wbcbench.bench.runner import store_record

        try:
            store_record(store, job.run, record)
        except Exception as exc:  # e.g. an unwritable log: keep the row, say what was lost
            record.log = None
            record.row["message"] = f"{record.row.get('message') or ''} (log not saved: {exc})"
            store_record(store, job.run, record)
        report.computed += 1
        budget[0] -= 1
        row = record.row
        if row.get("kind") == "timing" and row["status"] != "skipped":
            report.timed += 1
            conditions = _conditions(row)
            if conditions.get("busy"):
                report.busy.append(conditions)
        if row["status"] in NOT_OK:
            report.failed.append(f"{job.label}: {row['status']}: {row.get('message', '')}")
        if on_row is not None:
            on_row(job, row)

    with (
        tqdm(total=len(pending), desc="sweep", unit="run", disable=not show_progress) as bar,
        threadpool_limits(1),
    ):
        for job, rid in pending:
            if job.skip_reason:
                if budget[0] <= 0:
                    break
                finished(job, skipped_record(job, rid, version, job.skip_reason))
                bar.update()
        tracking = [(j, r) for j, r in pending if j.kind == "tracking" and not j.skip_reason]
        timing = [(j, r) for j, r in pending if j.kind == "timing" and not j.skip_reason]
        if tracking and budget[0] > 0:
            with make_executor(executor, scheduler) as ex:
                for job, record in ex.run(tracking[: budget[0]], version, str(store.folder)):
                    bar.set_postfix_str(job.label[:60])
                    finished(job, record)
                    bar.update()
        for group in timing_groups(timing):
            group = group[: max(0, budget[0])]
            if not group:
                break
            bar.set_postfix_str(group[0][0].label[:60])
            for (job, _), record in zip(
                group, guarded_timing_group(group, version, store.folder), strict=True
            ):
                finished(job, record)
                bar.update()
    store.refresh_mirror()
    final = store.run_statuses()
    for rid in planned_ids:
        status = final.get(rid)
        if status in NOT_OK:
            report.not_ok[status] = report.not_ok.get(status, 0) + 1
    if budget[0] <= 0 and max_jobs is not None:
        return report
    if plan.comparison is not None:
        from wbcbench.bench.solver_comparison import run_solver_comparison

        comparison = (plan, store.folder, show_progress)
        limit = plan.comparison.wall_limit_s
        _guarded("solver comparison", run_solver_comparison, comparison, limit, store.folder)
    if plan.spec.hls_scaling is not None:
        scaling = (plan.spec.hls_scaling, store, version)
        _guarded("hls scaling", run_hls_scaling, scaling, HLS_WALL_LIMIT_S, store.folder)
        store.refresh_mirror()  # (its rows were appended by the child)
    if plan.spec.push_recovery is not None and plan.push_targets:
        from wbcbench.bench.push_recovery import run_push_study

        study = plan.spec.push_recovery
        args = (
            plan.push_targets,
            list(study.directions),
            push_study(study),
            store.folder,
            version,
            show_progress,
        )
        _guarded("push recovery", run_push_study, args, study.wall_limit_s, store.folder)
    return report


def _conditions(row: dict[str, Any]) -> dict[str, Any]:
    """The machine conditions a timing row recorded (``settings.conditions``), or {}."""
    try:
        conditions = json.loads(str(row.get("settings") or "{}")).get("conditions")
    except (ValueError, AttributeError):
        return {}
    return conditions if isinstance(conditions, dict) else {}


#: wall-clock guard of the hierarchy scaling study [s] (dense linear algebra only: minutes)
HLS_WALL_LIMIT_S = 1800.0


def _guarded(
    what: str, fn: Callable[..., Any], args: tuple[Any, ...], seconds: float, folder: Path
) -> None:
    """``fn(*args)`` with one BLAS thread, in a child under the wall-clock guard where the
    platform has one (:mod:`wbcbench.bench.guard`, whose children run with one BLAS thread): a
    hang or a crash is reported and the sweep ends normally (what the child wrote to the folder
    stays; what it printed goes to ``folder``'s logs)."""
    from threadpoolctl import threadpool_limits

    from wbcbench.bench.guard import STOPPED_ENV, call_with_deadline, can_guard
    from wbcbench.bench.results import printed_path

    if not can_guard():
        with threadpool_limits(1):
            fn(*args)
        return
    printed = printed_path(folder, what.replace(" ", "_"))
    writer = (str(folder), os.getpid(), fn, args)
    end, left = time.monotonic() + seconds, seconds
    try:
        while True:
            outcome = call_with_deadline(as_writer, writer, left, printed)
            if outcome.ok:
                return
            print(f"{what}: {outcome.message}")
            left = end - time.monotonic()
            if not outcome.stalled or left <= 0:
                return
            # one step outlasted its own deadline: the work resumes in a new child, which
            # records that step as failed and goes on with the rest
            os.environ[STOPPED_ENV] = "1"
    finally:
        os.environ.pop(STOPPED_ENV, None)


def as_writer(folder: str, sweep_pid: int, fn: Callable[..., Any], args: tuple[Any, ...]) -> Any:
    """``fn(*args)`` in a guarded child that writes to ``folder`` for the sweep ``sweep_pid``,
    holding the folder's writers' lock (:func:`~wbcbench.bench.lock.hold_as_writer`) until the
    child ends."""
    from wbcbench.bench.lock import hold_as_writer

    hold_as_writer(folder, sweep_pid)
    return fn(*args)
