"""Kinematic runs: a velocity-level controller moves the robot without dynamics.

Each control tick the runner builds one :class:`RobotState` at (q, q̇_prev), asks the controller
for a generalized velocity q̇ (n,) and integrates it on the configuration manifold,
``q ← pin.integrate(q, q̇ dt)`` (exact for the free-flyer's SE(3) part). No physics runs: MuJoCo
is only used, when a ``MjData`` is passed, to place the model for visualisation.

Logged per tick, as the dynamic runner does where it applies: ``t``, ``ok``, ``iterations``,
``time.<stage>``, ``err.<task>.<part>``, ``base_z``, ``com.x/y/z``, ``diag.<name>``; and, for
kinematic runs, ``joint_margin`` (smallest distance of a joint to its limits [rad], negative when
a limit is violated), ``contact_drift`` (largest displacement of a held contact frame since the
start [m]) and ``collision_distance`` (the controller's smallest collision distance [m], from its
``min_distance`` diagnostic; absent when the controller checks no pair). No ``tau.*`` or
``wrench_*`` columns: a kinematic run has no torques or wrenches.

Solver failures: the fallback is q̇ = 0 (hold the posture) and the failure is counted; after
``sim.max_consecutive_failures`` failed ticks in a row the run stops with status ``failed``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from wbcbench.controllers.base import ControlOutput
from wbcbench.dynamics.state import RobotState
from wbcbench.runs import Run
from wbcbench.scenarios.initial import initial_state
from wbcbench.sim.closed_loop import Rejections, RunLog, RunResult, output_row


def run_kinematic(
    run: Run,
    progress: Callable[[int, int], None] | None = None,
    on_step: Callable[[RobotState, ControlOutput], None] | None = None,
    mj_data: mujoco.MjData | None = None,
    wrap_solver: Callable[[Any], Any] | None = None,
    check: Callable[[ControlOutput], str] | None = None,
) -> RunResult:
    """Run one kinematic run (runner ``kinematic``); never raises for a failed tick.

    Args:
        run: the run (:func:`wbcbench.runs.plan_run`); the solver fields are passed on unused by
            controllers that solve their hierarchy themselves.
        progress: called with (ticks done, total) after each tick.
        on_step: called with each tick's state and output.
        mj_data: a MuJoCo data of the robot's model to set ``qpos`` in each tick (visualisation).
        wrap_solver, check: as in :func:`wbcbench.sim.closed_loop.run_closed_loop`.
    """
    loaded, robot = run.scenario, run.robot
    spec = loaded.spec
    controller = run.make_controller(wrap_solver)
    contacts = controller.ctx.contacts

    model = robot.pin_model
    q, _ = initial_state(loaded, robot)
    v = np.zeros(robot.nv)
    frames = [c.frame for c in contacts]
    fids = [robot.frame_id(f) for f in frames]
    n_ticks = round(spec.duration * spec.control_rate)
    pin_data = model.createData()
    log = RunLog()
    task_parts: dict[str, list[str]] = {}
    failures = consecutive = 0
    status, message = "ok", ""
    contact_p0: list[np.ndarray] = []
    rejections = Rejections()
    wall0 = time.perf_counter()
    tick = 0
    try:
        for tick in range(n_ticks):
            t = tick * spec.dt
            state = RobotState(robot, q, v, pin_data)
            if tick == 0:
                controller.start(state)
                contact_p0 = [state.position(f).copy() for f in fids]
            out = controller.step(state, t)
            if on_step is not None:
                on_step(state, out)
            rejected = check(out) if check is not None else ""
            rejected = rejected if out.ok else ""  # a failed step is a failed tick already
            if rejected:
                rejections.add(t, rejected)
            if out.ok and out.qd is not None and not rejected:
                qd = out.qd
                consecutive = 0
            else:
                failures += 1
                consecutive += 1
                qd = np.zeros(robot.nv)
                if consecutive >= spec.sim.max_consecutive_failures:
                    status, message = (
                        "failed",
                        f"{consecutive} failed ticks in a row: {rejected or out.message}",
                    )

            row = output_row(t, out, task_parts)
            if rejected:
                row["ok"] = 0.0
            row["base_z"] = float(q[2])
            row["com.x"], row["com.y"], row["com.z"] = (float(x) for x in state.com)
            joints = q[7:]
            row["joint_margin"] = float(
                np.min(np.minimum(joints - robot.q_min, robot.q_max - joints))
            )
            drift = [
                np.linalg.norm(state.position(f) - p0)
                for f, p0 in zip(fids, contact_p0, strict=True)
            ]
            row["contact_drift"] = float(max(drift, default=0.0))
            for name, value in out.diagnostics.items():
                if name == "min_distance":
                    row["collision_distance"] = value
                else:
                    row[f"diag.{name}"] = value
            log.add(row)
            if progress is not None:
                progress(tick + 1, n_ticks)
            if status != "ok":
                break

            q = pin.integrate(model, q, qd * spec.dt)
            v = qd
            if mj_data is not None:
                mj_data.qpos[:] = robot.pin_to_mj(q, v)[0]
                mujoco.mj_kinematics(robot.mj_model, mj_data)
    finally:
        controller.close()

    status, message = rejections.outcome(status, message, tick + 1)
    return RunResult(
        status=status,
        message=message,
        log=log,
        ticks=tick + 1,
        failures=failures,
        wall_time=time.perf_counter() - wall0,
        robot=robot,
        contact_frames=frames,
        tau_max=controller.ctx.tau_max,
        task_parts=task_parts,
    )
