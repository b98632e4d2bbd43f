"""Contact schedules: which contacts hold their frame at each instant, and how hard.

A contact is active over time intervals ``[start, end)`` [s]. While active its frame is held
(the controllers' stationary-contact rows and its wrench variables are in their QPs); while not,
the frame is free and a swing task may drive it.

* **Lift-off** is planned: over the contact's ``unload`` seconds before an interval ends, its
  normal-force bounds scale by ``s = (end − t) / unload`` (from 1 to 0): ``s f_min ≤ f_z ≤
  s min(f_max, F)`` with F the robot's weight, so the wrench reaches zero without a jump.
* **Touchdown** is scheduled at an interval's start (> 0) and established when the simulated foot
  carries load: a runner that reports the feet's normal forces (:meth:`ContactSchedule.observe`)
  activates the contact at the first tick in ``[start − tolerance, start + tolerance]`` at which
  it carries ``touchdown_load``; if none does, the run ends with a message that names the
  contact, the scheduled time and the tolerance. After touchdown both bounds ramp in over
  ``unload`` seconds, ``s f_min ≤ f_z ≤ (r + (1 − r) s) min(f_max, F)`` with ``s = (t −
  touchdown) / unload`` and ``r = touchdown_load / F`` (the share the foot carries when its
  touchdown is confirmed): the new contact need not push at once, and the wrench does not jump
  onto it, as it does not jump off a foot that lifts off.
  Without observations (a replay, a test of one tick) a touchdown happens at its scheduled time.
* **Landing**: where an interval has a target (a footstep), a touchdown farther than
  ``landing_tolerance`` from it ends the run with a message that names the contact and the
  target.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from wbcbench.tasks.walking import WalkPlan

INF = math.inf


@dataclass(frozen=True)
class ContactPhase:
    """The contact set of one instant.

    Attributes:
        active: indices (into the context's contacts) of the active contacts, ascending.
        lower: per active contact, the factor on its minimum normal force (1 when settled).
        upper: per active contact, the factor on its maximum normal force (1: its own bound).
    """

    active: tuple[int, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]


@dataclass
class ScheduledContact:
    """One contact's intervals ``[(start, end), …]`` [s], optional touchdown targets (3,) [m]
    (one per interval; None: no target) and the ramp time ``unload`` [s] before lift-off (and
    after touchdown, for f_min)."""

    frame: str
    intervals: list[tuple[float, float]]
    targets: list[np.ndarray | None] = field(default_factory=list)
    unload: float = 0.1

    def __post_init__(self) -> None:
        if not self.targets:
            self.targets = [None] * len(self.intervals)


class ContactSchedule:
    """The contact set over a run; shared by the runner (which reports loads) and a controller
    (which reads :meth:`phase` at each tick).

    Args:
        contacts: one entry per contact of the controller's context, in its order; a contact
            held for the whole run has the single interval ``(0, inf)``.
        ramp_force: the normal force [N] the upper bound ramps down from when a contact has no
            f_max of its own (the robot's weight).
        touchdown_tolerance: how far from its scheduled time a touchdown may happen [s].
        touchdown_load: the normal force [N] from which a foot counts as landed.
        landing_tolerance: how far from its target a foot may land [m].
        plan: the walk the schedule comes from, if any (recorded with the run).
    """

    def __init__(
        self,
        contacts: Sequence[ScheduledContact],
        ramp_force: float,
        touchdown_tolerance: float = 0.05,
        touchdown_load: float = 20.0,
        landing_tolerance: float = 0.02,
        plan: WalkPlan | None = None,
    ) -> None:
        self.plan = plan
        self.contacts = list(contacts)
        self.ramp_force = ramp_force
        self.touchdown_tolerance = touchdown_tolerance
        self.touchdown_load = touchdown_load
        self.landing_tolerance = landing_tolerance
        #: (contact, interval) → the time its touchdown was confirmed
        self.confirmed: dict[tuple[int, int], float] = {}
        #: set by the first :meth:`observe`: touchdowns then wait for load
        self.observing = False
        #: (frame, time [s], distance to the target [m]) of each confirmed touchdown with one
        #: confirmed landings: (frame, time [s], the frame's offset from its footstep (3,) [m])
        self.landings: list[tuple[str, float, np.ndarray]] = []

    @property
    def frames(self) -> list[str]:
        return [c.frame for c in self.contacts]

    def touchdowns(self) -> list[tuple[float, str]]:
        """Every scheduled touchdown (time, frame), in time order."""
        out = [(a, c.frame) for c in self.contacts for a, _ in c.intervals if a > 0]
        return sorted(out)

    def contact_sets(self) -> list[tuple[int, ...]]:
        """Every non-empty set of contacts active together over the schedule as planned (each
        touchdown at its scheduled time), in the order they first occur."""
        return [active for _, active in self.set_instants()]

    def set_instants(self) -> list[tuple[float, tuple[int, ...]]]:
        """For each set of :meth:`contact_sets`, an instant [s] at which the schedule as planned
        holds it: the middle of the first stretch between two interval ends where it is active
        (after the last end: a second past it)."""
        ends = sorted(
            {0.0} | {x for c in self.contacts for span in c.intervals for x in span if x < INF}
        )
        instants = [(a + b) / 2 for a, b in pairwise(ends)] + [ends[-1] + 1.0]
        out: list[tuple[float, tuple[int, ...]]] = []
        for t in instants:
            active = tuple(
                i for i, c in enumerate(self.contacts) if any(a <= t < b for a, b in c.intervals)
            )
            if active and all(active != seen for _, seen in out):
                out.append((t, active))
        return out

    def _start(self, i: int, k: int) -> float | None:
        """When interval k of contact i became (or becomes) active; None: not yet."""
        start = self.contacts[i].intervals[k][0]
        if start <= 0 or not self.observing:
            return start
        return self.confirmed.get((i, k))

    def phase(self, t: float) -> ContactPhase:
        """The active contacts at ``t`` [s] and their normal-force factors."""
        active: list[int] = []
        lower: list[float] = []
        upper: list[float] = []
        # the share of the ramp force a landing foot carries when its touchdown is confirmed:
        # its upper bound ramps in from there
        rise = min(1.0, self.touchdown_load / self.ramp_force) if self.ramp_force > 0 else 1.0
        for i, c in enumerate(self.contacts):
            ramp = c.unload
            for k, (_, end) in enumerate(c.intervals):
                start = self._start(i, k)
                if start is None or not start <= t < end:
                    continue
                down = min(1.0, (end - t) / ramp) if end < INF else 1.0
                up = min(1.0, (t - start) / ramp) if start > 0 else 1.0
                active.append(i)
                lower.append(max(0.0, min(down, up)))
                upper.append(max(0.0, min(down, rise + (1.0 - rise) * up)))
                break
        return ContactPhase(tuple(active), tuple(lower), tuple(upper))

    def observe(self, t: float, normal: np.ndarray, positions: Sequence[np.ndarray]) -> str:
        """Confirm touchdowns from the simulated feet at ``t`` [s]: ``normal`` (c,) [N] the
        normal force each contact's foot carries, ``positions`` its frame's position (3,) [m].
        Returns why the run must end ("" while the schedule holds)."""
        self.observing = True
        tol = self.touchdown_tolerance
        for i, c in enumerate(self.contacts):
            for k, (start, _) in enumerate(c.intervals):
                if start <= 0 or (i, k) in self.confirmed or t < start - tol:
                    continue
                if normal[i] >= self.touchdown_load:
                    self.confirmed[(i, k)] = t
                    target = c.targets[k]
                    if target is not None:
                        offset = np.asarray(positions[i], dtype=float) - target
                        miss = float(np.linalg.norm(offset))
                        self.landings.append((c.frame, t, offset))
                        if miss > self.landing_tolerance:
                            where = ", ".join(f"{v:.3f}" for v in target)
                            return (
                                f"contact {c.frame!r} landed {1e3 * miss:.1f} mm from its target "
                                f"({where}) m at t = {t:.3f} s, beyond sim.landing_tolerance = "
                                f"{1e3 * self.landing_tolerance:g} mm"
                            )
                elif t > start + tol:
                    return (
                        f"the touchdown of contact {c.frame!r} scheduled at t = {start:.3f} s "
                        f"did not happen: its foot carried less than {self.touchdown_load:g} N "
                        f"until t = {t:.3f} s (sim.touchdown_tolerance = {tol:g} s)"
                    )
        return ""

    def scale_bounds(
        self,
        phase: ContactPhase,
        rows: Sequence[int | Sequence[int]],
        fmax: Sequence[float],
        lw: np.ndarray,
        uw: np.ndarray,
        out_l: np.ndarray,
        out_u: np.ndarray,
    ) -> None:
        """Write the stacked wrench bounds of ``phase``'s contacts into ``out_l``/``out_u``:
        ``lw``/``uw`` with each contact's normal-force row (``rows``, into the stack; a point
        set's one row per point, which share the ramp's force) scaled."""
        out_l[:] = lw
        out_u[:] = uw
        for j, entry in enumerate(rows):
            group = [int(entry)] if isinstance(entry, (int, np.integer)) else list(entry)
            for row in group:
                out_l[row] = lw[row] * phase.lower[j]
                if phase.upper[j] < 1.0:
                    out_u[row] = phase.upper[j] * min(fmax[j], self.ramp_force / len(group))
