"""The native hierarchy and its controllers (``hqp``, ``lqp``) equal the Python reference.

The engine first: on random hierarchies with conflicting levels, active inequalities and a
hard box, every strategy with every shortcut (merged finals, levels held hard when feasible,
slack-free first tries, proximal retry) gives the Python reference's solution and slacks.

Then the controllers, on the states of :mod:`tests.test_native_equality` (perturbed keyframes
in double support, single support, a hand on a wall, a force-level task), for every installed
backend. A hierarchy's optimum is unique (the last level's energy is strictly convex), but the
map from data to optimum is badly conditioned: the two Python strategies that define the same
optimum (cascade and null-space) differ by up to 0.3 relative on these states, from rounding
and the solvers' tolerances alone, and the null-space bases of the two impls differ the same
way. So, on each state both impls solve:

* every level's optimal slack norms agree, to 3e-6 relative with an active-set backend and 1e-3
  with an iterative one, or to 10 times the difference the two Python strategies show on the
  same state where that is larger. A level's optimum moves with the optimal slacks held from
  the levels above, by their multipliers times the change (the optimal value is convex in the
  held right-hand sides): rounding-level differences of a held slack whose multiplier is large
  move it beyond 3e-6 (measured: w.p5 of lqp on a wall state 7.2e-6 apart under one BLAS
  kernel, equal to that sensitivity bound), and the strategies' spread measures it;
* a state on which either impl retried a level with the proximal term is not compared: that
  impl solved the regularised level, whose optimum lies up to ½ρ‖x* − x_c‖² above the bare
  level's (DAQP, whose automatic proximal iterations engage or not on a numerically singular
  level Hessian by rounding, hits its iteration cap on the bare level in one impl and not the
  other); both answers are still checked as below;
* the native answer is what it must be: the floating-base dynamics met and the torques within
  their limits;
* with an active-set backend, τ, q̈ and f agree to 10 times the spread the Python strategies
  show on the same states (at least 1e-8), wherever the other strategy solves; an iterative
  backend's answers move with its stopping point, which the slacks and the checks above bound.
  The Goldfarb–Idnani backends (quadprog, qpmad, eiquadprog) need a positive definite Hessian
  and solve a semidefinite level as H + δI with the smallest δ = 1e-12 · 100ᵏ · max(1, |H_ii|)
  that factorises: whether the Cholesky factorisation of a numerically singular H succeeds at
  a given δ is decided by rounding, so each impl may solve a level regularised by another δ,
  and their answers agree to at least 1e-5 (measured: 1.5e-6 with quadprog on a wall state
  where the strategies' spread is 1.1e-8).

A backend may fail on a state in one impl and not the other, or at another level, where its
stopping rule meets a level QP whose feasible set is thin: the rows held from the levels above
leave it no interior, so it is feasible only by the hierarchy's widening of its bounds
(FEAS_TOL × the level's index + the violation carried from above, 1e-9 to 2e-7 of
1 + |bound|), of the order of the backend's own primal tolerance (1e-9 at tier high). The two
impls hand the backend the same level QP to rounding (the same null-space bases, ‖ΔH‖ ≤ 1e-14
relative; the bounds, which carry the slacks held from above, apart by as much as those
levels' answers: 1e-12 with DAQP, more with an iterative backend), and which impl's data the
backend calls feasible, or on which its interior-point iterations stall, is then decided by
rounding (DAQP and ProxQP declare it infeasible, Clarabel ends in InsufficientProgress or
AlmostSolved, ProxQP at its iteration cap). So such a mismatch is allowed, on any number of
states, when the failure is the backend's own verdict (an iteration cap, infeasibility or
numerical trouble reported by the backend, qpsolvers' "no solution found", which is how
qpsolvers reports them, or qpOASES's "QP could not be solved", which it reports when its
initial working set fails) and the failing level's QP lies in the band:
its feasibility margin (:func:`~wbcbench.qp.validity.feasibility_margin`, the largest
uniform tightening of its bounds, relative to 1 + |bound|, that leaves it feasible) is below
:func:`feasibility_band` (max(1e-6, 10 × the tier's accuracy), the hierarchy's own tolerance
for a held row's rounding; measured: every mismatch lies between 3e-9 and 2e-7, while 83 % of
the level QPs of the states where the impls agree lie above 1e-6; see docs/native.md,
"Feasibility verdicts");
any other failure in one impl only is an error. Every answer an impl does give is
checked in full (the dynamics and torque limits above); a case where no state is solved by
both impls compares nothing and is reported as skipped, with that reason.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.controllers import native
from wbcbench.controllers.native import frozen
from wbcbench.dynamics.state import RobotState
from wbcbench.qp import Problem, QPSolver, make_solver
from wbcbench.qp.hierarchy import accept_tol, accept_tol_for, solve_hierarchy
from wbcbench.qp.registry import solver_class
from wbcbench.qp.validity import feasibility_margin

from .conftest import ANY_TIER_SOLVERS, grounded_state
from .test_hierarchy import PAST_THE_BOUND, BoundBreaking, random_hierarchy
from .test_native_equality import CASES, build_pair, relative

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

STRATEGIES = ("cascade", "nullspace", "weighted")


def native_hierarchy(hard: Any, levels: list[Any], finals: list[Any]) -> tuple[Any, list[Any]]:
    """The Python hierarchy's data as the native engine takes them."""
    core = _native.core()
    h = core.HardConstraints()
    h.A, h.b, h.C, h.l, h.u = hard.A, hard.b, hard.C, hard.l, hard.u
    if hard.lb is not None:
        h.lb, h.ub = hard.lb, hard.ub
    soft = []
    for lv in [*levels, *(f.as_level() for f in finals)]:
        lv = lv.prepared(hard.n)
        p = core.PriorityLevel()
        p.name, p.A, p.b, p.C, p.l, p.u = lv.name, lv.A, lv.b, lv.C, lv.l, lv.u
        p.weight, p.hard_if_feasible = lv.weight, lv.hard_if_feasible
        soft.append(p)
    return h, soft


@pytest.mark.parametrize("strategy", STRATEGIES)
@pytest.mark.parametrize("shortcuts", ["none", "merge", "slack_free", "both"])
@pytest.mark.parametrize("solver", ["daqp", "quadprog"])
def test_engine_equals_python(strategy: str, shortcuts: str, solver: str) -> None:
    merge = shortcuts in ("merge", "both")
    slack_free = shortcuts in ("slack_free", "both")
    core = _native.core()
    for seed in range(6):
        for active in (False, True):
            hard, levels, finals = random_hierarchy(seed, active=active)
            levels[0].hard_if_feasible = seed % 2 == 1
            n_handles = 2 * (len(levels) + len(finals))
            python = solve_hierarchy(
                hard,
                levels,
                finals,
                strategy,
                [make_solver(solver, tier="high") for _ in range(n_handles)],
                prox=1e-8,
                merge_finals=merge,
                slack_free_first=slack_free,
            )
            engine = core.Hierarchy(0)
            handles = [make_solver(solver, tier="high") for _ in range(n_handles)]
            solve = native.LevelSolve(lambda pool, i, e=engine: e.slot(i), [handles])
            options = core.HierarchyOptions()
            options.strategy = getattr(core.Strategy, strategy)
            options.prox, options.merge_finals = 1e-8, merge
            options.slack_free_first, options.handles = slack_free, n_handles
            data = native_hierarchy(hard, levels, finals)
            result = engine.solve(*data, len(finals), options, solve)
            assert result.ok == python.ok
            assert relative(result.x, python.x) <= 1e-7, (seed, active)
            assert [lv.name for lv in result.levels] == [lv.name for lv in python.levels]
            for a, b in zip(result.levels, python.levels, strict=True):
                assert relative(a.w, b.w) <= 1e-7 and relative(a.v, b.v) <= 1e-7, a.name


def test_engine_failure_names_the_level() -> None:
    core = _native.core()
    hard, levels, finals = random_hierarchy(0)
    engine = core.Hierarchy(0)
    calls: list[tuple[int, int, str]] = []

    def fail(pool: int, handle: int, slot: int, reshaped: bool, level: str) -> None:
        calls.append((pool, handle, level))
        return None

    options = core.HierarchyOptions()
    options.strategy, options.prox, options.handles = core.Strategy.cascade, 1e-8, 4
    result = engine.solve(*native_hierarchy(hard, levels, finals), 1, options, fail)
    assert not result.ok and result.failed_level == "L1"
    # the bare QP, then its proximal retry, both with the level's handle
    assert calls == [(0, 0, "L1"), (0, 0, "L1")]
    assert result.retries == 1
    options.handles = 1  # fewer handles than QPs
    with pytest.raises(ValueError, match="one solver handle per level"):
        engine.solve(*native_hierarchy(hard, levels, finals), 1, options, fail)


def breaking_handles(strategy: str) -> list[Any]:
    """Four DAQP handles, the one of L2 (of the one QP when weighted) a BoundBreaking one whose
    bare QP is declared infeasible."""
    handles: list[Any] = [make_solver("daqp", tier="high") for _ in range(4)]
    if strategy == "weighted":
        handles[0] = BoundBreaking(0.5)
    else:
        handles[1] = BoundBreaking(0.5, infeasible_first=True)
    return handles


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_engine_refuses_an_answer_past_a_hard_bound(strategy: str) -> None:
    core = _native.core()
    hard, levels, finals = random_hierarchy(0)
    python = solve_hierarchy(hard, levels, finals, strategy, breaking_handles(strategy), prox=1e-8)
    engine = core.Hierarchy(0)
    handles = breaking_handles(strategy)
    solve = native.LevelSolve(lambda pool, i: engine.slot(i), [handles])
    options = core.HierarchyOptions()
    options.strategy = getattr(core.Strategy, strategy)
    options.prox, options.handles = 1e-8, len(handles)
    options.accept_tol = accept_tol(handles[0])
    result = engine.solve(*native_hierarchy(hard, levels, finals), len(finals), options, solve)
    level = "weighted" if strategy == "weighted" else "L2"
    assert not result.ok and not python.ok and result.failed_level == level
    assert re.fullmatch(PAST_THE_BOUND, result.message), result.message
    prefix = "weighted: failed: " if level == "weighted" else "level 'L2': daqp: failed: "
    for message in (solve.message(level, result.message), python.message):
        assert re.fullmatch(prefix + PAST_THE_BOUND, message), message


#: the controllers and the settings each is compared in; the strategy whose Python answer
#: measures the spread
CONTROLLERS: list[tuple[str, dict[str, Any], str]] = [
    ("lqp", {"strategy": "nullspace"}, "cascade"),
    ("lqp", {"strategy": "cascade"}, "nullspace"),
    ("hqp", {"strategy": "cascade", "finals": ["torque"]}, "nullspace"),
    ("hqp", {"strategy": "nullspace", "finals": ["wrench", "zero_torque_energy"]}, "cascade"),
]
ACTIVE_SET = {"quadprog", "qpoases", "daqp", "qpmad", "eiquadprog"}
#: (controller, backend) → cases where the backend runs for tens of seconds per state in either
#: impl (OSQP and HiGHS at tier high to their caps on these semidefinite level QPs; ProxQP,
#: which has no time cap, for minutes on the HQP's wall states); the rest of its cases run
SLOW: dict[tuple[str, str], set[str]] = {
    ("lqp", "osqp"): {"double", "force_level", "wall"},
    ("lqp", "highs"): {"double", "force_level"},
    ("hqp", "osqp"): set(CASES),
    ("hqp", "highs"): {"double", "force_level"},
    ("hqp", "proxqp"): {"wall"},
}


#: backends that solve a semidefinite level Hessian as H + δI with the smallest δ whose
#: Cholesky factorisation succeeds: which δ is decided by rounding, in each impl on its own
#: (see the module docstring)
REGULARISING = ("quadprog", "qpmad", "eiquadprog")

#: a level QP the backend itself gave up on or declared infeasible (see the module docstring)
BACKEND_VERDICT = re.compile(
    r"level '[^']+': \S+: (max_iter|infeasible|numerical): "
    r"|qpsolvers: no solution found$|QP could not be solved!$"
)


#: (controller, backend) whose one-impl failures may lie outside :func:`feasibility_band`:
#: Clarabel on hqp's level QPs ends in AlmostSolved or InsufficientProgress in one impl on
#: levels with room to spare (measured margins 0.18 to 0.86, a semidefinite Hessian, |z| up to
#: 2e3, data apart by a null-space rotation or by 4e-6 in the held equalities' right-hand
#: side), a cause the margin does not measure, not explained yet (docs/native.md)
OUTSIDE_BAND = {("hqp", "clarabel")}

#: qpOASES's own initialisation giving up (its initial homotopy, not a verdict on the level's
#: feasibility): it may end so on a level with room to spare (measured: lqp, the wall state,
#: native, under OPENBLAS_CORETYPE=Prescott, margin 0.125), so it is not held to the band
QPOASES_INIT_FAILED = re.compile(r"Initialisation failed! QP could not be solved!$")


#: the band of feasibility margins inside which the two impls may disagree on whether a step
#: is feasible, for a backend asked for ``accuracy``: a level QP whose feasible set reaches less
#: than this (relative to 1 + |bound|, :func:`~wbcbench.qp.validity.feasibility_margin`) inside
#: its bounds. The same measure as the acceptance of a level's answer
#: (:func:`~wbcbench.qp.hierarchy.accept_tol_for`: max(1e-6, 10 × accuracy)): a set thinner
#: than what the hierarchy accepts as a held row's rounding is feasible only to rounding
def feasibility_band(solver: str) -> float:
    return accept_tol_for(float(solver_class(solver).accuracy("high")))


class QpRecorder:
    """While active, a copy of every QP a Python solver handle is given, in order (the native
    ticks' level QPs that C++ solves itself are in their step's ``problems``)."""

    def __init__(self) -> None:
        self.problems: list[Problem] = []
        self._solve: Any = None

    def __enter__(self) -> QpRecorder:
        solve = self._solve = QPSolver.solve

        def recording(handle: QPSolver, problem: Problem, *args: Any, **kwargs: Any) -> Any:
            self.problems.append(frozen(problem))
            return solve(handle, problem, *args, **kwargs)

        QPSolver.solve = recording  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        QPSolver.solve = self._solve  # type: ignore[method-assign]

    def clear(self) -> None:
        self.problems = []

    def take(self) -> list[Problem]:
        out, self.problems = self.problems, []
        return out


def failed_level_margins(
    native: Any, python: Any, native_qps: list[Problem], python_qps: list[Problem]
) -> tuple[str, dict[str, float]]:
    """The level named in the failed step's message, and by impl the feasibility margin of the
    QP that failed: the last QP of that name the failing impl built, and the same attempt (the
    same count of QPs of that name) in the other impl; an impl that built no such QP is left
    out."""
    failed = "native" if not native.ok else "python"
    message = native.message if failed == "native" else python.message
    names = re.findall(r"level '([^']+)'", message)
    level = names[-1] if names else ""
    qps = {"native": native_qps, "python": python_qps}
    attempt = sum(p.name == level for p in qps[failed])
    margins: dict[str, float] = {}
    for impl in ("native", "python"):
        mine = [p for p in qps[impl] if p.name == level]
        if attempt and len(mine) >= attempt:
            margins[impl] = feasibility_margin(mine[attempt - 1])
    return level, margins


def in_band(native: Any, margins: dict[str, float], solver: str) -> bool:
    """The failing impl's level QP lies inside :func:`feasibility_band`: feasible, or
    infeasible, by less than the band."""
    failed = "native" if not native.ok else "python"
    return failed in margins and abs(margins[failed]) < feasibility_band(solver)


def slacks(diagnostics: dict[str, float]) -> dict[str, float]:
    return {k: v for k, v in diagnostics.items() if k.startswith(("w.", "v.", "slack."))}


def base_residual(robot: Any, q: np.ndarray, v: np.ndarray, out: Any, frames: list[str]) -> float:
    """Relative residual of the floating-base rows of M q̈ + h = Sᵀ τ + J_cᵀ f."""
    state = RobotState(robot, q, v)
    full = state.M @ out.qdd + state.h - state.contact_jacobian(frames).T @ out.wrench
    return float(np.abs(full[:6]).max() / max(1.0, np.abs(state.h[:6]).max()))


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("solver", ANY_TIER_SOLVERS)
@pytest.mark.parametrize(
    "name,config,other",
    CONTROLLERS,
    ids=lambda x: x if isinstance(x, str) else "-".join(map(str, x.values())),
)
def test_native_equals_python(
    name: str, config: dict[str, Any], other: str, solver: str, case: str
) -> None:
    backend = solver.removeprefix("qpsolvers:")
    if case in SLOW.get((name, backend), set()):
        pytest.skip(f"{backend} runs for tens of seconds per state here in either impl")
    scenario, keyframe = CASES[case]
    pair = build_pair(name, scenario, solver, config)
    robot, loaded = pair["robot"], pair["loaded"]
    python, nat = pair["python"], pair["native"]
    exact = backend in ACTIVE_SET
    spread_ref = build_pair(name, scenario, solver, {**config, "strategy": other})["python"]
    frames = python.ctx.contact_frames
    q0, v0 = robot.keyframe(keyframe)
    for c in (python, nat, spread_ref):
        c.start(RobotState(robot, q0, v0))
    rng = np.random.default_rng(7)
    window = loaded.spec.metrics.window or (0.0, loaded.spec.duration)
    compared: list[float] = []
    spread, both_solved, spread_known = 0.0, 0, False
    for _ in range(4):
        q, v = grounded_state(robot, keyframe, frames, rng, q_noise=0.05, v_noise=0.2)
        t = float(rng.uniform(*window))
        a = nat.step(RobotState(robot, q, v), t)
        with QpRecorder() as recorder:
            b = python.step(RobotState(robot, q, v), t)
        assert {"dynamics", "build", "solve", "crossing", "total"} <= set(a.timings)
        if a.ok != b.ok:
            # one impl's backend gave up where the other's did not: its own verdict, on a
            # level whose feasible set is thinner than the band, and the answer the other impl
            # gave is still checked in full
            failed, answer = (a, b) if not a.ok else (b, a)
            assert BACKEND_VERDICT.search(failed.message), failed.message
            level, margins = failed_level_margins(a, b, nat.native_problems(), recorder.problems)
            if (name, backend) not in OUTSIDE_BAND and not QPOASES_INIT_FAILED.search(
                failed.message
            ):
                assert in_band(a, margins, solver), (failed.message, level, margins)
            assert base_residual(robot, q, v, answer, frames) <= 1e-6
            assert np.all(np.abs(answer.tau) <= nat.ctx.tau_max * (1 + 1e-6) + 1e-6)
            continue
        if not b.ok:
            continue
        # each answer is what it must be: the floating-base rows met, torques in limits
        for out in (a, b):
            assert base_residual(robot, q, v, out, frames) <= 1e-6
            assert np.all(np.abs(out.tau) <= nat.ctx.tau_max * (1 + 1e-6) + 1e-6)
        assert slacks(a.diagnostics).keys() == slacks(b.diagnostics).keys()
        if a.diagnostics["prox_retries"] or b.diagnostics["prox_retries"]:
            continue  # a regularised level: the impls solved different problems (docstring)
        both_solved += 1
        c = spread_ref.step(RobotState(robot, q, v), t)
        same = c.ok and not c.diagnostics["prox_retries"]
        for key, value in slacks(b.diagnostics).items():
            tol = (3e-6 if exact else 1e-3) * max(1.0, abs(value))
            if same and key in c.diagnostics:  # the optimum's sensitivity on this state
                tol = max(tol, 10 * abs(c.diagnostics[key] - value))
            assert abs(a.diagnostics[key] - value) <= tol, (key, a.diagnostics[key], value, tol)
        if exact:
            if same:
                spread_known = True
                spread = max(spread, relative(c.tau, b.tau), relative(c.qdd, b.qdd))
            pairs = zip((a.tau, a.qdd, a.wrench), (b.tau, b.qdd, b.wrench), strict=True)
            compared.append(max(relative(x, y) for x, y in pairs))
    if spread_known:  # (the other strategy may fail on every state with some backends)
        floor = 1e-5 if backend in REGULARISING else 1e-8
        for diff in compared:
            assert diff <= max(floor, 10 * spread), (diff, spread)
    if not both_solved:
        pytest.skip(
            f"{solver} solved none of the states in both impls: each answer an impl gave was "
            "checked, none compared"
        )


#: the backends whose level QPs a native tick solves from C++ (``solver_calls: native``)
NATIVE_CALLS = ["osqp", "qpoases"]


@pytest.mark.parametrize("mode", ["cold", "hot"])
@pytest.mark.parametrize("case", ["double", "wall"])
@pytest.mark.parametrize("solver", NATIVE_CALLS)
@pytest.mark.parametrize(
    "name,config,other",
    CONTROLLERS,
    ids=lambda x: x if isinstance(x, str) else "-".join(map(str, x.values())),
)
def test_native_solver_calls_equal_python_calls(
    name: str,
    config: dict[str, Any],
    other: str,
    solver: str,
    case: str,
    mode: str,
) -> None:
    """The native tick with its level QPs solved from C++ (``solver_calls: native``, the
    default; the comparisons above keep their problems, which sends every solve through Python)
    against the same tick calling the Python handles. OSQP runs the same code on both sides:
    the same bits. Cmeel's qpOASES differs from CasADi's at round-off (its BLAS loops against
    OpenBLAS), which changes some hot starts' working-set paths (iteration counts) and picks
    another optimum of the semidefinite level QPs (a level's x moves by up to 1e-5 at |x| ~ 4e3
    on these states): the slacks agree as between the two impls above, the C++ answer meets the
    floating-base rows and the torque limits, and τ, q̈, f agree to 10 times the strategies'
    spread or 1e-6 (measured: at most 1.2e-7 where the spread is smaller, 1.1e-4 where it is
    1.3e-3). Where one impl's backend fails a level that the other's solves (seen: the C++
    qpOASES's hot start on lqp's nullspace level p2 of one double-support state stopped on
    "Abnormal termination due to Cholesky factorisation" under OPENBLAS_CORETYPE=Prescott, whose
    rounding changes the random states, while CasADi's solved it), only that impl solves the
    level again with the proximal term, whose optimum is another (that slack 1.8e-3 against
    3e-10; quadprog, DAQP and CasADi's qpOASES find the same optimum of that regularised QP to
    a relative KKT residual of 1e-14): the answers then only meet the hard rows, and are not
    compared. At most one state of four may be such."""
    from wbcbench.controllers.registry import make_controller
    from wbcbench.robots.loader import load_robot
    from wbcbench.runs import scenario_context
    from wbcbench.scenarios.load import load_scenario

    scenario, keyframe = CASES[case]
    loaded = load_scenario(scenario)
    robot = load_robot(loaded.spec.robot)

    def controller(impl: str, calls: str, settings: dict[str, Any]) -> Any:
        ctx = scenario_context(loaded, robot, solver=solver, mode=mode)
        return make_controller(name, ctx, {**settings, "impl": impl, "solver_calls": calls})

    cpp, py = controller("native", "native", config), controller("native", "python", config)
    spread_ref = controller("python", "python", {**config, "strategy": other})
    assert cpp.impl == "native"
    q0, v0 = robot.keyframe(keyframe)
    for c in (cpp, py, spread_ref):
        c.start(RobotState(robot, q0, v0))
    rng = np.random.default_rng(7)
    window = loaded.spec.metrics.window or (0.0, loaded.spec.duration)
    same_code = solver == "osqp"
    compared: list[float] = []
    spread, mismatched, regularised, spread_known = 0.0, 0, 0, False
    for _ in range(4):
        q, v = grounded_state(robot, keyframe, cpp.ctx.contact_frames, rng, 0.05, 0.2)
        t = float(rng.uniform(*window))
        a = cpp.step(RobotState(robot, q, v), t)
        assert cpp.native_solve.natives.records()  # the level QPs were solved in C++
        b = py.step(RobotState(robot, q, v), t)
        if same_code:
            assert (a.ok, a.message) == (b.ok, b.message)
            if a.ok:
                for x, y in zip((a.tau, a.qdd, a.wrench), (b.tau, b.qdd, b.wrench), strict=True):
                    np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)
            continue
        if a.ok != b.ok:
            mismatched += 1
            assert mismatched <= 2, (a.message, b.message)
            continue
        if not b.ok:
            continue
        assert base_residual(robot, q, v, a, cpp.ctx.contact_frames) <= 1e-6
        assert np.all(np.abs(a.tau) <= cpp.ctx.tau_max * (1 + 1e-6) + 1e-6)
        if a.diagnostics["prox_retries"] != b.diagnostics["prox_retries"]:
            # one impl's backend failed a level the other's solved, so only that impl solved
            # it again with the proximal term: the impls solved different problems
            regularised += 1
            continue
        c = spread_ref.step(RobotState(robot, q, v), t)
        for key, value in slacks(b.diagnostics).items():
            # as between the two impls above: 3e-6, or 10 times the two Python strategies'
            # difference on this state (the optimum's sensitivity to the held slacks)
            tol = 3e-6 * max(1.0, abs(value))
            if c.ok and key in c.diagnostics:
                tol = max(tol, 10 * abs(c.diagnostics[key] - value))
            assert abs(a.diagnostics[key] - value) <= tol, (key, a.diagnostics[key], value, tol)
        if c.ok:
            spread_known = True
            spread = max(spread, relative(c.tau, b.tau), relative(c.qdd, b.qdd))
        pairs = zip((a.tau, a.qdd, a.wrench), (b.tau, b.qdd, b.wrench), strict=True)
        compared.append(max(relative(x, y) for x, y in pairs))
    assert regularised <= 1, regularised
    if spread_known:
        for diff in compared:
            assert diff <= max(1e-6, 10 * spread), (diff, spread)


def test_rqr_has_no_native_tick() -> None:
    from wbcbench.controllers.registry import make_controller
    from wbcbench.errors import ControllerError
    from wbcbench.robots.loader import load_robot
    from wbcbench.runs import scenario_context
    from wbcbench.scenarios.load import load_scenario

    loaded = load_scenario("tocabi_stand_sway")
    ctx = scenario_context(loaded, load_robot(loaded.spec.robot), solver="daqp")
    assert make_controller("hqp", ctx, {"strategy": "rqr"}).impl == "python"
    assert make_controller("hqp", ctx, {"strategy": "cascade"}).impl == "native"
    with pytest.raises(ControllerError) as err:
        make_controller("hqp", ctx, {"strategy": "rqr", "impl": "native"})
    assert str(err.value) == (
        "hqp: strategy rqr has no native tick; valid choices with impl: native: cascade, "
        "nullspace, weighted (or impl: python)"
    )
