"""Registry sweep: every installed backend × mode × tier against a high-accuracy reference.

The reference is ProxQP at the ``high`` tier, itself accepted only if the independent KKT check
(:func:`wbcbench.qp.check_solution`) passes at 1e-8. Named settings (``osqp_libdwbc``) are swept
at the tiers and modes they run at, and their own definition is checked at the end. No timing is
asserted here.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

import wbcbench.qp as qp
from wbcbench.qp import MODES, TIERS, Problem, SolutionStatus, check_solution, make_solver
from wbcbench.qp.examples import infeasible_qp, random_qp, wbc_like_qp
from wbcbench.qp.registry import BACKENDS, NAMED_SETTINGS, QPSOLVERS_NAMES, QPSOLVERS_PREFIX
from wbcbench.qp.settings import TIER_EPS

ALL_NAMES = sorted([*BACKENDS, *NAMED_SETTINGS, *(QPSOLVERS_PREFIX + n for n in QPSOLVERS_NAMES)])
INSTALLED = set(qp.available_solvers())
#: the entries that keep a native object of their own (not the qpsolvers wrappers)
OWN_OBJECT = {*BACKENDS, *NAMED_SETTINGS}


def _param(name: str, *more: str) -> Any:
    reason = next((i["reason"] for i in qp.all_solvers() if i["name"] == name), "")
    return pytest.param(
        name,
        *more,
        marks=pytest.mark.skipif(name not in INSTALLED, reason=f"{name}: {reason}"),
    )


def _offers(name: str, tier: str, mode: str) -> bool:
    """Whether the entry runs at tier × mode (a missing one is kept, to show as a skip)."""
    return name not in INSTALLED or qp.solver_class(name).offers(tier, mode)


def _modes(name: str) -> tuple[str, ...]:
    return qp.solver_class(name).modes if name in INSTALLED else MODES


SOLVERS = [_param(n) for n in ALL_NAMES]
#: (name, tier, mode) for every combination the entry runs at
CHOICES = [_param(n, t, m) for n in ALL_NAMES for t in TIERS for m in MODES if _offers(n, t, m)]
#: (name, mode) at tier ``default`` and at tier ``mid`` (the tests that need 1e-6 accuracy)
DEFAULT_TIER = [_param(n, m) for n in ALL_NAMES for m in MODES if _offers(n, "default", m)]
MID = [_param(n, m) for n in ALL_NAMES for m in MODES if _offers(n, "mid", m)]

#: ‖x − x*‖∞ accepted per tier; ``default`` is each solver's own (loosest: OSQP's 1e-3).
DISTANCE = {"default": 2e-2, "low": 2e-2, "mid": 1e-4, "high": 1e-6}
#: HiGHS's QP solver does not tighten with its dual tolerance (and ignores the primal one), so
#: at ``high`` it stays at its default accuracy.
DISTANCE_FLOOR = {"highs": 1e-5, "qpsolvers:highs": 1e-5}

PROBLEMS = [
    random_qp(0, n=8, n_eq=2, n_in=5),
    random_qp(1, n=12, n_eq=4, n_in=8),
    random_qp(2, n=10, n_eq=0, n_in=6, box=False),
    random_qp(3, n=6, n_eq=3, n_in=0),
    random_qp(4, n=10, n_eq=2, n_in=6, box=False, inf_fraction=0.5),
]


def _reference(p: Problem) -> np.ndarray:
    sol = make_solver("proxqp", tier="high").solve(p)
    assert sol.success and sol.x is not None
    assert check_solution(p, sol, tol=1e-8).ok
    return sol.x


REFERENCES = [_reference(p) for p in PROBLEMS]


@pytest.mark.parametrize(("name", "tier", "mode"), CHOICES)
def test_random_qps_reach_the_reference(name: str, tier: str, mode: str) -> None:
    solver = make_solver(name, tier=tier, mode=mode)
    tol = max(DISTANCE[tier], DISTANCE_FLOOR.get(name, 0.0)) if tier == "high" else DISTANCE[tier]
    for p, ref in zip(PROBLEMS, REFERENCES, strict=True):
        for _ in range(2):  # the second call exercises warm / hot paths
            sol = solver.solve(p)
            assert sol.status is SolutionStatus.SOLVED, (p.name, sol.message)
            assert sol.solver == name and sol.tier == tier and sol.mode == solver.mode
            v = check_solution(p, sol, tol=10 * TIER_EPS.get(tier, 1e-2))
            assert v.distance_to(ref) <= tol, (p.name, v.distance_to(ref))
            assert v.primal_residual <= 10 * TIER_EPS.get(tier, 1e-2), (p.name, v)
            assert sol.wall_time > 0.0 and sol.setup_time >= 0.0
            assert abs(sol.objective - p.objective(ref)) <= 1e-3 * max(1.0, abs(sol.objective))


#: backends whose library reports the multipliers of its inequalities only, not those of the
#: rows it treats as equalities (qpmad): their duals are checked on a QP without equalities
INEQUALITY_DUALS_ONLY = {"qpmad"}


@pytest.mark.parametrize("name", [_param(n) for n in ALL_NAMES if _offers(n, "mid", "cold")])
def test_duals_follow_the_shared_convention(name: str) -> None:
    p = PROBLEMS[2] if name in INEQUALITY_DUALS_ONLY else PROBLEMS[1]
    sol = make_solver(name, tier="mid").solve(p)
    v = check_solution(p, sol, tol=1e-5, dual_tol=1e-4)
    if v.dual_residual is None:  # only wrappers that lack some duals may skip this
        assert name.startswith(QPSOLVERS_PREFIX)
        return
    assert v.ok, v


@pytest.mark.parametrize(("name", "mode"), DEFAULT_TIER)
def test_infeasible_problem_is_reported_not_raised(name: str, mode: str) -> None:
    solver = make_solver(name, mode=mode)
    for _ in range(2):
        sol = solver.solve(infeasible_qp())
        assert sol.status is not SolutionStatus.SOLVED
        # PIQP runs into its iteration limit on this problem instead of flagging it.
        allowed = {SolutionStatus.INFEASIBLE, SolutionStatus.FAILED}
        if name.endswith("piqp"):
            allowed.add(SolutionStatus.MAX_ITER)
        assert sol.status in allowed, (sol.status, sol.message)
    # The handle is still usable afterwards.
    assert solver.solve(PROBLEMS[0]).success


@pytest.mark.parametrize("name", SOLVERS)
def test_effective_mode_is_reported(name: str) -> None:
    for mode in _modes(name):
        solver = make_solver(name, mode=mode)
        expected = qp.settings.effective_mode(mode, solver.warm_start, solver.hot_start)
        assert solver.mode == expected
        assert solver.solve(PROBLEMS[0]).mode == expected
    if not qp.solver_class(name).hot_start:
        assert make_solver(name, mode="hot").mode != "hot"


@pytest.mark.parametrize("name", [n for n in SOLVERS if n.values[0] in OWN_OBJECT])
def test_hot_mode_updates_in_place_and_rebuilds_on_structure_change(name: str) -> None:
    solver = make_solver(name, mode="hot")
    if solver.mode != "hot":
        pytest.skip(f"{name} has no persistent native object")
    p = PROBLEMS[1]
    first = solver.solve(p)
    assert first.success and first.rebuilt and solver.builds == 1
    moved = dataclasses.replace(p, g=p.g + 0.05, u=p.u + 0.01)
    second = solver.solve(moved)
    assert second.success and not second.rebuilt and solver.builds == 1
    v = check_solution(moved, second, tol=1e-4)
    assert v.distance_to(_reference(moved)) <= DISTANCE["default"]
    other = PROBLEMS[0]  # a different structure
    assert other.structure_key() != p.structure_key()
    third = solver.solve(other)
    assert third.success and third.rebuilt and solver.builds == 2
    assert check_solution(other, third, tol=1e-2).distance_to(REFERENCES[0]) <= 2e-2


@pytest.mark.parametrize("name", [n for n in SOLVERS if n.values[0] in OWN_OBJECT])
def test_hot_mode_rebuilds_after_a_failed_solve(name: str) -> None:
    """A failed solve leaves a failed (possibly diverged) iterate in the native object: the next
    call must not start from it, but rebuild from the last solution that succeeded."""
    solver = make_solver(name, mode="hot")
    if solver.mode != "hot":
        pytest.skip(f"{name} has no persistent native object")
    good = infeasible_qp()
    good = dataclasses.replace(good, b=np.array([-1.0]))  # Σx = −1 with x ≤ 0: feasible
    assert solver.solve(good).success and solver.builds == 1
    assert not solver.solve(infeasible_qp()).success  # same structure: an in-place update
    after = solver.solve(good)
    assert after.success and after.rebuilt and solver.builds == 2


@pytest.mark.parametrize(
    "name", [n for n in SOLVERS if n.values[0] in OWN_OBJECT and _offers(n.values[0], "mid", "hot")]
)
def test_hot_mode_sees_in_place_changes_of_caller_arrays(name: str) -> None:
    solver = make_solver(name, tier="mid", mode="hot")
    p = dataclasses.replace(PROBLEMS[1], g=PROBLEMS[1].g.copy())
    solver.solve(p)
    p.g += 0.3  # a controller refilling a preallocated array
    sol = solver.solve(p)
    assert check_solution(p, sol, 1e-4).distance_to(_reference(p)) <= 1e-3


@pytest.mark.parametrize("name", ["proxqp", "osqp", "daqp"])
def test_warm_mode_passes_the_previous_solution(name: str) -> None:
    solver = make_solver(name, tier="mid", mode="warm")
    p = wbc_like_qp()
    first = solver.solve(p)
    second = solver.solve(p)
    assert first.iterations is not None and second.iterations is not None
    assert second.iterations < first.iterations
    # An explicit guess is passed in cold mode too.
    cold = make_solver(name, tier="mid", mode="cold")
    assert first.x is not None
    assert (cold.solve(p, x0=first.x).iterations or 0) <= (cold.solve(p).iterations or 0)


def test_qpsolvers_wrapper_passes_initvals(monkeypatch: pytest.MonkeyPatch) -> None:
    if "qpsolvers:proxqp" not in INSTALLED:
        pytest.skip("qpsolvers with proxqp not installed")
    import qpsolvers

    seen: list[Any] = []
    original = qpsolvers.solve_problem

    def spy(problem: Any, solver: str, initvals: Any = None, **kwargs: Any) -> Any:
        seen.append(initvals)
        return original(problem, solver=solver, initvals=initvals, **kwargs)

    monkeypatch.setattr(qpsolvers, "solve_problem", spy)
    solver = make_solver("qpsolvers:proxqp", mode="warm")
    first = solver.solve(PROBLEMS[0])
    solver.solve(PROBLEMS[0])
    assert seen[0] is None
    assert first.x is not None
    np.testing.assert_array_equal(seen[1], first.x)


WBC = wbc_like_qp()
WBC_REF = _reference(WBC)


@pytest.mark.parametrize(("name", "mode"), MID)
def test_wbc_like_problem(name: str, mode: str) -> None:
    """70 variables, 45 equalities, 60 inequalities, PSD rank-deficient H."""
    solver = make_solver(name, tier="mid", mode=mode)
    if name == "qpsolvers:quadprog":
        # qpsolvers passes H to quadprog unchanged; quadprog rejects a non-PD Hessian.
        sol = solver.solve(WBC)
        assert sol.status is SolutionStatus.FAILED
        assert "positive definite" in sol.message
        return
    scale = max(1.0, float(np.max(np.abs(WBC_REF))))
    if name == "eiquadprog":
        # Its stopping test accepts a sum of infeasibilities up to n_in·ε·tr(H)·tr(L⁻ᵀ)·100 (the
        # product of traces estimates H's condition): 0.16 here, where H is shifted by 2.3e-8.
        # It reports this QP optimal 0.10 outside an inequality; the independent check refuses
        # that answer.
        sol = solver.solve(WBC)
        assert sol.status is SolutionStatus.SOLVED, sol.message
        assert "H not positive definite: solved with H + " in sol.message
        v = check_solution(WBC, sol, tol=1e-6 * scale)
        assert not v.ok and 0.05 < v.primal_residual < 0.16, v
        return
    for _ in range(2):
        sol = solver.solve(WBC)
        assert sol.status is SolutionStatus.SOLVED, sol.message
        v = check_solution(WBC, sol, tol=1e-6 * scale)
        assert v.primal_residual <= 1e-6 * scale, v
        assert v.distance_to(WBC_REF) <= 1e-6 * scale, v.distance_to(WBC_REF)
    if name in ("quadprog", "qpmad"):
        assert "H not positive definite: solved with H + " in sol.message


@pytest.mark.parametrize("name", ["osqp", "clarabel", "daqp", "highs", "qpoases"])
def test_every_tier_caps_the_solve_time(name: str) -> None:
    """A stalled solve ends as a failure at the tier's time cap, never holds the run."""
    from wbcbench.qp.settings import TIER_TIME_LIMIT

    if name not in INSTALLED:
        pytest.skip(f"{name} is not installed")
    for tier in ("default", "low", "mid", "high"):
        options = make_solver(name, tier=tier).options
        assert TIER_TIME_LIMIT[tier] in options.values(), (name, tier, options)


def test_proxqp_stops_on_an_infeasible_level_it_does_not_detect() -> None:
    """A level QP of rc_lqp (14 variables, 40 inequality rows) that every other backend finds
    infeasible: ProxQP 0.8 does not, and with its default inner loops it ran for minutes. The
    inner-iteration cap of every tier ends it as a failure."""
    from pathlib import Path

    from wbcbench.qp.backends.proxqp import MAX_ITER_IN

    if "proxqp" not in INSTALLED:
        pytest.skip("proxqp is not installed")
    problem = Problem.load(Path(__file__).parent / "data" / "proxqp_stall_rc_lqp_level.npz")
    assert (problem.n, problem.n_eq, problem.n_in) == (14, 0, 40)
    for tier in TIERS:
        solver = make_solver("proxqp", tier=tier)
        assert solver.options["max_iter_in"] == MAX_ITER_IN
        if tier == "default":
            sol = solver.solve(problem)
            assert sol.status in (SolutionStatus.MAX_ITER, SolutionStatus.INFEASIBLE), sol.message
    for name in ("quadprog", "daqp", "clarabel", "qpmad", "eiquadprog"):
        if name in INSTALLED:
            assert make_solver(name).solve(problem).status is SolutionStatus.INFEASIBLE, name


def test_a_solve_past_its_time_cap_fails_as_max_iter() -> None:
    rng = np.random.default_rng(0)
    n = 300
    M = rng.standard_normal((n, n))
    problem = Problem(H=M @ M.T + 1e-3 * np.eye(n), g=rng.standard_normal(n),
                      C=rng.standard_normal((n, n)), l=-np.ones(n), u=np.ones(n))  # fmt: skip
    sol = make_solver("osqp", tier="high", time_limit=1e-6).solve(problem)
    assert sol.status == SolutionStatus.MAX_ITER, sol.message


# ---- named settings: osqp_libdwbc -------------------------------------------------------------
needs_libdwbc = pytest.mark.skipif(
    "osqp_libdwbc" not in INSTALLED, reason="osqp_libdwbc: package 'osqp' not installed"
)


def _settings_of(native: Any) -> dict[str, Any]:
    """Every setting of a native OSQP object, by name."""
    st = native.settings
    return {key: getattr(st, key) for key in dir(st) if not key.startswith("_")}


def _osqp_defaults() -> dict[str, Any]:
    """The settings of an OSQP object set up with nothing but its data."""
    import osqp
    import scipy.sparse as sp

    native = osqp.OSQP()
    one = sp.csc_matrix(np.eye(1))
    native.setup(one, np.zeros(1), one, -np.ones(1), np.ones(1))
    return _settings_of(native)


def _count_updates(solver: Any, monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Record the keyword arguments of every ``update`` call on the solver's native object."""
    calls: list[dict[str, Any]] = []
    native = solver._native
    real = native.update

    def spy(**kwargs: Any) -> Any:
        calls.append(kwargs)
        return real(**kwargs)

    monkeypatch.setattr(native, "update", spy)
    return calls


@needs_libdwbc
def test_osqp_libdwbc_is_osqp_at_libdwbcs_settings_and_the_defaults_elsewhere() -> None:
    """libdwbc sets alpha = 1.0 (and warm start, verbosity off); every other setting, the
    tolerances included, is OSQP's default: nothing else may differ from a bare OSQP object."""
    solver = make_solver("osqp_libdwbc", mode="hot")
    assert solver.solve(PROBLEMS[0]).success
    ours, defaults = _settings_of(solver._native), _osqp_defaults()
    assert ours.keys() == defaults.keys()
    assert {k: v for k, v in ours.items() if v != defaults[k]} == {"alpha": 1.0, "verbose": 0}
    assert ours["eps_abs"] == ours["eps_rel"] == 1e-3 and ours["warm_starting"] == 1
    # a rebuilt object (a new structure) gets the same settings
    assert solver.solve(PROBLEMS[1]).rebuilt
    assert _settings_of(solver._native) == ours


@needs_libdwbc
def test_osqp_libdwbc_starts_each_solve_from_the_previous_solution() -> None:
    p = wbc_like_qp()
    solver = make_solver("osqp_libdwbc", mode="hot")
    first, again = solver.solve(p), solver.solve(p)
    assert first.rebuilt and not again.rebuilt
    assert first.iterations is not None and again.iterations is not None
    assert again.iterations < first.iterations
    nearby = dataclasses.replace(p, g=1.01 * p.g)  # the next tick: nearby data
    warm = solver.solve(nearby)
    # the same settings from a fresh object and no guess
    cold = make_solver("osqp", mode="cold", eps_abs=1e-3, eps_rel=1e-3, alpha=1.0).solve(nearby)
    assert warm.success and not warm.rebuilt
    assert (warm.iterations or 0) < (cold.iterations or 0)


@needs_libdwbc
def test_osqp_libdwbc_sends_p_and_a_every_call_where_osqp_sends_what_changed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Re-sending the matrices makes OSQP factorise again: libdwbc does it every tick, hot
    ``osqp`` only when they changed (here: never, the same QP again)."""
    p = PROBLEMS[1]
    sent: dict[str, list[dict[str, Any]]] = {}
    for name in ("osqp_libdwbc", "osqp"):
        solver = make_solver(name, mode="hot")
        assert solver.solve(p).rebuilt
        sent[name] = _count_updates(solver, monkeypatch)
        for _ in range(3):
            sol = solver.solve(p)
            assert sol.success and not sol.rebuilt
    assert [sorted(kw) for kw in sent["osqp_libdwbc"]] == [["Ax", "Px", "l", "q", "u"]] * 3
    assert sent["osqp"] == []
    first = sent["osqp_libdwbc"][0]
    np.testing.assert_array_equal(first["q"], p.g)
    assert first["Px"].size == np.count_nonzero(np.triu(p.H) + np.eye(p.n))  # all of triu(H)


# ---- qpmad: the duals it reports, the factor it keeps -----------------------------------------
needs_qpmad = pytest.mark.skipif(
    "qpmad" not in INSTALLED, reason="qpmad: package 'pyqpmad' not installed"
)


@needs_qpmad
def test_qpmad_reports_the_duals_of_its_inequalities_only() -> None:
    """qpmad gives the multipliers of its active inequalities (they equal the reference's) and
    not those of the rows it treats as equalities: ``y`` with equality rows, ``z`` when a row of
    ``C`` has equal sides."""
    p = PROBLEMS[1]
    sol = make_solver("qpmad").solve(p)
    ref = make_solver("proxqp", tier="high").solve(p)
    assert sol.success and sol.y is None and sol.z is not None and sol.z_box is not None
    assert ref.z is not None and ref.z_box is not None
    np.testing.assert_allclose(sol.z, ref.z, rtol=0, atol=1e-6)
    np.testing.assert_allclose(sol.z_box, ref.z_box, rtol=0, atol=1e-6)
    assert check_solution(p, sol, tol=1e-8).dual_residual is None
    q = PROBLEMS[2]  # no equality rows: every dual
    assert make_solver("qpmad").solve(q).y is not None
    sides = q.C[0] @ REFERENCES[2]
    pinned = dataclasses.replace(q, l=q.l.copy(), u=q.u.copy())
    pinned.l[0] = pinned.u[0] = sides  # an equality written as an inequality
    sol = make_solver("qpmad").solve(pinned)
    assert sol.success and sol.z is None
    assert check_solution(pinned, sol, tol=1e-8).ok


@needs_qpmad
def test_qpmad_hot_reuses_the_cholesky_factor_while_h_is_unchanged() -> None:
    import pyqpmad

    kinds = pyqpmad.HessianType
    p = PROBLEMS[1]
    solver = make_solver("qpmad", mode="hot")
    assert solver.solve(p).rebuilt
    assert solver._native.params.hessian_type == kinds.HESSIAN_LOWER_TRIANGULAR
    for moved in (
        dataclasses.replace(p, g=p.g + 0.05, u=p.u + 0.01),  # H unchanged: its factor reused
        dataclasses.replace(p, H=p.H + 0.1 * np.eye(p.n)),  # H changed: factorised again
    ):
        sol = solver.solve(moved)
        kind = (
            kinds.HESSIAN_LOWER_TRIANGULAR if moved.H is not p.H else kinds.HESSIAN_CHOLESKY_FACTOR
        )
        assert sol.success and not sol.rebuilt
        assert solver._native.params.hessian_type == kind
        cold = make_solver("qpmad").solve(moved)
        assert check_solution(moved, sol, tol=1e-8).distance_to(cold.x) <= 1e-9
    # a semidefinite H: the factor kept is that of the shifted H, and the message says so
    solver = make_solver("qpmad", mode="hot")
    first, again = solver.solve(WBC), solver.solve(dataclasses.replace(WBC, g=WBC.g + 0.01))
    assert not again.rebuilt and "H not positive definite" in again.message
    assert again.message == first.message
    assert solver._native.params.hessian_type == kinds.HESSIAN_CHOLESKY_FACTOR
