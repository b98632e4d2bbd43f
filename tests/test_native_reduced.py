"""The native reduced-centroidal model equals ReducedModel on the same states (relative 1e-10)."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench import _native
from wbcbench.dynamics.chains import split_chains
from wbcbench.dynamics.reduced import ReducedDynamics, ReducedModel
from wbcbench.dynamics.state import RobotState
from wbcbench.robots.library import TOCABI_DOF_FAMILY
from wbcbench.robots.loader import Robot, load_robot

from .conftest import random_standing_state

pytestmark = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")

TOL = 1e-10
#: the quantities that go through (J_r M⁻¹ J_rᵀ)⁻¹: rounding there grows with its condition
#: number κ, so they are compared to max(TOL, κ · 1e-16); κ stays below 1e6 on the bundled robots
#: (the tolerance is TOL there) but reaches 1e9 on tocabi_dof20, whose 8-DoF chain has a nearly
#: rank-deficient J_G at some states
CONDITIONED = ("M_r", "b_r", "g_r", "Jbar_r")
DOUBLE, SINGLE = ("l_sole", "r_sole"), ("l_sole",)
QUANTITIES = "J_r dJr_v M_r b_r g_r Jbar_r J_cr J_G dJG_v M_uc b_uc g_uc M_uc_factor".split()
CHAIN_QUANTITIES = ("A_G", "I_G", "J_G", "drift", "mass", "com", "R")


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(a) - b), initial=0.0) / max(1.0, np.abs(b).max()))


def conditioned_tolerance(python: ReducedModel) -> float:
    """max(TOL, κ · 1e-16), κ the condition number of M_r (that of J_r M⁻¹ J_rᵀ)."""
    return max(TOL, float(np.linalg.cond(python.M_r)) * 1e-16)


def assert_equal_models(native: object, python: ReducedModel, fixed_base: bool) -> None:
    """Every quantity of ``native`` against ``python``."""
    tol_r = conditioned_tolerance(python)
    for name in QUANTITIES:
        a, b = np.asarray(getattr(native, name)), getattr(python, name)
        assert a.shape == b.shape, name
        if name == "b_uc" and not fixed_base:
            assert np.isnan(a).all() and np.isnan(b).all()
            continue
        err = relative(a, b)
        assert err <= (tol_r if name in CONDITIONED else TOL), (name, err)
    M_r = np.asarray(native.M_r)  # type: ignore[attr-defined]
    assert np.array_equal(M_r, M_r.T)
    for i, chain in enumerate(python.chains):
        centroid = native.chain(i)  # type: ignore[attr-defined]
        for name in CHAIN_QUANTITIES:
            a, b = np.asarray(getattr(centroid, name)), np.asarray(getattr(chain, name))
            assert a.shape == b.shape, (i, name)
            assert relative(a, b) <= TOL, (i, name, relative(a, b))


def check_robot(robot: Robot, frames: tuple[str, ...], n_states: int = 8) -> float:
    """Native vs Python at random perturbed states, fixed_base on and off, tasks included.

    Returns the largest tolerance the conditioned quantities were given."""
    split = split_chains(robot.pin_model, frames)
    reference = ReducedDynamics(robot.pin_model, split)
    native = _native.reduced_dynamics(robot, split, ["pelvis"])
    assert (native.n_plain, native.n_reduced) == (split.plain.size, split.n_reduced)
    assert native.n_chains == len(split.chains)
    assert np.array_equal(native.unconstrained, split.unconstrained)
    rng = np.random.default_rng(17)
    tol_r = TOL
    for k in range(n_states):
        q, v = random_standing_state(robot, rng, q_noise=0.1, v_noise=0.5)
        native.dynamics.update(q, v)
        for fixed_base in (True, False):
            seconds = native.compute(fixed_base)
            assert seconds > 0 and native.time == seconds
            # a fresh state per compute: the reference reads data.oYcrb, which M⁻¹ overwrites
            state = RobotState(robot, q, v)
            red = reference.compute(state, fixed_base=fixed_base)
            assert_equal_models(native, red, fixed_base)
        tol_r = max(tol_r, conditioned_tolerance(red))
        # eq. (22) and §3.4.1 on a reducible task (the CoM), a chain's hand and random rows
        tasks = {
            "com": (state.J_com, state.com_drift),
            "pelvis": (state.jacobian("pelvis"), state.drift("pelvis")),
            "random": (rng.normal(size=(4, robot.nv)), rng.normal(size=4)),
        }
        if robot.has_frame("r_hand"):
            tasks["r_hand"] = (state.jacobian("r_hand"), state.drift("r_hand"))
        for name, (J, drift) in tasks.items():
            Jr, drift_r = native.task(J, drift)
            Jr_ref, drift_ref = red.task(J, drift)
            assert relative(Jr, Jr_ref) <= conditioned_tolerance(red), name
            assert relative(drift_r, drift_ref) <= conditioned_tolerance(red), name
            mask = native.reducible_rows(J)
            assert mask.dtype == bool and np.array_equal(mask, red.reducible_rows(J)), name
        if k == 0:
            assert native.reducible_rows(state.J_com).all()
            if "r_hand" in tasks:
                assert not native.reducible_rows(tasks["r_hand"][0]).any()
    return tol_r


@pytest.mark.parametrize("frames", [DOUBLE, SINGLE], ids=["double", "single"])
def test_every_quantity_equals_the_reference(robot: Robot, frames: tuple[str, ...]) -> None:
    assert check_robot(robot, frames) == TOL


def test_a_hand_contact_with_an_overlapping_waist(comanplus: Robot) -> None:
    # the chain hangs from the waist, not from the base: its parent body's axes differ
    frames = ("l_sole", "r_sole", "l_palm")
    assert split_chains(comanplus.pin_model, frames).chains[0].parent_joint != 1
    assert check_robot(comanplus, frames, n_states=4) == TOL


@pytest.mark.parametrize("dof", [d for d in TOCABI_DOF_FAMILY if d != 33])
def test_dof_family(dof: int) -> None:
    robot = load_robot(f"tocabi_dof{dof}")
    assert split_chains(robot.pin_model, DOUBLE).unconstrained.size == dof - 12
    tol_r = check_robot(robot, DOUBLE, n_states=6)
    assert tol_r == TOL or dof == 20


def test_shared_dynamics_and_bad_input(tocabi: Robot) -> None:
    split = split_chains(tocabi.pin_model, DOUBLE)
    dynamics = _native.robot_dynamics(tocabi, ["pelvis"], list(DOUBLE))
    native = _native.reduced_dynamics(tocabi, split, dynamics=dynamics)
    assert native.dynamics is dynamics
    with pytest.raises(ValueError, match=r"contact frames \[l_sole\] but the dynamics has"):
        _native.reduced_dynamics(tocabi, split_chains(tocabi.pin_model, SINGLE), dynamics=dynamics)

    def spec_with(**change: object) -> object:
        spec = _native.split_spec(split)
        for key, value in change.items():
            setattr(spec, key, value)
        return spec

    core = _native._core
    with pytest.raises(ValueError, match=r"plain velocity index 99 out of range \[0, 39\)"):
        core.ReducedDynamics(dynamics, spec_with(plain=[*split.plain.tolist(), 99]))
    with pytest.raises(ValueError, match="velocity index 5 is in neither"):
        core.ReducedDynamics(dynamics, spec_with(plain=split.plain.tolist()[:5]))
    with pytest.raises(ValueError, match="velocity index 0 is in more than one part"):
        core.ReducedDynamics(dynamics, spec_with(plain=[0, *split.plain.tolist()]))
    chain = _native.split_spec(split).chains[0]
    chain.root_joints = [500]
    with pytest.raises(ValueError, match="root joint 500 is not a joint id"):
        core.ReducedDynamics(dynamics, spec_with(chains=[chain]))

    with pytest.raises(RuntimeError, match="not positive definite"):  # before any update
        native.compute(False)
    q, v = tocabi.keyframe("stand")
    dynamics.update(q, v)
    native.compute(False)
    n, n_r = tocabi.nv, split.n_reduced
    with pytest.raises(ValueError, match=rf"J must be \(m, {n}\) and drift \(m,\)"):
        native.task(np.zeros((3, n - 1)), np.zeros(3))
    with pytest.raises(ValueError, match=rf"J must be \(m, {n}\)"):
        native.task(np.zeros((3, n)), np.zeros(2))
    with pytest.raises(ValueError, match=rf"J must be \(m, {n}\)"):
        native.reducible_rows(np.zeros((2, n + 1)))
    with pytest.raises(IndexError):
        native.chain(1)
    Jr, drift_r = native.task(np.zeros((0, n)), np.zeros(0))
    assert Jr.shape == (0, n_r) and drift_r.shape == (0,)
