"""Hierarchical least squares: reduced regularised QR against its baselines and a QP cascade.

The references are independent of the solver under test: the SVD task-priority algorithm
(projectors, no QR), the full-coordinate QR algorithm, and a cascade of generic QPs (Clarabel,
an interior-point method), one per level, with the optimal task values of the levels above held
as equalities.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray

from wbcbench.errors import UnknownNameError, WbcBenchError
from wbcbench.qp.hls import HlsResult, Level, solve_hls
from wbcbench.qp.hls_baselines import (
    ALGORITHMS,
    fig1_stack,
    get_algorithm,
    scaling_series,
    solve_fullqr_hierarchy,
    solve_svd_hierarchy,
)

Array = NDArray[np.float64]
SOLVERS: dict[str, Callable[..., HlsResult]] = {
    "reduced_qr": solve_hls,
    "full_qr": solve_fullqr_hierarchy,
    "svd": solve_svd_hierarchy,
}

# --------------------------------------------------------------------------------------------
# Equality-only stacks: the three algorithms agree
# --------------------------------------------------------------------------------------------


def _equality_stack(n: int, seed: int, posture: bool) -> list[Level]:
    """Random stack with a full-rank level, a rank-deficient one and two conflicting ones.

    Level 2 has twice as many rows as its rank (and an inconsistent target), level 3 repeats
    combinations of level 1's rows (entirely conflicting) plus one free row, level 4 mixes rows
    of level 2 with free rows. The optional last level is a full posture task.
    """
    rng = np.random.default_rng(seed)
    m1, r2 = max(1, n // 4), max(1, n // 6)
    A1 = rng.standard_normal((m1, n))
    A2 = rng.standard_normal((2 * r2, r2)) @ rng.standard_normal((r2, n))
    A3 = np.vstack([rng.standard_normal((2, m1)) @ A1, rng.standard_normal((1, n))])
    A4 = np.vstack([rng.standard_normal((1, 2 * r2)) @ A2, rng.standard_normal((2, n))])
    levels = [
        Level(A1, rng.standard_normal(m1), name="full"),
        Level(A2, rng.standard_normal(2 * r2), name="rank-deficient"),
        Level(A3, rng.standard_normal(3), name="conflicting"),
        Level(A4, rng.standard_normal(3), name="partly conflicting"),
    ]
    if posture:
        levels.append(Level(np.eye(n), rng.standard_normal(n), name="posture"))
    return levels


@pytest.mark.parametrize("n", [6, 13, 30, 61])
@pytest.mark.parametrize("posture", [False, True])
@pytest.mark.parametrize("damping", [0.0, 0.1])
def test_three_algorithms_agree_on_equality_stacks(n: int, posture: bool, damping: float) -> None:
    for seed in range(3):
        levels = _equality_stack(n, seed, posture)
        results = {name: fn(levels, damping=damping) for name, fn in SOLVERS.items()}
        ref = results["svd"]
        for name, res in results.items():
            err = np.abs(res.x - ref.x).max()
            assert err <= 1e-9, f"{name} vs svd, n={n}, seed={seed}: {err:.2e}"
            ranks = [s.rank for s in res.levels]
            assert ranks == [s.rank for s in ref.levels], name


def test_reduced_qr_ranks_and_null_space_sizes() -> None:
    levels = _equality_stack(30, 0, posture=True)
    res = solve_hls(levels)
    # 7 full rows; rank 5 of 10 rows; 1 free row; 2 free rows; the posture takes the rest.
    assert [s.rank for s in res.levels] == [7, 5, 1, 2, 15]
    assert [s.dof_left for s in res.levels] == [23, 18, 17, 15, 0]
    assert res.levels[0].residual < 1e-12
    assert res.levels[2].residual > 0.1  # the conflicting rows cannot be met


def test_reduced_qr_is_the_minimum_norm_solution_of_each_level() -> None:
    levels = _equality_stack(20, 4, posture=False)
    res = solve_hls(levels)
    x1 = np.linalg.lstsq(levels[0].A, levels[0].b, rcond=None)[0]  # type: ignore[arg-type]
    assert np.abs(res.levels[0].x - x1).max() < 1e-12


# --------------------------------------------------------------------------------------------
# Algorithmic singularity: damping keeps the solution bounded and continuous
# --------------------------------------------------------------------------------------------


def _singular_stack(theta: float) -> list[Level]:
    """Level 2's second row turns parallel to level 1's first row as theta -> 0."""
    rng = np.random.default_rng(7)
    n = 7
    A1 = rng.standard_normal((2, n))
    v = rng.standard_normal(n)
    v -= A1.T @ np.linalg.lstsq(A1.T, v, rcond=None)[0]  # orthogonal to level 1's rows
    v *= np.linalg.norm(A1[0]) / np.linalg.norm(v)
    row = np.cos(theta) * A1[0] + np.sin(theta) * v
    A2 = np.vstack([rng.standard_normal(n), row])
    return [
        Level(A1, np.array([0.5, -0.2]), name="T1"),
        Level(A2, np.array([0.3, 1.0]), name="T2"),
        Level(np.eye(n), np.zeros(n), name="velocity"),
    ]


def test_damping_keeps_the_solution_bounded_through_a_singularity() -> None:
    thetas = np.linspace(-0.05, 0.05, 2001)  # step 5e-5, passes through theta = 0
    step, k = thetas[1] - thetas[0], 0.1
    plain = np.array([solve_hls(_singular_stack(t)).x for t in thetas])
    damped = np.array([solve_hls(_singular_stack(t), damping=[0.0, k, 0.0]).x for t in thetas])
    norm_plain, norm_damped = np.linalg.norm(plain, axis=1), np.linalg.norm(damped, axis=1)
    jump_plain = np.linalg.norm(np.diff(plain, axis=0), axis=1).max()
    jump_damped = np.linalg.norm(np.diff(damped, axis=0), axis=1).max()
    # Measured: max norm 6.8e3 undamped vs 2.41 damped; max jump 6.8e3 vs 3.7e-3.
    assert norm_damped.max() < 3.0
    assert norm_plain.max() / norm_damped.max() > 1000.0
    assert jump_damped < 100.0 * step  # Lipschitz in theta with a constant of order 1/k²
    assert jump_plain > 1000.0
    # The SVD baseline damps the same way.
    svd = solve_svd_hierarchy(_singular_stack(thetas[999]), damping=[0.0, k, 0.0]).x
    assert np.abs(svd - damped[999]).max() < 1e-9


def test_damping_does_not_shrink_the_null_space() -> None:
    # Damped level 2 still hands exactly n - rank directions to the posture level.
    res = solve_hls(_singular_stack(0.01), damping=[0.0, 0.05, 0.0])
    assert [s.dof_left for s in res.levels] == [5, 3, 0]
    # Level 1 (undamped) is met exactly whatever the damping below it.
    assert res.levels[2].residual > 0 and res.levels[0].residual < 1e-12


# --------------------------------------------------------------------------------------------
# Inequalities: per-level feasibility, no harm to higher levels, agreement with a QP cascade
# --------------------------------------------------------------------------------------------


def _qp(H: Array, g: Array, E: Array, e: Array, G: Array, h: Array) -> Array:
    """``min ½xᵀHx + gᵀx, Ex = e, Gx <= h`` by Clarabel (interior point), called directly.

    The cascade's QPs are semidefinite and degenerate (saturated inequalities depend on the
    fixed task rows, equalities repeat). quadprog needs a definite Hessian and independent
    active constraints and reports them "inconsistent"; ProxQP (eps_abs 1e-9) declares several
    of them primal infeasible. Clarabel solves all of them.
    """
    import clarabel
    from scipy import sparse

    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-10
    solver = clarabel.DefaultSolver(
        sparse.csc_matrix(np.triu(H)),
        g,
        sparse.csc_matrix(np.vstack([E, G])),
        np.concatenate([e, h]),
        [clarabel.ZeroConeT(E.shape[0]), clarabel.NonnegativeConeT(G.shape[0])],
        settings,
    )
    sol = solver.solve()
    # "AlmostSolved" happens on the degenerate levels; the comparisons below judge the accuracy.
    ok = (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved)
    assert sol.status in ok, sol.status
    return np.asarray(sol.x)


def _orth_rows(M: Array) -> Array:
    """Orthonormal rows spanning the rows of M (SVD), so the oracle's equalities are independent."""
    if M.shape[0] == 0:
        return M
    _, s, Vt = np.linalg.svd(M, full_matrices=False)
    return Vt[s > 1e-9 * max(1.0, s[0])]


def _cascade(levels: list[Level], n: int) -> tuple[list[float], list[float], Array]:
    """The lexicographic problem solved by generic QPs, one level (and phase) at a time.

    Returns the optimal task residual and least violation of every level and the final x.
    """
    tasks = np.zeros((0, n))
    G, h = np.zeros((0, n)), np.zeros(0)
    x = np.zeros(n)
    residuals, violations = [], []
    for lv in levels:
        E = _orth_rows(tasks)
        violation = 0.0
        if lv.C is not None:
            assert lv.l is not None and lv.u is not None
            C, lo, hi = lv.C, lv.l, lv.u
            mc = C.shape[0]
            H = np.block([[np.zeros((n, n)), np.zeros((n, mc))], [np.zeros((mc, n)), np.eye(mc)]])
            up, dn = np.isfinite(hi), np.isfinite(lo)
            Gw = np.block(
                [
                    [G, np.zeros((G.shape[0], mc))],
                    [C[up], -np.eye(mc)[up]],
                    [-C[dn], np.eye(mc)[dn]],
                ]
            )
            hw = np.concatenate([h, hi[up], -lo[dn]])
            Ew = np.hstack([E, np.zeros((E.shape[0], mc))])
            z = _qp(H, np.zeros(n + mc), Ew, Ew @ np.concatenate([x, np.zeros(mc)]), Gw, hw)
            w = z[n:]
            violation = float(np.linalg.norm(w))
            x = z[:n]
            lo, hi = lo + np.minimum(w, 0.0), hi + np.maximum(w, 0.0)
            G = np.vstack([G, C[np.isfinite(hi)], -C[np.isfinite(lo)]])
            h = np.concatenate([h, hi[np.isfinite(hi)], -lo[np.isfinite(lo)]])
        if lv.A is not None and lv.b is not None:
            x = _qp(lv.A.T @ lv.A, -lv.A.T @ lv.b, E, E @ x, G, h)
            tasks = np.vstack([tasks, lv.A])
            residuals.append(float(np.linalg.norm(lv.A @ x - lv.b)))
        else:
            residuals.append(0.0)
        violations.append(violation)
    return residuals, violations, x


def _inequality_stack(n: int, seed: int, infeasible: bool) -> list[Level]:
    """Limits, a task pushed into them, a task with its own inequalities, a posture.

    Level 3's inequalities bound a row of level 2's task: tight but feasible around the value
    level 2 reaches, or (``infeasible``) away from it, so level 3 first minimises their violation.
    """
    rng = np.random.default_rng(seed)
    K = rng.standard_normal((n // 2, n))
    limits = Level(
        C=np.vstack([np.eye(n), K]),
        l=-np.concatenate([np.full(n, 0.5), np.full(n // 2, 1.0)]),
        u=np.concatenate([np.full(n, 0.4), np.full(n // 2, np.inf)]),
        name="limits",
    )
    A2 = rng.standard_normal((3, n))
    task2 = Level(A2, 5.0 * rng.standard_normal(3), name="task")
    _, _, x2 = _cascade([limits, task2], n)
    C3 = np.vstack([A2[:1], rng.standard_normal((2, n))])
    c3 = C3 @ x2
    offset = np.array([0.3, 0.0, 0.0]) if infeasible else np.zeros(3)
    task3 = Level(
        rng.standard_normal((2, n)),
        3.0 * rng.standard_normal(2),
        C3,
        c3 + offset - 0.02,
        c3 + offset + 0.02,
        name="task+ineq",
    )
    posture = Level(np.eye(n), rng.standard_normal(n), name="posture")
    return [limits, task2, task3, posture]


def _violation(levels: list[Level], x: Array) -> float:
    """Largest violation of the inequalities of ``levels`` at ``x``."""
    worst = 0.0
    for lv in levels:
        if lv.C is not None:
            assert lv.l is not None and lv.u is not None
            cx = lv.C @ x
            worst = max(worst, float(np.max(np.maximum(lv.l - cx, cx - lv.u))))
    return worst


@pytest.mark.parametrize("n", [8, 15, 24])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_inequality_hierarchy_matches_qp_cascade(n: int, seed: int) -> None:
    levels = _inequality_stack(n, seed, infeasible=False)
    res = solve_hls(levels)
    residuals, _, x_ref = _cascade(levels, n)
    assert res.levels[1].n_active > 0, "the task should push x into its limits"
    for i, stats in enumerate(res.levels):
        # Every level's solution keeps the inequalities of that level and the levels above ...
        assert _violation(levels[: i + 1], stats.x) <= 1e-9, f"level {i}"
        # ... and does not increase the residual of any level above.
        for j in range(i):
            A, b = levels[j].A, levels[j].b
            if A is not None and b is not None:
                before = np.linalg.norm(A @ res.levels[j].x - b)
                assert np.linalg.norm(A @ stats.x - b) <= before + 1e-9, f"{j} by {i}"
        assert abs(stats.residual - residuals[i]) <= 1e-6, f"level {i} residual"
    assert np.abs(res.x - x_ref).max() <= 1e-6


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_infeasible_inequalities_are_violated_least(seed: int) -> None:
    n = 12
    levels = _inequality_stack(n, seed, infeasible=True)
    res = solve_hls(levels)
    residuals, violations, x_ref = _cascade(levels, n)
    assert violations[2] > 0.2
    assert abs(res.levels[2].violation - violations[2]) <= 1e-6
    assert res.levels[2].n_saturated >= 1
    # Higher levels are untouched by the violated level.
    assert _violation(levels[:2], res.x) <= 1e-9
    assert abs(res.levels[1].residual - residuals[1]) <= 1e-6
    assert np.abs(res.x - x_ref).max() <= 1e-6


def test_inequality_only_level_first_finds_a_feasible_point() -> None:
    rng = np.random.default_rng(3)
    n = 6
    C = rng.standard_normal((4, n))
    levels = [
        Level(C=C, l=np.full(4, 1.0), u=np.full(4, 2.0), name="away from the start"),
        Level(np.eye(n), np.zeros(n), name="posture"),
    ]
    res = solve_hls(levels)
    _, _, x_ref = _cascade(levels, n)
    assert res.levels[0].iterations > 0
    assert _violation(levels[:1], res.x) <= 1e-9
    assert np.abs(res.x - x_ref).max() <= 1e-6


def test_damped_level_with_active_inequalities_matches_damped_qp() -> None:
    rng = np.random.default_rng(5)
    n, k = 10, 0.5
    A, b = rng.standard_normal((3, n)), 10.0 * rng.standard_normal(3)
    box = Level(C=np.eye(n), l=np.full(n, -0.1), u=np.full(n, 0.1), name="limits")
    res = solve_hls([box, Level(A, b, damping=k), Level(np.eye(n), np.zeros(n))])
    # Level 2 alone: min ||A x - b||² + k² ||x||² in the box (strictly convex, so unique).
    G, h = np.vstack([np.eye(n), -np.eye(n)]), np.full(2 * n, 0.1)
    x_ref = _qp(A.T @ A + k * k * np.eye(n), -A.T @ b, np.zeros((0, n)), np.zeros(0), G, h)
    assert res.levels[1].n_saturated > 0
    assert np.abs(res.levels[1].x - x_ref).max() <= 1e-6


def test_inactive_inequalities_leave_the_equality_solution_unchanged() -> None:
    levels = _equality_stack(12, 1, posture=True)
    rng = np.random.default_rng(1)
    loose = Level(C=rng.standard_normal((5, 12)), l=np.full(5, -1e3), u=np.full(5, 1e3))
    for k in (0.0, 0.2):
        ref = solve_hls(levels, damping=k).x
        got = solve_hls([loose, *levels], damping=k).x
        assert np.abs(got - ref).max() < 1e-10


# --------------------------------------------------------------------------------------------
# Inputs, registry, sweep
# --------------------------------------------------------------------------------------------


def test_level_rejects_bad_inputs() -> None:
    with pytest.raises(WbcBenchError, match="needs A"):
        Level(name="empty")
    with pytest.raises(WbcBenchError, match="b must have 2 entries"):
        Level(np.eye(2), np.zeros(3))
    with pytest.raises(WbcBenchError, match="l > u"):
        Level(C=np.eye(2), l=np.ones(2), u=np.zeros(2))
    with pytest.raises(WbcBenchError, match="different column counts"):
        Level(np.eye(2), np.zeros(2), C=np.eye(3))
    with pytest.raises(WbcBenchError, match="disagree"):
        solve_hls([Level(np.eye(2)), Level(np.eye(3))])


def test_baselines_reject_inequalities_and_unknown_names() -> None:
    lv = [Level(C=np.eye(2), u=np.ones(2))]
    with pytest.raises(WbcBenchError, match="equality-only"):
        solve_svd_hierarchy(lv)
    with pytest.raises(UnknownNameError, match="valid choices: full_qr, reduced_qr, svd"):
        get_algorithm("cod")


def test_scaling_series_rows() -> None:
    rows = scaling_series([8, 16], repeats=2, impls=["python"])
    assert len(rows) == 2 * len(ALGORITHMS)
    assert {r["algorithm"] for r in rows} == set(ALGORITHMS)
    assert all(r["median_s"] > 0 and r["max_abs_diff"] < 1e-9 for r in rows)
    assert len(fig1_stack(40)) == 4
