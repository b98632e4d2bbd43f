"""DAQP: dual active-set solver for dense QPs.

Native form: ``min ½xᵀHx + fᵀx s.t. blower ≤ [I; A_daqp] x ≤ bupper`` where, when the problem
has a box, the first ``n`` entries of the bounds are the simple bounds ``lb, ub`` and
``A_daqp = [A; C]``; equality rows are flagged with sense 5 (``l = u = b``). DAQP's multipliers
``lam`` already follow the shared sign convention (positive on an active upper side).

H must be positive definite for DAQP's plain iterations. Since WBC Hessians are often only
semidefinite, this backend sets, unless given: ``eq_reduction = 1`` (eliminate the equality
constraints first; the reduced Hessian of a well-posed WBC problem is positive definite, and
on the WBC-like test problem this cuts the iterations from 80 to 26) and ``eps_prox = -1e-6``
(DAQP's own default: a negative value means proximal-point outer iterations only when the
Hessian it works with is singular, with the regularisation |eps_prox|; they converge to the
unregularised optimum). The magnitude matters: with ``eps_prox = -1`` the proximal term
outweighs the level QPs of ``lqp`` and ``rc_lqp`` (semidefinite H, largest eigenvalue
0.26–4.4), the outer iterations crawl (700–1600 of them, or DAQP's 10 000 limit) and stop at a
point whose duality gap the independent check refuses, while DAQP reports it optimal; with
1e-6 the same QPs take 3–5 iterations and pass (``docs/qp_export.md``).

The :class:`daqp.Model` API is used in all modes. Warm start: ``setup(..., primal_start)`` on a
fresh model (DAQP derives the initial active set from the guess). Hot: the model is kept and
``update`` sends the changed data; DAQP starts from the previous active set. Native ticks solve
through the same release's C library compiled into the native module
(:meth:`DAQPSolver.native_solver`), driven the same way. Internal time: DAQP's ``solve_time``
(covers the solve call; its setup is timed separately). Tiers (as qpbenchmark): ``primal_tol`` and
``dual_tol`` set to the tier's tolerance.
"""

from __future__ import annotations

import time
from typing import Any

import daqp as _daqp
import numpy as np

from wbcbench import _native
from wbcbench.qp.backends._common import tier_eps
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Array, Problem
from wbcbench.qp.settings import TIER_TIME_LIMIT
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "daqp"

EQUALITY_SENSE = 5

#: the settings this backend gives DAQP unless told otherwise (see the module docstring)
DEFAULT_SETTINGS: dict[str, Any] = {"eps_prox": -1e-6, "eq_reduction": 1}

_STATUS = {
    1: SolutionStatus.SOLVED,
    2: SolutionStatus.SOLVED,  # soft-constraint optimum
    -1: SolutionStatus.INFEASIBLE,
    -3: SolutionStatus.INFEASIBLE,  # unbounded
    -4: SolutionStatus.MAX_ITER,
    -2: SolutionStatus.NUMERICAL,  # cycling
    -5: SolutionStatus.NUMERICAL,  # non-convex
    -6: SolutionStatus.NUMERICAL,  # overdetermined initial active set
}
_FLAG_TEXT = {
    1: "optimal",
    2: "soft optimal",
    -1: "primal infeasible",
    -2: "cycling detected",
    -3: "unbounded",
    -4: "iteration limit",
    -5: "non-convex problem",
    -6: "overdetermined initial active set",
}


def _matrix(problem: Problem) -> Array:
    """``A_daqp = [A; C]`` (no copy when one of them is empty)."""
    A, C = problem.A, problem.C
    return C if not A.shape[0] else (A if not C.shape[0] else np.vstack([A, C]))


def _bounds(problem: Problem) -> tuple[Array, Array]:
    """``(bupper, blower)``: the box first when there is one, then equalities, inequalities."""
    hi, lo = [problem.b, problem.u], [problem.b, problem.l]
    if problem.has_box:
        lb, ub = problem.box()
        hi.insert(0, ub)
        lo.insert(0, lb)
    return np.concatenate(hi), np.concatenate(lo)


def _sense(problem: Problem) -> Any:
    """Constraint kinds: equality rows flagged, the rest plain."""
    k = problem.n if problem.has_box else 0
    sense = np.zeros(k + problem.n_eq + problem.n_in, np.int32)
    sense[k : k + problem.n_eq] = EQUALITY_SENSE
    return sense


class DAQPSolver(QPSolver):
    """DAQP; see the module docstring."""

    name = "daqp"
    default_eps = 1e-6  # its default primal_tol
    summary = "DAQP: dual active set, dense"
    warm_start = True
    hot_start = True
    internal_time_covers = "solve"

    @staticmethod
    def tier_caps(tier: str) -> dict[str, Any]:
        return {"time_limit": TIER_TIME_LIMIT[tier]}

    @staticmethod
    def tier_settings(tier: str) -> dict[str, Any]:
        eps = tier_eps(tier)
        return {} if eps is None else {"primal_tol": eps, "dual_tol": eps}

    def _settings(self) -> dict[str, Any]:
        """The settings every model gets: the defaults above, then this handle's."""
        return {**DEFAULT_SETTINGS, **self.options}

    def native_solver(self) -> Any | None:
        """DAQP's C library compiled into the native module (the C sources of the same daqp
        release), with this handle's mode and settings; None when the module is not built or a
        setting is not a plain number it knows."""
        core = _native._core
        if core is None:
            return None
        names = set(core.daqp_setting_names())
        settings = self._settings()
        if not all(k in names and isinstance(v, bool | int | float) for k, v in settings.items()):
            return None
        return core.DaqpSolver(self.mode, {k: float(v) for k, v in settings.items()})

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        M, (hi, lo), sense = _matrix(problem), _bounds(problem), _sense(problem)
        model = _daqp.Model()
        model.settings = self._settings()
        kwargs: dict[str, Any] = {}
        if guess is not None:
            # Primal only: DAQP 0.11 given the duals of a different problem as dual_start can
            # return NaNs flagged optimal; from x it derives the active set itself.
            kwargs["primal_start"] = guess.x
        flag, _ = model.setup(problem.H, problem.g, M, hi, lo, sense, **kwargs)
        t1 = time.perf_counter()
        if flag < 0:
            return Solution(
                status=_STATUS.get(flag, SolutionStatus.FAILED),
                setup_time=t1 - t0,
                message=f"setup failed: {_FLAG_TEXT.get(flag, flag)}",
            )
        out = model.solve()
        t2 = time.perf_counter()
        self._native = model if keep else None
        return self._result(out, problem, t1 - t0, t2 - t1)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        model = self._native
        t0 = time.perf_counter()
        kwargs: dict[str, Any] = {}
        if "H" in changed:
            kwargs["H"] = problem.H
        if "g" in changed:
            kwargs["f"] = problem.g
        if changed & {"A", "C"}:
            kwargs["A"] = _matrix(problem)
        if changed - {"H", "g"}:
            kwargs["bupper"], kwargs["blower"] = _bounds(problem)
        flag = model.update(**kwargs) if kwargs else 0
        t1 = time.perf_counter()
        if flag < 0:
            self._native = None
            return Solution(
                status=_STATUS.get(flag, SolutionStatus.FAILED),
                setup_time=t1 - t0,
                message=f"update failed: {_FLAG_TEXT.get(flag, flag)}",
            )
        out = model.solve()
        t2 = time.perf_counter()
        sol = self._result(out, problem, t1 - t0, t2 - t1)
        if sol.success and sol.x is not None and not np.all(np.isfinite(sol.x)):
            # DAQP 0.11 can return NaNs flagged optimal when a hot update follows a very
            # different problem (seen with proximal iterations): rebuild once, say so.
            retry = self._solve_fresh(problem, guess, keep=True)
            retry.rebuilt = True
            retry.wall_time += sol.wall_time
            retry.setup_time += sol.setup_time
            retry.message = f"{retry.message}; rebuilt after a non-finite hot result"
            return retry
        return sol

    @staticmethod
    def _result(out: Any, problem: Problem, setup: float, wall: float) -> Solution:
        x, fval, flag, info = out
        status = _STATUS.get(int(flag), SolutionStatus.FAILED)
        has_x = status in (SolutionStatus.SOLVED, SolutionStatus.MAX_ITER)
        lam = np.asarray(info["lam"]) if has_x else None  # DAQP returns fresh arrays
        k = problem.n if problem.has_box else 0
        return Solution(
            status=status,
            x=np.asarray(x) if has_x else None,
            y=None if lam is None else lam[k : k + problem.n_eq],
            z=None if lam is None else lam[k + problem.n_eq :],
            z_box=None if lam is None or not problem.has_box else lam[:k],
            iterations=int(info["iterations"]),
            wall_time=wall,
            setup_time=setup,
            internal_time=float(info["solve_time"]),
            objective=float(fval) if has_x else float("nan"),
            message=_FLAG_TEXT.get(int(flag), f"exitflag {flag}"),
        )
