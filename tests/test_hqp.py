"""hqp against the rigid-contact forward-dynamics oracle: contacts, wrench and strict hierarchy."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers.base import ControllerContext
from wbcbench.controllers.hqp import Hqp, HqpConfig
from wbcbench.dynamics.state import RobotState
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.robots.loader import Robot
from wbcbench.tasks.contacts import PlaneContact
from wbcbench.tasks.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePoseTask,
    JointPostureTask,
    Task,
)

from .conftest import IMPLS, random_standing_state
from .test_hierarchy import BoundBreaking


def task_pool(robot: Robot) -> list[Task]:
    """Five tasks in priority order (the OSF-HQP Table I structure)."""
    posture = JointPostureTask("posture", priority=5, kp=50.0, kv=14.0)
    posture.bind(robot.joint_names)
    return [
        ComTask("com", priority=1),
        FrameOrientationTask("pelvis", priority=2, frame="pelvis"),
        FramePoseTask("r_hand", priority=3, frame="r_hand"),
        FrameOrientationTask("torso", priority=4, frame="torso"),
        posture,
    ]


def contacts_for(robot: Robot, count: int) -> list[PlaneContact]:
    rects = robot.info.contact_rects
    frames = ["l_sole", "r_sole", "l_palm"][:count]
    return [
        PlaneContact(
            f,
            x_range=(rects[f].x_min, rects[f].x_max),
            y_range=(rects[f].y_min, rects[f].y_max),
            mu=0.8,
            fmin=1.0,
        )
        for f in frames
    ]


def make(
    robot: Robot,
    tasks: list[Task],
    contacts: list[PlaneContact],
    solver: str = "daqp",
    **cfg: object,
) -> Hqp:
    ctx = ControllerContext(
        robot=robot,
        tasks=tasks,
        contacts=contacts,
        # huge limits: the oracle checks the algebra with no inequality active
        tau_max=np.full(robot.k, 1e4),
        solver=solver,
        tier="high",
    )
    return Hqp(ctx, HqpConfig(**cfg))


def inactive(out, contacts: list[PlaneContact], margin: float = 1e-6) -> bool:
    for i, c in enumerate(contacts):
        C, lower, upper = c.wrench_constraints()
        r = C @ out.wrench[6 * i : 6 * i + 6]
        if np.any(r < lower + margin) or np.any(r > upper - margin):
            return False
    return True


@pytest.mark.parametrize("strategy", ["cascade", "nullspace"])
def test_oracle_and_strict_hierarchy_at_100_states(comanplus: Robot, strategy: str) -> None:
    robot = comanplus
    rng = np.random.default_rng(7)
    worst = {"contact_acc": 0.0, "wrench": 0.0, "hierarchy": 0.0}
    checked = failed = 0
    for i in range(100):
        n_tasks = 1 + i % 5
        n_contacts = 1 + (i // 5) % 3
        q, v = random_standing_state(robot, rng, q_noise=0.03, v_noise=0.1)
        if n_contacts == 3:
            q, _ = robot.keyframe("stand_wall")
            q = q.copy()
            q[7:] += rng.uniform(-0.02, 0.02, robot.k)
        contacts = contacts_for(robot, n_contacts)
        frames = [c.frame for c in contacts]
        tasks = task_pool(robot)[:n_tasks]
        fewer = task_pool(robot)[: max(1, n_tasks - 1)]
        outs = []
        for task_set in (tasks, fewer):
            # min ‖f‖² as the final level keeps the wrenches inside their cones (min ‖Γ‖² would
            # push them to the cone boundaries through internal forces)
            ctrl = make(
                robot,
                task_set,
                contacts,
                strategy=strategy,
                finals=["wrench"],
                wrench_weights=[1.0] * 6,
            )
            ctrl.start(RobotState(robot, q, v))
            outs.append(ctrl.step(RobotState(robot, q, v), 0.0))
        full, reduced = outs
        if not (full.ok and reduced.ok):
            # a backend failure on a nearly degenerate level is data for the benchmark, not a
            # wrong answer; the checks below are on every state that solved
            failed += 1
            continue
        state = RobotState(robot, q, v)
        oracle = forward_dynamics(state, full.tau, frames)
        worst["contact_acc"] = max(worst["contact_acc"], float(np.abs(oracle.contact_acc).max()))
        scale = max(1.0, float(np.linalg.norm(full.wrench)))
        err = float(np.linalg.norm(oracle.wrench - full.wrench)) / scale
        worst["wrench"] = max(worst["wrench"], err)
        if n_tasks > 1 and inactive(full, contacts) and inactive(reduced, contacts):
            realized_reduced = forward_dynamics(state, reduced.tau, frames).qdd
            for term_full in full.terms[: n_tasks - 1]:
                a = term_full.realized(oracle.qdd)
                b = term_full.realized(realized_reduced)
                scale_a = max(1.0, float(np.linalg.norm(a)))
                worst["hierarchy"] = max(worst["hierarchy"], float(np.abs(a - b).max()) / scale_a)
            checked += 1
    assert failed <= 5, failed
    assert checked >= 40, checked
    assert worst["contact_acc"] <= 1e-8, worst
    assert worst["wrench"] <= 1e-6, worst
    assert worst["hierarchy"] <= 1e-8, worst


def test_cascade_and_nullspace_give_the_same_torque(tocabi: Robot) -> None:
    rng = np.random.default_rng(3)
    contacts = contacts_for(tocabi, 2)
    compared = 0
    for _ in range(10):
        q, v = random_standing_state(tocabi, rng)
        outs = []
        for strategy in ("cascade", "nullspace"):
            ctrl = make(tocabi, task_pool(tocabi), contacts, "daqp", strategy=strategy, prox=0.0)
            ctrl.start(RobotState(tocabi, q, v))
            outs.append(ctrl.step(RobotState(tocabi, q, v), 0.0))
        if not (outs[0].ok and outs[1].ok):
            continue  # a backend failure at one state is benchmark data, not a wrong answer
        if outs[0].diagnostics["prox_retries"] or outs[1].diagnostics["prox_retries"]:
            continue  # a retried level is regularised: compare the bare hierarchies
        np.testing.assert_allclose(outs[0].tau, outs[1].tau, atol=1e-5 * np.abs(outs[0].tau).max())
        compared += 1
    assert compared >= 4, compared


def test_force_level_joint_damping_sets_torques(tocabi: Robot) -> None:
    """OSF-HQP T4: Γ = −k q̇ at its own level, below the motion tasks."""
    damping = JointPostureTask("damping", priority=3, kv=2.0, level="force")
    damping.bind(tocabi.joint_names)
    tasks = [ComTask("com", priority=1), damping]
    from wbcbench.tasks.tasks import JointDampingTask

    damping = JointDampingTask("damping", priority=3, kv=2.0, level="force")
    damping.bind(tocabi.joint_names)
    tasks = [ComTask("com", priority=1), damping]
    ctrl = make(tocabi, tasks, contacts_for(tocabi, 2), finals=["torque"])
    q, v = random_standing_state(tocabi, np.random.default_rng(1))
    ctrl.start(RobotState(tocabi, q, v))
    out = ctrl.step(RobotState(tocabi, q, v), 0.0)
    assert out.ok
    # CoM held exactly; the torque is the closest to −k q̇ the CoM task and contacts allow
    oracle = forward_dynamics(RobotState(tocabi, q, v), out.tau, ["l_sole", "r_sole"])
    com = out.terms[0]
    np.testing.assert_allclose(com.realized(oracle.qdd), com.acc_ref, atol=1e-7)
    assert np.linalg.norm(out.tau + 2.0 * v[6:]) < np.linalg.norm(2.0 * v[6:]) + 1e3


def test_rqr_strategy_matches_the_qp_cascade_without_active_inequalities(tocabi: Robot) -> None:
    rng = np.random.default_rng(4)
    contacts = contacts_for(tocabi, 2)
    q, v = random_standing_state(tocabi, rng)
    outs = []
    for strategy in ("nullspace", "rqr"):
        ctrl = make(
            tocabi,
            task_pool(tocabi)[:3],
            contacts,
            "quadprog",
            strategy=strategy,
            # min ‖f‖² then min ‖Γ‖²: unique, and inside the cones at this state
            finals=["wrench", "torque"],
            wrench_weights=[1.0] * 6,
        )
        ctrl.start(RobotState(tocabi, q, v))
        outs.append(ctrl.step(RobotState(tocabi, q, v), 0.0))
    assert outs[0].ok and outs[1].ok, outs[1].message
    np.testing.assert_allclose(outs[1].qdd, outs[0].qdd, atol=1e-6)
    assert "solve.L1" in outs[1].timings


@pytest.mark.parametrize("impl", IMPLS)
def test_a_torque_past_its_limit_is_not_an_ok_step(tocabi: Robot, impl: str) -> None:
    """A level QP declared infeasible, then its proximal retry answered with a torque 0.5 N·m
    past its limit and reported solved: the step fails, in both impls, and says why."""
    ctrl = make(tocabi, task_pool(tocabi), contacts_for(tocabi, 2), impl=impl)
    ctrl.solvers[1] = BoundBreaking(0.5, infeasible_first=True)
    q, v = random_standing_state(tocabi, np.random.default_rng(0))
    ctrl.start(RobotState(tocabi, q, v))
    out = ctrl.step(RobotState(tocabi, q, v), 0.0)
    assert not out.ok
    assert out.message == (
        "hqp: level 'L2': daqp: failed: reported solved but violates a bound or a held "
        "inequality by 5.0e-05 > 1e-06 (relative to the problem's scale)"
    )
