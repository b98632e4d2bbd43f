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


#: points of a foot's geometry within this height [m] of its lowest point make its footprint
SOLE_BAND = 0.005
#: how far [m] the sole box's centre may lie outside that footprint, or the foot's lowest point
#: from the sole plane, before ``validate`` warns
SOLE_TOLERANCE = 0.005


def _geom_points(m: mujoco.MjModel, d: mujoco.MjData, g: int) -> np.ndarray:
    """Points (p, 3) in the world that bound geom ``g``: a mesh's vertices, else the corners
    of the geom's own bounding box."""
    R = d.geom_xmat[g].reshape(3, 3)
    if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH and m.geom_dataid[g] >= 0:
        mesh = int(m.geom_dataid[g])
        adr, num = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
        local = m.mesh_vert[adr : adr + num]
    else:
        centre, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        local = centre + signs * half
    return d.geom_xpos[g] + local @ R.T


def _outside(points: np.ndarray, p: np.ndarray) -> float:
    """How far [m] the 2-D point ``p`` lies outside the convex hull of ``points`` (p, 2); 0
    inside (a lower bound beyond a vertex; the nearest point for a degenerate hull)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        return float(np.linalg.norm(points - p, axis=1).min())
    return max(0.0, float((hull.equations[:, :2] @ p + hull.equations[:, 2]).max()))


def sole_mismatches(robot: Any, q: np.ndarray, contacts: list[Any]) -> list[tuple[int, str]]:
    """(contact index, sentence) for each contact simulated with the model's geometry whose sole
    box does not sit under that geometry at configuration q (nq,): its centre more than
    :data:`SOLE_TOLERANCE` outside the footprint (the points within :data:`SOLE_BAND` of the
    foot's lowest point, in the contact frame's x–y plane), or the foot's lowest point more
    than :data:`SOLE_TOLERANCE` from the sole plane (the frame's x–y plane). Contacts whose
    bodies have no collision geometry are skipped. ``contacts`` are the scenario's
    :class:`~wbcbench.tasks.contacts.PlaneContact` objects with their ``contact_geometry``."""
    from wbcbench.robots.loader import frame_in_body, welded_bodies

    m = robot.mj_model
    d = mujoco.MjData(m)
    d.qpos[:], _ = robot.pin_to_mj(q)
    mujoco.mj_forward(m, d)
    out: list[tuple[int, str]] = []
    for i, (contact, geometry) in enumerate(contacts):
        if geometry != "model":
            continue
        body, p_b, R_b = frame_in_body(m, contact.frame)
        if body <= 0:
            continue
        bodies = welded_bodies(m, body)
        geoms = [
            g
            for g in range(m.ngeom)
            if int(m.geom_bodyid[g]) in bodies and (m.geom_contype[g] or m.geom_conaffinity[g])
        ]
        if not geoms:
            continue
        R = d.xmat[body].reshape(3, 3) @ R_b
        origin = d.xpos[body] + d.xmat[body].reshape(3, 3) @ p_b
        pts = (np.vstack([_geom_points(m, d, g) for g in geoms]) - origin) @ R
        lowest = float(pts[:, 2].min())
        centre = np.array(
            [
                (contact.x_range[0] + contact.x_range[1]) / 2,
                (contact.y_range[0] + contact.y_range[1]) / 2,
            ]
        )
        sole = pts[pts[:, 2] <= lowest + SOLE_BAND, :2]
        off = _outside(sole, centre)
        where = f"contacts[{i}] ({contact.frame!r}) at the initial posture"
        if off > SOLE_TOLERANCE:
            out.append(
                (
                    i,
                    f"{where}: the sole box's centre ({1e3 * centre[0]:.0f}, "
                    f"{1e3 * centre[1]:.0f}) mm lies {1e3 * off:.0f} mm outside the footprint of "
                    f"the foot's geometry (its points within {1e3 * SOLE_BAND:.0f} mm of its "
                    "lowest): the controllers' CoP limits are not under the simulated foot; give "
                    "the contact's 'cop' in its frame, or 'contact_geometry: box'",
                )
            )
        if abs(lowest) > SOLE_TOLERANCE:
            side = "below" if lowest < 0 else "above"
            out.append(
                (
                    i,
                    f"{where}: the foot's geometry reaches {1e3 * abs(lowest):.1f} mm {side} the "
                    "sole plane (the contact frame's x–y plane, where the controllers put the "
                    "ground): hold a frame in the sole plane, or simulate the foot as its sole "
                    "box ('contact_geometry: box')",
                )
            )
    return out


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
