"""The independent rigid-contact forward-dynamics oracle.

Given a torque, what does the robot really do when its contacts are rigid? Solve

    [ M    −J_cᵀ ] [ q̈ ]   [ Sᵀ Γ − h   ]
    [ J_c    0   ] [ f  ] = [ −J̇_c q̇    ]

with f the reaction on the robot. Controllers are checked against this, never against their own
formulas: zero contact acceleration, realized task accelerations, strict hierarchy, and predicted
wrench = realized wrench.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wbcbench.dynamics.state import RobotState


@dataclass
class OracleResult:
    qdd: np.ndarray  # (n,)
    wrench: np.ndarray  # (6c,) reaction on the robot
    contact_acc: np.ndarray  # J_c q̈ + J̇_c q̇ (6c,), ≈ 0 by construction


def forward_dynamics(state: RobotState, tau: np.ndarray, frames: list[str]) -> OracleResult:
    """Rigid-contact forward dynamics at ``state`` under joint torques ``tau`` (k,)."""
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
    return OracleResult(qdd=qdd, wrench=f, contact_acc=Jc @ qdd + dJc)
