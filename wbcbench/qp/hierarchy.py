"""Lexicographic (prioritized) least squares over one decision vector, by four strategies.

A hierarchy is: hard constraints that hold at every level, soft priority levels (each a least-
squares equality part ``‖A x − b‖²`` and a minimal-violation inequality part ``l ≤ C x − v ≤ u``,
``‖v‖²``), then final objectives ``‖F x − f‖²`` that resolve what redundancy is left.

Strategies:

* ``cascade`` — the conventional HQP (OSF-HQP paper §II, eq. 2–15): one QP per level over the
  full variable and that level's slacks, every hard constraint and every previous level's
  inequalities (with their optimal slacks) kept, every previous equality held at its optimum.
  The held equalities are kept as an orthonormal basis of their row space, evaluated at the
  previous level's solution: the same feasible set as fixing each slack, but never a rank-
  deficient or slightly inconsistent equality system for the solver.
* ``nullspace`` — the "sequential method": the previous equalities are eliminated, x = x_p + Z y
  with Z an orthonormal null-space basis (rank-revealing QR), so each level's QP is over y and the
  level's inequality slacks only; previous inequalities kept with fixed slacks.
* ``weighted`` — one QP: Σ weight_l (‖A_l x − b_l‖² + ‖v_l‖²) + Σ weight ‖F x − f‖².
* ``rqr`` — the regularised reduced-QR hierarchical least squares of :mod:`wbcbench.qp.hls`
  (active set per level, no QP solver); hard constraints become its first level. Within a level
  it gives the inequalities precedence over the equalities (RQR-HQP §III-B), where the QP
  strategies minimise both slacks jointly: the answers differ only when a level's own
  inequalities and equalities conflict.

Cascade and nullspace give the same solution whenever the finals determine it uniquely.

Two options of the sequential strategies save QPs without changing the solution they define:

* ``merge_finals`` — the finals' weighted ``weight ‖F x − f‖²`` is added to the last level's cost
  instead of a QP of its own (RC-LQP paper eq. 28: the acceleration energy is part of the LQP's
  cost, not a priority). The last level's optimum moves by O(weight).
* ``PriorityLevel.hard_if_feasible`` (null-space strategy) — when a level can be met exactly
  together with the levels above (zero slacks), its optimal set is its feasible set: the level is
  then held as hard constraints inside the next level's QP (if that level has no inequalities of
  its own), one QP for both. The level is solved on its own only when that QP is infeasible.
  Meant for constraint levels (contacts, wrench cones, limits), which are met in all but extreme
  states.
* ``slack_free_first`` — a level with inequalities of its own is first solved with them hard (no
  slack variables). When that QP is feasible and the multipliers of the level's inequalities
  vanish, (x, v = 0) satisfies the optimality conditions of the slack QP, so it is its optimum;
  otherwise the slack QP is solved as usual.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

from wbcbench.dynamics.dense import upper
from wbcbench.errors import UnknownNameError
from wbcbench.qp.base import QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.solution import Solution, SolutionStatus, SolveTimes

Array = np.ndarray
Strategy = Literal["cascade", "nullspace", "weighted", "rqr"]
#: the strategies, with one line each for `wbcbench list`
STRATEGY_SUMMARY: dict[str, str] = {
    "cascade": "one QP per level over the full variable, slacks of the levels above held",
    "nullspace": "levels above eliminated by a null-space basis (the sequential method)",
    "weighted": "one QP, levels weighted",
    "rqr": "regularised reduced-QR hierarchical least squares with active sets (no QP solver)",
}
STRATEGIES: tuple[str, ...] = tuple(STRATEGY_SUMMARY)
RANK_TOL = 1e-10
#: At level i (0-based) inequality bounds are widened by (i FEAS_TOL + carried) (1 + |bound|):
#: the previous optimum meets them only to the solver's tolerance, and with the held equalities
#: leaving few directions free, a violation of 1e-10 would make the next QP infeasible. "carried"
#: is the largest relative violation the levels above actually left (measured, see
#: :func:`_carried_violation`): a solver of modest accuracy (an ADMM or interior-point method at
#: its default tolerance) leaves more than i FEAS_TOL.
FEAS_TOL = 1e-9
#: A level's answer is accepted only when it meets the hard constraints and the inequalities of
#: the levels above (as widened for its QP) to ACCEPT_FACTOR × the accuracy its backend was asked
#: for, relative to the problem's scale (:func:`_held_excess`): a backend can report "optimal"
#: for a point
#: outside its QP's bounds (DAQP, after declaring a feasible level QP infeasible, on the proximal
#: retry), and the widening of the levels below would then carry that violation on and enlarge it.
ACCEPT_FACTOR = 10.0
#: ... and never below ACCEPT_FLOOR: an active-set solver's answer on an ill-conditioned level
#: leaves violations of its held rows well above its tier's tolerance but at rounding of the
#: problem's scale (measured up to 6e-8 with DAQP under three BLAS kernels), while the answers
#: this check exists to refuse lie 8e-6 and more outside
ACCEPT_FLOOR = 1e-6


def accept_tol(solver: object) -> float:
    """How far (relative to the problem's scale, :func:`_held_excess`) a level's answer from
    ``solver`` may lie outside the bounds its QP held hard: :data:`ACCEPT_FACTOR` × the accuracy
    of the handle's tier, at least :data:`ACCEPT_FLOOR`."""
    accuracy = getattr(solver, "accuracy", QPSolver.accuracy)
    return accept_tol_for(float(accuracy(getattr(solver, "tier", "default"))))


def accept_tol_for(accuracy: float) -> float:
    """:func:`accept_tol` for a backend asked for ``accuracy``."""
    return max(ACCEPT_FLOOR, ACCEPT_FACTOR * accuracy)


def _widen(lower: Array, upper: Array, relax: float) -> tuple[Array, Array]:
    if not relax:
        return lower, upper
    return lower - relax * (1.0 + np.abs(lower)), upper + relax * (1.0 + np.abs(upper))


def _rows(M: Array | None, n: int) -> Array:
    return np.zeros((0, n)) if M is None else np.atleast_2d(np.asarray(M, dtype=float))


def _vec(v: Array | None, m: int, fill: float = 0.0) -> Array:
    return np.full(m, fill) if v is None else np.asarray(v, dtype=float).reshape(m)


@dataclass
class Constraints:
    """Hard constraints (hold at every level): A x = b, l ≤ C x ≤ u, lb ≤ x ≤ ub."""

    n: int
    A: Array | None = None
    b: Array | None = None
    C: Array | None = None
    l: Array | None = None  # noqa: E741 - the QP literature's symbol for the lower bound
    u: Array | None = None
    lb: Array | None = None
    ub: Array | None = None

    def __post_init__(self) -> None:
        self.A = _rows(self.A, self.n)
        self.b = _vec(self.b, self.A.shape[0])
        self.C = _rows(self.C, self.n)
        self.l = _vec(self.l, self.C.shape[0], -np.inf)
        self.u = _vec(self.u, self.C.shape[0], np.inf)


@dataclass
class PriorityLevel:
    """One soft level: minimise ‖A x − b‖² + ‖v‖² with l ≤ C x − v ≤ u."""

    name: str
    A: Array | None = None
    b: Array | None = None
    C: Array | None = None
    l: Array | None = None  # noqa: E741 - the QP literature's symbol for the lower bound
    u: Array | None = None
    weight: float = 1.0
    #: null-space strategy: held as hard constraints when the next level's QP is feasible with
    #: them hard (then their optimal slacks are zero), one QP for both levels
    hard_if_feasible: bool = False

    def prepared(self, n: int) -> PriorityLevel:
        A = _rows(self.A, n)
        C = _rows(self.C, n)
        return PriorityLevel(
            self.name,
            A,
            _vec(self.b, A.shape[0]),
            C,
            _vec(self.l, C.shape[0], -np.inf),
            _vec(self.u, C.shape[0], np.inf),
            self.weight,
            self.hard_if_feasible,
        )


@dataclass
class Objective:
    """A final level: minimise ‖F x − f‖² over what the levels above leave free."""

    name: str
    F: Array
    f: Array
    weight: float = 1.0

    def as_level(self) -> PriorityLevel:
        return PriorityLevel(self.name, A=self.F, b=self.f, weight=self.weight)


@dataclass
class LevelResult:
    """Optimal slacks of one level: w = A x − b (m,), v = inequality violation (r,)."""

    name: str
    w: Array
    v: Array
    solution: Solution | None
    time: float


@dataclass
class HierarchyResult:
    """The solution; ``retries`` counts levels re-solved with the proximal term."""

    x: Array
    ok: bool
    message: str = ""
    levels: list[LevelResult] = field(default_factory=list)
    retries: int = 0


# -- linear algebra --------------------------------------------------------------------------


def _qr_pivoted(B: Array) -> tuple[Array, Array, Array]:
    """Column-pivoted Householder QR of B (n, p): full Q (n, n), R (min(n, p), p), 0-based
    pivots; LAPACK called directly (scipy.linalg.qr's checks and workspace queries cost as much
    as the factorisation at these sizes)."""
    n, p = B.shape
    qr, jpvt, tau, _, _ = lapack.dgeqp3(B)
    k = min(n, p)
    F = np.zeros((n, n), order="F")
    F[:, :k] = qr[:, :k]
    Q, _, _ = lapack.dorgqr(F, tau[:k])
    return Q, upper(qr[:k]), jpvt - 1


def row_space_and_null_space(E: Array, tol: float = RANK_TOL) -> tuple[Array, Array]:
    """Orthonormal bases (R, Z) of the row space and null space of E (p, n).

    R is (rank, n) with orthonormal rows spanning E's rows; Z is (n, n − rank). From a column-
    pivoted Householder QR of Eᵀ.
    """
    n = E.shape[1]
    if E.shape[0] == 0 or n == 0:  # (LAPACK rejects an empty factorisation)
        return np.zeros((0, n)), np.eye(n)
    Q, R, _ = _qr_pivoted(E.T)
    diag = np.abs(np.diag(R))
    rank = int(np.sum(diag > tol * max(1.0, diag[0]))) if diag.size else 0
    return Q[:, :rank].T, Q[:, rank:]


def _null_projector(A: Array) -> Array:
    """Orthogonal projector onto null(A), (n, n)."""
    R, _ = row_space_and_null_space(A)
    return np.eye(A.shape[1]) - R.T @ R


def _relative_violation(Cx: Array, lower: Array, upper: Array) -> float:
    """max over rows of how far C x lies outside [l, u], relative to 1 + |bound| (0 inside)."""
    if not Cx.size:
        return 0.0
    with np.errstate(invalid="ignore"):  # an infinite bound gives NaN, which fmax skips
        below = (lower - Cx) / (1.0 + np.abs(lower))
        above = (Cx - upper) / (1.0 + np.abs(upper))
    return float(max(0.0, np.fmax.reduce(below), np.fmax.reduce(above)))  # NaN never wins


def _held_rows(
    x: Array, hard: Constraints, prev_C: list[Array], prev_lo: list[Array], prev_hi: list[Array]
) -> Iterator[tuple[Array, Array, Array]]:
    """(C x, lower, upper) of each block of inequalities the levels hold: the hard constraints'
    rows, the box (as x against its bounds) and the levels above's rows."""
    if hard.C is not None and hard.C.shape[0]:
        assert hard.l is not None and hard.u is not None
        yield hard.C @ x, hard.l, hard.u
    if hard.lb is not None or hard.ub is not None:
        lower = hard.lb if hard.lb is not None else np.full(x.size, -np.inf)
        upper = hard.ub if hard.ub is not None else np.full(x.size, np.inf)
        yield x, lower, upper
    for C, lo, hi in zip(prev_C, prev_lo, prev_hi, strict=True):
        yield C @ x, lo, hi


def _carried_violation(
    x: Array, hard: Constraints, prev_C: list[Array], prev_lo: list[Array], prev_hi: list[Array]
) -> float:
    """The largest relative violation x leaves on the inequalities the next levels inherit (the
    level just solved is not among them: its rows are held shifted by its own slacks, which x
    meets by construction)."""
    rows = _held_rows(x, hard, prev_C, prev_lo, prev_hi)
    return max((_relative_violation(Cx, lo, hi) for Cx, lo, hi in rows), default=0.0)


def _violation(Cx: Array, lower: Array, upper: Array) -> Array:
    """Signed slack v that puts C x − v inside [l, u] with the smallest |v|."""
    return np.where(Cx > upper, Cx - upper, np.where(Cx < lower, Cx - lower, 0.0))


def _excess(Cx: Array, lower: Array, upper: Array, relax: float) -> tuple[float, float]:
    """How far C x lies outside [l, u] widened by ``relax`` × (1 + |bound|) (0 inside), and the
    rows' scale: the largest |C x| and finite |bound|."""
    if not Cx.size:
        return 0.0, 0.0
    with np.errstate(invalid="ignore"):  # an infinite bound gives NaN, which fmax skips
        below = lower - relax * (1.0 + np.abs(lower)) - Cx
        above = Cx - upper - relax * (1.0 + np.abs(upper))
    values = np.concatenate([Cx, lower, upper])
    scale = float(np.abs(values[np.isfinite(values)]).max(initial=0.0))
    return float(max(0.0, np.fmax.reduce(below), np.fmax.reduce(above))), scale


def _held_excess(
    x: Array,
    hard: Constraints,
    prev_C: list[Array],
    prev_lo: list[Array],
    prev_hi: list[Array],
    relax: float,
) -> float:
    """The largest violation x leaves on the hard constraints and the held inequalities beyond
    the ``relax`` widening, relative to 1 + the problem's scale (the largest |A x|, |b|, |C x|,
    finite |bound| and, with a box, |x|): the relative primal residual that the independent
    check of reported solutions measures (:func:`wbcbench.qp.validity.relative_kkt`). An
    active-set solver's answer on an ill-conditioned level leaves up to 2e-7 of 1 + |bound| on
    a row (measured: DAQP and quadprog, under some BLAS kernels), which the whole problem's
    scale puts at rounding; a wrong answer stands out against it."""
    parts: list[tuple[float, float]] = []
    if hard.A is not None and hard.b is not None and hard.A.shape[0]:
        # the equality rows' scale (the rows themselves are met by construction)
        parts.append((0.0, float(max(np.abs(hard.A @ x).max(), np.abs(hard.b).max()))))
    rows = _held_rows(x, hard, prev_C, prev_lo, prev_hi)
    parts += [_excess(Cx, lo, hi, relax) for Cx, lo, hi in rows]
    if not parts:
        return 0.0
    return max(v for v, _ in parts) / (1.0 + max(scale for _, scale in parts))


def _checked(
    sol: Solution,
    x: Array | None,
    hard: Constraints,
    prev_C: list[Array],
    prev_lo: list[Array],
    prev_hi: list[Array],
    relax: float,
    solver: object,
) -> tuple[Solution, Array | None]:
    """``(sol, x)``, or a failed copy of ``sol`` and None when x leaves the hard constraints or
    the held inequalities violated beyond the ``relax`` widening of the QP by more than
    :func:`accept_tol`: the backend's status is not taken on trust."""
    if x is None or not sol.success:
        return sol, x
    tol = accept_tol(solver)
    excess = _held_excess(x, hard, prev_C, prev_lo, prev_hi, relax)
    if excess <= tol:
        return sol, x
    message = (
        "reported solved but violates a bound or a held inequality by "
        f"{excess:.1e} > {tol:.0e} (relative to the problem's scale)"
    )
    return replace(sol, status=SolutionStatus.FAILED, message=message), None


# -- the strategies ----------------------------------------------------------------------------


def solve_hierarchy(
    hard: Constraints,
    levels: list[PriorityLevel],
    finals: list[Objective],
    strategy: str,
    solvers: list[QPSolver] | None = None,
    timer: SolveTimes | None = None,
    prox: float = 0.0,
    merge_finals: bool = False,
    slack_free_first: bool = False,
) -> HierarchyResult:
    """Solve the hierarchy; ``solvers`` holds one QP handle per level then per final.

    With ``slack_free_first`` a second set of handles, ``solvers[len(levels) + len(finals):]``,
    is used for the slack QPs when given (hot solvers then keep one problem structure each).
    ``merge_finals`` and ``slack_free_first`` apply to the cascade and null-space strategies
    (see the module docstring); ``merge_finals`` needs at least one level.

    ``prox`` > 0: a level whose QP the backend fails to solve is solved again with
    ``prox ‖P_l (x − x_c)‖²`` added (cascade and null-space strategies), P_l the projector onto
    the null space of the level's rows and x_c the previous
    level's solution (the hard equalities' minimum-norm solution at the first level). Without it
    a level's QP has a semidefinite Hessian and often an unbounded set of optima (internal
    contact forces, say), on which several backends fail; with it each level has one optimum,
    the same for both strategies. It leaves the level's objective untouched, so the level's
    optimum moves only through the inequalities (by about ``prox ‖x − x_c‖`` when x_c is
    infeasible); higher levels stay exact (they are held).

    An answer the backend reports solved counts as a failure (retried as above, then the
    hierarchy fails with the reason) when it leaves a hard constraint or a held inequality
    violated beyond the QP's widening by more than :func:`accept_tol`.
    """
    if strategy not in STRATEGIES:
        raise UnknownNameError("hierarchy strategy", strategy, STRATEGIES)
    n = hard.n
    soft = [lv.prepared(n) for lv in levels] + [f.as_level().prepared(n) for f in finals]
    n_finals = len(finals)
    if strategy == "rqr":
        return _solve_rqr(hard, soft, timer)
    if solvers is None or len(solvers) < (1 if strategy == "weighted" else len(soft)):
        raise ValueError("one solver handle per level (and per final) is needed")
    if strategy == "weighted":
        return _solve_weighted(hard, soft, solvers[0], timer)
    merged: list[PriorityLevel] = []
    if merge_finals and levels and finals:
        merged = soft[len(levels) :]
        soft = soft[: len(levels)]
    return _solve_sequential(
        hard,
        soft,
        n_finals,
        solvers,
        timer,
        strategy == "nullspace",
        prox,
        merged,
        slack_free_first,
    )


def _record(timer: SolveTimes | None, sol: Solution, name: str) -> None:
    if timer is not None:
        timer.add_solution(sol, level=name)


def _solve_weighted(
    hard: Constraints, soft: list[PriorityLevel], solver: QPSolver, timer: SolveTimes | None
) -> HierarchyResult:
    n = hard.n
    r_total = sum(lv.C.shape[0] for lv in soft)  # type: ignore[union-attr]
    nx = n + r_total
    H = np.zeros((nx, nx))
    g = np.zeros(nx)
    C_rows: list[Array] = []
    lo: list[Array] = []
    hi: list[Array] = []
    col = n
    for lv in soft:
        A, C = lv.A, lv.C
        assert A is not None and C is not None
        H[:n, :n] += lv.weight * (A.T @ A)
        g[:n] -= lv.weight * (A.T @ lv.b)
        r = C.shape[0]
        if r:
            H[col : col + r, col : col + r] += lv.weight * np.eye(r)
            block = np.zeros((r, nx))
            block[:, :n] = C
            block[:, col : col + r] = -np.eye(r)
            C_rows.append(block)
            lo.append(lv.l)  # type: ignore[arg-type]
            hi.append(lv.u)  # type: ignore[arg-type]
        col += r
    problem = _with_hard(hard, H, g, C_rows, lo, hi, nx, name="weighted")
    sol = solver.solve(problem)
    sol, x = _checked(sol, None if sol.x is None else sol.x[:n], hard, [], [], [], 0.0, solver)
    _record(timer, sol, "weighted")
    if not sol.success or x is None:
        return HierarchyResult(np.zeros(n), False, f"weighted: {sol.status}: {sol.message}")
    results = [_level_result(lv, x, None, 0.0) for lv in soft]
    results[0].solution = sol
    return HierarchyResult(x, True, "", results)


def _with_hard(
    hard: Constraints,
    H: Array,
    g: Array,
    C_rows: list[Array],
    lo: list[Array],
    hi: list[Array],
    nx: int,
    name: str,
    eq_rows: list[tuple[Array, Array]] = (),  # type: ignore[assignment]
    relax: float = 0.0,
) -> Problem:
    """A QP over z = (x, extra) with the hard constraints on x plus extra rows over z.

    ``relax`` widens the hard inequalities and bounds (see FEAS_TOL).
    """
    n = hard.n
    assert hard.A is not None and hard.C is not None and hard.b is not None
    assert hard.l is not None and hard.u is not None
    pad = np.zeros((hard.A.shape[0], nx - n))
    A_blocks = [np.hstack([hard.A, pad])] + [rows for rows, _ in eq_rows]
    b_blocks = [hard.b] + [rhs for _, rhs in eq_rows]
    if hard.C.shape[0]:
        C_rows = [np.hstack([hard.C, np.zeros((hard.C.shape[0], nx - n))]), *C_rows]
        hard_l, hard_u = _widen(hard.l, hard.u, relax)
        lo = [hard_l, *lo]
        hi = [hard_u, *hi]
    lb = ub = None
    if hard.lb is not None or hard.ub is not None:
        lb = np.full(nx, -np.inf)
        ub = np.full(nx, np.inf)
        if hard.lb is not None:
            lb[:n] = hard.lb
        if hard.ub is not None:
            ub[:n] = hard.ub
        lb[:n], ub[:n] = _widen(lb[:n], ub[:n], relax)
    return Problem(
        H,
        g,
        np.vstack(A_blocks),
        np.concatenate(b_blocks),
        np.vstack(C_rows) if C_rows else np.zeros((0, nx)),
        np.concatenate(lo) if lo else np.zeros(0),
        np.concatenate(hi) if hi else np.zeros(0),
        lb,
        ub,
        name=name,
    )


def _level_result(lv: PriorityLevel, x: Array, sol: Solution | None, t: float) -> LevelResult:
    assert lv.A is not None and lv.C is not None and lv.l is not None and lv.u is not None
    w = lv.A @ x - lv.b
    v = _violation(lv.C @ x, lv.l, lv.u) if lv.C.shape[0] else np.zeros(0)
    return LevelResult(lv.name, w, v, sol, t)


def _solve_sequential(
    hard: Constraints,
    soft: list[PriorityLevel],
    n_finals: int,
    solvers: list[QPSolver],
    timer: SolveTimes | None,
    nullspace: bool,
    prox: float,
    merged: list[PriorityLevel] = (),  # type: ignore[assignment]
    slack_free_first: bool = False,
) -> HierarchyResult:
    n = hard.n
    assert hard.A is not None
    n_soft = len(soft) + len(merged)
    second = solvers[n_soft:] if len(solvers) >= 2 * n_soft else solvers
    held_rows: list[Array] = [hard.A]  # equalities held so far (hard first)
    prev_C: list[Array] = []  # previous levels' inequalities with their slacks fixed
    prev_lo: list[Array] = []
    prev_hi: list[Array] = []
    results: list[LevelResult] = []
    x: Array | None = None
    retries = 0
    Eb = np.zeros((0, n))
    e = np.zeros(0)
    assert hard.b is not None
    # one factorisation of the hard equalities: bases and the minimum-norm solution x_p
    R_hard, Z, x_p = _hard_factor(hard.A, hard.b)
    last = len(soft) - 1
    skip = False
    carried = 0.0  # relative violation the levels solved so far left (see FEAS_TOL)
    for i, lv in enumerate(soft):
        if skip:  # solved together with the level above
            skip = False
            continue
        extra = merged if i == last else []
        assert lv.A is not None and lv.C is not None and lv.l is not None and lv.u is not None
        # growing with the level, so the previous optimum is strictly inside the widened set
        relax = FEAS_TOL * i + carried
        t0 = time.perf_counter()
        nxt = soft[i + 1] if i < last else None
        if nullspace and lv.hard_if_feasible and nxt is not None and not _rows_of(nxt.C):
            pair = _feasible_pair(
                hard, lv, nxt, x_p, Z, prev_C, prev_lo, prev_hi, solvers[i], relax + FEAS_TOL,
                merged if i + 1 == last else [], timer,
            )  # fmt: skip
            if pair is not None:
                x, Z_next, sol = pair
                elapsed = time.perf_counter() - t0
                res = _level_result(lv, x, None, 0.0)
                results += [res, _level_result(nxt, x, sol, elapsed)]
                if i + 1 == last:
                    break
                assert nxt.A is not None
                held_rows += [lv.A, nxt.A]
                # (the held level's own rows, shifted by its slacks, hold at x by construction)
                carried = max(carried, _carried_violation(x, hard, prev_C, prev_lo, prev_hi))
                if lv.C.shape[0]:
                    prev_C.append(lv.C)
                    prev_lo.append(lv.l + res.v)
                    prev_hi.append(lv.u + res.v)
                Z = Z_next
                if nxt.A.shape[0]:
                    _, Zl = row_space_and_null_space(nxt.A @ Z)
                    Z = Z @ Zl
                x_p = x
                skip = True
                continue
        if not nullspace:
            E = np.vstack(held_rows[1:]) if len(held_rows) > 1 else np.zeros((0, n))
            # only the part of the held rows not already fixed by the hard equalities, so that
            # [hard A; E] keeps full row rank (dependent rows that are only consistent to the
            # solver's tolerance make active-set solvers declare the system inconsistent)
            Eb, _ = row_space_and_null_space(E - (E @ R_hard.T) @ R_hard)
            e = Eb @ x if x is not None else np.zeros(0)
        center = x if x is not None else x_p
        # the bare level first; the proximal term only when the backend fails on it
        sol, x_new = None, None
        if slack_free_first and lv.C.shape[0]:
            # the level's inequalities hard: its optimum when their multipliers vanish
            if nullspace:
                sol, x_new = _nullspace_level(
                    hard, lv, x_p, Z, prev_C, prev_lo, prev_hi, solvers[i], relax, 0.0, extra, True
                )
            else:
                sol, x_new = _cascade_level(
                    hard, lv, Eb, e, prev_C, prev_lo, prev_hi, solvers[i], relax, center, 0.0,
                    extra, True,
                )  # fmt: skip
            if sol is not None:
                _record(timer, sol, lv.name)
        if x_new is None:
            handle = second[i] if slack_free_first and lv.C.shape[0] else solvers[i]
            for eps in (0.0, prox) if prox else (0.0,):
                if nullspace:
                    sol, x_new = _nullspace_level(
                        hard, lv, x_p, Z, prev_C, prev_lo, prev_hi, handle, relax, eps, extra
                    )
                else:
                    sol, x_new = _cascade_level(
                        hard, lv, Eb, e, prev_C, prev_lo, prev_hi, handle, relax, center, eps,
                        extra,
                    )  # fmt: skip
                if sol is not None:
                    _record(timer, sol, lv.name)
                if sol is None or (sol.success and x_new is not None):
                    break
                retries += eps == 0.0 and prox > 0
        elapsed = time.perf_counter() - t0
        if sol is not None and (not sol.success or x_new is None):
            msg = f"level {lv.name!r}: {sol.solver}: {sol.status}: {sol.message}"
            return HierarchyResult(np.zeros(n) if x is None else x, False, msg, results, retries)
        x = x_new
        assert x is not None
        res = _level_result(lv, x, sol, elapsed)
        results.append(res)
        # hold this level's optimum for the levels below (nothing to hold after the last)
        if i == len(soft) - 1:
            break
        if lv.A.shape[0]:
            held_rows.append(lv.A)
            if nullspace:
                _, Zl = row_space_and_null_space(lv.A @ Z)
                Z = Z @ Zl
                x_p = x
        carried = max(carried, _carried_violation(x, hard, prev_C, prev_lo, prev_hi))
        if lv.C.shape[0]:
            prev_C.append(lv.C)
            prev_lo.append(lv.l + res.v)
            prev_hi.append(lv.u + res.v)
        if nullspace:
            x_p = x
    assert x is not None
    results.extend(_level_result(f, x, None, 0.0) for f in merged)
    return HierarchyResult(x, True, "", results, retries)


def _rows_of(M: Array | None) -> int:
    return 0 if M is None else int(M.shape[0])


def _feasible_pair(
    hard: Constraints,
    lv: PriorityLevel,
    nxt: PriorityLevel,
    x_p: Array,
    Z: Array,
    prev_C: list[Array],
    prev_lo: list[Array],
    prev_hi: list[Array],
    solver: QPSolver,
    relax: float,
    merged: list[PriorityLevel],
    timer: SolveTimes | None,
) -> tuple[Array, Array, Solution | None] | None:
    """Level ``lv`` held hard inside ``nxt``'s QP (see ``hard_if_feasible``).

    Returns (x, Z with lv's equalities eliminated, the QP's solution), or None when lv cannot be
    met exactly (inconsistent equalities, or the QP is infeasible / fails).
    """
    assert lv.A is not None and lv.b is not None and lv.C is not None
    assert lv.l is not None and lv.u is not None
    if lv.A.shape[0]:
        r = lv.b - lv.A @ x_p
        _, Zl, y0 = _hard_factor(lv.A @ Z, r)
        x_l = x_p + Z @ y0
        scale = 1.0 + float(np.abs(lv.b).max(initial=0.0))
        if float(np.abs(lv.A @ x_l - lv.b).max()) > 1e3 * RANK_TOL * scale:
            return None  # the equalities cannot be met together with the levels above
        Z_l = Z @ Zl
    else:
        x_l, Z_l = x_p, Z
    sol, x = _nullspace_level(
        hard,
        nxt,
        x_l,
        Z_l,
        [*prev_C, lv.C],
        [*prev_lo, lv.l],
        [*prev_hi, lv.u],
        solver,
        relax,
        0.0,
        merged,
    )
    if sol is not None:
        _record(timer, sol, nxt.name)
    if x is None:
        return None
    return x, Z_l, sol


def _hard_factor(A: Array, b: Array) -> tuple[Array, Array, Array]:
    """Row-space basis R, null-space basis Z and minimum-norm solution of A x = b, from one QR."""
    n = A.shape[1]
    if A.shape[0] == 0:
        return np.zeros((0, n)), np.eye(n), np.zeros(n)
    Q, Rf, piv = _qr_pivoted(A.T)
    diag = np.abs(np.diag(Rf))
    rank = int(np.sum(diag > RANK_TOL * max(1.0, diag[0]))) if diag.size else 0
    if rank == A.shape[0]:
        # A[piv] = R₁ᵀ Q₁ᵀ: x = Q₁ R₁⁻ᵀ b[piv] is the minimum-norm solution
        y = scipy.linalg.solve_triangular(Rf[:rank, :rank], b[piv], trans="T", check_finite=False)
        x_p = Q[:, :rank] @ y
    else:
        x_p = np.linalg.lstsq(A, b, rcond=None)[0]
    return Q[:, :rank].T, Q[:, rank:], x_p


def _add_merged(
    H: Array, g: Array, merged: list[PriorityLevel], Z: Array | None, x_p: Array | None
) -> None:
    """Add Σ weight ½‖F x − f‖² to a level's QP over x (Z None) or over y, x = x_p + Z y."""
    d = H.shape[0] if Z is None else Z.shape[1]
    for f in merged:
        assert f.A is not None and f.b is not None
        if Z is None:
            H[:d, :d] += f.weight * (f.A.T @ f.A)
            g[:d] -= f.weight * (f.A.T @ f.b)
        else:
            assert x_p is not None
            FZ = f.A @ Z
            H[:d, :d] += f.weight * (FZ.T @ FZ)
            g[:d] += f.weight * (FZ.T @ (f.A @ x_p - f.b))


def _own_multipliers_vanish(sol: Solution, r: int) -> bool:
    """The last ``r`` inequality rows of the QP have (numerically) zero multipliers."""
    if sol.z is None or sol.x is None:
        return False
    z = np.abs(sol.z[-r:])
    scale = max(1.0, float(np.abs(sol.z).max(initial=0.0)), float(np.abs(sol.x).max()))
    # a multiplier at the solver's tolerance changes the level's optimum at that tolerance only
    return bool(z.max(initial=0.0) <= 1e-6 * scale)


def _cascade_level(
    hard: Constraints,
    lv: PriorityLevel,
    E: Array,
    e: Array,
    prev_C: list[Array],
    prev_lo: list[Array],
    prev_hi: list[Array],
    solver: QPSolver,
    relax: float,
    center: Array,
    prox: float,
    merged: list[PriorityLevel] = (),  # type: ignore[assignment]
    hard_own: bool = False,
) -> tuple[Solution, Array | None]:
    """QP over z = (x, w, v): min ½‖w‖² + ½‖v‖² + ½ prox ‖x − center‖², A x − w = b,
    l ≤ C x − v ≤ u, E x = e; ``merged`` finals added to the cost; ``hard_own``: v = 0 (no
    slack variables), accepted only when the level's inequality multipliers vanish."""
    n = hard.n
    assert lv.A is not None and lv.C is not None and lv.b is not None
    assert lv.l is not None and lv.u is not None
    m, r_own = lv.A.shape[0], lv.C.shape[0]
    r = 0 if hard_own else r_own
    nx = n + m + r
    H = np.zeros((nx, nx))
    g = np.zeros(nx)
    if prox:
        # regularise only the feasible directions (those the held equalities leave free) that
        # the level's objective does not see
        assert hard.A is not None
        _, Zf = row_space_and_null_space(np.vstack([hard.A, E]))
        P = Zf @ _null_projector(lv.A @ Zf) @ Zf.T
        H[:n, :n] = prox * P
        g[:n] = -prox * (P @ center)
    H[n:, n:] = np.eye(m + r)
    _add_merged(H[:n, :n], g[:n], merged, None, None)
    eq_rows: list[tuple[Array, Array]] = []
    if E.shape[0]:
        eq_rows.append((np.hstack([E, np.zeros((E.shape[0], m + r))]), e))
    if m:
        rows = np.zeros((m, nx))
        rows[:, :n] = lv.A
        rows[:, n : n + m] = -np.eye(m)
        eq_rows.append((rows, lv.b))
    C_rows: list[Array] = [np.hstack([Cp, np.zeros((Cp.shape[0], m + r))]) for Cp in prev_C]
    widened = [_widen(lp, hp, relax) for lp, hp in zip(prev_lo, prev_hi, strict=True)]
    lo = [w[0] for w in widened]
    hi = [w[1] for w in widened]
    if r_own:
        block = np.zeros((r_own, nx))
        block[:, :n] = lv.C
        if r:
            block[:, n + m :] = -np.eye(r)
        C_rows.append(block)
        lo.append(lv.l)
        hi.append(lv.u)
    problem = _with_hard(hard, H, g, C_rows, lo, hi, nx, lv.name, eq_rows, relax)
    sol = solver.solve(problem)
    sol, x = _checked(
        sol, None if sol.x is None else sol.x[:n], hard, prev_C, prev_lo, prev_hi, relax, solver
    )
    if not sol.success or x is None:
        return sol, None
    if hard_own and not _own_multipliers_vanish(sol, r_own):
        return sol, None
    return sol, x


def _nullspace_level(
    hard: Constraints,
    lv: PriorityLevel,
    x_p: Array,
    Z: Array,
    prev_C: list[Array],
    prev_lo: list[Array],
    prev_hi: list[Array],
    solver: QPSolver,
    relax: float,
    prox: float,
    merged: list[PriorityLevel] = (),  # type: ignore[assignment]
    hard_own: bool = False,
) -> tuple[Solution | None, Array | None]:
    """QP over (y, v) with x = x_p + Z y: min ½‖A Z y − (b − A x_p)‖² + ½‖v‖²; ``merged``
    finals added to the cost; ``hard_own``: v = 0 (no slack variables), accepted only when the
    level's inequality multipliers vanish."""
    assert lv.A is not None and lv.C is not None and lv.l is not None and lv.u is not None
    assert hard.C is not None and hard.l is not None and hard.u is not None
    d = Z.shape[1]
    r_own = lv.C.shape[0]
    r = 0 if hard_own else r_own
    if d == 0:
        return None, x_p.copy()
    nx = d + r
    AZ = lv.A @ Z
    H = np.zeros((nx, nx))
    # the proximal term centred on x_p: ‖Z y‖² = ‖y‖² (Z orthonormal)
    H[:d, :d] = AZ.T @ AZ
    if prox:
        # regularise only the directions the level's objective does not see
        H[:d, :d] += prox * _null_projector(AZ)
    H[d:, d:] = np.eye(r)
    g = np.zeros(nx)
    g[:d] = -AZ.T @ (lv.b - lv.A @ x_p)
    _add_merged(H, g, merged, Z, x_p)
    C_list: list[Array] = []
    lo: list[Array] = []
    hi: list[Array] = []

    def add(C: Array, lower: Array, upper: Array, slack: bool = False) -> None:
        if not C.shape[0]:
            return
        if not slack:
            lower, upper = _widen(lower, upper, relax)
        block = np.zeros((C.shape[0], nx))
        block[:, :d] = C @ Z
        if slack and r:
            block[:, d:] = -np.eye(r)
        shift = C @ x_p
        C_list.append(block)
        lo.append(lower - shift)
        hi.append(upper - shift)

    add(hard.C, hard.l, hard.u)
    if hard.lb is not None or hard.ub is not None:
        n = hard.n
        lower = hard.lb if hard.lb is not None else np.full(n, -np.inf)
        upper = hard.ub if hard.ub is not None else np.full(n, np.inf)
        finite = np.isfinite(lower) | np.isfinite(upper)
        add(np.eye(n)[finite], lower[finite], upper[finite])
    for Cp, lp, hp in zip(prev_C, prev_lo, prev_hi, strict=True):
        add(Cp, lp, hp)
    add(lv.C, lv.l, lv.u, slack=True)
    problem = Problem(
        H,
        g,
        np.zeros((0, nx)),
        np.zeros(0),
        np.vstack(C_list) if C_list else np.zeros((0, nx)),
        np.concatenate(lo) if lo else np.zeros(0),
        np.concatenate(hi) if hi else np.zeros(0),
        name=lv.name,
    )
    # y = 0 is the levels above's answer; the previous tick's y is in another basis
    sol = solver.solve(problem, origin=True)
    x = None if sol.x is None else x_p + Z @ sol.x[:d]
    sol, x = _checked(sol, x, hard, prev_C, prev_lo, prev_hi, relax, solver)
    if not sol.success or x is None:
        return sol, None
    if hard_own and not _own_multipliers_vanish(sol, r_own):
        return sol, None
    return sol, x


def _solve_rqr(
    hard: Constraints, soft: list[PriorityLevel], timer: SolveTimes | None
) -> HierarchyResult:
    from wbcbench.qp.hls import Level, solve_hls

    n = hard.n
    assert hard.A is not None and hard.C is not None
    C_hard, l_hard, u_hard = [hard.C], [hard.l], [hard.u]
    if hard.lb is not None or hard.ub is not None:
        lower = hard.lb if hard.lb is not None else np.full(n, -np.inf)
        upper = hard.ub if hard.ub is not None else np.full(n, np.inf)
        finite = np.isfinite(lower) | np.isfinite(upper)
        C_hard.append(np.eye(n)[finite])
        l_hard.append(lower[finite])
        u_hard.append(upper[finite])
    Ch = np.vstack(C_hard)
    levels = [
        Level(
            A=hard.A if hard.A.shape[0] else None,
            b=hard.b if hard.A.shape[0] else None,
            C=Ch if Ch.shape[0] else None,
            l=np.concatenate(l_hard) if Ch.shape[0] else None,  # type: ignore[arg-type]
            u=np.concatenate(u_hard) if Ch.shape[0] else None,  # type: ignore[arg-type]
            name="hard",
        )
    ]
    for lv in soft:
        assert lv.A is not None and lv.C is not None
        levels.append(
            Level(
                A=lv.A if lv.A.shape[0] else None,
                b=lv.b if lv.A.shape[0] else None,
                C=lv.C if lv.C.shape[0] else None,
                l=lv.l if lv.C.shape[0] else None,
                u=lv.u if lv.C.shape[0] else None,
                name=lv.name,
            )
        )
    result = solve_hls(levels)
    x = result.x
    hard_stats = result.levels[0]
    _record(
        timer,
        Solution(
            SolutionStatus.SOLVED,
            iterations=hard_stats.iterations,
            wall_time=hard_stats.time,
            solver="rqr",
        ),
        "hard",
    )
    out = []
    for lv, stats in zip(soft, result.levels[1:], strict=True):
        sol = Solution(
            SolutionStatus.SOLVED,
            x=stats.x,
            iterations=stats.iterations,
            wall_time=stats.time,
            solver="rqr",
        )
        _record(timer, sol, lv.name)
        out.append(_level_result(lv, x, sol, stats.time))
    hard_violation = result.levels[0].violation
    ok = bool(hard_violation <= 1e-6)
    msg = "" if ok else f"hard constraints violated by {hard_violation:.2e}"
    return HierarchyResult(x, ok, msg, out)
