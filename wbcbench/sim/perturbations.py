"""What a closed-loop run does to the ideal loop when a scenario's ``perturbations`` say so.

- pushes: an external wrench on a body over an interval, written to MuJoCo's ``xfrc_applied``
  before every physics step (the controller is never told);
- sensing: seeded Gaussian noise on the joint positions and rates the controller measures, and
  a delay of k control ticks between a measurement and the torque computed from it;
- actuation: the commanded torque rounded to a step (the first-order lag is the motors' own
  dynamics in the simulated model, :func:`wbcbench.robots.loader.simulation_model`);
- model error: the controller's model (:meth:`wbcbench.runs.Run.controller_robot`).

The noise stream is drawn from ``numpy.random.default_rng(seed)`` in a fixed order (q then v,
one draw per control tick), so two runs with the same seed measure the same states.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import mujoco
import numpy as np

from wbcbench.robots.loader import frame_body
from wbcbench.scenarios.schema import PerturbationsSpec, PushSpec


def push_scale(push: PushSpec, s: float) -> float:
    """The factor on the push's wrench at ``s`` [s] after its start (0 outside the push)."""
    if not 0.0 <= s < push.duration:
        return 0.0
    if push.profile is not None:
        times, values = zip(*push.profile, strict=True)
        return float(np.interp(s, times, values, left=0.0, right=0.0))
    if push.shape == "half_sine":
        return float(np.sin(np.pi * s / push.duration))
    return 1.0


def push_impulse(push: PushSpec) -> np.ndarray:
    """The push's linear impulse ∫ F dt (3,) [N·s], in the axes of its ``frame``."""
    if push.profile is not None:
        times, values = (np.asarray(a, dtype=float) for a in zip(*push.profile, strict=True))
        area = float(np.sum(np.diff(times) * (values[1:] + values[:-1]) / 2))
    else:
        area = push.duration * (2 / np.pi if push.shape == "half_sine" else 1.0)
    return np.asarray(push.force) * area


class Pushes:
    """The scenario's pushes on the simulated model."""

    def __init__(self, model: mujoco.MjModel, pushes: Sequence[PushSpec]) -> None:
        self.pushes = list(pushes)
        self.bodies = [frame_body(model, p.body) for p in self.pushes]

    def apply(self, data: mujoco.MjData, t: float) -> None:
        """Write the wrenches at time ``t`` [s] to ``data.xfrc_applied`` (world axes, at each
        body's centre of mass), overwriting the previous step's."""
        if not self.pushes:
            return
        for body in self.bodies:
            data.xfrc_applied[body] = 0.0
        for push, body in zip(self.pushes, self.bodies, strict=True):
            scale = push_scale(push, t - push.start)
            if scale == 0.0:
                continue
            force = scale * np.asarray(push.force)
            torque = scale * np.asarray(push.torque)
            if push.frame == "body":
                R = data.xmat[body].reshape(3, 3)
                force, torque = R @ force, R @ torque
            data.xfrc_applied[body, :3] += force
            data.xfrc_applied[body, 3:] += torque


class Sensing:
    """Noise on the measured joint state and the delay of the torque after its measurement."""

    def __init__(self, spec: PerturbationsSpec, k: int) -> None:
        self.q_noise = spec.sensing.q_noise
        self.v_noise = spec.sensing.v_noise
        self.delay = spec.sensing.delay
        self.quantum = spec.actuation.quantum
        self.rng = np.random.default_rng(spec.seed)
        self.k = k
        self._pending: deque[np.ndarray] = deque()

    def measure(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What the controller reads of the simulated (q (7+k,), v (6+k,)): the joints' part
        with noise, the base's exact."""
        if self.q_noise > 0 or self.v_noise > 0:
            q, v = q.copy(), v.copy()
            q[7:] += self.q_noise * self.rng.standard_normal(self.k)
            v[6:] += self.v_noise * self.rng.standard_normal(self.k)
        return q, v

    def command(self, tau: np.ndarray) -> np.ndarray:
        """The torque (k,) [N·m] to send this tick for ``tau``, computed this tick: the one
        computed ``delay`` ticks ago (the first one until that many were computed), rounded to
        the quantisation step."""
        if self.delay:
            self._pending.append(tau)
            tau = self._pending.popleft() if len(self._pending) > self.delay else self._pending[0]
        if self.quantum > 0:
            tau = self.quantum * np.round(tau / self.quantum)
        return tau
