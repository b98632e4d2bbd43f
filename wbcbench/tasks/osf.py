"""Contact-consistent operational-space quantities (TO-OSF §II and §III-B1, OSF-HQP eq. 16–17).

Everything the two OSF controllers (``to_osf``, ``osf_hqp``) need, computed from one
:class:`~wbcbench.dynamics.state.RobotState` in one place. Conventions are the project's: ``f`` is
the contact wrench **on the robot**, ``M q̈ + h = Sᵀ Γ + J_cᵀ f``; the papers' ``F_c`` is ``−f``.

Contact-constrained dynamics (n = 6 + k velocities, c contact rows, S = [0 I_k]):

    Λ_c = (J_c M⁻¹ J_cᵀ)⁻¹,  J̄_c = M⁻¹ J_cᵀ Λ_c,  N_c = I − J̄_c J_c,  Φ = M⁻¹ N_cᵀ,
    W = S Φ Sᵀ  (k×k, rank k − (c − 6)),
    q̈ = Φ Sᵀ Γ + q̈₀,            q̈₀ = −Φ h − J̄_c J̇_c q̇   (the zero-torque constrained motion),
    f = F Γ + f₀,                F = −J̄_cᵀ Sᵀ,  f₀ = J̄_cᵀ h − Λ_c J̇_c q̇.

Dynamically consistent inverse of ``Y = S N_c`` (k×n) with the inertia as weighting (TO-OSF
eq. 16–20): ``Ȳ = (I − v₂ (v₂ᵀ M v₂)⁻¹ v₂ᵀ M) Y†``, with ``Y†`` and the null-space basis ``v₂``
from a complete orthogonal decomposition (``cod``, Householder QR with column pivoting followed by
a QR of the trapezoidal factor) or from an SVD (``svd``). It equals Φ Sᵀ W⁺. ``pinv`` keeps the
plain Moore–Penrose ``Y†`` instead (the ablation of TO-OSF Fig. 6–7). The left null space of Y is
null(W): torques there change the contact wrench and no acceleration (the wrench distribution
space, ``N_w`` in TO-OSF, the range of ``Y_c`` in OSF-HQP).

Priority levels (tasks grouped by priority; ``J*_i = J_i Ȳ``, N*_{<1} = I):

    J*_{i|<i} = J*_i N*_{<i},   Λ_{i|<i} = (J*_{i|<i} W J*_{i|<i}ᵀ)⁺,
    J̄*_{i|<i} = W J*_{i|<i}ᵀ Λ_{i|<i},   N*_{<i+1} = N*_{<i} (I − J̄*_{i|<i} J*_{i|<i}),
    Γ = Σ_i J*_{i|<i}ᵀ Λ_{i|<i} (ẍ*_i − Ĵ_i Γ_{<i} − b_i),
    Ĵ_i = J_i Φ Sᵀ,  b_i = J_i q̈₀ + J̇_i q̇.

The coupling term ``Ĵ_i Γ_{<i}`` makes every level exact when feasible (``coupling="exact"``); the
papers' eq. (7) / (16) write each level's force as ``Λ_i ẍ*_i`` plus one compensation torque
(``coupling="literal"``, kept to measure what it costs). A force-level level (OSF-HQP eq. 30–31,
TO-OSF Remark 1) takes an operational force ``F*`` [N, N·m] instead: its torque is
``J*_{i|<i}ᵀ (F*_i + Λ_{i|<i}(−Ĵ_i Γ_{<i} − b_i))``, its realised acceleration ``Λ_{i|<i}⁻¹ F*_i``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Literal

import numpy as np
from scipy.linalg import lapack

from wbcbench.dynamics.dense import (
    spd_factor,
    spd_inverse,
    spd_solve,
    spd_solve_factored,
    tri_solve,
    upper,
)
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.tasks.contacts import PlaneContact
from wbcbench.tasks.tasks import Task

Inverse = Literal["cod", "svd", "pinv"]
Coupling = Literal["exact", "literal"]
INVERSES: tuple[str, ...] = ("cod", "svd", "pinv")
COUPLINGS: tuple[str, ...] = ("exact", "literal")


# -- decompositions -------------------------------------------------------------------------------


def _rank(diag: np.ndarray, rcond: float, scale: float = 0.0) -> int:
    """Numerical rank from a non-increasing vector of |R_ii| or singular values: those above
    ``rcond · max(largest, scale)``."""
    if diag.size == 0 or diag[0] <= 0.0:
        return 0
    return int(np.count_nonzero(diag > rcond * max(float(diag[0]), scale)))


@dataclass
class Decomposition:
    """Y† and the null spaces of a (k, n) matrix Y of rank r.

    Attributes:
        pinv: Moore–Penrose pseudo-inverse Y† (n, k).
        right_null: orthonormal basis of null(Y) (n, n − r) — TO-OSF's v₂.
        left_null: orthonormal basis of null(Yᵀ) (k, k − r).
        rank: r.
    """

    pinv: np.ndarray
    right_null: np.ndarray
    left_null: np.ndarray
    rank: int


def _complete_qr(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A = Q [R; 0] for a tall (m, r) A: the full orthogonal Q (m, m) and R (r, r)."""
    m, r = A.shape
    qr, tau, _, info = lapack.dgeqrf(A)
    if info != 0:
        raise np.linalg.LinAlgError(f"QR failed (info {info})")
    R = upper(qr[:r, :])
    reflectors = np.zeros((m, m))
    reflectors[:, :r] = qr
    q, _, info = lapack.dorgqr(reflectors, tau)
    if info != 0:
        raise np.linalg.LinAlgError(f"QR failed (info {info})")
    return np.asarray(q), R


def cod(Y: np.ndarray, rcond: float = 1e-9) -> Decomposition:
    """Complete orthogonal decomposition Y = Q [T 0; 0 0] Vᵀ (TO-OSF eq. 16–17).

    Householder QR with column pivoting, ``Y P = Q [R₁₁ R₁₂; 0 0]``, then a QR of the trapezoidal
    ``[R₁₁ R₁₂]ᵀ = Z [T'; 0]`` so that ``Y = Q₁ T'ᵀ Z₁ᵀ Pᵀ``: ``Y† = P Z₁ T'⁻ᵀ Q₁ᵀ``, ``v₂ = P Z₂``.
    """
    k = Y.shape[0]  # Y is wide (k ≤ n)
    qr, jpvt, tau, _, _ = lapack.dgeqp3(Y)
    r = _rank(np.abs(np.diag(qr)), rcond)
    # Y is wide here (k ≤ n): the first k columns hold the k reflectors of Q
    q_full, _, _ = lapack.dorgqr(qr[:, :k], tau)
    q1, q2 = q_full[:, :r], q_full[:, r:]
    trap = upper(qr[:r, :])  # (r, n) = [R11 R12]
    z, t = _complete_qr(trap.T)  # (n, n), (r, r)
    perm = jpvt - 1
    v = np.empty_like(z)
    v[perm] = z  # P Z
    v1, v2 = v[:, :r], v[:, r:]
    # Y† = V₁ T'⁻ᵀ Q₁ᵀ  (T' = t[:r] upper triangular)
    tinv_q1t = tri_solve(t, q1.T, trans=True)
    return Decomposition(pinv=v1 @ tinv_q1t, right_null=v2, left_null=q2, rank=r)


def svd(Y: np.ndarray, rcond: float = 1e-9) -> Decomposition:
    """The same quantities from a full SVD Y = U Σ Vᵀ."""
    u, s, vt = np.linalg.svd(Y, full_matrices=True)
    r = _rank(s, rcond)
    pinv = (vt[:r].T / s[:r]) @ u[:, :r].T
    return Decomposition(pinv=pinv, right_null=vt[r:].T, left_null=u[:, r:], rank=r)


def psd_pinv(
    X: np.ndarray, method: str = "cod", rcond: float = 1e-9, scale: float = 0.0
) -> tuple[np.ndarray, int]:
    """Pseudo-inverse of a symmetric positive semidefinite (m, m) matrix and its rank.

    ``cod``: pivoted Householder QR ``X P = Q R`` reveals the range Q₁ (X is symmetric, so its
    range is its row space), and ``X = Q₁ C Q₁ᵀ`` with C = Q₁ᵀ X Q₁ positive definite: the
    complete orthogonal decomposition gives ``X⁺ = Q₁ C⁻¹ Q₁ᵀ`` by one Cholesky solve. ``svd``:
    from the singular values. The rank counts the values above ``rcond · max(largest, scale)``:
    ``scale`` is the size X would have without the projections that made it small (a task fully
    determined by the levels above has X ≈ 0, whose noise must not be inverted).
    """
    m = X.shape[0]
    if m == 0:
        return np.zeros((0, 0)), 0
    if method == "svd":
        u, s, _ = np.linalg.svd(X)
        r = _rank(s, rcond, scale)
        return (u[:, :r] / s[:r]) @ u[:, :r].T, r  # r = 0 gives the zero matrix
    qr, _, tau, _, _ = lapack.dgeqp3(X)
    r = _rank(np.abs(np.diag(qr)), rcond, scale)
    if r == 0:
        return np.zeros((m, m)), 0
    if r == m:
        return spd_inverse(X), m
    q, _, _ = lapack.dorgqr(qr, tau)
    q1 = q[:, :r]
    return q1 @ spd_solve(q1.T @ X @ q1, q1.T), r


# -- contact-constrained dynamics -------------------------------------------------------------


@dataclass
class ContactDynamics:
    """Contact-constrained joint-space quantities at one state.

    Attributes:
        Lambda_c: contact-space inertia Λ_c (c, c).
        Jc_bar: dynamically consistent inverse J̄_c = M⁻¹ J_cᵀ Λ_c (n, c).
        Phi: Φ = M⁻¹ N_cᵀ (n, n), symmetric PSD.
        W: S Φ Sᵀ (k, k).
        Y: S N_c (k, n), the matrix whose inertia-weighted inverse gives J*.
        qdd0: zero-torque constrained joint acceleration q̈₀ (n,).
        F: wrench map F = −J̄_cᵀ Sᵀ (c, k): wrench change per torque.
        f0: wrench at zero torque (c,) [N, N·m].
    """

    Lambda_c: np.ndarray
    Jc_bar: np.ndarray
    Phi: np.ndarray
    W: np.ndarray
    Y: np.ndarray
    qdd0: np.ndarray
    F: np.ndarray
    f0: np.ndarray


def contact_dynamics(state: RobotState, frames: Sequence[str | PlaneContact]) -> ContactDynamics:
    """Λ_c, J̄_c, Φ, W, q̈₀ and the wrench map at ``state`` for the contacts ``frames`` (a frame
    name is a flat contact; a point set's rows are redundant: several points on one body)."""
    n, k = state.n, state.k
    Minv, h = state.Minv, state.h
    Jc = state.contact_jacobian(list(frames))
    dJc = state.contact_drift(list(frames))
    c = Jc.shape[0]
    if c == 0:
        z = np.zeros((0, n))
        Phi = Minv.copy()
        return ContactDynamics(
            np.zeros((0, 0)), z.T, Phi, Phi[6:, 6:], np.eye(n)[6:], -Minv @ h, z[:, 6:], np.zeros(0)
        )
    B = Minv @ Jc.T  # (n, c)
    if any(not isinstance(f, str) and f.points is not None and len(f.points) > 1 for f in frames):
        # several points on one body: J_c has dependent rows by construction
        Lambda_c, _ = psd_pinv(Jc @ B, "svd")
    else:
        try:
            Lambda_c = spd_inverse(Jc @ B)
        except np.linalg.LinAlgError:  # redundant contacts: J_c rank-deficient
            Lambda_c, _ = psd_pinv(Jc @ B, "svd")
    Xt = Lambda_c @ B.T  # J̄_cᵀ (c, n)
    Phi = Minv - B @ Xt
    Phi = 0.5 * (Phi + Phi.T)
    Y = -Xt.T[6:] @ Jc
    Y[:, 6:] += np.eye(k)
    qdd0 = -Phi @ h - Xt.T @ dJc
    F = -Xt[:, 6:]
    f0 = Xt @ h - Lambda_c @ dJc
    return ContactDynamics(Lambda_c, Xt.T, Phi, Phi[6:, 6:], Y, qdd0, F, f0)


def dynamically_consistent_inverse(
    cd: ContactDynamics, M: np.ndarray, method: str = "cod", rcond: float = 1e-9
) -> tuple[np.ndarray, np.ndarray]:
    """Ȳ (n, k) of Y = S N_c with weighting M (TO-OSF eq. 20) and N_w, a basis of null(W) (k, p).

    ``pinv`` returns the plain Y† (no inertia weighting) and the same N_w.
    """
    if method not in INVERSES:
        raise ControllerError(f"unknown inverse {method!r}; valid choices: {', '.join(INVERSES)}")
    dec = svd(cd.Y, rcond) if method == "svd" else cod(cd.Y, rcond)
    if method == "pinv" or dec.right_null.shape[1] == 0:
        return dec.pinv, dec.left_null
    v2 = dec.right_null
    Mv2 = M @ v2
    chol = spd_factor(v2.T @ Mv2)
    # α₂ = −(v₂ᵀ M v₂)⁻¹ v₂ᵀ M Y† β  (eq. 19)
    alpha = spd_solve_factored(chol, Mv2.T @ dec.pinv)
    return dec.pinv - v2 @ alpha, dec.left_null


# -- levels and parameters ----------------------------------------------------------------------


def task_jacobian(task: Task, state: RobotState) -> tuple[np.ndarray, np.ndarray]:
    """A task's Jacobian (m, n) and drift J̇ q̇ (m,) without its reference (for the parameters).

    Uses the task's own full-dimension terms and row selection, so it needs no started task.
    """
    rows = task._rows
    return task._full_jacobian(state)[rows], task._full_drift(state)[rows]


@dataclass
class LevelParams:
    """Operational-space parameters of one priority level (m = stacked task rows).

    Attributes:
        Jhat: Ĵ = J Φ Sᵀ (m, k): task acceleration per torque.
        bias: b = J q̈₀ + J̇ q̇ (m,): task acceleration at zero torque.
        Jstar: J*_{i|<i} (m, k).
        Lam: Λ_{i|<i} (m, m).
        B: J*_{i|<i}ᵀ Λ_{i|<i} (k, m).
        E: input map (k, m) of the level's reference: B (acceleration) or J*_{i|<i}ᵀ (force).
    """

    Jhat: np.ndarray
    bias: np.ndarray
    Jstar: np.ndarray
    Lam: np.ndarray
    B: np.ndarray
    E: np.ndarray

    @property
    def dim(self) -> int:
        return int(self.bias.shape[0])


@dataclass
class OsfParams:
    """Every state-dependent quantity the OSF controllers read each tick.

    Computed by :meth:`OsfModel.params` (possibly off the control loop); the control loop
    combines them with fresh task references only. Shapes: n velocities, k joints, c contact
    rows, p = dim null(W) (c − 6 for independent plane contacts), M = Σ level dims.

    Attributes:
        levels: per-priority parameters.
        Phi_a: Φ Sᵀ (n, k), q̈ per torque.
        qdd0: zero-torque q̈₀ (n,).
        F: wrench per torque (c, k); f0: wrench at zero torque (c,).
        W: S Φ Sᵀ (k, k).
        Nw: orthonormal basis of null(W) (k, p).
        Yc: wrench-distribution map (k, p): torque in null(W) with ``F Yc = Qf`` (OSF-HQP Y_c).
        Qf: orthonormal basis of the internal wrenches the distribution produces (c, p).
        Yw: ``Yc Qfᵀ`` (k, c): torque producing an internal wrench (TO-OSF N_w J̃_wᵀ).
        G: grasp map (6, c) in the base frame (the base rows of J_cᵀ): internal wrenches satisfy
            G f = 0.
        K, gamma0: the affine torque of all levels, Γ = K ρ + γ₀ (k, M), (k,); γ₀ is the
            compensation torque (TO-OSF Γ_gc). Empty unless requested.
        tick: control tick of the state the parameters were computed from.
        compute_time: seconds spent computing them (Pinocchio passes excluded).
    """

    levels: list[LevelParams]
    Phi_a: np.ndarray
    qdd0: np.ndarray
    F: np.ndarray
    f0: np.ndarray
    W: np.ndarray
    Nw: np.ndarray
    Yc: np.ndarray
    Qf: np.ndarray
    Yw: np.ndarray
    G: np.ndarray
    K: np.ndarray
    gamma0: np.ndarray
    coupling: str = "exact"
    tick: int = 0
    compute_time: float = 0.0

    # -- what a torque does -----------------------------------------------------------------

    def qdd(self, tau: np.ndarray) -> np.ndarray:
        """Constrained joint acceleration produced by ``tau`` (n,)."""
        return self.Phi_a @ tau + self.qdd0

    def wrench(self, tau: np.ndarray) -> np.ndarray:
        """Contact wrench (reaction on the robot) produced by ``tau`` (c,)."""
        return self.F @ tau + self.f0

    # -- the torque of eq. (7) / (25) -------------------------------------------------------

    def level_step(self, i: int, prev: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Γ_{≤i} from Γ_{<i} and level i's reference (acceleration or force)."""
        lv = self.levels[i]
        out = prev + lv.E @ ref - lv.B @ lv.bias
        if self.coupling == "exact":
            out -= lv.B @ (lv.Jhat @ prev)
        return out

    def partial_torques(self, refs: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Cumulative task torques Γ_{≤1}, …, Γ_{≤L} for per-level references."""
        tau = np.zeros(self.F.shape[1] if self.F.size else self.W.shape[0])
        out = []
        for i, ref in enumerate(refs):
            tau = self.level_step(i, tau, ref)
            out.append(tau)
        return out

    def torque(
        self, refs: Sequence[np.ndarray], f_internal: np.ndarray | None = None
    ) -> np.ndarray:
        """TO-OSF eq. (7): task torques plus the distribution torque of an internal wrench (c,)."""
        partial = self.partial_torques(refs)
        tau = partial[-1] if partial else np.zeros(self.W.shape[0])
        if f_internal is not None and self.Yw.size:
            tau = tau + self.Yw @ f_internal
        return tau

    # -- flat storage for the shared-memory parameter server ---------------------------------

    def arrays(self) -> list[np.ndarray]:
        """Every array, in a fixed order (see :meth:`from_arrays`)."""
        out: list[np.ndarray] = []
        for lv in self.levels:
            out.extend(getattr(lv, f.name) for f in fields(LevelParams))
        out.extend(getattr(self, name) for name in _FLAT_FIELDS)
        return out

    def from_arrays(
        self, arrays: Sequence[np.ndarray], tick: int, compute_time: float
    ) -> OsfParams:
        """A new set with this one's structure and the given arrays (as :meth:`arrays` orders)."""
        it = iter(arrays)
        levels = [
            LevelParams(**{f.name: next(it) for f in fields(LevelParams)}) for _ in self.levels
        ]
        flat = {name: next(it) for name in _FLAT_FIELDS}
        return OsfParams(
            levels=levels, coupling=self.coupling, tick=tick, compute_time=compute_time, **flat
        )


_FLAT_FIELDS = ("Phi_a", "qdd0", "F", "f0", "W", "Nw", "Yc", "Qf", "Yw", "G", "K", "gamma0")


@dataclass
class OsfModel:
    """Computes :class:`OsfParams` for a fixed set of levels and contacts.

    Attributes:
        levels: the tasks of each priority level, highest first.
        frames: the contacts: frame names (flat, 6 rows each) or contacts (3 rows per point of
            a point set).
        kinds: ``acceleration`` or ``force`` per level.
        inverse: ``cod`` | ``svd`` | ``pinv``.
        coupling: ``exact`` | ``literal``.
        rcond: relative rank threshold of the decompositions.
        affine: also compute Γ = K ρ + γ₀ over all levels (for TO-OSF's single QP).
    """

    levels: list[list[Task]]
    frames: Sequence[str | PlaneContact]
    kinds: list[str] = field(default_factory=list)
    inverse: str = "cod"
    coupling: str = "exact"
    rcond: float = 1e-9
    affine: bool = False

    def __post_init__(self) -> None:
        if not self.kinds:
            self.kinds = ["acceleration"] * len(self.levels)
        if self.inverse not in INVERSES:
            raise ControllerError(
                f"unknown inverse {self.inverse!r}; valid choices: {', '.join(INVERSES)}"
            )
        if self.coupling not in COUPLINGS:
            raise ControllerError(
                f"unknown coupling {self.coupling!r}; valid choices: {', '.join(COUPLINGS)}"
            )

    def params(
        self,
        state: RobotState,
        jacobians: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
        tick: int = 0,
    ) -> OsfParams:
        """All parameters at ``state``; ``jacobians`` (J, J̇q̇ per level) when already evaluated.

        ``compute_time`` excludes the Pinocchio passes (they count as the ``dynamics`` stage).
        """
        t0 = time.perf_counter()
        dyn0 = state.compute_time
        if jacobians is None:
            jacobians = [self.level_jacobian(state, tasks) for tasks in self.levels]
        cd = contact_dynamics(state, self.frames)
        k = state.k
        Ybar, Nw = dynamically_consistent_inverse(cd, state.M, self.inverse, self.rcond)
        W = cd.W
        Phi_a = cd.Phi[:, 6:]
        Minv = state.Minv
        levels: list[LevelParams] = []
        N: np.ndarray | None = None
        for i, (J, drift) in enumerate(jacobians):
            Jhat = J @ Phi_a
            bias = J @ cd.qdd0 + drift
            Js = J @ Ybar
            a = Js if N is None else Js @ N
            X = a @ W @ a.T
            # the task's inverse inertia without contacts or levels above, J M⁻¹ Jᵀ, sets the
            # scale its rank is judged against (a task the contacts fix entirely has X ≈ 0)
            scale = float(np.max(np.einsum("ij,ij->i", J @ Minv, J), initial=0.0))
            Lam, _ = psd_pinv(
                0.5 * (X + X.T), "svd" if self.inverse == "svd" else "cod", self.rcond, scale
            )
            B = a.T @ Lam
            E = B if self.kinds[i] == "acceleration" else a.T
            levels.append(LevelParams(Jhat, bias, a, Lam, B, E))
            if i + 1 < len(jacobians):
                Jbar = W @ B
                N = np.eye(k) - Jbar @ a if N is None else N - (N @ Jbar) @ a
        Yc, Qf = self._distribution(cd.F, Nw)
        Jc = state.contact_jacobian(self.frames)
        G = Jc[:, :6].T.copy()
        p = OsfParams(
            levels=levels,
            Phi_a=Phi_a.copy(),
            qdd0=cd.qdd0,
            F=cd.F,
            f0=cd.f0,
            W=W.copy(),
            Nw=Nw,
            Yc=Yc,
            Qf=Qf,
            Yw=Yc @ Qf.T,
            G=G,
            K=np.zeros((k, 0)),
            gamma0=np.zeros(k),
            coupling=self.coupling,
            tick=tick,
        )
        if self.affine:
            p.K, p.gamma0 = affine_torque(p)
        p.compute_time = time.perf_counter() - t0 - (state.compute_time - dyn0)
        return p

    @staticmethod
    def level_jacobian(state: RobotState, tasks: list[Task]) -> tuple[np.ndarray, np.ndarray]:
        """Stacked Jacobian and drift of one level's tasks."""
        parts = [task_jacobian(t, state) for t in tasks]
        return np.vstack([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    @staticmethod
    def _distribution(F: np.ndarray, Nw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Y_c with F Y_c = Q_f orthonormal: F N_w = Q_f R_f, Y_c = N_w R_f⁻¹."""
        p = Nw.shape[1]
        if p == 0:
            return np.zeros((Nw.shape[0], 0)), np.zeros((F.shape[0], 0))
        Qf, Rf = np.linalg.qr(F @ Nw)
        Yc = tri_solve(Rf, Nw.T, trans=True).T
        return Yc, Qf


def affine_torque(p: OsfParams) -> tuple[np.ndarray, np.ndarray]:
    """Γ = K ρ + γ₀ with ρ the stacked level references (TO-OSF eq. 12 as one affine map)."""
    k = p.W.shape[0]
    dims = [lv.dim for lv in p.levels]
    K = np.zeros((k, sum(dims)))
    gamma0 = np.zeros(k)
    col = 0
    for lv, m in zip(p.levels, dims, strict=True):
        if p.coupling == "exact" and col:
            K[:, :col] -= lv.B @ (lv.Jhat @ K[:, :col])
            gamma0 -= lv.B @ (lv.Jhat @ gamma0)
        K[:, col : col + m] = lv.E
        gamma0 -= lv.B @ lv.bias
        col += m
    return K, gamma0


def group_levels(tasks: Sequence[Task]) -> list[list[Task]]:
    """Tasks grouped by priority, highest priority (lowest number) first."""
    out: dict[int, list[Task]] = {}
    for t in sorted(tasks, key=lambda t: t.priority):
        out.setdefault(t.priority, []).append(t)
    return list(out.values())


def level_kinds(levels: Sequence[Sequence[Task]]) -> list[str]:
    """``acceleration`` or ``force`` per level; a level may not mix the two (OSF-HQP eq. 31)."""
    kinds = []
    for tasks in levels:
        found = {t.level for t in tasks}
        if len(found) > 1:
            names = ", ".join(f"{t.name} ({t.level})" for t in tasks)
            raise ControllerError(
                f"priority {tasks[0].priority} mixes acceleration- and force-level tasks "
                f"({names}); give them different priorities"
            )
        kinds.append(found.pop())
    return kinds
