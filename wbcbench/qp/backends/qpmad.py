"""qpmad through pyqpmad: Goldfarb–Idnani dual active set on a dense, strictly convex QP.

Native form: ``min ½xᵀHx + hᵀx s.t. lb ≤ x ≤ ub, Alb ≤ M x ≤ Aub`` with ``M = [A; C]``,
``Alb = [b; l]``, ``Aub = [b; u]`` (infinite sides allowed; the box passed only when the problem
has one). qpmad treats a row whose two sides lie within its ``tolerance`` (1e-12) of each other
as an equality: the rows of ``A``, and any row of ``C`` or bound with ``l = u``.

``H`` is passed as a Fortran-ordered copy, which qpmad overwrites with its Cholesky factor.
qpmad needs a positive definite ``H`` and raises when its factorisation fails; this backend then
solves with ``H + δI`` as the quadprog backend does (:func:`~wbcbench.qp.backends._common.
positive_definite`; ``Solution.message`` states ``δ``). The failed attempt is counted in the wall
time, the shift in the set-up.

Statuses: ``OK`` is solved; the iteration limit is ``max_iter`` (qpmad's default sets none);
qpmad raises on infeasible constraints (``Infeasible equality constraints``, ``Infeasible
inequality constraints``, ``Inconsistent constraints (lb > ub)``): infeasible, any other
exception a failed solve. Iterations: qpmad's count of inequality iterations.

Duals: qpmad reports the multipliers of its active inequalities only (a magnitude and which side
is active), mapped here to the shared convention; it does not report those of the rows it
treats as equalities. So ``y`` is reported only when there are no equality rows (as an empty
array), ``z`` only when no row of ``C`` has equal sides, and ``z_box`` only when no bound does;
the KKT check of :func:`wbcbench.qp.validity.check_solution` then needs a problem without
equalities.

Modes: qpmad takes no initial guess (every solve starts from the unconstrained minimum), so
``warm`` runs ``cold``. ``hot`` keeps the solver (its workspace reserved once for the problem's
sizes) and, while ``H`` is unchanged, its Cholesky factor: the next solve passes it as
``HESSIAN_CHOLESKY_FACTOR``, skipping the factorisation, the use qpmad documents for a fixed
Hessian (qpmad still inverts the triangular factor on each solve; reusing that inverse too needs
the Hessian type a solve leaves, which pyqpmad does not expose).

Tiers do not apply (the active-set method is exact up to round-off): qpmad's ``tolerance`` is
also its threshold for taking two sides as an equality and for linear dependence, so it stays
at qpmad's default at every tier. No time cap and no iteration cap (qpmad's defaults); a native
call that never returns is stopped by the run's wall-clock guard. No internal timer.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyqpmad

from wbcbench.qp.backends._common import apply_settings, positive_definite
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Array, Problem
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "pyqpmad"

#: qpmad's text of a Hessian whose Cholesky factorisation failed
_NOT_POSITIVE_DEFINITE = "Could not perform Cholesky decomposition"
#: the starts of qpmad's texts of infeasible constraints
_INFEASIBLE = ("Infeasible", "Inconsistent")


@dataclass
class _Native:
    """What a hot handle keeps: the solver, its parameters and the data buffers qpmad reads
    (``H`` holds the Cholesky factor of ``H + δI`` after a solve)."""

    solver: Any
    params: Any
    H: Array
    delta: float
    M: Array | None
    lo: Array
    hi: Array


def _general(problem: Problem) -> tuple[Array | None, Array, Array]:
    """``(M, Alb, Aub)``: ``M = [A; C]`` in Fortran order (None without rows) and its sides."""
    m = problem.n_eq + problem.n_in
    if not m:
        return None, np.zeros(0), np.zeros(0)
    M = np.empty((m, problem.n), order="F")
    M[: problem.n_eq] = problem.A
    M[problem.n_eq :] = problem.C
    lo = np.concatenate([problem.b, problem.l])
    hi = np.concatenate([problem.b, problem.u])
    return M, lo, hi


def _status(exc: RuntimeError) -> SolutionStatus:
    text = str(exc).rsplit("// ", 1)[-1]
    return SolutionStatus.INFEASIBLE if text.startswith(_INFEASIBLE) else SolutionStatus.FAILED


class QpmadSolver(QPSolver):
    """qpmad via pyqpmad; see the module docstring."""

    name = "qpmad"
    default_eps = 1e-9  # a dual active-set method: exact to round-off
    summary = "qpmad (pyqpmad): Goldfarb-Idnani dual active set, dense"
    warm_start = False
    hot_start = True
    internal_time_covers = ""

    def _params(self) -> Any:
        params = pyqpmad.SolverParameters()
        apply_settings(params, self.options, LIBRARY)
        return params

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        M, lo, hi = _general(problem)
        native = _Native(
            solver=pyqpmad.Solver(),
            params=self._params(),
            H=np.array(problem.H, order="F"),
            delta=0.0,
            M=M,
            lo=lo,
            hi=hi,
        )
        if keep:
            m = problem.n_eq + problem.n_in
            native.solver.reserve(problem.n, problem.n if problem.has_box else 0, m)
        native.params.hessian_type = pyqpmad.HessianType.HESSIAN_LOWER_TRIANGULAR
        t1 = time.perf_counter()
        sol = self._run(native, problem, t1 - t0)
        self._native = native if keep else None
        return sol

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        native: _Native = self._native
        t0 = time.perf_counter()
        if "H" in changed:
            native.H[...] = problem.H
            native.delta = 0.0
            native.params.hessian_type = pyqpmad.HessianType.HESSIAN_LOWER_TRIANGULAR
        else:  # the factor the last solve left in native.H
            native.params.hessian_type = pyqpmad.HessianType.HESSIAN_CHOLESKY_FACTOR
        if native.M is not None:
            if "A" in changed:
                native.M[: problem.n_eq] = problem.A
            if "C" in changed:
                native.M[problem.n_eq :] = problem.C
            if changed & {"b", "l", "u"}:
                native.lo = np.concatenate([problem.b, problem.l])
                native.hi = np.concatenate([problem.b, problem.u])
        t1 = time.perf_counter()
        return self._run(native, problem, t1 - t0)

    def _run(self, native: _Native, problem: Problem, setup: float) -> Solution:
        lb, ub = problem.box() if problem.has_box else (None, None)
        x = np.zeros(problem.n)

        def call() -> Any:
            return native.solver.solve(
                x, native.H, problem.g, lb, ub, native.M, native.lo, native.hi, native.params
            )

        wall = 0.0
        t0 = time.perf_counter()
        try:
            try:
                status = call()
            except RuntimeError as exc:
                if _NOT_POSITIVE_DEFINITE not in str(exc):
                    raise
                wall += time.perf_counter() - t0
                t_shift = time.perf_counter()
                G, native.delta = positive_definite(problem.H)
                native.H[...] = G
                setup += time.perf_counter() - t_shift
                t0 = time.perf_counter()
                status = call()
        except RuntimeError as exc:
            wall += time.perf_counter() - t0
            return Solution(status=_status(exc), wall_time=wall, setup_time=setup, message=str(exc))
        wall += time.perf_counter() - t0
        iterations = int(native.solver.get_num_iterations())
        if status != pyqpmad.ReturnStatus.OK:
            return Solution(
                status=SolutionStatus.MAX_ITER,
                iterations=iterations,
                wall_time=wall,
                setup_time=setup,
                message=str(status).rsplit(".", 1)[-1],
            )
        y, z, z_box = self._duals(native, problem)
        message = "OK"
        if native.delta:
            message += (
                f"; H not positive definite: solved with H + {native.delta:.1e}·I "
                "(qpmad needs a positive definite Hessian)"
            )
        return Solution(
            status=SolutionStatus.SOLVED,
            x=x,
            y=y,
            z=z,
            z_box=z_box,
            iterations=iterations,
            wall_time=wall,
            setup_time=setup,
            message=message,
        )

    def _duals(
        self, native: _Native, problem: Problem
    ) -> tuple[Array | None, Array | None, Array | None]:
        """``(y, z, z_box)`` from qpmad's active inequalities, each None where qpmad treats
        some of its rows as equalities (whose multipliers it does not report)."""
        tol = float(native.params.tolerance)
        n, n_eq = problem.n, problem.n_eq
        k = n if problem.has_box else 0
        active = native.solver.get_inequality_dual()
        signed = np.where(active.is_lower, -active.dual, active.dual)
        full = np.zeros(k + n_eq + problem.n_in)
        full[active.indices] = signed
        y = np.zeros(0) if n_eq == 0 else None
        z = None if np.any(np.abs(problem.u - problem.l) <= tol) else full[k + n_eq :]
        z_box = None
        if problem.has_box:
            lb, ub = problem.box()
            z_box = None if np.any(np.abs(ub - lb) <= tol) else full[:k]
        return y, z, z_box
