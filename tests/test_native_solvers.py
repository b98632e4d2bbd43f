"""The QP solvers the native module calls from C++ (``QPSolver.native_solver``) against the
Python backends they mirror: the same library, settings and update policy, so on the same
sequence of QPs the same answers, iteration counts and statuses, in every mode. eiquadprog's
Python backend solves through the same C++ class (the library has no Python binding), so its
answers are also held to their KKT conditions and to quadprog's optimum."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.controllers.native import qp_view
from wbcbench.qp import Problem, available_solvers, check_solution, make_solver, solver_class
from wbcbench.qp.settings import MODES

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

#: (solver, tier) pairs that have a C++ counterpart (qpoases and eiquadprog run every tier with
#: their default settings: one tier covers each)
CASES = [
    ("osqp", "default"),
    ("osqp", "high"),
    ("osqp_libdwbc", "default"),
    ("qpoases", "default"),
    ("qpoases_libdwbc", "default"),
    ("eiquadprog", "default"),
    ("daqp", "default"),
    ("daqp", "high"),
]

#: how far the C++ x, y, z, z_box may be from the Python ones: the same OSQP code gives the same
#: bits; cmeel's qpOASES multiplies with its own loops where CasADi's calls OpenBLAS, which moves
#: round-off (measured on this sequence: at most 7.3e-15, every mode)
ATOL = {"qpoases": 1e-10}


def sequence(rng: np.random.Generator, n: int, n_eq: int, n_in: int, box: bool) -> list[Problem]:
    """A drifting sequence of feasible QPs, as a controller's ticks make them: the same
    structure, values moving a little; an entry of A and of H turns zero and back (a new
    sparsity pattern for a sparse backend) and one QP is infeasible."""
    L = rng.standard_normal((n, n)) / np.sqrt(n)
    H0 = L @ L.T + 0.1 * np.eye(n)
    A0 = rng.standard_normal((n_eq, n))
    C0 = rng.standard_normal((n_in, n))
    x_feas = rng.standard_normal(n) * 0.1
    out = []
    for k in range(24):
        d = 0.01 * k
        H = H0 + d * np.diag(np.arange(n) / n)
        A = A0 + d * 0.1
        C = C0 - d * 0.05
        if k in (8, 9):
            A[0, 0] = 0.0
            H[0, 1] = H[1, 0] = 0.0
        b = A @ x_feas
        cx = C @ x_feas
        l_ = cx - 0.05 - 0.1 * rng.random(n_in)
        u_ = cx + 0.05 + 0.1 * rng.random(n_in)
        l_[:2] = u_[:2] = cx[:2]  # equal sides (an equality written as an inequality)
        l_[2] = -np.inf
        g = rng.standard_normal(n)
        lb = ub = None
        if box:
            lb, ub = x_feas - 0.2, x_feas + 0.2
        if k == 15:  # infeasible: two equal rows of A with different right-hand sides
            A[1] = A[0]
            b[1] = b[0] + 1.0
        out.append(Problem(H, g, A, b, C, l_, u_, lb, ub, name="seq"))
    return out


def fill(buf: Any, problem: Problem) -> None:
    buf.resize(problem.n, problem.n_eq, problem.n_in, problem.has_box)
    view = qp_view(buf, "seq")
    for key in ("H", "g", "A", "b", "C", "l", "u"):
        getattr(view, key)[...] = getattr(problem, key)
    if problem.has_box:
        view.lb[...], view.ub[...] = problem.box()


@pytest.mark.parametrize("box", [False, True], ids=["no-box", "box"])
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize(("solver", "tier"), CASES, ids=[f"{s}-{t}" for s, t in CASES])
def test_native_solver_equals_python(solver: str, tier: str, mode: str, box: bool) -> None:
    offered = solver_class(solver).offers(tier, mode)
    py = make_solver(solver, tier=tier, mode=mode if offered else "hot")
    cpp = py.native_solver()
    assert cpp is not None
    buf = _native._core.QpBuffers()
    rng = np.random.default_rng(3)
    statuses = set()
    for problem in sequence(rng, 30, 6, 20, box):
        fill(buf, problem)
        a = py.solve(problem, lean=True)
        status, iterations, _, _, internal, call, rebuilt, message = cpp.solve(buf)
        statuses.add(status)
        iterations = None if iterations < 0 else iterations  # < 0: not reported
        assert (status, iterations, rebuilt) == (a.status.value, a.iterations, a.rebuilt)
        assert message == a.message
        if not py.internal_time_covers:
            assert internal != internal  # NaN: the library has no timer
        elif iterations is not None:  # a solve ran (not a failed set-up)
            assert internal >= 0.0
        assert call > 0.0
        if a.success:
            assert a.x is not None
            atol = ATOL.get(solver, 1e-12)
            np.testing.assert_allclose(cpp.x, a.x, rtol=0, atol=atol)
            np.testing.assert_allclose(cpp.y, a.y, rtol=0, atol=atol)
            np.testing.assert_allclose(cpp.z, a.z, rtol=0, atol=atol)
            if box:
                np.testing.assert_allclose(cpp.z_box, a.z_box, rtol=0, atol=atol)
    # the infeasible QP failed in both (eiquadprog reports it solved, in both: see
    # test_eiquadprog_meets_the_kkt_conditions_except_where_its_tests_are_loose)
    assert "solved" in statuses and (len(statuses) > 1 or solver == "eiquadprog")
    assert cpp.builds == py.builds


def test_unknown_setting_stays_in_python() -> None:
    py = make_solver("osqp", solver_type="direct")
    assert py.native_solver() is None
    with pytest.raises(ValueError, match="osqp has no setting 'nope'"):
        _native._core.OsqpSolver("hot", {"nope": 1.0})
    assert make_solver("qpoases", nWSR=10).native_solver() is None
    with pytest.raises(ValueError, match="qpoases \\(native\\) takes no setting 'nope'"):
        _native._core.QpOasesSolver("hot", {"CPUtime": 5.0, "nope": 10.0})
    assert make_solver("daqp", nope=1).native_solver() is None
    with pytest.raises(ValueError, match="daqp has no setting 'nope'"):
        _native._core.DaqpSolver("hot", {"nope": 1.0})
    assert make_solver("eiquadprog", nope=1).native_solver() is None
    with pytest.raises(ValueError, match="eiquadprog has no setting 'nope' \\(only max_iter\\)"):
        _native._core.EiquadprogSolver("hot", {"nope": 1.0})
    sol = make_solver("eiquadprog", nope=1).solve(
        sequence(np.random.default_rng(0), 6, 2, 3, False)[0]
    )
    assert sol.status.value == "failed" and "no setting 'nope'" in sol.message


@pytest.mark.parametrize("mode", ["cold", "hot"])
def test_qpoases_box_only(mode: str) -> None:
    """No constraint rows: CasADi solves with a QProblemB, initialised again on every call (never
    hot-started), and so does the C++ one."""
    rng = np.random.default_rng(5)
    n = 12
    L = rng.standard_normal((n, n)) / np.sqrt(n)
    H0 = L @ L.T + 0.1 * np.eye(n)
    empty = np.zeros((0, n))
    py = make_solver("qpoases", mode=mode)
    cpp = py.native_solver()
    buf = _native._core.QpBuffers()
    for k in range(8):
        problem = Problem(
            H0 + 0.01 * k * np.eye(n),
            rng.standard_normal(n),
            empty,
            np.zeros(0),
            empty,
            np.zeros(0),
            np.zeros(0),
            np.full(n, -0.3),
            np.full(n, 0.3),
            name="box",
        )
        fill(buf, problem)
        a = py.solve(problem, lean=True)
        status, iterations, _, _, _, _, rebuilt, message = cpp.solve(buf)
        assert (status, iterations, rebuilt, message) == (
            a.status.value,
            a.iterations,
            a.rebuilt,
            a.message,
        )
        assert a.success and a.x is not None and a.z_box is not None
        np.testing.assert_allclose(cpp.x, a.x, rtol=0, atol=1e-10)
        np.testing.assert_allclose(cpp.z_box, a.z_box, rtol=0, atol=1e-10)
    assert cpp.builds == py.builds


@pytest.mark.parametrize("mode", ["cold", "hot"])
def test_qpoases_ill_posed_bounds(mode: str) -> None:
    """Bounds CasADi refuses (lower above upper): a failed solve on both sides, the C++ message
    being the end of CasADi's exception text, and no object kept."""
    rng = np.random.default_rng(1)
    n = 4
    problem = Problem(
        np.eye(n),
        rng.standard_normal(n),
        rng.standard_normal((1, n)),
        np.zeros(1),
        rng.standard_normal((2, n)),
        np.array([0.5, -1.0]),
        np.array([0.2, 1.0]),
        name="ill",
    )
    py = make_solver("qpoases", mode=mode)
    cpp = py.native_solver()
    buf = _native._core.QpBuffers()
    fill(buf, problem)
    a = py.solve(problem, lean=True)
    status, *_, message = cpp.solve(buf)
    assert status == a.status.value == "failed"
    # row 1 of [A; C]: C's first row
    assert message == (
        "Ill-posed problem detected: LBA[1] <= UBA[1] was violated. "
        "Got LBA[1] = 0.5 and UBA[1] = 0.2."
    )
    assert a.message.endswith(message)
    assert cpp.builds == py.builds == 0


needs_eiquadprog = pytest.mark.skipif(
    "eiquadprog" not in available_solvers(), reason="eiquadprog is not available"
)


@needs_eiquadprog
@pytest.mark.parametrize("box", [False, True], ids=["no-box", "box"])
@pytest.mark.parametrize("mode", MODES)
def test_eiquadprog_meets_the_kkt_conditions_except_where_its_tests_are_loose(
    mode: str, box: bool
) -> None:
    """The C++ answers of every mode against an independent oracle: their own KKT conditions
    (primal and dual residuals, duality gap) and a high-accuracy reference's optimum. One QP
    has two equal rows of A with different right-hand sides: whether the library's test for
    dependent equalities (a pivot below ε times the largest) catches the rounding-level pivot
    depends on the rounding, so it reports that QP infeasible, or optimal at a point 1.0 off
    the equalities, which the independent check refuses. Either way no wrong answer passes."""
    solver = make_solver("eiquadprog", mode=mode)
    for k, problem in enumerate(sequence(np.random.default_rng(3), 30, 6, 20, box)):
        sol = solver.solve(problem)
        if k == 15:
            if sol.success:
                check = check_solution(problem, sol, tol=1e-9)
                assert not check.ok and check.primal_residual > 0.5, check
            continue
        assert sol.success, (k, sol.message)
        check = check_solution(problem, sol, tol=1e-9)
        assert check.ok, (k, check)
        ref = make_solver("proxqp", tier="high").solve(problem)
        assert ref.x is not None and check_solution(problem, ref, tol=1e-8).ok
        scale = max(1.0, float(np.abs(ref.x).max()))
        assert check.distance_to(ref.x) <= 1e-7 * scale, (k, check.distance_to(ref.x))


@needs_eiquadprog
def test_eiquadprog_hot_rebuilds_when_the_finite_sides_change() -> None:
    """Each finite side is a row of the library's CI: a side turning infinite changes its
    sizes, so the kept object is rebuilt, in the Python handle and its C++ counterpart alike."""
    problems = sequence(np.random.default_rng(4), 12, 3, 8, True)[:4]
    problems[2] = dataclasses.replace(problems[2], u=problems[2].u.copy())
    problems[2].u[5] = np.inf
    py = make_solver("eiquadprog", mode="hot")
    cpp = py.native_solver()
    buf = _native._core.QpBuffers()
    rebuilt = []
    for problem in problems:
        fill(buf, problem)
        a = py.solve(problem, lean=True)
        status, *_, again, message = cpp.solve(buf)
        assert (status, again, message) == (a.status.value, a.rebuilt, a.message)
        assert a.success and check_solution(problem, a, tol=1e-9).ok
        rebuilt.append(a.rebuilt)
    assert rebuilt == [True, False, True, True]
    assert py.builds == cpp.builds == 3


# ---- qpoases_libdwbc ---------------------------------------------------------------------------
EPS = 2.221e-16  # qpOASES: EPS
#: Options::setToDefault() (qpOASES 3.2), the fields setToMPC / setToReliable change
DEFAULTS = {
    "enableRamping": 1.0,
    "enableFarBounds": 1.0,
    "enableFlippingBounds": 1.0,
    "enableRegularisation": 0.0,
    "enableFullLITests": 0.0,
    "enableNZCTests": 1.0,
    "enableDriftCorrection": 1.0,
    "enableCholeskyRefactorisation": 0.0,
    "enableEqualities": 0.0,
    "terminationTolerance": 5e6 * EPS,
    "initialStatusBounds": -1.0,
    "numRegularisationSteps": 0.0,
    "numRefinementSteps": 1.0,
}
#: qpOASES' Options::setToMPC() and setToReliable(), from its documentation
MPC = {
    **DEFAULTS,
    "enableRamping": 0.0,
    "enableFlippingBounds": 0.0,
    "enableRegularisation": 1.0,
    "enableNZCTests": 0.0,
    "enableDriftCorrection": 0.0,
    "enableEqualities": 1.0,
    "terminationTolerance": 1e9 * EPS,
    "initialStatusBounds": 0.0,
    "numRegularisationSteps": 1.0,
    "numRefinementSteps": 0.0,
}
RELIABLE = {
    **DEFAULTS,
    "enableFullLITests": 1.0,
    "enableCholeskyRefactorisation": 1.0,
    "numRefinementSteps": 2.0,
}

needs_qpoases_libdwbc = pytest.mark.skipif(
    "qpoases_libdwbc" not in available_solvers(), reason="qpoases_libdwbc not available"
)


@needs_qpoases_libdwbc
@pytest.mark.parametrize(
    ("kind", "expected"), [("task", MPC), ("wrench", RELIABLE)], ids=["task", "wrench"]
)
def test_qpoases_libdwbc_options_are_libdwbcs_per_qp_kind(
    kind: str, expected: dict[str, float]
) -> None:
    """libdwbc: setToMPC() for a task QP, setToReliable() for the contact-wrench QP, printing
    off; CasADi's usage: the defaults with equalities on."""
    py = make_solver("qpoases_libdwbc", mode="hot")
    py.qp_kind = kind
    settings = py.native_solver().settings()
    assert {k: settings[k] for k in expected} == pytest.approx(expected, rel=1e-12)
    assert settings["printLevel"] == 0.0  # PL_NONE
    casadi = make_solver("qpoases", mode="hot").native_solver().settings()
    assert {k: casadi[k] for k in DEFAULTS} == pytest.approx(
        {**DEFAULTS, "enableEqualities": 1.0}, rel=1e-12
    )


@needs_qpoases_libdwbc
def test_qpoases_libdwbc_hot_starts_from_its_working_set() -> None:
    """init once; then the vector hotstart while H and [A; C] stay the same (nWSR 0 on a repeated
    QP), the matrix hotstart when they change; the answers meet their KKT conditions and equal
    a fresh CasADi-usage solve's."""
    rng = np.random.default_rng(11)
    base = sequence(rng, 20, 2, 14, False)
    cpp = make_solver("qpoases_libdwbc", mode="hot").native_solver()
    buf = _native._core.QpBuffers()
    calls = []
    problems = [base[0], base[0], dataclasses.replace(base[0], g=base[1].g), base[2]]
    for k, problem in enumerate(problems):
        fill(buf, problem)
        status, iterations, *_ = cpp.solve(buf)
        assert status == "solved", k
        calls.append((cpp.last_call, iterations))
        fresh = make_solver("qpoases").solve(problem)  # CasADi's usage, a fresh object
        assert fresh.x is not None
        np.testing.assert_allclose(cpp.x, fresh.x, rtol=0, atol=1e-7)
        mine = dataclasses.replace(fresh, x=np.array(cpp.x), z=np.array(cpp.z))
        assert check_solution(problem, mine, tol=1e-7).ok
    assert [c for c, _ in calls] == ["init", "hotstart", "hotstart", "hotstart_matrices"]
    assert calls[1][1] == 0  # the same QP again: no working-set change
    assert cpp.builds == 1


@needs_qpoases_libdwbc
def test_qpoases_libdwbc_falls_back_to_a_reliable_init() -> None:
    """A hotstart that fails is followed, in the same call, by a fresh object initialised with
    setToReliable (libdwbc's fallback): reported as rebuilt; an infeasible QP still fails."""
    rng = np.random.default_rng(3)
    seq = sequence(rng, 30, 6, 20, False)
    cpp = make_solver("qpoases_libdwbc", mode="hot").native_solver()
    buf = _native._core.QpBuffers()
    for problem in seq[:15]:
        fill(buf, problem)
        assert cpp.solve(buf)[0] == "solved"
    fill(buf, seq[15])  # infeasible
    status, _, _, _, _, _, rebuilt, _ = cpp.solve(buf)
    assert (status, rebuilt, cpp.last_call) == ("infeasible", True, "reinit")
    fill(buf, seq[16])
    assert cpp.solve(buf)[0] == "solved" and cpp.last_call == "init"


@needs_qpoases_libdwbc
def test_osf_hqp_asks_for_a_wrench_handle_for_its_final_qp() -> None:
    """The QP kind picks libdwbc's options: osf_hqp's levels are task QPs (setToMPC), its final
    contact-wrench QP is the wrench kind (setToReliable); an unknown kind is refused."""
    from wbcbench.controllers.registry import make_controller
    from wbcbench.robots.loader import load_robot
    from wbcbench.runs import scenario_context
    from wbcbench.scenarios.load import load_scenario

    loaded = load_scenario("libdwbc_osf_cycle")
    ctx = scenario_context(
        loaded, load_robot(loaded.spec.robot), solver="qpoases_libdwbc", mode="hot"
    )
    controller: Any = make_controller("osf_hqp", ctx, {"impl": "native"})
    assert [h.qp_kind for h in controller.solvers] == ["task", "task"]
    assert controller.final_solver.qp_kind == "wrench"
    assert controller.final_solver.native_solver().settings() == pytest.approx(
        {**controller.solvers[0].native_solver().settings(), **RELIABLE}
    )
    with pytest.raises(ValueError, match="unknown QP kind 'nope'; valid choices: task, wrench"):
        ctx.new_solver("nope")


@needs_qpoases_libdwbc
@pytest.mark.parametrize("impl", ["python", "native"])
@pytest.mark.parametrize("scenario", ["libdwbc_osf_cycle", "lee2021iros_table1"])
def test_qpoases_libdwbc_solves_the_first_tick_of_a_replay(scenario: str, impl: str) -> None:
    """The contact-wrench QP's first solve is an init from scratch: it stays within libdwbc's
    cap of 300 working-set changes (started at setToReliable's lower bounds, the homotopy
    cycled past it and the tick failed), and every QP of the first ticks passes the independent
    KKT check; the wrench QP then hot-starts."""
    from wbcbench.bench.checks import CHECK_FACTOR, SolverCapture, check_reported
    from wbcbench.runs import plan_run
    from wbcbench.scenarios.load import load_scenario
    from wbcbench.sim.replay import record_states, replay

    loaded = load_scenario(scenario, ("duration=0.006",))
    rec = record_states(plan_run(loaded, "osf_hqp"))
    pairs: list[tuple[Problem, Any]] = []
    wrench: list[Any] = []

    def check(i: int, out: Any) -> str:
        wrench.append(next(sol for problem, sol in pairs if problem.name == "wrench"))
        message = check_reported(pairs, CHECK_FACTOR)
        pairs.clear()
        return message

    params = "periodic:1" if scenario == "libdwbc_osf_cycle" else "inline"
    config = {"impl": impl, "params": params}
    run = plan_run(loaded, "osf_hqp", "qpoases_libdwbc", mode="hot", config=config, timing=True)
    timings = replay(run, rec, on_step=check, wrap_solver=lambda h: SolverCapture(h, pairs))
    assert (timings.failures, timings.message) == (0, "")
    assert len(wrench) == len(rec) >= 3
    assert wrench[0].success and wrench[0].iterations < 300
    assert all(sol.success and not sol.rebuilt for sol in wrench[1:])
