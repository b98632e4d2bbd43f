"""The independent rigid-contact forward-dynamics oracle.

Given a torque, what does the robot really do when its contacts are rigid? Solve

    [ M    −J_cᵀ ] [ q̈ ]   [ Sᵀ Γ − h   ]
    [ J_c    0   ] [ f  ] = [ −J̇_c q̇    ]

with f the reaction on the robot. Controllers are checked against this, never against their own
formulas: zero contact acceleration, realized task accelerations, strict hierarchy, and predicted
wrench = realized wrench.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wbcbench.dynamics.state import RobotState
from wbcbench.tasks.contacts import PlaneContact, frame_wrenches


@dataclass
class OracleResult:
    qdd: np.ndarray  # (n,)
    wrench: np.ndarray  # (6c,) reaction on the robot, each contact's wrench at its frame
    contact_acc: np.ndarray  # J_c q̈ + J̇_c q̇ (Σ dim,), ≈ 0 by construction
    forces: np.ndarray  # (Σ dim,) the force variable: 6 per flat contact, 3 per point


def forward_dynamics(
    state: RobotState, tau: np.ndarray, frames: Sequence[str | PlaneContact]
) -> OracleResult:
    """Rigid-contact forward dynamics at ``state`` under joint torques ``tau`` (k,).

    ``frames``: the held contacts, a frame name for a flat one. A point set's rows are its
    points' accelerations (3 each): several points on one body make K singular yet consistent,
    its forces are then not unique but their wrench at the frame ``G f`` is, and q̈ is."""
    n = state.n
    M, h = state.M, state.h
    Jc = state.contact_jacobian(frames)
    dJc = state.contact_drift(frames)
    nc = Jc.shape[0]
    gen = np.zeros(n)
    gen[6:] = tau
    K = np.zeros((n + nc, n + nc))
    K[:n, :n] = M
    K[:n, n:] = -Jc.T
    K[n:, :n] = Jc
    rhs = np.concatenate([gen - h, -dJc])
    # lstsq: redundant contacts (e.g. three coplanar planes) make K singular yet consistent
    sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
    qdd, f = sol[:n], sol[n:]
    contacts = [PlaneContact(frame=c) if isinstance(c, str) else c for c in frames]
    wrench = frame_wrenches(contacts, f)
    return OracleResult(qdd=qdd, wrench=wrench, contact_acc=Jc @ qdd + dJc, forces=f)
