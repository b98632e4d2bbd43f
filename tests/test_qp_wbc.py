"""qp_wbc against the rigid-contact forward-dynamics oracle, with every installed backend."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers.qp_wbc import QpWbc, QpWbcConfig
from wbcbench.dynamics.state import RobotState
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.qp import Problem, make_solver
from wbcbench.robots.loader import Robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import load_scenario

from .conftest import ANY_TIER_SOLVERS, IMPLS, random_standing_state


def objective(problem: Problem, x: np.ndarray) -> float:
    return float(0.5 * x @ problem.H @ x + problem.g @ x)


SCENARIO = {"tocabi_like": "tocabi_stand_sway", "comanplus_like": "comanplus_stand_sway"}


def make_qp_wbc(
    robot: Robot, solver: str = "proxqp", tier: str = "high", **config: object
) -> QpWbc:
    loaded = load_scenario(SCENARIO[robot.name])
    ctx = scenario_context(loaded, robot, solver=solver, tier=tier, keep_problems=True)
    return QpWbc(ctx, QpWbcConfig(**config))  # type: ignore[arg-type]


def check_against_oracle(robot: Robot, controller: QpWbc, n_states: int, seed: int) -> dict:
    """Max oracle residuals over random standing states (relative to the wrench size)."""
    rng = np.random.default_rng(seed)
    worst = {"contact_acc": 0.0, "wrench_rel": 0.0, "qdd_rel": 0.0}
    frames = controller.ctx.contact_frames
    q0, v0 = robot.keyframe("stand")
    controller.start(RobotState(robot, q0, v0))
    for _ in range(n_states):
        q, v = random_standing_state(robot, rng)
        state = RobotState(robot, q, v)
        out = controller.step(state, t=float(rng.uniform(0, 10)))
        assert out.ok, out.message
        oracle = forward_dynamics(RobotState(robot, q, v), out.tau, frames)
        scale_f = max(1.0, float(np.linalg.norm(out.wrench)))
        scale_a = max(1.0, float(np.linalg.norm(out.qdd)))
        worst["contact_acc"] = max(worst["contact_acc"], float(np.abs(oracle.contact_acc).max()))
        worst["wrench_rel"] = max(
            worst["wrench_rel"], float(np.linalg.norm(oracle.wrench - out.wrench)) / scale_f
        )
        worst["qdd_rel"] = max(
            worst["qdd_rel"], float(np.linalg.norm(oracle.qdd - out.qdd)) / scale_a
        )
    return worst


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("variables", ["full", "eliminated"])
def test_oracle_100_states(robot: Robot, variables: str, impl: str) -> None:
    controller = make_qp_wbc(robot, "proxqp", "high", variables=variables, impl=impl)
    assert controller.impl == impl
    worst = check_against_oracle(robot, controller, n_states=100, seed=1)
    assert worst["contact_acc"] <= 1e-6, worst
    assert worst["wrench_rel"] <= 1e-6, worst
    assert worst["qdd_rel"] <= 1e-6, worst


@pytest.mark.parametrize("solver", ANY_TIER_SOLVERS)
def test_oracle_every_backend(tocabi: Robot, solver: str) -> None:
    controller = make_qp_wbc(tocabi, solver, "mid")
    worst = check_against_oracle(tocabi, controller, n_states=10, seed=2)
    assert worst["contact_acc"] <= 1e-6, worst
    assert worst["wrench_rel"] <= 1e-6, worst


def test_full_and_eliminated_give_the_same_optimum(tocabi: Robot) -> None:
    full = make_qp_wbc(tocabi, variables="full")
    elim = make_qp_wbc(tocabi, variables="eliminated")
    rng = np.random.default_rng(3)
    q0, v0 = tocabi.keyframe("stand")
    for c in (full, elim):
        c.start(RobotState(tocabi, q0, v0))
    for _ in range(10):
        q, v = random_standing_state(tocabi, rng)
        a = full.step(RobotState(tocabi, q, v), 3.0)
        b = elim.step(RobotState(tocabi, q, v), 3.0)
        np.testing.assert_allclose(a.tau, b.tau, atol=1e-5 * max(1, np.abs(a.tau).max()))
        np.testing.assert_allclose(a.qdd, b.qdd, atol=1e-6 * max(1, np.abs(a.qdd).max()))


def test_torque_limits_and_wrench_cone_hold(tocabi: Robot) -> None:
    controller = make_qp_wbc(tocabi)
    rng = np.random.default_rng(4)
    q0, v0 = tocabi.keyframe("stand")
    controller.start(RobotState(tocabi, q0, v0))
    for _ in range(10):
        q, v = random_standing_state(tocabi, rng)
        out = controller.step(RobotState(tocabi, q, v), 4.0)
        assert np.all(np.abs(out.tau) <= controller.ctx.tau_max + 1e-6)
        for i, contact in enumerate(controller.ctx.contacts):
            viol = contact.violation(out.wrench[6 * i : 6 * i + 6])
            assert max(viol.values()) <= 1e-6, viol


def test_every_backend_solves_a_saved_problem_to_the_same_optimum(tocabi: Robot, tmp_path) -> None:
    controller = make_qp_wbc(tocabi)
    q0, v0 = tocabi.keyframe("stand")
    controller.start(RobotState(tocabi, q0, v0))
    q, v = random_standing_state(tocabi, np.random.default_rng(5))
    out = controller.step(RobotState(tocabi, q, v), 2.5)
    path = tmp_path / "qp_wbc.npz"
    out.problems[0].save(path)
    problem = Problem.load(path)
    reference = make_solver("proxqp", tier="high").solve(problem)
    assert reference.success
    ref_obj = objective(problem, reference.x)
    for solver in ANY_TIER_SOLVERS:
        sol = make_solver(solver, tier="mid").solve(problem)
        assert sol.success, f"{solver}: {sol.message}"
        gap = abs(objective(problem, sol.x) - ref_obj) / max(1.0, abs(ref_obj))
        assert gap <= 1e-4, (solver, gap)
