"""RobotState against Pinocchio's own routines and finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from wbcbench.dynamics.state import RobotState
from wbcbench.robots.loader import Robot

from .conftest import random_standing_state


def _states(robot: Robot, seed: int, n: int = 5):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q, v = random_standing_state(robot, rng, q_noise=0.3, v_noise=1.0)
        yield q, v


def test_inertia_bias_gravity(robot: Robot) -> None:
    model = robot.pin_model
    data = model.createData()
    for q, v in _states(robot, 0):
        s = RobotState(robot, q, v)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        np.testing.assert_allclose(s.M, M, atol=1e-10)
        np.testing.assert_allclose(s.M, s.M.T, atol=0)
        np.testing.assert_allclose(s.Minv @ s.M, np.eye(s.n), atol=1e-8)
        np.testing.assert_allclose(s.h, pin.rnea(model, data, q, v, np.zeros(s.n)), atol=1e-9)
        np.testing.assert_allclose(s.g, pin.computeGeneralizedGravity(model, data, q), atol=1e-9)
        assert s.S.shape == (robot.k, s.n)


def _fd(robot: Robot, q: np.ndarray, v: np.ndarray, f, eps: float = 1e-6) -> np.ndarray:
    """d/dt f(q(t)) at q̈ = 0 by central differences along q(t) = q ⊕ v t."""
    qp = pin.integrate(robot.pin_model, q, v * eps)
    qm = pin.integrate(robot.pin_model, q, -v * eps)
    return (f(RobotState(robot, qp, v)) - f(RobotState(robot, qm, v))) / (2 * eps)


def test_drifts_match_finite_differences(robot: Robot) -> None:
    frames = robot.info.contact_frames + robot.info.hand_frames
    for q, v in _states(robot, 1, n=3):
        s = RobotState(robot, q, v)
        fd = _fd(robot, q, v, lambda x: x.J_com @ x.v)
        np.testing.assert_allclose(s.com_drift, fd, atol=1e-5)
        fd = _fd(robot, q, v, lambda x: x.cmm @ x.v)
        np.testing.assert_allclose(s.cmm_drift, fd, atol=1e-4 * max(1, np.abs(fd).max()))
        for f in frames:
            for local in (False, True):
                fd = _fd(robot, q, v, lambda x, f=f, local=local: x.jacobian(f, local) @ x.v)
                np.testing.assert_allclose(s.drift(f, local), fd, atol=1e-5, err_msg=f)


def test_jacobians_match_finite_differences_of_positions(robot: Robot) -> None:
    frame = robot.info.hand_frames[0]
    for q, v in _states(robot, 2, n=2):
        s = RobotState(robot, q, v)
        fd = _fd(robot, q, v, lambda x: x.position(frame))
        np.testing.assert_allclose(s.jacobian(frame)[:3] @ v, fd, atol=1e-6)
        fd = _fd(robot, q, v, lambda x: x.com)
        np.testing.assert_allclose(s.J_com @ v, fd, atol=1e-6)


def test_quantities_are_cached_and_timed(tocabi: Robot) -> None:
    q, v = tocabi.keyframe("stand")
    s = RobotState(tocabi, q, v)
    assert s.compute_time == 0.0
    M = s.M
    spent = s.compute_time
    assert spent > 0
    assert s.M is M
    assert s.compute_time == spent
    assert s.contact_jacobian(["l_sole", "r_sole"]).shape == (12, tocabi.nv)
