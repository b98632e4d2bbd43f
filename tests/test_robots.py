"""Generated humanoids: files, figures, keyframes, contacts, metadata, loader errors."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.errors import ModelError, UnknownNameError
from wbcbench.robots.convert import pin_to_mj
from wbcbench.robots.generator import MODELS_DIR, generate
from wbcbench.robots.library import SPECS, TOCABI_ARM, TOCABI_DOF_FAMILY, arm_chain, tocabi_like
from wbcbench.robots.loader import Robot, available_robots, load_robot
from wbcbench.robots.spec import ChainSpec, mirror_chain

NAMES = ("tocabi_like", "comanplus_like")

TOCABI_JOINTS = (
    *(f"L_{j}" for j in ("HipYaw", "HipRoll", "HipPitch", "Knee", "AnklePitch", "AnkleRoll")),
    *(f"R_{j}" for j in ("HipYaw", "HipRoll", "HipPitch", "Knee", "AnklePitch", "AnkleRoll")),
    "Waist1",
    "Waist2",
    "Upperbody",
    *(f"L_{j}" for j in ("Shoulder1", "Shoulder2", "Shoulder3", "Armlink", "Elbow", "Forearm")),
    "L_Wrist1",
    "L_Wrist2",
    "Neck",
    "Head",
    *(f"R_{j}" for j in ("Shoulder1", "Shoulder2", "Shoulder3", "Armlink", "Elbow", "Forearm")),
    "R_Wrist1",
    "R_Wrist2",
)
COMANPLUS_JOINTS = (
    *(f"L_{j}" for j in ("HipLat", "HipSag", "HipYaw", "Knee", "AnklePitch", "AnkleRoll")),
    *(f"R_{j}" for j in ("HipLat", "HipSag", "HipYaw", "Knee", "AnklePitch", "AnkleRoll")),
    "WaistLat",
    "WaistYaw",
    *(f"L_{j}" for j in ("ShSag", "ShLat", "ShYaw", "Elbow", "ForearmPlate", "Wrist1", "Wrist2")),
    *(f"R_{j}" for j in ("ShSag", "ShLat", "ShYaw", "Elbow", "ForearmPlate", "Wrist1", "Wrist2")),
)


@functools.cache
def _robot(name: str) -> Robot:
    return load_robot(name)


def _posed(robot: Robot, key: str) -> mujoco.MjData:
    d = mujoco.MjData(robot.mj_model)
    mujoco.mj_resetDataKeyframe(robot.mj_model, d, robot.keyframe_names.index(key))
    mujoco.mj_forward(robot.mj_model, d)
    return d


def _height(robot: Robot, d: mujoco.MjData) -> float:
    """Top of the highest capsule [m]."""
    m = robot.mj_model
    caps = np.flatnonzero(m.geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE)
    return float(
        max(
            d.geom_xpos[g, 2] + abs(d.geom_xmat[g, 8]) * m.geom_size[g, 1] + m.geom_size[g, 0]
            for g in caps
        )
    )


# ---------------------------------------------------------------------------------------------
# Files


def test_available_robots() -> None:
    family = [f"tocabi_dof{d}" for d in TOCABI_DOF_FAMILY if d != 33]
    assert available_robots() == sorted(["comanplus_like", "tocabi_like", *family])


@pytest.mark.parametrize("name", available_robots())
def test_committed_file_reproduces_byte_for_byte(name: str) -> None:
    committed = (MODELS_DIR / f"{name}.xml").read_text(encoding="utf-8")
    assert generate(SPECS[name]()) == committed


@pytest.mark.parametrize("name", NAMES)
def test_file_follows_the_mjcf_rules(name: str) -> None:
    text = (MODELS_DIR / f"{name}.xml").read_text(encoding="utf-8")
    assert "<include" not in text and "<frame" not in text
    assert '<compiler angle="radian" inertiafromgeom="false"/>' in text
    assert '<option timestep="0.001" integrator="implicitfast"/>' in text
    m = _robot(name).mj_model
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE and m.joint(0).name == "root"
    assert m.body(int(m.jnt_bodyid[0])).name == "pelvis"
    assert all(m.jnt_type[1:] == mujoco.mjtJoint.mjJNT_HINGE)
    assert m.body_jntnum[1:].max() == 1  # one joint per body
    assert text.count("<inertial ") == m.nbody - 1  # every body but the world
    inertia = np.sort(m.body_inertia[1:], axis=1)
    assert np.all(inertia[:, 0] + inertia[:, 1] >= inertia[:, 2])
    assert np.all(m.body_mass[1:] > 0)


# ---------------------------------------------------------------------------------------------
# Figures


def test_tocabi_joints_and_figures() -> None:
    r = _robot("tocabi_like")
    assert r.joint_names == TOCABI_JOINTS and r.k == 33 and r.nq == 40 and r.nv == 39
    mass = float(r.mj_model.body_subtreemass[0])
    assert 96.0 <= mass <= 100.0
    d = _posed(r, "stand")
    assert d.qpos[2] == pytest.approx(0.93, abs=0.01)
    assert _height(r, d) == pytest.approx(1.8, abs=0.03)
    tau = dict(zip(r.joint_names, r.tau_max, strict=True))
    assert (tau["L_HipYaw"], tau["R_Knee"], tau["Waist1"], tau["L_Elbow"]) == (333, 289, 303, 23)
    assert r.v_max[r.joint_index("Upperbody")] == 2.0
    assert r.v_max[r.joint_index("R_AnklePitch")] == 20.0
    # hip offset ±0.1025 m, sole plane 0.1585 m under the ankle axis
    d0 = mujoco.MjData(r.mj_model)
    mujoco.mj_kinematics(r.mj_model, d0)
    hip = d0.xanchor[r.mj_model.joint("L_HipYaw").id] - d0.xpos[r.mj_model.body("pelvis").id]
    assert hip[1] == pytest.approx(0.1025)
    ankle = d0.xanchor[r.mj_model.joint("L_AnkleRoll").id]
    assert ankle[2] - d0.site_xpos[r.mj_model.site("l_sole").id][2] == pytest.approx(0.1585)


def test_comanplus_joints_and_figures() -> None:
    r = _robot("comanplus_like")
    assert r.joint_names == COMANPLUS_JOINTS and r.k == 28 and r.nq == 35 and r.nv == 34
    mass = float(r.mj_model.body_subtreemass[0])
    assert 64.0 <= mass <= 67.0
    d = _posed(r, "stand")
    assert _height(r, d) == pytest.approx(1.6, abs=0.03)
    assert d.subtree_com[1, 2] == pytest.approx(0.89, abs=0.02)  # above the soles (z = 0)
    i = r.joint_index
    assert math.degrees(r.q_min[i("L_HipLat")]) == pytest.approx(-30)
    assert math.degrees(r.q_max[i("L_HipLat")]) == pytest.approx(95)
    assert math.degrees(r.q_min[i("R_HipLat")]) == pytest.approx(-95)  # mirrored
    assert math.degrees(r.q_max[i("L_Knee")]) == pytest.approx(140)
    assert r.tau_max[i("L_AnkleRoll")] == 60 and r.tau_max[i("R_Wrist2")] == 20
    assert r.info.sole_box("l_sole") == (-0.105, 0.105, -0.055, 0.055)


@pytest.mark.parametrize("name", NAMES)
def test_actuators_limits_and_joint_dynamics(name: str) -> None:
    r = _robot(name)
    m = r.mj_model
    assert m.nu == r.k
    assert [m.actuator(int(a)).name for a in r.actuator_ids] == list(r.joint_names)
    assert np.all(m.actuator_gear[:, 0] == 1.0) and np.all(m.actuator_ctrllimited == 1)
    assert m.actuator_ctrlrange[r.actuator_ids, 1] == pytest.approx(r.tau_max)
    assert r.pin_model.effortLimit[6:] == pytest.approx(r.tau_max)
    spec = {j.name: j for j in SPECS[name]().joints}
    for attr, field in (("armature", "armature"), ("damping", "damping")):
        assert getattr(r, attr) == pytest.approx([getattr(spec[j], field) for j in r.joint_names])
    assert r.frictionloss == pytest.approx([spec[j].frictionloss for j in r.joint_names])
    assert r.pin_model.armature[6:] == pytest.approx(r.armature)
    assert np.all(r.q_min < r.q_max)


@pytest.mark.parametrize("name", NAMES)
def test_geoms_capsules_and_collision_filter(name: str) -> None:
    m = _robot(name).mj_model
    colliding = {
        m.geom(g).name for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]
    }
    expected = {"floor", "l_foot", "r_foot"}
    if name == "comanplus_like":
        expected |= {"wall", "l_palm_box"}
    assert colliding == expected
    for b in range(1, m.nbody):
        g = m.geom(f"{m.body(b).name}_capsule")
        assert m.geom_type[g.id] == mujoco.mjtGeom.mjGEOM_CAPSULE and g.size[1] > 0


@pytest.mark.parametrize("name", NAMES)
def test_named_frames_exist(name: str) -> None:
    r = _robot(name)
    for frame in ("l_sole", "r_sole", "l_hand", "r_hand", "head", "pelvis", "torso"):
        assert r.has_frame(frame)
    # the head site (gaze) shadows the head body
    assert r.pin_model.frames[r.frame_id("head")].type == pin.FrameType.OP_FRAME
    assert r.mj_model.body("head") is not None
    assert r.has_frame("l_palm") == (name == "comanplus_like")
    assert not r.has_frame("L_Knee")  # joint frames are not task frames
    info = r.info
    assert info.contact_frames == ("l_sole", "r_sole")
    assert info.hand_frames == ("l_hand", "r_hand")
    assert (info.base_body, info.torso_body, info.head_frame) == ("pelvis", "torso", "head")
    assert info.default_keyframe == "stand"


# ---------------------------------------------------------------------------------------------
# Keyframes and contacts


@pytest.mark.parametrize("name", NAMES)
def test_stand_soles_flat_on_the_floor(name: str) -> None:
    r = _robot(name)
    d = _posed(r, "stand")
    m = r.mj_model
    for sole in ("l_sole", "r_sole"):
        sid = m.site(sole).id
        assert abs(d.site_xpos[sid, 2]) <= 1e-9
        assert d.site_xmat[sid].reshape(3, 3)[:, 2] == pytest.approx([0, 0, 1], abs=1e-9)
    floor = m.geom("floor").id
    touching = set()
    for c in d.contact[: d.ncon]:
        assert c.dist >= -1e-3
        pair = {int(c.geom[0]), int(c.geom[1])}
        if floor in pair:
            touching |= {m.geom(g).name for g in pair - {floor}}
    assert touching == {"l_foot", "r_foot"}
    # base at the origin facing +x
    assert d.qpos[0:2] == pytest.approx([0, 0]) and d.qpos[3:7] == pytest.approx([1, 0, 0, 0])
    # arms slightly away from the body
    pelvis_y = d.xpos[m.body("pelvis").id, 1]
    assert d.site_xpos[m.site("l_hand").id, 1] > pelvis_y + 0.25
    assert d.site_xpos[m.site("r_hand").id, 1] < pelvis_y - 0.25


def test_stand_left_on_one_foot_com_over_the_sole() -> None:
    r = _robot("tocabi_like")
    d = _posed(r, "stand_left")
    m = r.mj_model
    left, right = m.site("l_sole").id, m.site("r_sole").id
    assert abs(d.site_xpos[left, 2]) <= 1e-9
    assert d.site_xmat[left].reshape(3, 3)[:, 2] == pytest.approx([0, 0, 1], abs=1e-9)
    assert d.site_xpos[right, 2] > 0.03  # the right sole is lifted
    com = d.subtree_com[m.body("pelvis").id]
    offset = com[:2] - d.site_xpos[left, :2]
    assert abs(offset[1]) <= 0.002 and abs(offset[0]) <= 0.03


def test_stand_wall_palm_on_the_wall() -> None:
    r = _robot("comanplus_like")
    m = r.mj_model
    d = _posed(r, "stand_wall")
    palm = m.site("l_palm").id
    wall = m.geom("wall").id
    face_y = m.geom_pos[wall, 1] - m.geom_size[wall, 1]
    assert abs(d.site_xpos[palm, 1] - face_y) <= 1e-9
    assert d.site_xmat[palm].reshape(3, 3)[:, 2] == pytest.approx([0, -1, 0], abs=1e-9)
    pairs = [{int(c.geom[0]), int(c.geom[1])} for c in d.contact[: d.ncon]]
    assert {wall, m.geom("l_palm_box").id} in pairs
    for sole in ("l_sole", "r_sole"):
        assert abs(d.site_xpos[m.site(sole).id, 2]) <= 1e-9
    tocabi = _robot("tocabi_like").mj_model
    assert "wall" not in {tocabi.geom(g).name for g in range(tocabi.ngeom)}


def test_keyframe_in_pinocchio_convention() -> None:
    r = _robot("comanplus_like")
    q, v = r.keyframe()
    assert q.shape == (r.nq,) and v.shape == (r.nv,)
    assert q[3:7] == pytest.approx([0, 0, 0, 1])  # (x, y, z, w)
    qpos, _ = pin_to_mj(r, q, v)
    assert qpos == pytest.approx(r.mj_model.key_qpos[0])
    assert r.keyframe_names == ("stand", "stand_wall")


# ---------------------------------------------------------------------------------------------
# Errors


def test_unknown_robot_lists_choices() -> None:
    with pytest.raises(UnknownNameError) as exc:
        load_robot("nao")
    from wbcbench.robots.third_party import THIRD_PARTY

    valid = ", ".join(sorted([*available_robots(), *THIRD_PARTY]))
    assert str(exc.value) == (
        f"unknown robot 'nao'; valid choices: {valid} (or give a path to an MJCF/URDF file)"
    )


def test_unknown_frame_lists_sites_and_bodies() -> None:
    r = _robot("comanplus_like")
    valid = sorted(
        {
            f.name
            for f in r.pin_model.frames
            if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)
        }
    )
    assert "L_Knee" not in valid and "l_sole" in valid and "torso" in valid
    with pytest.raises(UnknownNameError) as exc:
        r.frame_id("nose")
    assert str(exc.value) == f"unknown frame 'nose'; valid choices: {', '.join(valid)}"


def test_unknown_keyframe_and_joint_list_choices() -> None:
    r = _robot("comanplus_like")
    with pytest.raises(UnknownNameError) as exc:
        r.keyframe("sit")
    assert str(exc.value) == "unknown keyframe 'sit'; valid choices: stand, stand_wall"
    with pytest.raises(UnknownNameError) as exc:
        r.joint_index("L_Toe")
    assert str(exc.value).startswith("unknown joint 'L_Toe'; valid choices: L_AnklePitch, ")


def test_missing_file_names_the_path(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.xml"
    with pytest.raises(ModelError) as exc:
        load_robot(path)
    assert str(exc.value) == f"{path}: no such robot model file"


def test_mjcf_without_free_joint_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "arm.xml"
    path.write_text(
        '<mujoco><worldbody><body name="a"><joint name="j" axis="0 1 0"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(ModelError, match=r"arm\.xml: the root body needs a free joint"):
        load_robot(path)


def test_external_mjcf_servos_become_torque_motors(tmp_path: Path) -> None:
    path = tmp_path / "hopper.xml"
    path.write_text(
        '<mujoco><worldbody><body name="base" pos="0 0 1"><freejoint name="root"/>'
        '<inertial pos="0 0 0" mass="3" diaginertia="0.1 0.1 0.1"/>'
        '<body name="leg" pos="0 0 -0.1"><joint name="hip" axis="0 1 0" range="-1 1"/>'
        '<inertial pos="0 0 -0.2" mass="1" diaginertia="0.02 0.02 0.001"/>'
        '<site name="foot" pos="0 0 -0.4"/></body></body></worldbody>'
        '<actuator><position joint="hip" kp="50" forcerange="-40 40"/></actuator></mujoco>'
    )
    r = load_robot(path)
    assert r.joint_names == ("hip",) and r.tau_max == pytest.approx([40.0])
    m = r.mj_model
    assert m.nu == 1 and m.actuator_biastype[0] == mujoco.mjtBias.mjBIAS_NONE
    assert r.has_frame("foot") and r.keyframe_names == ()


_HOPPER_BODY = (
    '<body name="base" pos="0 0 1"><freejoint name="root"/>'
    '<inertial pos="0 0 0" mass="3" diaginertia="0.1 0.1 0.1"/>'
    '<body name="leg" pos="0 0 -0.1"><joint name="hip" axis="0 1 0" range="-1 1"/>'
    '<inertial pos="0 0 -0.2" mass="1" diaginertia="{inertia}"/>'
    '<geom type="sphere" size="0.05"/></body></body>'
)


def _hopper_with_include(
    folder: Path, compiler: str = "", inertia: str = "0.02 0.02 0.001"
) -> Path:
    (folder / "parts").mkdir(exist_ok=True)
    (folder / "parts" / "body.xml").write_text(
        f"<mujocoinclude>{_HOPPER_BODY.format(inertia=inertia)}</mujocoinclude>"
    )
    path = folder / "hopper.xml"
    path.write_text(
        f'<mujoco>{compiler}<worldbody><include file="parts/body.xml"/></worldbody>'
        '<actuator><motor joint="hip"/></actuator></mujoco>'
    )
    return path


def test_mjcf_include_is_read_by_mujoco(tmp_path: Path) -> None:
    r = load_robot(_hopper_with_include(tmp_path))
    assert r.joint_names == ("hip",) and r.pin_model.nq == 8
    assert r.notes == (
        "the file has no floor: a plane at z = 0 was added (contype 1, conaffinity 1, condim 3, "
        "friction 1, not the file's geom defaults)",
    )


def test_mjcf_include_of_a_missing_file_names_it(tmp_path: Path) -> None:
    path = _hopper_with_include(tmp_path)
    (tmp_path / "parts" / "body.xml").unlink()
    with pytest.raises(ModelError) as exc:
        load_robot(path)
    assert str(exc.value) == (
        f"{path}: <include file='parts/body.xml'>: no such file {tmp_path}/parts/body.xml "
        f"(include paths are relative to the main file's folder, {tmp_path})"
    )


def test_the_files_balanceinertia_is_kept(tmp_path: Path) -> None:
    compiler = '<compiler balanceinertia="true"/>'
    r = load_robot(_hopper_with_include(tmp_path, compiler, inertia="0.02 0.02 0.1"))
    assert r.mj_model.body_inertia[2] == pytest.approx([0.14 / 3] * 3)


def test_unbalanced_inertia_is_balanced_in_both_libraries_with_a_note(tmp_path: Path) -> None:
    path = _hopper_with_include(tmp_path, inertia="0.02 0.02 0.1")
    r = load_robot(path)
    assert r.notes[0] == (
        "inertias that break A + B >= C in 1 of the file's bodies (leg): MuJoCo balanced them "
        "(the file does not set balanceinertia and MuJoCo cannot simulate them as written) and "
        "the controllers' model uses the same balanced values; fix those <inertial>s to keep "
        "the file's"
    )
    assert r.mj_model.body_inertia[2] == pytest.approx([0.14 / 3] * 3)
    assert np.linalg.eigvalsh(r.pin_model.inertias[2].inertia) == pytest.approx([0.14 / 3] * 3)


def test_urdf_package_paths(tmp_path: Path) -> None:
    mesh = tmp_path / "pkgs" / "bot" / "meshes" / "m.stl"
    mesh.parent.mkdir(parents=True)
    mesh.write_text(
        "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
        "endloop\nendfacet\nendsolid t\n"
    )
    urdf = (
        '<robot name="bot"><link name="base"><inertial><mass value="1"/>'
        '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
        '<visual><geometry><mesh filename="{uri}"/></geometry></visual></link>'
        '<link name="arm"><inertial><mass value="1"/>'
        '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="5" velocity="1"/></joint></robot>'
    )
    for i, uri in enumerate(("package://bot/meshes/m.stl", f"package://{mesh}")):
        path = tmp_path / f"bot{i}.urdf"
        path.write_text(urdf.format(uri=uri))
        assert load_robot(path, package_dirs=[tmp_path / "pkgs"]).joint_names == ("j",)
    path = tmp_path / "bot.urdf"
    path.write_text(urdf.format(uri="package:///nowhere/m.stl"))
    with pytest.raises(ModelError) as exc:
        load_robot(path)
    assert str(exc.value) == (
        f"{path}: <link name='base'> <visual> <mesh>: 'package:///nowhere/m.stl': "
        "no such file /nowhere/m.stl"
    )


def test_a_file_that_is_no_robot_model(tmp_path: Path) -> None:
    path = tmp_path / "scene.xml"
    path.write_text("<scene/>")
    with pytest.raises(ModelError) as exc:
        load_robot(path)
    assert str(exc.value) == (
        f"{path}: the root element is <scene>; a robot model is a URDF (<robot>) or an MJCF "
        "(<mujoco>) file"
    )


# ---------------------------------------------------------------------------------------------
# Parametric arms (the DoF-scaled family varies these lists)


def test_arm_length_is_a_parameter() -> None:
    base = tocabi_like()
    short_rows = TOCABI_ARM[:5]  # shoulder ×3, armlink, elbow
    arm = arm_chain(short_rows, "torso", (0.0, 0.154, 0.33))
    swap: dict[str, ChainSpec] = {"L_Shoulder1_link": arm, "R_Shoulder1_link": mirror_chain(arm)}
    chains = tuple(swap.get(c.links[0].body, c) for c in base.chains)
    spec = type(base)(
        name="tocabi_short_arms",
        base=base.base,
        chains=chains,
        keyframes=base.keyframes,
        info=base.info,
    )
    m = mujoco.MjModel.from_xml_string(generate(spec))
    assert m.nu == 33 - 6
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_kinematics(m, d)
    assert abs(d.site_xpos[m.site("l_sole").id, 2]) <= 1e-9
    assert m.site("r_hand").id >= 0
