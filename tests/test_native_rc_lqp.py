"""The native reduced-centroidal LQP (``rc_lqp``, impl: native) equals the Python reference.

On perturbed states with the soles on the ground (``grounded_state``) at random times in each
scenario's metrics window: double and single support (``ahn_double_support``,
``ahn_single_support``), ``tocabi_stand_sway`` (where the chains often cannot meet eq. 30 and
the step re-plans and falls back to the full-model LQP), and two robots of the TOCABI-like DoF
family (``ahn_dof_scaling``); for every installed backend, then for the option variants.

As in :mod:`tests.test_native_hierarchy` (whose docstring explains why): both LQPs are
hierarchies whose map from data to optimum is badly conditioned, so on each state both impls
solve

* every level's optimal slack norms agree (LQP 1's and LQP 2's of the plan, as the step reports
  them), to 3e-6 relative with an active-set backend and 1e-3 with an iterative one, the
  diagnostics keys are the same, and so are the timing stages where both took the same branch,
  but for the levels a QP may be solved through on one side only (:func:`check_stages`);
* the native answer is what the step promises: eq. (30) met (unless the full-model LQP solved
  the tick), the floating-base rows met (exact assembly) and the torques within their limits;
* with an active-set backend, the re-plan and fallback decisions agree, and τ, q̈ and f agree to
  10 times the spread the Python reference's two sequential strategies (null-space and cascade)
  show on the same states (at least 1e-5: a re-planned tick solves three more degenerate QPs),
  where both took the same branch (the full-model LQP inherits lqp's own spread, up to 1e-3 on
  tocabi_stand_sway).

A backend may fail on a state in one impl and not the other, on a level QP whose feasibility
margin lies in the band of :mod:`tests.test_native_hierarchy` (rounding-level differences of
the data meet its stopping rule differently on a level feasible only by the hierarchy's
widening; asserted for every such state). It may also return a level solution that breaks
the wrench inequalities or the q̈ limits without saying so (:func:`within_limits`), or one
that the step's wrench check rejects in one impl only (a re-plan there): at most two of the
four states.

With ``coupling_priority``, LQP 1's re-solve is nearly degenerate and its optimum not unique:
each impl's answer is checked for what the step promises, the slacks and τ not against the
other's.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.controllers.native import priority_groups
from wbcbench.controllers.registry import make_controller
from wbcbench.dynamics.state import RobotState
from wbcbench.qp import available_solvers
from wbcbench.robots.loader import load_robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import load_scenario

from .conftest import ANY_TIER_SOLVERS, grounded_state
from .test_native_equality import relative
from .test_native_hierarchy import (
    ACTIVE_SET,
    QpRecorder,
    base_residual,
    failed_level_margins,
    in_band,
    slacks,
)

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

#: the controller whose impls these tests compare
CONTROLLER = "rc_lqp"
#: case → (scenario, overrides)
CASES: dict[str, tuple[str, tuple[str, ...]]] = {
    "double": ("ahn_double_support", ()),
    "single": ("ahn_single_support", ()),
    "sway": ("tocabi_stand_sway", ()),
    "dof20": ("ahn_dof_scaling", ("robot=tocabi_dof20",)),
    "dof45": ("ahn_dof_scaling", ("robot=tocabi_dof45",)),
}
#: the option variants (on top of the defaults: nullspace, priority preview, exact assembly,
#: whole-robot LQP 2 energy, replan), each with the strategy that measures the spread
VARIANTS: list[dict[str, Any]] = [
    {"centroid_preview": "energy"},
    {"centroid_preview": "off"},
    {"assembly": "paper"},
    {"assembly": "exact", "diagnostics": True},
    {"coupling_priority": True},
    {"lqp2_energy": "chain"},
    {"infeasible_coupling": "fail"},
    {"strategy": "cascade"},
]
#: the backends the variants run on: the active-set ones and an interior-point one
VARIANT_SOLVERS = ["quadprog", "daqp", "qpoases", "clarabel"]
#: how far beyond the Python strategies' spread the native answer may lie: qpOASES stops on its
#: own termination tolerance (≈ 1e-9 relative) rather than at round-off, which on
#: tocabi_stand_sway moved τ up to 29 times the spread; eiquadprog stops once the summed
#: infeasibility is below n_in·ε·tr(H)·tr(L⁻ᵀ)·100 (its condition estimate), which there moved
#: τ up to 16 times the spread
SPREAD_FACTOR = {"qpoases": 100.0, "eiquadprog": 100.0}
#: on a state whose step falls back to the full-model LQP, the answers are held to that LQP's
#: per-level slacks, not to τ. DAQP is called from C++ through the module's own build of its C
#: sources and from Python through the wheel's build of them, which round differently; on the
#: single-support state that falls back, under OPENBLAS_CORETYPE=Prescott (which changes the
#: random states), the C++-called DAQP's last fallback level came out 6.2e-5 (relative) above
#: the Python reference's, whose two strategies agree to 2e-7, while every level above agrees
#: to 3e-6 (τ then moved 3e-2 relative): that level may lie this far above its optimum with
#: DAQP (an open defect, docs/native.md)
DAQP_FALLBACK_LAST = 1e-4
#: the step's timing stages every tick reports, in both impls
STAGES = {"dynamics", "build", "solve", "total", "reduced", "lqp1", "lqp2", "fallback"}
#: the levels a sequential LQP holds hard inside the next level's QP (``hard_if_feasible``: LQP
#: 1's and the full-model LQP's contacts, LQP 2's eq. 30 or its limits) and solves on their own
#: only when that QP is infeasible or its solver fails on it. Both paths lead to the same level
#: optima, and which one a step takes is the solver's outcome on that QP: an iterative backend's
#: can differ between the impls on data equal to round-off (measured: ProxQP on the re-planned
#: LQP 1 of ahn_double_support solved the pair in 1 467 iterations in one impl and stopped at its
#: 10 000-iteration cap in the other; on bit-identical data, ProxQP 0.8's AVX-512 build itself
#: takes 3 223 or 3 224 iterations depending on what the process allocated before)
HELD = {"lqp1.contacts", "lqp2.coupling", "lqp2.limits", "fallback.contacts"}
STATES = 4


def controllers(case: str, solver: str, config: dict[str, Any]) -> dict[str, Any]:
    """Python and native rc_lqp, and the Python one with the other sequential strategy."""
    scenario, overrides = CASES[case]
    loaded = load_scenario(scenario, overrides)
    robot = load_robot(loaded.spec.robot)
    other = "nullspace" if config.get("strategy") == "cascade" else "cascade"
    out: dict[str, Any] = {"robot": robot, "loaded": loaded}
    for key, impl, extra in (
        ("python", "python", {}),
        ("native", "native", {}),
        ("spread", "python", {"strategy": other}),
    ):
        ctx = scenario_context(loaded, robot, solver=solver, tier="high", keep_problems=True)
        out[key] = make_controller(CONTROLLER, ctx, {**config, **extra, "impl": impl})
    return out


def branch(out: Any) -> tuple[float, float]:
    return out.diagnostics["replan"], out.diagnostics["fallback"]


def close(a: float, b: float, tol: float) -> bool:
    """Equal within tol (relative to max(1, |b|)), or both NaN (a key the step had no value
    for, e.g. coupling_priority's re-solve slacks when it did not run)."""
    if np.isnan(a) or np.isnan(b):
        return bool(np.isnan(a) and np.isnan(b))
    return abs(a - b) <= tol * max(1.0, abs(b))


def slack_spread(c: Any, b: Any) -> float:
    """Largest relative difference of the slack norms two answers report."""
    out = 0.0
    for key, value in slacks(b.diagnostics).items():
        other = c.diagnostics.get(key, np.nan)
        if np.isfinite(value) and np.isfinite(other):
            out = max(out, abs(other - value) / max(1.0, abs(value)))
    return out


def within_limits(ctrl: Any, out: Any) -> bool:
    """The answer's wrench within its inequalities and q̈ within its limits (relative 1e-6):
    what the level QPs hold. A backend may return a level's QP solution that breaks them
    without reporting a failure (measured: quadprog and DAQP on LQP 1's nearly degenerate QPs
    with ``coupling_priority`` on tocabi_stand_sway, in either impl); the step checks the
    wrench only to ``wrench_tol`` (1e-3), so such an answer is counted as that impl's failure."""
    Cf = ctrl.Cw @ out.wrench
    lo, hi = ctrl.lw, ctrl.uw
    fl, fh = np.isfinite(lo), np.isfinite(hi)
    below = (lo[fl] - Cf[fl]) / (1 + np.abs(lo[fl]))
    above = (Cf[fh] - hi[fh]) / (1 + np.abs(hi[fh]))
    qdd = np.abs(out.qdd[6:]) - ctrl.config.qdd_limit * (1 + 1e-6)
    worst = max(below.max(initial=0.0), above.max(initial=0.0), qdd.max(initial=0.0))
    return bool(worst <= 1e-6)


def level_keys(out: Any) -> set[str]:
    """The names of the level QPs a step solved, from its per-level timings
    (``solve.<lqp>.<level>``; ``solve.lqp1`` and the like are the sums)."""
    return {key[6:] for key in out.timings if key.startswith("solve.") and key.count(".") >= 2}


def check_stages(a: Any, b: Any) -> None:
    """The native step ``a`` reports every timing stage of the Python step ``b`` (and more:
    ``crossing``), and the same level QPs but for a :data:`HELD` level one of them solved on
    its own."""
    levels_a, levels_b = level_keys(a), level_keys(b)
    stages_a = set(a.timings) - {f"solve.{name}" for name in levels_a}
    stages_b = set(b.timings) - {f"solve.{name}" for name in levels_b}
    assert stages_b <= stages_a, stages_b - stages_a
    assert levels_a ^ levels_b <= HELD, (levels_a - levels_b, levels_b - levels_a)


def fallback_levels(ctrl: Any, robot: Any, q: Any, v: Any, t: float, out: Any) -> list[float]:
    """The norm of each level's slack (w, v) that an answer of the full-model LQP leaves, on
    the Python reference's levels of that state: what the fallback's hierarchy fixes."""
    state = RobotState(robot, q, v)
    _, levels, _, _, _ = ctrl.full.hierarchy(state, ctrl.evaluate_tasks(state, t))
    x = np.concatenate([out.qdd, out.wrench])
    norms = []
    for lv in levels:
        w = lv.A @ x - lv.b
        if lv.C is not None and lv.C.shape[0]:
            cx = lv.C @ x
            w = np.concatenate([w, cx - np.clip(cx, lv.l, lv.u)])
        norms.append(float(np.linalg.norm(w)))
    return norms


def check_case(case: str, solver: str, config: dict[str, Any]) -> None:
    backend = solver.removeprefix("qpsolvers:")
    # coupling_priority's re-solve of LQP 1 is nearly degenerate: its optimum is not unique, and
    # which one a backend lands on moves with round-off (measured: slacks 5e-3 apart with DAQP,
    # τ 3e-3 apart with quadprog, depending on what the process ran before); there each impl's
    # answer is checked for what the step promises, not against the other's
    degenerate = bool(config.get("coupling_priority"))
    exact = backend in ACTIVE_SET and not degenerate
    pair = controllers(case, solver, config)
    robot, loaded = pair["robot"], pair["loaded"]
    python, nat, spread_ref = pair["python"], pair["native"], pair["spread"]
    frames = python.ctx.contact_frames
    keyframe = loaded.spec.initial.keyframe
    q0, v0 = robot.keyframe(keyframe)
    for c in (python, nat, spread_ref):
        c.start(RobotState(robot, q0, v0))
    assert nat.impl == "native" and python.impl == "python"
    rng = np.random.default_rng(7)
    window = loaded.spec.metrics.window or (0.0, loaded.spec.duration)
    paper = config.get("assembly") == "paper"
    tol_cpl = python.config.coupling_tol
    # per branch (re-planned, fell back): the Python strategies' spread of τ and q̈, and the
    # native answers' differences; the slacks' differences and spread over every branch
    spread: dict[tuple[float, float], float] = {}
    compared: list[tuple[tuple[float, float], float]] = []
    slack_diffs: list[tuple[str, float]] = []
    spread_slacks, mismatched, both_failed, fell_back = 0.0, 0, 0, 0
    budget_hits = 0
    for _ in range(STATES):
        q, v = grounded_state(robot, keyframe, frames, rng, q_noise=0.05, v_noise=0.2)
        t = float(rng.uniform(*window))
        a = nat.step(RobotState(robot, q, v), t)
        with QpRecorder() as recorder:
            b = python.step(RobotState(robot, q, v), t)
        assert {"dynamics", "build", "solve", "crossing", "total"} <= set(a.timings)
        if a.ok != b.ok:
            failed = a if not a.ok else b
            budget = ("max_iter", "inaccurate", "qpsolvers: no solution found")
            if backend not in ACTIVE_SET and any(word in failed.message for word in budget):
                # an iterative backend's budget, not a verdict on the QP: on data equal to
                # rounding one impl converges just inside its iterations or accuracy and the
                # other does not (measured with OSQP in double support, native solved: the
                # Python impl at max_iter on LQP 1's preview, or "solved inaccurate" on LQP 2's
                # p2, on 1 or 2 of the 4 states depending on what the process ran before;
                # qpsolvers names either outcome "no solution found")
                budget_hits += 1
                continue
            # a backend's verdict on a level QP whose feasible set is thinner than the band
            # (see tests.test_native_hierarchy)
            level, margins = failed_level_margins(a, b, nat.native_problems(), recorder.problems)
            assert in_band(a, margins, solver), (a.message, b.message, level, margins)
            continue
        if not b.ok:
            assert a.message and b.message
            both_failed += 1
            continue
        valid_a, valid_b = within_limits(nat, a), within_limits(python, b)
        if valid_a != valid_b:
            mismatched += 1
            assert mismatched <= 2, "a backend's wrong level solution in one impl"
        if not (valid_a and valid_b):
            continue
        assert a.diagnostics.keys() == b.diagnostics.keys()
        assert STAGES <= set(a.timings)
        if branch(a) == branch(b):  # (a level solution one impl's check rejected: a re-plan)
            check_stages(a, b)
        for key, value in slacks(b.diagnostics).items():
            if degenerate:
                break
            other = a.diagnostics[key]
            assert np.isnan(other) == np.isnan(value), key
            if not np.isnan(value):
                slack_diffs.append((key, abs(other - value) / max(1.0, abs(value))))
        # the native answer is what the step promises
        if not a.diagnostics["fallback"]:
            assert a.diagnostics["coupling_residual"] <= tol_cpl
        if not paper or a.diagnostics["fallback"]:
            assert base_residual(robot, q, v, a, frames) <= 1e-6
        assert np.all(np.abs(a.tau) <= nat.ctx.tau_max * (1 + 1e-6) + 1e-6)
        if exact and branch(a) != branch(b):
            # one impl's level solution failed the step's wrench check and re-planned: a nearly
            # degenerate level QP (coupling_priority's re-solve) the backend solved to a
            # different optimum in each impl
            mismatched += 1
            assert mismatched <= 2, (branch(a), branch(b))
            continue
        if exact and branch(a)[1] and branch(b)[1]:
            # both fell back to the full-model LQP: its levels' optima agree; its τ is not held
            # to the strategies' spread (measured under OPENBLAS_CORETYPE=Prescott: τ 3e-2 apart
            # with the C++-built DAQP where the two Python strategies differ by 1e-4, while
            # every level's slack agrees; the last level's optimum is ill-conditioned there)
            c = spread_ref.step(RobotState(robot, q, v), t)
            ref = fallback_levels(python, robot, q, v, t, b)
            got = fallback_levels(python, robot, q, v, t, a)
            other = (
                fallback_levels(python, robot, q, v, t, c)
                if c.ok and branch(c)[1] and within_limits(spread_ref, c)
                else ref
            )
            for i, (x, y, z) in enumerate(zip(got, ref, other, strict=True)):
                tol = 3e-6 * max(1.0, abs(y)) + 10 * abs(z - y)
                if backend == "daqp" and i == len(got) - 1:
                    tol = max(tol, DAQP_FALLBACK_LAST * max(1.0, abs(y)))
                assert abs(x - y) <= tol, (got, ref, other)
            fell_back += 1
            continue
        if exact:
            c = spread_ref.step(RobotState(robot, q, v), t)
            c_ok = c.ok and within_limits(spread_ref, c)
            if c_ok:
                spread_slacks = max(spread_slacks, slack_spread(c, b))
            if c_ok and branch(c) == branch(b):
                diff = max(relative(c.tau, b.tau), relative(c.qdd, b.qdd))
                spread[branch(b)] = max(spread.get(branch(b), 0.0), diff)
            pairs = zip((a.tau, a.qdd, a.wrench), (b.tau, b.qdd, b.wrench), strict=True)
            compared.append((branch(b), max(relative(x, y) for x, y in pairs)))
    assert budget_hits < STATES, "every state ended on an iterative backend's budget"
    if backend == "quadprog" and exact:  # the reference backend: agreement on nearly every state
        assert len(compared) + fell_back + both_failed >= STATES - 1, (len(compared), both_failed)
    tol = max(3e-6, 10 * spread_slacks) if exact else 1e-3
    for key, diff in slack_diffs:
        assert diff <= tol, (key, diff, tol)
    factor = SPREAD_FACTOR.get(backend, 10.0)
    for where, diff in compared:
        if where in spread:  # (the other strategy may fail or branch otherwise)
            assert diff <= max(1e-5, factor * spread[where]), (where, diff, spread[where])


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("solver", ANY_TIER_SOLVERS)
def test_native_equals_python(solver: str, case: str) -> None:
    check_case(case, solver, {})


@pytest.mark.parametrize("case", ["double", "sway"])
@pytest.mark.parametrize("solver", [s for s in VARIANT_SOLVERS if s in available_solvers()])
@pytest.mark.parametrize(
    "config", VARIANTS, ids=lambda c: "-".join(f"{k}={v}" for k, v in c.items())
)
def test_native_equals_python_in_every_variant(
    config: dict[str, Any], solver: str, case: str
) -> None:
    check_case(case, solver, config)


def test_native_row_split_and_preview_equal_python() -> None:
    """The structural row split (decided on the first tick) and the preview d = D q̈_p + d0
    (damped least squares by SVD, priority after priority) equal the reference's."""
    pair = controllers("sway", "quadprog", {})
    robot = pair["robot"]
    python, nat = pair["python"], pair["native"]
    q, v = grounded_state(robot, "stand", python.ctx.contact_frames, np.random.default_rng(3))
    for c in (python, nat):
        c.start(RobotState(robot, q, v))
        c.step(RobotState(robot, q, v), 2.0)
    tick, rows, tasks = nat.native_tick, python._rows, python.ctx.tasks
    assert tick.chain_priority == rows.chain_priority
    offsets = np.cumsum([0] + [t.dim for t in tasks])
    _, groups = priority_groups(tasks)
    for group, split1, split2 in zip(groups, tick.lqp1_rows, tick.lqp2_rows, strict=True):
        assert list(split1) == [offsets[i] + r for i in group for r in rows.lqp1[tasks[i].name]]
        assert list(split2) == [offsets[i] + r for i in group for r in rows.lqp2[tasks[i].name]]
    state = RobotState(robot, q, v)
    red = python.reduced.compute(state, fixed_base=False)
    preview = python.preview(state, red, python.evaluate_tasks(state, 2.0))
    assert relative(np.asarray(tick.preview_D), preview.D) <= 1e-9
    assert relative(np.asarray(tick.preview_d0), preview.d0) <= 1e-9
