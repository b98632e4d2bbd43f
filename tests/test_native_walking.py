"""impl: native equals impl: python on a changing contact set (``tocabi_walk``, two steps).

One controller per impl steps through the same ticks in order, so the native tick changes its
contact set in place, as in a walk: the unload ramp before the first lift-off, the ticks just
before, at and just after it (l_sole leaves at 1.2 s), single support on r_sole, the touchdown
(2.0 s) and the lower bound ramping in after it, the second lift-off (r_sole, 2.2 s) and single
support on l_sole. The states are those of a closed-loop walk of the native ``qp_wbc`` at
those times (a state far from the plan, e.g. a perturbed standing keyframe when the CoM plan has
moved over one foot, asks for accelerations that leave the hierarchies' lower levels
infeasible in both impls, and compares little).

At every tick both impls hold the same contacts and tasks (the swing task of a standing foot
leaves the QPs), build the same first QP (the weighted QP whole, a hierarchy's first level QP) to
1e-12 relative, and answer alike: ``qp_wbc`` to 1e-8 relative (an active-set backend on the
same data); ``to_osf`` and ``osf_hqp`` (with ``params: periodic:2``, whose parameters are
computed afresh at each change of the set) as ``tests/test_native_equality.py`` compares them:
their QPs' data to 1e-9, the answers to 1e-8 or the rounding times the reduced Hessian's
condition, the parameters as fresh in both and fresh at every change; ``hqp``, ``lqp`` and
``rc_lqp`` with the same optimal slacks (3e-6) and τ, q̈ and f within ten times the spread of
the Python reference's other strategy on the same state (the measure of how well conditioned
the optimum is, as in ``tests/test_native_hierarchy.py``; ``rc_lqp`` with the same re-plan and
fallback decisions and the bounds of ``tests/test_native_rc_lqp.py``), unless a level needed
the proximal retry in either impl (the impls then solved different problems). ``rc_lqp``'s
native tick switches to the reduced model of the new stance, built at set-up, at each change.
The native answer also realises its prediction under the rigid-contact oracle on the active
contacts (where its parameters are of the tick's own state), with the ramped normal-force
bounds held.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.controllers.base import Controller
from wbcbench.controllers.native import priority_groups
from wbcbench.dynamics.state import RobotState
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.robots.loader import Robot
from wbcbench.runs import plan_run
from wbcbench.sim.closed_loop import run_closed_loop

from .test_native_equality import DATA_TOLERANCE, in_basis_of, reduced_condition
from .test_native_hierarchy import QpRecorder

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

#: in order: the unload ramp, around the first lift-off (1.2 s), single support on r_sole,
#: around the touchdown (2.0 s) and in the ramp after it, around the second lift-off (2.2 s),
#: single support on l_sole
TIMES = [1.15, 1.199, 1.2, 1.201, 1.6, 1.999, 2.0, 2.001, 2.05, 2.199, 2.2, 2.201, 2.6]

#: controller, settings, the other strategy whose Python answer measures the spread (None:
#: one QP, compared to 1e-8)
CASES: list[tuple[str, dict[str, Any], str | None]] = [
    ("qp_wbc", {"variables": "full"}, None),
    ("qp_wbc", {"variables": "eliminated"}, None),
    ("hqp", {"strategy": "cascade"}, "nullspace"),
    ("lqp", {"strategy": "nullspace"}, "cascade"),
    ("to_osf", {}, None),
    ("osf_hqp", {"params": "periodic:2"}, None),
    ("rc_lqp", {"strategy": "nullspace"}, "cascade"),
]
#: rc_lqp: how far beyond the spread the native answer may lie, at least 1e-5 (the bounds of
#: tests/test_native_rc_lqp.py, which explains them)
RC_LQP_FACTOR = {"daqp": 200.0}
#: DAQP, and an active-set backend of another family
SOLVERS = ["daqp", "quadprog"]


#: the short walk: two steps, the default timing
WALK = ["walk.steps=2", "duration=4.7"]


@pytest.fixture(scope="module")
def walk_states() -> dict[float, tuple[np.ndarray, np.ndarray]]:
    """(q, v) at the start and at each of :data:`TIMES` in a closed-loop walk of the native
    ``qp_wbc``."""
    run = plan_run(
        "tocabi_walk",
        "qp_wbc",
        "daqp",
        config={"impl": "native"},
        overrides=[*WALK, "duration=2.7"],
    )
    states: list[tuple[np.ndarray, np.ndarray]] = []
    result = run_closed_loop(run, on_step=lambda state, out: states.append((state.q, state.v)))
    assert result.status == "ok", result.message
    dt = run.scenario.spec.dt
    return {t: states[round(t / dt)] for t in [0.0, *TIMES]}


def controller(name: str, solver: str, config: dict[str, Any]) -> Controller:
    run = plan_run(
        "tocabi_walk",
        name,
        solver,
        tier="high",
        config=config,
        overrides=WALK,
    )
    return run.make_controller(keep_problems=True)


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b), initial=0.0) / max(1.0, float(np.abs(b).max(initial=0))))


def slacks(diagnostics: dict[str, float]) -> dict[str, float]:
    return {k: v for k, v in diagnostics.items() if k.startswith(("slack.", "w.", "v."))}


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize(
    "name,config,other",
    CASES,
    ids=lambda x: x if isinstance(x, str) else "-".join(map(str, x.values())) if x else "",
)
def test_native_equals_python_across_lift_off_and_touchdown(
    tocabi: Robot,
    walk_states: dict[float, tuple[np.ndarray, np.ndarray]],
    name: str,
    config: dict[str, Any],
    other: str | None,
    solver: str,
) -> None:
    python = controller(name, solver, {**config, "impl": "python"})
    native = controller(name, solver, {**config, "impl": "native"})
    assert (python.impl, native.impl) == ("python", "native")
    spread_ref = (
        None if other is None else controller(name, solver, {"impl": "python", "strategy": other})
    )
    schedule = native.ctx.schedule
    assert schedule is not None
    q0, v0 = walk_states[0.0]  # the walk's start, where its run started its tasks
    for c in (python, native, spread_ref):
        if c is not None:
            c.start(RobotState(tocabi, q0, v0))
    compared, changes = 0, 0
    data = DATA_TOLERANCE.get(name, 1e-12)
    for t in TIMES:
        phase = schedule.phase(t)
        frames = [native.ctx.contacts[i].frame for i in phase.active]
        q, v = walk_states[t]
        held = native.native_tick.active_contacts if native.native_tick else None
        a = native.step(RobotState(tocabi, q, v), t)
        with QpRecorder() as recorder:  # the Python hierarchies keep no QPs: their handles'
            b = python.step(RobotState(tocabi, q, v), t)
        changed = held is not None and list(held) != list(phase.active)
        changes += changed
        assert list(native.native_tick.active_contacts) == list(phase.active), t
        assert [term.task.name for term in a.terms] == [term.task.name for term in b.terms]
        assert a.problems and recorder.problems
        pa, pb = a.problems[0], recorder.problems[0]
        assert pa.name == pb.name, t
        if name == "osf_hqp":
            pb = in_basis_of(pb, pa)
        for f in ("H", "g", "A", "b", "C", "l", "u", "lb", "ub"):
            x, y = getattr(pa, f), getattr(pb, f)
            if y is None:
                assert x is None, (t, f)
                continue
            assert x.shape == y.shape, (t, f)
            finite = np.isfinite(y)
            assert np.array_equal(finite, np.isfinite(x)), (t, f)
            assert relative(x[finite], y[finite]) <= data, (t, pb.name, f)
        assert a.ok == b.ok, (t, a.message, b.message)
        if not b.ok:
            continue
        compared += 1
        assert a.wrench.shape == (6 * len(frames),)
        stale = a.diagnostics.get("params_staleness", 0.0)
        assert stale == b.diagnostics.get("params_staleness", 0.0), t
        # the parameters of the old contact set are never used: a change computes them
        assert not (changed and stale), t
        # the native answer realises its prediction on the active contacts, in the ramped bounds
        # (parameters kept from an earlier tick, periodic:2, are those of another state here)
        if not stale:
            oracle = forward_dynamics(RobotState(tocabi, q, v), a.tau, frames)
            scale = max(1.0, float(np.abs(a.qdd).max()))
            assert float(np.abs(oracle.qdd - a.qdd).max()) <= 1e-6 * scale, t
            rel = float(np.linalg.norm(oracle.wrench - a.wrench))
            assert rel <= 1e-6 * max(1.0, float(np.linalg.norm(a.wrench))), t
        margin = 1e-6
        if name == "osf_hqp":  # each QP's bounds widen by carry_tolerance per level above
            margin += native.config.carry_tolerance * len(native.levels)
        for j, i in enumerate(phase.active):
            fz = a.wrench[6 * j + 2]
            assert fz >= phase.lower[j] * native.ctx.contacts[i].fmin - margin, (t, fz)
            if phase.upper[j] < 1:
                assert fz <= (phase.upper[j] + 1e-6) * schedule.ramp_force + margin, (t, fz)
        diff = max(
            relative(x, y) for x, y in ((a.tau, b.tau), (a.qdd, b.qdd), (a.wrench, b.wrench))
        )
        if spread_ref is None:
            # the QPs' data agree to rounding (for the OSF QPs amplified through Λ:
            # DATA_TOLERANCE); their answers to that rounding times the reduced Hessian's
            # condition, as in tests/test_native_equality.py (qp_wbc's weights 1e9 … 1 make
            # it 5e6 to 9e7 on these states)
            kappa = max(reduced_condition(p) for p in recorder.problems)
            bound = max(1e-8, kappa * 100 * np.finfo(float).eps)
            assert diff <= bound, (t, diff, bound)
            continue
        assert slacks(a.diagnostics).keys() == slacks(b.diagnostics).keys()
        if a.diagnostics["prox_retries"] or b.diagnostics["prox_retries"]:
            continue  # a regularised level: the impls solved different problems
        for key, value in slacks(b.diagnostics).items():
            assert abs(a.diagnostics[key] - value) <= 3e-6 * max(1.0, abs(value)), (t, key)
        factor, least = 10.0, 1e-8
        if name == "rc_lqp":  # the same re-plan and fallback decisions
            assert a.diagnostics["replan"] == b.diagnostics["replan"], t
            assert a.diagnostics["fallback"] == b.diagnostics["fallback"], t
            factor, least = RC_LQP_FACTOR.get(solver, 10.0), 1e-5
        c = spread_ref.step(RobotState(tocabi, q, v), t)
        if c.ok and not c.diagnostics["prox_retries"]:
            spread = max(relative(c.tau, b.tau), relative(c.qdd, b.qdd))
            assert diff <= max(least, factor * spread), (t, diff, spread)
    assert changes == 3  # lift-off, touchdown, lift-off: the set changed in place each time
    # hqp's cascade may find a lower level inconsistent once a bound is active (both impls say
    # so alike, checked above); the others keep every tick
    assert compared >= (1 if name == "hqp" else len(TIMES)), compared


def test_native_rc_lqp_refuses_a_contact_set_it_has_no_stance_for(tocabi: Robot) -> None:
    ctrl = controller("rc_lqp", "daqp", {"impl": "native"})
    q0, _ = tocabi.keyframe("stand")
    ctrl.start(RobotState(tocabi, q0, np.zeros(tocabi.nv)))
    tick = ctrl.native_tick
    with pytest.raises(ValueError) as exc:
        tick.select_contacts([])
    assert str(exc.value) == "rc_lqp: no chain split for the contacts [] (add_stance first)"
    nw = ctrl.Cw.shape[0]
    with pytest.raises(ValueError) as exc:
        tick.set_wrench_bounds(np.zeros(3), np.zeros(3))
    assert str(exc.value) == f"rc_lqp: wrench bounds of 3 and 3 rows; the contact set has {nw}"


def test_native_rc_lqp_builds_a_stance_the_schedule_did_not_foresee(
    tocabi: Robot, walk_states: dict[float, tuple[np.ndarray, np.ndarray]]
) -> None:
    """A contact set first met after set-up (here: the schedule foresees double support only)
    gets its stance on its first tick, in both impls: the tick takes its chain split then, and
    its row split, decided at that tick's state, is the reference's."""
    python = controller("rc_lqp", "daqp", {"impl": "python"})
    native = controller("rc_lqp", "daqp", {"impl": "native"})
    q0, v0 = walk_states[0.0]
    for c in (python, native):
        schedule = c.ctx.schedule
        assert schedule is not None
        double = schedule.contact_sets()[0]
        schedule.contact_sets = lambda double=double: [double]  # type: ignore[method-assign]
        c.start(RobotState(tocabi, q0, v0))
        assert list(c._stances) == [double]
    for t in (1.15, 1.6):  # double support, then single support on r_sole, unforeseen
        q, v = walk_states[t]
        a = native.step(RobotState(tocabi, q, v), t)
        b = python.step(RobotState(tocabi, q, v), t)
        assert a.ok and b.ok, (t, a.message, b.message)
    tick, rows, tasks = native.native_tick, python._rows, python.ctx.tasks
    assert rows is not None and len(python.active_contacts) == 1
    assert list(tick.active_contacts) == list(python.active_contacts)
    assert tick.chain_priority == rows.chain_priority
    offsets = np.cumsum([0] + [t.dim for t in tasks])
    _, groups = priority_groups(tasks, python.active_tasks)
    for group, split1, split2 in zip(groups, tick.lqp1_rows, tick.lqp2_rows, strict=True):
        assert list(split1) == [offsets[i] + r for i in group for r in rows.lqp1[tasks[i].name]]
        assert list(split2) == [offsets[i] + r for i in group for r in rows.lqp2[tasks[i].name]]
    # the native answer realises its prediction on the stance's contact
    frames = [native.ctx.contacts[i].frame for i in native.active_contacts]
    oracle = forward_dynamics(RobotState(tocabi, q, v), a.tau, frames)
    assert float(np.abs(oracle.qdd - a.qdd).max()) <= 1e-6 * max(1.0, float(np.abs(a.qdd).max()))


@pytest.mark.parametrize("name", ["to_osf", "osf_hqp"])
def test_native_osf_prepares_every_contact_set_before_the_walk(
    tocabi: Robot, walk_states: dict[float, tuple[np.ndarray, np.ndarray]], name: str
) -> None:
    """The native OSF controllers make each scheduled contact set's settings at the start, so
    that no tick of the walk makes any (the first tick still selects its set)."""
    native = controller(name, "daqp", {"impl": "native"})
    native.start(RobotState(tocabi, *walk_states[0.0]))
    # left as it was made: every contact, none selected yet
    assert native.active_contacts == (-1,)
    assert (native.nc, native.frames) == (12, ["l_sole", "r_sole"])
    assert native.level_tasks == native.tick_order
    prepared = dict(native._tick_settings)
    assert {(0, 1), (0,), (1,)} <= set(prepared)
    for t in TIMES:
        assert native.step(RobotState(tocabi, *walk_states[t]), t).ok, t
    assert native._tick_settings == prepared
