"""Shared fixtures: robots are loaded once per test session."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wbcbench import _native
from wbcbench.qp import available_solvers
from wbcbench.qp.registry import NAMED_SETTINGS
from wbcbench.robots.loader import Robot, load_robot

ROBOTS = ("tocabi_like", "comanplus_like")

# One BLAS thread for the whole session, as every command of the harness runs its control loops:
# a product's rounding depends on how BLAS splits it, and the equality tests compare answers of
# nearly degenerate QPs, so the thread count must not depend on which test ran first.
threadpool_limits(1)

#: the impls every controller with a native tick is tested on
IMPLS = ["python", "native"] if _native.BUILT else ["python"]

#: every installed solver that runs at any tier and mode: the backends and their qpsolvers
#: wrappers (a named setting such as osqp_libdwbc runs at its own tier and mode only)
ANY_TIER_SOLVERS = [s for s in available_solvers() if s not in NAMED_SETTINGS]


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


def grounded_state(
    robot: Robot,
    keyframe: str,
    frames: list[str],
    rng: np.random.Generator,
    q_noise: float = 0.1,
    v_noise: float = 0.3,
) -> tuple[np.ndarray, np.ndarray]:
    """A perturbed state that the rigid contacts admit: the keyframe's joints offset by
    ±``q_noise`` rad, then the contact frames put back on their keyframe placements (Gauss–Newton
    on the base and the joints, minimal-norm steps); velocities uniform in ±``v_noise`` projected
    onto J_c v = 0, so the soles neither penetrate, slide nor lift."""
    import pinocchio as pin

    from wbcbench.dynamics.state import RobotState

    model = robot.pin_model
    q0, _ = robot.keyframe(keyframe)
    goal = [RobotState(robot, q0, np.zeros(robot.nv)).placement(f) for f in frames]
    q = q0.copy()
    q[7:] = np.clip(q[7:] + rng.uniform(-q_noise, q_noise, robot.k), robot.q_min, robot.q_max)
    for _ in range(50):
        state = RobotState(robot, q, np.zeros(robot.nv))
        err = np.concatenate(
            [
                pin.log6(g.actInv(state.placement(f))).vector
                for f, g in zip(frames, goal, strict=True)
            ]
        )
        if np.abs(err).max() < 1e-12:
            break
        dq = -np.linalg.lstsq(state.contact_jacobian(frames), err, rcond=None)[0]
        q = pin.integrate(model, q, dq)
    else:
        raise RuntimeError("the soles could not be put back on the ground")
    Jc = RobotState(robot, q, np.zeros(robot.nv)).contact_jacobian(frames)
    v = rng.uniform(-v_noise, v_noise, robot.nv)
    v -= np.linalg.lstsq(Jc, Jc @ v, rcond=None)[0]
    return q, v


@pytest.fixture
def runs_in_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """Sweep runs in this process instead of a child of the guard's fork server: for tests whose
    monkeypatches must reach the run (the fork server's children never see them). The guard
    itself is tested in ``test_guard.py``."""
    from wbcbench.bench import guard

    monkeypatch.setattr(guard, "can_guard", lambda: False)
