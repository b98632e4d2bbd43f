"""rc_lqp and lqp against the rigid-contact forward-dynamics oracle; lqp's sequential method
against the cascade of full QPs; short closed-loop runs of the Ahn scenarios (tracking of rc_lqp
against lqp, exact against paper torque assembly).

Tests that read the Python reference's intermediate results (its LQPs' solutions, its reduced
model) run it with impl: python; those that read only the step's output run every impl."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from tests.conftest import IMPLS
from wbcbench.controllers.base import Controller
from wbcbench.controllers.lqp import Lqp, LqpConfig
from wbcbench.controllers.rc_lqp import RcLqp, RcLqpConfig
from wbcbench.dynamics.state import RobotState
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.robots.loader import Robot
from wbcbench.runs import plan_run, scenario_context
from wbcbench.scenarios.load import load_scenario
from wbcbench.sim.closed_loop import run_closed_loop

SCENARIOS = ["ahn_double_support", "ahn_single_support"]
# the reference backend of both controllers (an active-set method: exact up to round-off)
SOLVER = "quadprog"


def make(cls: type[Controller], cfg: object, scenario: str, robot: Robot) -> Controller:
    ctx = scenario_context(load_scenario(scenario), robot, solver=SOLVER, tier="high")
    return cls(ctx, cfg)  # type: ignore[arg-type]


def perturbed_state(
    robot: Robot, keyframe: str, rng: np.random.Generator, noise: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """Keyframe + uniform joint offsets (±noise rad) and velocities (±2·noise)."""
    q, _ = robot.keyframe(keyframe)
    q = q.copy()
    q[7:] = np.clip(q[7:] + rng.uniform(-noise, noise, robot.k), robot.q_min, robot.q_max)
    return q, rng.uniform(-2 * noise, 2 * noise, robot.nv)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_rc_lqp_exact_assembly_against_the_oracle(tocabi: Robot, scenario: str) -> None:
    """100 random states, every one solved and checked (active limits included): the exact
    torque realises LQP 1's q̈_r (through J_r) and LQP 2's q̈_uc in the rigid-contact forward
    dynamics; contacts stay put; the predicted wrench is the realised one."""
    rng = np.random.default_rng(11)
    ctrl = make(RcLqp, RcLqpConfig(assembly="exact", impl="python"), scenario, tocabi)
    assert isinstance(ctrl, RcLqp)
    keyframe = load_scenario(scenario).spec.initial.keyframe
    worst = {"qdd_r": 0.0, "qdd_uc": 0.0, "contact": 0.0, "wrench_rel": 0.0}
    for _ in range(100):
        q, v = perturbed_state(tocabi, keyframe, rng, noise=0.02)
        ctrl.start(RobotState(tocabi, q, v))  # tasks start here: their references are smooth
        out = ctrl.step(RobotState(tocabi, q, v), t=0.0)
        assert out.ok, out.message
        state = RobotState(tocabi, q, v)
        oracle = forward_dynamics(state, out.tau, ctrl.frames)
        red = ctrl.last_reduced
        assert red is not None and ctrl.last is not None
        x1 = ctrl.last[0].x
        n_r = ctrl.split.n_reduced
        uc = ctrl.split.unconstrained
        realised_r = red.J_r @ oracle.qdd + red.dJr_v
        scale = max(1.0, float(np.linalg.norm(out.wrench)))
        worst["qdd_r"] = max(worst["qdd_r"], float(np.abs(realised_r - x1[:n_r]).max()))
        worst["qdd_uc"] = max(worst["qdd_uc"], float(np.abs(oracle.qdd[uc] - out.qdd[uc]).max()))
        worst["contact"] = max(worst["contact"], float(np.abs(oracle.contact_acc).max()))
        rel = float(np.linalg.norm(oracle.wrench - out.wrench)) / scale
        worst["wrench_rel"] = max(worst["wrench_rel"], rel)
    assert worst["qdd_r"] <= 1e-6, worst
    assert worst["qdd_uc"] <= 1e-6, worst
    assert worst["contact"] <= 1e-8, worst
    assert worst["wrench_rel"] <= 1e-6, worst


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_rc_lqp_paper_assembly_departs_only_in_the_chains(
    tocabi: Robot, scenario: str, impl: str
) -> None:
    """The paper's Γ_cc (eq. 14) equals the exact one; its Γ_uc (eq. 17) leaves out the base's
    acceleration, so the realised motion departs from the planned one."""
    rng = np.random.default_rng(12)
    cfg = RcLqpConfig(assembly="paper", impl=impl)  # type: ignore[arg-type]
    ctrl = make(RcLqp, cfg, scenario, tocabi)
    assert isinstance(ctrl, RcLqp)
    keyframe = load_scenario(scenario).spec.initial.keyframe
    departures = []
    for _ in range(20):
        q, v = perturbed_state(tocabi, keyframe, rng)
        ctrl.start(RobotState(tocabi, q, v))
        out = ctrl.step(RobotState(tocabi, q, v), t=0.0)
        assert out.ok, out.message
        state = RobotState(tocabi, q, v)
        Jc = state.contact_jacobian(ctrl.frames)
        tau_exact = state.M[6:] @ out.qdd + state.h[6:] - Jc[:, 6:].T @ out.wrench
        act_cc = ctrl.split.plain[6:] - 6
        act_uc = ctrl.split.unconstrained - 6
        assert np.abs(out.tau[act_cc] - tau_exact[act_cc]).max() <= 1e-8 * max(
            1.0, float(np.abs(tau_exact).max())
        )
        diff_uc = float(np.abs(out.tau[act_uc] - tau_exact[act_uc]).max())
        assert out.diagnostics["assembly_diff"] == pytest.approx(diff_uc, rel=1e-9, abs=1e-12)
        oracle = forward_dynamics(state, out.tau, ctrl.frames)
        departures.append(float(np.abs(oracle.qdd - out.qdd).max()))
    # the fixed-base chain torque is not the constrained robot's: the plan is not realised
    assert max(departures) > 1e-3, departures


@pytest.mark.parametrize("preview", ["off", "priority"])
def test_rc_lqp_lqp2_tasks_leave_lqp1_priorities_unchanged(tocabi: Robot, preview: str) -> None:
    """Strict hierarchy across the split: another hand reference changes q̈_uc but not LQP 1's
    priorities (contacts, CoM, pelvis); without the preview it leaves all of q̈_r unchanged."""
    rng = np.random.default_rng(13)
    cfg = RcLqpConfig(centroid_preview=preview, impl="python")  # type: ignore[arg-type]
    a = make(RcLqp, cfg, "ahn_double_support", tocabi)
    b = make(RcLqp, cfg, "ahn_double_support", tocabi)
    assert isinstance(a, RcLqp) and isinstance(b, RcLqp)
    q, v = perturbed_state(tocabi, "stand", rng)
    a.start(RobotState(tocabi, q, v))
    b.start(RobotState(tocabi, q, v))
    hand = next(t for t in b.ctx.tasks if t.name == "l_hand")
    hand.kp = 400.0  # a different hand acceleration request
    hand._x0 = hand._x0 + np.array([0.02, 0.0, 0.03, 0.0, 0.0, 0.0])  # type: ignore[operator]
    oa = a.step(RobotState(tocabi, q, v), 0.0)
    ob = b.step(RobotState(tocabi, q, v), 0.0)
    assert oa.ok and ob.ok
    assert a.last is not None and b.last is not None
    n_r = a.split.n_reduced
    xa, xb = a.last[0].x, b.last[0].x
    if preview == "off":
        assert np.abs(xa[:n_r] - xb[:n_r]).max() <= 1e-8
    else:
        assert np.abs(xa[a.centroid_rows] - xb[b.centroid_rows]).max() > 1e-4
    for la, lb in zip(a.last[0].levels, b.last[0].levels, strict=True):
        if la.name in ("lqp1.contacts", "lqp1.p1"):
            # each level's realised rows: A x = b + w
            assert np.abs(la.w - lb.w).max(initial=0.0) <= 1e-8, la.name
    state = RobotState(tocabi, q, v)
    for out in (oa, ob):
        com = next(t for t in out.terms if t.task.name == "com")
        assert np.abs(com.J @ out.qdd + com.drift - (com.J @ oa.qdd + com.drift)).max() <= 1e-8
    Jc = state.contact_jacobian(a.frames)
    assert np.abs(Jc @ (oa.qdd - ob.qdd)).max() <= 1e-8
    uc = a.split.unconstrained
    assert np.abs(oa.qdd[uc] - ob.qdd[uc]).max() > 1e-2


@pytest.mark.parametrize("impl", IMPLS)
def test_rc_lqp_coupling_priority_holds_eq30(tocabi: Robot, impl: str) -> None:
    """With the optional extra priority, the final LQP 2 still meets eq. (30)."""
    rng = np.random.default_rng(14)
    cfg = RcLqpConfig(coupling_priority=True, impl=impl)  # type: ignore[arg-type]
    ctrl = make(RcLqp, cfg, "ahn_double_support", tocabi)
    for _ in range(5):
        q, v = perturbed_state(tocabi, "stand", rng)
        ctrl.start(RobotState(tocabi, q, v))
        out = ctrl.step(RobotState(tocabi, q, v), 0.0)
        assert out.ok, out.message
        assert out.diagnostics["coupling_residual"] <= 1e-7
        assert out.diagnostics["base_residual"] <= 1e-6


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_lqp_sequential_equals_cascade_and_holds_hard_priorities(
    tocabi: Robot, scenario: str
) -> None:
    rng = np.random.default_rng(15)
    seq = make(Lqp, LqpConfig(strategy="nullspace"), scenario, tocabi)
    cas = make(Lqp, LqpConfig(strategy="cascade"), scenario, tocabi)
    assert isinstance(seq, Lqp)
    keyframe = load_scenario(scenario).spec.initial.keyframe
    for _ in range(20):
        q, v = perturbed_state(tocabi, keyframe, rng)
        for c in (seq, cas):
            c.start(RobotState(tocabi, q, v))
        a = seq.step(RobotState(tocabi, q, v), 0.0)
        b = cas.step(RobotState(tocabi, q, v), 0.0)
        assert a.ok and b.ok, (a.message, b.message)
        scale = max(1.0, float(np.abs(b.qdd).max()))
        assert np.abs(a.qdd - b.qdd).max() <= 1e-6 * scale
        assert np.abs(a.wrench - b.wrench).max() <= 1e-6 * max(1.0, float(np.abs(b.wrench).max()))
        # levels 1-2 (dynamics, torque limits, contacts, wrench cone, q̈ limits) hold
        state = RobotState(tocabi, q, v)
        oracle = forward_dynamics(state, a.tau, seq.frames)
        assert np.abs(oracle.qdd - a.qdd).max() <= 1e-6 * scale
        assert np.abs(oracle.wrench - a.wrench).max() <= 1e-6 * max(
            1.0, float(np.abs(a.wrench).max())
        )
        assert (np.abs(a.tau) <= seq.ctx.tau_max * (1 + 1e-7) + 1e-6).all()
        Cf = seq.Cw @ a.wrench
        assert (Cf >= seq.lw - 1e-6).all() and (Cf <= seq.uw + 1e-6).all()
        assert (np.abs(a.qdd[6:]) <= seq.config.qdd_limit * (1 + 1e-7) + 1e-6).all()


# -- closed loop -------------------------------------------------------------------------------


@functools.cache
def closed_loop(scenario: str, controller: str, assembly: str = "exact") -> dict[str, float]:
    loaded = load_scenario(scenario, ("duration=2.5",))
    cfg = {"assembly": assembly} if controller == "rc_lqp" else {}
    res = run_closed_loop(plan_run(loaded, controller, "quadprog", config=cfg))
    arrays = res.log.arrays()
    window = slice(1000, None)  # after the first second (the motions start at t = 1 s)
    out = {"fell": float(res.status != "ok"), "failures": float(res.failures)}
    for key in ("err.com.pos", "err.l_hand.pos", "err.r_foot.pos"):
        if key in arrays:
            out[key] = float(np.mean(arrays[key][window]))
    return out


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_closed_loop_holds_and_tracks_like_lqp(scenario: str) -> None:
    lqp = closed_loop(scenario, "lqp")
    rc = closed_loop(scenario, "rc_lqp")
    for r in (lqp, rc):
        assert r["fell"] == 0.0 and r["failures"] == 0.0, r
    for key in lqp.keys() - {"fell", "failures"}:
        # within 2× of the conventional LQP (1 µm floor: the CoM errors are a few µm)
        assert rc[key] <= max(2.0 * lqp[key], 1e-6), (key, rc, lqp)


def test_closed_loop_one_chain_with_waist_arms_and_head_holds_its_posture() -> None:
    """COMAN+-like in double support: one unconstrained chain carries the waist, both arms and
    the head, so eq. (30) and the hand and torso rows fix every chain joint and the posture
    reaches the chain only through LQP 1's preview. rc_lqp stands, tracks and keeps its posture
    like lqp (1.2 s; before the preview took the posture in, a forearm–wrist pair counter-
    rotated and the robot fell at 0.25 s)."""
    loaded = load_scenario("comanplus_stand_sway", ("duration=1.2",))
    result = {}
    for controller in ("lqp", "rc_lqp"):
        res = run_closed_loop(plan_run(loaded, controller=controller, solver=SOLVER))
        assert res.status == "ok" and res.failures == 0, (controller, res.message)
        arrays = res.log.arrays()
        keys = ("err.com.pos", "err.l_hand.pos", "err.r_hand.pos", "err.posture.joint")
        result[controller] = {key: float(np.mean(arrays[key][200:])) for key in keys}
    for key, value in result["rc_lqp"].items():
        assert value <= max(2.0 * result["lqp"][key], 1e-6), (key, result)


def test_closed_loop_exact_assembly_tracks_at_least_as_well_as_the_papers() -> None:
    """The paper's Γ_uc (eq. 17) leaves out the chain's coupling with the base: in closed loop
    it tracks no better than the exact assembly (double support, 2.5 s)."""
    exact = closed_loop("ahn_double_support", "rc_lqp", "exact")
    paper = closed_loop("ahn_double_support", "rc_lqp", "paper")
    assert exact["fell"] == 0.0 and exact["failures"] == 0.0, exact
    for key in ("err.com.pos", "err.l_hand.pos"):
        assert exact[key] <= paper[key], (key, exact, paper)


# -- eq. (30) out of the chains' reach ---------------------------------------------------------


@pytest.mark.parametrize("impl", IMPLS)
def test_rc_lqp_replans_when_eq30_is_out_of_reach(tocabi: Robot, impl: str) -> None:
    """The bare standing keyframe (v = 0) of tocabi_stand_sway during the sway: LQP 1 asks the
    chains for a centroidal acceleration that eq. (30) cannot meet within their torque and q̈
    limits. The step re-plans and still realises exactly what it predicts, within the limits;
    with ``infeasible_coupling = "fail"`` it fails instead of returning an unrealisable plan."""
    cfg = RcLqpConfig(impl=impl)  # type: ignore[arg-type]
    replan = make(RcLqp, cfg, "tocabi_stand_sway", tocabi)
    cfg = RcLqpConfig(infeasible_coupling="fail", impl=impl)  # type: ignore[arg-type]
    fail = make(RcLqp, cfg, "tocabi_stand_sway", tocabi)
    assert isinstance(replan, RcLqp)
    q, _ = tocabi.keyframe("stand")
    v = np.zeros(tocabi.nv)
    for t in (2.5, 2.75, 3.0):
        replan.start(RobotState(tocabi, q, v))
        out = replan.step(RobotState(tocabi, q, v), t)
        assert out.ok, out.message
        assert out.diagnostics["replan"] == 1.0
        assert out.diagnostics["coupling_residual"] <= 1e-8
        state = RobotState(tocabi, q, v)
        oracle = forward_dynamics(state, out.tau, replan.frames)
        assert np.abs(oracle.qdd - out.qdd).max() <= 1e-6
        assert np.linalg.norm(oracle.wrench - out.wrench) <= 1e-6 * np.linalg.norm(out.wrench)
        assert (np.abs(out.tau) <= replan.ctx.tau_max * (1 + 1e-7) + 1e-6).all()
        fail.start(RobotState(tocabi, q, v))
        bad = fail.step(RobotState(tocabi, q, v), t)
        assert not bad.ok and "eq. (30)" in bad.message, bad.message


@pytest.mark.parametrize("impl", IMPLS)
def test_rc_lqp_falls_back_to_the_full_model_when_the_replan_misses(
    tocabi: Robot, impl: str
) -> None:
    """A state where the re-planned LQP 2 still cannot meet eq. (30) (the chains' torque limits
    move with the base acceleration): the tick is solved by the full-model LQP, exactly."""
    from tests.conftest import grounded_state

    cfg = RcLqpConfig(impl=impl)  # type: ignore[arg-type]
    ctrl = make(RcLqp, cfg, "tocabi_stand_sway", tocabi)
    # the fallback is the full-model LQP of the same impl
    full = make(Lqp, LqpConfig(impl=impl), "tocabi_stand_sway", tocabi)  # type: ignore[arg-type]
    rng = np.random.default_rng(2026)
    fallbacks = 0
    for _ in range(30):
        q, v = grounded_state(tocabi, "stand", ctrl.frames, rng)  # type: ignore[attr-defined]
        t = float(rng.uniform(1.0, 9.0))
        ctrl.start(RobotState(tocabi, q, v))
        out = ctrl.step(RobotState(tocabi, q, v), t)
        assert out.ok, out.message
        if out.diagnostics["fallback"]:
            fallbacks += 1
            full.start(RobotState(tocabi, q, v))
            ref = full.step(RobotState(tocabi, q, v), t)
            assert np.abs(out.tau - ref.tau).max() <= 1e-8 * max(1.0, float(np.abs(ref.tau).max()))
    assert fallbacks >= 1
