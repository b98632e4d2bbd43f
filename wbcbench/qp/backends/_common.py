"""Conversions several backends share: one-sided row splits, fixed sparsity patterns and the
shift that makes a Hessian positive definite."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from wbcbench.qp.settings import TIER_EPS

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]
Index = NDArray[np.intp]


#: Relative size of the diagonal shift :func:`positive_definite` starts from.
REGULARISATION = 1e-12


def positive_definite(H: Array, delta_rel: float = REGULARISATION) -> tuple[Array, float]:
    """``(H + δI, δ)`` for the backends that need a positive definite Hessian (Goldfarb–Idnani's
    dual methods start from ``H``'s Cholesky factor): ``δ = 0`` when ``H`` is already PD, else
    ``δ = delta_rel · max(1, max |H_ii|)`` multiplied by 100 until the factorisation succeeds
    (eight tries at most)."""
    try:
        np.linalg.cholesky(H)
        return H, 0.0
    except np.linalg.LinAlgError:
        pass
    scale = max(1.0, float(np.max(np.abs(np.diag(H)), initial=0.0)))
    delta = delta_rel * scale
    eye = np.eye(H.shape[0])
    for _ in range(8):
        G = H + delta * eye
        try:
            np.linalg.cholesky(G)
            return G, delta
        except np.linalg.LinAlgError:
            delta *= 100.0
    return H + delta * eye, delta


def tier_eps(tier: str) -> float | None:
    """Absolute tolerance of ``tier``, ``None`` for ``default``."""
    return TIER_EPS.get(tier)


def gap_checked_tier_settings(tier: str) -> dict[str, Any]:
    """The tier as absolute primal / dual / duality-gap tolerances, relative ones off (the
    settings ProxQP and PIQP share)."""
    eps = tier_eps(tier)
    if eps is None:
        return {}
    return {
        "eps_abs": eps,
        "eps_rel": 0.0,
        "check_duality_gap": True,
        "eps_duality_gap_abs": eps,
        "eps_duality_gap_rel": 0.0,
    }


def split_rows(C: Array, lower: Array, upper: Array) -> tuple[Array, Array, Index, Index]:
    """Rewrite ``lower ≤ C x ≤ upper`` as ``G x ≤ h`` keeping finite sides only.

    Returns:
        ``(G, h, up, lo)``: ``G = [C[up]; −C[lo]]``, ``h = [upper[up]; −lower[lo]]`` where
        ``up`` and ``lo`` index the rows with a finite upper and lower side.
    """
    up = np.flatnonzero(np.isfinite(upper))
    lo = np.flatnonzero(np.isfinite(lower))
    G = np.vstack([C[up], -C[lo]])
    h = np.concatenate([upper[up], -lower[lo]])
    return G, h, up, lo


def merge_split_duals(zG: Array, up: Index, lo: Index, m: int) -> Array:
    """Duals ``(m,)`` of ``l ≤ Cx ≤ u`` from the ``G x ≤ h`` duals of :func:`split_rows`."""
    z = np.zeros(m)
    z[up] += zG[: up.size]
    z[lo] -= zG[up.size : up.size + lo.size]
    return z


def pattern_csc(M: Array, mask: Mask) -> sp.csc_matrix:
    """CSC matrix of ``M`` whose stored entries are exactly ``mask`` (explicit zeros kept)."""
    m, n = M.shape
    rows = np.nonzero(mask.T)[1]
    data = M.T[mask.T]
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=0))])
    return sp.csc_matrix((data, rows, indptr), shape=(m, n))


def pattern_values(M: Array, mask: Mask) -> Array:
    """Values of ``M`` on ``mask`` in CSC order (column by column, rows ascending)."""
    return np.ascontiguousarray(M.T[mask.T])


def fits(M: Array, mask: Mask) -> bool:
    """True when every nonzero of ``M`` lies on ``mask``."""
    return not bool(np.any((M != 0.0) & ~mask))


def upper_mask(H: Array) -> Mask:
    """Nonzeros of ``triu(H)`` plus the whole diagonal (sparse solvers expect a stored one)."""
    mask = np.triu(H != 0.0)
    np.fill_diagonal(mask, True)
    return mask


def apply_settings(target: Any, options: dict[str, Any], library: str) -> None:
    """Set ``options`` as attributes of a native settings object, rejecting unknown names."""
    for key, value in options.items():
        if not hasattr(target, key):
            raise ValueError(f"{library} has no setting {key!r}")
        setattr(target, key, value)


def fill_buffers(buffers: Any, problem: Any, fields: frozenset[str] | None = None) -> None:
    """Copy ``problem`` (only ``fields`` when given) into native ``QpBuffers`` of its sizes
    (all fields, after sizing the buffers, when ``fields`` is None)."""
    if fields is None:
        buffers.resize(problem.n, problem.n_eq, problem.n_in, problem.has_box)
        fields = frozenset(("H", "g", "A", "b", "C", "l", "u", "lb", "ub"))
    for key in ("H", "g", "A", "b", "C", "l", "u"):
        if key in fields:
            getattr(buffers, key)[...] = getattr(problem, key)
    if problem.has_box and fields & {"lb", "ub"}:
        buffers.lb[...], buffers.ub[...] = problem.box()


def native_solution(
    cpp: Any,
    buffers: Any,
    problem: Any,
    copy_time: float,
    internal: bool = False,
    answer: Any = None,
) -> Any:
    """Solve with a native solver object of the module (``cpp.solve(buffers)``) and read its
    outcome into a :class:`~wbcbench.qp.solution.Solution`.

    ``copy_time`` [s] is the copy into ``buffers``, counted in the set-up time; ``internal``:
    report the object's own timer; ``answer(solution)``: whether x and the duals are read
    (default: when the solve succeeded).
    """
    from wbcbench.qp.solution import Solution, SolutionStatus

    status, iterations, setup, wall, timer, _, rebuilt, message = cpp.solve(buffers)
    sol = Solution(
        status=SolutionStatus(status),
        iterations=None if iterations < 0 else iterations,
        wall_time=wall,
        setup_time=copy_time + setup,
        internal_time=timer if internal else None,
        message=message,
        rebuilt=rebuilt,
    )
    if answer(sol) if answer is not None else sol.success:
        sol.x = np.array(cpp.x)
        sol.y, sol.z = np.array(cpp.y), np.array(cpp.z)
        sol.z_box = np.array(cpp.z_box) if problem.has_box else None
    return sol
