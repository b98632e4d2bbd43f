"""``pink``: pin-pink's differential IK on the robot's Pinocchio model, as a kin_hqp peer.

Each tick: pink's ``Configuration.update`` (forward kinematics and joint Jacobians), the targets
of pink's tasks one control period ahead (:mod:`wbcbench.peers.common`), ``pink.build_ik`` and
``qpsolvers.solve_problem`` with the config's ``solver``; q̇ = Δq / dt, already in Pinocchio's
tangent (the same model as every other controller's, copied: pink attaches its limits to it).

What pink expresses here, beside the table in :mod:`wbcbench.peers.common`:

- tasks: ``ComTask``, ``FrameTask`` (frames by name: another frame of the same name, e.g. the
  ``head`` body beside the ``head`` site, is renamed in pink's copy of the model so that pink
  finds the frame wbcbench resolves), ``PostureTask`` (a cost per joint; pink finds the
  floating base by the joint name ``root_joint``, which pink's copy of the model takes);
- held contacts: a ``FrameTask`` per sole in ``build_ik``'s ``constraints``, gain 0;
- limits: ``ConfigurationLimit`` (gain ξ dt) and ``VelocityLimit`` (the robot's or
  ``velocity_limit`` per joint; none on the floating base, as kin_hqp);
- the gaze of the RQR-HQP paper (eq. 54–55): pink has no gaze or look-at task, so the paper's
  row, J = [p]× [v]× J_ω − [v]× J_o with the rate −λ (v × p) (capped), enters through pink's
  own extension point, a :class:`pink.tasks.Task` subclass whose error and Jacobian are that
  row's (``wbcbench.peers.pink_tasks``).

What pink cannot express: collision avoidance among its limits. pink 4.4's collision handling
is a barrier (``pink.barriers.SelfCollisionBarrier``: a control barrier function on the
distances of a Pinocchio ``GeometryModel``'s collision pairs through coal, with a
safe-displacement term added to the cost), which its documentation defines for smooth convex
geometries only: the scenario's obstacle boxes are outside it (``PositionBarrier`` and
``BodySphericalBarrier`` bound a frame's position or two frames' spheres, not a capsule against a
box). The wrapper passes no collision geometry to pink, so ``pink`` avoids neither
self-collisions nor obstacles (their distance is measured, diagnostic ``min_distance``). Nor the
rest listed in :mod:`wbcbench.peers.common`: strict priorities, the CoM equality and polygon,
``base: support_foot``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from wbcbench.dynamics.state import RobotState
from wbcbench.peers.common import (
    Array,
    GazeReference,
    PeerConfig,
    PeerController,
    Reference,
)
from wbcbench.tasks.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    JointPostureTask,
    Task,
)


class PinkConfig(PeerConfig):
    """Settings of ``pink`` (no collision settings: pink's limits have no collision limit)."""


def _frame_costs(task: Task) -> tuple[float, float]:
    """1 or 0 for the position and orientation parts a frame task regulates."""
    if isinstance(task, FramePositionTask):
        return 1.0, 0.0
    if isinstance(task, FrameOrientationTask):
        return 0.0, 1.0
    return 1.0, 1.0


class PinkIK(PeerController):
    """pin-pink 4.4: one weighted least-squares QP a tick on the Pinocchio model."""

    name = "pink"
    summary = "pin-pink differential IK (weighted tasks, one QP via qpsolvers): kin_hqp's peer"
    Config = PinkConfig
    config: PinkConfig
    library = "pink"
    distribution = "pin-pink"

    def _setup(self) -> None:
        pink = self.lib
        robot, cfg, dt = self.ctx.robot, self.config, self.ctx.dt
        model = pin.Model(robot.pin_model)
        # pink finds the floating base by the name URDF loading gives it
        if model.names[1] != "root_joint":
            model.names[1] = "root_joint"
        frames = {getattr(t, "frame", "") for t in self.ctx.tasks} | set(self.ctx.contact_frames)
        for name in sorted(frames - {""}):
            keep = robot.frame_id(name)
            for i, frame in enumerate(model.frames):
                if frame.name == name and i != keep:
                    frame.name = f"{name}#{i}"
                    model.frames[i] = frame
        self.model = model
        self.configuration = pink.Configuration(
            model, model.createData(), pin.neutral(model), copy_data=False
        )
        self.tasks: list[Any] = []
        for task in self.ctx.tasks:
            if isinstance(task, ComTask):
                self.tasks.append(pink.tasks.ComTask(cost=np.ones(3)))
            elif isinstance(task, FramePositionTask | FrameOrientationTask | FramePoseTask):
                position, orientation = _frame_costs(task)
                self.tasks.append(pink.tasks.FrameTask(task.frame, position, orientation))
            elif isinstance(task, JointPostureTask):
                self.tasks.append(pink.tasks.PostureTask(cost=1.0))
            else:
                raise TypeError(f"pink: no pink task for {type(task).__name__}")
        self.contacts = [
            pink.tasks.FrameTask(frame, position_cost=1.0, orientation_cost=1.0, gain=0.0)
            for frame in self.ctx.contact_frames
        ]
        self.com_hold = None
        if cfg.com == "fixed":
            self.com_hold = pink.tasks.ComTask(cost=np.array([cfg.com_cost, cfg.com_cost, 0.0]))
        self.gaze_rows = None
        if self.gaze is not None:
            from wbcbench.peers.pink_tasks import RowsTask  # imports pink

            self.gaze_rows = RowsTask(cost=self.priority_cost(self.gaze) * np.ones(3))
        self.limits: list[Any] = []
        if cfg.limits:
            self.limits = [
                pink.limits.ConfigurationLimit(model, config_limit_gain=cfg.joint_limit_gain * dt),
                pink.limits.VelocityLimit(model, np.concatenate([np.full(6, np.inf), self.v_max])),
            ]

    def _start(self, state: RobotState) -> None:
        self.configuration.update(state.q)
        for task in self.contacts:
            task.set_target_from_configuration(self.configuration)

    def _update(self, state: RobotState) -> None:
        self.configuration.update(state.q)

    def _set_targets(self, refs: list[Reference], gaze: GazeReference | None) -> None:
        dt, conf = self.ctx.dt, self.configuration
        for lib_task, ref in zip(self.tasks, refs, strict=True):
            step = dt * ref.rate
            if isinstance(ref.task, ComTask):
                lib_task.set_cost(ref.cost)
                lib_task.set_target(self._com() + step)
            elif isinstance(ref.task, JointPostureTask):
                lib_task.cost = ref.cost
                target = conf.q.copy()
                target[7:] += step
                lib_task.set_target(target)
            else:
                T = conf.get_transform_frame_to_world(lib_task.frame)
                p, R = T.translation, T.rotation
                if isinstance(ref.task, FramePositionTask):
                    lib_task.set_position_cost(ref.cost)
                    target = pin.SE3(R, p + step)
                elif isinstance(ref.task, FrameOrientationTask):
                    lib_task.set_orientation_cost(ref.cost)
                    target = pin.SE3(pin.exp3(step) @ R, p)
                else:
                    lib_task.set_position_cost(ref.cost[:3])
                    lib_task.set_orientation_cost(ref.cost[3:])
                    target = pin.SE3(pin.exp3(step[3:]) @ R, p + step[:3])
                lib_task.set_target(target)
        if self.com_hold is not None:
            com = self._com()
            self.com_hold.set_target(com + dt * self.com_hold_rate(com))
        if self.gaze_rows is not None and gaze is not None:
            self.gaze_rows.set_rows(self._gaze_jacobian(), -dt * gaze.rate)

    def _com(self) -> Array:
        conf = self.configuration
        return np.asarray(pin.centerOfMass(self.model, conf.data, conf.q))

    def _gaze_jacobian(self) -> Array:
        """eq. 55 on pink's data: ḟ = ([p]× [v]× J_ω − [v]× J_o) q̇, world-aligned Jacobians."""
        assert self.gaze is not None
        model, data = self.model, self.configuration.data
        fid = self.ctx.robot.frame_id(self.gaze.frame)
        M = data.oMf[fid]
        v = M.rotation[:, self.gaze.axis]
        p = self.gaze.target - M.translation
        J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        vx, px = pin.skew(v), pin.skew(p)
        return np.asarray(px @ vx @ J6[3:] - vx @ J6[:3])

    def _extra_tasks(self) -> list[Any]:
        return [t for t in (self.com_hold, self.gaze_rows) if t is not None]

    def _velocity(self, delta_q: Array, state: RobotState) -> Array:
        return np.asarray(delta_q, dtype=float) / self.ctx.dt
