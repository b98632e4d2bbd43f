"""How closely the controllers' Pinocchio model and the simulated MuJoCo model agree.

Both are built from one compiled model (:mod:`wbcbench.robots.pinocchio_model`), so they agree
to round-off; :func:`model_parity` measures it at random states and ``validate`` prints it.
Each quantity is compared in MuJoCo's coordinates (see :mod:`wbcbench.robots.convert`):

- the joint-space inertia: ``M_mj`` against ``Tᵀ M_pin T``;
- the bias forces: ``qfrc_bias`` against ``Tᵀ rnea(q, v, Ṫv)``;
- every site's and body's world Jacobian (linear and angular rows at its origin), against
  Pinocchio's ``LOCAL_WORLD_ALIGNED`` frame Jacobian times T.

Each error is relative: the largest absolute difference over the largest entry of MuJoCo's
quantity at that state (1 when that is smaller than 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from wbcbench.robots.convert import (
    base_velocity_transform,
    bias_pin_to_mj,
    mass_matrix_pin_to_mj,
    mj_to_pin,
)
from wbcbench.robots.loader import Robot

#: the relative disagreement above which ``validate`` warns: round-off of a few hundred
#: operations on entries of order one, well below any modelling difference
PARITY_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Parity:
    """Largest relative disagreement between the two libraries over random states.

    Attributes:
        mass: of the joint-space inertia M(q).
        bias: of the bias forces (Coriolis, centrifugal and gravity).
        jacobian: of the frames' world Jacobians.
        states: how many random states were compared.
    """

    mass: float
    bias: float
    jacobian: float
    states: int

    @property
    def worst(self) -> float:
        """The largest of the three."""
        return max(self.mass, self.bias, self.jacobian)


def random_mj_state(robot: Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random MuJoCo ``(qpos, qvel)``: base pose in a 2 m cube, joints within their limits
    (±π when unlimited), velocities in ±2 (m/s, rad/s)."""
    m = robot.mj_model
    qpos = m.qpos0.copy()
    qpos[0:3] = rng.uniform(-1.0, 1.0, 3)
    quat = rng.normal(size=4)
    qpos[3:7] = quat / np.linalg.norm(quat)
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
    qpos[robot.mj_qpos_adr] = rng.uniform(lo, hi)
    qvel = rng.uniform(-2.0, 2.0, m.nv)
    return qpos, qvel


def _relative(diff: np.ndarray, reference: np.ndarray) -> float:
    return float(np.abs(diff).max() / max(1.0, float(np.abs(reference).max())))


def model_parity(robot: Robot, states: int = 10, seed: int = 0) -> Parity:
    """The largest relative disagreement of M(q), the bias forces and every site's and body's
    Jacobian between MuJoCo and Pinocchio, over ``states`` random states (``seed``)."""
    m, pm = robot.mj_model, robot.pin_model
    d, pd = mujoco.MjData(m), pm.createData()
    rng = np.random.default_rng(seed)
    frames = []  # (Pinocchio frame, MuJoCo object type, id)
    for fid, frame in enumerate(pm.frames):
        if frame.type == pin.FrameType.OP_FRAME:
            frames.append((fid, mujoco.mjtObj.mjOBJ_SITE, m.site(frame.name).id))
        elif frame.type == pin.FrameType.BODY:
            frames.append((fid, mujoco.mjtObj.mjOBJ_BODY, m.body(frame.name).id))
    m_mj = np.zeros((m.nv, m.nv))
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    err = {"mass": 0.0, "bias": 0.0, "jacobian": 0.0}
    for _ in range(states):
        qpos, qvel = random_mj_state(robot, rng)
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, m_mj)
        q, v = mj_to_pin(robot, qpos, qvel)
        m_pin = pin.crba(pm, pd, q)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        err["mass"] = max(
            err["mass"], _relative(mass_matrix_pin_to_mj(robot, q, m_pin) - m_mj, m_mj)
        )
        bias = bias_pin_to_mj(robot, pd, q, v)
        err["bias"] = max(err["bias"], _relative(bias - d.qfrc_bias, d.qfrc_bias))
        t = base_velocity_transform(robot, q)
        pin.computeJointJacobians(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        for fid, kind, mid in frames:
            if kind == mujoco.mjtObj.mjOBJ_SITE:
                mujoco.mj_jacSite(m, d, jacp, jacr, mid)
            else:
                mujoco.mj_jacBody(m, d, jacp, jacr, mid)
            j_pin = pin.getFrameJacobian(pm, pd, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED) @ t
            j_mj = np.vstack([jacp, jacr])
            err["jacobian"] = max(err["jacobian"], _relative(j_pin - j_mj, j_mj))
    return Parity(states=states, **err)
