"""A short walk in closed loop: the feet lift off and land on schedule and the run ends ok (the
weighted QP in both impls, the native ticks of the hierarchies and the OSF controllers, which
follow a contact set); a
touchdown the simulated foot never confirms ends the run with a message naming it."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbcbench import _native
from wbcbench.robots.loader import third_party_robots
from wbcbench.runs import plan_run
from wbcbench.sim.closed_loop import run_closed_loop

#: two steps on a quick timing at 500 Hz: lift-offs at 0.5 and 1.0 s, touchdowns at 0.9 and
#: 1.4 s, at rest by 1.8 s
SHORT = [
    "walk.steps=2",
    "walk.start=0.4",
    "walk.double=0.1",
    "walk.single=0.4",
    "walk.end=0.3",
    "walk.unload=0.05",
    "duration=1.8",
    "control_rate=500",
    "metrics.window=[0, 1.8]",
]


#: two steps of G1's own timing at 500 Hz, shorter holds: touchdowns at 1.6 and 2.6 s
G1_SHORT = [
    "walk.steps=2",
    "walk.start=0.6",
    "walk.end=0.5",
    "initial.settle=0.2",
    "duration=3.3",
    "control_rate=500",
    "metrics.window=[0, 3.3]",
]
MISSING = {name: dist for name, dist in third_party_robots().items() if dist}

#: (controller, impl): the weighted QP in both impls, the hierarchies and the OSF controllers
#: natively
WALKERS = [
    ("qp_wbc", "python"),
    ("qp_wbc", "native"),
    ("hqp", "native"),
    ("lqp", "native"),
    ("to_osf", "native"),
    ("osf_hqp", "native"),
    ("rc_lqp", "native"),
]


@pytest.mark.parametrize(("controller", "impl"), WALKERS)
def test_a_short_walk_lands_every_step(controller: str, impl: str) -> None:
    if impl == "native" and not _native.BUILT:
        pytest.skip(f"native module {_native.REASON}")
    run = plan_run("tocabi_walk", controller, "daqp", config={"impl": impl}, overrides=SHORT)
    assert run.impl == impl
    result = run_closed_loop(run)
    assert result.status == "ok", result.message
    log = result.log.arrays()
    assert log["touchdowns"][-1] == 2
    # the swing foot is released in single support and held again after touchdown
    t = log["t"]
    assert log["active.l_sole"][(t > 0.55) & (t < 0.85)].max() == 0
    assert log["active.l_sole"][t > 1.0].min() > 0
    # the inactive contact's predicted wrench is zero, the unloading one's ramps down
    fz = log["wrench_pred.l_sole.fz"]
    assert np.abs(fz[(t > 0.55) & (t < 0.85)]).max() == 0
    weight = pin.computeTotalMass(result.robot.pin_model) * 9.81
    ramp = (t >= 0.45) & (t < 0.5)
    assert np.all(fz[ramp] <= (0.5 - t[ramp]) / 0.05 * weight * (1 + 1e-6) + 1e-6)
    assert result.walk is not None and len(result.walk["footsteps"]) == 4
    # the CoM follows the plan
    assert np.mean(log["err.com.pos"]) < 5e-3


def test_a_touchdown_that_never_happens_ends_the_run() -> None:
    run = plan_run("tocabi_walk", "qp_wbc", "daqp", overrides=[*SHORT, "sim.touchdown_load=5000"])
    result = run_closed_loop(run)
    assert result.status == "failed"
    assert result.message.startswith(
        "the touchdown of contact 'l_sole' scheduled at t = 0.900 s did not happen: its foot "
        "carried less than 5000 N until t = 0.952 s (sim.touchdown_tolerance = 0.05 s)"
    ), result.message


def test_a_foot_that_lands_at_rest_on_the_floor_never_carries_load() -> None:
    # G1 starts grounded: its soles' frames are at the floor's surface, and so are its
    # footsteps; a swing that comes to rest there touches without pressing. Landing at
    # walk.touchdown_velocity (the scenario's 0.05 m/s) presses the foot on the floor at its
    # touchdown time.
    if "g1" in MISSING:
        pytest.skip(f"g1: {MISSING['g1']} is not installed (wbcbench[robots])")
    at_rest = [*G1_SHORT, "walk.touchdown_velocity=0"]
    result = run_closed_loop(plan_run("g1_walk", "qp_wbc", "daqp", overrides=at_rest))
    assert result.status == "failed"
    assert result.message.startswith(
        "the touchdown of contact 'l_sole' scheduled at t = 1.600 s did not happen"
    ), result.message
    moving = run_closed_loop(plan_run("g1_walk", "qp_wbc", "daqp", overrides=G1_SHORT))
    assert moving.status == "ok", moving.message
    log = moving.log.arrays()
    assert log["touchdowns"][-1] == 2
    landings = moving.walk["landings"] if moving.walk else []
    # each foot lands within a tick of its touchdown time, within 1 mm of its footstep
    assert [round(landing["t"], 3) for landing in landings] == [1.602, 2.602]
    assert max(landing["error"] for landing in landings) < 1e-3


def test_a_stored_walk_has_its_metrics_table_and_figure(tmp_path) -> None:
    from wbcbench.bench.results import ResultsStore
    from wbcbench.bench.runner import compute_tracking, store_record
    from wbcbench.report.load import load_results
    from wbcbench.report.plots import walk_figures
    from wbcbench.report.tables import TABLES

    run = plan_run("tocabi_walk", "qp_wbc", "daqp", overrides=SHORT)
    record = compute_tracking(run, "walk-run", "test")
    assert record.row["status"] == "ok", record.row["message"]
    store_record(ResultsStore(tmp_path), run, record)
    res = load_results(tmp_path)
    metric = res.metrics.set_index("metric")["value"]
    # the measured DCM follows the plan's; the CoP margin is the CoP check's violation seen from
    # inside (the same ticks: settled and loaded), here within 1 mm of the edge at worst
    assert 0 < metric["dcm_error_mean"] < 0.02
    assert metric["dcm_error_max"] >= metric["dcm_error_mean"]
    assert -1e-3 < metric["cop_margin_min"] < metric["cop_margin_mean"] < 0.1
    assert max(0.0, -metric["cop_margin_min"]) == metric["cop_violation_sim"]
    # the soles hold: a few mm of soft-contact creep at most
    assert 0 <= metric["slip_max"] < 5e-3
    # a landing's error splits into its horizontal and vertical parts
    landings = record.walk["landings"] if record.walk else []
    assert len(landings) == 2 and set(record.walk or {}) >= {"soles", "footsteps"}
    for landing in landings:
        assert np.hypot(landing["error_xy"], landing["error_z"]) == np.float64(landing["error"])
    assert metric["landing_error_max"] == max(landing["error"] for landing in landings)

    table = TABLES["walking"](res)
    assert table.frame is not None and len(table.frame) == 1
    row = table.frame.iloc[0]
    assert (row["robot"], row["controller"], row["steps"], row["status"]) == (
        "tocabi_like",
        "qp_wbc",
        "2/2",
        "ok",
    )
    # the plan the run followed is kept with its log, and the figure draws it with the run
    assert json_plan_equal(res.log("walk-run").attrs["walk"], record.walk)
    (tmp_path / "figures").mkdir()
    written = walk_figures(res, tmp_path / "figures")
    assert [p.name for p in written] == ["walk_tocabi_walk.png", "walk_tocabi_walk.svg"]


def json_plan_equal(text: str, walk: dict | None) -> bool:
    import json

    return json.loads(text) == json.loads(json.dumps(walk))
