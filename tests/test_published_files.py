"""Robot files as they are published, with no hand edits: a scene that includes its robot (two
<worldbody>s), default classes, a sole site nested in a <frame>, a joint and a body sharing a
name, balanceinertia with inertias that break the triangle inequality, position servos, and a
floorless robot file whose default geoms collide with nothing. Each goes through ``validate`` and
a short run, and the controllers' model is the simulated one (M(q) to round-off)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.cli import main
from wbcbench.errors import ModelError, ScenarioError
from wbcbench.robots.loader import ExtraFrame, load_robot
from wbcbench.robots.parity import PARITY_TOLERANCE, model_parity
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import load_scenario, load_scenario_robot
from wbcbench.scenarios.preflight import contact_rank, sole_placements
from wbcbench.sim.closed_loop import run_closed_loop

# Menagerie's layout: the robot's own file, its default classes (visual geoms that collide with
# nothing, collision geoms in a class), servos, the sole site inside a <frame>; the torso's body
# and its hinge are both named "Waist". The thigh's stated inertia (0.001, 0.001, 0.02) breaks
# A + B >= C; the file sets balanceinertia, as TOCABI's does.
_LEG = """
      <body name="{s}_thigh" pos="0 {y} -0.06">
        <joint name="{s}_hip_yaw" axis="0 0 1" range="-0.6 0.6"/>
        <inertial pos="0 0 0" mass="0.3" diaginertia="0.0003 0.0003 0.0003"/>
        <body name="{s}_thigh2">
          <joint name="{s}_hip_roll" axis="1 0 0" range="-0.6 0.6"/>
          <inertial pos="0 0 0" mass="0.3" diaginertia="0.0003 0.0003 0.0003"/>
          <body name="{s}_thigh3">
            <joint name="{s}_hip_pitch" axis="0 1 0" range="-1.5 1.0"/>
            <inertial pos="0 0 -0.12" mass="1.5" diaginertia="0.001 0.001 0.02"/>
            <geom type="capsule" fromto="0 0 0 0 0 -0.24" size="0.03"/>
            <body name="{s}_shank" pos="0 0 -0.25">
              <joint name="{s}_knee" axis="0 1 0" range="0 2"/>
              <inertial pos="0 0 -0.12" mass="1" diaginertia="0.006 0.006 0.0008"/>
              <geom type="capsule" fromto="0 0 0 0 0 -0.24" size="0.025"/>
              <body name="{s}_ankle" pos="0 0 -0.25">
                <joint name="{s}_ankle_pitch" axis="0 1 0" range="-1 1"/>
                <inertial pos="0 0 0" mass="0.1" diaginertia="0.0001 0.0001 0.0001"/>
                <body name="{s}_foot">
                  <joint name="{s}_ankle_roll" axis="1 0 0" range="-0.5 0.5"/>
                  <inertial pos="0.02 0 -0.03" mass="0.5" diaginertia="0.0008 0.002 0.0025"/>
                  <geom class="collision" type="box" pos="0.02 0 -0.03" size="0.09 0.045 0.01"/>
                  <frame pos="0.02 0 -0.04">
                    <site name="{s}_sole"/>
                  </frame>
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>"""

_ROBOT = """<mujoco model="mini_menagerie">
  <compiler angle="radian" balanceinertia="true"/>
  <default>
    <geom contype="0" conaffinity="0" group="2"/>
    <joint damping="0.5" armature="0.01"/>
    <position kp="100"/>
    <default class="collision">
      <geom contype="1" conaffinity="1" group="3"/>
    </default>
  </default>
  <worldbody>
    <body name="pelvis" pos="0 0 0.6">
      <freejoint name="floating_base"/>
      <inertial pos="0 0 0" mass="4" diaginertia="0.03 0.02 0.03"/>
      <geom type="box" size="0.06 0.1 0.05"/>
      <body name="Waist" pos="0 0 0.08">
        <joint name="Waist" axis="0 0 1" range="-0.5 0.5"/>
        <inertial pos="0 0 0.12" mass="5" diaginertia="0.05 0.04 0.03"/>
        <geom type="box" pos="0 0 0.12" size="0.07 0.12 0.12"/>
      </body>{legs}
    </body>
  </worldbody>
  <actuator>{servos}
  </actuator>
</mujoco>
"""

_SCENE = """<mujoco model="mini_scene">
  <include file="mini_robot.xml"/>
  <worldbody>
    <light pos="0 0 3"/>
    <geom name="floor" type="plane" size="0 0 0.05" contype="1" conaffinity="1"/>
  </worldbody>
</mujoco>
"""

JOINTS = ["Waist"] + [
    f"{s}_{j}"
    for s in "lr"
    for j in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
]
BENT = {"hip_pitch": -0.3, "knee": 0.6, "ankle_pitch": -0.3}


def write_pair(folder: Path) -> tuple[Path, Path]:
    """The robot file and the scene that includes it, in ``folder``."""
    legs = _LEG.format(s="l", y=0.08) + _LEG.format(s="r", y=-0.08)
    servos = "".join(f'\n    <position name="{j}" joint="{j}"/>' for j in JOINTS)
    robot = folder / "mini_robot.xml"
    robot.write_text(_ROBOT.format(legs=legs, servos=servos), encoding="utf-8")
    scene = folder / "mini_scene.xml"
    scene.write_text(_SCENE, encoding="utf-8")
    return robot, scene


def write_scenario(folder: Path, model: Path, name: str) -> Path:
    joints = ", ".join(f"{s}_{j}: {v}" for s in "lr" for j, v in BENT.items())
    path = folder / f"{name}.yaml"
    path.write_text(
        f"""version: 1
robot: {model.name}
initial: {{joints: {{{joints}}}, settle: 0.1}}
duration: 0.3
contacts:
  - {{frame: l_sole, cop: {{x: [-0.07, 0.11], y: [-0.045, 0.045]}}}}
  - {{frame: r_sole, cop: {{x: [-0.07, 0.11], y: [-0.045, 0.045]}}}}
tasks:
  - {{name: com, type: com, reference: {{type: sinusoid, amplitude: [0.01, 0, 0], frequency: 1}}}}
  - {{name: torso, type: frame_orientation, frame: Waist}}
  - {{name: posture, type: joint_posture, priority: 2, kp: 50, kv: 14}}
sim: {{self_collision: false}}
metrics:
  window: [0.0, 0.3]
""",
        encoding="utf-8",
    )
    return path


def test_scene_including_the_robot_is_one_robot_as_simulated(tmp_path: Path) -> None:
    _, scene = write_pair(tmp_path)
    robot = load_robot(scene)
    assert robot.k == len(JOINTS) == 13 and robot.nq == 20
    assert set(robot.joint_names) == set(JOINTS)
    assert robot.has_frame("l_sole") and robot.has_frame("Waist")
    # the thigh's inertia as MuJoCo balanced it, in both libraries
    m = robot.mj_model
    thigh = m.body("l_thigh3").id
    assert m.body_inertia[thigh] == pytest.approx([0.022 / 3] * 3)
    joint = robot.pin_model.getJointId("l_hip_pitch")
    assert np.linalg.eigvalsh(robot.pin_model.inertias[joint].inertia) == pytest.approx(
        [0.022 / 3] * 3
    )
    assert robot.pin_model.armature[6:] == pytest.approx(np.full(13, 0.01))
    parity = model_parity(robot, states=5)
    assert parity.worst <= PARITY_TOLERANCE, parity
    # the scene's floor is the file's: nothing added
    assert not any("no floor" in n for n in robot.notes)
    assert robot.notes == (
        "the file's actuators (13 position/velocity servos) were replaced by one torque motor per "
        "joint (13): the controllers command joint torques; a servo's forcerange became the "
        "joint's torque limit where the joint states none",
        "inertias that break A + B >= C in 2 of the file's bodies (l_thigh3, r_thigh3): MuJoCo "
        "balanced them (the file sets balanceinertia) and the controllers' model uses the same "
        "balanced values; fix those <inertial>s to keep the file's",
        "'Waist' names both a joint and a body: as a frame (tasks[].frame, contacts[].frame) it "
        "means the body, as a joint (joint_posture, initial.joints) the joint",
    )


def test_floorless_robot_file_gets_a_floor_that_collides(tmp_path: Path) -> None:
    robot_file, _ = write_pair(tmp_path)
    robot = load_robot(robot_file)
    m = robot.mj_model
    floor = m.geom("floor").id
    # the file's default geom (contype 0, conaffinity 0) is not the floor's
    assert (m.geom_contype[floor], m.geom_conaffinity[floor]) == (1, 1)
    assert robot.notes[2] == (
        "the file has no floor: a plane at z = 0 was added (contype 1, conaffinity 1, condim 3, "
        "friction 1, not the file's geom defaults)"
    )


@pytest.mark.parametrize("which", ["scene", "robot"])
def test_published_files_validate_and_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], which: str
) -> None:
    robot_file, scene = write_pair(tmp_path)
    path = write_scenario(tmp_path, scene if which == "scene" else robot_file, f"mini_{which}")
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"ok  {path}  (mini_{which}.xml, 3 tasks, 2 contacts, 0.3 s, hash ")
    assert "warning" not in out, out
    assert "model: MuJoCo and Pinocchio agree to " in out
    result = run_closed_loop(plan_run(load_scenario(path), controller="qp_wbc"))
    assert result.status == "ok", result.message


def test_validate_names_a_tilted_sole_and_a_foot_that_cannot_touch(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    robot_file, _ = write_pair(tmp_path)
    # the left foot's box in the file's default class (contype 0, conaffinity 0)
    text = robot_file.read_text()
    left = text.index('name="l_foot"')
    text = text[:left] + text[left:].replace('class="collision" type="box"', 'type="box"', 1)
    robot_file.write_text(text)
    path = write_scenario(tmp_path, robot_file, "mini_fall")
    # the right ankle 2.5° off the posture that holds the sole flat
    tilted = f"r_ankle_pitch: {BENT['ankle_pitch'] + float(np.deg2rad(2.5))!r}"
    path.write_text(path.read_text().replace("r_ankle_pitch: -0.3", tilted))
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert (
        "    warning: contacts[0] ('l_sole'): the foot cannot touch the floor or a wall: its geoms "
        "(contype/conaffinity: l_foot's box 0/0) share no bit with the floor's (floor 1/1)" in out
    )
    assert "share no bit with the floor's (floor 1/1); the robot falls through it." in out
    assert (
        "    warning: contacts[1] ('r_sole') at the initial posture: its sole plane is tilted "
        "2.5° from the floor (tolerances 1° and 2 mm): the controllers hold the sole flat where "
        "it is, so the foot rocks or drops at the first step; fix the keyframe or "
        "'initial.joints', or give the contact a frame in the sole plane ('frames:')"
    ) in out


def test_rank_deficient_contacts_are_named(tmp_path: Path) -> None:
    """Legs without ankle roll: two flat contacts have a contact Jacobian of rank 11 of 12."""
    robot_file, _ = write_pair(tmp_path)
    text = robot_file.read_text()
    for s in "lr":
        text = text.replace(
            f'<joint name="{s}_ankle_roll" axis="1 0 0" range="-0.5 0.5"/>', ""
        ).replace(f'<position name="{s}_ankle_roll" joint="{s}_ankle_roll"/>', "")
    robot_file.write_text(text)
    robot = load_robot(robot_file)
    assert robot.k == 11
    q = np.zeros(robot.nq)
    q[6] = 1.0
    why = contact_rank(robot, q, ["l_sole", "r_sole"])
    assert why.startswith("the contact Jacobian has rank 11 of 12 at the initial posture: ")
    assert "moment x" in why
    assert why.endswith(
        "give such a foot a line contact (forces only, along the axis its leg cannot turn "
        "about; points in the contact frame [m]) in 'contacts:': "
        "{frame: l_sole, type: line, points: [[x_front, y_mid, 0], [x_back, y_mid, 0]]}; "
        "{frame: r_sole, type: line, points: [[x_front, y_mid, 0], [x_back, y_mid, 0]]}"
    ), why
    (tmp_path / "full").mkdir()
    full = load_robot(write_pair(tmp_path / "full")[0])
    q_full = np.zeros(full.nq)
    q_full[6] = 1.0
    assert contact_rank(full, q_full, ["l_sole", "r_sole"]) == ""


def test_frame_given_as_body_and_offset(tmp_path: Path) -> None:
    robot_file, _ = write_pair(tmp_path)
    sole = ExtraFrame("l_sole_plane", "l_foot", (0.02, 0.0, -0.04), (0.0, 0.0, 0.3))
    robot = load_robot(robot_file, frames=[sole])
    model, data = robot.pin_model, robot.pin_model.createData()
    q = np.zeros(robot.nq)
    q[6] = 1.0
    pin.framesForwardKinematics(model, data, q)
    placed = data.oMf[robot.frame_id("l_sole_plane")]
    site = data.oMf[robot.frame_id("l_sole")]
    assert placed.translation == pytest.approx(site.translation, abs=1e-12)
    assert placed.rotation == pytest.approx(pin.rpy.rpyToMatrix(0.0, 0.0, 0.3), abs=1e-12)
    d = mujoco.MjData(robot.mj_model)
    d.qpos[:], _ = robot.pin_to_mj(q)
    mujoco.mj_forward(robot.mj_model, d)
    assert d.site("l_sole_plane").xpos == pytest.approx(placed.translation, abs=1e-12)
    with pytest.raises(ModelError) as exc:
        load_robot(robot_file, frames=[ExtraFrame("l_sole", "l_foot")])
    assert str(exc.value) == (
        f"{robot_file}: frame 'l_sole': the model has a body or site of that name already; name "
        "the added frame otherwise, or use the model's"
    )


def test_flat_soles_on_the_floor_pass(tmp_path: Path) -> None:
    robot = load_robot(write_pair(tmp_path)[1])
    q = np.zeros(robot.nq)
    q[6] = 1.0
    d = mujoco.MjData(robot.mj_model)
    d.qpos[:], _ = robot.pin_to_mj(q)
    mujoco.mj_forward(robot.mj_model, d)
    q[2] = -d.site("l_sole").xpos[2]  # the sole boxes' bottom faces at z = 0
    assert sole_placements(robot, q, [("l_sole", "model"), ("r_sole", "box")]) == []
    q[2] += 0.003
    assert sole_placements(robot, q, [("l_sole", "box")]) == [
        (
            0,
            "contacts[0] ('l_sole') at the initial posture: the contact frame is 3.0 mm above the "
            "floor (tolerances 1° and 2 mm): the controllers hold the sole flat where it is, so "
            "the foot rocks or drops at the first step; fix the keyframe or 'initial.joints', or "
            "give the contact a frame in the sole plane ('frames:')",
        )
    ]


def test_validate_into_a_closed_pipe_ends_quietly() -> None:
    """``wbcbench validate … | head``: the reader goes away before the output is written."""
    scenario = Path(__file__).parents[1] / "scenarios" / "tocabi_stand_sway.yaml"
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from wbcbench.cli import main; sys.exit(main())",
            "validate",
            str(scenario),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert child.stdout is not None and child.stderr is not None
    child.stdout.close()
    err = child.stderr.read().decode()
    assert child.wait(timeout=300) == 141
    assert err == ""


def test_scenario_frames_hold_the_contacts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Sole planes given as a body plus an offset: the same soles as the file's sites."""
    robot_file, _ = write_pair(tmp_path)
    path = write_scenario(tmp_path, robot_file, "mini_frames")
    frames = "".join(f"  {s}_plane: {{body: {s}_foot, pos: [0.02, 0, -0.04]}}\n" for s in "lr")
    text = path.read_text().replace("frame: l_sole", "frame: l_plane")
    text = text.replace("frame: r_sole", "frame: r_plane")
    path.write_text(text.replace("initial:", f"frames:\n{frames}initial:"))
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "warning" not in out, out
    robot = load_scenario_robot(load_scenario(path))
    assert robot.has_frame("l_plane") and robot.has_frame("l_sole")
    path.write_text(path.read_text().replace("body: l_foot", "body: l_fot"))
    with pytest.raises(ScenarioError) as exc:
        load_scenario_robot(load_scenario(path))
    assert str(exc.value).startswith(
        f"{path}: frames.l_plane.body: unknown body 'l_fot'; valid choices: Waist, l_ankle, "
    )
