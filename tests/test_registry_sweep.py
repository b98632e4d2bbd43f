"""Every registered controller, built-in or plugin, builds and steps with every installed solver
backend (a plugin whose optional library is missing is skipped with the reason)."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers.base import ControllerContext
from wbcbench.controllers.registry import (
    available_controllers,
    controller_class,
    make_controller,
)
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import UnknownNameError
from wbcbench.qp import available_solvers, solver_class
from wbcbench.robots.loader import Robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import load_scenario

from .conftest import random_standing_state

DYNAMIC = "tocabi_stand_sway"
#: velocity-level controllers do not apply to torque scenarios: they step on a kinematic one
KINEMATIC = "rqr_reach"


def applicable(scenario: str) -> list[str]:
    """Registered controllers (built-in and plugins) of the scenario's kind: velocity ones for a
    kinematic scenario, torque ones for a dynamic one."""
    kind = "velocity" if load_scenario(scenario).spec.kind == "kinematic" else "torque"
    return sorted(n for n in available_controllers() if controller_class(n).kind == kind)


def skip_unless_applies(name: str, scenario: str) -> None:
    """Skip, with the reason, a controller that cannot run the scenario here (a plugin whose
    optional library is not installed)."""
    reason = controller_class(name).applies_to(load_scenario(scenario).spec)
    if reason:
        pytest.skip(reason)


def context(robot: Robot, solver: str, scenario: str = DYNAMIC) -> ControllerContext:
    """Tier mid, cold; a named setting at its own tier and mode."""
    cls = solver_class(solver)
    tier = "mid" if "mid" in cls.tiers else cls.tiers[0]
    mode = "cold" if "cold" in cls.modes else cls.modes[0]
    return scenario_context(load_scenario(scenario), robot, solver=solver, tier=tier, mode=mode)


@pytest.mark.parametrize("solver", available_solvers())
@pytest.mark.parametrize("name", applicable(DYNAMIC))
def test_build_and_step(tocabi: Robot, name: str, solver: str) -> None:
    """Every controller × backend builds and steps; a failed QP is a clean, named failure.

    Whether a backend solves a controller's QPs is what the benchmark measures (a conventional
    HQP's last levels are nearly all equalities, which some interior-point and active-set
    backends reject at their default settings), so only the backends a controller declares as
    its reference must succeed.
    """
    skip_unless_applies(name, DYNAMIC)
    controller = make_controller(name, context(tocabi, solver))
    q0, v0 = tocabi.keyframe("stand")
    controller.start(RobotState(tocabi, q0, v0))
    rng = np.random.default_rng(0)
    for tick in range(3):
        q, v = random_standing_state(tocabi, rng, q_noise=0.01, v_noise=0.05)
        out = controller.step(RobotState(tocabi, q, v), 1e-3 * tick)
        assert out.tau.shape == (tocabi.k,) and np.all(np.isfinite(out.tau))
        assert out.qdd.shape == (tocabi.nv,)
        assert out.wrench.shape == (12,)
        for stage in ("dynamics", "build", "solve", "total"):
            assert out.timings[stage] >= 0.0
        assert out.timings["total"] >= out.timings["solve"]
        if solver in controller_class(name).reference_solvers:
            assert out.ok, out.message
        elif not out.ok:
            assert solver in out.message, out.message


@pytest.mark.parametrize("name", applicable(KINEMATIC))
def test_velocity_controller_steps_on_a_kinematic_scenario(tocabi: Robot, name: str) -> None:
    """Velocity-level controllers return a finite q̇ command (n,) and their stage timings."""
    assert set(applicable(DYNAMIC)) | set(applicable(KINEMATIC)) == set(available_controllers())
    skip_unless_applies(name, KINEMATIC)
    controller = make_controller(name, context(tocabi, "proxqp", KINEMATIC))
    q0, v0 = tocabi.keyframe("stand")
    controller.start(RobotState(tocabi, q0, v0))
    rng = np.random.default_rng(0)
    for tick in range(3):
        q, v = random_standing_state(tocabi, rng, q_noise=0.01, v_noise=0.05)
        out = controller.step(RobotState(tocabi, q, v), 5e-3 * tick)
        assert out.ok, out.message
        assert out.qd is not None and out.qd.shape == (tocabi.nv,)
        assert np.all(np.isfinite(out.qd))
        for stage in ("dynamics", "build", "solve", "total"):
            assert out.timings[stage] >= 0.0
        assert out.timings["total"] >= out.timings["solve"]


def test_unknown_controller_lists_valid_names(tocabi: Robot) -> None:
    with pytest.raises(UnknownNameError) as exc:
        make_controller("nosuch", context(tocabi, "proxqp"))
    message = str(exc.value)
    assert message.startswith("unknown controller 'nosuch'; valid choices: ")
    assert "hqp" in message and "qp_wbc" in message
