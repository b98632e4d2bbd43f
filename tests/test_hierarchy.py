"""Lexicographic least squares: the strategies against each other and first principles."""

from __future__ import annotations

import re
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from wbcbench.errors import UnknownNameError
from wbcbench.qp import Problem, Solution, SolutionStatus, make_solver
from wbcbench.qp.hierarchy import (
    Constraints,
    Objective,
    PriorityLevel,
    row_space_and_null_space,
    solve_hierarchy,
)


def random_hierarchy(seed: int, n: int = 14, active: bool = True):
    """Hard equalities + box, three conflicting levels (one with inequalities), a final."""
    rng = np.random.default_rng(seed)
    hard = Constraints(
        n,
        A=rng.standard_normal((3, n)),
        b=rng.standard_normal(3),
        lb=np.full(n, -2.0 if active else -50.0),
        ub=np.full(n, 2.0 if active else 50.0),
    )
    A1 = rng.standard_normal((4, n))
    A2 = np.vstack([A1[:2] + 0.1 * rng.standard_normal((2, n)), rng.standard_normal((3, n))])
    C2 = rng.standard_normal((3, n))
    c_mid = C2 @ rng.standard_normal(n)
    levels = [
        PriorityLevel("L1", A=A1, b=rng.standard_normal(4)),
        PriorityLevel(
            "L2",
            A=A2,
            b=rng.standard_normal(5),
            C=C2,
            l=c_mid - (0.05 if active else 50),
            u=c_mid + (0.05 if active else 50),
        ),
        PriorityLevel("L3", A=rng.standard_normal((6, n)), b=rng.standard_normal(6)),
    ]
    finals = [Objective("reg", np.eye(n), np.zeros(n))]
    return hard, levels, finals


class BoundBreaking:
    """A DAQP handle that reports solved a point ``excess`` past an upper bound: the simple
    bound its answer is closest to, or without simple bounds the first inequality row. With
    ``infeasible_first`` its first QP is declared infeasible, as DAQP declares some level QPs
    the levels above leave feasible, so that the point is the proximal retry's answer."""

    def __init__(self, excess: float, infeasible_first: bool = False) -> None:
        self.inner = make_solver("daqp", tier="high")
        self.excess = excess
        self.infeasible_first = infeasible_first
        self.calls = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def native_solver(self) -> None:
        """None: the broken answer is made here, so a native tick must call this handle."""
        return None

    def solve(self, problem: Problem, *args: Any, **kwargs: Any) -> Solution:
        self.calls += 1
        if self.infeasible_first and self.calls == 1:
            return Solution(SolutionStatus.INFEASIBLE, message="primal infeasible", solver="daqp")
        sol = self.inner.solve(problem, *args, **kwargs)
        assert sol.success and sol.x is not None
        x = sol.x.copy()
        if problem.ub is not None and np.isfinite(problem.ub).any():
            j = int(np.argmax(x - problem.ub))
            x[j] = problem.ub[j] + self.excess
        else:
            i = int(np.flatnonzero(np.isfinite(problem.u))[0])
            c = problem.C[i]
            x += (problem.u[i] + self.excess - c @ x) / (c @ c) * c
        return replace(sol, x=x)


#: what a level answer past a bound is refused with at the high tier (0.5 past a bound, relative
#: to 1 + the problem's scale; a step along an inequality row of the null-space QP moves several
#: variables)
PAST_THE_BOUND = (
    r"reported solved but violates a bound or a held inequality by (\d\.\de-\d\d) > 1e-06 "
    r"\(relative to the problem's scale\)"
)


def solve(strategy: str, hard, levels, finals, solver: str = "daqp"):
    handles = [make_solver(solver, tier="high") for _ in range(len(levels) + len(finals))]
    return solve_hierarchy(hard, levels, finals, strategy, handles)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("active", [False, True])
def test_cascade_nullspace_and_rqr_agree(seed: int, active: bool) -> None:
    hard, levels, finals = random_hierarchy(seed, active=active)
    cascade = solve("cascade", hard, levels, finals)
    nullspace = solve("nullspace", hard, levels, finals)
    rqr = solve_hierarchy(hard, levels, finals, "rqr")
    assert cascade.ok and nullspace.ok and rqr.ok, (cascade.message, nullspace.message)
    np.testing.assert_allclose(nullspace.x, cascade.x, atol=1e-6)
    if all(np.linalg.norm(lv.v) < 1e-9 for lv in cascade.levels):
        np.testing.assert_allclose(rqr.x, cascade.x, atol=1e-6)
    else:
        # rqr gives a level's inequalities precedence over its equalities (RQR-HQP §III-B);
        # the QP strategies trade the two off jointly: rqr violates them no more
        for a, b in zip(rqr.levels, cascade.levels, strict=True):
            assert np.linalg.norm(a.v) <= np.linalg.norm(b.v) + 1e-9


@pytest.mark.parametrize("seed", range(5))
def test_each_level_is_optimal_given_the_levels_above(seed: int) -> None:
    """Level 1 alone reaches the same residual as inside the hierarchy; hard rows hold."""
    hard, levels, finals = random_hierarchy(seed)
    full = solve("nullspace", hard, levels, finals)
    top = solve("nullspace", hard, levels[:1], finals)
    w_full = np.linalg.norm(full.levels[0].w)
    w_top = np.linalg.norm(top.levels[0].w)
    assert w_full == pytest.approx(w_top, abs=1e-7)
    np.testing.assert_allclose(hard.A @ full.x, hard.b, atol=1e-8)
    assert np.all(full.x <= 2.0 + 1e-8) and np.all(full.x >= -2.0 - 1e-8)
    # adding level 3 never worsens levels 1 and 2
    two = solve("nullspace", hard, levels[:2], finals)
    for i in range(2):
        assert np.linalg.norm(full.levels[i].w) <= np.linalg.norm(two.levels[i].w) + 1e-7
        assert np.linalg.norm(full.levels[i].v) <= np.linalg.norm(two.levels[i].v) + 1e-7


def test_weighted_approaches_the_hierarchy_with_separated_weights() -> None:
    """The weighted QP's distance to the strict hierarchy shrinks as the weights separate.

    With level weights s², s, 1 and the final at 1/s, the weighted optimum differs from the
    strict one by O(1/s). The separations are kept moderate (Hessian condition ≤ 1e7 with the
    final) so that this O(1/s) gap dwarfs the solver's rounding on any BLAS kernel.
    """
    hard, levels, finals = random_hierarchy(3, active=False)
    strict = solve("nullspace", hard, levels, finals)
    assert strict.ok
    assert np.linalg.norm(strict.levels[0].w) < 1e-8  # level 1 is feasible
    gaps, top_residuals = [], []
    for s in (10.0, 100.0, 1000.0):
        for lv, w in zip(levels, (s * s, s, 1.0), strict=True):
            lv.weight = w
        finals[0].weight = 1.0 / s
        weighted = solve_hierarchy(hard, levels, finals, "weighted", [make_solver("daqp", "high")])
        assert weighted.ok, weighted.message
        gaps.append(float(np.linalg.norm(weighted.x - strict.x)))
        top_residuals.append(float(np.linalg.norm(weighted.levels[0].w)))
    # each tenfold separation brings the weighted solution at least three times closer
    assert gaps[1] < gaps[0] / 3 and gaps[2] < gaps[1] / 3, gaps
    assert top_residuals[1] < top_residuals[0] / 3 and top_residuals[2] < top_residuals[1] / 3
    assert gaps[2] < 0.05 * max(1.0, float(np.linalg.norm(strict.x))), gaps


def test_every_backend_solves_the_cascade() -> None:
    from .conftest import ANY_TIER_SOLVERS

    hard, levels, finals = random_hierarchy(1, active=False)
    reference = solve("cascade", hard, levels, finals)
    for name in ANY_TIER_SOLVERS:
        if name in ("quadprog", "qpsolvers:quadprog", "highs", "qpsolvers:highs"):
            continue  # semidefinite level QPs: quadprog needs PD; HiGHS stays at ~1e-6
        result = solve("nullspace", hard, levels, finals, solver=name)
        assert result.ok, (name, result.message)
        np.testing.assert_allclose(result.x, reference.x, atol=1e-4, err_msg=name)


@pytest.mark.parametrize("strategy", ["cascade", "nullspace"])
def test_a_level_answer_past_a_hard_bound_is_refused(strategy: str) -> None:
    hard, levels, finals = random_hierarchy(0)
    handles: list[Any] = [make_solver("daqp", tier="high") for _ in range(4)]
    breaking = BoundBreaking(0.5, infeasible_first=True)
    handles[1] = breaking
    result = solve_hierarchy(hard, levels, finals, strategy, handles, prox=1e-8)
    assert not result.ok
    refused = re.fullmatch(f"level 'L2': daqp: failed: {PAST_THE_BOUND}", result.message)
    assert refused is not None, result.message
    assert float(refused[1]) >= 1e-3  # 0.5 against a scale of tens: far past the tolerance
    # the bare QP declared infeasible, then the proximal retry's answer refused
    assert breaking.calls == 2 and result.retries == 1
    weighted = solve_hierarchy(hard, levels, finals, "weighted", [BoundBreaking(0.5)])
    assert not weighted.ok
    assert re.fullmatch(f"weighted: failed: {PAST_THE_BOUND}", weighted.message)


def test_a_level_answer_within_the_tolerance_is_accepted() -> None:
    hard, levels, finals = random_hierarchy(0)
    handles: list[Any] = [make_solver("daqp", tier="high") for _ in range(3)]
    result = solve_hierarchy(
        hard, levels, finals, "cascade", [*handles, BoundBreaking(1e-12)], prox=1e-8
    )
    assert result.ok, result.message
    assert result.x.max() > hard.ub.max()  # type: ignore[union-attr]


def test_row_and_null_space_bases() -> None:
    rng = np.random.default_rng(0)
    E = rng.standard_normal((3, 7))
    E = np.vstack([E, E[0] + E[1]])  # rank 3
    R, Z = row_space_and_null_space(E)
    assert R.shape == (3, 7) and Z.shape == (7, 4)
    np.testing.assert_allclose(E @ Z, 0, atol=1e-12)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)


def test_unknown_strategy() -> None:
    hard, levels, finals = random_hierarchy(0)
    with pytest.raises(UnknownNameError) as exc:
        solve_hierarchy(hard, levels, finals, "lexico")
    assert str(exc.value) == (
        "unknown hierarchy strategy 'lexico'; valid choices: cascade, nullspace, rqr, weighted"
    )
