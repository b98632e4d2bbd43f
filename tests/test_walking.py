"""The walking pattern: the LIPM and DCM identities hold at every instant, the schedule always
has support, swings start and end at rest on their footsteps, and the plan reads back as data."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pandas as pd
import pytest

from wbcbench.report.walking import walk_figure, walk_phase_figure
from wbcbench.tasks.walking import (
    Footstep,
    SwingTrajectory,
    WalkPlan,
    WalkTiming,
    footsteps_from_walk,
    plan_walk,
)

START = {
    "l_sole": Footstep("l_sole", (0.0, 0.1, 0.0), 0.0),
    "r_sole": Footstep("r_sole", (0.0, -0.1, 0.0), 0.0),
}
COM = np.array([0.01, 0.003, 0.8])


def walk(turn: float = 0.0, steps: int = 6, timing: WalkTiming | None = None) -> WalkPlan:
    landings = footsteps_from_walk(START, "l_sole", steps, 0.2, turn=turn)
    return plan_walk(START, landings, COM, timing)


@pytest.mark.parametrize("turn", [0.0, 0.2])
def test_the_com_satisfies_the_lipm_and_the_dcm_definition_everywhere(turn: float) -> None:
    plan = walk(turn)
    w = plan.omega
    assert w == pytest.approx(math.sqrt(9.81 / COM[2]))
    for t in np.random.default_rng(0).uniform(0.0, plan.duration + 1.0, 500):
        x, dx, ddx = plan.com(t)
        # ẍ = ω² (x − p) and ξ = x + ẋ/ω, to round-off of metre-sized numbers
        np.testing.assert_allclose(ddx[:2], w * w * (x[:2] - plan.zmp(t)), atol=1e-12)
        np.testing.assert_allclose(plan.dcm(t), x[:2] + dx[:2] / w, atol=1e-12)
        assert x[2] == COM[2] and dx[2] == 0.0 and ddx[2] == 0.0


def test_the_com_starts_at_rest_and_ends_over_the_last_stance() -> None:
    plan = walk()
    x, dx, _ = plan.com(0.0)
    np.testing.assert_allclose(x, COM, atol=1e-15)
    np.testing.assert_allclose(dx, 0.0, atol=1e-12)
    # the DCM rests on the final ZMP point, the midpoint of the closing stance
    last, other = plan.footsteps[-1], plan.footsteps[-2]
    centre = 0.5 * (last.xy + other.xy)
    np.testing.assert_allclose(plan.dcm(plan.zmp_times[-1]), centre, atol=1e-12)
    x, dx, _ = plan.com(plan.duration)
    # what is left decays as e^{−ω t} over the final hold
    bound = math.exp(-plan.omega * plan.timing.end) * np.linalg.norm(plan.footsteps[-1].xy)
    assert np.linalg.norm(x[:2] - centre) < bound


def test_position_and_velocity_are_continuous_at_every_knot() -> None:
    plan = walk(0.1)
    eps = 1e-9
    for t in plan.zmp_times[1:]:
        before, after = plan.com(t - eps), plan.com(t + eps)
        np.testing.assert_allclose(before[0], after[0], atol=1e-8)
        np.testing.assert_allclose(before[1], after[1], atol=1e-7)
        np.testing.assert_allclose(plan.zmp(t - eps), plan.zmp(t + eps), atol=1e-7)


def test_in_single_support_the_zmp_is_on_the_stance_foot() -> None:
    plan = walk(0.1)
    where = {f.foot: f for f in plan.footsteps if f.is_initial}
    for step in plan.swings:
        stance = next(f for name, f in where.items() if name != step.foot)
        for t in np.linspace(step.lift_off, step.touch_down, 7):
            np.testing.assert_allclose(plan.zmp(t), stance.xy, atol=1e-12)
        where[step.foot] = step


def test_the_schedule_always_has_support_and_one_foot_in_single_support() -> None:
    plan = walk()
    schedule = plan.schedule()
    assert sorted(schedule) == ["l_sole", "r_sole"]
    for intervals in schedule.values():
        assert all(a < b for a, b in intervals)
        assert all(b1 < a2 for (_, b1), (a2, _) in itertools.pairwise(intervals))
    for t in np.linspace(0.0, plan.duration, 2001):
        assert plan.active("l_sole", t) or plan.active("r_sole", t)
    for step in plan.swings:
        mid = 0.5 * (step.lift_off + step.touch_down)
        assert not plan.active(step.foot, mid)
        assert plan.unload_factor(step.foot, mid) == 0.0
        # the normal-force bound ramps 1 → 0 over the unload time before lift-off
        t0 = step.lift_off - plan.timing.unload
        assert plan.unload_factor(step.foot, t0 - 1e-9) == 1.0
        assert plan.unload_factor(step.foot, t0 + 0.5 * plan.timing.unload) == pytest.approx(0.5)


def test_swings_leave_and_land_at_rest_on_their_footsteps_at_the_stated_height() -> None:
    plan = walk(0.2)
    for step in plan.swings:
        swing = plan.swing_trajectory(step)
        start, end = swing.start, swing.end
        x0, dx0, ddx0 = swing.sample(step.lift_off)
        x1, dx1, ddx1 = swing.sample(step.touch_down)
        np.testing.assert_allclose(x0, [*start.position, start.yaw], atol=1e-12)
        np.testing.assert_allclose(x1, [*end.position, end.yaw], atol=1e-12)
        for v in (dx0, ddx0, dx1, ddx1):
            np.testing.assert_allclose(v, 0.0, atol=1e-12)
        top, _, _ = swing.sample(0.5 * (step.lift_off + step.touch_down))
        assert top[2] == pytest.approx(plan.timing.swing_height)
        # the whole-walk reference of the foot is this swing inside its interval
        mid = step.lift_off + 0.3 * (step.touch_down - step.lift_off)
        whole = plan.foot_trajectory(step.foot).sample(mid)
        np.testing.assert_array_equal(whole[0], swing.sample(mid)[0])


def test_a_swing_with_a_touchdown_velocity_lands_moving_down_and_searches_after() -> None:
    v = 0.05
    plan = walk(0.2, timing=WalkTiming(touchdown_velocity=v))
    for step in plan.swings:
        swing = plan.swing_trajectory(step)
        x0, dx0, ddx0 = swing.sample(step.lift_off)
        x1, dx1, ddx1 = swing.sample(step.touch_down)
        np.testing.assert_allclose(x0, [*swing.start.position, swing.start.yaw], atol=1e-12)
        np.testing.assert_allclose(x1, [*step.position, step.yaw], atol=1e-12)
        for a in (dx0, ddx0, ddx1):
            np.testing.assert_allclose(a, 0.0, atol=1e-12)
        # it reaches its footstep moving straight down at v
        np.testing.assert_allclose(dx1, [0.0, 0.0, -v, 0.0], atol=1e-12)
        # the landing term keeps the foot above the path it would take landing at rest
        for s in np.linspace(0.01, 0.99, 25):
            t = step.lift_off + s * (step.touch_down - step.lift_off)
            at_rest = SwingTrajectory(swing.start, step, plan.timing.swing_height).sample(t)
            assert swing.sample(t)[0][2] > at_rest[0][2]
        # its derivatives are those of its path (central differences)
        h = 1e-6
        for t in np.linspace(step.lift_off + 0.01, step.touch_down - 0.01, 7):
            (xa, _, _), (xb, _, _) = swing.sample(t - h), swing.sample(t + h)
            x, dx, ddx = swing.sample(t)
            np.testing.assert_allclose(dx, (xb - xa) / (2 * h), atol=1e-7)
            (_, da, _), (_, db, _) = swing.sample(t - h), swing.sample(t + h)
            np.testing.assert_allclose(ddx, (db - da) / (2 * h), atol=1e-5)
        # past its touchdown time it goes on down at v for `double` seconds, then holds
        foot = plan.foot_trajectory(step.foot)
        late = step.touch_down + 0.03
        x, dx, ddx = foot.sample(late)
        np.testing.assert_allclose(x[[0, 1, 3]], np.array([*step.position, step.yaw])[[0, 1, 3]])
        assert x[2] == pytest.approx(step.position[2] - v * 0.03, abs=1e-12)
        np.testing.assert_allclose(dx, [0.0, 0.0, -v, 0.0], atol=1e-12)
        np.testing.assert_allclose(ddx, 0.0, atol=1e-12)
        after = swing.sample(step.touch_down + plan.timing.double + 0.01)
        assert after[0][2] == pytest.approx(step.position[2] - v * plan.timing.double)
        np.testing.assert_allclose(after[1], 0.0, atol=1e-12)
    # the timing reads back from plain data
    back = WalkPlan.from_dict(json.loads(json.dumps(plan.to_dict())))
    assert back.timing.touchdown_velocity == v


def test_footsteps_of_a_straight_and_a_turning_walk() -> None:
    straight = footsteps_from_walk(START, "l_sole", 5, 0.25)
    assert [f for f, _, _ in straight] == ["l_sole", "r_sole", "l_sole", "r_sole", "l_sole"]
    xs = [p[0] for _, p, _ in straight]
    np.testing.assert_allclose(xs, [0.25, 0.5, 0.75, 1.0, 1.0])  # the last step closes
    np.testing.assert_allclose([abs(p[1]) for _, p, _ in straight], 0.1)
    turning = footsteps_from_walk(START, "l_sole", 5, 0.2, turn=0.1)
    assert turning[-1][2] == pytest.approx(0.4)  # four turning steps, the closing one straight
    # the closing pair stands level across the path, at the stance width
    (_, a, yaw), (_, b, _) = turning[-2], turning[-1]
    across = np.array(a[:2]) - np.array(b[:2])
    assert np.linalg.norm(across) == pytest.approx(0.2)
    assert np.dot(across, [math.cos(yaw), math.sin(yaw)]) == pytest.approx(0.0, abs=1e-12)


def test_the_plan_reads_back_from_plain_data() -> None:
    plan = walk(0.15)
    data = json.loads(json.dumps(plan.to_dict()))
    back = WalkPlan.from_dict(data)
    assert back.schedule() == plan.schedule()
    for t in np.linspace(0.0, plan.duration, 50):
        np.testing.assert_array_equal(back.com(t)[0], plan.com(t)[0])


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: footsteps_from_walk(START, "l_sole", 1, 0.2), "at least 2 steps"),
        (lambda: footsteps_from_walk(START, "foot", 4, 0.2), "first must be one of"),
        (
            lambda: plan_walk(START, [("l_sole", (0, 0, 0), 0), ("l_sole", (0, 0, 0), 0)], COM),
            "feet must alternate, but 'l_sole' steps twice in a row",
        ),
        (lambda: WalkTiming(unload=0.5, double=0.2), "unload must be > 0 and at most double"),
        (lambda: WalkTiming(single=0.0), "single must be > 0 s"),
        (
            lambda: WalkTiming(touchdown_velocity=-0.1),
            "touchdown_velocity must be ≥ 0 m/s \\(a downward speed\\), got -0.1",
        ),
    ],
)
def test_bad_walks_say_what_is_wrong(make: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()  # type: ignore[operator]


def test_the_top_view_draws_every_footprint() -> None:
    plan = walk(0.1)
    fig = walk_figure(plan, measured={"CoM": np.zeros((3, 2))})
    ax = fig.axes[0]
    assert len(ax.patches) == len(plan.footsteps)
    labels = ax.get_legend_handles_labels()[1]
    assert {"ZMP (plan)", "DCM (plan)", "CoM (plan)", "CoM (run)"} <= set(labels)


@pytest.mark.parametrize(("slowest", "scale"), [(900.0, "linear"), (90_000.0, "log")])
def test_the_phase_figure_draws_each_runs_medians_p99s_and_the_deadline(
    slowest: float, scale: str
) -> None:
    medians = {"a": (700.0, 650.0, 800.0), "b": (slowest, 600.0, 750.0)}
    phases = pd.DataFrame(
        [
            {
                "scenario": "tocabi_walk",
                "controller": c,
                "solver": "daqp",
                "impl": "python",
                "phase": phase,
                "median [µs]": m,
                "p99 [µs]": 2 * m,
                "deadline [µs]": 1000.0,
            }
            for c, ms in medians.items()
            for phase, m in zip(("double", "single", "transition"), ms, strict=True)
        ]
    )
    ax = walk_phase_figure(phases).axes[0]
    # one bar per run and phase, grouped by phase, each as high as its median
    heights = [bar.get_height() for bar in ax.patches]
    assert heights == [700.0, slowest, 650.0, 600.0, 800.0, 750.0]
    assert [label.get_text() for label in ax.get_xticklabels()] == [
        "a × daqp\n(python, tocabi_walk)",
        "b × daqp\n(python, tocabi_walk)",
    ]
    p99 = [list(m.get_ydata()) for m in ax.get_lines() if m.get_marker() == "v"]
    assert [y for y in p99 if y] == [[1400.0, 2 * slowest], [1300.0, 1200.0], [1600.0, 1500.0]]
    assert any(list(line.get_ydata()) == [1000.0, 1000.0] for line in ax.get_lines())
    assert ax.get_yscale() == scale


def test_a_walk_figure_shows_the_run_that_got_furthest() -> None:
    """A walk that failed at 2.05 s is shown before the 0.5 s checks that stood still; among
    runs of equal length, an ok one before a fall."""
    import pandas as pd

    from wbcbench.report.plots import _walk_run

    runs = pd.DataFrame(
        {
            "run_id": ["check", "walk", "fell", "whole"],
            "status": ["ok", "failed", "fell", "ok"],
            "sim_duration_s": [0.5, 2.052, 0.5, 0.5],
        }
    )
    assert _walk_run(runs)["run_id"] == "walk"
    assert _walk_run(runs.iloc[[2, 0]])["run_id"] == "check"
