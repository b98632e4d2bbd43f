"""The third-party robots (example-robot-data): loaded by name, validated and run unchanged.

Skipped, with the reason, when the optional extra is not installed (`wbcbench[robots]`).
"""

from __future__ import annotations

import pytest

from wbcbench.controllers.registry import CONTROLLERS
from wbcbench.errors import ModelError
from wbcbench.robots.loader import load_robot, third_party_robots
from wbcbench.robots.third_party import THIRD_PARTY
from wbcbench.scenarios.load import check_against_robot, load_scenario, load_scenario_robot
from wbcbench.sim.closed_loop import RunSettings, run_closed_loop

MISSING = {name: dist for name, dist in third_party_robots().items() if dist}
SCENARIOS = {"talos": "talos_stand_sway", "g1": "g1_stand_sway"}
TORQUE_CONTROLLERS = sorted(
    name for name, cls in CONTROLLERS.items() if getattr(cls, "kind", "torque") == "torque"
)


def needs(name: str) -> pytest.MarkDecorator:
    return pytest.mark.skipif(
        name in MISSING, reason=f"{name}: {MISSING.get(name)} is not installed (wbcbench[robots])"
    )


@pytest.mark.parametrize("name", sorted(THIRD_PARTY))
def test_third_party_robot_loads_unchanged(name: str) -> None:
    if name in MISSING:
        with pytest.raises(ModelError, match=r"is not installed: pip install"):
            load_robot(name)
        pytest.skip(f"{MISSING[name]} is not installed (wbcbench[robots])")
    robot = load_robot(name)
    info = THIRD_PARTY[name].info
    for frame in (*info.contact_frames, *info.hand_frames, info.base_body, info.torso_body):
        assert frame is not None and robot.has_frame(frame), frame
    assert "the file has no floor: a plane at z = 0 was added" in robot.notes


@needs("talos")
def test_talos_mimic_joints_are_fixed() -> None:
    robot = load_robot("talos")
    assert robot.k == 32
    assert set(robot.mimic_joints.values()) == {"gripper_left_joint", "gripper_right_joint"}
    assert len(robot.mimic_joints) == 12


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenario_validates_and_stands(name: str) -> None:
    if name in MISSING:
        pytest.skip(f"{MISSING[name]} is not installed (wbcbench[robots])")
    loaded = load_scenario(SCENARIOS[name], ("duration=0.3",))
    check_against_robot(loaded, load_scenario_robot(loaded))
    result = run_closed_loop(loaded, RunSettings(controller="qp_wbc", solver="proxqp"))
    assert result.status == "ok", result.message
    assert result.failures == 0


@pytest.mark.slow
@pytest.mark.parametrize("controller", TORQUE_CONTROLLERS)
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_torque_controller_holds_the_robot(name: str, controller: str) -> None:
    if name in MISSING:
        pytest.skip(f"{MISSING[name]} is not installed (wbcbench[robots])")
    # DAQP: with ProxQP one rc_lqp solve on TALOS can run for minutes (README, known limitations)
    loaded = load_scenario(SCENARIOS[name], ("duration=1",))
    result = run_closed_loop(loaded, RunSettings(controller=controller, solver="daqp"))
    assert not result.fell, result.message
