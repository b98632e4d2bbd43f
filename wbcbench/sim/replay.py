"""Open-loop replay: time controllers on exactly the same recorded states.

A closed-loop run is recorded once (time, q, v at every control tick); every controller × solver
combination then steps through those states with its own internal state (hot solvers, warm
starts) but without feeding its torques back, so all combinations solve the same problems.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from os import PathLike
from typing import Any

import numpy as np

from wbcbench.controllers.base import ControlOutput
from wbcbench.dynamics.state import RobotState
from wbcbench.runs import Run
from wbcbench.sim.closed_loop import run_closed_loop


@dataclass
class Recording:
    """States of a closed-loop run: times (T,), q (T, nq), v (T, nv)."""

    scenario: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray

    def __len__(self) -> int:
        return len(self.t)

    def window(self, start: float, ticks: int) -> Recording:
        """The ``ticks`` states from time ``start`` [s] on (fewer if the recording ends)."""
        i0 = int(np.searchsorted(self.t, start - 1e-9))
        sl = slice(i0, i0 + ticks)
        return Recording(self.scenario, self.t[sl], self.q[sl], self.v[sl])

    def save(self, path: str | PathLike[str]) -> None:
        """Write the states to an ``.npz`` file."""
        np.savez(path, scenario=self.scenario, t=self.t, q=self.q, v=self.v)

    @classmethod
    def load(cls, path: str | PathLike[str]) -> Recording:
        """Read states written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as data:
            return cls(str(data["scenario"]), data["t"], data["q"], data["v"])


def record_states(run: Run) -> Recording:
    """Run ``run`` in closed loop once and keep the state of every control tick."""
    ts: list[float] = []
    qs: list[np.ndarray] = []
    vs: list[np.ndarray] = []
    dt = run.scenario.spec.dt

    def keep(state: RobotState, out: ControlOutput) -> None:
        ts.append(len(ts) * dt)
        qs.append(state.q.copy())
        vs.append(state.v.copy())

    run_closed_loop(run, on_step=keep)
    return Recording(run.name, np.asarray(ts), np.asarray(qs), np.asarray(vs))


@dataclass
class ReplayTimings:
    """Per-tick stage timings [s] of one controller × solver on a recording."""

    stages: dict[str, np.ndarray] = field(default_factory=dict)
    failures: int = 0
    message: str = ""  # the first failure's message

    def median_us(self, stage: str, warmup: int = 0) -> float:
        return self.quantile_us(stage, 0.5, warmup)

    def quantile_us(self, stage: str, q: float, warmup: int = 0) -> float:
        """The ``q`` quantile of a stage [µs] over the finite ticks after ``warmup``."""
        x = self.stages[stage][warmup:]
        x = x[np.isfinite(x)]
        return float(np.quantile(x, q) * 1e6) if x.size else float("nan")


class Replayer:
    """A fresh controller of one run stepping through a recording, one tick at a time.

    :func:`replay` steps it from the first recorded state to the last; the timing sweep steps
    several replayers on the same recording in interleaved blocks of ticks
    (:mod:`wbcbench.bench.timing`), so that they share the machine's moments.

    ``keep_problems`` makes each output carry its QPs; ``on_step(i, out)`` runs after each
    (timed) step and may return a failure message that marks the tick failed (e.g. an
    independent validity check); ``wrap_solver`` wraps every solver handle the controller makes.
    """

    def __init__(
        self,
        run: Run,
        recording: Recording,
        keep_problems: bool = False,
        on_step: Callable[[int, ControlOutput], str] | None = None,
        wrap_solver: Callable[[Any], Any] | None = None,
    ) -> None:
        self.recording = recording
        self.on_step = on_step
        self.controller = run.make_controller(wrap_solver, keep_problems=keep_problems)
        self.robot = self.controller.ctx.robot  # with the scenario's model error, if any
        self.data = self.robot.pin_model.createData()
        self.columns: dict[str, list[float]] = {}
        self.failures = 0
        self.message = ""
        self.done = 0  # ticks stepped

    def __len__(self) -> int:
        return len(self.recording)

    def step(self, i: int) -> None:
        """Step the controller on recorded state ``i`` (the next one: ticks go in order)."""
        assert i == self.done, f"tick {i} stepped after {self.done}"
        rec = self.recording
        state = RobotState(self.robot, rec.q[i], rec.v[i], self.data)
        if i == 0:
            self.controller.start(state)
        out = self.controller.step(state, float(rec.t[i]))
        self.done = i + 1
        problem = (out.message or "QP failed") if not out.ok else ""
        if self.on_step is not None:
            problem = self.on_step(i, out) or problem
        if problem:
            self.failures += 1
            self.message = self.message or f"tick {i}: {problem}"
        for stage, value in out.timings.items():
            # a stage first reported at tick i (e.g. a level that appears later) gets NaN before
            self.columns.setdefault(stage, [float("nan")] * i).append(value)
        for values in self.columns.values():
            if len(values) == i:  # a stage this tick did not report
                values.append(float("nan"))

    def timings(self) -> ReplayTimings:
        """The stage timings of the ticks stepped so far."""
        columns = {k: np.asarray(v) for k, v in self.columns.items()}
        return ReplayTimings(columns, self.failures, self.message)


def replay(
    run: Run,
    recording: Recording,
    keep_problems: bool = False,
    on_step: Callable[[int, ControlOutput], str] | None = None,
    wrap_solver: Callable[[Any], Any] | None = None,
) -> ReplayTimings:
    """Step a fresh controller of ``run`` through every recorded state; collect its stage
    timings (the arguments are :class:`Replayer`'s)."""
    replayer = Replayer(run, recording, keep_problems, on_step, wrap_solver)
    for i in range(len(recording)):
        replayer.step(i)
    return replayer.timings()
