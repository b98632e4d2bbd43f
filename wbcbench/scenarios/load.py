"""Loading, overriding and validating scenario files, and turning them into runtime objects.

Every error is a :class:`~wbcbench.errors.ScenarioError` naming the file and the key path
(``tasks[2].reference.amplitude``) and, where there is a closed set, the valid choices.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import typing
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import BaseModel, ValidationError

from wbcbench.errors import ScenarioError, UnknownNameError, WbcBenchError
from wbcbench.scenarios.schema import (
    REFERENCE_DIM_FIELD,
    Boolean,
    ContactSpec,
    PerturbationsSpec,
    Reference,
    Scenario,
    TaskSpec,
)
from wbcbench.tasks import trajectories as tr
from wbcbench.tasks.contacts import PlaneContact
from wbcbench.tasks.tasks import TASK_TYPES, JointPostureTask, Task

SCENARIO_DIR = Path(__file__).resolve().parents[2] / "scenarios"

# Keys added after scenarios were first hashed, with their defaults: left out of the hash while
# at them, so that stored results keep matching their scenarios.
_LATER_KEYS: tuple[tuple[tuple[str, ...], Any], ...] = (
    (("package_dirs",), []),
    (("frames",), {}),
    (("initial", "joints"), None),
    (("initial", "srdf"), None),
    (("initial", "state"), None),
    (("initial", "settle"), 0.0),
    (("sim", "self_collision"), True),
    (("sim", "touchdown_tolerance"), 0.05),
    (("sim", "touchdown_load"), 20.0),
    (("sim", "landing_tolerance"), 0.02),
    (("walk",), None),
    (("perturbations",), PerturbationsSpec().model_dump(mode="json")),
)
# the same for keys of each contact
_LATER_CONTACT_KEYS: tuple[tuple[str, Any], ...] = (
    ("type", "flat"),
    ("points", None),
    ("contact_geometry", "model"),
    ("schedule", None),
    ("unload", 0.1),
)


@dataclass
class LoadedScenario:
    """A validated scenario with where it came from."""

    spec: Scenario
    path: Path
    overrides: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return self.spec.name or self.path.stem

    @property
    def hash(self) -> str:
        """Stable hash of the validated content (file plus overrides), 12 hex digits."""
        data = self.spec.model_dump(mode="json")
        for keys, default in _LATER_KEYS:
            owner = data
            for key in keys[:-1]:
                owner = owner[key]
            if owner.get(keys[-1]) == default:
                del owner[keys[-1]]
        for contact in data["contacts"]:
            for key, default in _LATER_CONTACT_KEYS:
                if contact.get(key) == default:
                    del contact[key]
        text = json.dumps(data, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]


# -- key paths and messages


def format_loc(loc: tuple[Any, ...]) -> str:
    """('tasks', 2, 'reference', 'sinusoid', 'amplitude') → 'tasks[2].reference.amplitude'.

    Discriminated-union tags that pydantic inserts into the location are dropped.
    """
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in REFERENCE_DIM_FIELD or part in ("piecewise",):
            continue
        else:
            out += f".{part}" if out else str(part)
    return out or "(top level)"


def _model_at(loc: tuple[Any, ...], root: type[BaseModel] = Scenario) -> type[BaseModel] | None:
    """The schema model that owns the location (for listing its valid keys)."""
    model: Any = root
    for part in loc:
        if isinstance(part, int):
            continue
        if isinstance(part, str) and model is not None:
            if hasattr(model, "model_fields") and part in model.model_fields:
                ann = model.model_fields[part].annotation
                model = _unwrap(ann)
            else:
                # a discriminated-union tag: pick the member with that tag
                model = _union_member(model, part)
    return model if isinstance(model, type) and issubclass(model, BaseModel) else None


def _unwrap(ann: Any) -> Any:
    args = getattr(ann, "__args__", None)
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    for arg in args or ():
        found = _unwrap(arg)
        if found is not None:
            return found if not _is_union_of_models(ann) else ann
    return None


def _is_union_of_models(ann: Any) -> bool:
    args = getattr(ann, "__args__", ())
    return sum(isinstance(a, type) and issubclass(a, BaseModel) for a in args) > 1


def _union_member(ann: Any, tag: str) -> Any:
    for arg in getattr(ann, "__args__", ()) or ():
        if isinstance(arg, type) and issubclass(arg, BaseModel):
            field = arg.model_fields.get("type")
            if field is not None and tag in getattr(field.annotation, "__args__", ()):
                return arg
        found = _union_member(arg, tag)
        if found is not None:
            return found
    return None


def _message(err: dict[str, Any], root: type[BaseModel] = Scenario) -> str:
    kind = err["type"]
    loc = tuple(err["loc"])
    if kind == "extra_forbidden":
        owner = _model_at(loc[:-1], root)
        valid = sorted(owner.model_fields) if owner is not None else []
        return f"unknown key {loc[-1]!r}; valid keys: {', '.join(valid)}"
    if kind == "missing":
        return "required key is missing"
    if isinstance(err.get("input"), Boolean):
        return f"expected a number, got the boolean {err['input']!r}"
    if kind == "union_tag_not_found":
        return f"required key 'type' is missing; valid types: {', '.join(reference_types())}"
    if kind == "union_tag_invalid":
        ctx = err.get("ctx", {})
        return f"unknown type {ctx.get('tag')!r}; valid choices: {ctx.get('expected_tags')}"
    if kind == "literal_error":
        expected = err.get("ctx", {}).get("expected", "")
        return f"invalid value {err.get('input')!r}; valid choices: {expected}"
    msg = str(err["msg"])
    return msg.removeprefix("Value error, ")


def reference_types() -> list[str]:
    """The ``type`` of every reference trajectory, as a scenario file spells it."""
    union = typing.get_args(Reference)[0]
    return [typing.get_args(m.model_fields["type"].annotation)[0] for m in typing.get_args(union)]


def validation_error(
    file: str, exc: ValidationError, root: type[BaseModel] = Scenario, prefix: str = ""
) -> ScenarioError:
    """The first error of a pydantic ValidationError as a ScenarioError (others appended).

    ``root`` is the model that was validated and ``prefix`` its key path in the file.
    """

    def key(err: dict[str, Any]) -> str:
        loc = format_loc(tuple(err["loc"]))
        if not prefix:
            return loc
        return prefix if loc == "(top level)" else f"{prefix}.{loc}"

    errors: list[dict[str, Any]] = [dict(e) for e in exc.errors()]
    # a mapping where true, false or a mapping is valid (sim.self_collision): the mapping's
    # errors, at the key path without the union members' names
    members = {"bool", "SelfCollisionSpec"}
    if any(members & set(map(str, e["loc"])) for e in errors):
        errors = [
            {**e, "loc": tuple(p for p in e["loc"] if p not in members)}
            for e in errors
            if not (e["type"].startswith("bool") and isinstance(e.get("input"), dict))
        ] or errors
    first = errors[0]
    message = _message(first, root)
    if len(errors) > 1:
        rest = "; ".join(f"{key(e)}: {_message(e, root)}" for e in errors[1:4])
        message += f" (also: {rest}{' …' if len(errors) > 4 else ''})"
    return ScenarioError(file, key(first), message)


# -- overrides


def apply_override(raw: dict[str, Any], assignment: str, file: str) -> None:
    """Apply ``KEY=VALUE`` (dotted path, list indices as numbers; VALUE parsed as YAML)."""
    if "=" not in assignment:
        raise ScenarioError(file, assignment, "an override must look like KEY=VALUE")
    key, text = assignment.split("=", 1)
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ScenarioError(file, key, f"cannot parse override value {text!r}: {exc}") from None
    parts = key.split(".")
    node: Any = raw
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        where = ".".join(parts[: i + 1])
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise ScenarioError(
                    file, where, f"index {part!r} out of range (the list has {len(node)} items)"
                )
            if last:
                node[int(part)] = value
            else:
                node = node[int(part)]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        else:
            raise ScenarioError(file, where, f"cannot set a key inside a {type(node).__name__}")


# -- loading


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """A path, or the name of a scenario in the top-level ``scenarios/`` folder."""
    p = Path(name_or_path)
    if p.is_file():
        return p
    for candidate in (SCENARIO_DIR / f"{name_or_path}.yaml", SCENARIO_DIR / str(name_or_path)):
        if candidate.is_file():
            return candidate
    if p.is_dir():
        raise ScenarioError(str(p), "", "no such file: a folder, not a scenario file")
    if len(p.parts) > 1 or p.suffix in (".yaml", ".yml"):  # a path, not a scenario's name
        raise ScenarioError(str(p), "", "no such file")
    raise UnknownNameError(
        "scenario", str(name_or_path), available_scenarios(), hint="or give a path to a YAML file"
    )


def available_scenarios() -> list[str]:
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))


def load_scenario(
    name_or_path: str | Path, overrides: list[str] | tuple[str, ...] = ()
) -> LoadedScenario:
    """Read and validate a scenario (schema only; see :func:`check_against_robot`)."""
    path = resolve_scenario_path(name_or_path)
    file = str(path)
    raw = read_yaml_mapping(path, "a scenario file")
    for assignment in overrides:
        apply_override(raw, assignment, file)
    _fit_window_to_overridden_duration(raw, overrides)
    raw.setdefault("name", path.stem)
    try:
        spec = Scenario.model_validate(raw)
    except ValidationError as exc:
        raise validation_error(file, exc) from None
    except RecursionError:
        raise ScenarioError(file, "", "nested too deeply to be a scenario") from None
    for i, task in enumerate(spec.tasks):
        _check_reference_dim(file, i, task)
        _check_gains(file, i, task, spec.control_rate)
    _check_consistency(file, spec)
    _check_schedule(file, spec)
    return LoadedScenario(spec, path, tuple(overrides))


def _fit_window_to_overridden_duration(raw: dict[str, Any], overrides: Sequence[str]) -> None:
    """An override that shortens ``duration`` below the end of the file's metrics window (and
    says nothing of the window) moves the window inside the run, to ``[min(t0, d/2), d]``, as a
    sweep's ``max_duration`` does; a file whose own window outlasts its duration is an error."""
    keys = {a.split("=", 1)[0].strip() for a in overrides}
    if "duration" not in keys or keys & {"metrics", "metrics.window"}:
        return
    duration, metrics = raw.get("duration"), raw.get("metrics")
    if not isinstance(metrics, dict):
        return
    window = metrics.get("window")
    numbers = (int, float)
    if (
        isinstance(duration, numbers)
        and isinstance(window, list)
        and len(window) == 2
        and all(isinstance(v, numbers) for v in window)
        and window[1] > duration > 0
    ):
        metrics["window"] = [min(window[0], duration / 2), duration]


class UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, but a key given twice in one mapping is an error naming both
    lines (PyYAML keeps the last silently)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            line = key_node.start_mark.line + 1
            if isinstance(key, typing.Hashable) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None,
                    None,
                    f"duplicate key {key!r} (first at line {seen[key]})",
                    key_node.start_mark,
                )
            if isinstance(key, typing.Hashable):
                seen[key] = line
        return super().construct_mapping(node, deep=deep)


def read_yaml_mapping(path: Path, what: str) -> dict[str, Any]:
    """The YAML mapping in ``path``; every way a file can be unreadable is a ScenarioError
    naming it (a folder, another encoding than UTF-8, binary data, absurd nesting, not YAML)."""
    file = str(path)
    if path.is_dir():
        raise ScenarioError(file, "", f"is a folder, not {what}")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(
            file,
            "",
            f"is not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset {exc.start}); "
            "save it as UTF-8",
        ) from None
    except OSError as exc:
        raise ScenarioError(file, "", f"cannot be read: {exc.strerror or exc}") from None
    if "\x00" in text:
        raise ScenarioError(file, "", f"holds binary data (a NUL byte), not {what}")
    try:
        raw = yaml.load(text, Loader=UniqueKeyLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ScenarioError(file, "", f"not valid YAML{where}: {problem}") from None
    except RecursionError:
        raise ScenarioError(file, "", f"nested too deeply to be {what}") from None
    if not isinstance(raw, dict):
        raise ScenarioError(file, "", f"{what} must be a mapping of keys to values")
    return raw


def _check_gains(file: str, i: int, task: TaskSpec, rate: float) -> None:
    """Gains are ≥ 0 and within what a loop at ``rate`` can realise (kp ≤ rate², kv ≤ rate),
    and a gain vector has one value per axis of a frame or CoM task."""
    dim = len(task.selected_axes)
    for name, most in (("kp", rate**2), ("kv", rate)):
        gain = getattr(task, name)
        values = gain if isinstance(gain, list) else [gain]
        if any(v < 0 for v in values):
            raise ScenarioError(file, f"tasks[{i}].{name}", f"gains must be ≥ 0, got {gain}")
        if any(v > most for v in values):
            raise ScenarioError(
                file,
                f"tasks[{i}].{name}",
                f"{max(values):g} is beyond what a loop at control_rate {rate:g} Hz can realise "
                f"(at most {most:g})",
            )
        if isinstance(gain, list) and dim and len(gain) != dim:
            raise ScenarioError(
                file,
                f"tasks[{i}].{name}",
                f"expected one value or {dim} (one per axis {', '.join(task.selected_axes)}), "
                f"got {len(gain)}",
            )


def _check_consistency(file: str, spec: Scenario) -> None:
    """Checks across fields, each naming the key it blames."""
    seen: dict[str, int] = {}
    for i, t in enumerate(spec.tasks):
        if t.name in seen:
            raise ScenarioError(
                file, f"tasks[{i}].name", f"task name {t.name!r} is already tasks[{seen[t.name]}]"
            )
        seen[t.name] = i
    frames: dict[str, int] = {}
    for i, c in enumerate(spec.contacts):
        if c.frame in frames:
            raise ScenarioError(
                file,
                f"contacts[{i}].frame",
                f"frame {c.frame!r} already holds contacts[{frames[c.frame]}]; a frame holds one",
            )
        frames[c.frame] = i
        if c.fmax is not None and c.fmax < c.fmin:
            raise ScenarioError(
                file, f"contacts[{i}].fmax", f"fmax = {c.fmax:g} N is below fmin = {c.fmin:g} N"
            )
    if spec.kind == "dynamic" and not spec.contacts:
        raise ScenarioError(
            file,
            "contacts",
            "a dynamic scenario needs at least one contact: the torque-level controllers hold "
            "the floating base on its contacts (a robot with none, or a fixed base, is not "
            "supported)",
        )
    if spec.duration * spec.control_rate < 1:
        raise ScenarioError(
            file,
            "duration",
            f"{spec.duration:g} s holds no control tick at control_rate {spec.control_rate:g} Hz",
        )
    if spec.metrics.window is not None:
        t0, t1 = spec.metrics.window
        if not 0 <= t0 < t1:
            raise ScenarioError(file, "metrics.window", f"must satisfy 0 ≤ t0 < t1, got {[t0, t1]}")
        if t1 > spec.duration + 1e-9:
            raise ScenarioError(
                file,
                "metrics.window",
                f"ends at {t1:g} s, after the duration of {spec.duration:g} s",
            )
    if spec.kind == "kinematic" and spec.initial.settle > 0:
        raise ScenarioError(
            file, "initial.settle", "a kinematic scenario has no physics to settle; remove it"
        )
    if spec.kind == "kinematic" and spec.perturbations.active:
        raise ScenarioError(
            file,
            "perturbations",
            "a kinematic scenario has no physics to perturb; perturbations apply to dynamic "
            "scenarios (kind: dynamic)",
        )
    if spec.kind == "dynamic":
        steps = 1.0 / (spec.control_rate * spec.sim.timestep)
        if abs(steps - round(steps)) > 1e-6 * max(1.0, steps) or round(steps) < 1:
            hint = 1.0 / (max(1, round(steps)) * spec.sim.timestep)
            raise ScenarioError(
                file,
                "control_rate",
                f"the control period 1/{spec.control_rate:g} s must be a whole number (≥ 1) of "
                f"physics steps of sim.timestep = {spec.sim.timestep:g} s; e.g. control_rate: "
                f"{hint:g}",
            )


def _check_walk(file: str, spec: Scenario) -> None:
    """The walk's feet are contacts the walk alone schedules, and the tasks it names exist."""
    walk = spec.walk
    if walk is None:
        return
    frames = [c.frame for c in spec.contacts]
    for j, foot in enumerate(walk.feet):
        if foot not in frames:
            raise ScenarioError(
                file,
                f"walk.feet[{j}]",
                f"{foot!r} is not a contact of the scenario; valid choices: {', '.join(frames)}",
            )
        i = frames.index(foot)
        if spec.contacts[i].schedule is not None:
            raise ScenarioError(
                file,
                f"contacts[{i}].schedule",
                f"contact {foot!r} is a foot of the walk, which schedules it; remove its schedule",
            )
    if walk.first_foot not in walk.feet:
        raise ScenarioError(
            file,
            "walk.first",
            f"{walk.first_foot!r} is not a foot of the walk; valid choices: {', '.join(walk.feet)}",
        )
    names = {t.name: t for t in spec.tasks}
    coms = [t.name for t in spec.tasks if t.type == "com"]
    if walk.com_task not in coms:
        raise ScenarioError(
            file,
            "walk.com_task",
            f"{walk.com_task!r} is not a com task of the scenario; valid choices: "
            f"{', '.join(coms) or '(none: add a task of type com)'}",
        )
    turning = [t.name for t in spec.tasks if t.type in ("frame_orientation", "frame_pose")]
    for j, name in enumerate(walk.heading_tasks):
        if name not in turning:
            raise ScenarioError(
                file,
                f"walk.heading_tasks[{j}]",
                f"{name!r} is not a frame_orientation or frame_pose task; valid choices: "
                f"{', '.join(turning) or '(none)'}",
            )
    for foot in walk.feet:
        if f"swing.{foot}" in names:
            i = spec.tasks.index(names[f"swing.{foot}"])
            raise ScenarioError(
                file,
                f"tasks[{i}].name",
                f"'swing.{foot}' is the name of the walk's swing task; rename this task",
            )
    if walk.footsteps is not None:
        for j, step in enumerate(walk.footsteps):
            if step.foot not in walk.feet:
                raise ScenarioError(
                    file,
                    f"walk.footsteps[{j}].foot",
                    f"{step.foot!r} is not a foot of the walk; valid choices: "
                    f"{', '.join(walk.feet)}",
                )
            if j and step.foot == walk.footsteps[j - 1].foot:
                raise ScenarioError(
                    file,
                    f"walk.footsteps[{j}].foot",
                    f"{step.foot!r} steps twice in a row; the feet alternate",
                )
    # a duration shorter than the walk cuts it (a sweep's max_duration does): the run's
    # metrics then count the steps it completed of those planned


def _check_schedule(file: str, spec: Scenario) -> None:
    """Contact schedules: intervals in order without overlap, touchdowns inside the run,
    support at every instant, and no task that moves a frame a contact holds throughout."""
    _check_walk(file, spec)
    for i, c in enumerate(spec.contacts):
        if c.schedule is None:
            continue
        key = f"contacts[{i}].schedule"
        if not c.schedule:
            raise ScenarioError(
                file, key, "an empty schedule never holds the contact; give [[start, end], …]"
            )
        for k, (a, b) in enumerate(c.schedule):
            if not 0 <= a < b:
                raise ScenarioError(
                    file, f"{key}[{k}]", f"[{a:g}, {b:g}] must satisfy 0 ≤ start < end [s]"
                )
            if k:
                pa, pb = c.schedule[k - 1]
                if a < pb:
                    raise ScenarioError(
                        file,
                        f"{key}[{k}]",
                        f"[{a:g}, {b:g}] overlaps [{pa:g}, {pb:g}] ({key}[{k - 1}]); give the "
                        "intervals in time order, each starting after the previous one ends",
                    )
            if a > 0 and a >= spec.duration:
                raise ScenarioError(
                    file,
                    f"{key}[{k}]",
                    f"the touchdown at {a:g} s never happens: the run ends at {spec.duration:g} "
                    "s; start the interval earlier or lengthen duration",
                )
            if b < spec.duration and b - a < c.unload:
                raise ScenarioError(
                    file,
                    f"{key}[{k}]",
                    f"[{a:g}, {b:g}] is shorter than the lift-off ramp unload = {c.unload:g} s; "
                    "lengthen the interval or shorten unload",
                )
    if not spec.has_schedule:
        return
    from wbcbench.scenarios.walk import schedule_times

    times = schedule_times(spec)
    if spec.contacts:
        # the instants nothing holds: walk the union of every contact's intervals
        intervals = sorted(iv for per in times for iv in per)
        covered = 0.0
        for a, b in intervals:
            if a > covered + 1e-12 and covered < spec.duration:
                raise ScenarioError(
                    file,
                    "contacts",
                    f"no contact is active over [{covered:g}, {min(a, spec.duration):g}] s: "
                    "the robot has no support then; make the schedules' intervals meet or "
                    "overlap",
                )
            covered = max(covered, b)
        if covered < spec.duration:
            raise ScenarioError(
                file,
                "contacts",
                f"no contact is active over [{covered:g}, {spec.duration:g}] s: the robot has "
                "no support then; make the schedules' intervals meet or overlap",
            )
    held = {c.frame: i for i, c in enumerate(spec.contacts) if times[i] == [(0.0, np.inf)]}
    for j, t in enumerate(spec.tasks):
        moves = t.type == "frame_position" or (
            t.type == "frame_pose" and any(not a.startswith("r") for a in t.selected_axes)
        )
        if t.frame in held and moves:
            i = held[t.frame]
            raise ScenarioError(
                file,
                f"tasks[{j}].frame",
                f"task {t.name!r} moves frame {t.frame!r}, which contacts[{i}] holds for the "
                f"whole run; give contacts[{i}] a schedule with a swing interval (or make it a "
                "foot of the walk), or remove the task",
            )


def _check_reference_dim(file: str, i: int, task: TaskSpec) -> None:
    ref = task.reference
    if ref is None or task.type in ("joint_posture", "joint_damping"):
        return
    dim = len(task.selected_axes)
    key = f"tasks[{i}].reference"
    if ref.type == "piecewise":
        got = len(ref.values[0])
        field = "values"
    else:
        field = REFERENCE_DIM_FIELD[ref.type]
        vec = getattr(ref, field)
        if vec is None:
            return
        got = len(vec)
    if got != dim:
        raise ScenarioError(
            file,
            f"{key}.{field}",
            f"expected {dim} values (one per axis {', '.join(task.selected_axes)}), got {got}",
        )


# -- checks against the robot and the registries


def load_scenario_robot(loaded: LoadedScenario) -> Any:
    """The scenario's robot, with the scenario's ``frames:`` added; a robot that cannot be
    loaded is an error at the key ``robot``, a frame on an unknown body one at
    ``frames.<name>.body``."""
    from wbcbench.robots.loader import ExtraFrame, load_robot

    frames = tuple(ExtraFrame(name, f.body, f.pos, f.rpy) for name, f in loaded.spec.frames.items())
    try:
        robot = load_robot(
            loaded.spec.robot, base_dir=loaded.path.parent, package_dirs=loaded.spec.package_dirs
        )
    except ScenarioError:
        raise
    except WbcBenchError as exc:
        raise ScenarioError(str(loaded.path), "robot", str(exc)) from None
    if not frames:
        return robot
    # the added frames checked on the file's robot, so that an error names its scenario key
    m = robot.mj_model
    bodies = [m.body(b).name for b in range(1, m.nbody)]
    for frame in frames:
        key = f"frames.{frame.name}"
        if frame.body not in bodies:
            unknown = UnknownNameError("body", frame.body, bodies)
            raise ScenarioError(str(loaded.path), f"{key}.body", str(unknown))
        if robot.has_frame(frame.name):
            raise ScenarioError(
                str(loaded.path),
                key,
                f"the robot has a body or site {frame.name!r} already; name the frame otherwise",
            )
    return load_robot(
        loaded.spec.robot,
        base_dir=loaded.path.parent,
        package_dirs=loaded.spec.package_dirs,
        frames=frames,
    )


def check_against_robot(loaded: LoadedScenario, robot: Any) -> None:
    """Frames, joints, keyframe, bodies and torque-limit patterns named by the scenario must
    exist in the robot (its controllers' settings are the controller registry's to check:
    :func:`wbcbench.controllers.registry.check_scenario_settings`)."""
    spec, file = loaded.spec, str(loaded.path)

    def frame(key: str, name: str) -> None:
        if not robot.has_frame(name):
            try:
                robot.frame_id(name)
            except UnknownNameError as exc:
                raise ScenarioError(file, key, str(exc)) from None

    if spec.initial.source == "keyframe" and spec.initial.keyframe not in robot.keyframe_names:
        hint = (
            ""
            if robot.keyframe_names
            else "the model has no keyframes: give 'initial: {joints: {name: value, …}}' or "
            "'initial: {srdf: file, state: name}'"
        )
        raise ScenarioError(
            file,
            "initial.keyframe",
            str(UnknownNameError("keyframe", spec.initial.keyframe, robot.keyframe_names, hint)),
        )
    for i, c in enumerate(spec.contacts):
        frame(f"contacts[{i}].frame", c.frame)
        if (
            c.type == "flat"
            and c.cop is None
            and (robot.info is None or robot.info.sole_box(c.frame) is None)
        ):
            raise ScenarioError(
                file,
                f"contacts[{i}].cop",
                f"the robot has no sole size for frame {c.frame!r}: give "
                "'cop: {x: [min, max], y: [min, max]}' [m] in the contact frame",
            )
        if c.contact_geometry == "box":
            from wbcbench.robots.loader import frame_body

            if frame_body(robot.mj_model, c.frame) <= 0:
                raise ScenarioError(
                    file,
                    f"contacts[{i}].contact_geometry",
                    f"frame {c.frame!r} is neither a body nor a site of the simulated model, so "
                    "no sole box can be placed at it; valid choices: 'model' (the model's own "
                    "geometry), or 'box' on a frame that is a link, body or site of the file",
                )
    bodies = [robot.mj_model.body(b).name for b in range(1, robot.mj_model.nbody)]
    for i, pair in enumerate(spec.sim.excluded_pairs):
        for j, body in enumerate(pair):
            if body not in bodies:
                raise ScenarioError(
                    file,
                    f"sim.self_collision.exclude[{i}][{j}]",
                    str(UnknownNameError("body", body, bodies)),
                )
        if pair[0] == pair[1]:
            raise ScenarioError(
                file,
                f"sim.self_collision.exclude[{i}]",
                f"a pair of two bodies, got {pair[0]!r} twice (a body never collides with itself)",
            )
    pert = spec.perturbations
    named = [(f"perturbations.pushes[{i}].body", p.body) for i, p in enumerate(pert.pushes)]
    if pert.model.payload is not None:
        named.append(("perturbations.model.payload.body", pert.model.payload.body))
    for key, body in named:
        from wbcbench.robots.loader import frame_body

        if frame_body(robot.mj_model, body) <= 0:
            raise ScenarioError(file, key, str(UnknownNameError("body", body, bodies)))
    if spec.initial.source != "keyframe":
        from wbcbench.scenarios.initial import initial_joints

        initial_joints(loaded, robot)
    for i, t in enumerate(spec.tasks):
        if t.frame is not None:
            frame(f"tasks[{i}].frame", t.frame)
        for j, joint in enumerate(t.joints or []):
            if joint not in robot.joint_names:
                raise ScenarioError(
                    file,
                    f"tasks[{i}].joints[{j}]",
                    str(UnknownNameError("joint", joint, robot.joint_names)),
                )
        dims = len(t.joints or robot.joint_names)
        for gain in ("kp", "kv"):
            values = getattr(t, gain)
            if t.type in ("joint_posture", "joint_damping") and isinstance(values, list):
                if len(values) != dims:
                    raise ScenarioError(
                        file,
                        f"tasks[{i}].{gain}",
                        f"expected one value or {dims} (one per joint), got {len(values)}",
                    )
        ref = t.reference
        if t.type in ("joint_posture", "joint_damping") and ref is not None:
            field = "values" if ref.type == "piecewise" else REFERENCE_DIM_FIELD[ref.type]
            vec = getattr(ref, field)
            got = len(vec[0]) if ref.type == "piecewise" else (dims if vec is None else len(vec))
            if got != dims:
                raise ScenarioError(
                    file, f"tasks[{i}].reference.{field}", f"expected {dims} values, got {got}"
                )
    for pattern in spec.limits.torque:
        if not fnmatch.filter(robot.joint_names, pattern):
            raise ScenarioError(
                file,
                f"limits.torque.{pattern}",
                str(UnknownNameError("joint", pattern, robot.joint_names, hint="or a pattern")),
            )


def controller_settings(loaded: LoadedScenario, name: str) -> dict[str, Any]:
    return dict(loaded.spec.controllers.get(name, {}))


# -- runtime objects


def build_reference(task: TaskSpec, dim: int) -> tr.Trajectory | None:
    ref = task.reference
    if ref is None:
        return None
    if ref.type == "constant":
        value = np.zeros(dim) if ref.value is None else np.asarray(ref.value)
        return tr.Constant(value)
    if ref.type == "sinusoid":
        return tr.Sinusoid(np.asarray(ref.amplitude), ref.frequency, ref.t0, ref.phase)
    if ref.type == "spline_there_and_back":
        return tr.spline_there_and_back(ref.t0, ref.t1, np.asarray(ref.amplitude), ref.symmetric)
    if ref.type == "min_jerk":
        delta = np.asarray(ref.delta)
        return tr.MinimumJerk(np.array([ref.t0, ref.t1]), np.vstack([0 * delta, delta]))
    times, values = np.asarray(ref.times), np.asarray(ref.values)
    if ref.interpolation == "cubic":
        return tr.PiecewiseCubic(times, values)
    if ref.interpolation == "linear":
        return tr.PiecewiseLinear(times, values)
    return tr.MinimumJerk(times, values)


def build_tasks(spec: Scenario, robot: Any) -> list[Task]:
    """Task objects in priority order (stable within a priority)."""
    tasks: list[Task] = []
    for t in sorted(spec.tasks, key=lambda t: t.priority):
        cls = TASK_TYPES[t.type]
        kw: dict[str, Any] = dict(
            name=t.name,
            priority=t.priority,
            kp=np.asarray(t.kp) if isinstance(t.kp, list) else t.kp,
            kv=np.asarray(t.kv) if isinstance(t.kv, list) else t.kv,
            weight=t.weight,
            absolute=t.absolute,
            level=t.level,
        )
        if t.frame is not None:
            kw["frame"] = t.frame
        task: Task
        if issubclass(cls, JointPostureTask):
            joint_task = cls(joints=tuple(t.joints or ()), **kw)
            joint_task.bind(tuple(robot.joint_names))
            ref = build_reference(t, joint_task.dim)
            if ref is not None:
                joint_task.reference = ref
            task = joint_task
        else:
            axes = t.selected_axes
            task = cls(axes=axes, reference=build_reference(t, len(axes)), **kw)
        tasks.append(task)
    return tasks


def build_contacts(spec: Scenario, robot: Any) -> list[PlaneContact]:
    return [build_contact(c, robot) for c in spec.contacts]


def sole_boxes(spec: Scenario, robot: Any) -> dict[str, tuple[float, float, float, float]]:
    """Contact frame → sole box (x_min, x_max, y_min, y_max [m]) of every contact that says
    ``contact_geometry: box``: its CoP box, the same rectangle the controllers use."""
    boxes = {}
    for c in spec.contacts:
        if c.contact_geometry == "box":
            pc = build_contact(c, robot)
            boxes[c.frame] = (*pc.x_range, *pc.y_range)
    return boxes


def build_contact(c: ContactSpec, robot: Any) -> PlaneContact:
    if c.type != "flat":
        points = c.contact_points()
        xs, ys = [p[0] for p in points], [p[1] for p in points]
        return PlaneContact(
            frame=c.frame,
            x_range=(min(xs), max(xs)),
            y_range=(min(ys), max(ys)),
            mu=c.mu,
            fmin=c.fmin,
            facets=c.facets,
            fmax=np.inf if c.fmax is None else c.fmax,
            points=points,
        )
    if c.cop is not None:
        x_range, y_range = c.cop.x, c.cop.y
    else:
        box = robot.info.sole_box(c.frame) if robot.info is not None else None
        if box is None:
            raise WbcBenchError(
                f"contact {c.frame!r}: the robot has no default sole size for this frame; "
                "give 'cop: {x: [min, max], y: [min, max]}' in the scenario"
            )
        x_range, y_range = (box[0], box[1]), (box[2], box[3])
    return PlaneContact(
        frame=c.frame,
        x_range=(float(x_range[0]), float(x_range[1])),
        y_range=(float(y_range[0]), float(y_range[1])),
        mu=c.mu,
        fmin=c.fmin,
        facets=c.facets,
        mu_yaw=c.mu_yaw,
        fmax=np.inf if c.fmax is None else c.fmax,
    )


def torque_limits(spec: Scenario, robot: Any) -> np.ndarray:
    """The robot's limits scaled and overridden by the scenario (k,) [N·m]."""
    tau = np.asarray(robot.tau_max, dtype=float) * spec.limits.torque_scale
    for pattern, value in spec.limits.torque.items():
        for name in fnmatch.filter(robot.joint_names, pattern):
            tau[robot.joint_names.index(name)] = value
    return tau
