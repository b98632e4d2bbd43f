"""State, force and matrix conversions between MuJoCo and Pinocchio conventions.

MuJoCo: ``qpos = [p, qw, qx, qy, qz, joints]``, ``qvel = [v_world, ω_local, joint rates]``.
Pinocchio: ``q = [p, qx, qy, qz, qw, joints]``, ``v = [v_local, ω_local, joint rates]``.
With R the base rotation (body → world), ``v_pin = T qvel`` where ``T`` is
``blkdiag(Rᵀ, I₃, P)`` and ``P`` picks the MuJoCo dof of each Pinocchio joint (identity for the
generated models). Hence generalised forces map as ``τ_mj = Tᵀ τ_pin``, the mass matrix as
``M_mj = Tᵀ M_pin T``, and the bias as ``qfrc_bias = Tᵀ rnea(q, v_pin, Ṫ qvel)`` with
``Ṫ qvel = [−ω × v_local, 0, …]``: the base's local linear velocity changes when the base turns
even at zero MuJoCo acceleration.

The per-tick functions use the robot's precomputed index arrays, no Python loop over joints.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from wbcbench.robots.loader import Robot


def quat_to_matrix(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion given as (x, y, z, w) (Pinocchio order)."""
    x, y, z, w = quat_xyzw
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def base_rotation(q: np.ndarray) -> np.ndarray:
    """Base rotation R (3, 3), body → world, from a Pinocchio configuration (nq,)."""
    return quat_to_matrix(q[3:7])


def mj_to_pin(
    robot: Robot, qpos: np.ndarray, qvel: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo ``(qpos (nq,), qvel (nv,))`` → Pinocchio ``(q (nq,), v (nv,))``.

    The base quaternion is normalised (Pinocchio assumes unit quaternions).
    """
    qpos = np.asarray(qpos, dtype=float)
    q = np.empty(robot.nq)
    q[0:3] = qpos[0:3]
    quat = qpos[[4, 5, 6, 3]]
    q[3:7] = quat / np.linalg.norm(quat)
    q[7:] = qpos[robot.mj_qpos_adr]
    v = np.zeros(robot.nv)
    if qvel is not None:
        qvel = np.asarray(qvel, dtype=float)
        v[0:3] = base_rotation(q).T @ qvel[0:3]
        v[3:6] = qvel[3:6]
        v[6:] = qvel[robot.mj_dof_adr]
    return q, v


def pin_to_mj(
    robot: Robot, q: np.ndarray, v: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio ``(q (nq,), v (nv,))`` → MuJoCo ``(qpos (nq,), qvel (nv,))``."""
    q = np.asarray(q, dtype=float)
    qpos = np.zeros(robot.mj_model.nq)
    qpos[0:3] = q[0:3]
    qpos[3] = q[6]
    qpos[4:7] = q[3:6]
    qpos[robot.mj_qpos_adr] = q[7:]
    qvel = np.zeros(robot.mj_model.nv)
    if v is not None:
        v = np.asarray(v, dtype=float)
        qvel[0:3] = base_rotation(q) @ v[0:3]
        qvel[3:6] = v[3:6]
        qvel[robot.mj_dof_adr] = v[6:]
    return qpos, qvel


def base_velocity_transform(robot: Robot, q: np.ndarray) -> np.ndarray:
    """T (nv, nv) with ``v_pin = T qvel_mj``; rows in Pinocchio order, columns in MuJoCo's."""
    t = np.zeros((robot.nv, robot.nv))
    t[0:3, 0:3] = base_rotation(q).T
    t[3:6, 3:6] = np.eye(3)
    t[np.arange(6, robot.nv), robot.mj_dof_adr] = 1.0
    return t


def force_pin_to_mj(robot: Robot, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Generalised force in Pinocchio coordinates (nv,) → MuJoCo ``qfrc`` (nv,): Tᵀ τ."""
    out = np.empty(robot.nv)
    out[0:3] = base_rotation(q) @ tau[0:3]
    out[3:6] = tau[3:6]
    out[robot.mj_dof_adr] = tau[6:]
    return out


def mass_matrix_pin_to_mj(robot: Robot, q: np.ndarray, m_pin: np.ndarray) -> np.ndarray:
    """Joint-space inertia (nv, nv): Pinocchio coordinates → MuJoCo's, Tᵀ M T."""
    t = base_velocity_transform(robot, q)
    return t.T @ m_pin @ t


def bias_pin_to_mj(robot: Robot, data: pin.Data, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """MuJoCo ``qfrc_bias`` (nv,) from Pinocchio: Tᵀ rnea(q, v, Ṫ qvel).

    Args:
        data: Pinocchio data of ``robot.pin_model`` (overwritten).
        q, v: Pinocchio state (nq,), (nv,).
    """
    a = np.zeros(robot.nv)
    a[0:3] = -np.cross(v[3:6], v[0:3])
    return force_pin_to_mj(robot, q, pin.rnea(robot.pin_model, data, q, v, a))


def torque_to_ctrl(robot: Robot, tau: np.ndarray) -> np.ndarray:
    """MuJoCo ``ctrl`` (nu,) producing actuated torques ``tau`` (k,) [N·m] (Pinocchio order).

    Actuators not driving one of the k joints get 0; the result is not clipped to ``ctrlrange``.
    """
    ctrl = np.zeros(robot.mj_model.nu)
    ctrl[robot.actuator_ids] = np.asarray(tau, dtype=float) / robot.act_gear
    return ctrl
