"""Every torque-level controller against the rigid-contact forward-dynamics oracle (DESIGN §4)
on perturbed states the contacts admit: joints ±0.1 rad off the keyframe with the soles put back
on the ground, velocities ±0.3 rad/s with J_c v = 0, t inside the scenario's metrics window
(where the motions run). Every step reported ok must realise the q̈ and the wrench it predicts
and respect the torque limits; a step that cannot must say so (ok = False)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import IMPLS, grounded_state
from wbcbench.controllers.registry import controller_class
from wbcbench.dynamics.state import RobotState
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.robots.loader import Robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import load_scenario

CONTROLLERS = ["qp_wbc", "hqp", "to_osf", "osf_hqp", "lqp", "rc_lqp"]
SCENARIOS = ["tocabi_stand_sway", "ahn_double_support", "ahn_single_support"]
#: (controller, impl): every impl of the controllers that have a native tick
CASES = [
    (name, impl)
    for name in CONTROLLERS
    for impl in (IMPLS if controller_class(name).has_native else ["python"])
]
STATES = 24
#: (controller, impl) on a walk: also the native ticks that follow a changing contact set
WALK_CASES = [
    (name, impl)
    for name in CONTROLLERS
    for impl in (IMPLS if controller_class(name).native_schedule else ["python"])
]


def exact_solver(controller: str) -> str:
    """An active-set backend: exact up to round-off (the LQPs' reference is quadprog)."""
    return "quadprog" if controller in ("lqp", "rc_lqp") else "daqp"


@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize(("controller", "impl"), CASES)
def test_ok_steps_realise_their_prediction(
    tocabi: Robot, controller: str, impl: str, scenario: str
) -> None:
    loaded = load_scenario(scenario)
    ctx = scenario_context(loaded, tocabi, solver=exact_solver(controller), tier="high")
    cls = controller_class(controller)
    ctrl = cls(ctx, cls.Config(impl=impl))
    assert ctrl.impl == impl
    frames = ctx.contact_frames
    t0, t1 = loaded.spec.metrics.window
    rng = np.random.default_rng(2026)
    worst = {"qdd": 0.0, "wrench_rel": 0.0, "tau_excess": 0.0}
    ok = 0
    for _ in range(STATES):
        q, v = grounded_state(tocabi, loaded.spec.initial.keyframe, frames, rng)
        t = float(rng.uniform(t0, t1))
        ctrl.start(RobotState(tocabi, q, v))
        out = ctrl.step(RobotState(tocabi, q, v), t)
        if not out.ok:
            assert out.message
            continue
        ok += 1
        state = RobotState(tocabi, q, v)
        oracle = forward_dynamics(state, out.tau, frames)
        scale = max(1.0, float(np.abs(out.qdd).max()))
        worst["qdd"] = max(worst["qdd"], float(np.abs(oracle.qdd - out.qdd).max()) / scale)
        rel = float(np.linalg.norm(oracle.wrench - out.wrench))
        rel /= max(1.0, float(np.linalg.norm(out.wrench)))
        worst["wrench_rel"] = max(worst["wrench_rel"], rel)
        excess = np.abs(out.tau) - ctx.tau_max * (1 + 1e-7)
        worst["tau_excess"] = max(worst["tau_excess"], float(excess.max()))
    assert worst["qdd"] <= 1e-6, worst
    assert worst["wrench_rel"] <= 1e-6, worst
    assert worst["tau_excess"] <= 1e-6, worst
    # the LQPs keep every tick (rc_lqp through its re-plan); the others most: hqp's cascade
    # reports a lower level infeasible on 5 to 8 of these perturbed states with every exact
    # backend (DAQP 6, quadprog 5: the equalities the levels above carry are consistent only to
    # rounding there)
    assert ok >= (STATES if controller in ("lqp", "rc_lqp") else 0.7 * STATES), ok


#: ticks just before, at and just after the first lift-off (l_sole, 1.2 s) and touchdown
#: (2.0 s) of the short walk, in the unload ramp (1.15 s), in single support (1.6 s) and
#: while f_min ramps in after touchdown (2.05 s)
WALK_TIMES = [1.15, 1.199, 1.2, 1.201, 1.6, 1.999, 2.0, 2.001, 2.05]


def walk_solver(controller: str) -> str:
    """The exact backend on the walking states: quadprog for hqp too, whose lower levels DAQP
    reports primal infeasible (or solved outside a held bound) on most of these perturbed
    states, in both impls, where quadprog solves them."""
    return "quadprog" if controller == "hqp" else exact_solver(controller)


@pytest.mark.parametrize(("controller", "impl"), WALK_CASES)
def test_walking_ticks_realise_their_prediction_on_the_active_contacts(
    tocabi: Robot, controller: str, impl: str
) -> None:
    """Around a lift-off and a touchdown the QPs hold only the active contacts: the wrench has
    one 6-vector per active contact, the oracle with those contacts realises the predicted q̈
    and wrench, and an unloading contact's normal force stays within its ramped bounds."""
    from wbcbench.runs import plan_run

    run = plan_run(
        "tocabi_walk",
        controller,
        walk_solver(controller),
        tier="high",
        config={"impl": impl},
        overrides=["walk.steps=2", "duration=4.7"],
    )
    ctx = run.context()
    schedule = ctx.schedule
    assert schedule is not None
    ctrl = run.controller_cls(ctx, run.config)
    rng = np.random.default_rng(7)
    ok = 0
    for t in WALK_TIMES:
        phase = schedule.phase(t)
        frames = [ctx.contacts[i].frame for i in phase.active]
        assert len(frames) == (1 if 1.2 <= t < 2.0 else 2)
        q, v = grounded_state(tocabi, "stand", frames, rng, q_noise=0.01, v_noise=0.05)
        ctrl.start(RobotState(tocabi, q, v))
        out = ctrl.step(RobotState(tocabi, q, v), t)
        if not out.ok:
            assert out.message
            continue
        ok += 1
        assert out.wrench.shape == (6 * len(frames),)
        oracle = forward_dynamics(RobotState(tocabi, q, v), out.tau, frames)
        scale = max(1.0, float(np.abs(out.qdd).max()))
        assert float(np.abs(oracle.qdd - out.qdd).max()) <= 1e-6 * scale, t
        rel = float(np.linalg.norm(oracle.wrench - out.wrench))
        assert rel <= 1e-6 * max(1.0, float(np.linalg.norm(out.wrench))), t
        assert float((np.abs(out.tau) - ctx.tau_max * (1 + 1e-7)).max()) <= 1e-6
        held = 1e-6
        if controller == "osf_hqp":  # each QP's bounds widen by carry_tolerance per level above
            held += ctrl.config.carry_tolerance * len(ctrl.levels)
        for j, i in enumerate(phase.active):
            fz = out.wrench[6 * j + 2]
            contact = ctx.contacts[i]
            assert fz >= phase.lower[j] * contact.fmin - held, (t, fz)
            if phase.upper[j] < 1:
                assert fz <= (phase.upper[j] + 1e-6) * schedule.ramp_force + held, (t, fz)
        full = ctrl.full_wrench(out.wrench)
        for i in set(range(len(ctx.contacts))) - set(phase.active):
            assert not full[6 * i : 6 * i + 6].any()
    # hqp's cascade re-imposes each level's optimum as equalities on the next, which the
    # backend often finds inconsistent once a wrench or torque bound is active (a failed tick
    # that says so: 3 of these 9 ticks solve in the native impl, 4 in the Python one); the
    # others keep (nearly) every tick
    assert ok >= (1 if controller == "hqp" else len(WALK_TIMES) - 1), ok
