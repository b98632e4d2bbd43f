"""Shared fixtures: robots are loaded once per test session."""

from __future__ import annotations

import os

# One thread for every BLAS and OpenMP runtime, including those loaded after this file (scipy's
# own OpenBLAS is loaded when the solver backends are first imported): see the limit below.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import numpy as np  # noqa: E402 - the thread counts above must be set before any BLAS loads
import pytest  # noqa: E402
import scipy.linalg  # noqa: E402, F401 - loads scipy's OpenBLAS before the limit below
from threadpoolctl import threadpool_limits  # noqa: E402

from wbcbench import _native  # noqa: E402
from wbcbench.qp import available_solvers  # noqa: E402
from wbcbench.qp.registry import NAMED_SETTINGS  # noqa: E402
from wbcbench.robots.loader import Robot, load_robot  # noqa: E402

ROBOTS = ("tocabi_like", "comanplus_like")

#: the impls every controller with a native tick is tested on
IMPLS = ["python", "native"] if _native.BUILT else ["python"]

#: every installed solver that runs at any tier and mode: the backends and their qpsolvers
#: wrappers (a named setting such as osqp_libdwbc runs at its own tier and mode only)
ANY_TIER_SOLVERS = [s for s in available_solvers() if s not in NAMED_SETTINGS]

# One BLAS thread for the whole session, as every command of the harness runs its control loops:
# a product's rounding depends on how BLAS splits it, and the equality tests compare answers of
# nearly degenerate QPs, so the thread count must not depend on which tests were collected or
# ran first. Applied after the imports above, which load every BLAS the backends use (scipy's
# own OpenBLAS among them: limited before it was loaded, it kept its default thread count unless
# another test module happened to limit it again, and TO-OSF's pinv ablation on the wall states
# moved by 10x with it); the environment above covers any runtime loaded later.
threadpool_limits(1)


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread() -> None:
    """Every runtime at one thread when the first test runs, whatever the collected modules
    loaded in the meantime (asserted, so a new runtime that ignores the limit is noticed)."""
    from threadpoolctl import threadpool_info

    threadpool_limits(1)
    assert all(info["num_threads"] == 1 for info in threadpool_info()), threadpool_info()


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
