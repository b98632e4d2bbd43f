"""The OSF core, to_osf and osf_hqp against the rigid-contact forward-dynamics oracle (DESIGN §4).

(a) contact accelerations vanish; (b) every feasible level realises its reference; (c) a lower
level never changes what the levels above realise; (d) the wrench-distribution torque changes the
contact wrench and no task acceleration; (e) predicted wrench = realised wrench. Plus the algebra
of the dynamically consistent inverse (COD = SVD = Φ Sᵀ W⁺), the pinv ablation, and the
equivalence with the conventional HQP whose final level is the zero-torque energy ‖q̈ − q̈₀‖²_A.
"""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wbcbench.controllers.base import ControllerContext
from wbcbench.controllers.hqp import Hqp, HqpConfig
from wbcbench.controllers.osf_hqp import OsfHqp, OsfHqpConfig
from wbcbench.controllers.to_osf import OsfControllerBase, ToOsf, ToOsfConfig
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.metrics.consistency import dc_error
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.robots.loader import Robot
from wbcbench.tasks import osf
from wbcbench.tasks.contacts import PlaneContact
from wbcbench.tasks.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    JointPostureTask,
    Task,
)

from .conftest import IMPLS, random_standing_state

threadpool_limits(1)  # scipy's own OpenBLAS spins a second thread on these small matrices

FRAMES = ("l_sole", "r_sole", "l_palm")


def task_pool(robot: Robot) -> list[Task]:
    """Candidate tasks, highest priority first (priorities set by the caller)."""
    posture = JointPostureTask("posture", kp=50.0, kv=14.0)
    posture.bind(robot.joint_names)
    return [
        ComTask("com"),
        FrameOrientationTask("pelvis", frame="pelvis"),
        FramePoseTask("r_hand", frame="r_hand"),
        FrameOrientationTask("torso", frame="torso"),
        FramePositionTask("l_hand", frame="l_hand"),
        posture,
    ]


class FreeContact(PlaneContact):
    """A bilateral plane contact without wrench inequalities: the algebra is checked with no
    inequality active (and no random state can make one active)."""

    def wrench_constraints(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.zeros((0, 6)), np.zeros(0), np.zeros(0)


def loose_contacts(frames: list[str]) -> list[PlaneContact]:
    return [FreeContact(f) for f in frames]


def context(robot: Robot, tasks: list[Task], frames: list[str], solver: str = "daqp"):
    return ControllerContext(
        robot=robot,
        tasks=tasks,
        contacts=loose_contacts(frames),
        tau_max=np.full(robot.k, 1e6),
        solver=solver,
        tier="high",
        keep_problems=True,
    )


def realised(state_args, tau, frames, tasks):
    """Oracle task accelerations {name: (m,)} and the oracle result for a torque."""
    robot, q, v = state_args
    st = RobotState(robot, q, v)
    res = forward_dynamics(st, tau, frames)
    acc = {}
    for t in tasks:
        J, drift = osf.task_jacobian(t, st)
        acc[t.name] = J @ res.qdd + drift
    return acc, res


def random_case(robot: Robot, rng: np.random.Generator):
    """A random state near the wall keyframe, 1–5 levels (one or two tasks each), 1–3 contacts."""
    pool = task_pool(robot)
    n_levels = int(rng.integers(1, 6))
    chosen = [pool[i] for i in sorted(rng.choice(len(pool), size=n_levels, replace=False))]
    for p, t in enumerate(chosen, start=1):
        t.priority = p
    n_contacts = int(rng.integers(1, 4))
    frames = [FRAMES[i] for i in sorted(rng.choice(3, size=n_contacts, replace=False))]
    q, _ = robot.keyframe("stand_wall")
    q = q.copy()
    q[7:] = np.clip(q[7:] + rng.uniform(-0.05, 0.05, robot.k), robot.q_min, robot.q_max)
    v = rng.uniform(-0.2, 0.2, robot.nv)
    return chosen, frames, q, v


# -- the algebra ----------------------------------------------------------------------------------


@pytest.mark.parametrize("frames", [["l_sole"], ["l_sole", "r_sole"], list(FRAMES)])
def test_cod_and_svd_give_the_dynamically_consistent_inverse(comanplus: Robot, frames) -> None:
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, v = random_standing_state(comanplus, rng)
        st = RobotState(comanplus, q, v)
        cd = osf.contact_dynamics(st, frames)
        k, c = comanplus.k, 6 * len(frames)
        W_pinv = np.linalg.pinv(cd.W, rcond=1e-10, hermitian=True)
        reference = cd.Phi[:, 6:] @ W_pinv  # Φ Sᵀ W⁺
        y_cod, n_cod = osf.dynamically_consistent_inverse(cd, st.M, "cod")
        y_svd, n_svd = osf.dynamically_consistent_inverse(cd, st.M, "svd")
        scale = np.abs(reference).max()
        assert np.abs(y_cod - y_svd).max() <= 1e-9 * scale
        assert np.abs(y_cod - reference).max() <= 1e-9 * scale
        # Φ symmetric PSD, W of rank k − (c − 6), Φ Sᵀ W⁺ S Φ = Φ
        assert np.abs(cd.Phi - cd.Phi.T).max() <= 1e-12 * np.abs(cd.Phi).max()
        assert np.linalg.matrix_rank(cd.W, tol=1e-9 * np.abs(cd.W).max()) == k - (c - 6)
        PS = cd.Phi[:, 6:]
        assert np.abs(PS @ W_pinv @ PS.T - cd.Phi).max() <= 1e-9 * np.abs(cd.Phi).max()
        # N_w: an orthonormal basis of null(W), dimension c − 6
        for nw in (n_cod, n_svd):
            assert nw.shape == (k, c - 6)
            np.testing.assert_allclose(nw.T @ nw, np.eye(c - 6), atol=1e-10)
            assert np.abs(cd.W @ nw).max(initial=0.0) <= 1e-10 * np.abs(cd.W).max()


def test_pinv_breaks_dynamic_consistency(comanplus: Robot) -> None:
    tasks = task_pool(comanplus)[:5]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    q, v = random_standing_state(comanplus, np.random.default_rng(1))
    st = RobotState(comanplus, q, v)
    levels = osf.group_levels(tasks)
    errors = {
        inv: dc_error(osf.OsfModel(levels, ["l_sole", "r_sole"], inverse=inv).params(st))
        for inv in ("cod", "svd", "pinv")
    }
    assert errors["cod"] <= 1e-9 and errors["svd"] <= 1e-9, errors
    assert errors["pinv"] >= 1e-2, errors


def test_wrench_distribution_changes_the_wrench_only(comanplus: Robot) -> None:
    """(d): a torque Y_c z lies in null(W): no task acceleration changes, the wrench by Q_f z."""
    tasks = task_pool(comanplus)[:4]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    rng = np.random.default_rng(2)
    q, v = random_standing_state(comanplus, rng)
    st = RobotState(comanplus, q, v)
    p = osf.OsfModel(osf.group_levels(tasks), list(FRAMES)).params(st)
    tau = rng.normal(0, 20, comanplus.k)
    z = rng.normal(0, 50, p.Yc.shape[1])
    acc0, res0 = realised((comanplus, q, v), tau, list(FRAMES), tasks)
    acc1, res1 = realised((comanplus, q, v), tau + p.Yc @ z, list(FRAMES), tasks)
    for name in acc0:
        assert np.abs(acc1[name] - acc0[name]).max() <= 1e-8
    np.testing.assert_allclose(res1.wrench - res0.wrench, p.Qf @ z, atol=1e-6)
    assert np.abs(p.G @ (p.Qf @ z)).max() <= 1e-8  # an internal wrench


# -- the controllers against the oracle -----------------------------------------------------------


def make(cls, robot, tasks, frames, solver="daqp", **cfg):
    # the algebra tests leave the contacts free: the references must not trade against the
    # wrench (to_osf: the paper's internal-wrench cost) and every wrench row is weighted
    cfg.setdefault("wrench_weights", [1.0] * 6)
    if cls is ToOsf:
        cfg.setdefault("wrench_cost", "internal")
    config = (ToOsfConfig if cls is ToOsf else OsfHqpConfig)(**cfg)
    return cls(context(robot, tasks, frames, solver), config)


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("cls", [OsfHqp, ToOsf])
def test_oracle_100_random_states(
    comanplus: Robot, cls: type[OsfControllerBase], impl: str
) -> None:
    """(a), (b), (c), (e) at 100 random states, 1–5 levels, 1–3 contacts, nothing active."""
    rng = np.random.default_rng(11)
    worst = {"contact_acc": 0.0, "tracking": 0.0, "hierarchy": 0.0, "wrench": 0.0}
    for _ in range(100):
        tasks, frames, q, v = random_case(comanplus, rng)
        start = RobotState(comanplus, q, v)
        full = make(cls, comanplus, tasks, frames, impl=impl)
        full.start(start)
        out = full.step(RobotState(comanplus, q, v), 0.0)
        assert out.ok, out.message
        acc, res = realised((comanplus, q, v), out.tau, frames, tasks)
        worst["contact_acc"] = max(worst["contact_acc"], float(np.abs(res.contact_acc).max()))
        worst["wrench"] = max(
            worst["wrench"],
            float(np.abs(res.wrench - out.wrench).max()) / max(1.0, np.abs(res.wrench).max()),
        )
        # (b) every level whose operational-space inertia has full rank realises its reference
        params = full.server.get(RobotState(comanplus, q, v), 0).params
        for term, lv in zip(out.terms, params.levels, strict=True):
            if np.linalg.matrix_rank(lv.Lam) == term.dim:
                err = np.abs(acc[term.task.name] - term.acc_ref).max()
                worst["tracking"] = max(
                    worst["tracking"], err / max(1.0, np.abs(term.acc_ref).max())
                )
        # (c) adding the lowest level changes nothing above it
        if len(tasks) > 1:
            upper = make(cls, comanplus, tasks[:-1], frames, impl=impl)
            out_u = upper.step(RobotState(comanplus, q, v), 0.0)
            acc_u, _ = realised((comanplus, q, v), out_u.tau, frames, tasks[:-1])
            for t in tasks[:-1]:
                diff = np.abs(acc[t.name] - acc_u[t.name]).max()
                worst["hierarchy"] = max(worst["hierarchy"], diff)
    assert worst["contact_acc"] <= 1e-8, worst
    assert worst["tracking"] <= 1e-8, worst
    assert worst["hierarchy"] <= 1e-8, worst
    assert worst["wrench"] <= 1e-6, worst


def test_changing_a_lower_reference_leaves_higher_levels(comanplus: Robot) -> None:
    """(c) again, through a different lower reference rather than a missing level."""
    tasks = task_pool(comanplus)[:4]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    rng = np.random.default_rng(3)
    q, v = random_standing_state(comanplus, rng)
    st = RobotState(comanplus, q, v)
    for t in tasks:
        t.start(st)
    p = osf.OsfModel(osf.group_levels(tasks), ["l_sole", "r_sole"]).params(st)
    refs = [rng.normal(0, 1, lv.dim) for lv in p.levels]
    other = [*refs[:-1], rng.normal(0, 5, p.levels[-1].dim)]
    acc_a, _ = realised((comanplus, q, v), p.torque(refs), ["l_sole", "r_sole"], tasks)
    acc_b, _ = realised((comanplus, q, v), p.torque(other), ["l_sole", "r_sole"], tasks)
    for t in tasks[:-1]:
        assert np.abs(acc_a[t.name] - acc_b[t.name]).max() <= 1e-8
        np.testing.assert_allclose(acc_a[t.name], refs[tasks.index(t)], atol=1e-8)


def test_force_level_task_realises_its_force(comanplus: Robot) -> None:
    """OSF-HQP eq. 30–31: a force-level level realises ẍ = Λ⁻¹ F* and keeps the ones above."""
    tasks = task_pool(comanplus)[:3]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    tasks[1].level = "force"
    rng = np.random.default_rng(4)
    q, v = random_standing_state(comanplus, rng)
    st = RobotState(comanplus, q, v)
    levels = osf.group_levels(tasks)
    p = osf.OsfModel(levels, ["l_sole", "r_sole"], osf.level_kinds(levels)).params(st)
    refs = [rng.normal(0, 1, lv.dim) for lv in p.levels]
    refs[1] = rng.normal(0, 20, p.levels[1].dim)  # [N·m]
    acc, _ = realised((comanplus, q, v), p.torque(refs), ["l_sole", "r_sole"], tasks)
    np.testing.assert_allclose(acc["com"], refs[0], atol=1e-8)
    np.testing.assert_allclose(acc["pelvis"], np.linalg.solve(p.levels[1].Lam, refs[1]), atol=1e-8)


def test_mixed_levels_are_rejected(comanplus: Robot) -> None:
    tasks = task_pool(comanplus)[:2]
    tasks[1].level = "force"
    with pytest.raises(ControllerError, match="mixes acceleration- and force-level"):
        osf.level_kinds([tasks])


def test_literal_coupling_loses_lower_levels(comanplus: Robot) -> None:
    """The papers' literal Λ ẍ* + Γ_gc form: level 1 exact, lower levels not (what it costs)."""
    tasks = task_pool(comanplus)[:3]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    rng = np.random.default_rng(5)
    q, v = random_standing_state(comanplus, rng)
    st = RobotState(comanplus, q, v)
    levels = osf.group_levels(tasks)
    refs = [rng.normal(0, 1, len(lv[0].axes)) for lv in levels]
    errors = {}
    for coupling in ("exact", "literal"):
        p = osf.OsfModel(levels, ["l_sole", "r_sole"], coupling=coupling).params(st)
        acc, _ = realised((comanplus, q, v), p.torque(refs), ["l_sole", "r_sole"], tasks)
        errors[coupling] = [np.abs(acc[t.name] - r).max() for t, r in zip(tasks, refs, strict=True)]
    assert max(errors["exact"]) <= 1e-8
    assert errors["literal"][0] <= 1e-8
    assert max(errors["literal"][1:]) >= 1e-3


# -- equivalences ---------------------------------------------------------------------------------


def test_to_osf_without_amendment_is_the_osf_torque(comanplus: Robot) -> None:
    """With nothing active, to_osf amends nothing and its torque is eq. (7) at ẍ* and F_opt."""
    rng = np.random.default_rng(6)
    tasks = task_pool(comanplus)[:5]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    # the paper's literal wrench cost (internal wrench only): with the total-wrench cost the
    # references trade ~H_w/H against the wrench, a small amendment even with nothing active
    ctrl = make(
        ToOsf,
        comanplus,
        tasks,
        ["l_sole", "r_sole"],
        "proxqp",
        consistency=True,
        wrench_cost="internal",
    )
    q, v = random_standing_state(comanplus, rng)
    ctrl.start(RobotState(comanplus, q, v))
    out = ctrl.step(RobotState(comanplus, q, v), 0.0)
    assert out.ok, out.message
    amend = [val for key, val in out.diagnostics.items() if key.startswith("amend.")]
    assert max(amend) <= 1e-6
    p = ctrl.server.get(RobotState(comanplus, q, v), 0).params
    refs = [t.acc_ref for t in out.terms]  # one task per level
    dist = out.tau - p.torque(refs)
    assert np.abs(p.W @ dist).max() <= 1e-7 * max(1.0, np.abs(out.tau).max())
    assert out.diagnostics["leak_max"] <= 1e-8
    assert out.diagnostics["contact_acc"] <= 1e-8
    assert out.diagnostics["dc_error"] <= 1e-9


def test_cod_and_svd_controllers_agree(comanplus: Robot) -> None:
    tasks = task_pool(comanplus)[:5]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    q, v = random_standing_state(comanplus, np.random.default_rng(7))
    taus = {}
    for inv in ("cod", "svd"):
        c = make(OsfHqp, comanplus, tasks, list(FRAMES), inverse=inv, wrench_weights=[1.0] * 6)
        c.start(RobotState(comanplus, q, v))
        taus[inv] = c.step(RobotState(comanplus, q, v), 0.0).tau
    assert np.abs(taus["cod"] - taus["svd"]).max() <= 1e-6 * np.abs(taus["cod"]).max()


def test_osf_hqp_equals_hqp_with_zero_torque_energy(comanplus: Robot) -> None:
    """Same q̈ and task accelerations; torques equal up to null(W), and equal outright when both
    minimise the same contact-wrench objective afterwards."""
    rng = np.random.default_rng(8)
    frames = ["l_sole", "r_sole"]
    ones = [1.0] * 6
    tasks = task_pool(comanplus)[:4]
    for p, t in enumerate(tasks, start=1):
        t.priority = p
    for _ in range(3):
        q, v = random_standing_state(comanplus, rng, q_noise=0.02, v_noise=0.1)
        osf_c = make(OsfHqp, comanplus, tasks, frames, "proxqp", wrench_weights=ones)
        osf_c.start(RobotState(comanplus, q, v))
        a = osf_c.step(RobotState(comanplus, q, v), 0.0)
        for finals, same_torque in (
            (["zero_torque_energy"], False),
            (["zero_torque_energy", "wrench"], True),
        ):
            hqp = Hqp(
                context(comanplus, tasks, frames, "proxqp"),
                HqpConfig(finals=finals, wrench_weights=ones),  # type: ignore[arg-type]
            )
            b = hqp.step(RobotState(comanplus, q, v), 0.0)
            assert a.ok and b.ok, (a.message, b.message)
            acc_a, _ = realised((comanplus, q, v), a.tau, frames, tasks)
            acc_b, _ = realised((comanplus, q, v), b.tau, frames, tasks)
            qa = forward_dynamics(RobotState(comanplus, q, v), a.tau, frames).qdd
            qb = forward_dynamics(RobotState(comanplus, q, v), b.tau, frames).qdd
            assert np.linalg.norm(qa - qb) <= 1e-6 * np.linalg.norm(qa)
            for t in tasks:
                scale = max(1.0, float(np.linalg.norm(acc_a[t.name])))
                assert np.linalg.norm(acc_a[t.name] - acc_b[t.name]) <= 1e-6 * scale
            params = osf_c.server.get(RobotState(comanplus, q, v), 0).params
            dtau = a.tau - b.tau
            assert np.linalg.norm(params.W @ dtau) <= 1e-6 * np.linalg.norm(a.tau)
            if same_torque:
                assert np.linalg.norm(dtau) <= 1e-5 * np.linalg.norm(a.tau)


def test_config_errors_name_the_choices(comanplus: Robot) -> None:
    tasks = task_pool(comanplus)[:2]
    with pytest.raises(ControllerError, match="valid choices: com, pelvis"):
        make(ToOsf, comanplus, tasks, ["l_sole"], acc_limits={"nosuch": 1.0})
    with pytest.raises(Exception, match="invalid params mode 'periodic:0'"):
        ToOsfConfig(params="periodic:0")
    with pytest.raises(ControllerError, match=r"give 6 .* or 12"):
        make(OsfHqp, comanplus, tasks, ["l_sole", "r_sole"], wrench_weights=[1.0, 2.0])
