"""The scenario file schema (version 1).

Defaults live here; a scenario file holds only what differs. Every model forbids unknown keys.
Checks that need the robot (frame and joint names, keyframes) happen in
:mod:`wbcbench.scenarios.load` after the robot is loaded, still before any simulation step.
"""

from __future__ import annotations

import types
import typing
from itertools import pairwise
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

Vector = list[float]

#: the largest task priority (levels are numbered from 1, the highest)
MAX_PRIORITY = 1000


def _numeric(ann: Any) -> bool:
    """Whether a field's annotation holds numbers only (``float``, ``int``, lists, tuples and
    dict values of them, optional or not)."""
    if ann in (float, int):
        return True
    origin, args = typing.get_origin(ann), typing.get_args(ann)
    if origin in (typing.Union, types.UnionType):
        members = [a for a in args if a is not type(None)]
        return bool(members) and all(_numeric(a) for a in members)
    if origin in (list, tuple):
        return bool(args) and all(_numeric(a) for a in args if a is not Ellipsis)
    if origin is dict:
        return _numeric(args[1])
    return False


class Boolean:
    """A YAML boolean found where a number is expected: it fails the number's validation (its
    error, at the key's path, says so), where pydantic would read ``true`` as 1."""

    def __init__(self, value: bool) -> None:
        self.value = value

    def __repr__(self) -> str:
        return str(self.value).lower()


def _mark_booleans(value: Any) -> Any:
    if isinstance(value, bool):
        return Boolean(value)
    if isinstance(value, list | tuple):
        return [_mark_booleans(v) for v in value]
    if isinstance(value, dict):
        return {k: _mark_booleans(v) for k, v in value.items()}
    return value


class Strict(BaseModel):
    # every float in a scenario must be finite: NaN or ±inf never describes a set-up
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _numbers_are_not_booleans(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        return {
            key: _mark_booleans(value)
            if key in cls.model_fields and _numeric(cls.model_fields[key].annotation)
            else value
            for key, value in data.items()
        }


# -- reference trajectories


class ConstantRef(Strict):
    """Hold a value: the initial one (``value`` omitted) or an offset / absolute target."""

    type: Literal["constant"]
    value: Vector | None = None


class SinusoidRef(Strict):
    """x = a sin(2π f (t − t0) + φ) − a sin φ from t0 on (offset from the initial value)."""

    type: Literal["sinusoid"]
    amplitude: Vector
    frequency: float = Field(gt=0, description="[Hz]")
    t0: float = 0.0
    phase: float = 0.0


class SplineThereAndBackRef(Strict):
    """C² cubic move over [t0, t1]: 0 → +a → −a → 0 (``symmetric``) or 0 → a → 0."""

    type: Literal["spline_there_and_back"]
    t0: float
    t1: float
    amplitude: Vector
    symmetric: bool = True

    @model_validator(mode="after")
    def _times(self) -> SplineThereAndBackRef:
        if not self.t1 > self.t0:
            raise ValueError(f"t1 ({self.t1}) must be greater than t0 ({self.t0})")
        return self


class MinJerkRef(Strict):
    """Minimum-jerk move by ``delta`` over [t0, t1], held afterwards."""

    type: Literal["min_jerk"]
    t0: float
    t1: float
    delta: Vector

    @model_validator(mode="after")
    def _times(self) -> MinJerkRef:
        if not self.t1 > self.t0:
            raise ValueError(f"t1 ({self.t1}) must be greater than t0 ({self.t0})")
        return self


class PiecewiseRef(Strict):
    """Waypoints ``values[i]`` at ``times[i]``, joined by cubic, linear or minimum-jerk pieces."""

    type: Literal["piecewise"]
    times: Vector
    values: list[Vector]
    interpolation: Literal["cubic", "linear", "min_jerk"] = "cubic"

    @model_validator(mode="after")
    def _shape(self) -> PiecewiseRef:
        if len(self.times) < 2:
            raise ValueError("needs at least two waypoints")
        if any(b <= a for a, b in zip(self.times, self.times[1:], strict=False)):
            raise ValueError(f"times must be strictly increasing, got {self.times}")
        if len(self.values) != len(self.times):
            raise ValueError(
                f"{len(self.values)} values for {len(self.times)} times: give one per time"
            )
        if len({len(v) for v in self.values}) != 1:
            raise ValueError("every waypoint must have the same number of values")
        return self


Reference = Annotated[
    ConstantRef | SinusoidRef | SplineThereAndBackRef | MinJerkRef | PiecewiseRef,
    Field(discriminator="type"),
]

REFERENCE_DIM_FIELD = {
    "constant": "value",
    "sinusoid": "amplitude",
    "spline_there_and_back": "amplitude",
    "min_jerk": "delta",
}


# -- tasks and contacts

TaskType = Literal[
    "com", "frame_position", "frame_orientation", "frame_pose", "joint_posture", "joint_damping"
]

AXES_BY_TYPE: dict[str, tuple[str, ...]] = {
    "com": ("x", "y", "z"),
    "frame_position": ("x", "y", "z"),
    "frame_orientation": ("rx", "ry", "rz"),
    "frame_pose": ("x", "y", "z", "rx", "ry", "rz"),
}
FRAME_TASKS = ("frame_position", "frame_orientation", "frame_pose")
JOINT_TASKS = ("joint_posture", "joint_damping")


class TaskSpec(Strict):
    """One task. ``priority`` 1 is the highest."""

    name: str
    type: TaskType
    frame: str | None = None
    axes: list[str] | None = None
    joints: list[str] | None = None
    priority: int = Field(1, ge=1, le=MAX_PRIORITY, strict=True)
    weight: float | None = Field(None, gt=0)
    kp: float | Vector = 100.0
    kv: float | Vector = 20.0
    reference: Reference | None = None
    absolute: bool = False
    level: Literal["acceleration", "force"] = "acceleration"

    @field_validator("joints")
    @classmethod
    def _joints_once(cls, v: list[str] | None) -> list[str] | None:
        if v is None:
            return v
        if not v:
            raise ValueError("an empty list; name at least one joint, or leave 'joints' out")
        repeated = sorted({j for j in v if v.count(j) > 1})
        if repeated:
            raise ValueError(f"each joint at most once; repeated: {', '.join(repeated)}")
        return v

    @model_validator(mode="after")
    def _consistent(self) -> TaskSpec:
        if self.type in FRAME_TASKS and not self.frame:
            raise ValueError(f"a {self.type} task needs 'frame'")
        if self.type not in FRAME_TASKS and self.frame is not None:
            raise ValueError(f"a {self.type} task takes no 'frame'")
        if self.type not in JOINT_TASKS and self.joints is not None:
            raise ValueError(f"a {self.type} task takes no 'joints' (only joint tasks do)")
        valid_axes = AXES_BY_TYPE.get(self.type)
        if self.axes is not None:
            if valid_axes is None:
                raise ValueError(f"a {self.type} task takes no 'axes'; use 'joints'")
            bad = [a for a in self.axes if a not in valid_axes]
            if bad or len(set(self.axes)) != len(self.axes) or not self.axes:
                raise ValueError(
                    f"axes {self.axes} invalid for {self.type}; valid choices: "
                    f"{', '.join(valid_axes)} (each at most once)"
                )
        return self

    @property
    def selected_axes(self) -> tuple[str, ...]:
        if self.axes is not None:
            return tuple(self.axes)
        return AXES_BY_TYPE.get(self.type, ())


class CopBox(Strict):
    """Centre-of-pressure box in the contact frame [m]."""

    x: tuple[float, float]
    y: tuple[float, float]

    @field_validator("x", "y")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError(f"[min, max] with min < max, got {list(v)}")
        return v


#: how many points each contact type holds (None: any number from the minimum)
CONTACT_POINTS = {"point": (1, 1), "line": (2, 2), "polygon": (3, None)}


class ContactSpec(Strict):
    """A plane contact held by a robot frame (reaction-on-robot convention: fmin > 0).

    ``type: flat`` (the default) holds a 6-D wrench whose centre of pressure stays in the
    ``cop`` box; ``point``, ``line`` and ``polygon`` hold a 3-D force at each of their
    ``points`` (1, 2, at least 3 non-collinear; in the frame [m]), each inside its friction
    cone with at least ``fmin`` of normal force, and no moment: for feet that cannot hold a
    6-D wrench (a leg without ankle roll).
    """

    frame: str
    type: Literal["flat", "point", "line", "polygon"] = Field(
        "flat",
        description="flat: a 6-D wrench with a CoP box; point / line / polygon: a 3-D force "
        "at each of 'points'",
    )
    points: list[tuple[float, float, float]] | None = Field(
        None,
        description="the contact points [x, y, z] in the contact frame [m] (point: one, the "
        "frame origin when omitted; line: two; polygon: three or more, not collinear)",
    )
    mu: float = Field(0.5, gt=0, le=10)
    fmin: float = Field(30.0, ge=0, le=1e5, description="minimum normal force [N]")
    fmax: float | None = Field(None, gt=0, le=1e5, description="[N], at most 1e5")
    facets: int = Field(4, ge=3, le=64, description="edges of the friction pyramid")
    mu_yaw: float | None = Field(None, gt=0)
    cop: CopBox | None = None
    schedule: list[tuple[float, float]] | None = Field(
        None,
        description="activity intervals [[start, end], …] [s]: the frame is held inside them "
        "and free between them (a swing task may drive it); omitted: held throughout",
    )
    unload: float = Field(
        0.1,
        gt=0,
        description="[s] before each lift-off over which the normal-force bounds ramp to zero "
        "(and after each touchdown over which f_min ramps in)",
    )
    contact_geometry: Literal["model", "box"] = Field(
        "model",
        description="what the simulation's foot is: the model's own geometry, or the sole box "
        "(the cop box, or the robot's sole size) at the contact frame in its place",
    )

    @field_validator("points")
    @classmethod
    def _points_fit_type(
        cls, v: list[tuple[float, float, float]] | None, info: ValidationInfo
    ) -> list[tuple[float, float, float]] | None:
        kind = info.data.get("type", "flat")
        if v is None:
            return v
        if kind == "flat":
            raise ValueError(
                "a flat contact has no points (it holds a 6-D wrench over its 'cop' box); "
                "give type: point, line or polygon to hold forces at points"
            )
        lo, hi = CONTACT_POINTS[kind]
        if len(v) < lo or (hi is not None and len(v) > hi):
            wanted = f"{lo}" if lo == hi else f"at least {lo}"
            raise ValueError(f"a {kind} contact has {wanted} point(s), got {len(v)}")
        pts = np.asarray(v, dtype=float)
        if kind == "line" and np.linalg.norm(pts[1] - pts[0]) < 1e-6:
            raise ValueError(f"the two points of a line contact coincide: {[list(p) for p in v]}")
        if kind == "polygon" and np.linalg.matrix_rank(pts[1:] - pts[0], tol=1e-6) < 2:
            raise ValueError(
                f"the points of a polygon contact are collinear: {[list(p) for p in v]}; "
                "give type: line with two of them"
            )
        return v

    @model_validator(mode="after")
    def _type_keys(self) -> ContactSpec:
        if self.type == "flat":
            return self
        if self.points is None and self.type != "point":
            raise ValueError(
                f"a {self.type} contact needs 'points': [[x, y, z], …] in the frame [m]"
            )
        for key in ("cop", "mu_yaw"):
            if getattr(self, key) is not None:
                raise ValueError(
                    f"'{key}' is a flat contact's; a {self.type} contact holds no moment "
                    "(its points bound its centre of pressure): remove it"
                )
        if self.contact_geometry == "box":
            raise ValueError(
                f"contact_geometry: box needs a flat contact; a {self.type} contact is "
                "simulated with the model's geometry (contact_geometry: model)"
            )
        return self

    def contact_points(self) -> tuple[tuple[float, float, float], ...]:
        """The points of a point, line or polygon contact (the origin for a bare point)."""
        if self.points is None:
            return ((0.0, 0.0, 0.0),)
        return tuple((float(x), float(y), float(z)) for x, y, z in self.points)


class FrameSpec(Strict):
    """A frame fixed to a body of the robot at an offset: a contact's sole plane, or a task's
    point, that the model file does not mark (added to the model as a site; no file edit)."""

    body: str = Field(description="the body that carries the frame")
    pos: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="the frame's origin in the body's frame [m]"
    )
    rpy: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0),
        description="the frame's orientation in the body's frame: roll, pitch, yaw [rad] "
        "(R = Rz(yaw) Ry(pitch) Rx(roll))",
    )


class LimitsSpec(Strict):
    """Torque-limit overrides: ``torque`` maps joint names (or fnmatch patterns) to [N·m]."""

    torque_scale: float = Field(1.0, gt=0)
    torque: dict[str, float] = Field(default_factory=dict)

    @field_validator("torque")
    @classmethod
    def _positive(cls, v: dict[str, float]) -> dict[str, float]:
        for name, value in v.items():
            if value <= 0:
                raise ValueError(f"torque limit of {name!r} must be > 0, got {value}")
        return v


class SelfCollisionSpec(Strict):
    """Self-collisions simulated but for the listed body pairs (MuJoCo's ``<contact><exclude>``)."""

    exclude: list[list[str]] = Field(
        default_factory=list, description="pairs of body names whose contacts are not simulated"
    )

    @field_validator("exclude")
    @classmethod
    def _pairs(cls, v: list[list[str]]) -> list[list[str]]:
        for i, pair in enumerate(v):
            if len(pair) != 2:
                raise ValueError(f"item {i}: a pair [body, body], got {len(pair)} names: {pair}")
        return v


class SimSpec(Strict):
    """MuJoCo settings of closed-loop runs."""

    timestep: float = Field(0.0005, ge=1e-5, le=0.002, description="physics step [s]")
    integrator: Literal["implicitfast", "implicit", "Euler", "RK4"] = "implicitfast"
    joint_friction: bool = Field(
        False,
        description="simulate the model's joint damping and Coulomb friction (the papers' "
        "simulations drive ideal torque sources, so it is off by default)",
    )
    friction_compensation: bool = Field(
        False, description="add the model's viscous + Coulomb friction to the commanded torque"
    )
    fall_height: float = Field(
        0.6, gt=0, lt=1, description="fall when the base drops below this fraction of its start"
    )
    contact_slip: float = Field(
        0.02, gt=0, description="fall when a held contact frame moves more than this [m]"
    )
    touchdown_tolerance: float = Field(
        0.05,
        gt=0,
        description="a scheduled touchdown must carry load within this time of its schedule [s]",
    )
    touchdown_load: float = Field(
        20.0, gt=0, description="the normal force from which a landing foot carries load [N]"
    )
    landing_tolerance: float = Field(
        0.02,
        gt=0,
        description="end the run when a foot lands farther than this from its target [m]",
    )
    max_consecutive_failures: int = Field(
        20, ge=1, description="stop the run after this many failed control ticks in a row"
    )
    self_collision: bool | SelfCollisionSpec = Field(
        True,
        description="simulate contacts between the robot's own bodies (false: the robot's "
        "geoms touch the world only; {exclude: [[body, body], …]}: all but those pairs)",
    )

    @field_validator("self_collision", mode="before")
    @classmethod
    def _true_false_or_mapping(cls, v: Any) -> Any:
        if not isinstance(v, bool | dict | SelfCollisionSpec):
            raise ValueError(f"expected true, false or {{exclude: [[body, body], …]}}, got {v!r}")
        return v

    @property
    def excluded_pairs(self) -> list[tuple[str, str]]:
        """The body pairs ``self_collision`` leaves out (empty for true and false)."""
        sc = self.self_collision
        return [] if isinstance(sc, bool) else [(a, b) for a, b in sc.exclude]


class InitialSpec(Strict):
    """Where a run starts: a keyframe, a joint map or an SRDF group state (one of the three).

    With ``joints`` or ``srdf`` the free base is placed upright above the origin at the height
    that puts the lowest contact frame on the floor; joints not named are at zero. ``settle``
    holds that posture for a while before the run's time starts, so a model placed a little
    above or into the floor comes to rest before the controller is judged.
    """

    keyframe: str = "stand"
    joints: dict[str, float] | None = Field(None, description="joint name → position [rad, m]")
    srdf: str | None = Field(None, description="SRDF file, relative to the scenario's folder")
    state: str | None = Field(None, description="a group_state of the SRDF")
    settle: float = Field(0.0, ge=0, le=10, description="settling time before t = 0 [s]")

    @model_validator(mode="after")
    def _one_source(self) -> InitialSpec:
        given = [k for k in ("keyframe", "joints", "srdf") if k in self.model_fields_set]
        if len(given) > 1:
            raise ValueError(f"give one of keyframe, joints or srdf, not {' and '.join(given)}")
        if (self.srdf is None) != (self.state is None):
            raise ValueError("'srdf' and 'state' go together: {srdf: file, state: name}")
        return self

    @property
    def source(self) -> str:
        """``keyframe``, ``joints`` or ``srdf``."""
        if self.joints is not None:
            return "joints"
        return "srdf" if self.srdf is not None else "keyframe"


class MetricsSpec(Strict):
    """Tracking metrics are averaged over ``window`` [s] (whole run when omitted)."""

    window: tuple[float, float] | None = None
    timing_warmup: int = Field(50, ge=0, description="control ticks discarded from timing stats")


class ObstacleSpec(Strict):
    """A fixed box in the world (kinematic scenarios' collision avoidance)."""

    name: str
    type: Literal["box"] = "box"
    pos: tuple[float, float, float] = Field(description="centre in the world [m]")
    size: tuple[float, float, float] = Field(description="half sizes along the box axes [m]")
    rpy: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="roll, pitch, yaw [rad]")

    @field_validator("size")
    @classmethod
    def _positive(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if min(v) <= 0:
            raise ValueError(f"half sizes must be > 0, got {list(v)}")
        return v


class EnvironmentSpec(Strict):
    """What surrounds the robot besides the floor."""

    obstacles: list[ObstacleSpec] = Field(default_factory=list)

    @model_validator(mode="after")
    def _unique(self) -> EnvironmentSpec:
        names = [o.name for o in self.obstacles]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"obstacle names must be unique; repeated: {', '.join(dup)}")
        return self


class FootstepSpec(Strict):
    """One landing of an explicit walk: the foot's contact frame position [m] and yaw [rad]."""

    foot: str
    position: tuple[float, float, float]
    yaw: float = 0.0


class SwingTaskSpec(Strict):
    """The swing-foot tasks a walk adds (one ``frame_pose`` task ``swing.<foot>`` per foot)."""

    priority: int = Field(1, ge=1)
    weight: float | None = Field(None, gt=0)
    kp: float = Field(400.0, ge=0)
    kv: float = Field(40.0, ge=0)


class WalkSpec(Strict):
    """A walking pattern (:mod:`wbcbench.tasks.walking`): footsteps, the feet's contact schedule,
    swing-foot tasks, the CoM task's reference (LIPM / DCM) and the heading of chosen tasks."""

    feet: tuple[str, str] = Field(description="the two contacts (frames) that are the feet")
    first: str | None = Field(None, description="the foot that steps first (feet[0] by default)")
    steps: int | None = Field(None, ge=2, le=1000, description="steps of a generated walk")
    length: float = Field(0.1, ge=-1, le=1, description="step length [m]")
    width: float | None = Field(
        None, gt=0, le=2, description="distance between the feet [m] (the starting one's)"
    )
    turn: float = Field(0.0, ge=-1.6, le=1.6, description="turn per step [rad]")
    footsteps: list[FootstepSpec] | None = Field(
        None, description="explicit landings in order, instead of steps/length/width/turn"
    )
    single: float = Field(0.8, gt=0, le=10, description="single support (one swing) [s]")
    double: float = Field(0.2, gt=0, le=10, description="double support between swings [s]")
    start: float = Field(1.0, gt=0, le=60, description="double support before the first step [s]")
    end: float = Field(1.5, gt=0, le=60, description="double support after the last step [s]")
    unload: float = Field(0.1, gt=0, description="lift-off ramp [s], at most double")
    swing_height: float = Field(0.05, ge=0, le=0.5, description="swing clearance [m]")
    touchdown_velocity: float = Field(
        0.0,
        ge=0,
        le=1,
        description="the swing foot's downward speed at its footstep, kept past the touchdown "
        "time until the contact carries load [m/s]",
    )
    com_task: str = Field("com", description="the com task the CoM reference drives")
    heading_tasks: list[str] = Field(
        default_factory=list,
        description="frame_orientation / frame_pose tasks (pelvis, torso) that turn with the walk",
    )
    swing: SwingTaskSpec = Field(default_factory=lambda: SwingTaskSpec())

    @model_validator(mode="after")
    def _shape(self) -> WalkSpec:
        if (self.steps is None) == (self.footsteps is None):
            raise ValueError("give either 'steps' (a generated walk) or 'footsteps', not both")
        if self.feet[0] == self.feet[1]:
            raise ValueError(f"two different feet, got {self.feet[0]!r} twice")
        if self.unload > self.double:
            raise ValueError(f"unload ({self.unload} s) must be at most double ({self.double} s)")
        return self

    @property
    def first_foot(self) -> str:
        return self.first or self.feet[0]


# -- perturbations: what a real robot meets and the ideal run does not

Vec3 = tuple[float, float, float]


class PushSpec(Strict):
    """An external wrench on a body of the simulated robot over ``[start, start + duration]``.

    MuJoCo applies it at the body's centre of mass (``xfrc_applied``), set before every physics
    step; the controller is never told. ``shape`` scales it over the interval: ``pulse`` holds
    it (impulse = force × duration), ``half_sine`` rises and falls as sin(π s / duration)
    (impulse = force × duration × 2/π); ``profile`` gives the scale instead, as
    ``[[s, scale], …]`` pieces joined linearly (s from ``start`` [s]).
    """

    body: str = Field(description="a body of the robot, or a frame that names its body")
    start: float = Field(ge=0, le=3600, description="[s] from the run's start")
    duration: float = Field(gt=0, le=3600, description="[s]")
    force: Vec3 = Field((0.0, 0.0, 0.0), description="[N]")
    torque: Vec3 = Field((0.0, 0.0, 0.0), description="[N·m]")
    frame: Literal["world", "body"] = Field(
        "world", description="the axes of force and torque: the world's or the body's (moving)"
    )
    shape: Literal["pulse", "half_sine"] = "pulse"
    profile: list[tuple[float, float]] | None = None

    @model_validator(mode="after")
    def _profile(self) -> PushSpec:
        if self.profile is not None:
            times = [p[0] for p in self.profile]
            if len(times) < 2 or any(b <= a for a, b in pairwise(times)):
                raise ValueError(f"profile times must be at least two, increasing, got {times}")
            if times[0] < 0 or times[-1] > self.duration:
                raise ValueError(
                    f"profile times must lie in [0, duration = {self.duration:g}], got {times}"
                )
        return self


class SensingSpec(Strict):
    """What the controller measures: the simulated state with seeded Gaussian noise on the
    joint positions and rates (the floating base's state, an estimator's job, stays exact),
    and a delay between that measurement and the torque it gives."""

    q_noise: float = Field(0.0, ge=0, le=1, description="noise std on each joint position [rad]")
    v_noise: float = Field(0.0, ge=0, le=100, description="noise std on each joint rate [rad/s]")
    delay: int = Field(
        0, ge=0, le=1000, description="control ticks between a measurement and its torque"
    )


class ActuationSpec(Strict):
    """What the motors do with a commanded torque: rounded to a step, then a first-order lag."""

    lag: float = Field(0.0, ge=0, le=1, description="first-order time constant [s]; 0: none")
    quantum: float = Field(0.0, ge=0, le=100, description="torque quantisation step [N·m]")


class PayloadSpec(Strict):
    """A point mass fixed to a body of the simulated robot that the controller does not know."""

    body: str
    mass: float = Field(gt=0, le=1000, description="[kg]")
    offset: Vec3 = Field((0.0, 0.0, 0.0), description="from the body's origin, its axes [m]")


class ModelErrorSpec(Strict):
    """How the controller's model differs from the simulated robot.

    ``mass_scale``, ``inertia_scale`` and ``com_offset`` change the controller's Pinocchio
    model (every link's mass and rotational inertia scaled, every link's centre of mass moved
    in its joint's frame); ``payload`` changes the simulated model (MuJoCo) instead.
    """

    mass_scale: float = Field(1.0, gt=0, le=10)
    inertia_scale: float | None = Field(
        None, gt=0, le=10, description="rotational inertias; mass_scale when omitted"
    )
    com_offset: Vec3 = Field((0.0, 0.0, 0.0), description="[m], each link in its own frame")
    payload: PayloadSpec | None = None


class PerturbationsSpec(Strict):
    """Disturbances, sensing, actuation and model error; everything off by default."""

    seed: int = Field(0, ge=0, description="seeds the sensing noise")
    pushes: list[PushSpec] = Field(default_factory=list)
    sensing: SensingSpec = Field(default_factory=lambda: SensingSpec())
    actuation: ActuationSpec = Field(default_factory=lambda: ActuationSpec())
    model: ModelErrorSpec = Field(default_factory=lambda: ModelErrorSpec())

    @property
    def active(self) -> bool:
        """Whether anything differs from the ideal run."""
        return bool(self.summary())

    def summary(self) -> dict[str, Any]:
        """The keys that differ from their defaults (the seed only beside noise)."""
        out = self.model_dump(mode="json", exclude_defaults=True)
        noisy = self.sensing.q_noise > 0 or self.sensing.v_noise > 0
        if not noisy:
            out.pop("seed", None)
        elif "seed" not in out:
            out["seed"] = self.seed
        return out


class Scenario(Strict):
    """A declarative benchmark scenario."""

    version: Literal[1]
    name: str = ""
    description: str = ""
    reproduces: str | None = Field(None, description="the paper table / figure it reproduces")
    reconstruction: str | None = Field(
        None, description="how lost details of the paper's set-up were reconstructed"
    )
    robot: str
    package_dirs: list[str] = Field(
        default_factory=list,
        description="folders that hold the packages of the robot's package:// paths, relative "
        "to the scenario's folder",
    )
    frames: dict[str, FrameSpec] = Field(
        default_factory=dict,
        description="frames added to the robot, by name: {body, pos [m], rpy [rad]}",
    )
    kind: Literal["dynamic", "kinematic"] = Field(
        "dynamic",
        description="dynamic: torque controllers in MuJoCo; kinematic: velocity-level "
        "controllers integrated without dynamics",
    )
    initial: InitialSpec = Field(default_factory=lambda: InitialSpec())
    duration: float = Field(gt=0, le=3600, description="simulated time [s], at most an hour")
    control_rate: float = Field(1000.0, ge=1, le=10_000, description="[Hz]")
    contacts: list[ContactSpec] = Field(default_factory=list)
    tasks: list[TaskSpec] = Field(min_length=1)
    limits: LimitsSpec = Field(default_factory=lambda: LimitsSpec())
    sim: SimSpec = Field(default_factory=lambda: SimSpec())
    controllers: dict[str, dict[str, Any]] = Field(
        default_factory=dict, description="per-controller settings, validated by each controller"
    )
    metrics: MetricsSpec = Field(default_factory=lambda: MetricsSpec())
    walk: WalkSpec | None = None
    environment: EnvironmentSpec = Field(default_factory=lambda: EnvironmentSpec())
    perturbations: PerturbationsSpec = Field(
        default_factory=lambda: PerturbationsSpec(),
        description="pushes, sensing noise and delay, actuator lag, model error (all off)",
    )

    # Checks across fields (unique names, the window inside the duration, the control period a
    # multiple of the physics step, fmin ≤ fmax) live in wbcbench.scenarios.load, where each
    # error can name its exact key path.

    @property
    def dt(self) -> float:
        return 1.0 / self.control_rate

    @property
    def has_schedule(self) -> bool:
        """Its contacts change over the run (a contact schedule or a walk)."""
        return self.walk is not None or any(c.schedule is not None for c in self.contacts)
