"""Operational-space tasks: error, Jacobian, drift and the PD acceleration reference.

A task regulates a quantity x(q) of dimension m with the reference

    ẍ* = ẍ_d + k_p (x_d − x) + k_v (ẋ_d − ẋ)

and exposes what every controller needs to formulate it: the Jacobian J (m, n) and the drift
J̇ q̇ (m,), so that the realized task acceleration is ``J q̈ + J̇ q̇``. Frame quantities are
world-aligned (see :mod:`wbcbench.dynamics.state`); orientation errors are rotation vectors
``log(R_d Rᵀ)`` in world axes, whose derivative is the world angular velocity to first order.

Task types: CoM position, frame position, frame orientation, frame pose (with axis selection),
joint posture and joint damping. Each task is *started* once at the initial state, which fixes
the initial value that offset references are added to.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pinocchio as pin

from wbcbench.dynamics.state import RobotState
from wbcbench.tasks.trajectories import Constant, Trajectory

AXES6 = ("x", "y", "z", "rx", "ry", "rz")


@dataclass
class TaskTerm:
    """One task evaluated at one state.

    Attributes:
        J: task Jacobian (m, n).
        drift: J̇ q̇ (m,).
        acc_ref: the PD reference ẍ* (m,).
        error: x_d − x (m,) [m or rad].
        error_vel: ẋ_d − ẋ (m,).
    """

    task: Task
    J: np.ndarray
    drift: np.ndarray
    acc_ref: np.ndarray
    error: np.ndarray
    error_vel: np.ndarray

    @property
    def dim(self) -> int:
        return int(self.J.shape[0])

    def realized(self, qdd: np.ndarray) -> np.ndarray:
        """Task acceleration J q̈ + J̇ q̇ produced by a joint acceleration (m,)."""
        return self.J @ qdd + self.drift


@dataclass
class Task(ABC):
    """Base class. Subclasses implement :meth:`_measure` and :meth:`_full_jacobian`.

    Attributes:
        name: the task's name in logs and metrics.
        priority: 1 = highest. Hierarchical controllers use it as the level; weighted ones map it
            to a weight.
        kp, kv: PD gains (scalar or one per selected axis) [1/s², 1/s].
        reference: trajectory of the selected axes, offset from the initial value unless
            ``absolute``.
        weight: explicit weight (overrides the controller's weight for the priority).
        axes: selected rows of the full task (e.g. ``("x", "z")``).
    """

    name: str
    priority: int = 1
    kp: float | np.ndarray = 100.0
    kv: float | np.ndarray = 20.0
    reference: Trajectory | None = None
    weight: float | None = None
    absolute: bool = False
    axes: tuple[str, ...] = ()
    level: str = "acceleration"

    full_axes: ClassVar[tuple[str, ...]] = ("x", "y", "z")
    #: unit of the error norm, per part ("pos" in m, "rot" in rad, ...)
    kind: ClassVar[str] = "position"

    _rows: np.ndarray = field(init=False, repr=False)
    _x0: np.ndarray | None = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        if not self.axes:
            self.axes = self.full_axes
        self._rows = np.array([self.full_axes.index(a) for a in self.axes], dtype=int)
        if self.reference is None:
            self.reference = Constant(np.zeros(len(self.axes)))

    @property
    def dim(self) -> int:
        return len(self.axes)

    # -- to implement -----------------------------------------------------------------------

    @abstractmethod
    def _full_jacobian(self, state: RobotState) -> np.ndarray:
        """Task Jacobian of all axes (full dim, n)."""

    @abstractmethod
    def _full_drift(self, state: RobotState) -> np.ndarray:
        """Drift J̇ q̇ of all axes (full dim,)."""

    @abstractmethod
    def _value(self, state: RobotState) -> np.ndarray:
        """The regulated quantity (full dimension) in a form references can offset."""

    def _error(self, state: RobotState, x_d: np.ndarray) -> np.ndarray:
        """x_d − x (full dimension), x_d the full desired value."""
        return x_d - self._value(state)

    # -- common ------------------------------------------------------------------------------

    def start(self, state: RobotState) -> None:
        """Fix the initial value that offset references are added to."""
        self._x0 = self._value(state).copy()

    def desired(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Full-dimension (x_d, ẋ_d, ẍ_d) at time t [s]."""
        if self._x0 is None:
            raise RuntimeError(f"task {self.name!r} was not started")
        assert self.reference is not None
        pos, vel, acc = self.reference.sample(t)
        full = len(self.full_axes)
        x_d = self._x0.copy()
        if self.absolute:
            x_d[self._rows] = pos
        else:
            x_d[self._rows] += pos
        xd_d = np.zeros(full)
        xdd_d = np.zeros(full)
        xd_d[self._rows] = vel
        xdd_d[self._rows] = acc
        return x_d, xd_d, xdd_d

    def evaluate(self, state: RobotState, t: float) -> TaskTerm:
        x_d, xd_d, xdd_d = self.desired(t)
        J = self._full_jacobian(state)[self._rows]
        drift = self._full_drift(state)[self._rows]
        error = self._error(state, x_d)[self._rows]
        error_vel = xd_d[self._rows] - J @ state.v
        acc_ref = xdd_d[self._rows] + self.kp * error + self.kv * error_vel
        return TaskTerm(self, J, drift, acc_ref, error, error_vel)

    def error_norms(self, term: TaskTerm) -> dict[str, float]:
        """Error norms reported as metrics, keyed by part ("pos" [m], "rot" [rad], "joint")."""
        return {"pos": float(np.linalg.norm(term.error))}


@dataclass
class ComTask(Task):
    """Centre-of-mass position in the world [m]."""

    def _full_jacobian(self, state: RobotState) -> np.ndarray:
        return state.J_com

    def _full_drift(self, state: RobotState) -> np.ndarray:
        return state.com_drift

    def _value(self, state: RobotState) -> np.ndarray:
        return state.com


@dataclass
class FramePositionTask(Task):
    """World position of a frame origin [m]."""

    frame: str = ""

    def _full_jacobian(self, state: RobotState) -> np.ndarray:
        return state.jacobian(self.frame)[:3]

    def _full_drift(self, state: RobotState) -> np.ndarray:
        return state.drift(self.frame)[:3]

    def _value(self, state: RobotState) -> np.ndarray:
        return state.position(self.frame)


def _rotation_target(r0: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Rotation exp(offset) R0: offsets are world-frame rotation vectors."""
    return pin.exp3(offset) @ r0


@dataclass
class FrameOrientationTask(Task):
    """World orientation of a frame; error = log(R_d Rᵀ) in world axes [rad].

    The reference (``rx, ry, rz``) is a world rotation vector applied to the initial orientation
    (or, with ``absolute``, the rotation vector of the target orientation).
    """

    frame: str = ""
    full_axes: ClassVar[tuple[str, ...]] = ("rx", "ry", "rz")
    kind: ClassVar[str] = "orientation"
    _R0: np.ndarray | None = field(init=False, default=None, repr=False)

    def start(self, state: RobotState) -> None:
        self._R0 = state.rotation(self.frame).copy()
        self._x0 = np.zeros(3)

    def _full_jacobian(self, state: RobotState) -> np.ndarray:
        return state.jacobian(self.frame)[3:]

    def _full_drift(self, state: RobotState) -> np.ndarray:
        return state.drift(self.frame)[3:]

    def _value(self, state: RobotState) -> np.ndarray:
        return np.zeros(3)

    def _target(self, x_d: np.ndarray) -> np.ndarray:
        assert self._R0 is not None
        return pin.exp3(x_d) if self.absolute else _rotation_target(self._R0, x_d)

    def _error(self, state: RobotState, x_d: np.ndarray) -> np.ndarray:
        return pin.log3(self._target(x_d) @ state.rotation(self.frame).T)

    def error_norms(self, term: TaskTerm) -> dict[str, float]:
        return {"rot": float(np.linalg.norm(term.error))}


@dataclass
class FramePoseTask(Task):
    """Position and orientation of a frame, with axis selection among x y z rx ry rz."""

    frame: str = ""
    full_axes: ClassVar[tuple[str, ...]] = AXES6
    kind: ClassVar[str] = "pose"
    _R0: np.ndarray | None = field(init=False, default=None, repr=False)

    def start(self, state: RobotState) -> None:
        self._R0 = state.rotation(self.frame).copy()
        self._x0 = np.concatenate([state.position(self.frame), np.zeros(3)])

    def _full_jacobian(self, state: RobotState) -> np.ndarray:
        return state.jacobian(self.frame)

    def _full_drift(self, state: RobotState) -> np.ndarray:
        return state.drift(self.frame)

    def _value(self, state: RobotState) -> np.ndarray:
        return np.concatenate([state.position(self.frame), np.zeros(3)])

    def _error(self, state: RobotState, x_d: np.ndarray) -> np.ndarray:
        assert self._R0 is not None
        target = pin.exp3(x_d[3:]) if self.absolute else _rotation_target(self._R0, x_d[3:])
        rot_err = pin.log3(target @ state.rotation(self.frame).T)
        return np.concatenate([x_d[:3] - state.position(self.frame), rot_err])

    def error_norms(self, term: TaskTerm) -> dict[str, float]:
        lin = [i for i, a in enumerate(self.axes) if not a.startswith("r")]
        ang = [i for i, a in enumerate(self.axes) if a.startswith("r")]
        out = {}
        if lin:
            out["pos"] = float(np.linalg.norm(term.error[lin]))
        if ang:
            out["rot"] = float(np.linalg.norm(term.error[ang]))
        return out


@dataclass
class JointPostureTask(Task):
    """Positions of actuated joints [rad]; ``joints`` empty = all actuated joints."""

    joints: tuple[str, ...] = ()
    kind: ClassVar[str] = "joint"
    _idx: np.ndarray = field(init=False, repr=False)
    _J: np.ndarray | None = field(init=False, default=None, repr=False)

    def bind(self, joint_names: tuple[str, ...]) -> None:
        """Resolve joint names; must be called before :meth:`start` (axes become joint names)."""
        names = self.joints or joint_names
        self._idx = np.array([joint_names.index(j) for j in names], dtype=int)
        self.full_axes = tuple(joint_names)  # type: ignore[misc]
        self.axes = tuple(names)
        self._rows = self._idx.copy()
        if self.reference is None or getattr(self.reference, "dim", len(names)) != len(names):
            self.reference = Constant(np.zeros(len(names)))

    def _full_jacobian(self, state: RobotState) -> np.ndarray:
        if self._J is None:
            self._J = np.hstack([np.zeros((state.k, 6)), np.eye(state.k)])
        return self._J

    def _full_drift(self, state: RobotState) -> np.ndarray:
        return np.zeros(state.k)

    def _value(self, state: RobotState) -> np.ndarray:
        return state.q[7:]

    def error_norms(self, term: TaskTerm) -> dict[str, float]:
        return {"joint": float(np.linalg.norm(term.error))}


@dataclass
class JointDampingTask(JointPostureTask):
    """Joint damping: ẍ* = −k_v q̇ on the selected joints (no position term).

    The OSF-HQP paper's T4 writes it as a torque, Γ = −k q̇; at acceleration level it is the same
    request expressed as a joint deceleration. The reported error is ‖q̇‖ [rad/s].
    """

    kind: ClassVar[str] = "damping"

    def evaluate(self, state: RobotState, t: float) -> TaskTerm:
        J = self._full_jacobian(state)[self._rows]
        qd = state.v[6:][self._rows]
        acc_ref = -self.kv * qd
        zeros = np.zeros(len(self._rows))
        return TaskTerm(self, J, zeros, acc_ref, zeros, -qd)

    def start(self, state: RobotState) -> None:
        self._x0 = np.zeros(state.k)

    def error_norms(self, term: TaskTerm) -> dict[str, float]:
        return {"damping": float(np.linalg.norm(term.error_vel))}


#: the ``type`` names used in scenario files
TASK_TYPES: dict[str, type[Task]] = {
    "com": ComTask,
    "frame_position": FramePositionTask,
    "frame_orientation": FrameOrientationTask,
    "frame_pose": FramePoseTask,
    "joint_posture": JointPostureTask,
    "joint_damping": JointDampingTask,
}

#: unit of each error-norm part
ERROR_UNITS = {"pos": "m", "rot": "rad", "joint": "rad", "damping": "rad/s"}
