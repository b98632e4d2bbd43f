"""impl: native equals impl: python on the same states, for every installed backend.

Same state, same solver, tier and mode:

* every QP the native tick builds equals the Python one entry by entry, to 1e-12 relative to the
  matrix's size (measured: 2e-16, the rounding of a different summation order), OSF-HQP's once
  its wrench-distribution coordinates are in the same basis (:func:`in_basis_of`);
* τ, q̈ and the contact wrenches agree to 1e-8 relative (to max(1, |python|)), or to the tier's
  tolerance where the solver is iterative, widened where the QP itself cannot do better: a change
  δ of its data or of the solver's residuals moves the solution by up to κ δ, κ the condition
  number of the Hessian reduced to the equality constraints' null space (1e7 to 3e9 on these
  states, from the task weights' spread of 1e3 to 1e-7). δ is the rounding (100 ε) for every
  solver, plus the tier's residual tolerance (1e-9) for the iterative ones, which stop on it;
  TO-OSF's τ is a linear map of its QP's solution, which amplifies that by its gain
  (:func:`torque_gain`: 400 to 2400 on these states);
* an iterative solver may stop short on one impl's QP and not on the other's when they differ by
  rounding: such a state is checked up to the QPs both built and then skipped; at most half of
  the states may be, any number with first-order OSQP, which at tier high (1e-9) often stops
  short on OSF-HQP's level QPs.

The states are perturbed keyframes with the contacts put back in place (``grounded_state``), in
double support, single support, with a hand on a wall and with a force-level task (OSF-HQP's
Table I), at random times within the scenario.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import scipy.linalg as sla

from wbcbench import _native
from wbcbench.controllers.base import Controller
from wbcbench.controllers.registry import make_controller
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.qp import Problem, available_solvers
from wbcbench.qp.settings import TIER_EPS as TIERS_EPS
from wbcbench.robots.loader import load_robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import load_scenario

from .conftest import ANY_TIER_SOLVERS, grounded_state

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

#: scenario, keyframe: double support, single support, a hand on a wall
CASES = {
    "double": ("tocabi_stand_sway", "stand"),
    "single": ("ahn_single_support", "stand"),
    "wall": ("lee2021access_s4_cost", "stand_wall"),
    "force_level": ("lee2021iros_table1", "stand_arms_bent"),
}

#: the native controllers and the settings each is compared in
CONTROLLERS: dict[str, list[dict[str, Any]]] = {
    "qp_wbc": [{"variables": "full"}, {"variables": "eliminated"}],
    "to_osf": [
        {"inverse": "cod"},
        {"inverse": "svd", "coupling": "literal", "params": "periodic:2"},
        {"inverse": "pinv", "wrench_cost": "internal"},
        {"inverse": "cod", "internal": "constraint"},
    ],
    "osf_hqp": [{"inverse": "cod"}, {"inverse": "svd", "params": "periodic:2"}],
}

#: how closely the QPs' data agree: the weighted QP is assembled from the dynamics alone
#: (measured 2e-16); the OSF controllers' data pass through Λ_c, Ȳ and each level's Λ, whose
#: rounding grows with their condition (measured up to 6e-11)
DATA_TOLERANCE = {"qp_wbc": 1e-12, "to_osf": 1e-9, "osf_hqp": 1e-9}

#: iterative backends stop on residuals (1e-9 at tier high), which bounds x only through the
#: conditioning: the relative agreement they reach on these states, with a margin (interior-point
#: Clarabel and PIQP up to 9e-6; ProxQP up to 6e-5 on the wall states, varying from run to run
#: with the 2e-16 differences of the data; HiGHS up to 2e-5 on TO-OSF's QP, whose solution it
#: returns 1e-6 off the exact one, amplified by the map to τ; first-order OSQP more)
#: the residual tolerance the iterative backends stop on at tier high
TIER_EPS = TIERS_EPS["high"]
ITERATIVE = {"osqp": 1e-4, "clarabel": 3e-5, "piqp": 3e-5, "proxqp": 2e-4, "highs": 3e-5}
#: HiGHS on TO-OSF's QP: it stops on its objective, and on the wall states that objective is
#: flat along directions that move τ (measured with ``internal: basis``: the two impls' answers
#: 2.5e-3 apart in τ, 0.15 with the pseudo-inverse ablation, while Python's answer is 1.1e-5 from
#: the exact optimum in τ and 2e-13 in the objective; with ``internal: constraint`` it fails on
#: those states in both impls, "Solve error"). Its τ are not compared: its QPs' data and its
#: verdicts still are.
HIGHS_TO_OSF = np.inf


def build_pair(
    name: str,
    scenario: str,
    solver: str,
    config: dict[str, Any],
    tier: str = "high",
    mode: str = "cold",
) -> dict[str, Any]:
    loaded = load_scenario(scenario)
    robot = load_robot(loaded.spec.robot)
    out: dict[str, Any] = {"robot": robot, "loaded": loaded}
    for impl in ("python", "native"):
        ctx = scenario_context(
            loaded, robot, solver=solver, tier=tier, mode=mode, keep_problems=True
        )
        out[impl] = make_controller(name, ctx, {**config, "impl": impl})
    return out


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b), initial=0.0) / max(1.0, float(np.abs(b).max(initial=0))))


def reduced_condition(problem: Problem) -> float:
    """Condition number of the Hessian on the null space of the equality constraints."""
    Z = sla.null_space(problem.A) if problem.n_eq else np.eye(problem.n)
    return float(np.linalg.cond(Z.T @ problem.H @ Z))


def torque_gain(problem: Problem, tau: np.ndarray) -> float:
    """How much TO-OSF's map from its QP's solution to τ amplifies a relative difference of the
    solution: τ = γ₀ + C_τ x, C_τ the QP's first k inequality rows (the torque limits), so
    ‖Δτ‖∞ / max(1, ‖τ‖∞) ≤ ‖C_τ‖∞ max(1, ‖x‖∞) / max(1, ‖τ‖∞) × the relative ‖Δx‖∞ (x from an
    exact active-set solve of the same QP; measured up to about 400 with the pseudo-inverse of the
    ablation on the wall states)."""
    from wbcbench.qp import make_solver

    assert problem.C is not None
    sol = make_solver("quadprog", tier="high").solve(problem)
    if not sol.success or sol.x is None:
        return 1.0
    rows = problem.C[: tau.size]
    scale = float(np.abs(rows).sum(axis=1).max()) * max(1.0, float(np.abs(sol.x).max()))
    return max(1.0, scale / max(1.0, float(np.abs(tau).max())))


def in_basis_of(python: Problem, native: Problem) -> Problem:
    """The Python QP with its wrench-distribution variables expressed in the native QP's basis.

    OSF-HQP's variables F_r are coordinates in an orthonormal basis Q_f of the internal wrenches,
    which is unique only up to a rotation V (either pivoted QR may order tied columns its own
    way); every torque, wrench and bound is the same in any basis. The level QPs' last p columns
    and the wrench QP's columns are those coordinates: V is recovered from C (C_native = C V),
    checked orthogonal, and applied to H, g and C. Other QPs are returned unchanged.
    """
    if not (python.name.startswith("T") or python.name == "wrench") or python.C is None:
        return python
    # the F_r columns: those of the wrench QP, the last n − m of a level (its H is 1 on w)
    p = python.n if python.name == "wrench" else int(np.count_nonzero(np.diag(python.H) != 1.0))
    if p == 0:
        return python
    cols = slice(python.n - p, python.n)
    V, *_ = np.linalg.lstsq(python.C[:, cols], native.C[:, cols], rcond=None)
    np.testing.assert_allclose(V.T @ V, np.eye(p), atol=1e-8)
    T = np.eye(python.n)
    T[cols, cols] = V
    return Problem(
        T.T @ python.H @ T,
        T.T @ python.g,
        python.A @ T,
        python.b,
        python.C @ T,
        python.l,
        python.u,
        python.lb,
        python.ub,
        name=python.name,
    )


def compare(
    pair: dict[str, Any],
    keyframe: str,
    n_states: int,
    seed: int,
    tolerance: float,
    data_tolerance: float = 1e-12,
    iterative: bool = False,
    max_skipped: int = 0,
    torque_rows: bool = False,
) -> float:
    """The worst ratio of the τ, q̈ and wrench differences to their bound, over the states."""
    skipped = 0
    robot, loaded = pair["robot"], pair["loaded"]
    python: Controller = pair["python"]
    native: Controller = pair["native"]
    assert (python.impl, native.impl) == ("python", "native")
    frames = python.ctx.contact_frames
    q0, v0 = robot.keyframe(keyframe)
    for c in (python, native):
        c.start(RobotState(robot, q0, v0))
    rng = np.random.default_rng(seed)
    window = loaded.spec.metrics.window or (0.0, loaded.spec.duration)
    worst = 0.0
    for _ in range(n_states):
        q, v = grounded_state(robot, keyframe, frames, rng, q_noise=0.05, v_noise=0.2)
        t = float(rng.uniform(*window))
        a = native.step(RobotState(robot, q, v), t)
        b = python.step(RobotState(robot, q, v), t)
        # every QP both impls built: the first always, the later ones of a cascade as far as
        # both got (an iterative backend may stop short on one impl's QP and not the other's)
        assert a.problems and b.problems
        kappa = 1.0
        for i, (pa, pb) in enumerate(zip(a.problems, b.problems, strict=False)):
            pb = in_basis_of(pb, pa)
            # a cascade's later QPs carry the levels above's solution in g, l and u: they agree
            # only as well as that solution does
            carried = ("g", "l", "u") if i else ()
            for f in ("H", "g", "A", "b", "C", "l", "u", "lb", "ub"):
                x, y = getattr(pa, f), getattr(pb, f)
                if y is None:
                    assert x is None, f
                    continue
                finite = np.isfinite(y)
                assert np.array_equal(finite, np.isfinite(x)), f
                limit = max(data_tolerance, tolerance) if f in carried else data_tolerance
                assert relative(x[finite], y[finite]) <= limit, (pb.name, f)
            kappa = max(kappa, reduced_condition(pb))
        if a.ok != b.ok and iterative:
            skipped += 1
            assert skipped <= max_skipped, (a.message, b.message)
            continue
        assert a.ok == b.ok, (a.message, b.message)
        if not b.ok:
            continue
        assert len(a.problems) == len(b.problems)
        delta = 100 * np.finfo(float).eps + (TIER_EPS if iterative else 0.0)
        gain = torque_gain(b.problems[0], b.tau) if iterative and torque_rows else 1.0
        bound = max(tolerance, kappa * delta * gain)
        for x, y in ((a.tau, b.tau), (a.qdd, b.qdd), (a.wrench, b.wrench)):
            worst = max(worst, relative(x, y) / bound)
        for ta, tb in zip(a.terms, b.terms, strict=True):
            assert ta.task.name == tb.task.name
            np.testing.assert_allclose(ta.error, tb.error, rtol=0, atol=1e-12)
            np.testing.assert_allclose(ta.error_vel, tb.error_vel, rtol=0, atol=1e-10)
            np.testing.assert_allclose(ta.acc_ref, tb.acc_ref, rtol=1e-10, atol=1e-9)
            np.testing.assert_allclose(ta.J, tb.J, rtol=0, atol=1e-12)
        assert {"dynamics", "build", "solve", "crossing", "total"} <= set(a.timings)
    return worst


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("solver", ANY_TIER_SOLVERS)
@pytest.mark.parametrize(
    "name,config",
    [(name, cfg) for name, cfgs in CONTROLLERS.items() for cfg in cfgs],
    ids=lambda x: x if isinstance(x, str) else "-".join(map(str, x.values())),
)
def test_native_equals_python(name: str, config: dict[str, Any], solver: str, case: str) -> None:
    if case == "wall" and name == "osf_hqp" and solver.endswith("proxqp"):
        pytest.skip(
            "ProxQP runs for seconds to minutes on some of these level QPs, in either impl "
            "(its API has no time cap)"
        )
    if case == "force_level" and name == "qp_wbc":
        pytest.skip("the weighted QP has no force-level form (it tracks such a task as a motion)")
    scenario, keyframe = CASES[case]
    pair = build_pair(name, scenario, solver, config)
    tolerance = ITERATIVE.get(solver.removeprefix("qpsolvers:"), 1e-8)
    if name == "to_osf" and solver.removeprefix("qpsolvers:") == "highs":
        tolerance = HIGHS_TO_OSF
    worst = compare(
        pair,
        keyframe,
        n_states=4,
        seed=7,
        tolerance=tolerance,
        data_tolerance=DATA_TOLERANCE[name],
        iterative=solver.removeprefix("qpsolvers:") in ITERATIVE,
        max_skipped=4 if solver.removeprefix("qpsolvers:") == "osqp" else 2,
        torque_rows=name == "to_osf",
    )
    assert worst <= 1.0


@pytest.mark.skipif(
    "qpoases_libdwbc" not in available_solvers(), reason="qpoases_libdwbc not available"
)
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize(
    "name,config",
    [(name, cfg) for name, cfgs in CONTROLLERS.items() for cfg in cfgs],
    ids=lambda x: x if isinstance(x, str) else "-".join(map(str, x.values())),
)
def test_native_equals_python_qpoases_libdwbc(name: str, config: dict[str, Any], case: str) -> None:
    """The named setting at its own tier and mode (default, hot): one qpOASES object per QP
    kept from state to state on both impls, the same answers (an active-set method: exact up to
    the data's round-off)."""
    if case == "force_level" and name == "qp_wbc":
        pytest.skip("the weighted QP has no force-level form (it tracks such a task as a motion)")
    scenario, keyframe = CASES[case]
    pair = build_pair(name, scenario, "qpoases_libdwbc", config, tier="default", mode="hot")
    worst = compare(
        pair,
        keyframe,
        n_states=4,
        seed=7,
        tolerance=1e-8,
        data_tolerance=DATA_TOLERANCE[name],
        iterative=False,
        max_skipped=0,
        torque_rows=name == "to_osf",
    )
    assert worst <= 1.0


def test_impl_is_chosen_and_checked() -> None:
    loaded = load_scenario("tocabi_stand_sway")
    robot = load_robot(loaded.spec.robot)
    ctx = scenario_context(loaded, robot, solver="daqp")
    assert make_controller("qp_wbc", ctx).impl == "native"
    assert make_controller("rc_lqp", ctx).impl == "native"
    assert make_controller("kin_hqp", ctx).impl == "native"
    assert make_controller("kin_hqp", ctx, {"impl": "python"}).impl == "python"
    with pytest.raises(Exception, match="'native' or 'python'"):
        make_controller("kin_hqp", ctx, {"impl": "fast"})


def test_impl_default_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    loaded = load_scenario("tocabi_stand_sway")
    robot = load_robot(loaded.spec.robot)
    ctx = scenario_context(loaded, robot, solver="daqp")
    monkeypatch.setenv("WBCBENCH_IMPL", "python")
    assert make_controller("to_osf", ctx).impl == "python"
    assert make_controller("to_osf", ctx, {"impl": "native"}).impl == "native"
    assert make_controller("kin_hqp", ctx).impl == "python"
    monkeypatch.setenv("WBCBENCH_IMPL", "native")
    assert make_controller("kin_hqp", ctx).impl == "native"
    monkeypatch.setenv("WBCBENCH_IMPL", "fast")
    with pytest.raises(ControllerError) as err:
        make_controller("to_osf", ctx)
    assert str(err.value) == "WBCBENCH_IMPL='fast'; valid choices: native, python (or unset)"
