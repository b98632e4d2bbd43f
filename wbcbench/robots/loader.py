"""Load a humanoid once into MuJoCo (simulation) and Pinocchio (control), joined by name.

``load_robot("tocabi_like")`` loads a generated model; ``load_robot("path/to/robot.xml")`` or
``.urdf`` loads any humanoid with a free-floating base. Joints, frames and actuators are matched
by NAME between the two libraries, never by position. Package paths and mimic joints are
resolved first (:mod:`wbcbench.robots.sources`); MuJoCo compiles the file, and the Pinocchio
model is built from that compiled model (:mod:`wbcbench.robots.pinocchio_model`), so the
simulated robot and the controllers' are one. A model without a floor plane gets one.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from wbcbench import plugins
from wbcbench.errors import ModelError, UnknownNameError
from wbcbench.robots.generator import MODELS_DIR
from wbcbench.robots.library import SPECS
from wbcbench.robots.pinocchio_model import build_pinocchio_model
from wbcbench.robots.sources import (
    ModelSource,
    default_package_dirs,
    read_source,
    resolve_package_path,
)
from wbcbench.robots.spec import RobotFile, RobotInfo
from wbcbench.robots.third_party import THIRD_PARTY

_MODEL_SUFFIXES = (".xml", ".mjcf", ".urdf")


def available_robots() -> list[str]:
    """Names of the generated robots that ``load_robot`` accepts (sorted)."""
    return sorted(SPECS)


GROUP = "wbcbench.robots"


def _check(name: str, obj: object) -> str:
    """Why ``obj`` cannot be the robot ``name`` ("" when it can)."""
    if not isinstance(obj, RobotFile):
        return f"{obj!r} is not a wbcbench.robots.spec.RobotFile"
    if name in SPECS or name in THIRD_PARTY:
        return f"{name!r} is a built-in robot name; choose another"
    return ""


def plugin_robots() -> tuple[dict[str, tuple[RobotFile, plugins.Origin]], dict[str, str]]:
    """The registered and plugin robots that load (name → file, origin), and the plugin
    entries that do not, with why."""
    return plugins.external(GROUP, _check)


def register_robot(name: str, robot: RobotFile, replace: bool = False) -> None:
    """Add a robot under ``name`` (a scenario's ``robot: name``) for this process and its runs.

    Raises:
        PluginError: not a RobotFile, a built-in name, or a name registered already (without
            ``replace``).
    """
    problem = _check(name, robot)
    if problem:
        raise plugins.PluginError(f"register_robot({name!r}): {problem}")
    plugins.register(GROUP, name, robot, replace)


def third_party_robots() -> dict[str, str]:
    """Names of the third-party robots ``load_robot`` accepts → the distribution that ships
    each, or "" when it is installed."""
    dirs = default_package_dirs()
    out = {}
    for name, entry in sorted(THIRD_PARTY.items()):
        try:
            resolve_package_path(entry.uri, dirs, Path(name), "robot")
            out[name] = ""
        except ModelError:
            out[name] = entry.distribution
    return out


@dataclass(frozen=True, eq=False)
class Robot:
    """A humanoid with a free-floating base, as both a MuJoCo and a Pinocchio model.

    Arrays of length k follow ``joint_names``, the Pinocchio order of the k actuated joints;
    Pinocchio's configuration is ``q = [p, qx, qy, qz, qw, joints]`` (nq = 7 + k) and its
    velocity ``v = [v_local, ω_local, joint rates]`` (nv = 6 + k).

    Attributes:
        name: model name (library name or file stem).
        path: model file.
        mj_model: MuJoCo model (free joint first, one motor per actuated joint).
        pin_model: Pinocchio model (free flyer first).
        info: metadata (contact, hand, head frames …); mostly empty for external files.
        joint_names: actuated joint names in Pinocchio order, (k,).
        tau_max: torque limits [N·m], (k,); ``inf`` when the model gives none.
        q_min, q_max: position limits [rad], (k,); ``∓inf`` for unlimited joints.
        v_max: velocity limits [rad/s], (k,); ``inf`` when unknown.
        armature: reflected rotor inertia [kg·m²], (k,).
        damping: viscous joint damping [N·m·s/rad], (k,).
        frictionloss: dry joint friction [N·m], (k,).
        mj_qpos_adr: MuJoCo qpos address of each actuated joint, (k,).
        mj_dof_adr: MuJoCo dof (qvel) address of each actuated joint, (k,).
        actuator_ids: MuJoCo actuator id driving each actuated joint, (k,).
        act_gear: that actuator's gear (torque = gear · ctrl), (k,).
        keyframe_names: MuJoCo keyframes, in file order.
        mimic_joints: URDF mimic joints, held fixed at their offset (name → master joint).
        mj_spec: the MuJoCo spec ``mj_model`` was compiled from.
        notes: what loading changed in the file's model, one sentence each (``validate`` prints
            them).
    """

    name: str
    path: Path
    mj_model: mujoco.MjModel
    pin_model: pin.Model
    info: RobotInfo
    joint_names: tuple[str, ...]
    tau_max: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray
    armature: np.ndarray
    damping: np.ndarray
    frictionloss: np.ndarray
    mj_qpos_adr: np.ndarray
    mj_dof_adr: np.ndarray
    actuator_ids: np.ndarray
    act_gear: np.ndarray
    keyframe_names: tuple[str, ...]
    _frames: dict[str, int] = field(repr=False)
    mimic_joints: dict[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    #: the MuJoCo spec ``mj_model`` was compiled from (copied, edited and compiled again for
    #: a simulation that changes the model, see :func:`simulation_model`)
    mj_spec: mujoco.MjSpec | None = field(default=None, repr=False)

    def __getstate__(self) -> dict[str, Any]:
        """For a process that needs the models but not the spec (which does not pickle): the
        parameter server's worker."""
        return {**self.__dict__, "mj_spec": None}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    @property
    def k(self) -> int:
        """Number of actuated joints."""
        return len(self.joint_names)

    @property
    def nq(self) -> int:
        """Pinocchio configuration size, 7 + k."""
        return 7 + self.k

    @property
    def nv(self) -> int:
        """Velocity size, 6 + k (same in MuJoCo and Pinocchio)."""
        return 6 + self.k

    @property
    def frame_names(self) -> list[str]:
        """Names ``frame_id`` accepts: sites (Pinocchio operational frames) and bodies."""
        return sorted(self._frames)

    def has_frame(self, name: str) -> bool:
        """Whether ``name`` is a site or body of the model."""
        return name in self._frames

    def frame_id(self, name: str) -> int:
        """Pinocchio frame id of site or body ``name``; a site shadows a body of the same name."""
        try:
            return self._frames[name]
        except KeyError:
            raise UnknownNameError("frame", name, self._frames) from None

    def joint_index(self, name: str) -> int:
        """Index of actuated joint ``name`` in the k-vectors (``tau_max``, ``q[7:]`` …)."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise UnknownNameError("joint", name, self.joint_names) from None

    def keyframe(self, name: str = "stand") -> tuple[np.ndarray, np.ndarray]:
        """Keyframe ``name`` as Pinocchio ``(q (nq,), v (nv,))``."""
        if name not in self.keyframe_names:
            raise UnknownNameError("keyframe", name, self.keyframe_names)
        key = self.keyframe_names.index(name)
        return self.mj_to_pin(self.mj_model.key_qpos[key], self.mj_model.key_qvel[key])

    def mj_to_pin(
        self, qpos: np.ndarray, qvel: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo state → Pinocchio ``(q, v)``; see ``convert.mj_to_pin``."""
        from wbcbench.robots import convert  # convert imports this module

        return convert.mj_to_pin(self, qpos, qvel)

    def pin_to_mj(
        self, q: np.ndarray, v: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio state → MuJoCo ``(qpos, qvel)``; see ``convert.pin_to_mj``."""
        from wbcbench.robots import convert

        return convert.pin_to_mj(self, q, v)

    def fresh_mj_model(self) -> mujoco.MjModel:
        """A deep copy of ``mj_model``, to change (timestep, limits …) without side effects."""
        return copy.copy(self.mj_model)


# ---------------------------------------------------------------------------------------------
# Loading


@dataclass(frozen=True)
class ExtraFrame:
    """A frame a scenario adds to the robot: a site of ``body`` at ``pos`` [m], turned by
    ``rpy`` [rad] (R = Rz(yaw) Ry(pitch) Rx(roll)) in that body's frame. It is a site of the
    simulated model and an operational frame of the controllers' (a site has no mass)."""

    name: str
    body: str
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


def load_robot(
    name_or_path: str | os.PathLike[str],
    base_dir: Path | None = None,
    package_dirs: Sequence[str | os.PathLike[str]] = (),
    frames: Sequence[ExtraFrame] = (),
) -> Robot:
    """Load a generated robot by name, or any free-floating humanoid MJCF / URDF by path.

    ``frames`` are added to the model as sites (a scenario's ``frames:``).

    A relative path is resolved against ``base_dir`` (a scenario file's folder) when given, and
    so are the ``package_dirs`` that ``package://`` mesh paths are looked up in (before the
    installed ``example-robot-data``, see :func:`wbcbench.robots.sources.default_package_dirs`).
    Loaded robots are cached by file and modification time: models are read-only after loading
    (simulations work on :meth:`Robot.fresh_mj_model` copies or :func:`simulation_model`).

    Raises:
        UnknownNameError: a bare name that is not a generated robot.
        ModelError: the file is missing or not a usable free-floating model.
    """
    text = os.fspath(name_or_path)
    if text in SPECS:
        path = MODELS_DIR / f"{text}.xml"
        if not path.is_file():
            raise ModelError(f"{path}: generated model missing; run `make models`")
        return _cached_load(path, text, SPECS[text]().info, (), frames)
    if text in THIRD_PARTY:
        entry = THIRD_PARTY[text]
        shares = tuple(default_package_dirs())
        try:
            path = resolve_package_path(entry.uri, shares, Path(text), "robot")
        except ModelError:
            raise ModelError(
                f"robot {text!r} is a model of {entry.distribution}, which is not installed: "
                f"pip install '{entry.distribution}' (or 'wbcbench[{entry.extra}]')"
            ) from None
        return _cached_load(path, text, entry.info, shares, frames)
    found = plugins.find(GROUP, text, _check)
    if found is not None:
        robot: RobotFile = found[0]
        if not Path(robot.path).is_file():
            raise ModelError(f"robot {text!r} ({found[1]}): {robot.path}: no such model file")
        return _cached_load(Path(robot.path), text, robot.info, tuple(robot.package_dirs), frames)
    looks_like_path = (
        isinstance(name_or_path, os.PathLike)
        or text.lower().endswith(_MODEL_SUFFIXES)
        or os.sep in text
        or "/" in text
    )
    if not looks_like_path:
        raise UnknownNameError(
            "robot",
            text,
            [*available_robots(), *THIRD_PARTY, *plugin_robots()[0]],
            hint="or give a path to an MJCF/URDF file",
        )
    path = Path(text).expanduser()
    if not path.is_absolute() and base_dir is not None and not path.is_file():
        path = Path(base_dir) / path
    if not path.is_file():
        raise ModelError(f"{path}: no such robot model file")
    dirs = tuple(
        Path(d).expanduser() if base_dir is None else Path(base_dir) / Path(d).expanduser()
        for d in package_dirs
    )
    return _cached_load(path, path.stem, None, dirs, frames)


_CACHE: dict[tuple[str, float, str, tuple[Path, ...], tuple[ExtraFrame, ...]], Robot] = {}


def _cached_load(
    path: Path,
    name: str,
    info: RobotInfo | None,
    package_dirs: tuple[Path, ...],
    frames: Sequence[ExtraFrame] = (),
) -> Robot:
    key = (str(path.resolve()), path.stat().st_mtime, name, package_dirs, tuple(frames))
    robot = _CACHE.get(key)
    if robot is None:
        source = read_source(path, package_dirs)
        robot = _load(source, name, info if info is not None else RobotInfo(), tuple(frames))
        _CACHE[key] = robot
    return robot


def _load(
    source: ModelSource, name: str, info: RobotInfo, frames: tuple[ExtraFrame, ...] = ()
) -> Robot:
    path = source.path
    notes: list[str] = []
    mj_model, spec = _mujoco_model(source, notes, frames)
    pin_model = build_pinocchio_model(mj_model, path)
    robot = _assemble(path, name, info, mj_model, pin_model, source.urdf_limits)
    object.__setattr__(robot, "mj_spec", spec)
    for shared in sorted(set(robot.joint_names) & set(robot.frame_names)):
        kind = (
            "site" if mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_SITE, shared) >= 0 else "body"
        )
        notes.append(
            f"{shared!r} names both a joint and a {kind}: as a frame (tasks[].frame, "
            f"contacts[].frame) it means the {kind}, as a joint (joint_posture, initial.joints) "
            "the joint"
        )
    if source.mimic_joints:
        pairs = ", ".join(f"{j} (mimics {m})" for j, m in source.mimic_joints.items())
        notes.insert(0, f"mimic joints held fixed at their offset: {pairs}")
        object.__setattr__(robot, "mimic_joints", dict(source.mimic_joints))
    object.__setattr__(robot, "notes", tuple(notes))
    return robot


def _mujoco_spec(source: ModelSource) -> mujoco.MjSpec:
    try:
        if source.is_urdf:
            return mujoco.MjSpec.from_string(source.text)
        return mujoco.MjSpec.from_file(str(source.path))
    except Exception as exc:  # MuJoCo raises a bare ValueError/Exception on parse errors
        raise ModelError(f"{source.path}: MuJoCo cannot read it: {exc}") from exc


def _robot_joints(path: Path, spec: mujoco.MjSpec) -> tuple[str, ...]:
    """The names of the spec's hinge and slide joints (the actuated ones), in file order.

    Raises:
        ModelError: no free joint on a body of the world, or an unnamed joint.
    """
    free = [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1 or free[0].parent.parent.name != spec.worldbody.name:
        raise ModelError(
            f"{path}: the root body needs a free joint (a free-floating humanoid base)"
            + (f"; the file has {len(free)}" if len(free) > 1 else "")
        )
    names = []
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_FREE:
            continue
        if not joint.name:
            raise ModelError(
                f"{path}: a <joint> of body {joint.parent.name!r} has no name; name it (joints "
                "are matched by name between the simulation, the controllers and the scenario)"
            )
        names.append(joint.name)
    return tuple(names)


def _drop_unrepresentable(path: Path, spec: mujoco.MjSpec, notes: list[str]) -> None:
    """Delete what Pinocchio's model cannot hold, so that the simulation does not hold it either:
    equality constraints and tendons (and the sensors that read a tendon), with a note each."""
    for kind, items in (("<equality>", spec.equalities), ("<tendon>", spec.tendons)):
        listed = [e.name or f"#{i}" for i, e in enumerate(items)]
        if not listed:
            continue
        if kind == "<tendon>":
            for sensor in list(spec.sensors):
                if sensor.objtype == mujoco.mjtObj.mjOBJ_TENDON:
                    spec.delete(sensor)
        for item in list(items):
            spec.delete(item)
        notes.append(
            f"{kind} elements ({', '.join(listed)}) removed: the controllers' multibody model "
            "holds no constraint between joints and no tendon, so neither is simulated"
        )


def _inertia_breaks_triangle(body: mujoco.MjsBody) -> bool:
    """Whether a body's stated inertia breaks A + B ≥ C (the file's values, before MuJoCo)."""
    if body.mass <= 0:
        return False
    if not np.isnan(body.fullinertia[0]):
        full = body.fullinertia  # ixx iyy izz ixy ixz iyz
        matrix = np.array(
            [[full[0], full[3], full[4]], [full[3], full[1], full[5]], [full[4], full[5], full[2]]]
        )
        principal = np.linalg.eigvalsh(matrix)
    else:
        principal = np.asarray(body.inertia, dtype=float)
    if not principal.any():
        return False
    a, b, c = np.sort(principal)
    return bool(a + b < c)


def _add_frames(path: Path, spec: mujoco.MjSpec, frames: tuple[ExtraFrame, ...]) -> None:
    taken = {e.name for e in (*spec.bodies, *spec.sites) if e.name}
    for frame in frames:
        body = spec.body(frame.body)
        if body is None:
            bodies = sorted(b.name for b in spec.bodies if b.name and b.name != "world")
            raise UnknownNameError(f"body of frame {frame.name!r} in {path}", frame.body, bodies)
        if frame.name in taken:
            raise ModelError(
                f"{path}: frame {frame.name!r}: the model has a body or site of that name "
                "already; name the added frame otherwise, or use the model's"
            )
        quat = np.empty(4)
        mujoco.mju_euler2Quat(quat, np.asarray(frame.rpy, dtype=float), "XYZ")
        body.add_site(name=frame.name, pos=list(frame.pos), quat=list(quat), group=5)
        taken.add(frame.name)


def _mujoco_model(
    source: ModelSource, notes: list[str], frames: tuple[ExtraFrame, ...] = ()
) -> tuple[mujoco.MjModel, mujoco.MjSpec]:
    path = source.path
    spec = _mujoco_spec(source)
    _add_frames(path, spec, frames)
    # the free joint at the body origin, where the file puts the root body's frame
    spec.compiler.alignfree = False
    if source.is_urdf:
        # a URDF link without <inertial> is massless (not MuJoCo's geom-derived inertia)
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
        _urdf_to_floating(spec, source.urdf_limits)
    joint_names = _robot_joints(path, spec)
    if not source.is_urdf and not _plain_motors(spec, joint_names):
        _replace_actuators(spec, joint_names, notes)
    _drop_unrepresentable(path, spec, notes)
    unbalanced = [b.name for b in spec.bodies if _inertia_breaks_triangle(b)]
    if unbalanced and not spec.compiler.balanceinertia:
        spec.compiler.balanceinertia = True
        why = "the file does not set balanceinertia and MuJoCo cannot simulate them as written"
    else:
        why = "the file sets balanceinertia"
    if unbalanced:
        shown = ", ".join(unbalanced[:6]) + (", …" if len(unbalanced) > 6 else "")
        notes.append(
            f"inertias that break A + B >= C in {len(unbalanced)} of the file's bodies ({shown}): "
            f"MuJoCo balanced them ({why}) and the controllers' model uses the same balanced "
            "values; fix those <inertial>s to keep the file's"
        )
    if _add_floor(spec):
        notes.append(
            "the file has no floor: a plane at z = 0 was added (contype 1, conaffinity 1, "
            "condim 3, friction 1, not the file's geom defaults)"
        )
    try:
        return spec.compile(), spec
    except Exception as exc:
        raise ModelError(f"{path}: MuJoCo cannot compile it: {exc}") from exc


#: the collision settings of the floor the loader adds (never the file's geom defaults)
FLOOR = {
    "contype": 1,
    "conaffinity": 1,
    "condim": 3,
    "friction": [1.0, 0.005, 0.0001],
    "solref": [0.02, 1.0],
    "solimp": [0.9, 0.95, 0.001, 0.5, 2.0],
    "margin": 0.0,
    "gap": 0.0,
    "priority": 0,
}


def _add_floor(spec: mujoco.MjSpec) -> bool:
    """A floor plane at z = 0 when the world has none (URDFs never have one); whether added."""
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_PLANE and geom.parent.name == spec.worldbody.name:
            return False
    spec.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05], **FLOOR
    )
    return True


def _urdf_to_floating(spec: mujoco.MjSpec, limits: dict[str, tuple[float, float]]) -> None:
    """Free joint on the root link, URDF effort limits as force limits, one motor per joint."""
    spec.compiler.fusestatic = False  # keep fixed links as bodies: they are named frames
    root = spec.worldbody.first_body()
    if root is None:
        raise ModelError("URDF has no links")
    root.add_freejoint(name="root")
    joints = [j.name for j in spec.joints if j.type != mujoco.mjtJoint.mjJNT_FREE]
    for name in joints:
        effort = limits.get(name, (np.inf, np.inf))[0]
        if np.isfinite(effort):
            joint = spec.joint(name)
            joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
            joint.actfrcrange = [-effort, effort]
    _add_motors(spec, tuple(joints))


def _is_limited(flag: int, rng: np.ndarray) -> bool:
    """MJCF limit flag: "true", or "auto" with a nonempty range (autolimits)."""
    if flag == mujoco.mjtLimited.mjLIMITED_TRUE:
        return True
    return bool(flag == mujoco.mjtLimited.mjLIMITED_AUTO and rng[0] < rng[1])


def _joint_limit(spec: mujoco.MjSpec, name: str) -> float:
    joint = spec.joint(name)
    if _is_limited(joint.actfrclimited, joint.actfrcrange):
        return float(np.max(np.abs(joint.actfrcrange)))
    return float("inf")


def _add_motors(spec: mujoco.MjSpec, joints: tuple[str, ...]) -> None:
    for name in joints:
        limit = _joint_limit(spec, name)
        motor = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        motor.set_to_motor()
        motor.gear[0] = 1.0
        if np.isfinite(limit):
            motor.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            motor.ctrlrange = [-limit, limit]


def _is_plain_motor(act: mujoco.MjsActuator) -> bool:
    return bool(
        act.trntype == mujoco.mjtTrn.mjTRN_JOINT
        and act.dyntype == mujoco.mjtDyn.mjDYN_NONE
        and act.gaintype == mujoco.mjtGain.mjGAIN_FIXED
        and act.biastype == mujoco.mjtBias.mjBIAS_NONE
        and act.gainprm[0] == 1.0
    )


def _plain_motors(spec: mujoco.MjSpec, joints: tuple[str, ...]) -> bool:
    """Whether every joint is driven by exactly one plain torque motor (and nothing else is)."""
    targets = [a.target for a in spec.actuators]
    return all(_is_plain_motor(a) for a in spec.actuators) and sorted(targets) == sorted(joints)


def _actuator_kind(act: mujoco.MjsActuator) -> str:
    if act.trntype != mujoco.mjtTrn.mjTRN_JOINT:
        return f"{act.trntype.name[6:].lower()} actuator"
    if act.dyntype != mujoco.mjtDyn.mjDYN_NONE:
        return f"{act.dyntype.name[6:].lower()} actuator"
    if act.biastype == mujoco.mjtBias.mjBIAS_AFFINE:
        return "position/velocity servo"
    if act.gainprm[0] != 1.0:
        return f"motor with gain {act.gainprm[0]:g}"
    return "motor"


def _replace_actuators(spec: mujoco.MjSpec, joints: tuple[str, ...], notes: list[str]) -> None:
    """Swap whatever actuators the file has (position servos …) for one torque motor per joint.

    A whole-body controller commands torques; a servo's force limit becomes the torque limit
    when the joint has none.
    """
    kinds: dict[str, int] = {}
    for act in spec.actuators:
        kind = _actuator_kind(act)
        kinds[kind] = kinds.get(kind, 0) + 1
    listed = ", ".join(f"{n} {kind}{'s' if n > 1 else ''}" for kind, n in kinds.items())
    notes.append(
        f"the file's actuators ({listed or 'none'}) were replaced by one torque motor per joint "
        f"({len(joints)}): the controllers command joint torques; a servo's forcerange became "
        "the joint's torque limit where the joint states none"
    )
    for act in list(spec.actuators):
        if act.target in joints and _is_limited(act.forcelimited, act.forcerange):
            joint = spec.joint(act.target)
            if not _is_limited(joint.actfrclimited, joint.actfrcrange):
                joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
                joint.actfrcrange = list(act.forcerange)
        spec.delete(act)
    _add_motors(spec, joints)


def welded_bodies(model: mujoco.MjModel, body: int) -> set[int]:
    """The bodies welded to ``body``: up to its nearest ancestor with a joint, and every body
    below that one reached without crossing a joint (fixed URDF links such as a sole link)."""
    root = body
    while model.body_jntnum[root] == 0 and model.body_parentid[root] != 0:
        root = int(model.body_parentid[root])
    group = {root}
    for b in range(root + 1, model.nbody):
        if model.body_jntnum[b] == 0 and int(model.body_parentid[b]) in group:
            group.add(b)
    return group


#: height [m] of the sole box of :func:`simulation_model` above the sole plane
SOLE_BOX_HEIGHT = 0.02


def frame_in_body(model: mujoco.MjModel, name: str) -> tuple[int, np.ndarray, np.ndarray]:
    """(body, position (3,), rotation (3, 3)) of frame ``name`` (a site or a body) in the body
    that carries it; body −1 when the model has neither."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        R = np.empty(9)
        mujoco.mju_quat2Mat(R, model.site_quat[sid])
        return int(model.site_bodyid[sid]), model.site_pos[sid].copy(), R.reshape(3, 3)
    return frame_body(model, name), np.zeros(3), np.eye(3)


def simulation_model(
    robot: Robot,
    soles: dict[str, tuple[float, float, float, float]],
    exclude: Sequence[tuple[str, str]] = (),
    payloads: Sequence[tuple[str, float, Sequence[float]]] = (),
    actuator_lag: float = 0.0,
) -> mujoco.MjModel:
    """``robot``'s MuJoCo model (a fresh copy) with the edits of a scenario's simulation.

    ``exclude``: pairs of bodies whose contacts with each other are not simulated (MuJoCo's
    ``<contact><exclude>``).

    ``soles``: the foot of each contact frame is simulated as its sole box: the collision
    geoms of the bodies welded to the frame collide with nothing, and a box (x_min, x_max,
    y_min, y_max [m] in the frame, :data:`SOLE_BOX_HEIGHT` high) whose bottom face lies in the
    frame's x–y plane takes their place, with the contact parameters of the first geom it
    replaces (the added floor's collision settings, :data:`FLOOR`, when none of them collides).
    The box is massless: masses and inertias are those of ``robot.mj_model`` either way.

    ``payloads``: ``(frame, mass [kg], offset (3,) [m])``, a point mass welded to the body that
    carries the frame, ``offset`` from that body's origin in its axes (a body of its own, so
    the file's bodies keep their inertias).

    ``actuator_lag``: a first-order time constant [s] on every motor (MuJoCo's exact filter
    dynamics, applied in the same step: the motor's torque follows its command as
    1 − exp(−t / lag)).

    Raises:
        ModelError: the robot keeps no MuJoCo spec, a frame is not in the MuJoCo model, or the
            edited model does not compile.
    """
    if not soles and not exclude and not payloads and not actuator_lag:
        return robot.fresh_mj_model()
    if robot.mj_spec is None:
        raise ModelError(f"{robot.path}: no MuJoCo spec kept to edit the feet of")
    m = robot.mj_model
    spec = robot.mj_spec.copy()
    for frame, (x0, x1, y0, y1) in soles.items():
        body, p, R = frame_in_body(m, frame)
        if body <= 0:
            raise ModelError(f"{robot.path}: MuJoCo has no body or site {frame!r}")
        contact: dict[str, Any] = {}
        for b in sorted(welded_bodies(m, body)):
            for geom in spec.body(m.body(b).name).geoms:
                if geom.contype or geom.conaffinity:
                    contact = contact or {
                        "contype": geom.contype,
                        "conaffinity": geom.conaffinity,
                        "condim": geom.condim,
                        "friction": list(geom.friction),
                        "solref": list(geom.solref),
                        "solimp": list(geom.solimp),
                    }
                    geom.contype = geom.conaffinity = 0
        if not contact:
            # no foot geom collides: the box collides as the added floor does, never with the
            # file's geom defaults (which may collide with nothing)
            contact = {k: v for k, v in FLOOR.items() if k not in ("margin", "gap", "priority")}
        half = np.array([(x1 - x0) / 2, (y1 - y0) / 2, SOLE_BOX_HEIGHT / 2])
        centre = p + R @ np.array([(x0 + x1) / 2, (y0 + y1) / 2, SOLE_BOX_HEIGHT / 2])
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, R.ravel())
        spec.body(m.body(body).name).add_geom(
            name=f"{frame}_sole_box",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=half,
            pos=centre,
            quat=quat,
            # massless: a body whose inertia MuJoCo derives from its geoms keeps the one the
            # controllers' model was built from
            density=0.0,
            **contact,
        )
    for first, second in exclude:
        spec.add_exclude(bodyname1=first, bodyname2=second)
    for i, (frame, mass, offset) in enumerate(payloads):
        body = frame_body(m, frame)
        if body <= 0:
            raise ModelError(f"{robot.path}: MuJoCo has no body or site {frame!r}")
        # a point mass; MuJoCo asks every body for a positive inertia
        spec.body(m.body(body).name).add_body(
            name=f"payload_{i}_on_{m.body(body).name}",
            pos=list(offset),
            mass=mass,
            inertia=[1e-6 * mass] * 3,
            explicitinertial=True,
        )
    if actuator_lag > 0:
        for a in robot.actuator_ids:
            act = spec.actuator(m.actuator(int(a)).name)
            act.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
            act.dynprm[0] = actuator_lag
            act.actearly = True
    try:
        return spec.compile()
    except Exception as exc:
        raise ModelError(f"{robot.path}: MuJoCo cannot compile the edited model: {exc}") from exc


def frame_body(model: mujoco.MjModel, name: str) -> int:
    """The MuJoCo body that carries frame ``name`` (a site's body, or the body itself); -1 when
    the model has neither."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return int(model.site_bodyid[sid])
    return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))


def _name2id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str, path: Path) -> int:
    idx = mujoco.mj_name2id(model, kind, name)
    if idx < 0:
        raise ModelError(f"{path}: MuJoCo has no {kind.name[6:].lower()} named {name!r}")
    return int(idx)


def _assemble(
    path: Path,
    name: str,
    info: RobotInfo,
    m: mujoco.MjModel,
    pin_model: pin.Model,
    urdf_limits: dict[str, tuple[float, float]],
) -> Robot:
    joint_names = tuple(pin_model.names[i] for i in range(2, pin_model.njoints))
    free = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1 or m.jnt_qposadr[free[0]] != 0 or m.jnt_dofadr[free[0]] != 0:
        raise ModelError(f"{path}: MuJoCo needs exactly one free joint, on the root body")
    if m.nv != 6 + len(joint_names):
        raise ModelError(
            f"{path}: MuJoCo has {m.nv} dofs, Pinocchio {6 + len(joint_names)}; "
            "the joints of both must match one for one"
        )
    jid = np.array([_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j, path) for j in joint_names], int)
    act_of_joint = {
        int(m.actuator_trnid[a, 0]): a
        for a in range(m.nu)
        if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
    }
    missing = [j for j, i in zip(joint_names, jid, strict=True) if int(i) not in act_of_joint]
    if missing:
        raise ModelError(f"{path}: joints without an actuator: {', '.join(missing)}")
    act = np.array([act_of_joint[int(i)] for i in jid], dtype=int)

    limited = m.jnt_limited[jid].astype(bool)
    q_min = np.where(limited, m.jnt_range[jid, 0], -np.inf)
    q_max = np.where(limited, m.jnt_range[jid, 1], np.inf)
    gear = m.actuator_gear[act, 0].copy()
    frc_limited = m.jnt_actfrclimited[jid].astype(bool)
    ctrl_limited = m.actuator_ctrllimited[act].astype(bool)
    ctrl_limit = np.abs(m.actuator_ctrlrange[act]).max(axis=1) * np.abs(gear)
    tau_max = np.where(
        frc_limited,
        np.abs(m.jnt_actfrcrange[jid]).max(axis=1),
        np.where(ctrl_limited, ctrl_limit, np.inf),
    )
    if info.velocity_limits:
        v_max = np.array([info.velocity_limits.get(j, np.inf) for j in joint_names])
    else:
        v_max = np.array([urdf_limits.get(j, (np.inf, np.inf))[1] for j in joint_names])
    # the limits the file states, on Pinocchio's side too (MuJoCo has no velocity limit)
    pin_model.effortLimit[6:] = tau_max
    pin_model.velocityLimit[6:] = v_max

    dof = m.jnt_dofadr[jid]
    frames: dict[str, int] = {}
    # Sites are written after bodies so a site shadows a body of the same name ("head").
    for kind in (pin.FrameType.BODY, pin.FrameType.OP_FRAME):
        for fid, frame in enumerate(pin_model.frames):
            if frame.type == kind:
                frames[frame.name] = fid
    keys = tuple(
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_KEY, i) or f"key{i}" for i in range(m.nkey)
    )
    return Robot(
        name=name,
        path=path,
        mj_model=m,
        pin_model=pin_model,
        info=info,
        joint_names=joint_names,
        tau_max=tau_max,
        q_min=q_min,
        q_max=q_max,
        v_max=v_max,
        armature=m.dof_armature[dof].copy(),
        damping=m.dof_damping[dof].copy(),
        frictionloss=m.dof_frictionloss[dof].copy(),
        mj_qpos_adr=m.jnt_qposadr[jid].astype(int),
        mj_dof_adr=dof.astype(int),
        actuator_ids=act,
        act_gear=gear,
        keyframe_names=keys,
        _frames=frames,
    )
