"""PIQP (dense interface): proximal interior point.

Native form matches the problem's: ``min ½xᵀPx + cᵀx s.t. Ax = b, h_l ≤ Gx ≤ h_u,
x_l ≤ x ≤ x_u`` (``±inf`` allowed; rows free on both sides are left out, as PIQP would
zero them with a warning). Duals ``z_l, z_u, z_bl, z_bu ≥ 0`` are merged as
``z = z_u − z_l`` and ``z_box = z_bu − z_bl``. Warm start: not supported by PIQP (``warm`` runs
``cold``). Hot: ``DenseSolver`` is kept and ``update`` sends the changed data (same finite-side
pattern required), saving allocation and setup; iterations start afresh. Internal time:
``result.info.solve_time`` when ``compute_timings`` is on (this backend turns it on unless told
otherwise); it covers the solve call. Tiers: ``eps_abs``, ``eps_rel = 0``, duality-gap check
on with ``eps_duality_gap_abs = eps`` and ``eps_duality_gap_rel = 0``.
"""

from __future__ import annotations

import time
from collections.abc import Hashable
from typing import Any

import numpy as np
import piqp as _piqp

from wbcbench.qp.backends._common import Index, apply_settings, gap_checked_tier_settings
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Array, Problem
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "piqp"

_STATUS = {
    _piqp.PIQP_SOLVED: SolutionStatus.SOLVED,
    _piqp.PIQP_MAX_ITER_REACHED: SolutionStatus.MAX_ITER,
    _piqp.PIQP_PRIMAL_INFEASIBLE: SolutionStatus.INFEASIBLE,
    _piqp.PIQP_DUAL_INFEASIBLE: SolutionStatus.INFEASIBLE,
    _piqp.PIQP_NUMERICS: SolutionStatus.NUMERICAL,
}


def _f(M: Array) -> Array | None:
    """PIQP's dense interface wants Fortran-ordered matrices; ``None`` for empty blocks."""
    return np.asfortranarray(M) if M.shape[0] else None


def _kept_rows(problem: Problem) -> Index:
    """Inequality rows with at least one finite side (PIQP warns on, and zeroes, free rows)."""
    return np.flatnonzero(np.isfinite(problem.l) | np.isfinite(problem.u))


def _data(problem: Problem, rows: Index) -> dict[str, Any]:
    lb, ub = problem.box() if problem.has_box else (None, None)
    all_rows = rows.size == problem.n_in
    return {
        "P": np.asfortranarray(problem.H),
        "c": problem.g,
        "A": _f(problem.A),
        "b": problem.b if problem.n_eq else None,
        "G": _f(problem.C if all_rows else problem.C[rows]),
        "h_l": (problem.l if all_rows else problem.l[rows]) if rows.size else None,
        "h_u": (problem.u if all_rows else problem.u[rows]) if rows.size else None,
        "x_l": lb,
        "x_u": ub,
    }


_FIELD = {"H": "P", "g": "c", "A": "A", "b": "b", "C": "G", "l": "h_l", "u": "h_u"}


class PIQPSolver(QPSolver):
    """PIQP dense; see the module docstring."""

    name = "piqp"
    default_eps = 1e-8  # its default eps_abs
    summary = "PIQP: proximal interior point, dense"
    warm_start = False
    hot_start = True
    internal_time_covers = "solve"

    @staticmethod
    def tier_settings(tier: str) -> dict[str, Any]:
        return gap_checked_tier_settings(tier)

    def _native_signature(self, problem: Problem) -> Hashable:
        lb, ub = problem.box()
        masks = (np.isfinite(problem.l), np.isfinite(problem.u), np.isfinite(lb), np.isfinite(ub))
        return (problem.structure_key(), *(m.tobytes() for m in masks))

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        solver = _piqp.DenseSolver()
        apply_settings(solver.settings, {"compute_timings": True, **self.options}, LIBRARY)
        rows = _kept_rows(problem)
        solver.setup(**_data(problem, rows))
        t1 = time.perf_counter()
        status = solver.solve()
        t2 = time.perf_counter()
        self._native = solver if keep else None
        return self._result(solver, status, problem, rows, t1 - t0, t2 - t1)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        solver = self._native
        t0 = time.perf_counter()
        rows = _kept_rows(problem)
        data = _data(problem, rows)
        kwargs = {_FIELD[k]: data[_FIELD[k]] for k in changed if k in _FIELD}
        if changed & {"lb", "ub"}:
            kwargs["x_l"], kwargs["x_u"] = data["x_l"], data["x_u"]
        if kwargs:
            solver.update(**kwargs)
        t1 = time.perf_counter()
        status = solver.solve()
        t2 = time.perf_counter()
        return self._result(solver, status, problem, rows, t1 - t0, t2 - t1)

    @staticmethod
    def _result(
        solver: Any, status: Any, problem: Problem, rows: Index, setup: float, wall: float
    ) -> Solution:
        res = solver.result
        info = res.info
        st = _STATUS.get(status, SolutionStatus.FAILED)
        has_x = st in (SolutionStatus.SOLVED, SolutionStatus.MAX_ITER, SolutionStatus.NUMERICAL)
        timed = bool(solver.settings.compute_timings)
        z = None
        if has_x:
            z = np.zeros(problem.n_in)
            z[rows] = np.array(res.z_u) - np.array(res.z_l)
        return Solution(
            status=st,
            x=np.array(res.x) if has_x else None,
            y=np.array(res.y) if has_x else None,
            z=z,
            z_box=np.array(res.z_bu) - np.array(res.z_bl) if has_x and problem.has_box else None,
            iterations=int(info.iter),
            wall_time=wall,
            setup_time=setup,
            internal_time=float(info.solve_time) if timed else None,
            message=str(status).rsplit(".", 1)[-1],
        )
