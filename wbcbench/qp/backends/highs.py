"""HiGHS (highspy): its active-set QP solver on the sparse (column-wise) form.

Native form: ``min ½xᵀQx + cᵀx s.t. L ≤ Mx ≤ U, lb ≤ x ≤ ub`` with ``M = [A; C]`` (equality
rows as ``L = U = b``) and ``Q`` given as its lower triangle. HiGHS's duals have the opposite
sign of the shared convention (``row_dual``/``col_dual`` are reduced costs), so ``y, z =
−row_dual`` and ``z_box = −col_dual``.

Warm start: not used (``warm`` runs ``cold``). Hot: one ``Highs`` object is kept; when only
``g`` or bounds change they are sent with ``changeColsCost``/``changeColsBounds``/
``changeRowsBounds``, a changed ``H`` alone goes through ``passHessian``, and a changed ``A`` or
``C`` passes the whole model again to the same object. Internal time: the increase of
``getRunTime()`` over ``run()`` (covers the solve). Tiers (as qpbenchmark):
``primal_feasibility_tolerance`` and ``dual_feasibility_tolerance`` (HiGHS notes the primal one
has no effect on QPs).
"""

from __future__ import annotations

import time
from typing import Any

import highspy
import numpy as np
import scipy.sparse as sp

from wbcbench.qp.backends._common import tier_eps
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.settings import TIER_TIME_LIMIT
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "highspy"

_M = highspy.HighsModelStatus
_STATUS = {
    _M.kOptimal: SolutionStatus.SOLVED,
    _M.kInfeasible: SolutionStatus.INFEASIBLE,
    _M.kUnboundedOrInfeasible: SolutionStatus.INFEASIBLE,
    _M.kUnbounded: SolutionStatus.INFEASIBLE,
    _M.kIterationLimit: SolutionStatus.MAX_ITER,
    _M.kTimeLimit: SolutionStatus.MAX_ITER,
}


def _hessian(problem: Problem) -> Any:
    L = sp.csc_matrix(np.tril(problem.H))
    hess = highspy.HighsHessian()
    hess.dim_ = problem.n
    hess.format_ = highspy.HessianFormat.kTriangular
    hess.start_ = L.indptr
    hess.index_ = L.indices
    hess.value_ = L.data
    return hess


def _model(problem: Problem) -> Any:
    M = sp.csc_matrix(np.vstack([problem.A, problem.C]))
    lb, ub = problem.box()
    model = highspy.HighsModel()
    lp = model.lp_
    lp.num_col_ = problem.n
    lp.num_row_ = M.shape[0]
    lp.col_cost_ = problem.g
    lp.col_lower_ = lb
    lp.col_upper_ = ub
    lp.row_lower_ = np.concatenate([problem.b, problem.l])
    lp.row_upper_ = np.concatenate([problem.b, problem.u])
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.num_col_ = problem.n
    lp.a_matrix_.num_row_ = M.shape[0]
    lp.a_matrix_.start_ = M.indptr
    lp.a_matrix_.index_ = M.indices
    lp.a_matrix_.value_ = M.data
    model.hessian_ = _hessian(problem)
    return model


class HiGHSSolver(QPSolver):
    """HiGHS; see the module docstring."""

    name = "highs"
    default_eps = 1e-7  # its default primal and dual feasibility tolerances
    summary = "HiGHS: active-set QP, sparse"
    warm_start = False
    hot_start = True
    internal_time_covers = "solve"

    @staticmethod
    def tier_caps(tier: str) -> dict[str, Any]:
        # HiGHS's QP iteration limit is unbounded by default
        return {"time_limit": TIER_TIME_LIMIT[tier], "qp_iteration_limit": 1_000_000}

    @staticmethod
    def tier_settings(tier: str) -> dict[str, Any]:
        eps = tier_eps(tier)
        if eps is None:
            return {}
        return {"primal_feasibility_tolerance": eps, "dual_feasibility_tolerance": eps}

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        h = highspy.Highs()
        h.setOptionValue("output_flag", False)
        for key, value in self.options.items():
            if h.setOptionValue(key, value) != highspy.HighsStatus.kOk:
                raise ValueError(f"HiGHS rejected option {key}={value!r}")
        h.passModel(_model(problem))
        t1 = time.perf_counter()
        self._native = h if keep else None
        return self._run(h, problem, t1 - t0)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        h = self._native
        t0 = time.perf_counter()
        n, m = problem.n, problem.n_eq + problem.n_in
        if changed & {"A", "C"}:
            h.passModel(_model(problem))
        else:
            if "H" in changed:
                h.passHessian(_hessian(problem))
            if "g" in changed:
                h.changeColsCost(n, np.arange(n, dtype=np.int32), problem.g)
            if changed & {"lb", "ub"}:
                lb, ub = problem.box()
                h.changeColsBounds(n, np.arange(n, dtype=np.int32), lb, ub)
            if changed & {"b", "l", "u"} and m:
                h.changeRowsBounds(
                    m,
                    np.arange(m, dtype=np.int32),
                    np.concatenate([problem.b, problem.l]),
                    np.concatenate([problem.b, problem.u]),
                )
        t1 = time.perf_counter()
        return self._run(h, problem, t1 - t0)

    @staticmethod
    def _run(h: Any, problem: Problem, setup: float) -> Solution:
        r0 = h.getRunTime()
        t1 = time.perf_counter()
        h.run()
        t2 = time.perf_counter()
        internal = h.getRunTime() - r0
        model_status = h.getModelStatus()
        status = _STATUS.get(model_status, SolutionStatus.FAILED)
        x = y = z = z_box = None
        if status in (SolutionStatus.SOLVED, SolutionStatus.MAX_ITER):
            sol = h.getSolution()
            x = np.array(sol.col_value)
            if sol.dual_valid:
                row_dual = -np.array(sol.row_dual)
                y, z = row_dual[: problem.n_eq], row_dual[problem.n_eq :]
                z_box = -np.array(sol.col_dual) if problem.has_box else None
        return Solution(
            status=status,
            x=x,
            y=y,
            z=z,
            z_box=z_box,
            iterations=int(h.getInfo().qp_iteration_count),
            wall_time=t2 - t1,
            setup_time=setup,
            internal_time=float(internal),
            message=h.modelStatusToString(model_status),
        )
