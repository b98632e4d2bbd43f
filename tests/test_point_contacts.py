"""Point and line contacts: a humanoid whose legs have 5 joints (no ankle roll, as Unitree H1's)
stands and sways on line contacts (two points per sole) with every torque-level controller.

The robot is the shipped tocabi_like file with its ankle-roll joints (and their motors) taken
out: each foot is then welded to its ankle-pitch link, and two flat 6-D contacts have a contact
Jacobian of rank 11 of 12. A point's rows are checked against Pinocchio's own Jacobian of a frame
added at the point; each controller's tick against the rigid-contact oracle (DESIGN §4); the
native tick against the Python one; and short closed-loop runs in MuJoCo.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import wbcbench.robots
from tests.conftest import IMPLS, grounded_state
from wbcbench.cli import main
from wbcbench.controllers.registry import controller_class
from wbcbench.dynamics.state import RobotState, contact_basis
from wbcbench.errors import ScenarioError
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.robots.loader import Robot
from wbcbench.runs import plan_run, scenario_context
from wbcbench.scenarios.load import load_scenario, load_scenario_robot
from wbcbench.scenarios.preflight import contact_rank
from wbcbench.sim.closed_loop import run_closed_loop
from wbcbench.tasks.contacts import frame_wrenches

CONTROLLERS = ["qp_wbc", "hqp", "lqp", "rc_lqp", "to_osf", "osf_hqp"]
NATIVE = [c for c in CONTROLLERS if controller_class(c).has_native]
#: the points of each sole's line contact, along its x axis [m]
LINE = [[0.12, 0.0, 0.0], [-0.12, 0.0, 0.0]]


def five_joint_legs(folder: Path) -> Path:
    """tocabi_like without its ankle-roll joints: legs of 5 joints, 31 actuated joints."""
    text = (Path(wbcbench.robots.__file__).parent / "models" / "tocabi_like.xml").read_text()
    text = re.sub(r'\s*<joint name="[LR]_AnkleRoll"[^>]*/>', "", text)
    text = re.sub(r'\s*<motor name="[LR]_AnkleRoll"[^>]*/>', "", text)

    def drop_ankle_roll(match: re.Match[str]) -> str:
        values = match.group(2).split()
        del values[7 + 11], values[7 + 5]  # R_AnkleRoll, L_AnkleRoll in qpos
        return f'{match.group(1)}{" ".join(values)}"'

    text = re.sub(r'(<key name="[^"]*" qpos=")([^"]*)"', drop_ankle_roll, text)
    path = folder / "five_joint_legs.xml"
    path.write_text(text.replace('model="tocabi_like"', 'model="five_joint_legs"'))
    return path


def scenario_text(contacts: str, duration: float = 2.2) -> str:
    return f"""version: 1
description: legs of 5 joints on line contacts, CoM ±20 mm along x
robot: five_joint_legs.xml
initial: {{keyframe: stand}}
duration: {duration}
control_rate: 1000
contacts:
{contacts}
tasks:
  - name: com
    type: com
    priority: 1
    reference: {{type: spline_there_and_back, t0: 0.1, t1: 2.1, amplitude: [0.02, 0.0, 0.0]}}
  - name: pelvis
    type: frame_orientation
    frame: pelvis
    priority: 1
  - name: torso
    type: frame_orientation
    frame: torso
    priority: 2
  - name: posture
    type: joint_posture
    priority: 3
    kp: 50
    kv: 14
metrics:
  window: [0.1, 2.1]
"""


LINE_CONTACTS = "\n".join(
    f"  - {{frame: {s}_sole, type: line, points: {LINE}, mu: 0.5, fmin: 10}}" for s in "lr"
)

FLAT_CONTACTS = "\n".join(
    f"  - {{frame: {s}_sole, mu: 0.5, fmin: 10, cop: {{x: [-0.12, 0.12], y: [-0.05, 0.05]}}}}"
    for s in "lr"
)


@pytest.fixture(scope="module")
def robot(sway: Path) -> Robot:
    return load_scenario_robot(load_scenario(sway))


@pytest.fixture(scope="module")
def sway(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("five_joint_legs")
    five_joint_legs(folder)
    path = folder / "line_sway.yaml"
    path.write_text(scenario_text(LINE_CONTACTS))
    return path


def test_point_rows_are_the_jacobian_of_a_frame_at_the_point(sway: Path, robot: Robot) -> None:
    """A point's rows and drift: Pinocchio's LOCAL Jacobian and classical acceleration of a frame
    added at the point (same axes as the contact frame), at a random state."""
    loaded = load_scenario(sway)
    ctx = scenario_context(loaded, robot)
    contact = ctx.contacts[0]
    model = robot.pin_model.copy()
    parent = model.frames[robot.frame_id(contact.frame)]
    ids = [
        model.addFrame(
            pin.Frame(
                f"point{i}",
                parent.parentJoint,
                parent.parentFrame,
                parent.placement * pin.SE3(np.eye(3), np.asarray(p)),
                pin.FrameType.OP_FRAME,
            )
        )
        for i, p in enumerate(contact.points or ())
    ]
    rng = np.random.default_rng(7)
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    v = rng.uniform(-1, 1, model.nv)
    data = model.createData()
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    J = np.vstack([pin.getFrameJacobian(model, data, i, pin.ReferenceFrame.LOCAL)[:3] for i in ids])
    drift = np.concatenate(
        [
            pin.getFrameClassicalAcceleration(model, data, i, pin.ReferenceFrame.LOCAL).linear
            for i in ids
        ]
    )
    state = RobotState(robot, q, v)
    np.testing.assert_allclose(state.contact_jacobian([contact]), J, atol=1e-12)
    np.testing.assert_allclose(state.contact_drift([contact]), drift, atol=1e-10)
    # the independent rows: 5 of the line's 6, the same constraint
    Jk, dk = state.contact_constraint([contact])
    assert Jk.shape == (5, robot.nv)
    np.testing.assert_allclose(np.linalg.pinv(Jk) @ Jk @ J.T, J.T, atol=1e-9)
    T = contact_basis(contact.points)
    np.testing.assert_allclose(T @ T.T, np.eye(5), atol=1e-12)
    np.testing.assert_allclose(dk, T @ drift, atol=1e-10)


def test_rank_warning_names_the_line_contact(sway: Path, robot: Robot) -> None:
    """Flat soles on these legs: the warning gives the line contact to write instead, and the
    line contacts it gives have full rank."""
    path = sway.parent / "flat.yaml"
    path.write_text(scenario_text(FLAT_CONTACTS))
    loaded = load_scenario(path)
    q0, _ = robot.keyframe("stand")
    flat_contacts = scenario_context(loaded, robot).contacts
    why = contact_rank(robot, q0, flat_contacts)
    assert why.startswith("the contact Jacobian has rank 11 of 12 at the initial posture: ")
    assert why.endswith(
        "give such a foot a line contact (forces only, along the axis its leg cannot turn "
        "about; points in the contact frame [m]) in 'contacts:': "
        "{frame: l_sole, type: line, points: [[0.12, 0, 0], [-0.12, 0, 0]]}; "
        "{frame: r_sole, type: line, points: [[0.12, 0, 0], [-0.12, 0, 0]]}"
    ), why
    lines = scenario_context(load_scenario(sway), robot).contacts
    assert contact_rank(robot, q0, lines) == ""


@pytest.mark.parametrize(
    ("contact", "key", "message"),
    [
        (
            "{frame: l_sole, type: line, points: [[0.1, 0, 0]]}",
            "contacts[0].points",
            "a line contact has 2 point(s), got 1",
        ),
        (
            "{frame: l_sole, points: [[0.1, 0, 0]]}",
            "contacts[0].points",
            "a flat contact has no points (it holds a 6-D wrench over its 'cop' box); give "
            "type: point, line or polygon to hold forces at points",
        ),
        (
            "{frame: l_sole, type: polygon, points: [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]}",
            "contacts[0].points",
            "the points of a polygon contact are collinear: [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], "
            "[0.2, 0.0, 0.0]]; give type: line with two of them",
        ),
        (
            "{frame: l_sole, type: point, cop: {x: [-0.1, 0.1], y: [-0.05, 0.05]}}",
            "contacts[0]",
            "'cop' is a flat contact's; a point contact holds no moment (its points bound its "
            "centre of pressure): remove it",
        ),
        (
            "{frame: l_sole, type: edge, points: [[0.1, 0, 0], [-0.1, 0, 0]]}",
            "contacts[0].type",
            "'flat', 'point', 'line' or 'polygon'",
        ),
    ],
)
def test_bad_point_contacts_are_named(sway: Path, contact: str, key: str, message: str) -> None:
    path = sway.parent / "bad.yaml"
    path.write_text(scenario_text(f"  - {contact}"))
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert str(path) in str(err.value)
    assert f"{key}: " in str(err.value)
    assert message in str(err.value)


def exact_solver(controller: str) -> str:
    return "quadprog" if controller in ("lqp", "rc_lqp") else "daqp"


CASES = [(c, impl) for c in CONTROLLERS for impl in (IMPLS if c in NATIVE else ["python"])]


@pytest.mark.parametrize(("controller", "impl"), CASES)
def test_ticks_on_line_contacts_realise_their_prediction(
    sway: Path, robot: Robot, controller: str, impl: str
) -> None:
    """The oracle at perturbed states: the q̈ and the soles' wrenches the tick predicts are
    the ones the torque realises, each point's force is in its friction pyramid with at least
    f_min of normal force, and the torque limits hold."""
    loaded = load_scenario(sway)
    ctx = scenario_context(loaded, robot, solver=exact_solver(controller), tier="high")
    cls = controller_class(controller)
    ctrl = cls(ctx, cls.Config(impl=impl))
    rng = np.random.default_rng(29)
    ok = 0
    for _ in range(4):
        q, v = grounded_state(robot, "stand", ctx.contact_frames, rng, 0.05, 0.2)
        t = float(rng.uniform(0.1, 2.1))
        ctrl.start(RobotState(robot, q, v))
        out = ctrl.step(RobotState(robot, q, v), t)
        if not out.ok:  # hqp's cascade, as on flat soles (test_oracle.py): a lower level
            assert controller == "hqp" and out.message  # infeasible to rounding
            continue
        ok += 1
        oracle = forward_dynamics(RobotState(robot, q, v), out.tau, ctx.contacts)
        scale = max(1.0, float(np.abs(out.qdd).max()))
        assert np.abs(oracle.qdd - out.qdd).max() <= 1e-6 * scale
        predicted = frame_wrenches(ctx.contacts, out.wrench)
        assert np.linalg.norm(oracle.wrench - predicted) <= 1e-6 * np.linalg.norm(predicted)
        assert np.abs(oracle.contact_acc).max() <= 1e-8 * scale
        assert out.wrench.size == 12  # 2 soles × 2 points × 3
        for contact, f in zip(ctx.contacts, np.split(out.wrench, 2), strict=True):
            C, lower, upper = contact.wrench_constraints()
            excess = max(float(np.max(lower - C @ f)), float(np.max(C @ f - upper)))
            assert excess <= 1e-5, excess  # osf_hqp carries 1e-6 per level
        assert np.all(np.abs(out.tau) <= ctx.tau_max * (1 + 1e-7))
    assert ok >= (2 if controller == "hqp" else 4), ok


@pytest.mark.skipif("native" not in IMPLS, reason="the native module is not built")
@pytest.mark.parametrize("controller", NATIVE)
def test_native_tick_equals_python_on_line_contacts(
    sway: Path, robot: Robot, controller: str
) -> None:
    loaded = load_scenario(sway)
    ctx = scenario_context(loaded, robot, solver=exact_solver(controller), tier="high")
    cls = controller_class(controller)
    ticks = {impl: cls(ctx, cls.Config(impl=impl)) for impl in ("python", "native")}
    rng = np.random.default_rng(5)
    for _ in range(3):
        q, v = grounded_state(robot, "stand", ctx.contact_frames, rng, 0.05, 0.2)
        t = float(rng.uniform(0.1, 2.1))
        outs = {}
        for impl, ctrl in ticks.items():
            ctrl.start(RobotState(robot, q, v))
            outs[impl] = ctrl.step(RobotState(robot, q, v), t)
        py, nat = outs["python"], outs["native"]
        if controller == "hqp" and not (py.ok and nat.ok):
            continue  # its cascade's lower level, infeasible to rounding on some states
        assert py.ok and nat.ok, (py.message, nat.message)
        # the forces along each line are set by the small wrench regularisation alone: the
        # torque is conditioned to about 1e-7 relative there (1e-12 for the OSF ones)
        scale = max(1.0, float(np.abs(py.tau).max()))
        np.testing.assert_allclose(nat.tau, py.tau, atol=1e-5 * scale)
        np.testing.assert_allclose(nat.qdd, py.qdd, atol=1e-8 * max(1.0, np.abs(py.qdd).max()))
        np.testing.assert_allclose(
            frame_wrenches(ctx.contacts, nat.wrench),
            frame_wrenches(ctx.contacts, py.wrench),
            atol=1e-5 * scale,
        )


@pytest.mark.parametrize(("controller", "impl"), CASES)
def test_five_joint_legs_stand_and_sway_on_line_contacts(
    sway: Path, controller: str, impl: str
) -> None:
    """Closed loop in MuJoCo: the native ticks sway the CoM ±20 mm along x (2 s); the Python
    references, slower, the first 0.4 s of it."""
    overrides = () if impl == "native" else ("duration=0.15",)
    run = plan_run(
        load_scenario(sway, overrides), controller, exact_solver(controller), config={"impl": impl}
    )
    result = run_closed_loop(run)
    assert result.status == "ok", result.message
    log = result.log.arrays()
    (com_error,) = (np.nanmax(v) for k, v in log.items() if k.startswith("err.com."))
    assert com_error < 5e-3, com_error


def test_validate_names_a_task_the_held_soles_leave_unreachable(
    sway: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """On flat soles these legs cannot shift the pelvis sideways (that takes ankle roll); on
    line soles they can: the pelvis pose task is named in the first case only."""
    paths = []
    for name, contacts in (("flat_pose", FLAT_CONTACTS), ("line_pose", LINE_CONTACTS)):
        text = scenario_text(contacts).replace(
            "name: pelvis\n    type: frame_orientation", "name: pelvis\n    type: frame_pose"
        )
        paths.append(sway.parent / f"{name}.yaml")
        paths[-1].write_text(text)
    assert main(["validate", *map(str, paths)]) == 0
    out = capsys.readouterr().out
    flat_out, line_out = out.split(f"ok  {paths[1]}")
    assert (
        "    warning: tasks[1] ('pelvis') at the initial posture: its Jacobian has rank 5 of 6 in "
        "the task's axes with the contacts held: no joint motion moves frame 'pelvis' along y, "
        "so its target cannot be reached there; give the task only the axes its joints move "
        "('axes:'), or a frame those joints carry\n"
    ) in flat_out
    assert "warning" not in line_out, line_out


def test_a_scheduled_line_contact_ramps_each_points_normal_force() -> None:
    """Lifting off a line contact: each point's f_min and f_max ramp, the points sharing the
    ramp's force (the same total bound as a flat contact's)."""
    from wbcbench.tasks.contacts import PlaneContact
    from wbcbench.tasks.schedule import ContactSchedule, ScheduledContact

    line = PlaneContact("l_sole", fmin=10.0, points=((0.12, 0.0, 0.0), (-0.12, 0.0, 0.0)))
    C, lw, uw = line.wrench_constraints()
    assert line.normal_rows() == [0, 5]
    assert C[line.normal_rows()].tolist() == [[0, 0, 1, 0, 0, 0], [0, 0, 0, 0, 0, 1]]
    schedule = ContactSchedule(
        [ScheduledContact("l_sole", [(0.0, 1.0)], unload=0.1)], ramp_force=500.0
    )
    ramp = schedule.phase(0.95)  # halfway down the lift-off ramp
    out_l, out_u = np.empty_like(lw), np.empty_like(uw)
    schedule.scale_bounds(ramp, [line.normal_rows()], [np.inf], lw, uw, out_l, out_u)
    assert out_l[[0, 5]].tolist() == pytest.approx([5.0, 5.0])
    assert out_u[[0, 5]].tolist() == pytest.approx([125.0, 125.0])
    others = [r for r in range(len(lw)) if r not in (0, 5)]
    assert out_l[others].tolist() == lw[others].tolist()
    assert out_u[others].tolist() == uw[others].tolist()
