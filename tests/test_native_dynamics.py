"""The native per-tick dynamics equal RobotState's on the same states (relative 1e-10)."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.dynamics.state import RobotState
from wbcbench.robots.loader import Robot

from .conftest import random_standing_state

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

TASK_FRAMES = {"tocabi_like": ["pelvis", "l_hand", "r_hand"], "comanplus_like": ["pelvis"]}
CONTACTS = ["l_sole", "r_sole"]


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(a) - b), initial=0.0) / max(1.0, np.abs(b).max()))


def test_every_quantity_equals_robot_state(robot: Robot) -> None:
    tasks = TASK_FRAMES[robot.name]
    native = _native.robot_dynamics(robot, tasks, CONTACTS)
    assert (native.nq, native.nv) == (robot.pin_model.nq, robot.nv)
    rng = np.random.default_rng(11)
    for _ in range(25):
        q, v = random_standing_state(robot, rng, q_noise=0.1, v_noise=0.3)
        seconds = native.update(q, v)
        assert seconds > 0
        state = RobotState(robot, q, v)
        pairs = {
            "M": (native.M, state.M),
            "Minv": (native.Minv, state.Minv),
            "h": (native.h, state.h),
            "g": (native.g, state.g),
            "com": (native.com, state.com),
            "J_com": (native.J_com, state.J_com),
            "com_drift": (native.com_drift, state.com_drift),
            "cmm": (native.cmm, state.cmm),
            "J_c": (native.contact_jacobian, state.contact_jacobian(CONTACTS)),
            "dJc_v": (native.contact_drift, state.contact_drift(CONTACTS)),
        }
        for i, frame in enumerate(tasks):
            pairs[f"J {frame}"] = (native.task_jacobian(i), state.jacobian(frame))
            pairs[f"dJv {frame}"] = (native.task_drift(i), state.drift(frame))
        for name, (a, b) in pairs.items():
            assert np.shape(a) == np.shape(b), name
            assert relative(a, b) <= 1e-10, (name, relative(a, b))
        assert native.mass == pytest.approx(state.mass, rel=1e-12)


def test_bad_input_is_an_error_not_a_crash(tocabi: Robot) -> None:
    with pytest.raises(ValueError, match="unknown frame 'nosuch'"):
        _native.robot_dynamics(tocabi, ["nosuch"], [])
    native = _native.robot_dynamics(tocabi, ["pelvis"], [])
    q, v = tocabi.keyframe("stand")
    with pytest.raises(ValueError, match="wrong size"):
        native.update(q[:-1], v)
    with pytest.raises(IndexError):
        native.task_jacobian(3)
    native.update(q, v)
    assert native.contact_jacobian.shape == (0, tocabi.nv)


def test_the_status_names_the_compiler() -> None:
    info = _native.status()
    assert info["built"] and info["compiler"] and "-O3" in info["flags"]
