"""kin_hqp: collision geometry, the velocity-level hierarchy against a QP cascade, closed loop.

Oracles: coal (hpp-fcl) for capsule and box distances, MuJoCo for capsule placements, finite
differences on the configuration manifold for the distance and gaze Jacobians, and a cascade of
generic QPs (Clarabel through the solver layer) for the hierarchy with inequalities. The native
tick is held to the Python reference: its closest points, collision pairs, levels, task terms
and q̇ on the same states.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench import _native
from wbcbench.bench.run_metrics import run_metrics
from wbcbench.controllers.kin_hqp import (
    GazeTask,
    GazeTerm,
    KinHqp,
    KinHqpConfig,
    default_self_pairs,
)
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import WbcBenchError
from wbcbench.qp import Problem, make_solver
from wbcbench.qp.hls import Level
from wbcbench.robots.loader import Robot
from wbcbench.runs import plan_run, scenario_context, scenario_obstacles
from wbcbench.scenarios.load import (
    controller_settings,
    load_scenario,
)
from wbcbench.sim.closed_loop import run_closed_loop
from wbcbench.tasks.collision import (
    Box,
    CollisionModel,
    closest_segment_box,
    closest_segment_segment,
    robot_capsules,
)

from .conftest import random_standing_state
from .test_native_hls import assert_same

Array = np.ndarray

needs_native = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

#: the controller whose impls test_native_impl_equals_the_python_reference compares
CONTROLLER = KinHqp.name


def controller_for(robot: Robot, scenario: str, **overrides: Any) -> KinHqp:
    """kin_hqp built as the kinematic runner builds it, with settings overridden."""
    loaded = load_scenario(scenario)
    spec = loaded.spec
    ctx = scenario_context(loaded, robot)
    cfg = {**controller_settings(loaded, CONTROLLER), **overrides}
    ctrl = KinHqp(ctx, KinHqpConfig.model_validate(cfg))
    ctrl.use_environment(scenario_obstacles(loaded))
    q0, v0 = robot.keyframe(spec.initial.keyframe)
    ctrl.start(RobotState(robot, q0, v0))
    return ctrl


# --------------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------------


def _coal_capsule(p0: Array, p1: Array, r: float) -> tuple[Any, Any]:
    import coal

    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    x = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(axis, x), axis])
    return coal.Capsule(r, float(np.linalg.norm(p1 - p0))), coal.Transform3s(R, 0.5 * (p0 + p1))


def test_segment_distances_match_coal() -> None:
    import coal

    rng = np.random.default_rng(0)
    P, r = 300, 0.02
    a0, a1, b0, b1 = (rng.normal(size=(P, 3)) for _ in range(4))
    R = np.array([pin.rpy.rpyToMatrix(*rng.normal(size=3)) for _ in range(P)])
    c, h = rng.normal(size=(P, 3)), rng.uniform(0.05, 0.5, size=(P, 3))
    pa, pb = closest_segment_segment(a0, a1, b0, b1)
    qa, qb = closest_segment_box(a0, a1, c, R, h)
    req = coal.DistanceRequest()
    checked = 0
    for i in range(P):
        cap_a, tf_a = _coal_capsule(a0[i], a1[i], r)
        cap_b, tf_b = _coal_capsule(b0[i], b1[i], r)
        ref = coal.distance(cap_a, tf_a, cap_b, tf_b, req, coal.DistanceResult())
        if ref > 0:
            assert abs(ref - (np.linalg.norm(pa[i] - pb[i]) - 2 * r)) <= 1e-9
        box = coal.Box(*(2 * h[i]))
        ref = coal.distance(
            cap_a, tf_a, box, coal.Transform3s(R[i], c[i]), req, coal.DistanceResult()
        )
        if ref > 0:
            checked += 1
            assert abs(ref - (np.linalg.norm(qa[i] - qb[i]) - r)) <= 1e-9
            # the box point is on (or in) the box
            local = R[i].T @ (qb[i] - c[i])
            assert np.all(np.abs(local) <= h[i] + 1e-12)
    assert checked > 100


def test_parallel_and_degenerate_segments() -> None:
    a0 = np.array([[0.0, 0, 0], [0.0, 0, 0]])
    a1 = np.array([[1.0, 0, 0], [0.0, 0, 0]])  # second: a point
    b0 = np.array([[0.5, 1, 0], [2.0, 1, 0]])
    b1 = np.array([[2.0, 1, 0], [2.0, 3, 0]])
    pa, pb = closest_segment_segment(a0, a1, b0, b1)
    assert np.linalg.norm(pa[0] - pb[0]) == pytest.approx(1.0)
    np.testing.assert_allclose(pb[1], [2.0, 1.0, 0.0])


def _segment_pairs(rng: np.random.Generator, P: int) -> tuple[Array, Array, Array, Array]:
    """Random segment pairs: a quarter general, a half near-parallel (direction off by 1e-14 to
    1e-2, overlapping or not), then exactly parallel, collinear and degenerate (points) ones."""
    a0, a1, b0, b1 = (rng.normal(size=(P, 3)) for _ in range(4))
    for i in range(P // 4, 3 * P // 4):
        d = a1[i] - a0[i]
        b0[i] = a0[i] + 0.3 * rng.normal(size=3)
        b1[i] = b0[i] + d * rng.uniform(-2, 2) + 10.0 ** rng.uniform(-14, -2) * rng.normal(size=3)
    i = 3 * P // 4
    off = np.cross(a1[i] - a0[i], rng.normal(size=3))
    off *= 0.1 / np.linalg.norm(off)
    b0[i], b1[i] = a0[i] + off, a1[i] + off  # parallel, 0.1 apart
    b0[i + 1], b1[i + 1] = a1[i + 1] + (a1[i + 1] - a0[i + 1]), a1[i + 1]  # collinear, touching
    a1[i + 2] = a0[i + 2]  # A a point
    b1[i + 3] = b0[i + 3]  # B a point
    a1[i + 4], b1[i + 4] = a0[i + 4], b0[i + 4]  # both points
    return a0, a1, b0, b1


@needs_native
def test_native_closest_points_equal_the_python_ones() -> None:
    core = _native._core
    rng = np.random.default_rng(10)
    P = 400
    a0, a1, b0, b1 = _segment_pairs(rng, P)
    pa, pb = closest_segment_segment(a0, a1, b0, b1)
    R = np.array([pin.rpy.rpyToMatrix(*rng.normal(size=3)) for _ in range(P)])
    c, h = rng.normal(size=(P, 3)), rng.uniform(0.05, 0.5, size=(P, 3))
    h[:10, 0] = 0.0  # flat boxes
    e1 = a1.copy()
    e1[10:20] = a0[10:20] + R[10:20, :, 0]  # segments along a box axis (zero slopes)
    qa, qb = closest_segment_box(a0, e1, c, R, h)
    for i in range(P):
        got_a, got_b = core.closest_segment_segment(a0[i], a1[i], b0[i], b1[i])
        np.testing.assert_allclose(got_a, pa[i], rtol=0, atol=1e-12, err_msg=f"pair {i}")
        np.testing.assert_allclose(got_b, pb[i], rtol=0, atol=1e-12, err_msg=f"pair {i}")
        got_a, got_b = core.closest_segment_box(a0[i], e1[i], c[i], R[i], h[i])
        np.testing.assert_allclose(got_a, qa[i], rtol=0, atol=1e-12, err_msg=f"box {i}")
        np.testing.assert_allclose(got_b, qb[i], rtol=0, atol=1e-12, err_msg=f"box {i}")
    # the parallel pair keeps its distance, the touching collinear pair touches
    assert np.linalg.norm(pa[3 * P // 4] - pb[3 * P // 4]) == pytest.approx(0.1)
    assert np.linalg.norm(pa[3 * P // 4 + 1] - pb[3 * P // 4 + 1]) <= 1e-12


@needs_native
@pytest.mark.parametrize("scenario", ["rqr_reach", "rqr_stress"])
def test_native_collision_pairs_equal_the_python_model(comanplus: Robot, scenario: str) -> None:
    """Distances, gradients and closest points of every pair (self and obstacle) at random
    configurations, some of them penetrating."""
    ctrl = controller_for(comanplus, scenario, impl="native")
    tick = ctrl.native_tick
    rng = np.random.default_rng(11)
    penetrating = 0
    for _ in range(6):
        q, v = random_standing_state(comanplus, rng, q_noise=0.3)
        ref = ctrl.collision.evaluate(RobotState(comanplus, q, v))
        assert tick.run(q, v, 0.0)
        got = tick.collisions
        assert got.size == ctrl.collision.n_pairs == len(ref.d)
        np.testing.assert_allclose(got.d, ref.d, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.grad, ref.grad, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.points, ref.points.reshape(-1, 6), rtol=0, atol=1e-12)
        assert got.min_distance == ref.min_distance
        penetrating += int(np.sum(ref.d < 0))
    if scenario == "rqr_stress":
        assert penetrating > 0, "the states should push capsules into the obstacles"


def test_capsules_move_with_their_bodies_as_in_mujoco(comanplus: Robot) -> None:
    rng = np.random.default_rng(1)
    q, v = random_standing_state(comanplus, rng, q_noise=0.4)
    state = RobotState(comanplus, q, v)
    data = mujoco.MjData(comanplus.mj_model)
    data.qpos[:] = comanplus.pin_to_mj(q, v)[0]
    mujoco.mj_forward(comanplus.mj_model, data)
    caps = robot_capsules(comanplus)
    assert "head" in caps  # a site of the same name must not shadow the body frame
    for body, cap in caps.items():
        gid = mujoco.mj_name2id(comanplus.mj_model, mujoco.mjtObj.mjOBJ_GEOM, f"{body}_capsule")
        half = data.geom_xmat[gid].reshape(3, 3)[:, 2] * comanplus.mj_model.geom_size[gid][1]
        M = state.placement(cap.frame_id)
        np.testing.assert_allclose(M.act(cap.p0), data.geom_xpos[gid] - half, atol=1e-12)
        np.testing.assert_allclose(M.act(cap.p1), data.geom_xpos[gid] + half, atol=1e-12)


def _fd_jacobian(robot: Robot, q: Array, f: Any, eps: float = 1e-7) -> Array:
    """Central differences of f along each velocity direction: (m, n)."""
    cols = []
    for i in range(robot.nv):
        dv = np.zeros(robot.nv)
        dv[i] = eps
        fp = f(pin.integrate(robot.pin_model, q, dv))
        fm = f(pin.integrate(robot.pin_model, q, -dv))
        cols.append((fp - fm) / (2 * eps))
    return np.column_stack(cols)


@pytest.mark.parametrize("robot_name", ["comanplus_like", "tocabi_like"])
def test_distance_gradient_matches_finite_differences(
    robot_name: str, comanplus: Robot, tocabi: Robot
) -> None:
    robot = comanplus if robot_name == "comanplus_like" else tocabi
    boxes = [
        Box.from_rpy("front", [0.35, -0.25, 0.8], [0.05, 0.2, 0.02], [0.1, 0.3, 0.2]),
        Box.from_rpy("side", [0.1, -0.55, 0.9], [0.1, 0.03, 0.3], [0.0, 0.0, 0.5]),
    ]
    pairs = default_self_pairs(robot.name)
    bodies = [b for s in "LR" for b in (f"{s}_Elbow_link", f"{s}_Wrist2_link")]
    model = CollisionModel(robot, pairs, bodies, boxes)
    assert model.n_pairs == 16 + 2 * len(bodies)
    rng = np.random.default_rng(2)
    q, v = random_standing_state(robot, rng, q_noise=0.3)
    terms = model.evaluate(RobotState(robot, q, v))
    assert np.all(terms.d > 0)
    fd = _fd_jacobian(robot, q, lambda x: model.evaluate(RobotState(robot, x, v)).d)
    np.testing.assert_allclose(terms.grad, fd, atol=2e-6)


def test_pairs_within_two_joints_are_rejected(comanplus: Robot) -> None:
    with pytest.raises(WbcBenchError) as exc:
        CollisionModel(comanplus, [("R_Wrist2_link", "R_ForearmPlate_link")])
    assert str(exc.value) == (
        "collision pair (R_Wrist2_link, R_ForearmPlate_link): the bodies are 2 joint(s) apart; "
        "pairs within 2 joints of each other are not checked"
    )
    with pytest.raises(WbcBenchError, match="unknown capsule body 'hand'; valid choices: "):
        CollisionModel(comanplus, [("hand", "torso")])


def test_gaze_jacobian_matches_finite_differences(comanplus: Robot) -> None:
    gaze = GazeTask(name="gaze", frame="head", axis=0, target=np.array([0.8, -0.3, 3.0]))
    rng = np.random.default_rng(3)
    q, v = random_standing_state(comanplus, rng, q_noise=0.2)

    def f(x: Array) -> Array:
        return -gaze.evaluate(RobotState(comanplus, x, v), 0.0).error  # f = v × p

    J = gaze.evaluate(RobotState(comanplus, q, v), 0.0).J
    np.testing.assert_allclose(J, _fd_jacobian(comanplus, q, f), atol=1e-6)


# --------------------------------------------------------------------------------------------
# One tick: equalities exact, inequalities kept, agreement with a cascade of generic QPs
# --------------------------------------------------------------------------------------------


def _violation(level: Level, x: Array) -> float:
    if level.C is None or level.l is None or level.u is None:
        return 0.0
    cx = level.C @ x
    return float(np.max(np.maximum(level.l - cx, cx - level.u), initial=0.0))


@pytest.mark.parametrize(
    ("settings", "n_eq"),
    [
        ({}, 6 + 2),  # right sole (left sole is the root) + CoM hold
        ({"base": "floating", "com": "polygon"}, 12),
        ({"base": "floating", "com": "fixed", "velocity_limit": 0.05}, 12 + 2),
    ],
    ids=["paper", "floating-polygon", "floating-tight"],
)
def test_feet_fixed_and_inequalities_kept_at_random_states(
    comanplus: Robot, settings: dict[str, Any], n_eq: int
) -> None:
    ctrl = controller_for(comanplus, "rqr_gaze", **settings)
    rng = np.random.default_rng(4)
    for tick in range(4):
        q, v = random_standing_state(comanplus, rng, q_noise=0.05)
        state = RobotState(comanplus, q, v)
        problem = ctrl.build(state, 0.1 * tick)
        out = ctrl.step(RobotState(comanplus, q, v), 0.1 * tick)
        assert out.ok, out.message
        assert out.qd is not None and out.qd.shape == (comanplus.nv,)
        assert out.tau.size == 0 and out.qdd.size == 0 and out.wrench.size == 0
        feet = state.contact_jacobian(["l_sole", "r_sole"]) @ out.qd
        assert np.abs(feet).max() <= 1e-9
        x = np.linalg.lstsq(problem.T, out.qd, rcond=None)[0]
        for level in problem.levels:
            assert _violation(level, x) <= 1e-9, level.name
        assert out.diagnostics["n_eq"] == n_eq
        for name in ("contacts", "constraints", "hand", "gaze"):
            assert f"solve.{name}" in out.timings
            assert f"iter.{name}" in out.diagnostics and f"active.{name}" in out.diagnostics


def _orth_rows(M: Array) -> Array:
    if M.shape[0] == 0:
        return M
    _, s, Vt = np.linalg.svd(M, full_matrices=False)
    return Vt[s > 1e-9 * max(1.0, s[0])]


def _qp_cascade(levels: list[Level], n: int) -> list[float]:
    """Optimal residual of each level by generic QPs (Clarabel, high accuracy tier).

    Level i minimises ‖A_i x − b_i‖² keeping the task values of the levels above (their optimal
    set) and every inequality declared at or above it.
    """
    solver = make_solver("clarabel", tier="high")
    tasks = np.zeros((0, n))
    C, lo, hi = np.zeros((0, n)), np.zeros(0), np.zeros(0)
    x = np.zeros(n)
    residuals = []
    for lv in levels:
        if lv.C is not None and lv.l is not None and lv.u is not None:
            C, lo, hi = np.vstack([C, lv.C]), np.concatenate([lo, lv.l]), np.concatenate([hi, lv.u])
        if lv.A is None or lv.b is None:
            residuals.append(0.0)
            continue
        E = _orth_rows(tasks)
        H = lv.A.T @ lv.A + 1e-12 * np.eye(n)
        sol = solver.solve(Problem(H, -lv.A.T @ lv.b, E, E @ x, C, lo, hi))
        assert sol.x is not None, sol.message
        x = sol.x
        tasks = np.vstack([tasks, lv.A])
        residuals.append(float(np.linalg.norm(lv.A @ x - lv.b)))
    return residuals


@pytest.mark.parametrize(
    ("scenario", "settings", "jitter"),
    [
        ("rqr_stress", {}, 0.0),
        ("rqr_gaze", {"velocity_limit": 0.05}, 0.05),
        ("rqr_gaze", {"base": "floating", "com": "polygon", "velocity_limit": 0.02}, 0.05),
    ],
    ids=["stress", "gaze-tight", "floating-tight"],
)
def test_hierarchy_matches_qp_cascade(
    comanplus: Robot, scenario: str, settings: dict[str, Any], jitter: float
) -> None:
    ctrl = controller_for(comanplus, scenario, damping=0.0, **settings)
    rng = np.random.default_rng(5)
    q, v = random_standing_state(comanplus, rng, q_noise=jitter)
    if jitter == 0.0:
        q = comanplus.keyframe("stand")[0]
    problem = ctrl.build(RobotState(comanplus, q, v), 0.0)
    res = ctrl.solve(problem)
    levels = problem.levels
    assert sum(s.n_active for s in res.levels) >= 5, "the case must activate inequalities"
    ref = _qp_cascade(levels, problem.T.shape[1])
    for i, stats in enumerate(res.levels):
        # every level keeps its inequalities and those above it ...
        for lv in levels[: i + 1]:
            assert _violation(lv, stats.x) <= 1e-9, f"{lv.name} at level {i}"
        # ... does not increase the residual of any level above ...
        for j in range(i):
            A, b = levels[j].A, levels[j].b
            if A is not None and b is not None:
                before = np.linalg.norm(A @ res.levels[j].x - b)
                assert np.linalg.norm(A @ stats.x - b) <= before + 1e-9, f"{j} by {i}"
        # ... and reaches the optimal residual of the QP cascade
        assert abs(stats.residual - ref[i]) <= 1e-6, f"level {levels[i].name}"


def test_baseline_hierarchies_agree_without_inequalities(comanplus: Robot) -> None:
    rng = np.random.default_rng(6)
    q, v = random_standing_state(comanplus, rng, q_noise=0.05)
    outs = {}
    for hierarchy in ("rqr", "svd", "full_qr"):
        ctrl = controller_for(
            comanplus, "rqr_gaze", hierarchy=hierarchy, inequalities=False, damping=0.0
        )
        out = ctrl.step(RobotState(comanplus, q, v), 0.0)
        assert out.ok, out.message
        outs[hierarchy] = out.qd
    np.testing.assert_allclose(outs["svd"], outs["rqr"], atol=1e-9)
    np.testing.assert_allclose(outs["full_qr"], outs["rqr"], atol=1e-9)
    with pytest.raises(ValueError, match="hierarchy 'svd' handles equality levels only"):
        KinHqpConfig(hierarchy="svd")


@needs_native
@pytest.mark.parametrize(
    ("scenario", "settings", "jitter"),
    [
        ("rqr_stress", {}, 0.0),
        ("rqr_stress", {}, 0.03),
        ("rqr_reach", {}, 0.05),
        ("rqr_gaze", {"velocity_limit": 0.05}, 0.05),
        ("rqr_gaze", {"base": "floating", "com": "polygon", "velocity_limit": 0.02}, 0.05),
        ("rqr_gaze", {"damping": 0.0, "velocity_limit": 0.02}, 0.05),
        ("rqr_gaze", {"hierarchy": "svd", "inequalities": False}, 0.05),
        ("rqr_gaze", {"hierarchy": "full_qr", "inequalities": False}, 0.05),
    ],
    ids=[
        "stress",
        "stress-jitter",
        "reach",
        "gaze-tight",
        "floating",
        "undamped",
        "svd",
        "full_qr",
    ],
)
def test_native_impl_equals_the_python_reference(
    comanplus: Robot, scenario: str, settings: dict[str, Any], jitter: float
) -> None:
    """Same states: the native tick's levels equal the Python build's (to 1e-12), its task
    terms too, and the hierarchy gives the same active sets, level by level, and q̇ to 1e-10 on
    the same levels, and to 1e-10 plus 1e-12 times the levels' conditioning from the tick's own
    build."""
    py = controller_for(comanplus, scenario, impl="python", **settings)
    nat = controller_for(comanplus, scenario, impl="native", **settings)
    assert (py.impl, nat.impl) == ("python", "native")
    rng = np.random.default_rng(8)
    active = 0
    for tick in range(5):
        q, v = random_standing_state(comanplus, rng, q_noise=jitter)
        if jitter == 0.0:
            q = comanplus.keyframe("stand")[0]
        t = 0.1 * tick
        problem = py.build(RobotState(comanplus, q, v), t)
        ref, got = py.solve(problem), nat.solve(problem)
        assert_same(got, ref, problem.levels, f"{scenario} tick {tick}")
        active += sum(s.n_active for s in ref.levels)
        out_py = py.step(RobotState(comanplus, q, v), t)
        out_nat = nat.step(RobotState(comanplus, q, v), t)
        assert out_py.ok and out_nat.ok, (out_py.message, out_nat.message)
        _same_levels(nat.native_tick, problem)
        _same_terms(out_nat.terms, out_py.terms)
        assert out_py.qd is not None and out_nat.qd is not None
        # the two ticks build their levels apart (equal to 1e-12, checked above): q̇ agrees to
        # the solvers' 1e-10 plus that difference times the levels' conditioning
        scale = max(1.0, float(np.abs(out_py.qd).max()))
        bound = 1e-10 + level_condition(problem.levels) * 1e-12 * scale
        assert np.abs(out_nat.qd - out_py.qd).max() <= bound
        for key, value in out_py.diagnostics.items():
            if key.startswith(("iter.", "active.", "n_")) or key == "active":
                assert out_nat.diagnostics[key] == value, key
        assert out_nat.timings["solve_internal"] <= out_nat.timings["solve"]
    if settings.get("inequalities", True):
        assert active > 0, "the states should activate inequalities"


def level_condition(levels: list[Any]) -> float:
    """The largest condition number of a level's task matrix on its numerical range (singular
    values above 1e-9 of the largest, the rank test of the hierarchy's decompositions)."""
    worst = 1.0
    for lv in levels:
        if lv.A is None or not lv.A.size:
            continue
        sigma = np.linalg.svd(lv.A, compute_uv=False)
        if sigma[0] > 0:
            kept = sigma[sigma > 1e-9 * sigma[0]]
            worst = max(worst, float(kept[0] / kept[-1]))
    return worst


def _same_levels(tick: Any, problem: Any) -> None:
    """The native tick's last levels and root map against the Python build of the same state."""
    np.testing.assert_allclose(tick.root_map, problem.T, rtol=0, atol=1e-12)
    levels = tick.levels()
    assert [lv[0] for lv in levels] == [lv.name for lv in problem.levels]
    assert (tick.n_eq, tick.n_ineq, tick.n_task) == (problem.n_eq, problem.n_ineq, problem.n_task)
    for (name, A, b, C, lo, hi, damping, has_task, has_ineq), lv in zip(
        levels, problem.levels, strict=True
    ):
        assert (has_task, has_ineq) == (lv.A is not None, lv.C is not None), name
        assert damping == lv.damping, name
        if has_task:
            np.testing.assert_allclose(A, lv.A, rtol=0, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(b, lv.b, rtol=0, atol=1e-12, err_msg=name)
        if has_ineq:
            np.testing.assert_allclose(C, lv.C, rtol=0, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(lo, lv.l, rtol=0, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(hi, lv.u, rtol=0, atol=1e-12, err_msg=name)


def _same_terms(got: list[Any], ref: list[Any]) -> None:
    """Task terms of the two impls: the same tasks, Jacobians, errors and (gaze) angles."""
    assert [t.task.name for t in got] == [t.task.name for t in ref]
    for g, r in zip(got, ref, strict=True):
        for part in ("J", "drift", "acc_ref", "error", "error_vel"):
            np.testing.assert_allclose(
                getattr(g, part), getattr(r, part), rtol=0, atol=1e-12, err_msg=part
            )
        if isinstance(r, GazeTerm):
            assert isinstance(g, GazeTerm)
            assert g.angle == pytest.approx(r.angle, abs=1e-12)


def test_applies_only_to_kinematic_scenarios() -> None:
    assert KinHqp.applies_to(load_scenario("rqr_reach").spec) == ""
    assert "velocity controller" in KinHqp.applies_to(load_scenario("tocabi_stand_sway").spec)


# --------------------------------------------------------------------------------------------
# Closed loop (kinematic): the paper's three scenarios
# --------------------------------------------------------------------------------------------


def _run(scenario: str, on_step: Any = None) -> tuple[Any, dict[str, Array], dict[str, float]]:
    loaded = load_scenario(scenario)
    result = run_closed_loop(plan_run(loaded, controller="kin_hqp"), on_step=on_step)
    assert result.status == "ok", result.message
    assert result.failures == 0
    rows = run_metrics(result, [], loaded.spec.metrics.window, loaded.spec.metrics.timing_warmup)
    metrics = {f"{r.task}.{r.metric}": r.value for r in rows}
    return result, result.log.arrays(), metrics


@pytest.mark.slow
def test_rqr_reach_reaches_the_target_within_limits() -> None:
    _, log, metrics = _run("rqr_reach")
    assert metrics["hand.err_final"] < 1e-3
    assert metrics["*.joint_limit_violation"] == 0.0
    assert metrics["*.min_collision_distance"] >= 0.005 - 1e-6  # the collision margin
    assert np.all(log["diag.n_eq"] == 8) and np.all(log["diag.n_ineq"] == 72)
    assert log["contact_drift"].max() < 1e-4  # first-order integration of zero foot velocity


@pytest.mark.slow
def test_rqr_gaze_hand_holds_while_the_gaze_gives_way() -> None:
    _, log, metrics = _run("rqr_gaze")
    hand, gaze = log["err.hand.pos"], log["err.gaze.rot"]
    assert metrics["hand.err_final"] < 1e-3
    # the hand's error never increases: the lower gaze level cannot disturb it
    assert np.all(np.diff(hand) <= 1e-9)
    # the gaze error grows while the hand moves, and the target stays out of sight
    assert gaze.max() > gaze[0] + 0.05
    assert gaze[-1] > 0.3
    assert np.all(gaze < np.pi / 2)


@pytest.mark.slow
def test_rqr_stress_never_violates_a_bound() -> None:
    commands: list[Array] = []
    _, log, metrics = _run("rqr_stress", on_step=lambda s, out: commands.append(out.qd))
    qd = np.array(commands)
    assert np.abs(qd[:, 6:]).max() <= 3e-4 * (1 + 1e-9)
    assert metrics["*.joint_limit_violation"] == 0.0
    assert metrics["*.min_collision_distance"] >= 0.0
    assert np.all(log["diag.n_ineq"] == 160) and np.all(log["diag.n_eq"] == 8)
    assert np.median(log["diag.active"]) >= 10, "the bounds should saturate"
