"""Independent checks of what a QP backend reports, shared by every path that steps a controller:
``wbcbench run``, the sweeps' closed-loop runs and the timing replays.

A controller's solver handles are wrapped (:class:`SolverCapture`) so every (problem, solution)
of a step is kept (a native tick that solves a handle's QPs in C++ adds copies of them and of
the answers after its timed region); after the step, outside the controller's timed stages,
every QP the backend reported ``solved`` must meet its KKT conditions (:func:`check_reported`):
the primal residual, and where the backend gives duals the dual residual and the duality gap,
each relative to the problem's scale (:func:`~wbcbench.qp.validity.relative_kkt`), within
``factor`` × the accuracy the run's tier asks of that backend (at the ``default`` tier, the
accuracy of the backend's own settings: :meth:`~wbcbench.qp.QPSolver.accuracy`). A failure reads
``reported solved but relative <measure> <value> > <limit> (<solver>, <QP name>)``.

The check costs about 50 µs a QP (the residuals in NumPy), outside the timed stages; a native
tick copies its C++-solved QPs and answers for it (a few µs a QP, also taken out of its time).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from wbcbench.errors import WbcBenchError
from wbcbench.qp import Problem, Solution, make_solver
from wbcbench.qp.base import QPSolver
from wbcbench.qp.registry import solver_class
from wbcbench.qp.validity import relative_kkt

#: the default margin over the tier's accuracy (a backend stops when its own, differently
#: scaled, measures meet the tolerance; relative to the problem's scale they sit within a few
#: times it)
CHECK_FACTOR = 10.0


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
        # native ticks that solve a handle's QPs in C++ add copies of those QPs and answers
        # here after their timed region (controllers.native)
        self.sink = sink

    def solve(self, problem: Problem, *args: Any, **kwargs: Any) -> Solution:
        sol = self._inner.solve(problem, *args, **kwargs)
        self.sink.append((problem, sol))
        return sol

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


#: round-off floor of the optimality measures: whole-body QPs weigh their objectives over up to
#: nine decades, and an exact active-set backend (quadprog) leaves dual residuals and gaps up
#: to ~2e-6 of the problem's scale on the hierarchies' nearly degenerate levels
OPTIMALITY_FLOOR = 1e-6


def check_reported(pairs: list[tuple[Problem, Solution]], factor: float) -> str:
    """The first QP reported solved whose relative KKT residuals exceed their limits, as a
    message ("" when every one passes).

    Limits, with ``eps`` the accuracy the solution's tier asks of its backend
    (:meth:`~wbcbench.qp.QPSolver.accuracy`): the primal residual ``factor × eps``; the dual
    residual ``factor × max(eps, OPTIMALITY_FLOOR)``; the duality gap the same, at the tiers that
    set a gap tolerance (not ``default``: ProxQP and OSQP do not stop on the gap by default).

    Duals are a certificate, not the answer: a feasible x whose duals miss their limit gets a
    second opinion (:func:`objective_excess`): it passes when its objective is within the same
    limit of a reference backend's optimum (measured: HiGHS returns optimal x with duals
    stationary to only 4e-4 of the scale; DAQP once returned x 14 % above the optimum as solved,
    with duals 1e-2 off).
    """
    for problem, sol in pairs:
        if not sol.success:
            continue
        eps = _accuracy(sol)
        prim, dual, gap = relative_kkt(problem, sol)
        where = f"({sol.solver}, {problem.name or 'QP'})"
        if not prim <= factor * eps:
            return (
                f"reported solved but relative primal residual {prim:.1e} > "
                f"{factor * eps:.0e} {where}"
            )
        optimality = factor * max(eps, OPTIMALITY_FLOOR)
        checks = [("dual residual", dual)]
        if sol.tier != "default":
            checks.append(("duality gap", gap))
        for what, value in checks:
            if value is not None and not value <= optimality:
                excess, reference = objective_excess(problem, sol)
                if excess <= optimality:
                    break
                return (
                    f"reported solved but relative {what} {value:.1e} > {optimality:.0e}, "
                    f"objective {excess:.1e} above {reference}'s {where}"
                )
    return ""


#: backends that give the second opinion, in order (the first that solves the QP)
REFERENCES = ("quadprog", "clarabel")


def objective_excess(problem: Problem, sol: Solution) -> tuple[float, str]:
    """How far ``sol``'s objective lies above a reference backend's optimum of ``problem``,
    relative to 1 + the largest of the objective's terms, and the reference's name; ``inf``
    when no reference solves it."""
    assert sol.x is not None

    def objective(x: np.ndarray) -> tuple[float, float]:
        quad, lin = 0.5 * float(x @ problem.H @ x), float(problem.g @ x)
        return quad + lin, max(abs(quad), abs(lin))

    for name in REFERENCES:
        try:
            ref = make_solver(name, tier="high").solve(problem)
        except (WbcBenchError, ValueError):
            continue
        if ref.success and ref.x is not None:
            f, scale = objective(sol.x)
            f_ref, scale_ref = objective(ref.x)
            return (f - f_ref) / (1.0 + max(scale, scale_ref)), name
    return float("inf"), "every reference backend"


def _accuracy(sol: Solution) -> float:
    try:
        return solver_class(sol.solver).accuracy(sol.tier)
    except WbcBenchError:  # a solution of no registered backend: the tier's, or the default
        return QPSolver.accuracy(sol.tier)


class ReportedCheck:
    """``wrap_solver`` and ``check`` for a closed-loop run (:func:`run_closed_loop`)."""

    def __init__(self, factor: float) -> None:
        self.factor = factor
        self.pairs: list[tuple[Problem, Solution]] = []

    def wrap(self, handle: Any) -> SolverCapture:
        return SolverCapture(handle, self.pairs)

    def __call__(self, out: Any) -> str:
        message = check_reported(self.pairs, self.factor)
        self.pairs.clear()
        return message
