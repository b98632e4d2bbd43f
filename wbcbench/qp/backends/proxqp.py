"""ProxQP (proxsuite, dense backend): primal-dual proximal augmented Lagrangian.

Native API: ``proxsuite.proxqp.dense.QP(n, n_eq, n_in, box_constraints)``, ``init``,
``update``, ``solve``. Warm start: ``InitialGuess.WARM_START`` with ``solve(x, y, z)``
(without ``z`` when the problem has a box, see ``_run``). Hot:
the object is kept, ``update`` receives only the changed data and the solve starts from the
previous result (``WARM_START_WITH_PREVIOUS_RESULT``), or from a given guess (an explicit
``x0``, or the origin of a null-space level's coordinates: ``origin`` in
:meth:`~wbcbench.qp.QPSolver.solve`); the preconditioner is not recomputed on update
(ProxQP's default). Internal time: ``results.info.solve_time`` when
``compute_timings`` is on (this backend turns it on unless told otherwise); it covers the solve
call, not ``init``/``update``.

Cap: ProxQP has no time limit, and 0.8 does not always detect a primal-infeasible QP: on a
level QP of ``rc_lqp`` (14 variables, 40 inequality rows, H positive semidefinite, infeasible
for quadprog, DAQP, Clarabel, PIQP and OSQP) it ran to its default 10 000 outer iterations in
60–119 s, almost all of it after the first 2 000, where each outer iteration's inner
(semismooth Newton) loop grows long. Every tier caps the inner iterations at
:data:`MAX_ITER_IN` (ProxQP's default: 1 500), which ends that solve as ``max_iter`` in about
2 s. The outer iterations keep ProxQP's default: converging solves need up to a few thousand
(a hot ``qp_wbc`` tick on ``lee2021access_s1_accuracy``: 2 500–3 000), so an outer cap that
stops the stall as quickly would fail them.

Reproducibility: the AVX-512 and AVX2 builds that proxsuite 0.8 loads on such CPUs do not give
bit-identical results on bit-identical data. Fresh objects in one process, solving the same
``rc_lqp`` level QP (12 variables, 46 inequality rows), took 3 223 or 3 224 iterations, and
the two solutions' ‖x‖² differed by 9e-10 relative. This happened with one thread; the generic
build always gave one result. So wbcbench loads the generic build
(:mod:`wbcbench.qp.proxsuite_build`; ``WBCBENCH_PROXSUITE=vectorized`` restores proxsuite's own
choice, faster and reproducible to its tolerance only).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from proxsuite import proxqp

from wbcbench.qp.backends._common import apply_settings, gap_checked_tier_settings
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "proxsuite"

#: ProxQP's inner-iteration cap per outer iteration at every tier (its default is 1 500; see
#: the module docstring)
MAX_ITER_IN = 50

_STATUS = {
    proxqp.QPSolverOutput.PROXQP_SOLVED: SolutionStatus.SOLVED,
    proxqp.QPSolverOutput.PROXQP_MAX_ITER_REACHED: SolutionStatus.MAX_ITER,
    proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE: SolutionStatus.INFEASIBLE,
    proxqp.QPSolverOutput.PROXQP_DUAL_INFEASIBLE: SolutionStatus.INFEASIBLE,
    proxqp.QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: SolutionStatus.INFEASIBLE,
}


class ProxQPSolver(QPSolver):
    """ProxQP dense; see the module docstring."""

    name = "proxqp"
    default_eps = 1e-5  # its default eps_abs, absolute
    summary = "ProxQP (proxsuite): proximal augmented Lagrangian, dense"
    warm_start = True
    hot_start = True
    internal_time_covers = "solve"

    @staticmethod
    def tier_caps(tier: str) -> dict[str, Any]:
        return {"max_iter_in": MAX_ITER_IN}

    @staticmethod
    def tier_settings(tier: str) -> dict[str, Any]:
        return gap_checked_tier_settings(tier)

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        box = problem.has_box
        lb, ub = problem.box() if box else (None, None)
        opts = {"compute_timings": True, "verbose": False, **self.options}
        t0 = time.perf_counter()
        qp = proxqp.dense.QP(problem.n, problem.n_eq, problem.n_in, box)
        apply_settings(qp.settings, opts, LIBRARY)
        # A fresh object has no previous result: WARM_START_WITH_PREVIOUS_RESULT would start
        # from its uninitialised workspace (whatever the heap held, so runs differed between
        # processes). It starts from the guess or ProxQP's own initial guess, and only the
        # later in-place updates of a kept object start from its last iterate.
        if guess is not None:
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START
        if box:
            qp.init(problem.H, problem.g, problem.A, problem.b, problem.C, problem.l,
                    problem.u, lb, ub)  # fmt: skip
        else:
            qp.init(problem.H, problem.g, problem.A, problem.b, problem.C, problem.l, problem.u)
        t1 = time.perf_counter()
        self._run(qp, problem, guess)
        t2 = time.perf_counter()
        if keep:
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        self._native = qp if keep else None
        return self._result(qp, problem, t1 - t0, t2 - t1)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        qp = self._native
        kwargs: dict[str, Any] = {k: getattr(problem, k) for k in changed}
        if "lb" in kwargs or "ub" in kwargs:
            kwargs["lb"], kwargs["ub"] = problem.box()
        if "lb" in kwargs:
            kwargs["l_box"] = kwargs.pop("lb")
            kwargs["u_box"] = kwargs.pop("ub")
        t0 = time.perf_counter()
        if kwargs:
            qp.update(**kwargs)
        t1 = time.perf_counter()
        self._run(qp, problem, guess)
        t2 = time.perf_counter()
        if guess is not None:
            # solve(x, y, z) leaves the object's setting at WARM_START: back to its hot start
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        return self._result(qp, problem, t1 - t0, t2 - t1)

    @staticmethod
    def _run(qp: Any, problem: Problem, guess: Guess | None) -> None:
        if guess is None:
            qp.solve()
            return
        # With box constraints, ProxQP 0.8's dense warm start rejects the n_in + n duals and
        # corrupts memory when given the n_in inequality duals alone: pass no z there.
        qp.solve(guess.x, guess.y, None if problem.has_box else guess.z)

    def _result(self, qp: Any, problem: Problem, setup: float, wall: float) -> Solution:
        res = qp.results
        info = res.info
        n_in = problem.n_in
        z = np.array(res.z)
        timed = bool(qp.settings.compute_timings)
        return Solution(
            status=_STATUS.get(info.status, SolutionStatus.FAILED),
            x=np.array(res.x),
            y=np.array(res.y),
            z=z[:n_in],
            z_box=z[n_in:] if problem.has_box else None,
            iterations=int(info.iter_ext),
            wall_time=wall,
            setup_time=setup,
            internal_time=info.solve_time * 1e-6 if timed else None,
            message=str(info.status).rsplit(".", 1)[-1],
        )
