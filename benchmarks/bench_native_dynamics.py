"""The per-tick dynamics, native against the Python reference (RobotState), same state."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.dynamics.state import RobotState
from wbcbench.robots.loader import load_robot

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

TASKS = ["pelvis", "l_hand", "r_hand", "torso"]
CONTACTS = ["l_sole", "r_sole"]


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("tocabi_like")
    q, v = robot.keyframe("stand")
    rng = np.random.default_rng(0)
    q = q.copy()
    q[7:] += rng.uniform(-0.05, 0.05, robot.k)
    v = rng.uniform(-0.2, 0.2, robot.nv)
    return robot, q, v


def test_native_dynamics(benchmark, setup) -> None:
    robot, q, v = setup
    native = _native.robot_dynamics(robot, TASKS, CONTACTS)
    benchmark(native.update, q, v)


def test_python_dynamics(benchmark, setup) -> None:
    robot, q, v = setup
    data = robot.pin_model.createData()

    def tick() -> list[np.ndarray]:
        s = RobotState(robot, q, v, data)
        out = [s.M, s.Minv, s.h, s.g, s.J_com, s.com_drift, s.cmm]
        out += [s.contact_jacobian(CONTACTS), s.contact_drift(CONTACTS)]
        for f in TASKS:
            out += [s.jacobian(f), s.drift(f)]
        return out

    benchmark(tick)
