"""Independent checks of what a QP backend reports, shared by the timing and closed-loop runs.

A controller's solver handles are wrapped (:class:`SolverCapture`) so every (problem, solution)
of a step is kept; after the step, outside the controller's timed stages, every QP the backend
reported ``solved`` must have a primal residual below ``tol`` × the magnitude of its data
(:func:`check_reported`). A failure reads ``reported solved but <measure> <value> > <limit>
(<solver>, <QP name>)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from wbcbench.qp import Problem, Solution, check_solution


def data_scale(problem: Problem) -> float:
    """The magnitude of a problem's data: max(1, |g|, |b|, finite |l|, |u|, |lb|, |ub|)."""
    parts = [1.0, *(float(np.max(np.abs(v), initial=0.0)) for v in (problem.g, problem.b))]
    for v in (problem.l, problem.u, problem.lb, problem.ub):
        if v is not None and v.size:
            finite = v[np.isfinite(v)]
            parts.append(float(np.max(np.abs(finite), initial=0.0)))
    return max(parts)


class SolverCapture:
    """A solver handle that remembers each (problem, solution) of the current step."""

    def __init__(self, inner: Any, sink: list[tuple[Problem, Solution]]) -> None:
        self._inner = inner
        self._sink = sink

    def solve(self, problem: Problem, *args: Any, **kwargs: Any) -> Solution:
        sol = self._inner.solve(problem, *args, **kwargs)
        self._sink.append((problem, sol))
        return sol

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


def check_reported(pairs: list[tuple[Problem, Solution]], tol: float) -> str:
    """The first QP reported solved whose primal residual exceeds ``tol`` × its data scale."""
    for problem, sol in pairs:
        if not sol.success:
            continue
        limit = tol * data_scale(problem)
        v = check_solution(problem, sol, tol=limit, dual_tol=float("inf"))
        if not v.ok:
            return f"reported solved but {v.message} ({sol.solver}, {problem.name or 'QP'})"
    return ""


class ReportedCheck:
    """``wrap_solver`` and ``check`` for a closed-loop run (:func:`run_closed_loop`)."""

    def __init__(self, tol: float) -> None:
        self.tol = tol
        self.pairs: list[tuple[Problem, Solution]] = []

    def wrap(self, handle: Any) -> SolverCapture:
        return SolverCapture(handle, self.pairs)

    def __call__(self, out: Any) -> str:
        message = check_reported(self.pairs, self.tol)
        self.pairs.clear()
        return message
