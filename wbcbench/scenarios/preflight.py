"""Checks of a scenario's contacts and tasks on its robot before the first step, which
``validate`` prints.

- :func:`floor_collisions`: the geometry simulated at each contact can collide with the world
  (a floor plane, or a wall for a hand contact; MuJoCo's rule: ``contype`` of one geom and
  ``conaffinity`` of the other share a bit).
- :func:`sole_placements`: each contact that faces the floor (its z axis within
  :data:`FLOOR_FACING` of the floor's normal; a hand on a wall does not) has its sole in the
  floor plane at the initial posture:
  the contact frame's z axis within :data:`SOLE_TILT_TOLERANCE` of the floor's normal, and the
  sole (the frame itself for a sole box or a foot without geometry, else the foot's lowest
  geometry) within :data:`SOLE_HEIGHT_TOLERANCE` of the floor.
- :func:`contact_rank`: the stacked contact Jacobian (6 rows per flat contact, the independent
  rows of a point set) has full row rank at the initial posture, else the controllers' contact
  constraint is singular; the warning writes out the line contact to give instead.
- :func:`task_reach`: each CoM or frame task's axes can be moved by the joints with the
  contacts held, at the initial posture.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from wbcbench.dynamics.state import RobotState
from wbcbench.scenarios.schema import AXES_BY_TYPE, FRAME_TASKS, TaskSpec
from wbcbench.tasks.contacts import PlaneContact, point_wrench_map

#: largest angle [rad] between a contact frame's z axis and the floor's normal (1°: a 0.1 m
#: half-sole then lifts its edge 1.7 mm off the floor)
SOLE_TILT_TOLERANCE = np.deg2rad(1.0)
#: largest gap [m] between a sole and the floor, above or below
SOLE_HEIGHT_TOLERANCE = 0.002
#: a singular value of the contact Jacobian below this fraction of the largest counts as zero
RANK_TOLERANCE = 1e-8
#: a contact whose z axis is further than this [rad] from the floor's normal is not on the floor
FLOOR_FACING = np.deg2rad(45.0)


def _floors(m: mujoco.MjModel) -> list[int]:
    return [
        g
        for g in range(m.ngeom)
        if m.geom_bodyid[g] == 0 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE
    ]


def _collide(m: mujoco.MjModel, g1: int, g2: int) -> bool:
    return bool(
        (m.geom_contype[g1] & m.geom_conaffinity[g2])
        or (m.geom_contype[g2] & m.geom_conaffinity[g1])
    )


def _name(m: mujoco.MjModel, g: int) -> str:
    """A geom's name, or its body's and its type for an unnamed one ("l_foot's box")."""
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
    if name:
        return name
    body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
    return f"{body}'s {mujoco.mjtGeom(m.geom_type[g]).name[7:].lower()}"


def floor_collisions(m: mujoco.MjModel, frames: list[str]) -> list[tuple[int, str]]:
    """(contact index, sentence) for each contact frame none of whose feet's geoms (the geoms of
    the bodies welded to it in the simulated model ``m``) can collide with the world's (a
    floor plane, a wall)."""
    from wbcbench.robots.loader import frame_body, welded_bodies

    world = {b for b in range(m.nbody) if m.body_weldid[b] == 0}  # bodies welded to the world
    floors = [g for g in range(m.ngeom) if int(m.geom_bodyid[g]) in world]
    out = []
    for i, frame in enumerate(frames):
        body = frame_body(m, frame)
        if body <= 0:
            continue
        bodies = welded_bodies(m, body)
        feet = [g for g in range(m.ngeom) if int(m.geom_bodyid[g]) in bodies]
        if any(_collide(m, f, g) for f in floors for g in feet):
            continue
        where = f"contacts[{i}] ({frame!r})"
        if not floors:
            why = "the world has no geometry"
        elif not feet:
            why = "the bodies welded to it have no geometry"
        else:
            listed = ", ".join(
                f"{_name(m, g)} {m.geom_contype[g]}/{m.geom_conaffinity[g]}" for g in feet[:4]
            )
            floor = ", ".join(
                f"{_name(m, f)} {m.geom_contype[f]}/{m.geom_conaffinity[f]}" for f in floors
            )
            why = (
                f"its geoms (contype/conaffinity: {listed}) share no bit with the floor's ({floor})"
            )
        out.append(
            (
                i,
                f"{where}: the foot cannot touch the floor or a wall: {why}; the robot falls "
                "through it. "
                "Set contype and conaffinity of the foot's geoms (MuJoCo's rule: one's contype "
                "and the other's conaffinity share a bit), or simulate the foot as its sole box "
                "('contact_geometry: box')",
            )
        )
    return out


def sole_placements(
    robot: Any, q: np.ndarray, contacts: Sequence[tuple[str, str]]
) -> list[tuple[int, str]]:
    """(contact index, sentence) for each contact facing the floor whose sole is not in the
    floor plane at configuration q (nq,): tilted by more than :data:`SOLE_TILT_TOLERANCE`, or
    more than :data:`SOLE_HEIGHT_TOLERANCE` above or below the floor. ``contacts``: (frame,
    contact_geometry) pairs. Nothing when the world has no floor plane."""
    from wbcbench.robots.loader import frame_in_body, welded_bodies

    m = robot.mj_model
    floors = _floors(m)
    if not floors:
        return []
    d = mujoco.MjData(m)
    d.qpos[:], _ = robot.pin_to_mj(q)
    mujoco.mj_forward(m, d)
    floor = floors[0]
    normal = d.geom_xmat[floor].reshape(3, 3)[:, 2]
    origin = d.geom_xpos[floor]
    out = []
    for i, (frame, geometry) in enumerate(contacts):
        body, p_b, R_b = frame_in_body(m, frame)
        if body <= 0:
            continue
        R = d.xmat[body].reshape(3, 3) @ R_b
        position = d.xpos[body] + d.xmat[body].reshape(3, 3) @ p_b
        tilt = float(np.arccos(np.clip(R[:, 2] @ normal, -1.0, 1.0)))
        if tilt > FLOOR_FACING:
            continue
        feet = [
            g
            for g in range(m.ngeom)
            if int(m.geom_bodyid[g]) in welded_bodies(m, body) and _collide(m, g, floor)
        ]
        if geometry == "box" or not feet:
            height, what = float((position - origin) @ normal), "the contact frame"
        else:
            height = min(mujoco.mj_geomDistance(m, d, floor, g, 1.0, None) for g in feet)
            what = "the foot's geometry"
        problems = []
        if tilt > SOLE_TILT_TOLERANCE:
            problems.append(f"its sole plane is tilted {np.rad2deg(tilt):.1f}° from the floor")
        if abs(height) > SOLE_HEIGHT_TOLERANCE:
            side = "above" if height > 0 else "below"
            problems.append(f"{what} is {1e3 * abs(height):.1f} mm {side} the floor")
        if problems:
            out.append(
                (
                    i,
                    f"contacts[{i}] ({frame!r}) at the initial posture: {' and '.join(problems)} "
                    f"(tolerances {np.rad2deg(SOLE_TILT_TOLERANCE):.0f}° and "
                    f"{1e3 * SOLE_HEIGHT_TOLERANCE:.0f} mm): the controllers hold the sole flat "
                    "where it is, so the foot rocks or drops at the first step; fix the "
                    "keyframe or 'initial.joints', or give the contact a frame in the sole plane "
                    "('frames:')",
                )
            )
    return out


def contact_rank(robot: Any, q: np.ndarray, contacts: Sequence[str | PlaneContact]) -> str:
    """Why the contacts' stacked Jacobian is rank-deficient at configuration q (nq,), naming the
    contact wrench components it cannot produce and the point or line contact that would hold
    such a foot; "" at full row rank.

    A flat contact has 6 rows (its frame's LOCAL Jacobian); a point set has as many as its
    points' geometry can hold independently (3 for one point, 5 for a line, 6 for a polygon):
    the rows of its points' velocities that are not redundant by construction.
    """
    if not contacts:
        return ""
    model = robot.pin_model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    blocks, labels = [], []
    axes = ("force x", "force y", "force z", "moment x", "moment y", "moment z")
    for c in contacts:
        frame, points = (c, None) if isinstance(c, str) else (c.frame, c.points)
        J6 = pin.getFrameJacobian(model, data, robot.frame_id(frame), pin.ReferenceFrame.LOCAL)
        if points is None:
            blocks.append(J6)
            labels += [f"{frame}'s {axis}" for axis in axes]
            continue
        # the points' velocities Gᵀ J6, on the range of Gᵀ (the motions the points can hold)
        basis, sv, _ = np.linalg.svd(point_wrench_map(points).T, full_matrices=False)
        r = int((sv > RANK_TOLERANCE * sv[0]).sum())
        blocks.append(basis[:, :r].T @ point_wrench_map(points).T @ J6)
        labels += [f"{frame}'s points ({j + 1} of {r})" for j in range(r)]
    jac = np.vstack(blocks)
    u, s, _ = np.linalg.svd(jac)
    rank = int((s > RANK_TOLERANCE * s[0]).sum())
    if rank == jac.shape[0]:
        return ""
    # the wrench directions no joint motion reaches: the left null space
    directions = []
    lacking: dict[str, set[str]] = {}
    for column in u[:, rank:].T:
        big = np.flatnonzero(np.abs(column) > 0.3 * np.abs(column).max())
        directions.append(" with ".join(labels[i] for i in big))
        for i in big:
            frame, _, axis = labels[i].partition("'s ")
            lacking.setdefault(frame, set()).add(axis)
    return (
        f"the contact Jacobian has rank {rank} of {jac.shape[0]} at the initial posture: no "
        f"joint motion moves {'; nor '.join(directions)} independently (a leg with fewer than "
        "6 joints, or aligned joint axes), so the contacts' constraint is singular and the "
        "controllers' contact-force problem has no unique solution; "
        + _point_contact_advice(robot, contacts, lacking)
    )


def _point_contact_advice(
    robot: Any, contacts: Sequence[str | PlaneContact], lacking: dict[str, set[str]]
) -> str:
    """The contacts to give instead: a line along the axis whose moment the foot cannot hold
    (through the sole's centre, over its length), else points at the sole's corners."""
    advice = []
    for c in contacts:
        frame = c if isinstance(c, str) else c.frame
        if frame not in lacking or not (isinstance(c, str) or c.points is None):
            continue
        box: tuple[Any, ...] | None
        if isinstance(c, str):
            box = robot.info.sole_box(frame) if robot.info is not None else None
        else:
            box = (*c.x_range, *c.y_range)
        # the sole's extent, or names for it where the robot does not give it
        x_lo, x_hi, y_lo, y_hi = (
            ("x_back", "x_front", "y_right", "y_left") if box is None else (f"{v:.3g}" for v in box)
        )
        xc, yc = (
            ("x_mid", "y_mid")
            if box is None
            else (
                f"{(box[0] + box[1]) / 2:.3g}",
                f"{(box[2] + box[3]) / 2:.3g}",
            )
        )
        moments = lacking[frame] & {"moment x", "moment y"}
        if moments == {"moment x"}:  # no roll: forces along the sole's x axis
            kind, points = "line", [[x_hi, yc, "0"], [x_lo, yc, "0"]]
        elif moments == {"moment y"}:  # no pitch: forces along its y axis
            kind, points = "line", [[xc, y_hi, "0"], [xc, y_lo, "0"]]
        else:  # neither: one force at the sole's centre
            kind, points = "point", [[xc, yc, "0"]]
        text = ", ".join("[" + ", ".join(p) + "]" for p in points)
        advice.append(f"{{frame: {frame}, type: {kind}, points: [{text}]}}")
    if not advice:
        return (
            "give such a foot point or line contacts (forces only, at the sole's corners or "
            "along its edge)"
        )
    return (
        "give such a foot a line contact (forces only, along the axis its leg cannot turn "
        "about; points in the contact frame [m]) in 'contacts:': " + "; ".join(advice)
    )


def task_reach(
    robot: Any,
    q: np.ndarray,
    tasks: Sequence[TaskSpec],
    contacts: Sequence[str | PlaneContact],
) -> list[tuple[int, str]]:
    """``(index, sentence)`` for each CoM or frame task whose controlled directions no joint
    motion that keeps the contacts held can move at configuration q (nq,): its Jacobian J times
    a basis N_c of the held contacts' null space lacks rank in the task's axes (a frame moved by
    no actuated joint, or an axis its joints are aligned against)."""
    state = RobotState(robot, q, np.zeros(robot.nv))
    Jk, _ = state.contact_constraint(list(contacts))
    N = _null_space(Jk, robot.nv)
    # a base motion the contacts leave free and no joint drives (all of it without contacts)
    # is not the joints' to make: take it out
    E = np.zeros((robot.nv, 6))
    E[:6] = np.eye(6)
    E = E @ _null_space(Jk[:, :6], 6)
    N = N - E @ (E.T @ N)
    out = []
    for i, task in enumerate(tasks):
        if task.type == "com":
            J, names = state.J_com, list(AXES_BY_TYPE["com"])
        elif task.type in FRAME_TASKS and task.frame is not None:
            J, names = state.jacobian(task.frame), list(AXES_BY_TYPE["frame_pose"])
        else:
            continue
        rows = [names.index(a) for a in task.selected_axes]
        u, s, _ = np.linalg.svd(J[rows] @ N)
        rank = int((s > 1e-6 * max(float(np.abs(J[rows]).max(initial=0.0)), 1.0)).sum())
        if rank == len(rows):
            continue
        where = f"frame {task.frame!r}" if task.frame else "the CoM"
        if rank == 0:
            why = f"no joint moves {where} with the contacts held"
        else:
            lacking = []
            for column in u[:, rank:].T:
                big = np.flatnonzero(np.abs(column) > 0.3 * np.abs(column).max())
                lacking.append(" with ".join(names[rows[b]] for b in big))
            why = (
                f"its Jacobian has rank {rank} of {len(rows)} in the task's axes with the "
                f"contacts held: no joint motion moves {where} along {'; nor '.join(lacking)}"
            )
        out.append(
            (
                i,
                f"tasks[{i}] ({task.name!r}) at the initial posture: {why}, so its target "
                "cannot be reached there; give the task only the axes its joints move "
                "('axes:'), or a frame those joints carry",
            )
        )
    return out


def _null_space(A: np.ndarray, n: int) -> np.ndarray:
    """An orthonormal basis (n, n − rank) of null(A), A (m, n); the identity when m = 0."""
    if A.shape[0] == 0:
        return np.eye(n)
    _, s, vt = np.linalg.svd(A)
    rank = int((s > RANK_TOLERANCE * max(float(s[0]), 1e-300)).sum())
    return vt[rank:].T.copy()
