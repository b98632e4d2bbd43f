"""Any backend through the qpsolvers package, registered as ``qpsolvers:<name>``.

This exists to show what a generic wrapper costs: ``wall_time`` is the whole
``qpsolvers.solve_problem`` call (qpsolvers' conversions, the native setup and the solve), so
compare it with the native backend's ``setup_time + wall_time``. The problem is passed in
qpsolvers' one-sided form (``G x ≤ h`` from the finite sides of ``l ≤ Cx ≤ u``, equalities and
the box as they are), as CSC matrices for the sparse solvers (OSQP, Clarabel, HiGHS) the way
qpsolvers recommends, dense otherwise; its duals are merged back into the shared convention.

Warm start: qpsolvers' ``initvals`` (used by the solvers whose qpsolvers interface accepts a
primal guess). Hot: qpsolvers keeps no solver object, so ``hot`` runs ``warm``. Internal time:
none (qpsolvers does not report it uniformly). Tiers: the native backend module's
``tier_settings`` (qpsolvers forwards them to the solver under the same names).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import qpsolvers as _qpsolvers
import scipy.sparse as sp

from wbcbench.qp.backends._common import merge_split_duals, split_rows
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "qpsolvers"

#: Solvers qpsolvers hands sparse matrices (it converts dense input with a warning).
_SPARSE = frozenset({"clarabel", "highs", "osqp"})

#: Solvers whose qpsolvers interface (4.x) uses a primal initial guess; others ignore it.
_ACCEPTS_INITVALS = frozenset({"osqp", "proxqp"})


def make_wrapper(
    inner: str,
    tier_settings: Callable[[str], dict[str, Any]],
    tier_caps: Callable[[str], dict[str, Any]] = lambda tier: {},
    default_eps: float = QPSolver.default_eps,
) -> type[QPSolver]:
    """A :class:`QPSolver` subclass solving through ``qpsolvers.solve_problem(solver=inner)``.

    Args:
        inner: qpsolvers' name of the solver.
        tier_settings: the native backend's tier translation (empty dicts if none).
        tier_caps: the native backend's time / iteration caps, where they are the library's own
            settings (empty dicts otherwise).
        default_eps: the native backend's default accuracy (:attr:`QPSolver.default_eps`).
    """

    inner_eps = default_eps  # (a class body cannot read a parameter of the same name)

    class QpsolversSolver(QPSolver):
        name = f"qpsolvers:{inner}"
        default_eps = inner_eps
        summary = f"{inner} through qpsolvers' generic solve_problem"
        warm_start = inner in _ACCEPTS_INITVALS
        hot_start = False
        internal_time_covers = ""

        @staticmethod
        def tier_settings(tier: str) -> dict[str, Any]:
            return tier_settings(tier)

        @staticmethod
        def tier_caps(tier: str) -> dict[str, Any]:
            return tier_caps(tier)

        def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
            t0 = time.perf_counter()
            G, h, up, lo = split_rows(problem.C, problem.l, problem.u)
            to = sp.csc_matrix if inner in _SPARSE else np.asarray
            qp = _qpsolvers.Problem(
                P=to(problem.H),
                q=problem.g,
                G=to(G) if G.shape[0] else None,
                h=h if G.shape[0] else None,
                A=to(problem.A) if problem.n_eq else None,
                b=problem.b if problem.n_eq else None,
                lb=problem.lb,
                ub=problem.ub,
            )
            initvals = guess.x if guess is not None else None
            with warnings.catch_warnings():
                # Status chatter (e.g. "terminated with status PrimalInfeasible"); the status
                # is in the Solution.
                warnings.simplefilter("ignore")
                t1 = time.perf_counter()
                sol = _qpsolvers.solve_problem(qp, solver=inner, initvals=initvals, **self.options)
                t2 = time.perf_counter()
            found = bool(sol.found)
            x = np.array(sol.x) if found and sol.x is not None else None
            z = None
            if found and sol.z is not None:
                z = merge_split_duals(np.asarray(sol.z), up, lo, problem.n_in)
            elif found and problem.n_in == 0:
                z = np.zeros(0)
            y = np.array(sol.y) if found and sol.y is not None else None
            if found and y is None and problem.n_eq == 0:
                y = np.zeros(0)
            z_box = None
            if found and problem.has_box and sol.z_box is not None:
                z_box = np.array(sol.z_box)
            return Solution(
                status=SolutionStatus.SOLVED if found else SolutionStatus.FAILED,
                x=x,
                y=y,
                z=z,
                z_box=z_box,
                wall_time=t2 - t1,
                setup_time=t1 - t0,
                message="found" if found else "qpsolvers: no solution found",
            )

    QpsolversSolver.__name__ = QpsolversSolver.__qualname__ = f"Qpsolvers_{inner}"
    return QpsolversSolver
