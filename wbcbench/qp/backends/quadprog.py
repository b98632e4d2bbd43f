"""quadprog: Goldfarb–Idnani dual active set on a dense, strictly convex QP.

Native form: ``min ½xᵀGx − aᵀx s.t. Cᵀx ≥ b`` with the first ``meq`` columns of ``C`` as
equalities. Rows are split on their finite sides: columns ``[Aᵀ | −C[up]ᵀ | C[lo]ᵀ | −I[ub] |
I[lb]]`` with ``b = [b; −u[up]; l[lo]; −ub; lb]``. The multipliers (``≥ 0`` for inequalities)
are mapped back to the shared convention (``y = −λ_eq``, ``z = λ_up − λ_lo``).

quadprog needs a strictly positive definite ``G``. When ``H`` is not (its Cholesky
factorisation fails), this backend solves with ``H + δI``, ``δ = 1e-12 · max(1, max |H_ii|)``,
multiplied by 100 until the factorisation succeeds (:func:`~wbcbench.qp.backends._common.
positive_definite`); this perturbs the optimum by ``O(δ)`` in the cost and ``Solution.message``
states the ``δ`` used. A PD ``H`` is passed unchanged.

No warm or hot start (``warm`` and ``hot`` run ``cold``); no internal timer; tiers do not apply
(the active-set method is exact up to round-off).
"""

from __future__ import annotations

import time

import numpy as np
import quadprog as _quadprog

from wbcbench.qp.backends._common import positive_definite, split_rows
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "quadprog"


class QuadprogSolver(QPSolver):
    """quadprog; see the module docstring."""

    name = "quadprog"
    default_eps = 1e-9  # a dual active-set method: exact to round-off
    summary = "quadprog: Goldfarb-Idnani dual active set, dense"
    warm_start = False
    hot_start = False
    internal_time_covers = ""

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        G, h, up, lo = split_rows(problem.C, problem.l, problem.u)
        blocks, rhs = [problem.A, -G], [problem.b, -h]
        if problem.has_box:
            lb, ub = problem.box()
            Gb, hb, ubi, lbi = split_rows(np.eye(problem.n), lb, ub)
            blocks.append(-Gb)
            rhs.append(-hb)
        Ct = np.vstack(blocks)
        H, delta = positive_definite(problem.H)
        Cmat = np.ascontiguousarray(Ct.T)
        bvec = np.concatenate(rhs)
        neg_g = -problem.g
        t1 = time.perf_counter()
        try:
            x, _, _, iters, lag, _ = _quadprog.solve_qp(H, neg_g, Cmat, bvec, problem.n_eq)
        except ValueError as exc:
            t2 = time.perf_counter()
            text = str(exc)
            status = SolutionStatus.INFEASIBLE if "inconsistent" in text else SolutionStatus.FAILED
            return Solution(status=status, wall_time=t2 - t1, setup_time=t1 - t0, message=text)
        t2 = time.perf_counter()
        lag = np.asarray(lag)
        n_eq = problem.n_eq
        k = n_eq + G.shape[0]
        z = np.zeros(problem.n_in)
        z[up] += lag[n_eq : n_eq + up.size]
        z[lo] -= lag[n_eq + up.size : k]
        z_box = None
        if problem.has_box:
            z_box = np.zeros(problem.n)
            z_box[ubi] += lag[k : k + ubi.size]
            z_box[lbi] -= lag[k + ubi.size :]
        message = "optimal"
        if delta:
            message += (
                f"; H not positive definite: solved with H + {delta:.1e}·I "
                "(quadprog needs a positive definite Hessian)"
            )
        return Solution(
            status=SolutionStatus.SOLVED,
            x=np.array(x),
            y=-lag[:n_eq],
            z=z,
            z_box=z_box,
            iterations=int(iters[0]),
            wall_time=t2 - t1,
            setup_time=t1 - t0,
            message=message,
        )
