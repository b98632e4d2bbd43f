"""The native hierarchical least squares: the C++ mirror of :mod:`wbcbench.qp.hls` and of the two
baselines of :mod:`wbcbench.qp.hls_baselines` (``wbcbench/_native/src/qp/hls.cpp``).

The same algorithms step for step (column-pivoted Householder QR as LAPACK's ``dgeqp3`` does it,
the orthogonal factor applied and never formed, Tikhonov damping with the basis from the
non-regularised factor, the primal active set per level with the saturated rows carried down,
the least-violation phase) and the same per-level statistics, in buffers the native solver
keeps: solving a stack of the same sizes again allocates nothing.

:class:`NativeHls` holds one native solver: :meth:`NativeHls.load` copies a stack of
:class:`~wbcbench.qp.hls.Level` into it, :meth:`NativeHls.solve` runs one of the three
algorithms and returns the :class:`~wbcbench.qp.hls.HlsResult` the Python function returns;
its ``time`` and the levels' times are measured inside the module. ``solve_hls_native``,
``solve_fullqr_hierarchy_native`` and ``solve_svd_hierarchy_native`` take the arguments of
their Python counterparts.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from wbcbench import _native
from wbcbench.errors import SolverError
from wbcbench.qp.hls import Array, HlsResult, Level, LevelStats, level_dampings, start_point
from wbcbench.qp.hls_baselines import ALGORITHMS, Solver, equality_tasks


class NativeHls:
    """One native hierarchy solver and the stack loaded into it."""

    def __init__(self) -> None:
        core = _native.core()
        self.solver = core.HlsSolver()
        self._algorithms = {name: getattr(core.HlsAlgorithm, name) for name in ALGORITHMS}
        self._options = core.HlsOptions()
        self._names: list[str] = []
        self._empty: Array = np.zeros((0, 0))
        self._none: Array = np.zeros(0)

    def load(self, levels: Sequence[Level], damping: float | Sequence[float] | None = None) -> None:
        """Copy ``levels`` (and their dampings, or ``damping`` overriding them) into the solver."""
        ks = level_dampings(levels, damping)
        n = start_point(levels, None).size
        if self._empty.shape[1] != n:
            self._empty = np.zeros((0, n))
        empty, none = self._empty, self._none
        self.solver.resize(len(levels), n)
        self._names = [lv.name for lv in levels]
        for i, (lv, k) in enumerate(zip(levels, ks, strict=True)):
            task = lv.A is not None and lv.b is not None
            ineq = lv.C is not None and lv.l is not None and lv.u is not None
            self.solver.set_level(
                i,
                lv.name,
                lv.A if task else empty,
                lv.b if task else none,
                lv.C if ineq else empty,
                lv.l if ineq else none,
                lv.u if ineq else none,
                k,
                task,
                ineq,
            )

    def run(
        self,
        algorithm: str = "reduced_qr",
        x0: Array | None = None,
        rank_tol: float = 1e-9,
        feas_tol: float = 1e-9,
        max_iter: int | None = None,
    ) -> bool:
        """Solve the loaded stack, leaving the result in the solver (no conversion); ok."""
        opts = self._options
        opts.rank_tol, opts.feas_tol, opts.max_iter = rank_tol, feas_tol, max_iter or 0
        start = np.zeros(self.solver.n) if x0 is None else np.asarray(x0, dtype=float)
        return bool(self.solver.solve(self._algorithms[algorithm], start, opts))

    def result(self) -> HlsResult:
        """The last solve as the Python reference returns it (raises SolverError on failure)."""
        return hls_result(self.solver, self._names)

    def solve(
        self,
        algorithm: str = "reduced_qr",
        x0: Array | None = None,
        rank_tol: float = 1e-9,
        feas_tol: float = 1e-9,
        max_iter: int | None = None,
    ) -> HlsResult:
        """Solve the loaded stack with ``algorithm`` (a name of ``hls_baselines.ALGORITHMS``)."""
        self.run(algorithm, x0, rank_tol, feas_tol, max_iter)
        return self.result()


def hls_result(solver: Any, names: Sequence[str]) -> HlsResult:
    """A native solver's last solve as the Python reference returns it, its levels named
    ``names`` (raises SolverError on failure)."""
    if not solver.ok:
        raise SolverError(solver.message)
    stats = [
        LevelStats(name, time, it, active, sat, residual, violation, rank, left, x)
        for name, (time, it, active, sat, residual, violation, rank, left, x) in zip(
            names, solver.stats(), strict=True
        )
    ]
    return HlsResult(np.array(solver.x), stats, float(solver.time))


def solve_hls_native(
    levels: Sequence[Level],
    *,
    damping: float | Sequence[float] | None = None,
    x0: Array | None = None,
    rank_tol: float = 1e-9,
    feas_tol: float = 1e-9,
    max_iter: int | None = None,
) -> HlsResult:
    """:func:`wbcbench.qp.hls.solve_hls`, natively."""
    solver = NativeHls()
    solver.load(levels, damping)
    return solver.solve("reduced_qr", start_point(levels, x0), rank_tol, feas_tol, max_iter)


def solve_fullqr_hierarchy_native(
    levels: Sequence[Level],
    *,
    damping: float | Sequence[float] | None = None,
    x0: Array | None = None,
    rank_tol: float = 1e-9,
) -> HlsResult:
    """:func:`wbcbench.qp.hls_baselines.solve_fullqr_hierarchy`, natively."""
    return _baseline("full_qr", levels, damping, x0, rank_tol)


def solve_svd_hierarchy_native(
    levels: Sequence[Level],
    *,
    damping: float | Sequence[float] | None = None,
    x0: Array | None = None,
    rank_tol: float = 1e-9,
) -> HlsResult:
    """:func:`wbcbench.qp.hls_baselines.solve_svd_hierarchy`, natively."""
    return _baseline("svd", levels, damping, x0, rank_tol)


def _baseline(
    algorithm: str,
    levels: Sequence[Level],
    damping: float | Sequence[float] | None,
    x0: Array | None,
    rank_tol: float,
) -> HlsResult:
    """A baseline of equality levels only (rejected as the Python baselines reject them)."""
    equality_tasks(levels)
    solver = NativeHls()
    solver.load(levels, damping)
    return solver.solve(algorithm, start_point(levels, x0), rank_tol)


#: the native counterpart of each of ``hls_baselines.ALGORITHMS``
NATIVE_ALGORITHMS: dict[str, Solver] = {
    "reduced_qr": solve_hls_native,
    "full_qr": solve_fullqr_hierarchy_native,
    "svd": solve_svd_hierarchy_native,
}
