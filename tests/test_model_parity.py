"""MuJoCo and Pinocchio must describe the same multibody: mass matrix, bias forces, frame
placements and frame Jacobians agree to round-off over random states, for every shipped robot
(generated, third-party, the example plugin's) and for a URDF."""

from __future__ import annotations

import functools
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.robots.convert import (
    base_velocity_transform,
    bias_pin_to_mj,
    force_pin_to_mj,
    mass_matrix_pin_to_mj,
    mj_to_pin,
    pin_to_mj,
    torque_to_ctrl,
)
from wbcbench.robots.loader import Robot, available_robots, load_robot, third_party_robots
from wbcbench.robots.parity import PARITY_TOLERANCE, model_parity

TOL = 1e-9
N_STATES = 100

EXAMPLE_BIPED = (
    Path(__file__).parents[1]
    / "examples/plugin/src/wbcbench_example_plugin/models/example_biped.xml"
)
SHIPPED = [
    *available_robots(),
    *(name for name, missing in third_party_robots().items() if not missing),
    str(EXAMPLE_BIPED),
]


@functools.cache
def _robot(name: str) -> Robot:
    return load_robot(name)


def _random_mj_state(robot: Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Random base pose, joint positions within limits, velocities (MuJoCo convention)."""
    m = robot.mj_model
    qpos = np.zeros(m.nq)
    qpos[0:3] = rng.uniform(-1.0, 1.0, 3)
    quat = rng.normal(size=4)
    qpos[3:7] = quat / np.linalg.norm(quat)
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
    qpos[robot.mj_qpos_adr] = rng.uniform(lo, hi)
    qvel = rng.uniform(-2.0, 2.0, m.nv)
    return qpos, qvel


def parity_errors(robot: Robot, n_states: int, seed: int = 0) -> dict[str, float]:
    """Largest |MuJoCo − Pinocchio| of M, qfrc_bias and every site/body placement."""
    m, pm = robot.mj_model, robot.pin_model
    d, pd = mujoco.MjData(m), pm.createData()
    rng = np.random.default_rng(seed)
    frames = []
    for name in robot.frame_names:
        fid = robot.frame_id(name)
        if pm.frames[fid].type == pin.FrameType.OP_FRAME:
            frames.append((fid, m.site(name).id, True))
        else:
            frames.append((fid, m.body(name).id, False))
    # Bodies shadowed by a site of the same name are still compared, through Pinocchio's list.
    for fid, frame in enumerate(pm.frames):
        if frame.type == pin.FrameType.BODY and robot.frame_id(frame.name) != fid:
            frames.append((fid, m.body(frame.name).id, False))
    err = {"M": 0.0, "bias": 0.0, "frames": 0.0}
    m_mj = np.zeros((m.nv, m.nv))
    for _ in range(n_states):
        qpos, qvel = _random_mj_state(robot, rng)
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, m_mj)  # MuJoCo 4 signature (mjData.qM is gone)
        q, v = mj_to_pin(robot, qpos, qvel)
        m_pin = pin.crba(pm, pd, q)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        err["M"] = max(err["M"], np.abs(mass_matrix_pin_to_mj(robot, q, m_pin) - m_mj).max())
        err["bias"] = max(err["bias"], np.abs(bias_pin_to_mj(robot, pd, q, v) - d.qfrc_bias).max())
        pin.framesForwardKinematics(pm, pd, q)
        for fid, mid, is_site in frames:
            pos = d.site_xpos[mid] if is_site else d.xpos[mid]
            rot = (d.site_xmat[mid] if is_site else d.xmat[mid]).reshape(3, 3)
            placement = pd.oMf[fid]
            e = max(
                np.abs(placement.translation - pos).max(), np.abs(placement.rotation - rot).max()
            )
            err["frames"] = max(err["frames"], e)
    return err


@pytest.mark.parametrize("name", SHIPPED, ids=lambda n: Path(n).stem)
def test_shipped_robot_parity_of_mass_bias_and_jacobians(name: str) -> None:
    """M(q), the bias forces and every site's and body's Jacobian, relative to the largest
    entry of MuJoCo's, agree to PARITY_TOLERANCE (1e-12) at 10 random states."""
    parity = model_parity(load_robot(name), states=10, seed=4)
    assert parity.worst <= PARITY_TOLERANCE, parity


@pytest.mark.parametrize("name", ["tocabi_like", "comanplus_like"])
def test_generated_model_parity(name: str) -> None:
    err = parity_errors(_robot(name), N_STATES)
    assert err["M"] <= TOL, err
    assert err["bias"] <= TOL, err
    assert err["frames"] <= TOL, err


@pytest.mark.parametrize("name", ["tocabi_like", "comanplus_like"])
def test_state_conversions_round_trip_and_match_transform(name: str) -> None:
    robot = _robot(name)
    rng = np.random.default_rng(1)
    for _ in range(10):
        qpos, qvel = _random_mj_state(robot, rng)
        q, v = mj_to_pin(robot, qpos, qvel)
        assert q[3:7] == pytest.approx(qpos[[4, 5, 6, 3]], abs=1e-15)
        assert v == pytest.approx(base_velocity_transform(robot, q) @ qvel, abs=1e-12)
        qpos2, qvel2 = pin_to_mj(robot, q, v)
        assert qpos2 == pytest.approx(qpos, abs=1e-14)
        assert qvel2 == pytest.approx(qvel, abs=1e-12)
        tau = rng.normal(size=robot.nv)
        t = base_velocity_transform(robot, q)
        assert force_pin_to_mj(robot, q, tau) == pytest.approx(t.T @ tau, abs=1e-12)


@pytest.mark.parametrize("name", ["tocabi_like", "comanplus_like"])
def test_base_velocity_matches_mujoco_body_velocity(name: str) -> None:
    """Pinocchio's base twist (LOCAL) from the converted v equals MuJoCo's body velocity."""
    robot = _robot(name)
    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    pd = robot.pin_model.createData()
    qpos, qvel = _random_mj_state(robot, np.random.default_rng(2))
    d.qpos[:], d.qvel[:] = qpos, qvel
    mujoco.mj_forward(m, d)
    q, v = mj_to_pin(robot, qpos, qvel)
    pin.forwardKinematics(robot.pin_model, pd, q, v)
    for frame in ("l_sole", "r_hand"):
        twist = pin.getFrameVelocity(
            robot.pin_model, pd, robot.frame_id(frame), pin.ReferenceFrame.LOCAL
        )
        res = np.zeros(6)  # MuJoCo: [angular, linear] in the site frame
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, m.site(frame).id, res, 1)
        assert twist.angular == pytest.approx(res[0:3], abs=1e-10)
        assert twist.linear == pytest.approx(res[3:6], abs=1e-10)


@pytest.mark.parametrize("name", ["tocabi_like", "comanplus_like"])
def test_torque_to_ctrl_drives_the_named_joints(name: str) -> None:
    robot = _robot(name)
    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    tau = np.linspace(-1.0, 1.0, robot.k) * np.minimum(robot.tau_max, 10.0)
    d.ctrl[:] = torque_to_ctrl(robot, tau)
    mujoco.mj_forward(m, d)
    q, _ = mj_to_pin(robot, d.qpos)
    expected = force_pin_to_mj(robot, q, np.concatenate([np.zeros(6), tau]))
    assert d.qfrc_actuator == pytest.approx(expected, abs=1e-12)


# ---------------------------------------------------------------------------------------------
# URDF

_URDF = """<?xml version="1.0"?>
<robot name="mini">
  <link name="base">
    <inertial><origin xyz="0 0 0.05"/><mass value="6"/>
      <inertia ixx="0.08" iyy="0.06" izz="0.05" ixy="0.001" ixz="0.002" iyz="0.003"/></inertial>
    <collision><geometry><box size="0.2 0.3 0.2"/></geometry></collision>
  </link>
  {legs}
  <link name="head"><inertial><mass value="0.8"/>
    <inertia ixx="0.004" iyy="0.004" izz="0.003" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="head_mount" type="fixed"><parent link="base"/><child link="head"/>
    <origin xyz="0 0 0.3" rpy="0 0 0.4"/></joint>
</robot>
"""

_LEG = """
  <link name="{s}_thigh"><inertial><origin xyz="0 0 -0.15"/><mass value="2"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.004" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="{s}_shank"><inertial><origin xyz="0.01 0 -0.15" rpy="0.1 0 0"/><mass value="1.5"/>
    <inertia ixx="0.015" iyy="0.014" izz="0.003" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="{s}_foot"><inertial><origin xyz="0.03 0 -0.03"/><mass value="0.7"/>
    <inertia ixx="0.001" iyy="0.003" izz="0.003" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="{s}_hip" type="revolute"><parent link="base"/><child link="{s}_thigh"/>
    <origin xyz="0 {y} -0.05" rpy="0.2 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.0" effort="{e}" velocity="7"/><dynamics damping="0.1"/></joint>
  <joint name="{s}_knee" type="revolute"><parent link="{s}_thigh"/><child link="{s}_shank"/>
    <origin xyz="0 0 -0.3"/><axis xyz="0.6 0.8 0"/>
    <limit lower="0" upper="2.2" effort="60" velocity="9"/></joint>
  <joint name="{s}_ankle" type="fixed"><parent link="{s}_shank"/><child link="{s}_foot"/>
    <origin xyz="0 0 -0.3"/></joint>
"""


def write_urdf(directory: Path) -> Path:
    """A small floating-base biped URDF: 4 revolute joints, fixed feet and head."""
    legs = _LEG.format(s="r", y=-0.1, e=80) + _LEG.format(s="l", y=0.1, e=90)
    path = directory / "mini.urdf"
    path.write_text(_URDF.format(legs=legs), encoding="utf-8")
    return path


def test_urdf_loads_with_floating_base_and_parity(tmp_path: Path) -> None:
    robot = load_robot(write_urdf(tmp_path))
    assert robot.name == "mini"
    assert robot.k == 4 and robot.nq == 11 and robot.nv == 10
    assert set(robot.joint_names) == {"l_hip", "l_knee", "r_hip", "r_knee"}
    limits = dict(zip(robot.joint_names, robot.tau_max, strict=True))
    assert limits == {"l_hip": 90.0, "l_knee": 60.0, "r_hip": 80.0, "r_knee": 60.0}
    assert robot.v_max[robot.joint_index("l_knee")] == 9.0
    assert robot.q_min[robot.joint_index("r_hip")] == -1.5
    assert robot.damping[robot.joint_index("r_hip")] == pytest.approx(0.1)
    assert robot.info.contact_frames == ()
    for frame in ("base", "l_foot", "r_foot", "head"):
        assert robot.has_frame(frame)
    err = parity_errors(robot, N_STATES, seed=3)
    assert max(err.values()) <= TOL, err
    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    tau = np.array([1.0, 2.0, 3.0, 4.0])
    d.ctrl[:] = torque_to_ctrl(robot, tau)
    mujoco.mj_forward(m, d)
    assert d.qfrc_actuator[robot.mj_dof_adr] == pytest.approx(tau)
