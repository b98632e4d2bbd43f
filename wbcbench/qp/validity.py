"""An independent check of a solution, whatever status the solver reported.

Sign convention (the one :class:`~wbcbench.qp.solution.Solution` uses): Lagrangian
``L = ½xᵀHx + gᵀx + yᵀ(Ax − b) + zᵀCx + z_boxᵀx``, so the KKT conditions read

* stationarity: ``Hx + g + Aᵀy + Cᵀz + z_box = 0``;
* dual feasibility: ``z_i > 0`` only where ``u_i`` is finite, ``z_i < 0`` only where ``l_i``
  is finite (same for ``z_box`` with ``ub``/``lb``);
* a zero duality gap ``xᵀHx + gᵀx + bᵀy + Σ (u_i z_i⁺ + l_i z_i⁻) + Σ (ub_j z_box_j⁺ +
  lb_j z_box_j⁻) = 0`` (``v⁺ = max(v, 0)``, ``v⁻ = min(v, 0)``), which with the two above is
  complementary slackness.

The residuals are absolute and measured in the infinity norm, as in qpbenchmark:

* primal residual ``max(‖Ax − b‖∞, [Cx − u]⁺, [l − Cx]⁺, [x − ub]⁺, [lb − x]⁺)``;
* dual residual ``max(‖stationarity‖∞, dual-feasibility violation)``;
* duality gap ``|…|`` as above.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from wbcbench.qp.problem import Problem
from wbcbench.qp.solution import Solution, SolutionStatus

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Validity:
    """Residuals of a solution (absolute, infinity norm) and the verdict against ``tol``.

    Attributes:
        primal_residual: max constraint violation; ``inf`` when there is no ``x``.
        dual_residual: KKT stationarity and dual-sign violation, ``None`` without duals.
        duality_gap: ``|primal − dual objective|``, ``None`` without duals.
        tol: tolerance applied to the primal residual.
        dual_tol: tolerance applied to the dual residual and the duality gap.
        ok: every available measure is within its tolerance.
        message: the first measure that is not, e.g. ``"primal residual 1.2e-02 > 1e-06"``.
        x: the checked primal solution (for :meth:`distance_to`).
    """

    primal_residual: float
    dual_residual: float | None
    duality_gap: float | None
    tol: float
    dual_tol: float
    ok: bool
    message: str
    x: Array | None

    def distance_to(self, reference_x: Array) -> float:
        """``‖x − reference_x‖∞``, e.g. to a high-accuracy reference solution (``inf`` if no x)."""
        if self.x is None:
            return float("inf")
        return float(np.max(np.abs(self.x - reference_x), initial=0.0))


def primal_residual(problem: Problem, x: Array) -> float:
    """Max violation of equalities, inequalities and bounds at ``x`` ``(n,)``."""
    return _primal_residual(problem, x, problem.A @ x, problem.C @ x)


def _primal_residual(problem: Problem, x: Array, Ax: Array, Cx: Array) -> float:
    parts = [0.0]
    if problem.n_eq:
        parts.append(float(np.max(np.abs(Ax - problem.b))))
    if problem.n_in:
        parts.append(float(np.max(Cx - problem.u)))
        parts.append(float(np.max(problem.l - Cx)))
    if problem.lb is not None and problem.n:
        parts.append(float(np.max(problem.lb - x)))
    if problem.ub is not None and problem.n:
        parts.append(float(np.max(x - problem.ub)))
    return max(parts)


def _support(z: Array, lo: Array, hi: Array) -> tuple[float, float]:
    """``Σ hi_i z_i⁺ + lo_i z_i⁻`` over finite sides, and the dual-sign violation."""
    zp, zm = np.maximum(z, 0.0), np.minimum(z, 0.0)
    fin_hi, fin_lo = np.isfinite(hi), np.isfinite(lo)
    term = float(hi[fin_hi] @ zp[fin_hi] + lo[fin_lo] @ zm[fin_lo])
    viol = max(
        float(np.max(zp[~fin_hi], initial=0.0)),
        float(np.max(-zm[~fin_lo], initial=0.0)),
    )
    return term, viol


def dual_measures(problem: Problem, sol: Solution) -> tuple[float | None, float | None]:
    """``(dual residual, duality gap)`` of ``sol``, or ``(None, None)`` without enough duals."""
    if sol.x is None:
        return None, None
    terms = _dual_terms(problem, sol, sol.x, problem.H @ sol.x)
    return (None, None) if terms is None else (terms.dual, abs(terms.gap))


@dataclass(frozen=True)
class _DualTerms:
    dual: float  # the dual residual
    gap: float  # the signed duality gap
    ATy: Array
    CTz: Array
    support: float  # the bounds' terms of the gap


def _dual_terms(problem: Problem, sol: Solution, x: Array, Hx: Array) -> _DualTerms | None:
    """The dual measures and the products they are built of, None without enough duals."""
    y = sol.y if sol.y is not None else (np.zeros(0) if problem.n_eq == 0 else None)
    z = sol.z if sol.z is not None else (np.zeros(0) if problem.n_in == 0 else None)
    if y is None or z is None or (problem.has_box and sol.z_box is None):
        return None
    ATy, CTz = problem.A.T @ y, problem.C.T @ z
    stat = Hx + problem.g + ATy + CTz
    gap = float(x @ Hx + problem.g @ x + problem.b @ y)
    support, viol = _support(z, problem.l, problem.u)
    if problem.has_box:
        assert sol.z_box is not None
        stat = stat + sol.z_box
        lb, ub = problem.box()
        term_box, viol_box = _support(sol.z_box, lb, ub)
        support += term_box
        viol = max(viol, viol_box)
    gap += support
    dual = max(float(np.max(np.abs(stat), initial=0.0)), viol)
    return _DualTerms(dual, gap, ATy, CTz, support)


def check_solution(
    problem: Problem,
    solution: Solution,
    tol: float = 1e-6,
    dual_tol: float | None = None,
) -> Validity:
    """Check ``solution`` against ``problem`` independently of its reported status.

    Args:
        problem: the QP that was solved.
        solution: what the backend returned.
        tol: bound on the primal residual.
        dual_tol: bound on the dual residual and the duality gap (defaults to ``tol``). Both
            are absolute, so scale them with the problem's magnitudes.

    Returns:
        The residuals and the verdict; measures the backend's duals do not allow are ``None``
        and do not count against ``ok``.
    """
    dual_tol = tol if dual_tol is None else dual_tol
    x = solution.x
    if x is None or x.shape != (problem.n,) or not np.all(np.isfinite(x)):
        return Validity(float("inf"), None, None, tol, dual_tol, False, "no primal solution", x)
    prim = primal_residual(problem, x)
    dual, gap = dual_measures(problem, solution)
    message = ""
    if prim > tol:
        message = f"primal residual {prim:.1e} > {tol:g}"
    elif dual is not None and dual > dual_tol:
        message = f"dual residual {dual:.1e} > {dual_tol:g}"
    elif gap is not None and gap > dual_tol:
        message = f"duality gap {gap:.1e} > {dual_tol:g}"
    return Validity(prim, dual, gap, tol, dual_tol, not message, message, x)


def validated(
    problem: Problem,
    solution: Solution,
    tol: float = 1e-6,
    dual_tol: float | None = None,
) -> Solution:
    """A copy of ``solution`` whose status also reflects :func:`check_solution`.

    A solution reported ``solved`` that fails the check becomes ``failed`` with the message
    ``"reported solved but <measure> <value> > <tol>"``; other statuses are kept as reported.
    """
    if not solution.success:
        return solution
    validity = check_solution(problem, solution, tol, dual_tol)
    if validity.ok:
        return solution
    return replace(
        solution,
        status=SolutionStatus.FAILED,
        message=f"reported solved but {validity.message}",
    )


def _inf_norm(*parts: Array | float) -> float:
    return max((float(np.max(np.abs(p), initial=0.0)) for p in parts), default=0.0)


def relative_kkt(problem: Problem, sol: Solution) -> tuple[float, float | None, float | None]:
    """``(primal, dual, gap)`` residuals of ``sol`` relative to the problem's scale, as OSQP and
    ProxQP measure their own stopping criteria:

    * primal: the primal residual over ``1 + max(‖Ax‖∞, ‖b‖∞, ‖Cx‖∞, finite ‖l‖∞, ‖u‖∞, the
      bounds and ‖x‖∞ where there are bounds)``;
    * dual: the dual residual over ``1 + max(‖Hx‖∞, ‖g‖∞, ‖Aᵀy‖∞, ‖Cᵀz‖∞, ‖z_box‖∞)``;
    * gap: the duality gap over ``1 + max(|xᵀHx|, |gᵀx|, |bᵀy|, |the support terms|)``.

    ``inf`` primal when there is no finite x; ``None`` for what the backend's duals do not allow.
    A shift of 0.5 N·m in a torque that the dynamics rows of a whole-body QP (scale ~10²) tie to
    the other variables is a relative primal residual of ~5e-3.
    """
    x = sol.x
    if x is None or x.shape != (problem.n,) or not np.all(np.isfinite(x)):
        return float("inf"), None, None
    Ax, Cx = problem.A @ x, problem.C @ x
    scale = [Ax, problem.b, Cx]
    for side in (problem.l, problem.u, problem.lb, problem.ub):
        if side is not None and side.size:
            scale.append(side[np.isfinite(side)])
    if problem.has_box:
        scale.append(x)
    prim = _primal_residual(problem, x, Ax, Cx) / (1.0 + _inf_norm(*scale))
    Hx = problem.H @ x
    d = _dual_terms(problem, sol, x, Hx)
    if d is None:
        return prim, None, None
    parts = [Hx, problem.g, d.ATy, d.CTz]
    if sol.z_box is not None:
        parts.append(sol.z_box)
    dual = d.dual / (1.0 + _inf_norm(*parts))
    y = sol.y if sol.y is not None else np.zeros(0)
    terms = [float(x @ Hx), float(problem.g @ x), float(problem.b @ y), d.support]
    gap = abs(d.gap) / (1.0 + max(abs(t) for t in terms))
    return prim, dual, gap


def feasibility_margin(problem: Problem) -> float:
    """How far inside its bounds the QP's feasible set reaches: the largest t ≤ 1 for which some
    x meets ``A x = b`` and every finite bound with ``t (1 + |bound|)`` to spare
    (``l + t (1 + |l|) ≤ C x ≤ u − t (1 + |u|)``, the same for ``lb``, ``ub``), from one LP
    (HiGHS through SciPy).

    The units are those of the widening of :mod:`wbcbench.qp.hierarchy` (``FEAS_TOL``): a
    level QP whose held rows leave no interior has a margin equal to its widening (about 1e-9
    per level), a level with room to spare one of order 1; negative: infeasible by that much
    (the bounds must be widened by ``−t (1 + |bound|)`` to admit an x). 1 with no finite
    bound, NaN when the LP solver fails. The LP is solved to 1e-10: margins below about 1e-10
    are not resolved.
    """
    from scipy.optimize import linprog

    n = problem.n
    blocks = [(problem.C, problem.l, problem.u)]
    if problem.has_box:
        lower = problem.lb if problem.lb is not None else np.full(n, -np.inf)
        upper = problem.ub if problem.ub is not None else np.full(n, np.inf)
        blocks.append((np.eye(n), lower, upper))
    rows: list[Array] = []
    rhs: list[Array] = []
    for C, lo, hi in blocks:
        up, down = np.isfinite(hi), np.isfinite(lo)
        # C x + t (1 + |u|) ≤ u and −C x + t (1 + |l|) ≤ −l over (x, t)
        rows += [np.hstack([C[up], 1.0 + np.abs(hi[up, None])])]
        rows += [np.hstack([-C[down], 1.0 + np.abs(lo[down, None])])]
        rhs += [hi[up], -lo[down]]
    A_ub = np.vstack(rows) if rows else np.zeros((0, n + 1))
    if not A_ub.shape[0]:
        return 1.0
    cost = np.zeros(n + 1)
    cost[-1] = -1.0  # maximise t
    A_eq = np.hstack([problem.A, np.zeros((problem.n_eq, 1))]) if problem.n_eq else None
    tight = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
    # HiGHS's presolve can end in an unknown status at tight tolerances on these thin sets
    for options in (tight, {**tight, "presolve": False}, {}):
        res = linprog(
            cost,
            A_ub=A_ub,
            b_ub=np.concatenate(rhs),
            A_eq=A_eq,
            b_eq=problem.b if problem.n_eq else None,
            bounds=[(None, None)] * n + [(None, 1.0)],
            method="highs",
            options=options,
        )
        if res.status == 0:
            return float(-res.fun)
    return float("nan")
