"""Clarabel: interior point on the conic form, sparse (CSC).

Native form: ``min ½xᵀPx + qᵀx s.t. Mx + s = h, s ∈ K`` with ``P`` upper triangular. Clarabel has
no two-sided rows, so rows are split on their finite sides: the equalities go to a
``ZeroConeT`` and ``[C[up]; −C[lo]; I[ub]; −I[lb]] x ≤ [u[up]; −l[lo]; ub; −lb]`` to a
``NonnegativeConeT``; infinite sides are dropped. Its duals are ``≥ 0`` per one-sided row and are
merged back into the shared two-sided convention.

Warm start: not supported by Clarabel (``warm`` runs ``cold``). Hot: the solver is kept and
``update(P=, q=, A=, b=)`` sends the changed values, saving the setup (equilibration and the
KKT's symbolic factorisation); the interior-point iterations start afresh. An update needs the
same finite-side pattern and sparsity pattern, else the solver is rebuilt. Internal time:
``solution.solve_time`` (covers the solve call). Tiers: ``tol_feas = tol_gap_abs = eps``,
``tol_gap_rel = 0``. Clarabel's ``AlmostSolved`` (reduced accuracy) is reported as
``numerical``.
"""

from __future__ import annotations

import time
from collections.abc import Hashable
from typing import Any

import clarabel as _clarabel
import numpy as np

from wbcbench.qp.backends._common import (
    Index,
    apply_settings,
    fits,
    pattern_csc,
    pattern_values,
    tier_eps,
    upper_mask,
)
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Array, Problem
from wbcbench.qp.settings import TIER_TIME_LIMIT
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "clarabel"

_STATUS = {
    "Solved": SolutionStatus.SOLVED,
    "AlmostSolved": SolutionStatus.NUMERICAL,
    "PrimalInfeasible": SolutionStatus.INFEASIBLE,
    "DualInfeasible": SolutionStatus.INFEASIBLE,
    "AlmostPrimalInfeasible": SolutionStatus.INFEASIBLE,
    "AlmostDualInfeasible": SolutionStatus.INFEASIBLE,
    "MaxIterations": SolutionStatus.MAX_ITER,
    "MaxTime": SolutionStatus.MAX_ITER,
    "NumericalError": SolutionStatus.NUMERICAL,
    "InsufficientProgress": SolutionStatus.NUMERICAL,
}


def _finite_sides(problem: Problem) -> tuple[Index, ...]:
    lb, ub = problem.box()
    return (
        np.flatnonzero(np.isfinite(problem.u)),
        np.flatnonzero(np.isfinite(problem.l)),
        np.flatnonzero(np.isfinite(ub)),
        np.flatnonzero(np.isfinite(lb)),
    )


def _conic(problem: Problem, sides: tuple[Index, ...]) -> tuple[Array, Array]:
    """``(M, h)`` of the conic rows, equalities first."""
    up, lo, ubi, lbi = sides
    lb, ub = problem.box()
    eye = np.eye(problem.n)
    M = np.vstack([problem.A, problem.C[up], -problem.C[lo], eye[ubi], -eye[lbi]])
    h = np.concatenate([problem.b, problem.u[up], -problem.l[lo], ub[ubi], -lb[lbi]])
    return M, h


class ClarabelSolver(QPSolver):
    """Clarabel; see the module docstring."""

    name = "clarabel"
    default_eps = 1e-8  # its default tol_feas and tol_gap_abs
    summary = "Clarabel: interior point on the conic form, sparse"
    warm_start = False
    hot_start = True
    internal_time_covers = "solve"

    @staticmethod
    def tier_caps(tier: str) -> dict[str, Any]:
        return {"time_limit": TIER_TIME_LIMIT[tier]}

    @staticmethod
    def tier_settings(tier: str) -> dict[str, Any]:
        eps = tier_eps(tier)
        if eps is None:
            return {}
        return {"tol_feas": eps, "tol_gap_abs": eps, "tol_gap_rel": 0.0}

    def _native_signature(self, problem: Problem) -> Hashable:
        sides = _finite_sides(problem)
        return (problem.structure_key(), *(s.tobytes() for s in sides))

    def _can_update(self, problem: Problem) -> bool:
        p_mask, m_mask = self._masks
        M, _ = _conic(problem, _finite_sides(problem))
        return (
            fits(np.triu(problem.H), p_mask)
            and fits(M, m_mask)
            and bool(self._native.is_data_update_allowed())
        )

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        sides = _finite_sides(problem)
        M, h = _conic(problem, sides)
        p_mask, m_mask = upper_mask(problem.H), M != 0.0
        settings = _clarabel.DefaultSettings()
        settings.verbose = False
        apply_settings(settings, self.options, LIBRARY)
        cones = []
        if problem.n_eq:
            cones.append(_clarabel.ZeroConeT(problem.n_eq))
        if M.shape[0] > problem.n_eq:
            cones.append(_clarabel.NonnegativeConeT(M.shape[0] - problem.n_eq))
        solver = _clarabel.DefaultSolver(
            pattern_csc(np.triu(problem.H), p_mask),
            problem.g,
            pattern_csc(M, m_mask),
            h,
            cones,
            settings,
        )
        t1 = time.perf_counter()
        res = solver.solve()
        t2 = time.perf_counter()
        if keep:
            self._native = solver
            self._masks = (p_mask, m_mask)
        return self._result(res, problem, sides, t1 - t0, t2 - t1)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        solver = self._native
        p_mask, m_mask = self._masks
        t0 = time.perf_counter()
        sides = _finite_sides(problem)
        kwargs: dict[str, Any] = {}
        if "g" in changed:
            kwargs["q"] = problem.g
        if "H" in changed:
            kwargs["P"] = pattern_values(np.triu(problem.H), p_mask)
        if changed - {"g", "H"}:
            M, h = _conic(problem, sides)
            if changed & {"A", "C"}:
                kwargs["A"] = pattern_values(M, m_mask)
            kwargs["b"] = h
        if kwargs:
            solver.update(**kwargs)
        t1 = time.perf_counter()
        res = solver.solve()
        t2 = time.perf_counter()
        return self._result(res, problem, sides, t1 - t0, t2 - t1)

    @staticmethod
    def _result(
        res: Any, problem: Problem, sides: tuple[Index, ...], setup: float, wall: float
    ) -> Solution:
        up, lo, ubi, lbi = sides
        status_text = str(res.status)
        status = _STATUS.get(status_text, SolutionStatus.FAILED)
        x = z_all = None
        if status not in (SolutionStatus.INFEASIBLE, SolutionStatus.FAILED):
            x = np.array(res.x)
            z_all = np.array(res.z)
        y = z = z_box = None
        if z_all is not None:
            n_eq, n_in, n = problem.n_eq, problem.n_in, problem.n
            k = n_eq
            y = z_all[:k]
            z = np.zeros(n_in)
            z[up] += z_all[k : k + up.size]
            k += up.size
            z[lo] -= z_all[k : k + lo.size]
            k += lo.size
            if problem.has_box:
                z_box = np.zeros(n)
                z_box[ubi] += z_all[k : k + ubi.size]
                k += ubi.size
                z_box[lbi] -= z_all[k : k + lbi.size]
        return Solution(
            status=status,
            x=x,
            y=y,
            z=z,
            z_box=z_box,
            iterations=int(res.iterations),
            wall_time=wall,
            setup_time=setup,
            internal_time=float(res.solve_time),
            message=status_text,
        )
