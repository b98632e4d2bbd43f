"""qpOASES through CasADi's ``conic`` interface: online active set on the dense form.

Native form: ``min ½xᵀHx + gᵀx s.t. lba ≤ [A; C] x ≤ uba, lbx ≤ x ≤ ubx`` (equalities as
``lba = uba = b``). CasADi's multipliers ``lam_a``, ``lam_x`` follow the shared sign
convention. Data are converted to ``casadi.DM`` before the call (counted in ``setup_time``).

Modes: CasADi hot-starts qpOASES automatically from the second call on the same ``conic``
object, so ``cold`` builds a fresh object on every call and ``hot`` keeps one (rebuilt when
:meth:`Problem.structure_key` changes). This interface does not hand an initial guess to
qpOASES, so ``warm`` runs ``cold``. Internal time: CasADi's ``t_wall_solver`` statistic (the
qpOASES ``init``/``hotstart`` call, i.e. the solve). Tiers do not apply: qpOASES solves to its
own round-off-level tolerances (``default`` settings in every tier). qpOASES prints a
copyright banner when an object is built; this backend silences stdout during construction.

No effective time cap: the tiers' ``CPUtime`` is passed, but CasADi's bundled qpOASES has no
clock (its ``getCPUtime`` returns -1), so the cap never fires. The native counterpart
(:meth:`QpOASESSolver.native_solver`) accepts it and does not pass it on, to the same effect.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import time
from collections.abc import Iterator
from typing import Any

import casadi as _casadi
import numpy as np

from wbcbench import _native
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.settings import TIER_TIME_LIMIT
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "casadi"

# enableEqualities: rows with equal bounds are handled as equalities; without it qpOASES fails
# to initialise on the equality-constrained levels of hierarchical controllers.
_DEFAULT_OPTIONS: dict[str, Any] = {
    "printLevel": "none",
    "error_on_fail": False,
    "enableEqualities": True,
}


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Send the C-level stdout to /dev/null (qpOASES prints its banner with ``printf``)."""
    libc = ctypes.CDLL(None)
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        libc.fflush(None)
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def _status(stats: dict[str, Any]) -> SolutionStatus:
    if stats.get("success"):
        return SolutionStatus.SOLVED
    text = str(stats.get("return_status", "")).lower()
    if "infeasib" in text or "unbounded" in text:
        return SolutionStatus.INFEASIBLE
    if "working set" in text or "nwsr" in text or "iteration" in text:
        return SolutionStatus.MAX_ITER
    return SolutionStatus.FAILED


class QpOASESSolver(QPSolver):
    """qpOASES via CasADi; see the module docstring."""

    name = "qpoases"
    default_eps = 1e-9  # its default terminationTolerance, about 5e6 machine epsilons
    summary = "qpOASES through CasADi: online active set, dense"
    warm_start = False
    hot_start = True
    internal_time_covers = "solve"

    @staticmethod
    def tier_caps(tier: str) -> dict[str, Any]:
        return {"CPUtime": TIER_TIME_LIMIT[tier]}

    @classmethod
    def accuracy(cls, tier: str) -> float:
        """Its own round-off-level tolerance at every tier (tiers do not apply)."""
        return cls.default_eps

    def native_solver(self) -> Any | None:
        """qpOASES from C++ (cmeel-qpoases' library), called as CasADi calls it, in this
        handle's mode; None when the module is not built or a setting other than the tier's
        ``CPUtime`` is given. Results equal this backend's to round-off (CasADi's qpOASES
        multiplies through OpenBLAS, cmeel's through its own loops)."""
        core = _native._core
        if core is None:
            return None
        options: dict[str, float] = {}
        for key, value in self.options.items():
            if key != "CPUtime" or not isinstance(value, bool | int | float):
                return None
            options[key] = float(value)
        return core.QpOasesSolver(self.mode, options)

    def _build(self, problem: Problem) -> Any:
        m = problem.n_eq + problem.n_in
        sparsity = {
            "h": _casadi.Sparsity.dense(problem.n, problem.n),
            "a": _casadi.Sparsity.dense(m, problem.n),
        }
        with _quiet_stdout():
            return _casadi.conic("qp", "qpoases", sparsity, {**_DEFAULT_OPTIONS, **self.options})

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        solver = self._build(problem)
        t1 = time.perf_counter()
        self._native = solver if keep else None
        return self._call(solver, problem, t1 - t0)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        return self._call(self._native, problem, 0.0)

    @staticmethod
    def _call(solver: Any, problem: Problem, build_time: float) -> Solution:
        DM = _casadi.DM
        t0 = time.perf_counter()
        lb, ub = problem.box()
        args = {
            "h": DM(problem.H),
            "g": DM(problem.g),
            "a": DM(np.vstack([problem.A, problem.C])),
            "lba": DM(np.concatenate([problem.b, problem.l])),
            "uba": DM(np.concatenate([problem.b, problem.u])),
            "lbx": DM(lb),
            "ubx": DM(ub),
        }
        t1 = time.perf_counter()
        out = solver.call(args)
        t2 = time.perf_counter()
        stats = solver.stats()
        status = _status(stats)
        x = y = z = z_box = None
        if status in (SolutionStatus.SOLVED, SolutionStatus.MAX_ITER):
            x = np.array(out["x"]).ravel()
            lam_a = np.array(out["lam_a"]).ravel()
            y, z = lam_a[: problem.n_eq], lam_a[problem.n_eq :]
            z_box = np.array(out["lam_x"]).ravel() if problem.has_box else None
        return Solution(
            status=status,
            x=x,
            y=y,
            z=z,
            z_box=z_box,
            iterations=int(stats.get("iter_count", 0)),
            wall_time=t2 - t1,
            setup_time=build_time + (t1 - t0),
            internal_time=float(stats["t_wall_solver"]) if "t_wall_solver" in stats else None,
            message=str(stats.get("return_status", "")),
        )
