"""pink and mink as kin_hqp's peers: what each step guarantees, and a closed-loop run.

Oracles: the weighted least-squares step with the soles held, solved here from wbcbench's own
task Jacobians and references (KKT system by NumPy); the soles' velocity J_c q̇; the joint
limits after integration on the configuration manifold; the collision distances of kin_hqp's
capsule model. Tests of a peer whose library is not installed are skipped with the reason.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.cli import main
from wbcbench.controllers.registry import controller_class
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError, WbcBenchError
from wbcbench.peers.common import INSTALL, PeerController, import_library
from wbcbench.report.load import load_results
from wbcbench.report.plots import peers_figure
from wbcbench.report.tables import TABLES
from wbcbench.robots.loader import Robot
from wbcbench.runs import plan_run, scenario_context, scenario_obstacles
from wbcbench.scenarios.load import controller_settings, load_scenario
from wbcbench.sim.kinematic import run_kinematic

from .conftest import grounded_state

PEERS = ("pink", "mink")
#: a CoM offset and a posture: both map exactly onto the libraries' ComTask and PostureTask
EXACT_TASKS = (
    "tasks=[{name: com, type: com, priority: 1, kp: 10, kv: 0,"
    " reference: {type: constant, value: [0.01, -0.005, -0.01]}},"
    " {name: posture, type: joint_posture, priority: 2, kp: 2, kv: 0}]"
)


def peer(name: str) -> type[PeerController]:
    """The peer's class; the test is skipped with the reason when its library is missing."""
    cls = controller_class(name)
    assert issubclass(cls, PeerController)
    reason = cls.applies_to(load_scenario("rqr_reach").spec)
    if reason:
        pytest.skip(reason)
    return cls


def build(
    name: str, robot: Robot, scenario: str, overrides: tuple[str, ...] = (), **settings: Any
) -> PeerController:
    """The peer as the kinematic runner builds it, with the scenario's settings overridden."""
    cls = peer(name)
    loaded = load_scenario(scenario, list(overrides))
    config = cls.Config(**{**controller_settings(loaded, name), **settings})
    controller = cls(scenario_context(loaded, robot), config)
    controller.use_environment(scenario_obstacles(loaded))
    return controller


def started(controller: PeerController, q: np.ndarray) -> RobotState:
    state = RobotState(controller.ctx.robot, q, np.zeros(controller.ctx.robot.nv))
    controller.start(state)
    return state


# -- the plugin interface ----------------------------------------------------------------------


def test_entry_points_load_without_importing_the_libraries() -> None:
    """The controllers' modules import neither library: the entry points load without them."""
    code = (
        "import sys, wbcbench.peers.pink_ik, wbcbench.peers.mink_ik\n"
        "from wbcbench.controllers.registry import controller_class\n"
        "assert controller_class('pink').name == 'pink' and controller_class('mink')\n"
        "print(sorted({'pink', 'mink', 'qpsolvers'} & set(sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_missing_library_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ControllerError) as exc:
        import_library("pink", "wbcbench_no_such_module", "pin-pink")
    assert str(exc.value).startswith("pink: needs pin-pink (module 'wbcbench_no_such_module')")
    assert str(exc.value).endswith(f"install the peers extra: {INSTALL}")
    cls = controller_class("pink")
    monkeypatch.setattr(cls, "library", "wbcbench_no_such_module")
    reason = cls.applies_to(load_scenario("rqr_reach").spec)
    assert reason == (f"pin-pink (module 'wbcbench_no_such_module') is not installed: {INSTALL}")
    with pytest.raises(WbcBenchError, match=r"pip install 'wbcbench\[peers\]'"):
        plan_run("rqr_reach", "pink")


@pytest.mark.parametrize("name", PEERS)
def test_a_task_the_libraries_cannot_express_is_refused(name: str) -> None:
    cls = controller_class(name)
    spec = load_scenario(
        "comanplus_sway_kinematic",
        ["tasks=[{name: hand, type: frame_pose, frame: r_hand, axes: [x, z]}]"],
    ).spec
    reason = cls.applies_to(spec)
    assert "frame's own axes" in reason or "not installed" in reason


# -- one step ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", PEERS)
def test_unconstrained_step_is_the_weighted_least_squares_step(name: str, comanplus: Robot) -> None:
    """Without limits, q̇ minimises Σ c_i² ‖J_i q̇ − r_i‖² + damping ‖q̇‖² with the soles held
    (J_c q̇ = 0), c_i the priorities' costs and r_i = ẋ_d + λ e: solved here from wbcbench's
    Jacobians by the KKT system."""
    rng = np.random.default_rng(3)
    damping = 1e-4
    for _ in range(3):
        settings = {"collision": False} if name == "mink" else {}
        controller = build(
            name,
            comanplus,
            "comanplus_sway_kinematic",
            (EXACT_TASKS,),
            limits=False,
            damping=damping,
            solver="quadprog",
            **settings,
        )
        q, _ = grounded_state(comanplus, "stand", controller.ctx.contact_frames, rng, q_noise=0.05)
        started(controller, q)
        state = RobotState(comanplus, q, np.zeros(comanplus.nv))
        out = controller.step(state, 0.5)
        assert out.ok, out.message
        assert out.qd is not None

        H = damping * np.eye(comanplus.nv)
        g = np.zeros(comanplus.nv)
        for task in controller.ctx.tasks:
            term = task.evaluate(state, 0.5)
            rate = term.error_vel + term.J @ state.v + task.kp * term.error
            c2 = controller.priority_cost(task) ** 2
            H += c2 * term.J.T @ term.J
            g += c2 * term.J.T @ rate
        Jc = state.contact_jacobian(controller.ctx.contact_frames)
        m = Jc.shape[0]
        kkt = np.block([[H, Jc.T], [Jc, np.zeros((m, m))]])
        expected = np.linalg.solve(kkt, np.concatenate([g, np.zeros(m)]))[: comanplus.nv]
        scale = np.abs(expected).max()
        assert scale > 1e-3
        np.testing.assert_allclose(out.qd, expected, rtol=0, atol=1e-6 * scale)


@pytest.mark.parametrize("name", PEERS)
def test_contacts_held_and_limits_respected_after_integration(name: str, comanplus: Robot) -> None:
    """The soles' velocity is zero (held as equality constraints), every joint stays inside its
    limits after the step's integration and under its velocity bound, while a posture reference
    pulls joints beyond their limits."""
    controller = build(name, comanplus, "rqr_reach")
    q, _ = comanplus.keyframe("stand")
    q = q.copy()
    # three joints a hair inside a limit, a posture task pulling them past it
    joints = [comanplus.joint_index(j) for j in ("R_ShSag", "L_Knee", "WaistYaw")]
    for i, j in enumerate(joints):
        q[7 + j] = (comanplus.q_max if i % 2 == 0 else comanplus.q_min)[j] - (
            1e-3 if i % 2 == 0 else -1e-3
        )
    past = [
        f"{comanplus.joint_names[j]}: {(2.0 if i % 2 == 0 else -2.0):g}"
        for i, j in enumerate(joints)
    ]
    posture = (
        "tasks=[{name: hand, type: frame_position, frame: r_hand, priority: 1, kp: 2, kv: 0,"
        " absolute: true, reference: {type: constant, value: [0.40, -0.25, 1.00]}},"
        " {name: posture, type: joint_posture, priority: 1, kp: 5, kv: 0, absolute: true,"
        f" joints: [{', '.join(comanplus.joint_names[j] for j in joints)}],"
        f" reference: {{type: constant, value: [{', '.join(p.split(': ')[1] for p in past)}]}}}}]"
    )
    controller = build(name, comanplus, "rqr_reach", (posture,))
    state = started(controller, q)
    dt = controller.ctx.dt
    v = np.zeros(comanplus.nv)
    for tick in range(40):
        state = RobotState(comanplus, q, v)
        out = controller.step(state, tick * dt)
        assert out.ok, out.message
        assert out.qd is not None
        soles = state.contact_jacobian(controller.ctx.contact_frames) @ out.qd
        assert np.abs(soles).max() < 1e-7 * max(1.0, np.abs(out.qd).max())
        assert np.all(np.abs(out.qd[6:]) <= controller.v_max * (1 + 1e-6) + 1e-9)
        q = pin.integrate(comanplus.pin_model, q, out.qd * dt)
        v = out.qd
        assert np.all(q[7:] <= comanplus.q_max + 1e-9)
        assert np.all(q[7:] >= comanplus.q_min - 1e-9)
    # the joints moved toward their limits, not away
    assert q[7 + joints[0]] > comanplus.q_max[joints[0]] - 1e-3


def test_mink_collision_limit_is_kin_hqps_distance_rate_bound(comanplus: Robot) -> None:
    """mink's collision limit on rqr_stress (the arm threaded through two frames, 0.5 mm gaps,
    the joints' velocity bound lifted so that the hand pushes into the frame): each step closes
    kin_hqp's capsule distance by no more than ξ_d dt (d − d_safe), up to the step's second
    order, so it never goes below d_safe = 0."""
    controller = build("mink", comanplus, "rqr_stress", velocity_limit=None)
    xi, margin = controller.config.collision_gain, controller.config.collision_margin
    q, _ = comanplus.keyframe("stand")
    started(controller, q)
    v = np.zeros(comanplus.nv)
    dt = controller.ctx.dt
    distances = []
    for tick in range(60):
        state = RobotState(comanplus, q, v)
        out = controller.step(state, tick * dt)
        assert out.ok, out.message
        assert out.qd is not None
        distances.append(out.diagnostics["min_distance"])
        q = pin.integrate(comanplus.pin_model, q, out.qd * dt)
        v = out.qd
    d = np.asarray(distances)
    assert d[0] - d[-1] > 1e-5  # the hand did push toward the frame
    closing = d[:-1] - d[1:]
    assert np.all(closing <= xi * dt * (d[:-1] - margin) + 1e-6)
    assert d.min() >= margin - 1e-6


# -- closed loop -------------------------------------------------------------------------------


@pytest.mark.parametrize("name", PEERS)
def test_closed_loop_reach_tracks(name: str) -> None:
    """A short kinematic run of rqr_reach: the hand closes in on its target at the capped
    speed (0.25 m/s), the soles stay put and the joints inside their limits."""
    peer(name)
    run = plan_run("rqr_reach", name, overrides=["duration=2.5", "metrics.window=[0, 2.5]"])
    result = run_kinematic(run)
    assert result.status == "ok", result.message
    cols = result.log.arrays()
    hand = np.asarray(cols["err.hand.pos"])
    assert hand[0] > 0.39
    assert hand[-1] < 0.05
    assert np.max(cols["contact_drift"]) < 1e-3
    assert np.min(cols["joint_margin"]) >= -1e-9


# -- the report ----------------------------------------------------------------------------------


def test_peers_table_and_figure_from_a_sweep(tmp_path: Path) -> None:
    """A short sweep of the three on rqr_gaze (tracking and the replay of kin_hqp's states)
    fills the peers table, tracking, times and hierarchy columns, and draws its figure."""
    peer("pink")
    peer("mink")
    sweep = tmp_path / "peers.yaml"
    sweep.write_text(
        "version: 1\n"
        "tracking:\n"
        "  - scenarios: [rqr_gaze]\n"
        "    controllers: [kin_hqp, pink, mink]\n"
        "    set: [duration=0.5, 'metrics.window=[0, 0.5]']\n"
        "timing:\n"
        "  - scenarios: [rqr_gaze]\n"
        "    controllers: [kin_hqp, pink, mink]\n"
        "    solvers: [default]\n"
        "    impls: [python]\n"
        "    ticks: 30\n"
        "    warmup: 5\n"
        "    record_with: [kin_hqp]\n"
    )
    out = tmp_path / "res"
    assert main(["sweep", str(sweep), "--out", str(out), "--executor", "serial"]) == 0
    table = TABLES["peers_kinematic"](load_results(out))
    assert table.frame is not None
    frame = table.frame.set_index("controller")
    assert list(frame.index) == ["kin_hqp", "pink", "mink"]
    assert (frame["status"] == "ok").all()
    assert frame["priority 1 error mean / final"].str.startswith("hand ").all()
    assert frame["lower tasks' error mean / final"].str.startswith("gaze ").all()
    assert np.isfinite(frame["t median python [µs]"]).all()
    assert (frame["joint-limit violation [rad]"] == 0.0).all()
    # the strict hierarchy gives the gaze nothing of the hand's level; the weighted QPs do
    residual = frame["priority 1 residual mean / max"].str.split(" / ").str[0].astype(float)
    assert residual["kin_hqp"] < residual["pink"] and residual["kin_hqp"] < residual["mink"]
    figures = out / "figures"
    figures.mkdir(exist_ok=True)
    paths = peers_figure(load_results(out), figures)
    assert [p.name for p in paths] == ["peers_kinematic.png", "peers_kinematic.svg"]
