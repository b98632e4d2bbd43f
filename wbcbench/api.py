"""The small Python API: a scenario's controller to step by hand, and a results folder to read.

    import wbcbench

    ctrl = wbcbench.make_controller("tocabi_stand_sway", "osf_hqp", solver="daqp")
    q, v = ctrl.initial_state()
    out = ctrl.step(q, v, t=0.0)   # out.tau (k,), out.qdd (nv,), out.wrench (6c,), out.ok
    ctrl.close()

    res = wbcbench.load_results("results")   # res.runs, res.metrics (pandas DataFrames)

Conventions are Pinocchio's, as everywhere in wbcbench: ``q`` (nq,) is the free-flyer pose
(position [m], quaternion x, y, z, w) followed by the joint positions in the model's order;
``v`` (nv,) is the base's spatial velocity in its own frame (linear, angular) followed by the
joint velocities. ``tau`` is in the actuated joints' order (``robot.joint_names``), and the
wrench stacks one 6-vector (force, torque) per contact of ``contact_frames``, each in its
contact frame, the contact's reaction on the robot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from wbcbench.controllers.base import Controller, ControlOutput
from wbcbench.dynamics.state import RobotState
from wbcbench.report.load import Results, load_results
from wbcbench.robots.loader import Robot
from wbcbench.scenarios.initial import initial_state
from wbcbench.scenarios.load import LoadedScenario, load_scenario, load_scenario_robot

__all__ = ["Results", "ScenarioController", "load_results", "make_controller"]


class ScenarioController:
    """A controller set up from a scenario file, started at the scenario's initial state.

    Attributes:
        scenario: the loaded (validated) scenario.
        robot: its robot (Pinocchio model, keyframes, limits).
        controller: the controller instance (its ``impl`` says native or python).
        contact_frames: the frames whose wrenches ``step`` predicts, in order.
    """

    def __init__(self, scenario: LoadedScenario, robot: Robot, controller: Controller) -> None:
        self.scenario = scenario
        self.robot = robot
        self.controller = controller
        self.contact_frames = list(controller.ctx.contact_frames)
        self.controller.start(RobotState(robot, *self.initial_state()))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(q, v)`` of the scenario's initial state (copies)."""
        return initial_state(self.scenario, self.robot)

    def step(self, q: np.ndarray, v: np.ndarray, t: float) -> ControlOutput:
        """One control tick at state ``(q, v)`` and scenario time ``t`` [s]."""
        q = np.asarray(q, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        if q.shape != (self.robot.nq,) or v.shape != (self.robot.nv,):
            raise ValueError(
                f"q must have shape ({self.robot.nq},) and v ({self.robot.nv},); "
                f"got {q.shape} and {v.shape}"
            )
        return self.controller.step(RobotState(self.robot, q, v), float(t))

    def close(self) -> None:
        """Stop what the controller runs beside the loop (the parameter worker of ``async``)."""
        self.controller.close()

    def __enter__(self) -> ScenarioController:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def make_controller(
    scenario: str | Path,
    controller: str,
    solver: str = "default",
    *,
    tier: str = "default",
    mode: str = "hot",
    overrides: list[str] | None = None,
    **config: Any,
) -> ScenarioController:
    """A scenario's controller, ready to step.

    Args:
        scenario: a scenario name (``wbcbench list``) or a path to a YAML file.
        controller: a registered controller name.
        solver: a QP backend name, or ``default`` (the sweeps' default backend).
        tier, mode: the backend's accuracy tier and mode (as in sweeps).
        overrides: ``KEY=VALUE`` scenario overrides, as ``wbcbench run --set``.
        **config: the controller's settings on top of the scenario's (e.g. ``impl="python"``,
            ``params="async"``); unknown keys are errors that name the valid ones.
    """
    from wbcbench.bench.sweep import default_solver
    from wbcbench.sim.closed_loop import RunSettings
    from wbcbench.sim.setup import build_controller

    loaded = load_scenario(str(scenario), list(overrides or []))
    robot = load_scenario_robot(loaded)
    settings = RunSettings(
        controller=controller,
        solver=default_solver() if solver == "default" else solver,
        tier=tier,
        mode=mode,
        controller_config=dict(config),
    )
    return ScenarioController(loaded, robot, build_controller(loaded, settings, robot))
