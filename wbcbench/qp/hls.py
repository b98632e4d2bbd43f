"""Hierarchical least squares with regularised QR in reduced coordinates.

The method of the RQR-HQP paper (regularised QR for prioritised kinematic control): a stack
of levels is solved one after the other, each level in the
null-space basis ``Z`` of everything the levels above it fixed (§II-B),

    x = x_prev + Z y,    Z = null([A_1; C_sat,1; ...; A_{i-1}; C_sat,i-1]),

with ``Z`` obtained from column-pivoted Householder QR of the stacked transposed constraints and
updated level by level (the orthogonal factor is applied to ``Z``, never formed). Each level may
be damped (Tikhonov, §II-C): its step minimises ``||A Z y - b'||² + k² ||y||²``, but the basis
passed to the next level comes from the non-regularised factorisation, so the damping never
shrinks the null space. Inequalities ``l <= C x <= u`` are handled by a primal active-set method
per level that starts from the previous level's solution (§III-B); the inequalities saturated at
the end of a level (positive multiplier) become equalities for all following levels, the others
stay inequalities.

A level whose inequalities cannot be met inside the set left by the levels above first minimises
their violation (a least-squares slack ``w``); the violated rows are then held at their least
violation for the rest of the level and for the levels below.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray
from scipy.linalg import lapack

from wbcbench.errors import SolverError, WbcBenchError

Array = NDArray[np.float64]

# LAPACK block size used to size work arrays; 64 covers the optimal block of common BLAS builds.
_NB = 64


# --------------------------------------------------------------------------------------------
# Public data
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Level:
    """One priority level: ``A x = b`` in the least-squares sense, subject to ``l <= C x <= u``.

    Either part may be absent. ``l``/``u`` may hold ``±inf`` for one-sided rows; a missing ``l``
    or ``u`` means no bound on that side.

    Attributes:
        A: (m, n) task matrix, or None.
        b: (m,) task target, or None (zeros if ``A`` is given).
        C: (mc, n) inequality matrix, or None.
        l: (mc,) lower bounds, or None.
        u: (mc,) upper bounds, or None.
        name: label used in results and error messages.
        damping: Tikhonov factor ``k >= 0`` of the level (0: undamped).
    """

    A: Array | None = None
    b: Array | None = None
    C: Array | None = None
    l: Array | None = None  # noqa: E741 -- the paper's symbol for the lower bound
    u: Array | None = None
    name: str = ""
    damping: float = 0.0

    def __post_init__(self) -> None:
        label = self.name or "<unnamed>"
        if self.A is None and self.C is None:
            raise WbcBenchError(f"level {label}: needs A (task) or C (inequalities)")
        if self.A is not None:
            A = _as_matrix(self.A, f"level {label}: A")
            b = np.zeros(A.shape[0]) if self.b is None else _as_vector(self.b, A.shape[0], "b")
            object.__setattr__(self, "A", A)
            object.__setattr__(self, "b", b)
        elif self.b is not None:
            raise WbcBenchError(f"level {label}: b given without A")
        if self.C is not None:
            C = _as_matrix(self.C, f"level {label}: C")
            mc = C.shape[0]
            lo = np.full(mc, -np.inf) if self.l is None else _as_vector(self.l, mc, "l")
            hi = np.full(mc, np.inf) if self.u is None else _as_vector(self.u, mc, "u")
            if np.any(lo > hi):
                raise WbcBenchError(f"level {label}: l > u in rows {np.flatnonzero(lo > hi)}")
            object.__setattr__(self, "C", C)
            object.__setattr__(self, "l", lo)
            object.__setattr__(self, "u", hi)
        elif self.l is not None or self.u is not None:
            raise WbcBenchError(f"level {label}: bounds given without C")
        if self.A is not None and self.C is not None and self.A.shape[1] != self.C.shape[1]:
            raise WbcBenchError(f"level {label}: A and C have different column counts")
        if not self.damping >= 0.0:
            raise WbcBenchError(f"level {label}: damping must be >= 0, got {self.damping}")

    @property
    def n(self) -> int:
        """Number of variables (columns)."""
        M = self.A if self.A is not None else self.C
        assert M is not None
        return int(M.shape[1])


@dataclass(frozen=True)
class LevelStats:
    """What one level did.

    Attributes:
        name: the level's name.
        time: wall time of the level [s].
        iterations: active-set iterations (0 for a level solved in closed form).
        n_active: inequality rows active at the level's solution (working set, including rows
            held at their least violation).
        n_saturated: of those, rows turned into equalities for the following levels.
        residual: ``||A x - b||`` at the level's solution (0 without a task).
        violation: ``||w||``, least violation of the level's own inequalities (0 if feasible).
        rank: degrees of freedom the level fixed (task rank plus saturated rows).
        dof_left: dimension of the null space passed to the next level.
        x: (n,) solution after this level.
    """

    name: str
    time: float
    iterations: int
    n_active: int
    n_saturated: int
    residual: float
    violation: float
    rank: int
    dof_left: int
    x: Array = field(repr=False)


@dataclass(frozen=True)
class HlsResult:
    """Solution of a hierarchy.

    Attributes:
        x: (n,) solution after the last level.
        levels: per-level statistics, in priority order.
        time: total wall time [s].
    """

    x: Array
    levels: list[LevelStats]
    time: float


# --------------------------------------------------------------------------------------------
# Column-pivoted Householder QR, kept in LAPACK's compact form
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PivotedQR:
    """``M[:, piv] = Q R`` of a (q, m) matrix, Q held as Householder reflectors.

    Attributes:
        h: (q, m) LAPACK ``geqp3`` output (R above the diagonal, reflectors below).
        tau: (min(q, m),) reflector factors.
        piv: (m,) 0-based column permutation.
        rank: number of ``|R_ii|`` above the rank tolerance.
    """

    h: Array
    tau: Array
    piv: NDArray[np.intp]
    rank: int

    @property
    def rows(self) -> int:
        """q, the dimension Q acts on."""
        return int(self.h.shape[0])

    def r(self, k: int) -> Array:
        """(k, m) leading rows of R."""
        return np.triu(self.h[:k, :])

    def apply(self, c: Array, side: str, trans: str = "N") -> Array:
        """``Q c`` / ``Qᵀ c`` (side "L", c is (q, ·)) or ``c Q`` / ``c Qᵀ`` (side "R", (·, q))."""
        if self.tau.size == 0 or c.size == 0:
            return np.array(c, dtype=float, order="F")
        k = self.tau.size
        dim = c.shape[1] if side == "L" else c.shape[0]
        out, _, info = lapack.dormqr(
            side, trans, self.h[:, :k], self.tau, c, lwork=max(1, _NB * dim)
        )
        if info != 0:  # only reachable through a programming error in the arguments
            raise SolverError(f"LAPACK dormqr failed with info={info}")
        return np.asarray(out)

    def null_basis(self, Z: Array) -> Array:
        """(n, q - rank) ``Z Q[:, rank:]``: ``Z`` restricted to the null space of ``Mᵀ``."""
        return self.apply(Z, "R")[:, self.rank :]


def pivoted_qr(M: Array, rank_tol: float) -> PivotedQR:
    """Column-pivoted Householder QR of ``M`` (q, m) with rank ``#{|R_ii| > rank_tol}``."""
    q, m = M.shape
    if q == 0 or m == 0:
        return PivotedQR(np.zeros((q, m), order="F"), np.zeros(0), np.arange(m), 0)
    h, jpvt, tau, _, info = lapack.dgeqp3(M, lwork=max(3 * m + 1, 2 * m + (m + 1) * _NB))
    if info != 0:
        raise SolverError(f"LAPACK dgeqp3 failed with info={info}")
    # Pivoting makes |R_ii| non-increasing, so counting is the same as finding the first drop.
    rank = int(np.count_nonzero(np.abs(np.diagonal(h)) > rank_tol))
    return PivotedQR(h, tau, jpvt - 1, rank)


def _triangular_solve(R: Array, rhs: Array, trans: int = 0) -> Array:
    """``R⁻¹ rhs`` (trans 0) or ``R⁻ᵀ rhs`` (trans 1), reading only the upper triangle of ``R``.

    LAPACK ``trtrs`` directly: the scipy wrapper's checks cost more than the solve at these sizes.
    """
    sol, info = lapack.dtrtrs(R, rhs, lower=0, trans=trans)
    if info != 0:
        raise SolverError(f"singular triangular factor (LAPACK dtrtrs info={info})")
    return np.asarray(sol)


def ls_coefficients(fac: PivotedQR, r: Array, k: float) -> Array:
    """Coefficients ``w`` of the (damped) min-norm least-squares solution ``u = Q[:, :len(w)] w``.

    ``fac`` factorises ``Mᵀ`` for a (m, q) matrix ``M``, so ``M[piv] = Rᵀ Qᵀ``. Undamped, the rank
    truncated ``min ||R_rᵀ w - r[piv]||`` is solved (a triangular solve when the rows of ``M`` are
    independent). Damped, ``min ||Rᵀ w - r[piv]||² + k² ||w||²`` is solved through the QR of the
    small augmented matrix ``[Rᵀ; k I]``: it is the paper's regularised system ``[M; k I]``
    restricted to the row space of ``M``, obtained from the factorisation already at hand.

    Args:
        fac: factorisation of ``Mᵀ`` (q, m).
        r: (m,) right-hand side.
        k: damping factor (0: undamped).

    Returns:
        (rank,) undamped or (min(q, m),) damped coefficients.
    """
    m = r.shape[0]
    rp = r[fac.piv]
    if k == 0.0:
        rr = fac.rank
        if rr == 0:
            return np.zeros(0)
        if rr == m:
            return _triangular_solve(fac.h[:rr, :rr], rp, trans=1)
        R = fac.r(rr)
        # Dependent rows (a conflicting level): a least-squares solve in the rank-r factor.
        Qt, Rt = sla.qr(R.T, mode="economic", check_finite=False)
        return _triangular_solve(Rt, Qt.T @ rp)
    s = fac.tau.size
    if s == 0:
        return np.zeros(0)
    K = np.vstack([fac.r(s).T, k * np.eye(s)])
    Qk, Rk = sla.qr(K, mode="economic", check_finite=False)
    return _triangular_solve(Rk, Qk[:m].T @ rp)


def min_norm_lsq(M: Array, r: Array, k: float, rank_tol: float) -> tuple[Array, PivotedQR]:
    """(Damped) minimum-norm solution of ``M u ≈ r`` and the factorisation of ``Mᵀ``.

    Args:
        M: (m, q) matrix.
        r: (m,) right-hand side.
        k: damping factor (0: undamped).
        rank_tol: rank tolerance on ``|R_ii|``.

    Returns:
        u (q,) and the pivoted QR of ``Mᵀ``.
    """
    fac = pivoted_qr(M.T, rank_tol)
    w = ls_coefficients(fac, r, k)
    pad = np.zeros((M.shape[1], 1))
    pad[: w.size, 0] = w
    return fac.apply(pad, "L")[:, 0], fac


# --------------------------------------------------------------------------------------------
# Primal active set for one least-squares problem with inequalities
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Tolerances:
    rank: float
    feas: float
    max_iter: int | None


@dataclass(frozen=True)
class _ActiveSetResult:
    z: Array  # (q,) solution
    working: NDArray[np.intp]  # indices of the rows in the final working set
    lam: Array  # (len(working),) their multipliers, >= 0 at termination
    saturated: NDArray[np.bool_]  # (len(working),) multiplier clearly positive
    iterations: int


def _face_basis(GW: Array, q: int, tol: float) -> tuple[Array, PivotedQR]:
    """(q, q - |W|) orthonormal basis of the null space of the working rows, and their QR."""
    fac = pivoted_qr(GW.T, tol)
    return fac.apply(np.eye(q), "L")[:, fac.rank :], fac


def _multipliers(fac: PivotedQR, grad: Array) -> Array:
    """Solve ``G_Wᵀ λ = -grad`` by the QR of ``G_Wᵀ`` (rows are independent by construction)."""
    nw = fac.piv.size
    rhs = fac.apply(-grad[:, None], "L", "T")[:nw, 0]
    lam = np.empty(nw)
    lam[fac.piv] = _triangular_solve(fac.h[:nw, :nw], rhs)
    return lam


def active_set_lsq(
    F: Array, g: Array, k: float, G: Array, h: Array, z0: Array, tol: _Tolerances
) -> _ActiveSetResult:
    """Primal active set for ``min ½||F z - g||² + ½k²||z||²  s.t.  G z <= h`` from feasible ``z0``.

    Each iteration restricts the least-squares problem to the face of the working set (null
    space of its rows, by QR), steps to the face's minimiser, stops at the first blocking row
    (added to the working set) and, at a face minimiser, drops the row with the most negative
    multiplier. Singular objectives are handled by minimum-norm steps.

    Args:
        F: (m, q) objective matrix.
        g: (m,) objective target.
        k: damping factor.
        G: (mi, q) inequality rows.
        h: (mi,) inequality bounds.
        z0: (q,) feasible start.
        tol: rank / feasibility tolerances and the iteration cap.

    Returns:
        Solution, final working set and multipliers, iteration count.

    Raises:
        SolverError: the iteration cap was reached (cycling on a degenerate vertex).
    """
    q = z0.size
    z = z0.copy()
    working: list[int] = []
    max_iter = tol.max_iter or 10 * (q + G.shape[0]) + 10
    fac = pivoted_qr(np.zeros((q, 0)), tol.rank)
    N = np.eye(q)
    for it in range(1, max_iter + 1):
        M = F @ N
        # The damping acts on z + N u; with v = u + Nᵀz it becomes a plain damped problem in v.
        shift = -(N.T @ z) if k > 0.0 else np.zeros(N.shape[1])
        v, _ = min_norm_lsq(M, g - F @ z - M @ shift, k, tol.rank)
        p = N @ (v + shift)
        if np.linalg.norm(p) > 1e-13 * (1.0 + np.linalg.norm(z)):
            Gp = G @ p
            slack = np.maximum(h - G @ z, 0.0)
            blocking = Gp > 1e-12 * (1.0 + np.abs(G).sum(axis=1) * np.linalg.norm(p))
            blocking[working] = False
            alpha, j = 1.0, -1
            if blocking.any():
                ratios = slack[blocking] / Gp[blocking]
                i = int(np.argmin(ratios))
                if ratios[i] < 1.0:
                    alpha, j = float(ratios[i]), int(np.flatnonzero(blocking)[i])
            z = z + alpha * p
            if j >= 0:
                working.append(j)
                N, fac = _face_basis(G[working], q, tol.rank)
                continue
        # At the minimiser of the current face: optimal unless a multiplier has the wrong sign.
        if not working:
            none = np.zeros(0, dtype=np.intp)
            return _ActiveSetResult(z, none, np.zeros(0), none.astype(bool), it)
        grad = F.T @ (F @ z - g) + k * k * z
        lam = _multipliers(fac, grad)
        worst = int(np.argmin(lam))
        lam_tol = 1e-10 * (1.0 + np.abs(grad).max())
        if lam[worst] >= -lam_tol:
            W = np.asarray(working, dtype=np.intp)
            return _ActiveSetResult(z, W, lam, lam > lam_tol, it)
        working.pop(worst)
        N, fac = _face_basis(G[working], q, tol.rank)
    raise SolverError(f"active set did not converge in {max_iter} iterations")


# --------------------------------------------------------------------------------------------
# The hierarchy
# --------------------------------------------------------------------------------------------


@dataclass
class _State:
    """What the levels above hand down: point, null-space basis, inequalities still free."""

    x: Array  # (n,)
    Z: Array  # (n, p)
    G: Array  # (mi, n) one-sided rows G x <= h
    h: Array  # (mi,)


@dataclass(frozen=True)
class _LevelOutcome:
    iterations: int
    n_active: int
    n_saturated: int
    violation: float


def _one_sided(C: Array, lo: Array, hi: Array) -> tuple[Array, Array]:
    """``l <= C x <= u`` as ``G x <= h`` rows, dropping infinite sides. Shapes (mi, n), (mi,)."""
    up, dn = np.isfinite(hi), np.isfinite(lo)
    return np.vstack([C[up], -C[dn]]), np.concatenate([hi[up], -lo[dn]])


def _task(level: Level, n: int) -> tuple[Array, Array]:
    """(m, n) task matrix and (m,) target; empty for an inequality-only level."""
    if level.A is None or level.b is None:
        return np.zeros((0, n)), np.zeros(0)
    return level.A, level.b


def _equality_level(st: _State, A: Array, b: Array, k: float, rank_tol: float) -> int:
    """Closed-form level (§II-B/C). Updates ``st`` in place; returns the rank used."""
    p = st.Z.shape[1]
    if p == 0 or A.shape[0] == 0:
        return 0
    F = A @ st.Z
    fac = pivoted_qr(F.T, rank_tol)
    w = ls_coefficients(fac, b - A @ st.x, k)
    # One application of Q to Z gives both the step (leading columns) and the next basis.
    ZQ = fac.apply(st.Z, "R")
    st.x = st.x + ZQ[:, : w.size] @ w
    st.Z = ZQ[:, fac.rank :]
    return fac.rank


def _least_violation(
    st: _State, C: Array, lo: Array, hi: Array, tol: _Tolerances
) -> tuple[Array, Array, int]:
    """Phase 1: ``min ||w||²  s.t.  l <= C (x + Z y) - w <= u``, earlier inequalities kept.

    Returns:
        y (p,), w (mc,), active-set iterations.
    """
    p, mc = st.Z.shape[1], C.shape[0]
    CZ, Cx = C @ st.Z, C @ st.x
    up, dn = np.isfinite(hi), np.isfinite(lo)
    Gz = st.G @ st.Z
    G = np.block(
        [
            [CZ[up], -np.eye(mc)[up]],
            [-CZ[dn], np.eye(mc)[dn]],
            [Gz, np.zeros((Gz.shape[0], mc))],
        ]
    )
    h = np.concatenate([(hi - Cx)[up], (Cx - lo)[dn], st.h - st.G @ st.x])
    F = np.hstack([np.zeros((mc, p)), np.eye(mc)])
    w0 = Cx - np.clip(Cx, lo, hi)
    res = active_set_lsq(F, np.zeros(mc), 0.0, G, h, np.concatenate([np.zeros(p), w0]), tol)
    return res.z[:p], res.z[p:], res.iterations


def _inequality_level(
    st: _State, A: Array, b: Array, level: Level, k: float, tol: _Tolerances
) -> tuple[int, _LevelOutcome]:
    """Level with inequalities (its own or inherited), §III-B. Updates ``st``; returns rank."""
    n, p_in = st.x.size, st.Z.shape[1]
    iterations, violation, n_held = 0, 0.0, 0
    Gown, hown = np.zeros((0, n)), np.zeros(0)
    if level.C is not None:
        assert level.l is not None and level.u is not None
        C, lo, hi = level.C, level.l, level.u
        Cx = C @ st.x
        if np.any(Cx - hi > tol.feas) or np.any(lo - Cx > tol.feas):
            y, w, it = _least_violation(st, C, lo, hi, tol)
            iterations += it
            st.x = st.x + st.Z @ y
            violation = float(np.linalg.norm(w))
            held = np.abs(w) > tol.feas
            n_held = int(held.sum())
            # Rows held at their least violation are equalities from here on (§III-B).
            fac = pivoted_qr((C[held] @ st.Z).T, tol.rank)
            st.Z = fac.null_basis(st.Z)
            lo, hi = lo + np.minimum(w, 0.0), hi + np.maximum(w, 0.0)
            C, lo, hi = C[~held], lo[~held], hi[~held]
        Gown, hown = _one_sided(C, lo, hi)
    G, h = np.vstack([st.G, Gown]), np.concatenate([st.h, hown])
    Gz, F = G @ st.Z, A @ st.Z
    res = active_set_lsq(F, b - A @ st.x, k, Gz, h - G @ st.x, np.zeros(st.Z.shape[1]), tol)
    st.x = st.x + st.Z @ res.z
    sat = res.working[res.saturated]
    # Non-regularised factorisation of [C_sat; A] in reduced coordinates gives the next basis.
    fac = pivoted_qr(np.vstack([Gz[sat], F]).T, tol.rank)
    st.Z = fac.null_basis(st.Z)
    keep = np.ones(G.shape[0], dtype=bool)
    keep[sat] = False
    st.G, st.h = G[keep], h[keep]
    outcome = _LevelOutcome(
        iterations + res.iterations, res.working.size + n_held, sat.size + n_held, violation
    )
    return p_in - st.Z.shape[1], outcome


def _n_vars(levels: Sequence[Level]) -> int:
    if not levels:
        raise WbcBenchError("empty hierarchy: give at least one level")
    sizes = {lv.n for lv in levels}
    if len(sizes) != 1:
        raise WbcBenchError(f"levels disagree on the number of variables: {sorted(sizes)}")
    return sizes.pop()


def level_dampings(levels: Sequence[Level], damping: float | Sequence[float] | None) -> list[float]:
    """Per-level damping: each level's own, or one value / one per level overriding them."""
    if damping is None:
        return [lv.damping for lv in levels]
    if isinstance(damping, int | float):
        return [float(damping)] * len(levels)
    ks = [float(k) for k in damping]
    if len(ks) != len(levels):
        raise WbcBenchError(f"{len(ks)} damping values for {len(levels)} levels")
    return ks


def start_point(levels: Sequence[Level], x0: Array | None) -> Array:
    """(n,) starting point: ``x0`` or zeros."""
    n = _n_vars(levels)
    if x0 is None:
        return np.zeros(n)
    return _as_vector(x0, n, "x0")


def solve_hls(
    levels: Sequence[Level],
    *,
    damping: float | Sequence[float] | None = None,
    x0: Array | None = None,
    rank_tol: float = 1e-9,
    feas_tol: float = 1e-9,
    max_iter: int | None = None,
) -> HlsResult:
    """Solve a hierarchy of least-squares levels with the reduced, regularised QR method.

    Args:
        levels: levels in priority order (highest first), all with n columns.
        damping: overrides the levels' ``damping`` (one value, or one per level).
        x0: (n,) point the minimum-norm steps are measured from; zeros by default.
        rank_tol: ``|R_ii|`` below this counts as rank loss.
        feas_tol: inequality violation tolerated before the least-violation phase runs.
        max_iter: active-set iteration cap per problem (default ``10 (q + rows) + 10``).

    Returns:
        The solution and per-level statistics.

    Raises:
        WbcBenchError: inconsistent level sizes.
        SolverError: an active set did not converge.
    """
    t_start = time.perf_counter()
    ks = level_dampings(levels, damping)
    x = start_point(levels, x0)
    n = x.size
    st = _State(x, np.eye(n), np.zeros((0, n)), np.zeros(0))
    tol = _Tolerances(rank_tol, feas_tol, max_iter)
    stats: list[LevelStats] = []
    for level, k in zip(levels, ks, strict=True):
        t0 = time.perf_counter()
        A, b = _task(level, n)
        if level.C is None and st.G.shape[0] == 0:
            rank = _equality_level(st, A, b, k, rank_tol)
            out = _LevelOutcome(0, 0, 0, 0.0)
        else:
            rank, out = _inequality_level(st, A, b, level, k, tol)
        elapsed = time.perf_counter() - t0
        stats.append(
            LevelStats(
                name=level.name,
                time=elapsed,
                iterations=out.iterations,
                n_active=out.n_active,
                n_saturated=out.n_saturated,
                residual=float(np.linalg.norm(A @ st.x - b)),
                violation=out.violation,
                rank=rank,
                dof_left=st.Z.shape[1],
                x=st.x.copy(),
            )
        )
    return HlsResult(st.x, stats, time.perf_counter() - t_start)


# --------------------------------------------------------------------------------------------
# Input helpers
# --------------------------------------------------------------------------------------------


def _as_matrix(M: object, what: str) -> Array:
    arr = np.asarray(M, dtype=float)
    if arr.ndim != 2:
        raise WbcBenchError(f"{what} must be a 2-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise WbcBenchError(f"{what} contains non-finite entries")
    return arr


def _as_vector(v: object, size: int, what: str) -> Array:
    arr = np.asarray(v, dtype=float).reshape(-1)
    if arr.size != size:
        raise WbcBenchError(f"{what} must have {size} entries, got {arr.size}")
    return arr
