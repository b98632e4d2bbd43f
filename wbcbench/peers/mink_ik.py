"""``mink``: mink's differential IK on the robot's MuJoCo model, as a kin_hqp peer.

Each tick: mink's ``Configuration.update`` at the state's configuration (MuJoCo's qpos, from
Pinocchio's q), the targets of mink's tasks one control period ahead
(:mod:`wbcbench.peers.common`), ``mink.build_ik`` and ``qpsolvers.solve_problem`` with the
config's ``solver``; Δq / dt is MuJoCo's qvel (the free joint's linear rate in world axes), which
:meth:`~wbcbench.robots.loader.Robot.mj_to_pin` turns into Pinocchio's q̇.

mink's model is a copy of the robot's MuJoCo model compiled from its spec at start, with the
scenario's obstacle boxes added as world geoms and the ``<body>_capsule`` geoms made collidable
(contype = conaffinity = 1: the generated robots' capsules collide with nothing in simulation,
and mink's collision limit skips pairs whose contype and conaffinity exclude each other). Only
mink's kinematics and distance queries run on it.

What mink expresses here, beside the table in :mod:`wbcbench.peers.common`:

- tasks: ``ComTask`` (MuJoCo's ``subtree_com`` of the root body), ``FrameTask`` (sites, else
  bodies, as wbcbench resolves a frame name), ``PostureTask`` (a cost per dof);
- held contacts: a ``FrameTask`` per sole in ``build_ik``'s ``constraints``, gain 0;
- limits: ``ConfigurationLimit`` (gain ξ dt), ``VelocityLimit`` (per joint) and, with
  ``collision: true``, ``CollisionAvoidanceLimit`` on kin_hqp's capsule pairs and on
  ``obstacle_bodies`` × the obstacle boxes, on MuJoCo's own geom distances
  (``mj_geomDistance``) instead of kin_hqp's closest-point formulas. mink 1.3 bounds the
  approach of a pair over the step, −ḋ dt, by gain · (d − d_min) / dt (a displacement against
  a distance over the period), so the gain that gives kin_hqp's bound ḋ ≥ −ξ_d (d − d_safe)
  is ξ_d dt², not ξ_d dt. Pairs farther apart than ``collision_detection_distance`` add no row
  (kin_hqp keeps every pair);
- the gaze: mink's ``LookAtTask`` on the same frame axis and target. Its error is a − d̂ (the
  axis against the unit direction to the target), not the paper's v × p; its gain is λ dt,
  scaled each tick by min(1, cap / ‖λ (v × p)‖) so that kin_hqp's gaze cap holds.

What mink cannot express: the rest listed in :mod:`wbcbench.peers.common` (strict priorities,
the CoM equality and polygon, ``base: support_foot``).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pinocchio as pin
from pydantic import Field, model_validator

from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.peers.common import (
    Array,
    GazeReference,
    PeerConfig,
    PeerController,
    Reference,
)
from wbcbench.tasks.collision import CAPSULE_SUFFIX
from wbcbench.tasks.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePositionTask,
    JointPostureTask,
)


class MinkConfig(PeerConfig):
    """Settings of ``mink``: the shared ones and its collision avoidance."""

    collision: bool = Field(
        True, description="avoid the capsule pairs and the obstacles (CollisionAvoidanceLimit)"
    )
    collision_gain: float = Field(0.5, gt=0, description="ξ_d of kin_hqp's bound [1/s]")
    collision_margin: float = Field(0.005, ge=0, description="d_safe [m]")
    collision_detection_distance: float = Field(
        0.1, gt=0, description="pairs farther apart than this add no row [m]"
    )

    @model_validator(mode="after")
    def _detection_beyond_margin(self) -> MinkConfig:
        if self.collision_detection_distance <= self.collision_margin:
            raise ValueError(
                "collision_detection_distance must exceed collision_margin, or no pair is "
                "ever detected before it is too close"
            )
        return self


class MinkIK(PeerController):
    """mink 1.3: one weighted least-squares QP a tick on the MuJoCo model."""

    name = "mink"
    summary = "mink differential IK (weighted tasks, collision limits, one QP via qpsolvers)"
    Config = MinkConfig
    config: MinkConfig
    library = "mink"
    distribution = "mink"

    def _setup(self) -> None:
        # mink's model holds the obstacles, which arrive after construction: built at start
        self.configuration: Any = None
        if self.ctx.robot.mj_spec is None:
            raise ControllerError("mink: the robot was loaded without its MuJoCo spec")

    def _frame(self, name: str) -> tuple[str, str]:
        """The MuJoCo object wbcbench means by a frame name: a site, else a body."""
        model = self.model
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) >= 0:
            return name, "site"
        return name, "body"

    def _compile(self) -> mujoco.MjModel:
        """The robot's model with the capsules collidable and the obstacle boxes added."""
        spec = self.ctx.robot.mj_spec.copy()  # type: ignore[union-attr]
        for geom in spec.geoms:
            if geom.name.endswith(CAPSULE_SUFFIX):
                geom.contype, geom.conaffinity = 1, 1
        for box in self.obstacles:
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, np.asarray(box.R, dtype=float).reshape(9))
            spec.worldbody.add_geom(
                name=f"obstacle_{box.name}",
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=np.asarray(box.half, dtype=float),
                pos=np.asarray(box.center, dtype=float),
                quat=quat,
                contype=1,
                conaffinity=1,
            )
        return spec.compile()

    def _start(self, state: RobotState) -> None:
        mink, cfg, dt, robot = self.lib, self.config, self.ctx.dt, self.ctx.robot
        self.model = model = self._compile()
        self.configuration = mink.Configuration(model, robot.pin_to_mj(state.q)[0])
        self.tasks: list[Any] = []
        for task in self.ctx.tasks:
            if isinstance(task, ComTask):
                self.tasks.append(mink.ComTask(cost=np.ones(3)))
            elif isinstance(task, JointPostureTask):
                self.tasks.append(mink.PostureTask(model, cost=np.zeros(model.nv)))
            else:
                frame, kind = self._frame(task.frame)  # type: ignore[attr-defined]
                self.tasks.append(mink.FrameTask(frame, kind, 0.0, 0.0))
        self.contacts = []
        for name in self.ctx.contact_frames:
            frame, kind = self._frame(name)
            hold = mink.FrameTask(frame, kind, position_cost=1.0, orientation_cost=1.0, gain=0.0)
            hold.set_target_from_configuration(self.configuration)
            self.contacts.append(hold)
        self.com_hold = None
        if cfg.com == "fixed":
            self.com_hold = mink.ComTask(cost=np.array([cfg.com_cost, cfg.com_cost, 0.0]))
        self.look_at = None
        if self.gaze is not None:
            frame, kind = self._frame(self.gaze.frame)
            axis = np.eye(3)[self.gaze.axis]
            cost = self.priority_cost(self.gaze)
            self.look_at = mink.LookAtTask(frame, kind, axis=axis, cost=cost, gain=1.0)
            self.look_at.set_target(np.asarray(self.gaze.target, dtype=float))
        self.limits: list[Any] = []
        if cfg.limits:
            named = zip(robot.joint_names, self.v_max, strict=True)
            speeds = {joint: float(v) for joint, v in named if np.isfinite(v)}
            self.limits += [
                mink.ConfigurationLimit(model, gain=min(1.0, cfg.joint_limit_gain * dt)),
                mink.VelocityLimit(model, speeds),
            ]
        pairs = self._geom_pairs()
        if cfg.collision and pairs:
            self.limits.append(
                mink.CollisionAvoidanceLimit(
                    model,
                    pairs,
                    # mink bounds the displacement's normal part by gain (d − d_min) / dt
                    gain=min(1.0, cfg.collision_gain * dt * dt),
                    minimum_distance_from_collisions=cfg.collision_margin,
                    collision_detection_distance=cfg.collision_detection_distance,
                )
            )

    def _geom_pairs(self) -> list[tuple[list[str], list[str]]]:
        """kin_hqp's capsule pairs and obstacle pairs as mink's geom groups."""
        pairs = [([a + CAPSULE_SUFFIX], [b + CAPSULE_SUFFIX]) for a, b in self._pairs]
        if self.obstacles:
            bodies = [b + CAPSULE_SUFFIX for b in self._obstacle_bodies]
            boxes = [f"obstacle_{box.name}" for box in self.obstacles]
            pairs.append((bodies, boxes))
        return pairs

    def _update(self, state: RobotState) -> None:
        self.configuration.update(self.ctx.robot.pin_to_mj(state.q)[0])

    def _set_targets(self, refs: list[Reference], gaze: GazeReference | None) -> None:
        mink, dt, conf, robot = self.lib, self.ctx.dt, self.configuration, self.ctx.robot
        for lib_task, ref in zip(self.tasks, refs, strict=True):
            step = dt * ref.rate
            if isinstance(ref.task, ComTask):
                lib_task.set_cost(ref.cost)
                lib_task.set_target(conf.data.subtree_com[1] + step)
            elif isinstance(ref.task, JointPostureTask):
                cost = np.zeros(self.model.nv)
                cost[robot.mj_dof_adr] = ref.cost
                lib_task.set_cost(cost)
                target = conf.q.copy()
                target[robot.mj_qpos_adr] += step
                lib_task.set_target(target)
            else:
                T = conf.get_transform_frame_to_world(lib_task.frame_name, lib_task.frame_type)
                p, R = T.translation(), T.rotation().as_matrix()
                if isinstance(ref.task, FramePositionTask):
                    position, orientation = ref.cost, np.zeros(3)
                    p_t, R_t = p + step, R
                elif isinstance(ref.task, FrameOrientationTask):
                    position, orientation = np.zeros(3), ref.cost
                    p_t, R_t = p, pin.exp3(step) @ R
                else:
                    position, orientation = ref.cost[:3], ref.cost[3:]
                    p_t, R_t = p + step[:3], pin.exp3(step[3:]) @ R
                lib_task.set_position_cost(position)
                lib_task.set_orientation_cost(orientation)
                rotation = mink.SO3.from_matrix(R_t)
                lib_task.set_target(mink.SE3.from_rotation_and_translation(rotation, p_t))
        if self.com_hold is not None:
            com = np.asarray(conf.data.subtree_com[1], dtype=float)
            self.com_hold.set_target(com + dt * self.com_hold_rate(com))
        if self.look_at is not None and gaze is not None:
            # the capped rate's norm against the uncapped ‖λ (v × p)‖: kin_hqp's cap as a scale
            # of the gain λ dt
            uncapped = gaze.gain * float(np.linalg.norm(gaze.term.error))
            scale = 1.0 if uncapped == 0.0 else float(np.linalg.norm(gaze.rate)) / uncapped
            self.look_at.gain = min(1.0, gaze.gain * dt * scale)

    def _extra_tasks(self) -> list[Any]:
        return [t for t in (self.com_hold, self.look_at) if t is not None]

    def _velocity(self, delta_q: Array, state: RobotState) -> Array:
        qvel = np.asarray(delta_q, dtype=float) / self.ctx.dt
        return self.ctx.robot.mj_to_pin(self.configuration.q, qvel)[1]
