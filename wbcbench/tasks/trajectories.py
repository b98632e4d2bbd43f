"""Reference trajectories x_d(t), ẋ_d(t), ẍ_d(t) for tasks.

Every trajectory returns vectors of the task's dimension. By default they are *offsets* added to
the task's value at the start of the run (so "move the CoM +25 mm" needs no knowledge of where the
CoM starts); a task may declare its reference absolute instead.

The cubic pieces are evaluated from their polynomial coefficients directly (a handful of NumPy
operations per call) because a trajectory is sampled for every task at every control tick.
"""

from __future__ import annotations

import bisect
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

Sample = tuple[np.ndarray, np.ndarray, np.ndarray]


class Trajectory(ABC):
    """Base class: ``sample(t)`` returns (position, velocity, acceleration), each (dim,)."""

    dim: int

    @abstractmethod
    def sample(self, t: float) -> Sample:
        """(x, ẋ, ẍ) at time t [s]."""


@dataclass
class Constant(Trajectory):
    """A fixed value (zero offset by default)."""

    value: np.ndarray

    def __post_init__(self) -> None:
        self.value = np.asarray(self.value, dtype=float)
        self.dim = self.value.size
        self._zero = np.zeros(self.dim)

    def sample(self, t: float) -> Sample:
        return self.value, self._zero, self._zero


@dataclass
class Sinusoid(Trajectory):
    """x = a sin(2π f (t − t0) + φ) − a sin φ for t ≥ t0 (zero before), per axis.

    Subtracting ``a sin φ`` makes the position continuous at t0 whatever the phase.
    """

    amplitude: np.ndarray
    frequency: float
    t0: float = 0.0
    phase: float = 0.0

    def __post_init__(self) -> None:
        self.amplitude = np.asarray(self.amplitude, dtype=float)
        self.dim = self.amplitude.size
        self._zero = np.zeros(self.dim)

    def sample(self, t: float) -> Sample:
        if t < self.t0:
            return self._zero, self._zero, self._zero
        w = 2.0 * np.pi * self.frequency
        arg = w * (t - self.t0) + self.phase
        a = self.amplitude
        return (
            a * (np.sin(arg) - np.sin(self.phase)),
            a * (w * np.cos(arg)),
            a * (-w * w * np.sin(arg)),
        )


class PiecewiseCubic(Trajectory):
    """C² cubic spline through waypoints with zero velocity at both ends, held outside them."""

    def __init__(self, times: np.ndarray, values: np.ndarray) -> None:
        times = np.asarray(times, dtype=float)
        values = np.asarray(values, dtype=float)
        if values.ndim == 1:
            values = values[:, None]
        spline = CubicSpline(times, values, axis=0, bc_type="clamped")
        self.dim = values.shape[1]
        self._breaks = [float(x) for x in spline.x]
        self._coef = spline.c  # (4, segments, dim), highest power first
        self._first = values[0].copy()
        self._last = values[-1].copy()
        self._zero = np.zeros(self.dim)

    def sample(self, t: float) -> Sample:
        if t <= self._breaks[0]:
            return self._first, self._zero, self._zero
        if t >= self._breaks[-1]:
            return self._last, self._zero, self._zero
        i = bisect.bisect_right(self._breaks, t) - 1
        s = t - self._breaks[i]
        c3, c2, c1, c0 = self._coef[:, i, :]
        return (
            ((c3 * s + c2) * s + c1) * s + c0,
            (3.0 * c3 * s + 2.0 * c2) * s + c1,
            6.0 * c3 * s + 2.0 * c2,
        )


def spline_there_and_back(
    t0: float, t1: float, amplitude: np.ndarray, symmetric: bool = True
) -> PiecewiseCubic:
    """The papers' CoM / hand moves: 0 → +a → −a → 0 over [t0, t1] (``symmetric``), else 0 → a → 0.

    A C² cubic spline with zero velocity at t0 and t1: the "±25 mm during t = 10–12 s" of the
    TO-OSF paper's scenario #1 is ``spline_there_and_back(10, 12, [0.025, 0, 0])``.
    """
    a = np.asarray(amplitude, dtype=float)
    if symmetric:
        times = np.array([t0, t0 + 0.25 * (t1 - t0), t0 + 0.75 * (t1 - t0), t1])
        values = np.vstack([0 * a, a, -a, 0 * a])
    else:
        times = np.array([t0, 0.5 * (t0 + t1), t1])
        values = np.vstack([0 * a, a, 0 * a])
    return PiecewiseCubic(times, values)


class _Waypoints(Trajectory):
    """Values at increasing times, held before the first and after the last."""

    def __init__(self, times: np.ndarray, values: np.ndarray) -> None:
        self._times = [float(x) for x in np.asarray(times, dtype=float)]
        values = np.asarray(values, dtype=float)
        if values.ndim == 1:
            values = values[:, None]
        self._values = values
        self.dim = values.shape[1]
        self._zero = np.zeros(self.dim)

    def sample(self, t: float) -> Sample:
        if t <= self._times[0]:
            return self._values[0], self._zero, self._zero
        if t >= self._times[-1]:
            return self._values[-1], self._zero, self._zero
        i = bisect.bisect_right(self._times, t) - 1
        duration = self._times[i + 1] - self._times[i]
        return self._piece(i, (t - self._times[i]) / duration, duration)

    @abstractmethod
    def _piece(self, i: int, s: float, duration: float) -> Sample:
        """(x, ẋ, ẍ) at the fraction s ∈ [0, 1) of piece i lasting ``duration`` [s]."""


class MinimumJerk(_Waypoints):
    """Quintic minimum-jerk move between waypoints (rest at each waypoint), held outside them."""

    def _piece(self, i: int, s: float, duration: float) -> Sample:
        delta = self._values[i + 1] - self._values[i]
        p = s**3 * (10 - 15 * s + 6 * s * s)
        dp = 30 * s * s * (1 - s) ** 2 / duration
        ddp = 60 * s * (1 - s) * (1 - 2 * s) / duration**2
        return self._values[i] + p * delta, dp * delta, ddp * delta


class PiecewiseLinear(_Waypoints):
    """Linear interpolation between waypoints (for step-like references); zero acceleration."""

    def _piece(self, i: int, s: float, duration: float) -> Sample:
        delta = self._values[i + 1] - self._values[i]
        return self._values[i] + s * delta, delta / duration, self._zero
