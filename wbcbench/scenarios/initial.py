"""A scenario's initial state: a keyframe, a joint map or an SRDF group state.

A keyframe is taken as the model file gives it. A joint map or an SRDF state sets the named joints
(the others at zero) and puts the free base upright above the origin, at the height where the
geometry of the scenario's contact frames touches the floor (the lowest geom of the bodies welded
to each contact frame; the frames themselves at z = 0 when those bodies have no geometry).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from wbcbench.errors import ScenarioError, UnknownNameError


def srdf_states(file: str, key: str, path: Path) -> dict[str, dict[str, float]]:
    """The ``group_state`` elements of an SRDF: state name → joint name → value.

    Several groups may define one state name (TALOS: per-limb groups); their joints are merged.
    """
    if not path.is_file():
        raise ScenarioError(file, key, f"no such SRDF file {path}")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ScenarioError(file, key, f"{path} is not valid XML: {exc}") from None
    states: dict[str, dict[str, float]] = {}
    for state in root.iter("group_state"):
        joints = states.setdefault(state.get("name", ""), {})
        for joint in state.iter("joint"):
            try:
                joints[joint.get("name", "")] = float(joint.get("value", "").split()[0])
            except (ValueError, IndexError):
                raise ScenarioError(
                    file,
                    key,
                    f"{path}: <group_state name={state.get('name')!r}> <joint "
                    f"name={joint.get('name')!r}>: value {joint.get('value')!r} is not a number",
                ) from None
    return states


def srdf_path(loaded: Any) -> Path:
    """The scenario's ``initial.srdf``: a path relative to the scenario's folder, or a
    ``package://`` path resolved like the robot's mesh paths (``package_dirs``, then the
    installed example-robot-data)."""
    from wbcbench.errors import ModelError
    from wbcbench.robots.sources import PACKAGE_PREFIX, default_package_dirs, resolve_package_path

    spec, file = loaded.spec, str(loaded.path)
    text = spec.initial.srdf
    if text.startswith(PACKAGE_PREFIX):
        dirs = [loaded.path.parent / d for d in spec.package_dirs] + default_package_dirs()
        try:
            return resolve_package_path(text, dirs, loaded.path, "initial.srdf")
        except ModelError as exc:
            message = str(exc).removeprefix(f"{file}: initial.srdf: ")
            raise ScenarioError(file, "initial.srdf", message) from None
    srdf = Path(text)
    return srdf if srdf.is_absolute() else loaded.path.parent / srdf


def initial_joints(loaded: Any, robot: Any) -> dict[str, float]:
    """The joint positions the scenario's ``initial`` names, checked against the robot.

    Raises:
        ScenarioError: an unknown joint, SRDF state or keyframe, or a value out of range, at
            the key ``initial.<…>`` with the valid choices.
    """
    spec, file = loaded.spec.initial, str(loaded.path)
    if spec.source == "joints":
        values = dict(spec.joints or {})
        for name in values:
            if name not in robot.joint_names:
                raise ScenarioError(
                    file,
                    f"initial.joints.{name}",
                    str(UnknownNameError("joint", name, robot.joint_names)),
                )
        prefix = "initial.joints"
    else:
        path = srdf_path(loaded)
        states = srdf_states(file, "initial.srdf", path)
        if spec.state not in states:
            raise ScenarioError(
                file, "initial.state", str(UnknownNameError(f"state of {path}", spec.state, states))
            )
        # an SRDF is written for the full robot; a reduced model lacks some of its joints
        values = {j: v for j, v in states[spec.state].items() if j in robot.joint_names}
        if not values:
            raise ScenarioError(
                file,
                "initial.state",
                f"{spec.state!r} of {path} sets none of the robot's joints "
                f"({', '.join(sorted(states[spec.state])) or 'it names none'})",
            )
        prefix = f"initial.state ({spec.state} in {path.name})"
    for name, value in values.items():
        j = robot.joint_index(name)
        lo, hi = robot.q_min[j], robot.q_max[j]
        if not lo - 1e-9 <= value <= hi + 1e-9:
            where = f"{prefix}.{name}" if spec.source == "joints" else prefix
            raise ScenarioError(
                file, where, f"{name} = {value:g} is outside the joint's range [{lo:g}, {hi:g}]"
            )
    return values


def grounded_configuration(
    robot: Any, joints: dict[str, float], contact_frames: list[str], box_frames: Any = ()
) -> np.ndarray:
    """q (nq,) with ``joints`` set (the rest at zero) and the base upright above the origin, at
    the height where the feet touch the floor: the geometry welded to the contact frames, or
    the frame itself for those in ``box_frames`` (simulated as a sole box whose bottom face is
    the frame's x–y plane) and for feet without geometry (the lowest body when there is no
    contact frame)."""
    q = pin.neutral(robot.pin_model)
    q[:7] = [0, 0, 0, 0, 0, 0, 1]
    for name, value in joints.items():
        q[7 + robot.joint_index(name)] = value
    data = robot.pin_model.createData()
    pin.framesForwardKinematics(robot.pin_model, data, q)
    if contact_frames:
        heights = [data.oMf[robot.frame_id(f)].translation[2] for f in contact_frames]
    else:
        heights = [data.oMi[i].translation[2] for i in range(1, robot.pin_model.njoints)]
    q[2] = -float(min(heights))
    model_frames = [f for f in contact_frames if f not in box_frames]
    if model_frames:
        # the frames of box feet are at their height above the floor; the others' geometry
        box_gap = [
            h + q[2] for f, h in zip(contact_frames, heights, strict=True) if f in box_frames
        ]
        q[2] -= min([floor_gap(robot, q, model_frames), *box_gap])
    return q


def self_collisions(robot: Any, q: np.ndarray) -> list[tuple[str, str, float]]:
    """Pairs of the robot's bodies whose geoms overlap at configuration q (nq,): (body, body,
    depth [m]), deepest first, one entry per pair."""
    m = robot.mj_model
    d = mujoco.MjData(m)
    d.qpos[:], _ = robot.pin_to_mj(q)
    mujoco.mj_forward(m, d)
    deepest: dict[tuple[str, str], float] = {}
    for i in range(d.ncon):
        con = d.contact[i]
        b1, b2 = int(m.geom_bodyid[con.geom1]), int(m.geom_bodyid[con.geom2])
        if b1 == 0 or b2 == 0 or con.dist >= 0:
            continue
        pair = (m.body(b1).name, m.body(b2).name)
        deepest[pair] = max(deepest.get(pair, 0.0), -float(con.dist))
    return sorted(((a, b, depth) for (a, b), depth in deepest.items()), key=lambda x: -x[2])


def floor_gap(robot: Any, q: np.ndarray, contact_frames: list[str]) -> float:
    """Signed distance [m] from the floor planes to the nearest geom welded to a contact frame,
    at configuration q (nq,); 0 when those bodies have no geometry or the world has no plane."""
    from wbcbench.robots.loader import frame_body, welded_bodies

    m = robot.mj_model
    d = mujoco.MjData(m)
    d.qpos[:], _ = robot.pin_to_mj(q)
    mujoco.mj_forward(m, d)
    bodies: set[int] = set()
    for name in contact_frames:
        body = frame_body(m, name)
        if body > 0:
            bodies |= welded_bodies(m, body)
    floors = [
        g
        for g in range(m.ngeom)
        if m.geom_bodyid[g] == 0 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE
    ]
    feet = [g for g in range(m.ngeom) if int(m.geom_bodyid[g]) in bodies]
    if not floors or not feet:
        return 0.0
    return min(mujoco.mj_geomDistance(m, d, f, g, 1.0, None) for f in floors for g in feet)


def initial_state(loaded: Any, robot: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(q (nq,), v (nv,))`` in Pinocchio's convention at the scenario's start (copies)."""
    spec = loaded.spec
    if spec.initial.source == "keyframe":
        q, v = robot.keyframe(spec.initial.keyframe)
        return q.copy(), v.copy()
    joints = initial_joints(loaded, robot)
    boxes = {c.frame for c in spec.contacts if c.contact_geometry == "box"}
    q = grounded_configuration(robot, joints, [c.frame for c in spec.contacts], boxes)
    return q, np.zeros(robot.nv)
