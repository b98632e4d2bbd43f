"""Reduced-dimension whole-body dynamics through the unconstrained chains' centroidal dynamics.

RC-LQP paper §3.2–3.4 (eq. 8–22). Each unconstrained chain u (see :mod:`wbcbench.dynamics.chains`)
is summarised by its average spatial velocity relative to the body it hangs from,

    v_G,u = I_G,u⁻¹ A_G,u q̇_u = J_G,u q̇_u                              (eq. 8–10)

with A_G,u (6, n_u) the chain's centroidal momentum matrix (momentum about the chain's own CoM
produced by its joints alone) and I_G,u (6, 6) = blkdiag(m_u I₃, I_c,u) its centroidal inertia,
both in the axes of the body the chain hangs from (the base for every humanoid in the library:
the paper's ``ᵇ``). Rows are [linear; angular], Pinocchio's order. The reduced velocity is

    q̇_r = J_r q̇ = [q̇_vc; q̇_cc; q̇_kept; v_G,1; …]                       (eq. 11–13)

and the dynamics projected on it (eq. 14a–e, 15)

    M_r = (J_r M⁻¹ J_rᵀ)⁻¹,   b_r = M_r (J_r M⁻¹ b − J̇_r q̇),   g_r = M_r J_r M⁻¹ g,
    J̄_r = M⁻¹ J_rᵀ M_r,       J_c,r = J_c J̄_r = J_c restricted to the plain coordinates.

Facts the controllers rely on (checked in ``tests/test_chains.py``): the base rows of J̄_rᵀ are
S_vc and its constraint rows S_cc, because M's columns of the base and the constraint chain see
a chain only through its momentum. So the top six rows of eq. (14) *are* the floating-base
Newton–Euler equations, and its constraint-chain rows give the exact Γ_cc, whenever
q̈_r = J_r q̈ + J̇_r q̇.

The drift J̇_G,u q̇ used here is I_G,u⁻¹ times the rate of the chain's relative centroidal
momentum at zero q̈ (the base and the other chains frozen): the acceleration coordinate of a chain
is its momentum rate scaled by its centroidal inertia. The literal derivative of I_G⁻¹ A_G q̇
adds −I_G⁻¹ İ_G v_G, a second-order term in the chain's velocity; both LQPs use the same drift,
so eq. (30) and the base's Newton–Euler rows hold exactly either way.

Each chain's fixed-base dynamics (eq. 17), M_uc q̈_uc + b_uc + g_uc = Γ_uc, is the chain on its
parent body held still: M_uc = M[uc, uc], g_uc = g[uc], b_uc from one RNEA with only the chain's
velocities.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from wbcbench.dynamics.chains import CENTROID_DIM, ChainSplit
from wbcbench.dynamics.dense import skew, spd_factor, spd_inverse, spd_solve
from wbcbench.dynamics.state import ContactLike, RobotState


@dataclass
class ChainCentroid:
    """Centroidal quantities of one unconstrained chain, in its parent body's axes.

    Attributes:
        A_G: centroidal momentum matrix (6, n_u) [kg·m/s, kg·m²/s per rad/s].
        I_G: centroidal inertia blkdiag(m I₃, I_c) (6, 6).
        J_G: centroidal inertial Jacobian I_G⁻¹ A_G (6, n_u).
        drift: J̇_G q̇ (6,) [m/s², rad/s²].
        mass: chain mass [kg].
        com: chain CoM in the world (3,) [m].
        R: world rotation of the parent body (3, 3).
    """

    A_G: np.ndarray
    I_G: np.ndarray
    J_G: np.ndarray
    drift: np.ndarray
    mass: float
    com: np.ndarray
    R: np.ndarray


@dataclass
class ReducedModel:
    """Reduced dynamics of one state (RC-LQP eq. 11–17). n_r = split.n_reduced.

    Attributes:
        split: the chain split it was built for.
        J_r: reduced Jacobian (n_r, n); dJr_v: J̇_r q̇ (n_r,) (non-zero in chain rows only).
        M_r: reduced inertia (n_r, n_r); b_r, g_r: Coriolis/centrifugal and gravity (n_r,).
        Jbar_r: dynamically consistent inverse M⁻¹ J_rᵀ M_r (n, n_r).
        J_cr: reduced contact Jacobian (6c, n_r) (eq. 15).
        chains: centroidal quantities per chain.
        J_G: block-diagonal J_G of every chain (6·n_chains, n_uc).
        dJG_v: stacked J̇_G q̇ of every chain (6·n_chains,).
        M_uc: fixed-base inertia of the chains' joints (n_uc, n_uc) (eq. 17).
        b_uc, g_uc: fixed-base Coriolis/centrifugal and gravity (n_uc,) [N·m]; NaN when the
            fixed-base pass was not requested.
        time: wall time of the reduced quantities [s] (Pinocchio quantities of the state that
            were first requested here are included).
    """

    split: ChainSplit
    J_r: np.ndarray
    dJr_v: np.ndarray
    M_r: np.ndarray
    b_r: np.ndarray
    g_r: np.ndarray
    Jbar_r: np.ndarray
    J_cr: np.ndarray
    chains: list[ChainCentroid]
    J_G: np.ndarray
    dJG_v: np.ndarray
    M_uc: np.ndarray
    b_uc: np.ndarray
    g_uc: np.ndarray
    time: float

    @property
    def n_plain(self) -> int:
        return int(self.split.plain.size)

    @functools.cached_property
    def M_uc_factor(self) -> np.ndarray:
        """Upper Cholesky factor Lᵀ of M_uc = L Lᵀ (computed once, on first use)."""
        return spd_factor(self.M_uc)

    def task(self, J: np.ndarray, drift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A task J q̈ + J̇ q̇ in the reduced space (eq. 22): (J J̄_r (m, n_r), drift (m,)).

        Valid for rows with J N_r = 0 (see :meth:`reducible_rows`): then
        J q̈ + J̇ q̇ = J J̄_r q̈_r + (J̇ q̇ − J J̄_r J̇_r q̇).
        """
        Jr = J @ self.Jbar_r
        return Jr, drift - Jr @ self.dJr_v

    def reducible_rows(self, J: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Boolean mask (m,): rows with J N_r = 0, i.e. expressible through q̇_r (§3.4.1)."""
        residual = np.abs(J - (J @ self.Jbar_r) @ self.J_r).max(axis=1)
        scale = np.maximum(1.0, np.abs(J).max(axis=1))
        return residual <= tol * scale


class ReducedDynamics:
    """Builds :class:`ReducedModel` for one robot and one chain split, tick after tick.

    Holds its own Pinocchio Data for the chains' relative passes (allocating one per tick would
    cost more than the passes).
    """

    def __init__(
        self,
        model: pin.Model,
        split: ChainSplit,
        contacts: Sequence[str | ContactLike] | None = None,
    ) -> None:
        self.model = model
        self.split = split
        #: the contacts whose rows J_cr holds (by default the split's frames, flat)
        self.contacts = list(split.contact_frames if contacts is None else contacts)
        self._data = model.createData()
        n, n_r = split.n, split.n_reduced
        plain = split.plain
        self._plain = plain
        self._J_r = np.zeros((n_r, n))
        self._J_r[np.arange(plain.size), plain] = 1.0
        self._uc = split.unconstrained
        self._v_rel = np.zeros(n)
        self._zero = np.zeros(n)
        self._eye_r = np.eye(n_r)
        # column offset of each chain in q̈_uc (chains are stacked chain after chain)
        sizes = [c.dof for c in split.chains]
        self._uc_cols = np.concatenate([[0], np.cumsum(sizes)]).astype(int)

    def compute(self, state: RobotState, fixed_base: bool = True) -> ReducedModel:
        """Reduced model at ``state``; ``fixed_base`` adds eq. (17)'s b_uc (one more RNEA)."""
        t0 = time.perf_counter()
        split = self.split
        model, data = self.model, self._data
        n_p = self._plain.size
        cmm, com = state.cmm, state.com
        oYcrb = state.subtree_inertias
        oMi = state.data.oMi
        # relative motion of the chains: base and constraint chain frozen
        v_rel = self._v_rel
        v_rel[:] = 0.0
        v_rel[self._uc] = state.v[self._uc]
        pin.computeCentroidalMomentumTimeVariation(model, data, state.q, v_rel, self._zero)
        dh_lin = data.dhg.linear
        dh_ang = data.dhg.angular
        J_r = self._J_r
        dJr_v = np.zeros(split.n_reduced)
        chains: list[ChainCentroid] = []
        n_ch = len(split.chains)
        J_G_all = np.zeros((CENTROID_DIM * n_ch, self._uc.size))
        for i, chain in enumerate(split.chains):
            Y = oYcrb[chain.root_joints[0]]
            for r in chain.root_joints[1:]:
                Y = Y + oYcrb[r]
            m, c, Ic = float(Y.mass), np.array(Y.lever), np.array(Y.inertia)
            R = oMi[chain.parent_joint].rotation
            # rate of relative momentum at zero q̈ (only the chains move, so the whole robot's
            # is the chains'; with one chain it is this chain's)
            if len(split.chains) > 1:
                v_rel[:] = 0.0
                v_rel[chain.idx] = state.v[chain.idx]
                pin.computeCentroidalMomentumTimeVariation(model, data, state.q, v_rel, self._zero)
                dh_lin, dh_ang = data.dhg.linear, data.dhg.angular
            # [A_G | J̇_G-momentum] in one block: columns of the chain's joints, then the drift
            X = np.empty((6, chain.dof + 1))
            X[:, :-1] = cmm[:, chain.idx]
            X[:3, -1] = dh_lin
            X[3:, -1] = dh_ang
            # k about c = k about the total CoM + (C − c) × l
            X[3:] += skew(com - c) @ X[:3]
            X[:3] = R.T @ X[:3]
            X[3:] = R.T @ X[3:]
            Ic_l = R.T @ Ic @ R
            Y6 = np.empty_like(X)
            Y6[:3] = X[:3] / m
            Y6[3:] = spd_solve(Ic_l, X[3:])
            A_G, J_G, drift = X[:, :-1], Y6[:, :-1], Y6[:, -1]
            I_G = np.zeros((6, 6))
            I_G[:3, :3] = m * np.eye(3)
            I_G[3:, 3:] = Ic_l
            rows = slice(n_p + CENTROID_DIM * i, n_p + CENTROID_DIM * (i + 1))
            J_r[rows, chain.idx] = J_G
            dJr_v[rows] = drift
            cols = slice(self._uc_cols[i], self._uc_cols[i + 1])
            J_G_all[CENTROID_DIM * i : CENTROID_DIM * (i + 1), cols] = J_G
            chains.append(ChainCentroid(A_G, I_G, J_G, drift, m, c, R.copy()))

        Minv, h, g = state.Minv, state.h, state.g
        JMinv = J_r @ Minv  # (n_r, n)
        Lambda_inv = JMinv @ J_r.T
        M_r = spd_inverse(Lambda_inv)
        proj = M_r @ (JMinv @ np.column_stack([h - g, g]))
        b_r = proj[:, 0] - M_r @ dJr_v
        g_r = proj[:, 1]
        Jbar_r = JMinv.T @ M_r
        Jc = state.contact_jacobian(self.contacts)
        J_cr = np.zeros((Jc.shape[0], split.n_reduced))
        J_cr[:, :n_p] = Jc[:, self._plain]

        uc = self._uc
        M_uc = state.M[np.ix_(uc, uc)]
        g_uc = g[uc]
        if fixed_base and uc.size:
            v_rel[:] = 0.0
            v_rel[uc] = state.v[uc]
            b_uc = pin.nonLinearEffects(model, data, state.q, v_rel)[uc] - g_uc
        else:
            b_uc = np.full(uc.size, np.nan)
        return ReducedModel(
            split=split,
            J_r=J_r.copy(),
            dJr_v=dJr_v,
            M_r=M_r,
            b_r=b_r,
            g_r=g_r,
            Jbar_r=Jbar_r,
            J_cr=J_cr,
            chains=chains,
            J_G=J_G_all,
            dJG_v=dJr_v[n_p:].copy(),
            M_uc=M_uc,
            b_uc=b_uc,
            g_uc=g_uc,
            time=time.perf_counter() - t0,
        )
