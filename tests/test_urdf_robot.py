"""A humanoid as a researcher brings it: a URDF with package:// mesh paths, sole links with no
geometry and a mimic joint, and a scenario that starts from a joint map. No hand edits."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from wbcbench.cli import main
from wbcbench.errors import ModelError, ScenarioError
from wbcbench.robots.loader import load_robot
from wbcbench.runs import check_scenario, plan_run
from wbcbench.scenarios.initial import initial_state
from wbcbench.scenarios.load import load_scenario, load_scenario_robot
from wbcbench.sim.closed_loop import ContactSensor, run_closed_loop

_INERTIA = '<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/>'


def _link(name: str, mass: float, inertia: float, geometry: str = "", com: str = "0 0 0") -> str:
    collision = (
        f'<collision><origin xyz="{com}"/><geometry>{geometry}</geometry></collision>'
        if geometry
        else ""
    )
    return (
        f'<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{mass}"/>'
        f"{_INERTIA.format(i=inertia)}</inertial>{collision}</link>"
    )


def _joint(name: str, parent: str, child: str, xyz: str, axis: str, effort: float = 150) -> str:
    return (
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>'
        f'<limit lower="-2" upper="2" effort="{effort}" velocity="10"/></joint>'
    )


def _leg(s: str, y: float) -> str:
    foot = '<box size="0.2 0.1 0.04"/>'
    return "".join(
        [
            _link(f"{s}_hip", 1.0, 0.002),
            _link(f"{s}_thigh", 3.0, 0.02, com="0 0 -0.15"),
            _link(f"{s}_shank", 2.0, 0.015, com="0 0 -0.15"),
            _link(f"{s}_ankle", 0.5, 0.001),
            _link(f"{s}_foot", 1.0, 0.003, foot, com="0.02 0 -0.03"),  # box from z = -0.05 up
            f'<link name="{s}_sole"/>',
            _joint(f"{s}_hip_roll", "pelvis", f"{s}_hip", f"0 {y} -0.05", "1 0 0"),
            _joint(f"{s}_hip_pitch", f"{s}_hip", f"{s}_thigh", "0 0 0", "0 1 0"),
            _joint(f"{s}_knee", f"{s}_thigh", f"{s}_shank", "0 0 -0.3", "0 1 0"),
            _joint(f"{s}_ankle_pitch", f"{s}_shank", f"{s}_ankle", "0 0 -0.3", "0 1 0"),
            _joint(f"{s}_ankle_roll", f"{s}_ankle", f"{s}_foot", "0 0 0", "1 0 0"),
            f'<joint name="{s}_sole_fixed" type="fixed"><parent link="{s}_foot"/>'
            f'<child link="{s}_sole"/><origin xyz="0.02 0 -0.05"/></joint>',
        ]
    )


def write_humanoid(folder: Path) -> Path:
    """A 10-DoF biped with a one-finger gripper whose second finger mimics the first.

    The pelvis' visual mesh is a ``package://mini_description/…`` path to an STL written under
    ``folder/packages``; the soles are fixed links with no geometry under box feet.
    """
    meshes = folder / "packages" / "mini_description" / "meshes"
    meshes.mkdir(parents=True)
    (meshes / "pelvis.stl").write_text(
        "solid t\n"
        + "".join(
            f"facet normal 0 0 0\nouter loop\n{a}\n{b}\n{c}\nendloop\nendfacet\n"
            for a, b, c in [
                ("vertex 0 0 0", "vertex 0.1 0 0", "vertex 0 0.1 0"),
                ("vertex 0 0 0", "vertex 0 0.1 0", "vertex 0 0 0.1"),
                ("vertex 0 0 0", "vertex 0 0 0.1", "vertex 0.1 0 0"),
                ("vertex 0.1 0 0", "vertex 0 0 0.1", "vertex 0 0.1 0"),
            ]
        )
        + "endsolid t\n"
    )
    pelvis = (
        '<link name="pelvis"><inertial><mass value="10"/>'
        f"{_INERTIA.format(i=0.1)}</inertial>"
        '<visual><geometry><mesh filename="package://mini_description/meshes/pelvis.stl"/>'
        "</geometry></visual>"
        '<collision><origin xyz="0 0 0.1"/><geometry><box size="0.2 0.3 0.2"/></geometry>'
        "</collision></link>"
    )
    gripper = "".join(
        [
            _link("finger_a", 0.05, 1e-5),
            _link("finger_b", 0.05, 1e-5),
            _joint("finger_a_joint", "pelvis", "finger_a", "0.1 0 0.2", "0 0 1", 5),
            '<joint name="finger_b_joint" type="revolute"><parent link="pelvis"/>'
            '<child link="finger_b"/><origin xyz="0.1 0 0.25"/><axis xyz="0 0 1"/>'
            '<limit lower="-2" upper="2" effort="5" velocity="10"/>'
            '<mimic joint="finger_a_joint" multiplier="-1" offset="0"/></joint>',
        ]
    )
    path = folder / "mini_humanoid.urdf"
    path.write_text(
        f'<?xml version="1.0"?><robot name="mini_humanoid">{pelvis}'
        f"{_leg('l', 0.1)}{_leg('r', -0.1)}{gripper}</robot>",
        encoding="utf-8",
    )
    return path


BENT = {"hip_pitch": -0.3, "knee": 0.6, "ankle_pitch": -0.3}


def write_scenario(folder: Path, robot: Path, extra: str = "") -> Path:
    joints = ", ".join(f"{s}_{j}: {v}" for s in "lr" for j, v in BENT.items())
    path = folder / "mini_stand.yaml"
    path.write_text(
        f"""version: 1
robot: {robot.name}
package_dirs: [packages]
initial: {{joints: {{{joints}}}, settle: 0.2}}
duration: 0.4
contacts:
  - {{frame: l_sole, cop: {{x: [-0.08, 0.08], y: [-0.04, 0.04]}}}}
  - {{frame: r_sole, cop: {{x: [-0.08, 0.08], y: [-0.04, 0.04]}}}}
tasks:
  - {{name: com, type: com, reference: {{type: sinusoid, amplitude: [0.01, 0, 0], frequency: 1}}}}
  - {{name: pelvis, type: frame_orientation, frame: pelvis}}
  - {{name: posture, type: joint_posture, priority: 2, kp: 50, kv: 14}}
metrics:
  window: [0.1, 0.4]
{extra}""",
        encoding="utf-8",
    )
    return path


def test_urdf_loads_with_packages_mimic_and_a_floor(tmp_path: Path) -> None:
    urdf = write_humanoid(tmp_path)
    with pytest.raises(ModelError) as exc:
        load_robot(urdf)
    assert str(exc.value).startswith(
        f"{urdf}: <link name='pelvis'> <visual> <mesh>: cannot resolve "
        "'package://mini_description/meshes/pelvis.stl': package 'mini_description' is in none "
        "of the package folders ("
    )
    assert str(exc.value).endswith(
        "); add the folder that holds mini_description/ to the scenario's 'package_dirs:'"
    )
    robot = load_robot(urdf, package_dirs=[tmp_path / "packages"])
    assert robot.mimic_joints == {"finger_b_joint": "finger_a_joint"}
    assert "finger_b_joint" not in robot.joint_names and robot.k == 11
    assert robot.has_frame("finger_b") and robot.has_frame("l_sole")
    m = robot.mj_model
    planes = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE]
    assert len(planes) == 1 and m.geom_bodyid[planes[0]] == 0


def test_joint_map_puts_the_soles_on_the_floor(tmp_path: Path) -> None:
    path = write_scenario(tmp_path, write_humanoid(tmp_path))
    loaded = load_scenario(path)
    robot = load_scenario_robot(loaded)
    check_scenario(loaded, robot)
    q, v = initial_state(loaded, robot)
    assert not v.any()
    assert q[7 + robot.joint_index("l_knee")] == 0.6
    assert q[7 + robot.joint_index("finger_a_joint")] == 0.0
    m = robot.mj_model
    d = mujoco.MjData(m)
    d.qpos[:], _ = robot.pin_to_mj(q)
    mujoco.mj_forward(m, d)
    sensor = ContactSensor(m, robot, ["l_sole", "r_sole"])
    for i in range(2):
        assert sensor.frame_pose(d, i)[0][2] == pytest.approx(0.0, abs=1e-12)


def test_sole_link_without_geometry_reads_the_foot_contact(tmp_path: Path) -> None:
    path = write_scenario(tmp_path, write_humanoid(tmp_path))
    loaded = load_scenario(path)
    robot = load_scenario_robot(loaded)
    m = robot.mj_model
    sole = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "l_sole")
    assert m.body_geomnum[sole] == 0
    d = mujoco.MjData(m)
    d.qpos[:], _ = robot.pin_to_mj(initial_state(loaded, robot)[0])
    d.qpos[2] -= 0.002  # 2 mm into the floor: the feet are pushed up
    mujoco.mj_forward(m, d)
    wrench = ContactSensor(m, robot, ["l_sole", "r_sole"]).wrenches(d)
    assert wrench[2] > 0 and wrench[8] > 0


def test_validate_and_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_scenario(tmp_path, write_humanoid(tmp_path))
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"ok  {path}  (mini_humanoid.urdf, 3 tasks, 2 contacts, 0.4 s, hash ")
    assert "mimic joints held fixed at their offset: finger_b_joint (mimics finger_a_joint)" in out
    code = main(["run", str(path), "--out", str(tmp_path / "out"), "--no-progress"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "mini_stand · qp_wbc" in out and ": ok" in out


def test_settle_starts_the_run_at_rest(tmp_path: Path) -> None:
    path = write_scenario(tmp_path, write_humanoid(tmp_path))
    result = run_closed_loop(plan_run(load_scenario(path), controller="qp_wbc"))
    assert result.status == "ok", result.message
    cols = result.log.arrays()
    assert np.all(cols["wrench_sim.l_sole.fz"] > 0) and np.all(cols["wrench_sim.r_sole.fz"] > 0)


@pytest.mark.parametrize(
    ("initial", "key", "message"),
    [
        (
            "{joints: {l_kne: 0.5}}",
            "initial.joints.l_kne",
            "unknown joint 'l_kne'; valid choices: finger_a_joint, l_ankle_pitch, l_ankle_roll, "
            "l_hip_pitch, l_hip_roll, l_knee, r_ankle_pitch, r_ankle_roll, r_hip_pitch, "
            "r_hip_roll, r_knee",
        ),
        (
            "{joints: {l_knee: 2.5}}",
            "initial.joints.l_knee",
            "l_knee = 2.5 is outside the joint's range [-2, 2]",
        ),
        (
            "{keyframe: stand}",
            "initial.keyframe",
            "unknown keyframe 'stand'; valid choices: (none) (the model has no keyframes: give "
            "'initial: {joints: {name: value, …}}' or 'initial: {srdf: file, state: name}')",
        ),
        (
            "{keyframe: stand, joints: {l_knee: 0.5}}",
            "initial",
            "give one of keyframe, joints or srdf, not keyframe and joints",
        ),
        (
            "{srdf: mini.srdf}",
            "initial",
            "'srdf' and 'state' go together: {srdf: file, state: name}",
        ),
        (
            "{srdf: none.srdf, state: half_sitting}",
            "initial.srdf",
            "no such SRDF file {dir}/none.srdf",
        ),
        (
            "{srdf: mini.srdf, state: half_sittin}",
            "initial.state",
            "unknown state of {dir}/mini.srdf 'half_sittin'; valid choices: half_sitting",
        ),
    ],
)
def test_initial_state_errors_name_the_key_and_the_choices(
    tmp_path: Path, initial: str, key: str, message: str
) -> None:
    robot = write_humanoid(tmp_path)
    (tmp_path / "mini.srdf").write_text(
        '<robot name="mini"><group_state name="half_sitting" group="all">'
        '<joint name="l_knee" value="0.6"/></group_state></robot>'
    )
    path = write_scenario(tmp_path, robot)
    text = path.read_text()
    path.write_text(text.replace(text.split("\n")[3], f"initial: {initial}"))
    with pytest.raises(ScenarioError) as exc:
        loaded = load_scenario(path)
        check_scenario(loaded, load_scenario_robot(loaded))
    assert str(exc.value) == f"{path}: {key}: {message.replace('{dir}', str(tmp_path))}"


def test_srdf_state_sets_the_named_joints(tmp_path: Path) -> None:
    robot = write_humanoid(tmp_path)
    (tmp_path / "mini.srdf").write_text(
        '<robot name="mini"><group_state name="half_sitting" group="left_leg">'
        '<joint name="l_knee" value="0.6"/><joint name="arm_joint" value="1"/></group_state>'
        '<group_state name="half_sitting" group="right_leg"><joint name="r_knee" value="0.5"/>'
        "</group_state></robot>"
    )
    path = write_scenario(tmp_path, robot)
    path.write_text(
        path.read_text().replace(
            path.read_text().split("\n")[3], "initial: {srdf: mini.srdf, state: half_sitting}"
        )
    )
    loaded = load_scenario(path)
    robot_model = load_scenario_robot(loaded)
    q, _ = initial_state(loaded, robot_model)
    assert q[7 + robot_model.joint_index("l_knee")] == 0.6
    assert q[7 + robot_model.joint_index("r_knee")] == 0.5


def test_self_collisions_are_named_and_can_be_switched_off(tmp_path: Path) -> None:
    from wbcbench.scenarios.initial import grounded_configuration, self_collisions
    from wbcbench.sim.closed_loop import prepare_model

    path = write_scenario(tmp_path, write_humanoid(tmp_path), "sim: {self_collision: false}\n")
    loaded = load_scenario(path)
    robot = load_scenario_robot(loaded)
    assert self_collisions(robot, initial_state(loaded, robot)[0]) == []
    crossed = grounded_configuration(robot, {"l_hip_roll": -0.17, "r_hip_roll": 0.17}, [])
    overlaps = self_collisions(robot, crossed)
    assert [(a, b) for a, b, _ in overlaps] == [("l_foot", "r_foot")] and overlaps[0][2] > 0
    model = prepare_model(robot, loaded)
    data = mujoco.MjData(model)
    data.qpos[:], _ = robot.pin_to_mj(crossed)
    mujoco.mj_forward(model, data)
    bodies = {(model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]) for c in data.contact}
    assert all(0 in pair for pair in bodies)
