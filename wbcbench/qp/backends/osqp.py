"""OSQP (v1 API): operator-splitting ADMM on the sparse (CSC) form.

Native form: ``min ½xᵀPx + qᵀx s.t. l ≤ Ax ≤ u`` with ``P`` upper triangular; the problem's
``A``, ``C`` and box are stacked as ``[A; C; I]`` with ``l = [b; l; lb]``, ``u = [b; u; ub]``
(``±inf`` passed through). The CSC patterns hold the nonzeros of the data (plus ``P``'s
diagonal). Warm start: ``warm_start(x, y)`` on a fresh object. Hot: the object is kept and
``update(q, l, u, Px, Ax)`` sends what changed; OSQP then starts from its previous iterate. An
update is only possible while the new nonzeros fit the stored patterns, else the object is
rebuilt. Internal time: ``info.solve_time`` (covers the solve call; ``setup``/``update`` are
timed separately by OSQP and here in ``setup_time``). Tiers: ``eps_abs``, ``eps_rel = 0``; OSQP
v1 checks the duality gap by default (``check_dualgap``).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import osqp as _osqp

from wbcbench import _native
from wbcbench.qp.backends._common import (
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

LIBRARY = "osqp"

_S = _osqp.SolverStatus
_STATUS = {
    _S.OSQP_SOLVED: SolutionStatus.SOLVED,
    _S.OSQP_SOLVED_INACCURATE: SolutionStatus.NUMERICAL,
    _S.OSQP_PRIMAL_INFEASIBLE: SolutionStatus.INFEASIBLE,
    _S.OSQP_PRIMAL_INFEASIBLE_INACCURATE: SolutionStatus.INFEASIBLE,
    _S.OSQP_DUAL_INFEASIBLE: SolutionStatus.INFEASIBLE,
    _S.OSQP_DUAL_INFEASIBLE_INACCURATE: SolutionStatus.INFEASIBLE,
    _S.OSQP_MAX_ITER_REACHED: SolutionStatus.MAX_ITER,
    _S.OSQP_TIME_LIMIT_REACHED: SolutionStatus.MAX_ITER,
}


#: OSQP's former setting names, which osqp.OSQP still takes
_RENAMED = {"polish": "polishing", "warm_start": "warm_starting"}


def _stack(problem: Problem) -> tuple[Array, Array, Array]:
    """``(M, lo, hi)`` with ``M = [A; C; I]`` (the identity only when there is a box)."""
    blocks, lo, hi = [problem.A, problem.C], [problem.b, problem.l], [problem.b, problem.u]
    if problem.has_box:
        lb, ub = problem.box()
        blocks.append(np.eye(problem.n))
        lo.append(lb)
        hi.append(ub)
    return np.vstack(blocks), np.concatenate(lo), np.concatenate(hi)


class OSQPSolver(QPSolver):
    """OSQP; see the module docstring."""

    name = "osqp"
    default_eps = 1e-3  # its default eps_abs = eps_rel
    summary = "OSQP (ADMM, sparse LDLᵀ); hot mode sends only the data that changed"
    warm_start = True
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
        # ADMM needs many more than its default 4000 iterations to reach 1e-6 / 1e-9 on
        # whole-body QPs (weights spanning nine decades); the tier asks for that accuracy.
        return {"eps_abs": eps, "eps_rel": 0.0, "max_iter": 200_000}

    #: every in-place update sends all the data (osqp_libdwbc), not only what changed
    send_all: bool = False

    def native_solver(self) -> Any | None:
        """OSQP's C library through the native module (the same OSQP as this wheel's), with
        this handle's mode and settings; None when the module is not built or a setting is not
        a plain number it knows."""
        core = _native._core
        if core is None:
            return None
        names = set(core.osqp_setting_names())
        options: dict[str, float] = {}
        for key, value in self.options.items():
            key = _RENAMED.get(key, key)
            if key not in names or not isinstance(value, bool | int | float):
                return None
            options[key] = float(value)
        return core.OsqpSolver(self.mode, options, send_all=self.send_all)

    def _can_update(self, problem: Problem) -> bool:
        p_mask, m_mask = self._masks
        M, _, _ = _stack(problem)
        return fits(np.triu(problem.H), p_mask) and fits(M, m_mask)

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        M, lo, hi = _stack(problem)
        p_mask, m_mask = upper_mask(problem.H), M != 0.0
        P = pattern_csc(np.triu(problem.H), p_mask)
        solver = _osqp.OSQP()
        solver.setup(P, problem.g, pattern_csc(M, m_mask), lo, hi, verbose=False, **self.options)
        if guess is not None:
            solver.warm_start(x=guess.x, y=self._stacked_duals(problem, guess))
        t1 = time.perf_counter()
        res = solver.solve(raise_error=False)
        t2 = time.perf_counter()
        if keep:
            self._native = solver
            self._masks = (p_mask, m_mask)
        return self._result(res, problem, t1 - t0, t2 - t1)

    def _fields_to_send(self, changed: frozenset[str]) -> frozenset[str]:
        """The problem fields an in-place update sends: those that changed (new values of ``H``
        or of ``A`` / ``C`` make OSQP factorise its KKT matrix again)."""
        return changed

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        solver = self._native
        p_mask, m_mask = self._masks
        t0 = time.perf_counter()
        changed = self._fields_to_send(changed)
        kwargs: dict[str, Any] = {}
        if "g" in changed:
            kwargs["q"] = problem.g
        if "H" in changed:
            kwargs["Px"] = pattern_values(np.triu(problem.H), p_mask)
        if changed & {"A", "C", "b", "l", "u", "lb", "ub"}:
            M, lo, hi = _stack(problem)
            if changed & {"A", "C"}:
                kwargs["Ax"] = pattern_values(M, m_mask)
            if changed & {"b", "l", "u", "lb", "ub"}:
                kwargs["l"], kwargs["u"] = lo, hi
        if kwargs:
            solver.update(**kwargs)
        if guess is not None:
            solver.warm_start(x=guess.x, y=self._stacked_duals(problem, guess))
        t1 = time.perf_counter()
        res = solver.solve(raise_error=False)
        t2 = time.perf_counter()
        return self._result(res, problem, t1 - t0, t2 - t1)

    @staticmethod
    def _stacked_duals(problem: Problem, guess: Guess) -> Array | None:
        if guess.y is None or guess.z is None:
            return None
        parts = [guess.y, guess.z]
        if problem.has_box:
            if guess.z_box is None:
                return None
            parts.append(guess.z_box)
        return np.concatenate(parts)

    @staticmethod
    def _result(res: Any, problem: Problem, setup: float, wall: float) -> Solution:
        info = res.info
        status = _STATUS.get(info.status_val, SolutionStatus.FAILED)
        ok = status in (SolutionStatus.SOLVED, SolutionStatus.NUMERICAL, SolutionStatus.MAX_ITER)
        x = np.array(res.x) if ok and res.x is not None else None
        y = np.array(res.y) if ok and res.y is not None else None
        n_eq, n_in = problem.n_eq, problem.n_in
        return Solution(
            status=status,
            x=x,
            y=None if y is None else y[:n_eq],
            z=None if y is None else y[n_eq : n_eq + n_in],
            z_box=None if y is None or not problem.has_box else y[n_eq + n_in :],
            iterations=int(info.iter),
            wall_time=wall,
            setup_time=setup,
            internal_time=float(info.solve_time),
            message=str(info.status),
        )
