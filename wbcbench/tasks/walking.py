"""A walking pattern: footsteps, contact schedule, swing-foot paths and a LIPM/DCM CoM reference.

Everything here is plain data computed once before a run, so the runner, the report and a test
can read the same plan back (:meth:`WalkPlan.to_dict`).

The CoM reference follows the linear inverted pendulum (LIPM) at a constant height z_c,
``ẍ = ω² (x − p)`` with ``ω = √(g / z_c)``, written with the divergent component of motion
(DCM) ``ξ = x + ẋ / ω`` as ``ξ̇ = ω (ξ − p)`` and ``ẋ = ω (ξ − x)`` (Englsberger, Ott and
Albu-Schäffer, "Three-Dimensional Bipedal Walking Control Based on Divergent Component of
Motion", IEEE T-RO 31(2), 2015; in the plane, the virtual repellent point is the ZMP p).

The ZMP (the centre of pressure of the whole robot) is planned piecewise linear in time: held at
the stance foot's centre in single support, moved in a straight line to the next stance foot in
double support. With such a ZMP the DCM that stays bounded has a closed form on each piece,
found backwards from the end where ξ rests on the last ZMP point:

    ξ(t) = p(t) + b/ω + e^{ω (t − t₁)} (ξ(t₁) − p(t₁) − b/ω)      on [t₀, t₁], slope b,

and the CoM, started at rest at the robot's CoM, has one too (forwards):

    x(t₀ + u) = α − b/ω + b u + (γ/2) e^{ω u} + D e^{−ω u},   ξ(t₀ + u) = α + b u + γ e^{ω u}.

The ZMP of the first hold is chosen so that ξ(0) equals the starting CoM: the CoM reference then
starts with zero velocity, and the plan satisfies the LIPM exactly at every instant (the tests
check ``ẍ = ω² (x − p)`` and ``ξ = x + ẋ/ω`` at random times).
"""

from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wbcbench.tasks.trajectories import Sample, Trajectory

GRAVITY = 9.81


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Footstep:
    """Where a foot stands: ``position`` (x, y, z) of its contact frame [m] and ``yaw`` [rad].

    ``lift_off`` and ``touch_down`` [s] bound the swing that brings the foot here (``nan`` for the
    two footsteps the robot starts on).
    """

    foot: str
    position: tuple[float, float, float]
    yaw: float
    lift_off: float = math.nan
    touch_down: float = math.nan

    @property
    def xy(self) -> np.ndarray:
        return np.array(self.position[:2])

    @property
    def is_initial(self) -> bool:
        return math.isnan(self.touch_down)


@dataclass(frozen=True)
class WalkTiming:
    """The durations of a walk [s].

    Attributes:
        single: single support (one swing).
        double: double support between two swings (the ZMP moves to the next stance foot).
        start: double support before the first step (the CoM starts at rest).
        end: double support after the last step (the CoM comes to rest over the feet).
        unload: the time before lift-off over which the leaving foot's normal-force bound
            ramps to zero; at most ``double``.
        swing_height: the swing foot's clearance above the line between lift-off and touchdown
            [m].
        touchdown_velocity: the swing foot's downward speed as it reaches its footstep [m/s];
            past its touchdown time it goes on down at that speed (for at most ``double``) until
            the contact is confirmed. 0: it lands at rest.
    """

    single: float = 0.8
    double: float = 0.2
    start: float = 1.0
    end: float = 1.5
    unload: float = 0.1
    swing_height: float = 0.05
    touchdown_velocity: float = 0.0

    def __post_init__(self) -> None:
        for name in ("single", "double", "start", "end"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0 s, got {getattr(self, name)}")
        if not 0 < self.unload <= self.double:
            raise ValueError(
                f"unload must be > 0 and at most double ({self.double} s), got {self.unload}"
            )
        if self.swing_height < 0:
            raise ValueError(f"swing_height must be ≥ 0 m, got {self.swing_height}")
        if self.touchdown_velocity < 0:
            raise ValueError(
                f"touchdown_velocity must be ≥ 0 m/s (a downward speed), got "
                f"{self.touchdown_velocity}"
            )


def footsteps_from_walk(
    start: dict[str, Footstep],
    first: str,
    steps: int,
    length: float,
    width: float | None = None,
    turn: float = 0.0,
) -> list[tuple[str, tuple[float, float, float], float]]:
    """The landing poses of a straight or turning walk, as (foot, position, yaw).

    The path starts at the midpoint of the two starting feet, heading along their mean yaw. Each
    step but the last advances the path by ``length`` [m] and turns it by ``turn`` [rad] (per
    step); the swing foot lands beside the path, at ``width`` / 2 to its side (the starting feet's
    distance by default). The last step brings the trailing foot beside the other, so the walk
    ends standing with both feet level. Feet alternate, starting with ``first``.
    """
    if steps < 2:
        raise ValueError(
            f"a walk needs at least 2 steps (the last one closes the stance), got {steps}"
        )
    if len(start) != 2 or first not in start:
        raise ValueError(f"first must be one of the two feet {sorted(start)}, got {first!r}")
    left, right = start[first], next(f for name, f in start.items() if name != first)
    centre = 0.5 * (left.xy + right.xy)
    heading = math.atan2(
        math.sin(left.yaw) + math.sin(right.yaw), math.cos(left.yaw) + math.cos(right.yaw)
    )
    # which side of the path the first foot is on: +1 left of the heading, −1 right
    lateral = _rot(heading).T @ (left.xy - right.xy)
    side_first = 1.0 if lateral[1] >= 0 else -1.0
    half = 0.5 * (float(np.hypot(*lateral)) if width is None else width)
    z = {left.foot: left.position[2], right.foot: right.position[2]}

    out: list[tuple[str, tuple[float, float, float], float]] = []
    names = (left.foot, right.foot)
    for k in range(steps):
        foot = names[k % 2]
        side = side_first if k % 2 == 0 else -side_first
        if k < steps - 1:
            centre = centre + _rot(heading) @ np.array([length, 0.0])
            heading = heading + turn
        xy = centre + _rot(heading) @ np.array([0.0, side * half])
        out.append((foot, (float(xy[0]), float(xy[1]), float(z[foot])), _wrap(heading)))
    return out


@dataclass
class _Piece:
    """One piece of the ZMP / DCM / CoM plan along one horizontal axis pair (x, y)."""

    t0: float
    t1: float
    p0: np.ndarray  # ZMP at t0
    slope: np.ndarray  # ZMP velocity on the piece
    gamma: np.ndarray  # ξ(t0 + u) = α + b u + γ e^{ωu}
    d: np.ndarray  # CoM homogeneous term: x = α − b/ω + b u + (γ/2) e^{ωu} + D e^{−ωu}


@dataclass
class WalkPlan:
    """A planned walk: footsteps, contact schedule, ZMP, DCM, CoM and swing-foot references.

    Times are absolute run times [s]; positions are in the world frame [m].
    """

    footsteps: list[Footstep]
    timing: WalkTiming
    com_height: float
    zmp_times: np.ndarray
    zmp_points: np.ndarray  # (k, 2)
    com_start: np.ndarray  # (3,)
    omega: float = field(init=False)
    _pieces: list[_Piece] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.omega = math.sqrt(GRAVITY / self.com_height)
        self._pieces = self._solve()
        self._starts = [p.t0 for p in self._pieces]

    # -- the LIPM solution

    def _solve(self) -> list[_Piece]:
        w = self.omega
        t, p = self.zmp_times, self.zmp_points
        n = len(t) - 1
        slopes = [(p[i + 1] - p[i]) / (t[i + 1] - t[i]) for i in range(n)]
        # the bounded DCM, backwards from rest on the last ZMP point
        xi = [np.zeros(2) for _ in range(n + 1)]
        xi[n] = p[n].copy()
        for i in range(n - 1, -1, -1):
            b = slopes[i]
            xi[i] = p[i] + b / w + math.exp(-w * (t[i + 1] - t[i])) * (xi[i + 1] - p[i + 1] - b / w)
        pieces: list[_Piece] = []
        x = self.com_start[:2].copy()
        for i in range(n):
            b, h = slopes[i], t[i + 1] - t[i]
            alpha = p[i] + b / w
            gamma = (xi[i + 1] - p[i + 1] - b / w) * math.exp(-w * h)
            d = x - (alpha - b / w + 0.5 * gamma)
            pieces.append(_Piece(float(t[i]), float(t[i + 1]), p[i].copy(), b, gamma, d))
            e_pos, e_neg = math.exp(w * h), math.exp(-w * h)
            x = alpha - b / w + b * h + 0.5 * gamma * e_pos + d * e_neg
        # after the last point the ZMP rests; ξ = p there and the CoM converges to it
        last = np.zeros(2)
        pieces.append(_Piece(float(t[n]), math.inf, p[n].copy(), last, last, x - p[n]))
        return pieces

    def _piece(self, t: float) -> tuple[_Piece, float]:
        i = max(0, bisect.bisect_right(self._starts, t) - 1)
        piece = self._pieces[i]
        return piece, max(0.0, t - piece.t0)

    def zmp(self, t: float) -> np.ndarray:
        """The planned ZMP (x, y) at time t."""
        piece, u = self._piece(t)
        return piece.p0 + piece.slope * u

    def dcm(self, t: float) -> np.ndarray:
        """The planned DCM (x, y) at time t."""
        piece, u = self._piece(t)
        b, w = piece.slope, self.omega
        return piece.p0 + b / w + b * u + piece.gamma * math.exp(w * u)

    def com(self, t: float) -> Sample:
        """The planned CoM (x, y, z) and its first two derivatives at time t (z constant)."""
        piece, u = self._piece(t)
        b, w = piece.slope, self.omega
        e_pos, e_neg = math.exp(w * u), math.exp(-w * u)
        alpha = piece.p0 + b / w
        xy = alpha - b / w + b * u + 0.5 * piece.gamma * e_pos + piece.d * e_neg
        dxy = b + 0.5 * w * piece.gamma * e_pos - w * piece.d * e_neg
        ddxy = 0.5 * w * w * piece.gamma * e_pos + w * w * piece.d * e_neg
        z = self.com_start[2]
        return np.array([*xy, z]), np.array([*dxy, 0.0]), np.array([*ddxy, 0.0])

    # -- schedule and swings

    @property
    def feet(self) -> list[str]:
        return sorted({f.foot for f in self.footsteps if f.is_initial})

    @property
    def duration(self) -> float:
        """When the walk has come to rest: the last ZMP point plus the final hold."""
        return float(self.zmp_times[-1]) + self.timing.end

    @property
    def swings(self) -> list[Footstep]:
        """The footsteps reached by a swing, in time order."""
        return [f for f in self.footsteps if not f.is_initial]

    def schedule(self) -> dict[str, list[tuple[float, float]]]:
        """Each foot's contact intervals [start, end) over [0, duration]."""
        out: dict[str, list[tuple[float, float]]] = {}
        for foot in self.feet:
            begin, intervals = 0.0, []
            for s in self.swings:
                if s.foot == foot:
                    intervals.append((begin, s.lift_off))
                    begin = s.touch_down
            intervals.append((begin, self.duration))
            out[foot] = intervals
        return out

    def active(self, foot: str, t: float) -> bool:
        return any(a <= t < b for a, b in self.schedule()[foot]) or t >= self.duration

    def unload_factor(self, foot: str, t: float) -> float:
        """A contact's share of its normal-force bounds at t: 1, ramping to 0 by lift-off."""
        for s in self.swings:
            if s.foot == foot and s.lift_off - self.timing.unload <= t < s.lift_off:
                return (s.lift_off - t) / self.timing.unload
        return 1.0 if self.active(foot, t) else 0.0

    def swing_trajectory(self, step: Footstep) -> SwingTrajectory:
        """The path of the swing that lands on ``step``."""
        before = [f for f in self.footsteps if f.foot == step.foot]
        start = before[before.index(step) - 1]
        t = self.timing
        return SwingTrajectory(start, step, t.swing_height, t.touchdown_velocity, t.double)

    def foot_trajectory(self, foot: str) -> FootTrajectory:
        """The whole walk's pose reference of one foot: held between swings, swung between."""
        steps = [f for f in self.footsteps if f.foot == foot]
        return FootTrajectory([self.swing_trajectory(s) for s in steps[1:]], steps[0])

    def heading(self) -> HeadingTrajectory:
        """The yaw the pelvis and torso follow: the mean of the feet's, turned smoothly."""
        current = {f.foot: f.yaw for f in self.footsteps if f.is_initial}
        times, values = [0.0], [_mean_yaw(list(current.values()))]
        for s in self.swings:
            current[s.foot] = s.yaw
            times.append(s.touch_down + self.timing.double)
            values.append(_mean_yaw(list(current.values())))
        return HeadingTrajectory(np.array(times), np.unwrap(np.array(values)), self.timing.single)

    # -- plain data

    def to_dict(self) -> dict[str, Any]:
        """The plan as plain data (lists and floats): footsteps, schedule, ZMP points, timing."""
        return {
            "footsteps": [
                {
                    "foot": f.foot,
                    "position": list(f.position),
                    "yaw": f.yaw,
                    "lift_off": None if f.is_initial else f.lift_off,
                    "touch_down": None if f.is_initial else f.touch_down,
                }
                for f in self.footsteps
            ],
            "schedule": {k: [list(i) for i in v] for k, v in self.schedule().items()},
            "zmp": {"times": self.zmp_times.tolist(), "points": self.zmp_points.tolist()},
            "com_start": self.com_start.tolist(),
            "com_height": self.com_height,
            "timing": {
                k: getattr(self.timing, k)
                for k in (
                    "single",
                    "double",
                    "start",
                    "end",
                    "unload",
                    "swing_height",
                    "touchdown_velocity",
                )
            },
            "duration": self.duration,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> WalkPlan:
        """The plan :meth:`to_dict` wrote."""
        nan = math.nan
        steps = [
            Footstep(
                f["foot"],
                tuple(f["position"]),
                f["yaw"],
                nan if f["lift_off"] is None else f["lift_off"],
                nan if f["touch_down"] is None else f["touch_down"],
            )
            for f in data["footsteps"]
        ]
        return cls(
            steps,
            WalkTiming(**data["timing"]),
            data["com_height"],
            np.array(data["zmp"]["times"]),
            np.array(data["zmp"]["points"]),
            np.array(data["com_start"]),
        )


def _mean_yaw(yaws: list[float]) -> float:
    return math.atan2(sum(math.sin(y) for y in yaws), sum(math.cos(y) for y in yaws))


def plan_walk(
    start: dict[str, Footstep],
    landings: list[tuple[str, tuple[float, float, float], float]],
    com_start: np.ndarray,
    timing: WalkTiming | None = None,
) -> WalkPlan:
    """Time a footstep sequence and plan its ZMP, DCM and CoM.

    Args:
        start: the two feet the robot stands on, by contact name.
        landings: (foot, position, yaw) of each step in order; feet must alternate.
        com_start: the CoM at t = 0, at rest; its height is the LIPM's.
        timing: durations; :class:`WalkTiming`'s defaults when omitted.

    The timeline: ``timing.start`` of double support, then per step ``timing.double`` (the ZMP
    moves onto the stance foot) and ``timing.single`` (the other foot swings), then a last
    ``timing.double`` onto the midpoint of the final stance and ``timing.end`` at rest there.
    """
    timing = timing or WalkTiming()
    if not landings:
        raise ValueError("a walk needs at least one step")
    for (a, _, _), (b, _, _) in itertools.pairwise(landings):
        if a == b:
            raise ValueError(f"feet must alternate, but {a!r} steps twice in a row")
    if landings[0][0] not in start:
        raise ValueError(f"step 1's foot {landings[0][0]!r} is not one of {sorted(start)}")
    com_start = np.asarray(com_start, dtype=float)
    where = dict(start)
    footsteps = list(start.values())
    knots_t: list[float] = [timing.start]
    knots_p: list[np.ndarray] = []
    t = timing.start
    for foot, position, yaw in landings:
        stance = next(f for name, f in where.items() if name != foot)
        t += timing.double
        knots_t.append(t)
        knots_p.append(stance.xy)
        lift_off, t = t, t + timing.single
        knots_t.append(t)
        knots_p.append(stance.xy)
        xyz = (float(position[0]), float(position[1]), float(position[2]))
        step = Footstep(foot, xyz, float(yaw), lift_off, t)
        footsteps.append(step)
        where[foot] = step
    t += timing.double
    knots_t.append(t)
    last = where[landings[-1][0]]
    other = next(f for name, f in where.items() if name != last.foot)
    knots_p.append(0.5 * (last.xy + other.xy))
    times = np.array([0.0, *knots_t])

    def plan(p0: np.ndarray) -> WalkPlan:
        points = np.vstack([p0, p0, *knots_p])
        return WalkPlan(footsteps, timing, float(com_start[2]), times, points, com_start)

    # The first hold's ZMP p₀ is chosen so that ξ(0) is the starting CoM: the CoM then starts at
    # rest. ξ(0) is affine in p₀ with the same scalar factor on both axes, ξ(0) = A + B p₀.
    base = plan(np.zeros(2)).dcm(0.0)
    gain = plan(np.ones(2)).dcm(0.0)[0] - base[0]
    return plan((com_start[:2] - base) / gain)


class SwingTrajectory(Trajectory):
    """A swing foot's position (x, y, z) and yaw between lift-off and touchdown.

    Horizontally and in yaw a minimum-jerk move; vertically the same move plus a bump
    ``h · 64 s³ (1 − s)³`` that peaks at h halfway, and, with a touchdown velocity v, the quintic
    ``−v T (7 s⁴ − 3 s⁵ − 4 s³)`` (T the swing's duration) that is zero at both ends with zero
    acceleration there and gives the landing its downward speed v. It leaves at rest; it lands
    with zero horizontal velocity, zero acceleration and vertical velocity −v. After the
    touchdown time the foot goes on down at v for at most ``search`` seconds (a touchdown
    search: the contact takes over once the foot carries load), then is held. ``sample``
    returns (x, y, z, yaw) and its derivatives.
    """

    dim = 4

    def __init__(
        self,
        start: Footstep,
        end: Footstep,
        height: float,
        touchdown_velocity: float = 0.0,
        search: float = 0.0,
    ) -> None:
        self.start, self.end, self.height = start, end, height
        self.touchdown_velocity, self.search = touchdown_velocity, search
        self._a = np.array([*start.position, start.yaw])
        delta_yaw = _wrap(end.yaw - start.yaw)
        self._delta = np.array([*(np.array(end.position) - start.position), delta_yaw])
        self._t0, self._t1 = end.lift_off, end.touch_down

    def sample(self, t: float) -> Sample:
        duration = self._t1 - self._t0
        v = self.touchdown_velocity
        if t > self._t1:
            x = np.array([*self.end.position, self.end.yaw])
            dx, ddx = np.zeros(4), np.zeros(4)
            if v > 0:
                late = min(t - self._t1, self.search)
                x[2] -= v * late
                dx[2] = -v if t - self._t1 < self.search else 0.0
            return x, dx, ddx
        s = min(max((t - self._t0) / duration, 0.0), 1.0)
        p = s**3 * (10 - 15 * s + 6 * s * s)
        dp = 30 * s * s * (1 - s) ** 2 / duration
        ddp = 60 * s * (1 - s) * (1 - 2 * s) / duration**2
        x, dx, ddx = self._a + p * self._delta, dp * self._delta, ddp * self._delta
        bump = 64.0 * s**3 * (1 - s) ** 3
        dbump = 192.0 * s * s * (1 - s) ** 2 * (1 - 2 * s) / duration
        ddbump = 384.0 * s * (1 - s) * (1 - 5 * s + 5 * s * s) / duration**2
        # the end-velocity term of the quintic Hermite basis: zero value at both ends, zero
        # slope at the start and unit slope (in s) at the end, zero curvature at both
        land = s**3 * (-4 + 7 * s - 3 * s * s)
        dland = s * s * (-12 + 28 * s - 15 * s * s) / duration
        ddland = s * (-24 + 84 * s - 60 * s * s) / duration**2
        h, w = self.height, -v * duration
        x[2] += h * bump + w * land
        dx[2] += h * dbump + w * dland
        ddx[2] += h * ddbump + w * ddland
        return x, dx, ddx


class FootTrajectory(Trajectory):
    """One foot's (x, y, z, yaw) over the walk: each swing in its interval, held between."""

    dim = 4

    def __init__(self, swings: list[SwingTrajectory], initial: Footstep) -> None:
        self._swings = swings
        self._ends = [s.end.touch_down for s in swings]
        self._hold = np.array([*initial.position, initial.yaw])
        self._zero = np.zeros(4)

    def sample(self, t: float) -> Sample:
        i = bisect.bisect_left(self._ends, t)
        if i > 0 and t - self._ends[i - 1] < self._swings[i - 1].search:
            return self._swings[i - 1].sample(t)  # its touchdown search
        if i == len(self._swings):
            if self._swings:
                return self._swings[-1].sample(t)  # landed (or searching), then held
            return self._hold, self._zero, self._zero
        return self._swings[i].sample(t)


class HeadingTrajectory(Trajectory):
    """Yaw [rad]: a minimum-jerk turn of ``turn_time`` ending at each of ``times``."""

    dim = 1

    def __init__(self, times: np.ndarray, values: np.ndarray, turn_time: float) -> None:
        self._times, self._values, self._turn = times, values, turn_time
        self._zero = np.zeros(1)

    def sample(self, t: float) -> Sample:
        i = bisect.bisect_right(self._times.tolist(), t) - 1
        value = float(self._values[i])
        if i + 1 < len(self._times):
            t1 = float(self._times[i + 1])
            t0 = t1 - min(self._turn, t1 - float(self._times[i]))
            if t >= t0:
                duration = t1 - t0
                s = (t - t0) / duration
                delta = float(self._values[i + 1]) - value
                p = s**3 * (10 - 15 * s + 6 * s * s)
                dp = 30 * s * s * (1 - s) ** 2 / duration
                ddp = 60 * s * (1 - s) * (1 - 2 * s) / duration**2
                return (
                    np.array([value + p * delta]),
                    np.array([dp * delta]),
                    np.array([ddp * delta]),
                )
        return np.array([value]), self._zero, self._zero
