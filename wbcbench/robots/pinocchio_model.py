"""The controllers' Pinocchio model, built from the model MuJoCo compiled.

MuJoCo compiles the file (MJCF or URDF): includes, default classes, ``<frame>`` elements,
``balanceinertia``, angle units, ``euler`` sequences and every other compiler option are applied
once, by MuJoCo. This module reads the compiled :class:`mujoco.MjModel` and builds the same
multibody with Pinocchio's model-building API (``Model.addJoint``, ``appendBodyToJoint``,
``addBodyFrame``, ``addFrame``), so that the simulated robot and the controllers' model are one
and the same: body placements, joint anchors and axes, masses, centres of mass and inertias
(as simulated, balanced or not), armature, damping and friction.

MuJoCo → Pinocchio, body by body (bodies are stored parents first):

- a body's frame sits at ``body_pos``, ``body_quat`` in its parent's frame; its joints then
  move it, each about its own anchor ``jnt_pos`` and axis ``jnt_axis`` (both in the body's
  frame), the first joint first. A hinge becomes a revolute joint, a slide a prismatic joint,
  each placed at its anchor; the body hangs below the last joint at minus that anchor.
- a body without joints is welded to its parent: its inertia is appended to the parent's joint.
- the free joint of the root body becomes the free flyer, placed at the identity (MuJoCo puts
  that body's frame where ``qpos`` says, ignoring its pose in the file).
- ``dof_armature`` becomes ``Model.armature``: Pinocchio adds it to the diagonal of M (CRBA)
  and to the RNEA's torque, as MuJoCo does.

Every body becomes a ``BODY`` frame and every site an ``OP_FRAME`` of the same name. Joints keep
their names as joints (``Model.names``) but get no frame: the harness's frames are bodies and
sites, so a joint that shares its name with a body (published files have them) leaves one frame
of that name, and a frame lookup never has to choose. A ball joint has no place in a model whose
configuration is ``[base, one angle per joint]``: it is reported, naming the joint and its body.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from wbcbench.errors import ModelError

_AXES = {(1.0, 0.0, 0.0): "X", (0.0, 1.0, 0.0): "Y", (0.0, 0.0, 1.0): "Z"}


def _rotation(quat_wxyz: np.ndarray) -> np.ndarray:
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat_wxyz, dtype=float))
    return R.reshape(3, 3)


def _se3(pos: np.ndarray, quat_wxyz: np.ndarray) -> pin.SE3:
    return pin.SE3(_rotation(quat_wxyz), np.asarray(pos, dtype=float).copy())


def _translation(p: np.ndarray) -> pin.SE3:
    return pin.SE3(np.eye(3), np.asarray(p, dtype=float).copy())


def _joint_model(kind: int, axis: np.ndarray) -> pin.JointModel:
    """Revolute or prismatic joint about ``axis`` (unit, in the joint's frame); the aligned
    joint types when the axis is a coordinate axis."""
    key = tuple(float(a) for a in axis)
    aligned = _AXES.get(key)  # type: ignore[arg-type]
    if kind == mujoco.mjtJoint.mjJNT_HINGE:
        if aligned:
            return getattr(pin, f"JointModelR{aligned}")()
        return pin.JointModelRevoluteUnaligned(axis.copy())
    if aligned:
        return getattr(pin, f"JointModelP{aligned}")()
    return pin.JointModelPrismaticUnaligned(axis.copy())


def _body_inertia(m: mujoco.MjModel, b: int) -> pin.Inertia:
    """Spatial inertia of body ``b`` about its own frame, as MuJoCo simulates it."""
    R = _rotation(m.body_iquat[b])
    inertia = R @ np.diag(m.body_inertia[b]) @ R.T
    return pin.Inertia(float(m.body_mass[b]), m.body_ipos[b].copy(), inertia)


def build_pinocchio_model(m: mujoco.MjModel, path: Path) -> pin.Model:
    """Pinocchio's model of the multibody MuJoCo compiled in ``m`` (see the module docstring).

    Joint, body and site names are MuJoCo's; the joints come in MuJoCo's order, so Pinocchio's
    ``v[6:]`` is MuJoCo's ``qvel[6:]`` for a model with one free joint first.

    Raises:
        ModelError: naming ``path`` and the element, for a ball joint or a free joint that is
            not on a body of the world.
    """
    model = pin.Model()
    model.name = Path(path).stem
    # Pinocchio joint and frame holding each MuJoCo body's frame, and the body's placement in
    # that joint's frame
    joint_of = {0: 0}
    frame_of = {0: 0}
    placement_of = {0: pin.SE3.Identity()}
    dofs: list[tuple[int, int]] = []  # (Pinocchio joint, its first MuJoCo dof)
    for b in range(1, m.nbody):
        parent = int(m.body_parentid[b])
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"
        joint = joint_of[parent]
        # the body's frame in the parent's joint frame, before its own joints move it
        placement = placement_of[parent] * _se3(m.body_pos[b], m.body_quat[b])
        # ``placement``: the body's frame, before the next joint moves it, in the frame of
        # ``joint``. A joint at anchor a moves the body about a: T(a) · motion · T(−a).
        for j in range(int(m.body_jntadr[b]), int(m.body_jntadr[b] + m.body_jntnum[b])):
            kind = int(m.jnt_type[j])
            jname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
            if kind == mujoco.mjtJoint.mjJNT_BALL:
                raise ModelError(
                    f"{path}: <joint name={jname!r} type='ball'> in body {name!r}: Pinocchio's "
                    "model here holds one angle per joint; write the ball joint as three hinges "
                    "(one per axis) in that body"
                )
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                if joint != 0:
                    raise ModelError(
                        f"{path}: <freejoint name={jname!r}> in body {name!r}: only the root "
                        "body of the robot may have a free joint"
                    )
                jid = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), jname)
                placement = pin.SE3.Identity()
            else:
                anchor = m.jnt_pos[j]
                limited = bool(m.jnt_limited[j])
                lo, hi = m.jnt_range[j] if limited else (-np.inf, np.inf)
                jid = model.addJoint(
                    joint,
                    _joint_model(kind, m.jnt_axis[j]),
                    placement * _translation(anchor),
                    jname,
                    np.full(1, np.inf),
                    np.full(1, np.inf),
                    np.full(1, float(lo)),
                    np.full(1, float(hi)),
                )
                placement = _translation(-anchor)
            dofs.append((jid, int(m.jnt_dofadr[j])))
            joint = jid
        if joint != 0:
            model.appendBodyToJoint(joint, _body_inertia(m, b), placement)
        joint_of[b] = joint
        placement_of[b] = placement
        frame_of[b] = model.addBodyFrame(name, joint, placement, frame_of[parent])
    for s in range(m.nsite):
        b = int(m.site_bodyid[s])
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, s) or f"site{s}"
        model.addFrame(
            pin.Frame(
                name,
                joint_of[b],
                frame_of[b],
                placement_of[b] * _se3(m.site_pos[s], m.site_quat[s]),
                pin.FrameType.OP_FRAME,
            ),
            False,
        )
    model.armature = _pin_order(model, dofs, m.dof_armature)
    model.damping = _pin_order(model, dofs, m.dof_damping)
    model.friction = _pin_order(model, dofs, m.dof_frictionloss)
    return model


def _pin_order(model: pin.Model, dofs: list[tuple[int, int]], per_mj_dof: np.ndarray) -> np.ndarray:
    """A per-dof vector in MuJoCo's dof order → Pinocchio's velocity order."""
    out = np.zeros(model.nv)
    for jid, dof in dofs:
        nv = model.joints[jid].nv
        out[model.idx_vs[jid] : model.idx_vs[jid] + nv] = per_mj_dof[dof : dof + nv]
    return out
