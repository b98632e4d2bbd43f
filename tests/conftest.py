"""Shared fixtures: robots are loaded once per test session."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.robots.loader import Robot, load_robot

ROBOTS = ("tocabi_like", "comanplus_like")


@pytest.fixture(scope="session", params=ROBOTS)
def robot(request: pytest.FixtureRequest) -> Robot:
    return load_robot(request.param)


@pytest.fixture(scope="session")
def tocabi() -> Robot:
    return load_robot("tocabi_like")


@pytest.fixture(scope="session")
def comanplus() -> Robot:
    return load_robot("comanplus_like")


def random_standing_state(
    robot: Robot, rng: np.random.Generator, q_noise: float = 0.05, v_noise: float = 0.2
) -> tuple[np.ndarray, np.ndarray]:
    """The standing keyframe with random joint offsets and random velocities."""
    q, _ = robot.keyframe("stand")
    q = q.copy()
    q[7:] += rng.uniform(-q_noise, q_noise, robot.k)
    q[7:] = np.clip(q[7:], robot.q_min, robot.q_max)
    v = rng.uniform(-v_noise, v_noise, robot.nv)
    return q, v
