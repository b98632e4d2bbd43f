"""The native hierarchical least squares against the Python reference, on the same stacks.

The three algorithms (reduced QR with active sets, full-coordinate QR, SVD task priority) must
give the reference's x to 1e-10, the same ranks and null-space sizes, and, with inequalities,
the same active sets: the same number of active and saturated rows and iterations per level, and
the same rows tight at every level's solution.

A level's residual ‖A x − b‖ is checked as what it is, a function of that level's x: each impl
reports the residual of its own x (to round-off), and the two residuals differ by no more than
‖A (x_native − x_ref)‖ (the triangle inequality), which scales with ‖A‖. A fixed bound would
not: the impls' factorisations round differently (LAPACK's kernels against Eigen's), the x's
differ within X_TOL, and on a stack with ‖A‖ ≈ 1e2 that moves the residual by ~1e-8 (measured:
6.8e-9 at n = 61, |x − x_ref| = 2.6e-11, with OpenBLAS's Haswell kernels).
"""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.errors import SolverError, WbcBenchError
from wbcbench.qp.hls import HlsResult, Level, solve_hls
from wbcbench.qp.hls_baselines import ALGORITHMS, fig1_stack, get_algorithm, scaling_series
from wbcbench.qp.hls_native import NativeHls, solve_hls_native, solve_svd_hierarchy_native

from .test_hls import _equality_stack, _inequality_stack, _singular_stack

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

X_TOL = 1e-10


def tight_rows(levels: list[Level], x: np.ndarray, tol: float = 1e-9) -> list[tuple[int, int]]:
    """(level, row) of every inequality bound met with equality at x (within tol)."""
    out = []
    for i, lv in enumerate(levels):
        if lv.C is None or lv.l is None or lv.u is None:
            continue
        cx = lv.C @ x
        hit = (np.abs(cx - lv.u) <= tol) | (np.abs(cx - lv.l) <= tol)
        out += [(i, int(r)) for r in np.flatnonzero(hit)]
    return out


def residual_bound(level: Level, x: np.ndarray, x_ref: np.ndarray, residual: float) -> float:
    """How far a level's residual at x may lie from its residual at x_ref: ‖A (x − x_ref)‖,
    plus the round-off of computing a norm (1e-12 relative)."""
    rounding = 1e-12 * (1.0 + residual)
    if level.A is None:
        return rounding
    return float(np.linalg.norm(level.A @ (x - x_ref))) + rounding


def own_residual(level: Level, x: np.ndarray) -> float:
    if level.A is None or level.b is None:
        return 0.0
    return float(np.linalg.norm(level.A @ x - level.b))


def assert_same(native: HlsResult, ref: HlsResult, levels: list[Level], what: str) -> None:
    """x to 1e-10 and the same statistics, level by level; residuals as their x's imply."""
    err = float(np.abs(native.x - ref.x).max())
    assert err <= X_TOL, f"{what}: |x - x_ref| = {err:.2e}"
    assert len(native.levels) == len(ref.levels) == len(levels)
    for i, (got, want) in enumerate(zip(native.levels, ref.levels, strict=True)):
        where = f"{what}, level {want.name!r}"
        assert got.name == want.name
        assert (got.rank, got.dof_left) == (want.rank, want.dof_left), where
        assert (got.iterations, got.n_active, got.n_saturated) == (
            want.iterations,
            want.n_active,
            want.n_saturated,
        ), where
        for stats in (got, want):
            own = own_residual(levels[i], stats.x)
            assert abs(stats.residual - own) <= 1e-12 * (1.0 + own), where
        bound = residual_bound(levels[i], got.x, want.x, want.residual)
        assert abs(got.residual - want.residual) <= bound, where
        assert abs(got.violation - want.violation) <= 1e-9 * (1 + want.violation), where
        assert np.abs(got.x - want.x).max() <= X_TOL, where
        assert tight_rows(levels, got.x) == tight_rows(levels, want.x), where
        assert got.time > 0.0
    assert native.time >= sum(s.time for s in native.levels)


@pytest.mark.parametrize("n", [10, 20, 40, 60, 80, 100])
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_fig1_stacks(algorithm: str, n: int) -> None:
    levels = fig1_stack(n)
    ref = get_algorithm(algorithm, "python")(levels)
    assert_same(get_algorithm(algorithm, "native")(levels), ref, levels, f"{algorithm} N={n}")


@pytest.mark.parametrize("n", [6, 13, 30, 61])
@pytest.mark.parametrize("posture", [False, True])
@pytest.mark.parametrize("damping", [0.0, 0.1])
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_random_equality_stacks(algorithm: str, n: int, posture: bool, damping: float) -> None:
    for seed in range(3):
        levels = _equality_stack(n, seed, posture)
        ref = get_algorithm(algorithm, "python")(levels, damping=damping)
        got = get_algorithm(algorithm, "native")(levels, damping=damping)
        assert_same(got, ref, levels, f"{algorithm} n={n} seed={seed}")


@pytest.mark.parametrize("n", [8, 15, 24])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("infeasible", [False, True])
def test_random_inequality_stacks(n: int, seed: int, infeasible: bool) -> None:
    levels = _inequality_stack(n, seed, infeasible)
    for damping in (None, 0.0, 0.3):
        ref = solve_hls(levels, damping=damping)
        assert_same(solve_hls_native(levels, damping=damping), ref, levels, f"n={n} seed={seed}")
    if infeasible:
        assert ref.levels[2].violation > 0.1  # the least-violation phase ran


def test_random_boxes_and_starting_points() -> None:
    """Random box and general inequalities on every level, from random starting points."""
    rng = np.random.default_rng(11)
    for trial in range(20):
        n = int(rng.integers(4, 30))
        levels = []
        for i in range(int(rng.integers(2, 5))):
            m, mc = int(rng.integers(1, 6)), int(rng.integers(0, 8))
            C = rng.standard_normal((mc, n)) if mc else None
            lo = -rng.uniform(0.0, 1.0, mc) if mc else None
            hi = rng.uniform(0.0, 1.0, mc) if mc else None
            if mc:
                assert lo is not None and hi is not None
                lo[rng.random(mc) < 0.3] = -np.inf
            levels.append(
                Level(rng.standard_normal((m, n)), 3 * rng.standard_normal(m), C, lo, hi, f"L{i}")
            )
        levels.insert(0, Level(C=np.eye(n), l=np.full(n, -0.3), u=np.full(n, 0.3), name="box"))
        x0 = 0.1 * rng.standard_normal(n)
        k = float(rng.choice([0.0, 1e-3, 0.2]))
        ref = solve_hls(levels, damping=k, x0=x0)
        assert_same(solve_hls_native(levels, damping=k, x0=x0), ref, levels, f"trial {trial}")


def test_singular_stack_damped_and_undamped() -> None:
    """Through the algorithmic singularity: exactly singular (theta = 0, a rank drop), and near
    it damped only (undamped at theta = 1e-6, |x| ~ 2e5 and both impls' round-off with it: they
    differ by 3e-5, 1.5e-10 relative)."""
    damped = [0.0, 0.1, 0.0]
    for theta, dampings in ((-0.01, (None, damped)), (0.0, (None, damped)), (1e-6, (damped,))):
        levels = _singular_stack(theta)
        for damping in dampings:
            for algorithm in ALGORITHMS:
                ref = get_algorithm(algorithm, "python")(levels, damping=damping)
                got = get_algorithm(algorithm, "native")(levels, damping=damping)
                assert_same(got, ref, levels, f"{algorithm} theta={theta}")


def test_a_solver_is_reused_across_stacks_of_other_sizes() -> None:
    solver = NativeHls()
    for n, seed in ((20, 0), (8, 1), (24, 2), (8, 1)):
        levels = _inequality_stack(n, seed, infeasible=seed == 1)
        solver.load(levels)
        assert_same(solver.solve(), solve_hls(levels), levels, f"n={n}")


def test_failures_raise_as_the_reference_does() -> None:
    levels = _inequality_stack(12, 0, infeasible=False)
    with pytest.raises(SolverError) as ref:
        solve_hls(levels, max_iter=1)
    with pytest.raises(SolverError) as got:
        solve_hls_native(levels, max_iter=1)
    assert str(got.value) == str(ref.value) == "active set did not converge in 1 iterations"
    with pytest.raises(WbcBenchError, match="equality-only"):
        solve_svd_hierarchy_native(levels)
    with pytest.raises(WbcBenchError, match="disagree"):
        solve_hls_native([Level(np.eye(2)), Level(np.eye(3))])


def test_scaling_series_runs_both_impls() -> None:
    rows = scaling_series([8, 16], repeats=2)
    assert len(rows) == 2 * len(ALGORITHMS) * 2
    assert {(r["algorithm"], r["impl"]) for r in rows} == {
        (a, i) for a in ALGORITHMS for i in ("python", "native")
    }
    assert all(r["median_s"] > 0 and r["max_abs_diff"] < 1e-9 for r in rows)
    assert all(r["call_median_s"] >= r["median_s"] for r in rows)
