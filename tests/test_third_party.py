"""The third-party robots (example-robot-data, icub-models): loaded by name, validated and run
unchanged.

Skipped, with the reason, when the optional extra is not installed (`wbcbench[robots]`,
`wbcbench[icub]`).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import wbcbench
from wbcbench.controllers.registry import CONTROLLERS
from wbcbench.errors import ModelError
from wbcbench.robots.loader import SOLE_BOX_HEIGHT, load_robot, third_party_robots
from wbcbench.robots.third_party import THIRD_PARTY
from wbcbench.runs import check_scenario, plan_run
from wbcbench.scenarios.initial import initial_state
from wbcbench.scenarios.load import load_scenario, load_scenario_robot
from wbcbench.sim.closed_loop import RunResult, prepare_model, run_closed_loop

MISSING = {name: dist for name, dist in third_party_robots().items() if dist}
SCENARIOS = {
    "talos": "talos_stand_sway",
    "talos_mesh": "talos_mesh_stand_sway",
    "g1": "g1_stand_sway",
    "icub": "icub_stand_sway",
}
TORQUE_CONTROLLERS = sorted(
    name for name, cls in CONTROLLERS.items() if getattr(cls, "kind", "torque") == "torque"
)


def why_missing(name: str) -> str:
    return f"{name}: {MISSING.get(name)} is not installed (wbcbench[{THIRD_PARTY[name].extra}])"


def needs(name: str) -> pytest.MarkDecorator:
    return pytest.mark.skipif(name in MISSING, reason=why_missing(name))


@pytest.mark.parametrize("name", sorted(THIRD_PARTY))
def test_third_party_robot_loads_unchanged(name: str) -> None:
    if name in MISSING:
        with pytest.raises(ModelError, match=r"is not installed: pip install"):
            load_robot(name)
        pytest.skip(why_missing(name))
    robot = load_robot(name)
    info = THIRD_PARTY[name].info
    for frame in (*info.contact_frames, *info.hand_frames, info.base_body, info.torso_body):
        assert frame is not None and robot.has_frame(frame), frame
    assert any(
        n.startswith("the file has no floor: a plane at z = 0 was added") for n in robot.notes
    )


@needs("talos")
def test_talos_mimic_joints_are_fixed() -> None:
    robot = load_robot("talos")
    assert robot.k == 32
    assert set(robot.mimic_joints.values()) == {"gripper_left_joint", "gripper_right_joint"}
    assert len(robot.mimic_joints) == 12


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenario_validates_and_stands(name: str) -> None:
    if name in MISSING:
        pytest.skip(why_missing(name))
    loaded = load_scenario(SCENARIOS[name], ("duration=0.3",))
    check_scenario(loaded, load_scenario_robot(loaded))
    result = run_closed_loop(plan_run(loaded, controller="qp_wbc", solver="proxqp"))
    assert result.status == "ok", result.message
    assert result.failures == 0


@pytest.mark.slow
@pytest.mark.parametrize("controller", TORQUE_CONTROLLERS)
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_torque_controller_holds_the_robot(name: str, controller: str) -> None:
    if name in MISSING:
        pytest.skip(why_missing(name))
    loaded = load_scenario(SCENARIOS[name], ("duration=1",))
    result = run_closed_loop(plan_run(loaded, controller=controller, solver="daqp"))
    assert not result.fell, result.message


@needs("talos_mesh")
def test_contact_geometry_box_replaces_the_mesh_feet() -> None:
    """TALOS' mesh feet become their sole boxes in the simulation: the meshes collide with
    nothing, each box lies flat at its sole frame, and masses and inertias stay the file's."""
    loaded = load_scenario("talos_mesh_stand_sway")
    robot = load_scenario_robot(loaded)
    model = prepare_model(robot, loaded)
    assert (model.nq, model.nv, model.nu) == (
        robot.mj_model.nq,
        robot.mj_model.nv,
        robot.mj_model.nu,
    )
    np.testing.assert_array_equal(model.body_mass, robot.mj_model.body_mass)
    np.testing.assert_array_equal(model.body_inertia, robot.mj_model.body_inertia)
    rect = robot.info.contact_rects["left_sole_link"]
    for frame in ("left_sole_link", "right_sole_link"):
        box = model.geom(f"{frame}_sole_box")
        assert box.type == mujoco.mjtGeom.mjGEOM_BOX
        half = [(rect.x_max - rect.x_min) / 2, (rect.y_max - rect.y_min) / 2, SOLE_BOX_HEIGHT / 2]
        np.testing.assert_allclose(box.size, half)
        assert model.body(int(box.bodyid[0])).name == frame
    data = mujoco.MjData(model)
    data.qpos[:], _ = robot.pin_to_mj(*initial_state(loaded, robot))
    mujoco.mj_forward(model, data)
    touching = {model.body(int(model.geom_bodyid[c.geom2])).name for c in data.contact[: data.ncon]}
    assert touching == {"left_sole_link", "right_sole_link"}
    assert all(abs(c.dist) < 1e-3 for c in data.contact[: data.ncon])


@needs("talos_mesh")
def test_mesh_feet_need_the_sole_box_to_stand() -> None:
    """With its mesh feet TALOS slips off its heels while settling; with the sole boxes it
    stands, and the run's settings say which feet were boxes."""
    overrides = ("duration=0.3", *(f"contacts.{i}.contact_geometry=model" for i in range(2)))
    loaded = load_scenario("talos_mesh_stand_sway", overrides)
    result = run_closed_loop(plan_run(loaded, controller="lqp", solver="daqp"))
    assert result.fell
    assert "the foot is simulated with its mesh" in result.message  # and the fix is named
    assert "'contact_geometry: box'" in result.message
    loaded = load_scenario("talos_mesh_stand_sway", ("duration=0.3",))
    result = run_closed_loop(plan_run(loaded, controller="lqp", solver="daqp"))
    assert result.status == "ok" and result.failures == 0, result.message


@needs("talos")
def test_rc_lqp_row_split_on_talos_is_structural() -> None:
    """At half-sitting no chain joint turns the torso about the world x axis (its yaw is 0), so
    J N_r = 0 holds for that row there only: the row belongs to LQP 2 with the torso's other
    two, which the split finds by testing a generic posture too."""
    with wbcbench.make_controller("talos_stand_sway", "rc_lqp", solver="daqp") as ctrl:
        rows = ctrl.controller._rows
        assert rows is not None
        assert rows.lqp1["torso"].size == 0 and rows.lqp2["torso"].tolist() == [0, 1, 2]
        assert rows.lqp1["com"].tolist() == [0, 1, 2]
        assert rows.lqp1["pelvis"].tolist() == [0, 1, 2]
        legs = [i for i, j in enumerate(ctrl.robot.joint_names) if j.startswith("leg_")]
        assert len(legs) == 12 and rows.lqp1["posture"].tolist() == legs


@needs("talos")
@pytest.mark.parametrize("solver", ["proxqp", "daqp"])
def test_rc_lqp_on_talos_tracks_as_lqp_does(solver: str) -> None:
    loaded = load_scenario("talos_stand_sway", ("duration=1",))
    result = run_closed_loop(plan_run(loaded, controller="rc_lqp", solver=solver))
    assert result.status == "ok" and result.failures == 0, result.message
    log = result.log.arrays()
    for hand in ("l_hand", "r_hand"):
        assert np.mean(log[f"err.{hand}.pos"]) < 1e-4, hand


@needs("g1")
def test_validate_warns_that_g1_holds_its_ankles_above_the_sole(capsys) -> None:
    from wbcbench.cli import main

    assert main(["validate", "g1_stand_sway"]) == 0
    warnings = [line for line in capsys.readouterr().out.splitlines() if "warning:" in line]
    assert len(warnings) == 2
    assert warnings[0] == (
        "    warning: contacts[0] ('left_ankle_roll_link') at the initial posture: the foot's "
        "geometry reaches 35.0 mm below the sole plane (the contact frame's x–y plane, where "
        "the controllers put the ground): hold a frame in the sole plane, or simulate the foot "
        "as its sole box ('contact_geometry: box')"
    )


@needs("talos")
def test_validate_offers_the_exclude_list_of_talos_overlapping_bodies(capsys) -> None:
    from wbcbench.cli import main

    pairs = (
        "[leg_left_1_link, leg_left_3_link], [leg_right_1_link, leg_right_3_link], "
        "[arm_left_5_link, arm_left_7_link], [arm_right_5_link, arm_right_7_link], "
        "[base_link, torso_2_link]"
    )
    assert main(["validate", "talos_stand_sway", "--set", "sim.self_collision=true"]) == 0
    notes = [line for line in capsys.readouterr().out.splitlines() if "overlap" in line]
    assert notes == [
        "    note: at the initial posture 5 pairs of the robot's bodies overlap "
        "(leg_left_1_link–leg_left_3_link 92.8 mm, leg_right_1_link–leg_right_3_link 92.8 mm, "
        "arm_left_5_link–arm_left_7_link 44.6 mm, arm_right_5_link–arm_right_7_link 44.6 mm, "
        "base_link–torso_2_link 0.1 mm); the simulation pushes them apart: set "
        f"'sim: {{self_collision: {{exclude: [{pairs}]}}}}' to leave those pairs out, or "
        "'sim: {self_collision: false}' to simulate contacts with the world only"
    ]
    excluded = f"sim.self_collision={{exclude: [{pairs}]}}"
    assert main(["validate", "talos_stand_sway", "--set", excluded]) == 0
    assert "overlap" not in capsys.readouterr().out
    loaded = load_scenario("talos_stand_sway", ("duration=0.3", excluded))
    result = run_closed_loop(plan_run(loaded, controller="lqp", solver="daqp"))
    assert result.status == "ok" and result.failures == 0, result.message


def _icub_sway(elbow: float) -> tuple[RunResult, np.ndarray, dict[str, np.ndarray]]:
    """to_osf (DAQP) on icub_stand_sway to t = 1.5 s, past the CoM's first peak (+20 mm at
    t = 1.25 s), with both elbows starting at ``elbow`` [rad]: the result, the joint positions
    (ticks × k) and the log."""
    overrides = (
        "duration=1.5",
        f"initial.joints.l_elbow={elbow}",
        f"initial.joints.r_elbow={elbow}",
    )
    run = plan_run(load_scenario("icub_stand_sway", overrides), controller="to_osf", solver="daqp")
    q: list[np.ndarray] = []
    result = run_closed_loop(run, on_step=lambda state, out: q.append(state.q[7:].copy()))
    return result, np.array(q), result.log.arrays()


def _metric(result: RunResult, name: str) -> float:
    from wbcbench.bench.run_metrics import run_metrics

    rows = run_metrics(result, [], None, 0)
    return next(row.value for row in rows if row.metric == name)


@needs("icub")
def test_icub_sway_keeps_the_elbows_inside_their_range() -> None:
    """Holding the hands in the world while the CoM (and the shoulders with it) moves 20 mm
    back asks iCub's short arms to straighten the elbow by about 0.5 rad. From elbows at 0.8 rad
    that passes the elbow's lower limit (0.262 rad); the torque controllers know no joint
    position limit, so MuJoCo's limit stops the arm, the hands drift and the hierarchy pulls
    the chest and pelvis after them. The scenario starts the elbows at 1.2 rad: every joint
    stays inside its range and the hands and chest are held."""
    robot = load_robot("icub")
    elbows = [robot.joint_index(j) for j in ("l_elbow", "r_elbow")]
    result, q, log = _icub_sway(0.8)
    assert result.status == "ok"  # the QPs are all solved ...
    assert np.all(q[:, elbows].min(axis=0) < robot.q_min[elbows] + 1e-3)
    assert np.max(log["err.torso.rot"]) > 0.1 and np.max(log["err.l_hand.pos"]) > 0.01
    # ... but the run's log and metrics say a joint sat at its limit, and for how long
    assert np.min(log["joint_margin"]) < 1e-3
    at_limit = _metric(result, "ticks_at_joint_limit")
    assert at_limit == np.sum(log["joint_margin"] < 1e-3) > 0

    result, q, log = _icub_sway(1.2)
    assert result.status == "ok" and result.failures == 0, result.message
    margin = np.minimum(q - robot.q_min, robot.q_max - q)
    assert margin.min() > 0.02
    assert _metric(result, "ticks_at_joint_limit") == 0
    assert np.max(log["err.torso.rot"]) < 1e-3
    for hand in ("l_hand", "r_hand"):
        assert np.max(log[f"err.{hand}.pos"]) < 1e-3, hand
