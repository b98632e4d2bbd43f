"""Scenario validation: every bad input gives one error naming the file and the key path."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from wbcbench.cli import main
from wbcbench.errors import ScenarioError
from wbcbench.robots.loader import load_robot, third_party_robots
from wbcbench.robots.third_party import THIRD_PARTY
from wbcbench.runs import check_scenario
from wbcbench.scenarios.load import (
    SCENARIO_DIR,
    available_scenarios,
    load_scenario,
    load_scenario_robot,
)

BASE = SCENARIO_DIR / "tocabi_stand_sway.yaml"


def variant(tmp_path: Path, old: str, new: str, name: str = "bad.yaml") -> Path:
    text = BASE.read_text()
    assert old in text, old
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return path


def error_of(path: Path, overrides: tuple[str, ...] = ()) -> str:
    with pytest.raises(ScenarioError) as exc:
        loaded = load_scenario(path, overrides)
        check_scenario(loaded, load_robot(loaded.spec.robot))
    return str(exc.value)


@pytest.mark.parametrize("name", available_scenarios())
def test_shipped_scenarios_validate(name: str) -> None:
    loaded = load_scenario(name)
    missing = third_party_robots().get(loaded.spec.robot)
    if missing:
        extra = THIRD_PARTY[loaded.spec.robot].extra
        pytest.skip(f"{loaded.spec.robot}: {missing} is not installed (wbcbench[{extra}])")
    # the robot as a run loads it: with the scenario's own frames (a sole plane) added
    check_scenario(loaded, load_scenario_robot(loaded))
    assert len(loaded.hash) == 12


def test_unknown_key(tmp_path: Path) -> None:
    path = variant(tmp_path, "duration: 10.0", "duration: 10.0\ndurration: 3")
    assert error_of(path) == (
        f"{path}: durration: unknown key 'durration'; valid keys: contacts, control_rate, "
        "controllers, description, duration, environment, frames, initial, kind, limits, metrics, "
        "name, package_dirs, perturbations, reconstruction, reproduces, robot, sim, tasks, "
        "version, walk"
    )


def test_unknown_key_inside_a_task(tmp_path: Path) -> None:
    path = variant(tmp_path, "  - name: pelvis\n", "  - name: pelvis\n    gain: 3\n")
    assert error_of(path) == (
        f"{path}: tasks[1].gain: unknown key 'gain'; valid keys: absolute, axes, frame, joints, "
        "kp, kv, level, name, priority, reference, type, weight"
    )


def test_unknown_task_type(tmp_path: Path) -> None:
    path = variant(tmp_path, "type: com\n", "type: centre_of_mass\n")
    assert error_of(path) == (
        f"{path}: tasks[0].type: invalid value 'centre_of_mass'; valid choices: 'com', "
        "'frame_position', 'frame_orientation', 'frame_pose', 'joint_posture' or 'joint_damping'"
    )


def test_frame_the_robot_lacks(tmp_path: Path) -> None:
    path = variant(tmp_path, "frame: l_hand", "frame: l_hnd")
    message = error_of(path)
    assert message.startswith(f"{path}: tasks[3].frame: unknown frame 'l_hnd'; valid choices: ")
    assert "l_hand" in message and "r_sole" in message


def test_contact_frame_the_robot_lacks(tmp_path: Path) -> None:
    path = variant(tmp_path, "frame: l_sole", "frame: left_foot")
    assert error_of(path).startswith(f"{path}: contacts[0].frame: unknown frame 'left_foot'")


def test_trajectory_of_the_wrong_dimension(tmp_path: Path) -> None:
    path = variant(tmp_path, "amplitude: [0.025, 0.0, 0.0]", "amplitude: [0.025, 0.0]")
    assert error_of(path) == (
        f"{path}: tasks[0].reference.amplitude: expected 3 values (one per axis x, y, z), got 2"
    )


def test_trajectory_with_reversed_times(tmp_path: Path) -> None:
    path = variant(tmp_path, "t0: 2.0, t1: 6.0", "t0: 6.0, t1: 2.0")
    assert error_of(path) == f"{path}: tasks[0].reference: t1 (2.0) must be greater than t0 (6.0)"


def test_unknown_trajectory_type(tmp_path: Path) -> None:
    path = variant(tmp_path, "type: spline_there_and_back", "type: spline")
    assert error_of(path) == (
        f"{path}: tasks[0].reference: unknown type 'spline'; valid choices: 'constant', "
        "'sinusoid', 'spline_there_and_back', 'min_jerk', 'piecewise'"
    )


def test_axes_invalid_for_the_task_type(tmp_path: Path) -> None:
    path = variant(tmp_path, "    frame: pelvis\n", "    frame: pelvis\n    axes: [x]\n")
    assert error_of(path) == (
        f"{path}: tasks[1]: axes ['x'] invalid for frame_orientation; valid choices: rx, ry, rz "
        "(each at most once)"
    )


def test_controller_settings_are_validated(tmp_path: Path) -> None:
    assert error_of(BASE, ("controllers.qp_wbc.wieghts=[1, 2]",)) == (
        f"{BASE}: controllers.qp_wbc.wieghts: unknown key 'wieghts'; valid keys: "
        "acceleration_weight, impl, solver_calls, torque_weight, variables, weights, wrench_weight"
    )
    assert error_of(BASE, ("controllers.qp_wbc.variables=half",)) == (
        f"{BASE}: controllers.qp_wbc.variables: invalid value 'half'; valid choices: 'full' or "
        "'eliminated'"
    )


def test_overrides_are_validated_like_the_file() -> None:
    assert error_of(BASE, ("duration=-1",)) == f"{BASE}: duration: Input should be greater than 0"
    assert error_of(BASE, ("tasks.9.kp=3",)) == (
        f"{BASE}: tasks.9: index '9' out of range (the list has 6 items)"
    )
    loaded = load_scenario(BASE, ("duration=3", "tasks.0.kp=50"))
    assert loaded.spec.duration == 3.0
    assert loaded.spec.tasks[0].kp == 50
    assert loaded.hash != load_scenario(BASE).hash


def test_cli_prints_one_line_and_no_traceback(tmp_path: Path, capsys) -> None:
    path = variant(tmp_path, "type: com\n", "type: comm\n")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {path}: tasks[0].type:")
    assert main(["run", str(BASE), "--solver", "nosuch"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: unknown solver 'nosuch'; valid choices: ")
    assert "proxqp" in err and "osqp" in err and "Traceback" not in err


def test_cli_subprocess_has_no_traceback(tmp_path: Path) -> None:
    path = variant(tmp_path, "frame: l_hand", "frame: l_hnd")
    proc = subprocess.run(
        [sys.executable, "-m", "wbcbench.cli", "validate", str(path)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"error: {path}: tasks[3].frame: unknown frame 'l_hnd'")


def test_a_contact_without_cop_on_a_frame_with_no_sole_size(tmp_path: Path) -> None:
    path = variant(
        tmp_path, "  - {frame: r_sole, mu: 0.5, fmin: 30}\n",
        "  - {frame: r_sole, mu: 0.5, fmin: 30}\n  - {frame: l_hand, mu: 0.5, fmin: 5}\n",
    )  # fmt: skip
    assert error_of(path).startswith(
        f"{path}: contacts[2].cop: the robot has no sole size for frame 'l_hand'"
    )


def test_a_shorter_duration_override_moves_the_window_inside_the_run() -> None:
    assert load_scenario(BASE).spec.metrics.window == (1.0, 9.0)
    assert load_scenario(BASE, ("duration=3",)).spec.metrics.window == (1.0, 3.0)
    assert load_scenario(BASE, ("duration=0.5",)).spec.metrics.window == (0.25, 0.5)
    # an explicit window is the user's: checked, not moved
    msg = error_of(BASE, ("duration=0.5", "metrics.window=[1, 9]"))
    assert msg == f"{BASE}: metrics.window: ends at 9 s, after the duration of 0.5 s"


def test_impl_choices_are_named(tmp_path: Path) -> None:
    assert error_of(BASE, ("controllers.qp_wbc.impl=fast",)) == (
        f"{BASE}: controllers.qp_wbc.impl: invalid value 'fast'; valid choices: 'native' or "
        "'python'"
    )
    assert error_of(BASE, ("controllers.kin_hqp.impl=fast",)) == (
        f"{BASE}: controllers.kin_hqp.impl: invalid value 'fast'; valid choices: 'native' or "
        "'python'"
    )


def test_the_readme_scenario_example_validates(tmp_path: Path) -> None:
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    section = readme[readme.index("## Scenarios") :]
    start = section.index("```yaml\n") + len("```yaml\n")
    example = tmp_path / "example.yaml"
    example.write_text(section[start : section.index("```", start)])
    loaded = load_scenario(example)
    check_scenario(loaded, load_scenario_robot(loaded))
    assert loaded.spec.robot == "tocabi_like" and len(loaded.spec.contacts) == 2


def test_validate_warns_when_the_sole_box_is_not_under_the_foot(tmp_path: Path, capsys) -> None:
    from wbcbench.cli import main

    path = variant(
        tmp_path,
        "  - {frame: l_sole, mu: 0.5, fmin: 30}",
        "  - {frame: l_sole, mu: 0.5, fmin: 30, cop: {x: [0.2, 0.4], y: [-0.05, 0.05]}}",
        "shifted.yaml",
    )
    assert main(["validate", str(path)]) == 0
    warnings = [line for line in capsys.readouterr().out.splitlines() if "warning:" in line]
    assert warnings == [
        "    warning: contacts[0] ('l_sole') at the initial posture: the sole box's centre "
        "(300, 0) mm lies 150 mm outside the footprint of the foot's geometry (its points "
        "within 5 mm of its lowest): the controllers' CoP limits are not under the simulated "
        "foot; give the contact's 'cop' in its frame, or 'contact_geometry: box'"
    ]
    assert main(["validate", str(BASE)]) == 0
    assert "warning:" not in capsys.readouterr().out


def test_contact_geometry_box_needs_a_frame_of_the_simulated_model(tmp_path: Path) -> None:
    path = variant(
        tmp_path,
        "  - {frame: l_sole, mu: 0.5, fmin: 30}",
        "  - {frame: l_sole, mu: 0.5, fmin: 30, contact_geometry: box}",
    )
    loaded = load_scenario(path)
    check_scenario(loaded, load_robot(loaded.spec.robot))  # l_sole is a site: accepted
    bad = tmp_path / "boxes.yaml"
    bad.write_text(path.read_text().replace("contact_geometry: box", "contact_geometry: boxes"))
    assert error_of(bad) == (
        f"{bad}: contacts[0].contact_geometry: invalid value 'boxes'; valid choices: 'model' or "
        "'box'"
    )


def test_self_collision_exclude_list(tmp_path: Path) -> None:
    """{exclude: [[a, b], …]} simulates every self-contact but those pairs'; names are checked."""
    from wbcbench.sim.closed_loop import prepare_model

    loaded = load_scenario(BASE, ("sim.self_collision={exclude: [[L_Knee_link, R_Knee_link]]}",))
    robot = load_robot(loaded.spec.robot)
    check_scenario(loaded, robot)
    model = prepare_model(robot, loaded)
    assert model.nexclude == robot.mj_model.nexclude + 1
    pair = {model.body(int(model.exclude_signature[-1]) >> 16).name,
            model.body(int(model.exclude_signature[-1]) & 0xFFFF).name}  # fmt: skip
    assert pair == {"L_Knee_link", "R_Knee_link"}
    assert error_of(BASE, ("sim.self_collision={exclude: [[L_Knee, R_Knee_link]]}",)).startswith(
        f"{BASE}: sim.self_collision.exclude[0][0]: unknown body 'L_Knee'; valid choices: "
    )
    assert error_of(BASE, ("sim.self_collision={exclude: [[L_Knee_link]]}",)) == (
        f"{BASE}: sim.self_collision.exclude: item 0: a pair [body, body], got 1 names: "
        "['L_Knee_link']"
    )
    assert error_of(BASE, ("sim.self_collision=3",)) == (
        f"{BASE}: sim.self_collision: expected true, false or {{exclude: [[body, body], …]}}, got 3"
    )


def test_a_key_given_twice_names_both_lines(tmp_path: Path) -> None:
    path = variant(tmp_path, "duration: 10.0\n", "duration: 10.0\nduration: 3\n")
    assert error_of(path) == (
        f"{path}: not valid YAML at line 9, column 1: duplicate key 'duration' (first at line 8)"
    )


def test_a_boolean_where_a_number_is_expected(tmp_path: Path) -> None:
    path = variant(tmp_path, "duration: 10.0", "duration: true")
    assert error_of(path) == f"{path}: duration: expected a number, got the boolean true"
    path = variant(tmp_path, "amplitude: [0.025, 0.0, 0.0]", "amplitude: [0.025, false, 0.0]")
    assert error_of(path) == (
        f"{path}: tasks[0].reference.amplitude[1]: expected a number, got the boolean false"
    )


def test_a_missing_file_or_a_folder_is_no_such_file(tmp_path: Path) -> None:
    missing = tmp_path / "nope.yaml"
    assert error_of(missing) == f"{missing}: no such file"
    assert error_of(tmp_path) == f"{tmp_path}: no such file: a folder, not a scenario file"


def test_a_reference_without_type_lists_the_types(tmp_path: Path) -> None:
    path = variant(tmp_path, "type: spline_there_and_back, ", "")
    assert error_of(path) == (
        f"{path}: tasks[0].reference: required key 'type' is missing; valid types: constant, "
        "sinusoid, spline_there_and_back, min_jerk, piecewise"
    )


def test_priorities_are_whole_numbers_up_to_a_bound() -> None:
    assert error_of(BASE, ("tasks.0.priority=1.0e+30",)) == (
        f"{BASE}: tasks[0].priority: Input should be a valid integer"
    )
    assert error_of(BASE, ("tasks.0.priority=1001",)) == (
        f"{BASE}: tasks[0].priority: Input should be less than or equal to 1000"
    )


def test_a_dynamic_scenario_without_contacts() -> None:
    assert error_of(BASE, ("contacts=[]",)) == (
        f"{BASE}: contacts: a dynamic scenario needs at least one contact: the torque-level "
        "controllers hold the floating base on its contacts (a robot with none, or a fixed "
        "base, is not supported)"
    )


def test_joint_lists_are_not_empty_and_name_each_joint_once() -> None:
    assert error_of(BASE, ("tasks.5.joints=[]",)) == (
        f"{BASE}: tasks[5].joints: an empty list; name at least one joint, or leave 'joints' out"
    )
    twice = ("tasks.5.joints=[l_knee, r_knee, l_knee]",)
    assert error_of(BASE, twice) == (
        f"{BASE}: tasks[5].joints: each joint at most once; repeated: l_knee"
    )


def test_speed_limits_are_positive() -> None:
    assert error_of(BASE, ("controllers.kin_hqp.speed_limits.hand=-1.0",)) == (
        f"{BASE}: controllers.kin_hqp.speed_limits.hand: Input should be greater than 0"
    )
