"""The Python API: runs of scenarios, a scenario's controller to step by hand, a results
folder to read.

    import wbcbench

    res = wbcbench.run("tocabi_stand_sway", ["qp_wbc", "osf_hqp"], ["proxqp", "daqp"])
    res.runs      # one row per run: status, ticks, wall time [s], ...
    res.metrics   # long form: run_id, task, metric, value, unit

    ctrl = wbcbench.make_controller("tocabi_stand_sway", "osf_hqp", solver="daqp")
    q, v = ctrl.initial_state()
    out = ctrl.step(q, v, t=0.0)   # out.tau (k,), out.qdd (nv,), out.wrench, out.ok
    ctrl.close()

    res = wbcbench.load_results("results")   # res.runs, res.metrics (pandas DataFrames)

Conventions are Pinocchio's, as everywhere in wbcbench: ``q`` (nq,) is the free-flyer pose
(position [m], quaternion x, y, z, w) followed by the joint positions in the model's order;
``v`` (nv,) is the base's spatial velocity in its own frame (linear, angular) followed by the
joint velocities. ``tau`` is in the actuated joints' order (``robot.joint_names``), and the
wrench stacks one 6-vector (force, torque) per contact of ``contact_frames``, each in its
contact frame, the contact's reaction on the robot; a point, line or polygon contact stacks a
3-D force per point instead (``controller.full_wrench`` gives its 6-vector at the frame).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from wbcbench.controllers.base import Controller, ControlOutput
from wbcbench.dynamics.state import RobotState
from wbcbench.report.load import Results, load_results
from wbcbench.robots.loader import Robot
from wbcbench.runs import plan_matrix, plan_run
from wbcbench.scenarios.initial import initial_state
from wbcbench.scenarios.load import LoadedScenario

__all__ = ["Results", "ScenarioController", "load_results", "make_controller", "run"]


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
    overrides: Sequence[str] = (),
    **config: Any,
) -> ScenarioController:
    """A scenario's controller, ready to step; validated as every run is
    (:func:`wbcbench.runs.plan_run`).

    Args:
        scenario: a scenario name (``wbcbench list``) or a path to a YAML file.
        controller: a registered controller name.
        solver: a QP backend name, or ``default`` (the sweeps' default backend).
        tier, mode: the backend's accuracy tier and mode (as in sweeps).
        overrides: ``KEY=VALUE`` scenario overrides, as ``wbcbench run --set``.
        **config: the controller's settings on top of the scenario's (e.g. ``impl="python"``,
            ``params="async"``); unknown keys are errors that name the valid ones.
    """
    planned = plan_run(
        scenario, controller, solver, tier=tier, mode=mode, config=config, overrides=overrides
    )
    return ScenarioController(planned.scenario, planned.robot, planned.make_controller())


def run(
    scenario: str | Path | Sequence[str | Path],
    controllers: str | Sequence[str] = "qp_wbc",
    solvers: str | Sequence[str] = "default",
    *,
    tier: str = "default",
    mode: str = "cold",
    overrides: Sequence[str] = (),
    out: str | Path = "results/api",
    progress: Callable[[str, int, int], None] | None = None,
) -> Results:
    """Closed-loop (or kinematic) runs of every scenario × controller × solver, stored in
    ``out`` as ``wbcbench run`` stores them, and returned.

    Each run is validated before the first simulation step, checked as a sweep's (every QP
    reported solved must meet its optimality conditions) and runs under the wall-clock guard; a
    run already in ``out`` (same scenario, settings and code) is read back, not run again.

    Args:
        scenario: one or more scenario names or YAML paths.
        controllers: registered controller names; one that does not apply to a scenario is
            left out.
        solvers: QP backend names, or ``default``; a controller that solves with its own
            solver (kin_hqp) runs once, with it.
        tier, mode: the backends' accuracy tier and mode.
        overrides: ``KEY=VALUE`` scenario overrides, as ``wbcbench run --set``.
        out: the results folder (created; appended to).
        progress: called with (run label, ticks done, ticks in the run) as a run goes.

    Returns:
        The rows of these runs: ``runs`` (status ``ok``/``fell``/``failed``/``error``,
        ``ticks``, ``sim_duration_s`` [s], ``wall_time_s`` [s], ``message``, ...) and
        ``metrics`` (long form; every value's unit in the ``unit`` column: tracking errors in
        m, rad or rad/s per task, times in µs).
    """
    from wbcbench.bench.results import ResultsStore
    from wbcbench.bench.runner import code_version, execute, run_id

    names = [scenario] if isinstance(scenario, str | Path) else list(scenario)
    runs, _ = plan_matrix(
        names,
        [controllers] if isinstance(controllers, str) else list(controllers),
        [solvers] if isinstance(solvers, str) else list(solvers),
        tier,
        mode,
        overrides,
    )
    store = ResultsStore(out)
    version = code_version(store)
    ids = []
    for planned in runs:
        ids.append(run_id(planned, version))
        report = None
        if progress is not None:
            label = planned.label

            def report(done: int, total: int, label: str = label) -> None:
                progress(label, done, total)

        execute(planned, store, progress=report)
    store.refresh_mirror()
    results = load_results(out)
    results.runs = results.runs[results.runs["run_id"].isin(ids)].reset_index(drop=True)
    results.metrics = results.metrics[results.metrics["run_id"].isin(ids)].reset_index(drop=True)
    return results
