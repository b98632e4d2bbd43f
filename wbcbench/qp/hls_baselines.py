"""Equality-only baselines for the hierarchical least-squares solver, and the size sweep.

Two references the RQR-HQP paper compares its reduced QR method against (§II-D, Fig. 1):

* the classical task-priority algorithm with SVD pseudo-inverses and null-space projectors
  (eq. 5–6): ``x_i = x_{i-1} + (A_i P_{i-1})⁺ (b_i - A_i x_{i-1})``,
  ``P_i = P_{i-1} - (A_i P_{i-1})⁺ (A_i P_{i-1})``;
* a QR algorithm that keeps every level in full coordinates: at each level a full-size QR of
  the stacked constraints above it gives an n × n projector, and the level is solved in all n
  variables.

Both return the same minimum-norm hierarchical solution as ``solve_hls`` (undamped, or damped
with the same ``k``), with the same result type. ``scaling_series`` times the three against the
problem size N, in Python and natively (:mod:`wbcbench.qp.hls_native`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import scipy.linalg as sla

from wbcbench import _native
from wbcbench.errors import SolverError, UnknownNameError, WbcBenchError
from wbcbench.qp.hls import (
    Array,
    HlsResult,
    Level,
    LevelStats,
    level_dampings,
    min_norm_lsq,
    pivoted_qr,
    solve_hls,
    start_point,
)


def equality_tasks(levels: Sequence[Level]) -> list[tuple[Array, Array]]:
    """(A, b) of every level; the baselines have no inequality handling."""
    tasks = []
    for i, lv in enumerate(levels):
        if lv.C is not None or lv.A is None or lv.b is None:
            raise WbcBenchError(
                f"level {lv.name or i}: the SVD / full-QR baselines take equality-only levels"
            )
        tasks.append((lv.A, lv.b))
    return tasks


def _stats(name: str, t0: float, A: Array, b: Array, x: Array, rank: int, left: int) -> LevelStats:
    return LevelStats(
        name=name,
        time=time.perf_counter() - t0,
        iterations=0,
        n_active=0,
        n_saturated=0,
        residual=float(np.linalg.norm(A @ x - b)),
        violation=0.0,
        rank=rank,
        dof_left=left,
        x=x.copy(),
    )


def solve_svd_hierarchy(
    levels: Sequence[Level],
    *,
    damping: float | Sequence[float] | None = None,
    x0: Array | None = None,
    rank_tol: float = 1e-9,
) -> HlsResult:
    """Classical task-priority hierarchy with SVD pseudo-inverses (paper eq. 5–6).

    Undamped, singular values ``<= rank_tol`` are truncated. Damped, the step uses
    ``σ / (σ² + k²)`` on every singular value (damped least squares) while the projector update
    uses the undamped, truncated pseudo-inverse, so the damping does not alter the null space.

    Args:
        levels: equality-only levels in priority order.
        damping: overrides the levels' ``damping``.
        x0: (n,) starting point (zeros by default).
        rank_tol: singular-value threshold.

    Returns:
        Solution and per-level statistics (no iterations or active sets).
    """
    t_start = time.perf_counter()
    tasks, ks = equality_tasks(levels), level_dampings(levels, damping)
    x = start_point(levels, x0)
    n = x.size
    P = np.eye(n)
    stats = []
    dof = n
    for lv, (A, b), k in zip(levels, tasks, ks, strict=True):
        t0 = time.perf_counter()
        M = A @ P
        U, s, Vt = sla.svd(M, full_matrices=False, check_finite=False)
        r = int(np.count_nonzero(s > rank_tol))
        c = U.T @ (b - A @ x)
        if k > 0.0:
            x = x + Vt.T @ (s / (s * s + k * k) * c)
        else:
            x = x + Vt[:r].T @ (c[:r] / s[:r])
        P = P - Vt[:r].T @ Vt[:r]
        dof -= r
        stats.append(_stats(lv.name, t0, A, b, x, r, dof))
    return HlsResult(x, stats, time.perf_counter() - t_start)


def solve_fullqr_hierarchy(
    levels: Sequence[Level],
    *,
    damping: float | Sequence[float] | None = None,
    x0: Array | None = None,
    rank_tol: float = 1e-9,
) -> HlsResult:
    """Task-priority hierarchy by QR in full coordinates (no reduction of the variable).

    Level i factorises the stacked ``[A_1; ...; A_{i-1}]ᵀ`` (n × m_1+...+m_{i-1}, full n × n
    orthogonal factor), forms the projector ``P = Z Zᵀ`` on its null space and solves
    ``min ||A_i P d - (b_i - A_i x)||`` (+ ``k² ||d||²``) in all n variables.

    Args:
        levels: equality-only levels in priority order.
        damping: overrides the levels' ``damping``.
        x0: (n,) starting point (zeros by default).
        rank_tol: ``|R_ii|`` threshold.

    Returns:
        Solution and per-level statistics (no iterations or active sets).
    """
    t_start = time.perf_counter()
    tasks, ks = equality_tasks(levels), level_dampings(levels, damping)
    x = start_point(levels, x0)
    n = x.size
    stacked = np.zeros((0, n))
    stats = []
    for lv, (A, b), k in zip(levels, tasks, ks, strict=True):
        t0 = time.perf_counter()
        above = pivoted_qr(stacked.T, rank_tol)
        Z = above.apply(np.eye(n), "L")[:, above.rank :]
        P = Z @ Z.T
        d, fac = min_norm_lsq(A @ P, b - A @ x, k, rank_tol)
        x = x + d
        stacked = np.vstack([stacked, A])
        stats.append(_stats(lv.name, t0, A, b, x, fac.rank, n - above.rank - fac.rank))
    return HlsResult(x, stats, time.perf_counter() - t_start)


Solver = Callable[..., HlsResult]

#: The three hierarchy algorithms, by the names used in benchmark tables.
ALGORITHMS: dict[str, Solver] = {
    "reduced_qr": solve_hls,
    "full_qr": solve_fullqr_hierarchy,
    "svd": solve_svd_hierarchy,
}


#: the implementations of the algorithms: the Python reference, the C++ mirror
IMPLS = ("python", "native")


def get_algorithm(name: str, impl: str = "python") -> Solver:
    """Look up a hierarchy algorithm by name, in Python or natively."""
    if name not in ALGORITHMS:
        raise UnknownNameError("hierarchy algorithm", name, ALGORITHMS)
    if impl not in IMPLS:
        raise UnknownNameError("impl", impl, IMPLS)
    if impl == "native":
        from wbcbench.qp.hls_native import NATIVE_ALGORITHMS

        return NATIVE_ALGORITHMS[name]
    return ALGORITHMS[name]


def default_impls() -> tuple[str, ...]:
    """Both impls where the native module is built, else the Python one."""
    return IMPLS if _native.BUILT else ("python",)


def fig1_stack(n: int, n_levels: int = 4, fill: float = 0.8, seed: int = 0) -> list[Level]:
    """A fixed-shape random stack for the size sweep (the paper's Fig. 1 setting).

    ``n_levels`` equality levels of ``round(fill n / n_levels)`` rows each, Gaussian entries, so
    the levels together use ``fill`` of the n variables whatever n is.

    Args:
        n: number of variables N.
        n_levels: number of levels.
        fill: fraction of the variables the stack constrains, in (0, 1].
        seed: random seed.

    Returns:
        The levels, highest priority first.
    """
    rng = np.random.default_rng(seed)
    m = max(1, round(fill * n / n_levels))
    return [
        Level(rng.standard_normal((m, n)), rng.standard_normal(m), name=f"L{i + 1}")
        for i in range(n_levels)
    ]


Timed = Callable[[], tuple[float, float, Array]]


def timed_call(name: str, impl: str, levels: Sequence[Level]) -> Timed:
    """One timed solve of ``levels`` by algorithm ``name`` in ``impl``: ``(time, call, x)``.

    Python: ``time`` and ``call`` are the wall time of the function call. Native: the stack is
    copied into a native solver once, here; ``time`` is the solve measured inside the module and
    ``call`` the wall time of the call from Python (the crossing included, not the conversion of
    the result).
    """
    fn = get_algorithm(name, impl)
    if impl == "python":

        def call() -> tuple[float, float, Array]:
            t0 = time.perf_counter()
            x = fn(levels).x
            dt = time.perf_counter() - t0
            return dt, dt, x

        return call
    from wbcbench.qp.hls_native import NativeHls

    solver = NativeHls()
    solver.load(levels)
    core = solver.solver

    def call_native() -> tuple[float, float, Array]:
        t0 = time.perf_counter()
        ok = solver.run(name)
        wall = time.perf_counter() - t0
        if not ok:
            raise SolverError(core.message)
        return float(core.time), wall, np.array(core.x)

    return call_native


def scaling_series(
    sizes: Sequence[int],
    repeats: int = 50,
    *,
    n_levels: int = 4,
    fill: float = 0.8,
    seed: int = 0,
    algorithms: Sequence[str] = tuple(ALGORITHMS),
    impls: Sequence[str] | None = None,
) -> list[dict[str, Any]]:
    """Median solve time of each algorithm against the problem size N (paper Fig. 1).

    Protocol: one stack per N (``fig1_stack``), one discarded warm-up call per algorithm and
    impl, then ``repeats`` rounds that call every algorithm in every impl once in turn, so slow
    drifts of the machine affect all of them alike. The native times are measured inside the
    module (see :func:`timed_call`).

    Args:
        sizes: values of N.
        repeats: timed calls per algorithm and N.
        n_levels: levels in the stack.
        fill: fraction of the variables the stack constrains.
        seed: random seed of the stacks.
        algorithms: names from ``ALGORITHMS``.
        impls: names from ``IMPLS``; default: :func:`default_impls`.

    Returns:
        One row per (N, algorithm, impl): ``N``, ``algorithm``, ``impl``, ``median_s``,
        ``p25_s``, ``p75_s``, ``call_median_s`` (the wall time of the call from Python),
        ``repeats``, ``max_abs_diff`` (largest deviation of x from the Python ``reduced_qr``
        solution).
    """
    impls = tuple(impls) if impls is not None else default_impls()
    keys = [(name, impl) for impl in impls for name in algorithms]
    rows: list[dict[str, Any]] = []
    for n in sizes:
        levels = fig1_stack(n, n_levels, fill, seed)
        ref = solve_hls(levels).x
        calls = {key: timed_call(*key, levels) for key in keys}
        xs = {key: call()[2] for key, call in calls.items()}  # warm-up
        times: dict[tuple[str, str], list[tuple[float, float]]] = {key: [] for key in keys}
        for _ in range(repeats):
            for key, call in calls.items():
                dt, wall, xs[key] = call()
                times[key].append((dt, wall))
        for key in keys:
            t = np.asarray(times[key])
            rows.append(
                {
                    "N": int(n),
                    "algorithm": key[0],
                    "impl": key[1],
                    "median_s": float(np.median(t[:, 0])),
                    "p25_s": float(np.percentile(t[:, 0], 25)),
                    "p75_s": float(np.percentile(t[:, 0], 75)),
                    "call_median_s": float(np.median(t[:, 1])),
                    "repeats": int(repeats),
                    "max_abs_diff": float(np.abs(xs[key] - ref).max()),
                }
            )
    return rows
