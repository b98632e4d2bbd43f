"""Chain split and reduced-centroidal model (RC-LQP §3) against the full model's dynamics."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.dynamics.chains import split_chains
from wbcbench.dynamics.reduced import ReducedDynamics
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ModelError
from wbcbench.robots.library import TOCABI_DOF_FAMILY, tocabi_arm
from wbcbench.robots.loader import Robot, load_robot

from .conftest import random_standing_state

CASES = [
    ("tocabi_like", ("l_sole", "r_sole")),
    ("tocabi_like", ("l_sole",)),
    ("comanplus_like", ("l_sole", "r_sole")),
    # a hand in contact: the waist joins the constraint chain and the right arm needs it
    ("comanplus_like", ("l_sole", "r_sole", "l_palm")),
]


def _names(robot: Robot, idx: np.ndarray) -> set[str]:
    return {robot.joint_names[i - 6] for i in idx}


def test_tocabi_double_and_single_support_split(tocabi: Robot) -> None:
    ds = split_chains(tocabi.pin_model, ("l_sole", "r_sole"))
    assert ds.constraint.size == 12 and ds.kept.size == 0 and len(ds.chains) == 1
    assert ds.chains[0].dof == 21 and ds.n_reduced == 6 + 12 + 6
    assert {"Waist1", "Neck", "L_Wrist2", "R_Shoulder1"} <= _names(tocabi, ds.chains[0].idx)
    ss = split_chains(tocabi.pin_model, ("l_sole",))
    # the swing leg and the upper body hang from the pelvis: one 27-DoF chain
    assert ss.constraint.size == 6 and len(ss.chains) == 1 and ss.chains[0].dof == 27
    assert {"R_HipYaw", "R_AnkleRoll"} <= _names(tocabi, ss.chains[0].idx)
    for split in (ds, ss):
        every = np.concatenate([split.virtual, split.constraint, split.kept, split.unconstrained])
        assert np.array_equal(np.sort(every), np.arange(tocabi.nv))


def test_overlapping_waist_when_a_hand_is_in_contact(comanplus: Robot) -> None:
    split = split_chains(comanplus.pin_model, ("l_sole", "r_sole", "l_palm"))
    assert {"WaistLat", "WaistYaw", "L_ShSag"} <= _names(comanplus, split.constraint)
    (chain,) = split.chains
    assert _names(comanplus, chain.idx) == {j for j in comanplus.joint_names if j[:2] == "R_"} - {
        j for j in comanplus.joint_names if "Hip" in j or "Knee" in j or "Ankle" in j
    }
    assert _names(comanplus, chain.overlap) == {"WaistLat", "WaistYaw"}


@pytest.mark.parametrize("dof", TOCABI_DOF_FAMILY)
def test_dof_family_unconstrained_chain_size(dof: int) -> None:
    robot = load_robot("tocabi_like" if dof == 33 else f"tocabi_dof{dof}")
    assert robot.k == dof
    split = split_chains(robot.pin_model, ("l_sole", "r_sole"))
    assert split.unconstrained.size == dof - 12


def test_family_arms_keep_mass_and_reach() -> None:
    full = tocabi_arm(8)
    for dof in range(1, 16):
        rows = tocabi_arm(dof)
        assert len(rows) == dof
        assert sum(r[6] for r in rows) == pytest.approx(sum(r[6] for r in full))
        assert sum(r[7] for r in rows) == pytest.approx(sum(r[7] for r in full))
        assert all(a[1] != b[1] for a, b in itertools.pairwise(rows) if dof > 8)


def test_unknown_contact_frame_names_the_choices(tocabi: Robot) -> None:
    with pytest.raises(ModelError, match=r"no frame 'l_toe'; valid frames: .*l_sole"):
        split_chains(tocabi.pin_model, ("l_toe",))


@pytest.mark.parametrize(("name", "frames"), CASES)
def test_reduced_model_identities(name: str, frames: tuple[str, ...]) -> None:
    """Eq. (14)–(15) against the full model at random states and random accelerations."""
    robot = load_robot(name)
    split = split_chains(robot.pin_model, frames)
    builder = ReducedDynamics(robot.pin_model, split)
    rng = np.random.default_rng(3)
    n = robot.nv
    cc = np.concatenate([split.constraint, split.kept])
    for _ in range(10):
        q, v = random_standing_state(robot, rng, v_noise=1.0)
        state = RobotState(robot, q, v)
        red = builder.compute(state)
        eye = np.eye(n)
        # base and constraint rows of J̄_rᵀ are selections (M sees a chain through its momentum)
        assert np.abs(red.Jbar_r.T[:6] - eye[:6]).max() <= 1e-10
        assert np.abs(red.Jbar_r.T[6 : 6 + cc.size] - eye[cc]).max() <= 1e-10
        # J̄_r is a generalized inverse and eq. (15) equals eq. (14e)
        assert np.abs(red.J_r @ red.Jbar_r - np.eye(split.n_reduced)).max() <= 1e-9
        Jc = state.contact_jacobian(frames)
        assert np.abs(Jc @ red.Jbar_r - red.J_cr).max() <= 1e-9
        # rows of eq. (14) at q̈_r = J_r q̈ + J̇_r q̇ equal the full dynamics' rows
        qdd = rng.normal(size=n)
        qdd_r = red.J_r @ qdd + red.dJr_v
        lhs = red.M_r @ qdd_r + red.b_r + red.g_r
        rhs = state.M @ qdd + state.h
        scale = max(1.0, float(np.abs(rhs).max()))
        assert np.abs(lhs[:6] - rhs[:6]).max() <= 1e-9 * scale
        assert np.abs(lhs[6 : 6 + cc.size] - rhs[cc]).max() <= 1e-9 * scale
        # the CoM is a reduced-space task (J N_r = 0), a hand in a chain is not
        assert red.reducible_rows(state.J_com).all()
        assert not red.reducible_rows(state.jacobian("r_hand")).any()
        # eq. (17): M_uc and g_uc are the full model's blocks
        uc = split.unconstrained
        assert np.array_equal(red.M_uc, state.M[np.ix_(uc, uc)])


@pytest.mark.parametrize(("name", "frames"), CASES[:2])
def test_chain_drift_is_the_relative_momentum_rate(name: str, frames: tuple[str, ...]) -> None:
    """I_G (J_G q̈_u + J̇_G q̇) = d/dt (A_G q̇_u) along a motion of the chain alone (central
    finite difference of the chain's centroidal momentum in its parent's axes)."""
    robot = load_robot(name)
    split = split_chains(robot.pin_model, frames)
    builder = ReducedDynamics(robot.pin_model, split)
    rng = np.random.default_rng(4)
    (chain,) = split.chains
    q, v = random_standing_state(robot, rng, v_noise=1.0)
    v_rel = np.zeros(robot.nv)
    v_rel[chain.idx] = v[chain.idx]
    a_rel = np.zeros(robot.nv)
    a_rel[chain.idx] = rng.normal(size=chain.dof)

    def momentum(qq: np.ndarray, vv: np.ndarray) -> np.ndarray:
        c = builder.compute(RobotState(robot, qq, vv), fixed_base=False).chains[0]
        return c.A_G @ vv[chain.idx]

    eps = 1e-6
    m = robot.pin_model
    fd = (
        momentum(pin.integrate(m, q, v_rel * eps), v_rel + a_rel * eps)
        - momentum(pin.integrate(m, q, -v_rel * eps), v_rel - a_rel * eps)
    ) / (2 * eps)
    c = builder.compute(RobotState(robot, q, v_rel)).chains[0]
    predicted = c.I_G @ (c.J_G @ a_rel[chain.idx] + c.drift)
    assert np.abs(fd - predicted).max() <= 1e-6 * max(1.0, float(np.abs(fd).max()))


def test_reduced_model_does_not_depend_on_what_was_computed_first(tocabi: Robot) -> None:
    """M⁻¹ reuses Pinocchio's subtree-inertia buffer: a reduced model computed after it must be
    the one computed before it."""
    split = split_chains(tocabi.pin_model, ["l_sole", "r_sole"])
    reduced = ReducedDynamics(tocabi.pin_model, split)
    q, v = tocabi.keyframe("stand")
    v = np.random.default_rng(3).uniform(-0.3, 0.3, tocabi.nv)
    first = reduced.compute(RobotState(tocabi, q, v))
    after_minv = RobotState(tocabi, q, v)
    after_minv.Minv  # noqa: B018 - computed first on purpose
    second = reduced.compute(after_minv)
    for name in ("M_r", "b_r", "g_r", "J_r", "Jbar_r", "J_G"):
        np.testing.assert_allclose(getattr(second, name), getattr(first, name), rtol=0, atol=1e-9)
