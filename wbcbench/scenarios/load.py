"""Loading, overriding and validating scenario files, and turning them into runtime objects.

Every error is a :class:`~wbcbench.errors.ScenarioError` naming the file and the key path
(``tasks[2].reference.amplitude``) and, where there is a closed set, the valid choices.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import BaseModel, ValidationError

from wbcbench.errors import ScenarioError, UnknownNameError, WbcBenchError
from wbcbench.scenarios.schema import (
    REFERENCE_DIM_FIELD,
    ContactSpec,
    Scenario,
    TaskSpec,
)
from wbcbench.tasks import trajectories as tr
from wbcbench.tasks.contacts import PlaneContact
from wbcbench.tasks.tasks import TASK_TYPES, JointPostureTask, Task

SCENARIO_DIR = Path(__file__).resolve().parents[2] / "scenarios"


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
        text = json.dumps(self.spec.model_dump(mode="json"), sort_keys=True)
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
    if kind == "union_tag_invalid":
        ctx = err.get("ctx", {})
        return f"unknown type {ctx.get('tag')!r}; valid choices: {ctx.get('expected_tags')}"
    if kind == "literal_error":
        expected = err.get("ctx", {}).get("expected", "")
        return f"invalid value {err.get('input')!r}; valid choices: {expected}"
    msg = str(err["msg"])
    return msg.removeprefix("Value error, ")


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
    if p.exists():
        return p
    for candidate in (SCENARIO_DIR / f"{name_or_path}.yaml", SCENARIO_DIR / str(name_or_path)):
        if candidate.exists():
            return candidate
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
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ScenarioError(file, "", f"not valid YAML: {exc}") from None
    if not isinstance(raw, dict):
        raise ScenarioError(file, "", "a scenario file must be a mapping of keys to values")
    for assignment in overrides:
        apply_override(raw, assignment, file)
    raw.setdefault("name", path.stem)
    try:
        spec = Scenario.model_validate(raw)
    except ValidationError as exc:
        raise validation_error(file, exc) from None
    for i, task in enumerate(spec.tasks):
        _check_reference_dim(file, i, task)
    return LoadedScenario(spec, path, tuple(overrides))


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


def check_against_robot(loaded: LoadedScenario, robot: Any) -> None:
    """Frames, joints, keyframe and controller settings named by the scenario must exist."""
    from wbcbench.controllers.registry import controller_class

    spec, file = loaded.spec, str(loaded.path)

    def frame(key: str, name: str) -> None:
        if not robot.has_frame(name):
            try:
                robot.frame_id(name)
            except UnknownNameError as exc:
                raise ScenarioError(file, key, str(exc)) from None

    if spec.initial.keyframe not in robot.keyframe_names:
        raise ScenarioError(
            file,
            "initial.keyframe",
            str(UnknownNameError("keyframe", spec.initial.keyframe, robot.keyframe_names)),
        )
    for i, c in enumerate(spec.contacts):
        frame(f"contacts[{i}].frame", c.frame)
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
    for name, settings in spec.controllers.items():
        try:
            cls = controller_class(name)
        except UnknownNameError as exc:
            raise ScenarioError(file, f"controllers.{name}", str(exc)) from None
        try:
            cls.Config.model_validate(settings)
        except ValidationError as exc:
            raise validation_error(file, exc, cls.Config, f"controllers.{name}") from None


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


def build_contact(c: ContactSpec, robot: Any) -> PlaneContact:
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
