"""Contact schedules: the scenario keys, their checks (exact messages), the schedule's phases,
ramps and touchdown confirmation, and the walk's expansion into tasks."""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from wbcbench.controllers.rc_lqp import RcLqp
from wbcbench.errors import ScenarioError, WbcBenchError
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import SCENARIO_DIR, load_scenario
from wbcbench.tasks.schedule import ContactSchedule, ScheduledContact

WALK = SCENARIO_DIR / "tocabi_walk.yaml"
STAND = SCENARIO_DIR / "tocabi_stand_sway.yaml"


def write(tmp_path: Path, raw: dict[str, Any]) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def raw_of(path: Path) -> dict[str, Any]:
    return copy.deepcopy(yaml.safe_load(path.read_text()))


def error_of(tmp_path: Path, raw: dict[str, Any]) -> str:
    path = write(tmp_path, raw)
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    return str(exc.value).removeprefix(f"{path}: ")


# -- checks of the file


def test_overlapping_intervals(tmp_path: Path) -> None:
    raw = raw_of(STAND)
    raw["contacts"][0]["schedule"] = [[0, 3], [2.5, 10]]
    assert error_of(tmp_path, raw) == (
        "contacts[0].schedule[1]: [2.5, 10] overlaps [0, 3] (contacts[0].schedule[0]); give the "
        "intervals in time order, each starting after the previous one ends"
    )


def test_no_support(tmp_path: Path) -> None:
    raw = raw_of(STAND)
    raw["contacts"][0]["schedule"] = [[0, 3], [4, 10]]
    raw["contacts"][1]["schedule"] = [[0, 2], [3.5, 10]]
    assert error_of(tmp_path, raw) == (
        "contacts: no contact is active over [3, 3.5] s: the robot has no support then; make "
        "the schedules' intervals meet or overlap"
    )


def test_touchdown_after_the_end_never_happens(tmp_path: Path) -> None:
    raw = raw_of(STAND)
    raw["contacts"][0]["schedule"] = [[0, 3], [12, 20]]
    assert error_of(tmp_path, raw) == (
        "contacts[0].schedule[1]: the touchdown at 12 s never happens: the run ends at 10 s; "
        "start the interval earlier or lengthen duration"
    )


def test_swing_task_on_a_held_frame(tmp_path: Path) -> None:
    raw = raw_of(STAND)
    raw["contacts"][0]["schedule"] = [[0, 3], [4, 10]]
    raw["tasks"].append({"name": "lift", "type": "frame_position", "frame": "r_sole"})
    assert error_of(tmp_path, raw) == (
        "tasks[6].frame: task 'lift' moves frame 'r_sole', which contacts[1] holds for the "
        "whole run; give contacts[1] a schedule with a swing interval (or make it a foot of the "
        "walk), or remove the task"
    )


def test_interval_shorter_than_the_ramp(tmp_path: Path) -> None:
    raw = raw_of(STAND)
    raw["contacts"][0]["schedule"] = [[0, 0.05], [1, 10]]
    assert error_of(tmp_path, raw) == (
        "contacts[0].schedule[0]: [0, 0.05] is shorter than the lift-off ramp unload = 0.1 s; "
        "lengthen the interval or shorten unload"
    )


def test_walk_foot_is_not_a_contact(tmp_path: Path) -> None:
    raw = raw_of(WALK)
    raw["walk"]["feet"] = ["l_sole", "r_foot"]
    assert error_of(tmp_path, raw) == (
        "walk.feet[1]: 'r_foot' is not a contact of the scenario; valid choices: l_sole, r_sole"
    )


def test_walk_foot_with_its_own_schedule(tmp_path: Path) -> None:
    raw = raw_of(WALK)
    raw["contacts"][1]["schedule"] = [[0, 20]]
    assert error_of(tmp_path, raw) == (
        "contacts[1].schedule: contact 'r_sole' is a foot of the walk, which schedules it; "
        "remove its schedule"
    )


def test_walk_names_a_com_task(tmp_path: Path) -> None:
    raw = raw_of(WALK)
    raw["walk"]["com_task"] = "centre"
    assert error_of(tmp_path, raw) == (
        "walk.com_task: 'centre' is not a com task of the scenario; valid choices: com"
    )


def test_walk_steps_or_footsteps(tmp_path: Path) -> None:
    raw = raw_of(WALK)
    raw["walk"]["footsteps"] = [{"foot": "l_sole", "position": [0.1, 0.1, 0.0]}]
    assert error_of(tmp_path, raw).startswith(
        "walk: give either 'steps' (a generated walk) or 'footsteps', not both"
    )


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (-0.05, "Input should be greater than or equal to 0"),
        (1.5, "Input should be less than or equal to 1"),
    ],
)
def test_walk_touchdown_velocity_is_a_downward_speed(
    tmp_path: Path, value: float, message: str
) -> None:
    raw = raw_of(WALK)
    raw["walk"]["touchdown_velocity"] = value
    assert error_of(tmp_path, raw) == f"walk.touchdown_velocity: {message}"


def test_native_tick_of_a_fixed_contact_set_refuses_a_schedule(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # every built-in native tick follows the contacts: one that would not, as a plugin's may
    monkeypatch.setattr(RcLqp, "native_schedule", False)
    with pytest.raises(WbcBenchError) as exc:
        plan_run(WALK, "rc_lqp", "daqp", config={"impl": "native"})
    assert str(exc.value) == (
        f"{WALK}: rc_lqp: the native tick holds a fixed contact set and this scenario's contacts "
        "change (a contact schedule or a walk); run the Python reference: impl python (--set "
        "controllers.rc_lqp.impl=python, or controllers: {rc_lqp: {impl: python}} in the "
        "scenario)"
    )


@pytest.mark.parametrize("controller", ["qp_wbc", "hqp", "lqp", "to_osf", "osf_hqp", "rc_lqp"])
def test_native_tick_that_follows_a_schedule_is_planned(controller: str) -> None:
    run = plan_run(WALK, controller, "daqp", config={"impl": "native"})
    assert run.impl == "native"


def test_a_walk_uses_three_contact_sets() -> None:
    schedule = plan_run(WALK, "qp_wbc", "daqp").context().schedule
    assert schedule is not None
    left, right = (schedule.frames.index(f) for f in ("l_sole", "r_sole"))
    # double support, then single support on the stance foot of the first step, then the other
    first = schedule.phase(schedule.touchdowns()[0][0] - 0.1).active
    assert len(first) == 1
    other = (left,) if first == (right,) else (right,)
    assert schedule.contact_sets() == [tuple(sorted((left, right))), first, other]


def test_a_sweep_runs_native_only_the_ticks_that_follow_a_schedule(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from wbcbench.bench.sweep import _impl_configs

    impls = ["native", "python"]
    assert _impl_configs(impls, "qp_wbc", scheduled=True) == [{"impl": i} for i in impls]
    assert _impl_configs(impls, "to_osf", scheduled=True) == [{"impl": i} for i in impls]
    assert _impl_configs(impls, "rc_lqp", scheduled=True) == [{"impl": i} for i in impls]
    monkeypatch.setattr(RcLqp, "native_schedule", False)  # a tick of a fixed contact set
    assert _impl_configs(impls, "rc_lqp", scheduled=True) == [{"impl": "python"}]
    assert _impl_configs(impls, "rc_lqp", scheduled=False) == [{"impl": i} for i in impls]


# -- the schedule at run time


def schedule() -> ContactSchedule:
    left = ScheduledContact("l", [(0.0, 1.0), (2.0, math.inf)], [None, np.zeros(3)], unload=0.1)
    right = ScheduledContact("r", [(0.0, math.inf)], unload=0.1)
    return ContactSchedule([left, right], ramp_force=500.0, touchdown_tolerance=0.05)


def test_phases_and_ramps() -> None:
    s = schedule()
    assert s.phase(0.5).active == (0, 1)
    ramp = s.phase(0.95)  # halfway down the lift-off ramp
    assert ramp.active == (0, 1)
    assert ramp.lower[0] == pytest.approx(0.5) and ramp.upper[0] == pytest.approx(0.5)
    assert s.phase(1.0).active == (1,)  # lifted off
    # after touchdown f_min ramps in from 0, the upper bound from the confirming load
    # (20 N of the 500 N ramp force) to the full bound, as they ramp out before lift-off
    rise = 20.0 / 500.0
    assert s.phase(2.0).lower[0] == 0.0 and s.phase(2.0).upper[0] == pytest.approx(rise)
    assert s.phase(2.05).lower[0] == pytest.approx(0.5)
    assert s.phase(2.05).upper[0] == pytest.approx(rise + (1 - rise) * 0.5)
    assert s.phase(2.1).lower[0] == 1.0 and s.phase(2.1).upper[0] == 1.0
    # the bounds written for the ramp: f_min and min(f_max, weight) scaled
    lw, uw = np.array([10.0, -np.inf]), np.array([np.inf, 0.0])
    out_l, out_u = np.empty(2), np.empty(2)
    s.scale_bounds(ramp, [0], [np.inf], lw, uw, out_l, out_u)
    assert out_l.tolist() == pytest.approx([5.0, -np.inf])
    assert out_u.tolist() == pytest.approx([250.0, 0.0])


def test_touchdown_waits_for_load_and_ends_when_it_never_comes() -> None:
    s = schedule()
    pos = [np.zeros(3), np.zeros(3)]
    assert s.observe(1.5, np.array([0.0, 800.0]), pos) == ""
    assert s.observe(2.01, np.array([0.0, 800.0]), pos) == ""
    assert s.phase(2.01).active == (1,)  # scheduled, but no load yet
    assert s.observe(2.02, np.array([30.0, 770.0]), pos) == ""
    assert s.confirmed == {(0, 1): 2.02}
    assert s.phase(2.02).active == (0, 1)
    late = schedule()
    late.observe(0.0, np.array([400.0, 400.0]), pos)
    assert late.observe(2.06, np.array([0.0, 800.0]), pos) == (
        "the touchdown of contact 'l' scheduled at t = 2.000 s did not happen: its foot carried "
        "less than 20 N until t = 2.060 s (sim.touchdown_tolerance = 0.05 s)"
    )


def test_landing_off_target() -> None:
    s = schedule()
    pos = [np.array([0.03, 0.0, 0.0]), np.zeros(3)]
    assert s.observe(2.0, np.array([100.0, 700.0]), pos) == (
        "contact 'l' landed 30.0 mm from its target (0.000, 0.000, 0.000) m at t = 2.000 s, "
        "beyond sim.landing_tolerance = 20 mm"
    )


def test_walk_expands_into_schedule_tasks_and_plan() -> None:
    overrides = ["walk.steps=2", "duration=4.7", "walk.touchdown_velocity=0.05"]
    run = plan_run(WALK, "qp_wbc", "daqp", overrides=overrides)
    ctx = run.context()
    assert ctx.schedule is not None and ctx.schedule.plan is not None
    names = [t.name for t in ctx.tasks]
    assert "swing.l_sole" in names and "swing.r_sole" in names
    assert ctx.schedule.touchdowns() == [(2.0, "l_sole"), (3.0, "r_sole")]
    plan = ctx.schedule.plan
    com = next(t for t in ctx.tasks if t.name == "com")
    assert com.absolute
    x, _, _ = com.reference.sample(1.7)  # type: ignore[union-attr]  # the plan's CoM
    assert np.allclose(x, plan.com(1.7)[0])
    # the swing task's offset lands the foot on its footstep
    swing = next(t for t in ctx.tasks if t.name == "swing.l_sole")
    step = plan.swings[0]
    offset, rate, _ = swing.reference.sample(step.touch_down)  # type: ignore[union-attr]
    start = next(f for f in plan.footsteps if f.foot == "l_sole" and f.is_initial)
    assert np.allclose(offset[:3], np.array(step.position) - start.position)
    # … moving straight down at walk.touchdown_velocity
    assert plan.timing.touchdown_velocity == 0.05
    assert np.allclose(rate, [0.0, 0.0, -0.05, 0.0, 0.0, 0.0])
