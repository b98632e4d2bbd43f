"""The parameter server: where and when the operational-space parameters are computed.

TO-OSF §III-B2 and OSF-HQP §III-B3 compute the contact-constrained operational-space parameters
(Λ, J̃ᵀ, Ñᵀ, the wrench maps, the compensation torque) apart from the real-time loop, which only
evaluates the task references and solves the QPs with the newest parameters. Three modes:

* ``inline`` — computed from the current state every tick;
* ``periodic:N`` — refreshed every N control ticks in the control loop, reused in between
  (deterministic: closed-loop runs are reproducible);
* ``async`` — a separate worker process computes them continuously from the newest state the loop
  publishes; the loop reads the newest complete set. The worker is a spawned interpreter, never
  a fork of the loop's process (which may hold a native library's threads: a forked child would
  wait for them forever); the server waits for it to be ready before the loop goes on, so its
  start-up is not counted as staleness. Both directions go through one
  ``multiprocessing.shared_memory`` block: the state with a sequence counter, the parameters in a
  double buffer, each slot with its own sequence counter (odd while being written), so the loop
  never reads a torn set and never waits once the first set exists.

Each :meth:`ParameterServer.get` reports the control-loop time spent on parameters and their
staleness in ticks (current tick − tick of the state they were computed from). Worker processes
are stopped and the shared memory released by :meth:`ParameterServer.close` (the closed-loop
runner calls it through ``Controller.close``), and otherwise when the server is garbage collected
or the interpreter exits.
"""

from __future__ import annotations

import multiprocessing as mp
import time
import weakref
from dataclasses import dataclass
from multiprocessing.shared_memory import SharedMemory
from typing import Any

import numpy as np

from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.tasks.osf import OsfModel, OsfParams

MODES = ("inline", "periodic:N", "async")
FIRST_SET_TIMEOUT = 120.0  # [s] for the worker process to start


@dataclass(frozen=True)
class ParamsMode:
    """A parsed ``params`` setting: kind ``inline`` | ``periodic`` | ``async`` and the period N."""

    kind: str
    period: int = 1

    def __str__(self) -> str:
        return f"periodic:{self.period}" if self.kind == "periodic" else self.kind


def parse_params_mode(text: str) -> ParamsMode:
    """``inline``, ``periodic:N`` (N ≥ 1) or ``async``; anything else names the valid choices."""
    if text in ("inline", "async"):
        return ParamsMode(text)
    if text.startswith("periodic:"):
        value = text.removeprefix("periodic:")
        if value.isdigit() and int(value) >= 1:
            return ParamsMode("periodic", int(value))
    raise ControllerError(
        f"invalid params mode {text!r}; valid choices: {', '.join(MODES)} (N an integer ≥ 1)"
    )


@dataclass
class ParamsRead:
    """What the control loop got this tick.

    Attributes:
        params: the parameter set to use.
        loop_time: control-loop seconds spent on parameters this tick (computing them inline,
            or publishing the state and copying the newest set).
        staleness: ticks between the state they were computed from and the current tick.
        compute_time: seconds it took to compute this set (wherever it was computed).
    """

    params: OsfParams
    loop_time: float
    staleness: int
    compute_time: float


# -- shared-memory layout -----------------------------------------------------------------------

# header slots (float64)
_IN_SEQ, _IN_TICK, _LATEST, _STOP, _ERROR, _READY = 0, 1, 2, 3, 4, 5
_SEQ = (6, 7)
_TICK = (8, 9)
_TIME = (10, 11)
_HEADER = 12


@dataclass(frozen=True)
class _Layout:
    nq: int
    nv: int
    shapes: tuple[tuple[int, ...], ...]

    @property
    def sizes(self) -> list[int]:
        return [int(np.prod(s)) for s in self.shapes]

    @property
    def slot_size(self) -> int:
        return sum(self.sizes)

    @property
    def state_offset(self) -> int:
        return _HEADER

    def slot_offset(self, slot: int) -> int:
        return _HEADER + self.nq + self.nv + slot * self.slot_size

    @property
    def total(self) -> int:
        return _HEADER + self.nq + self.nv + 2 * self.slot_size

    def views(self, flat: np.ndarray) -> list[np.ndarray]:
        """Arrays of the slot held in ``flat`` (no copy)."""
        out, pos = [], 0
        for shape, size in zip(self.shapes, self.sizes, strict=True):
            out.append(flat[pos : pos + size].reshape(shape))
            pos += size
        return out


def _write_slot(buf: np.ndarray, layout: _Layout, slot: int, p: OsfParams) -> None:
    pos = layout.slot_offset(slot)
    for arr, size in zip(p.arrays(), layout.sizes, strict=True):
        buf[pos : pos + size] = arr.ravel()
        pos += size


def _worker(
    model: OsfModel, robot: Any, shm_name: str, layout: _Layout, template_shapes: tuple
) -> None:
    """Worker loop: compute parameters from the newest published state until told to stop.

    Runs in a spawned process that attaches the block by name (it shares the parent's resource
    tracker, so the block stays registered once and the parent unlinks it).
    """
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)  # as the loop's process: one BLAS thread
    shm = SharedMemory(name=shm_name)
    try:
        buf = np.ndarray((layout.total,), dtype=np.float64, buffer=shm.buf)
        data = robot.pin_model.createData()
        s0 = layout.state_offset
        buf[_READY] = 1.0
        last = -1.0
        while buf[_STOP] == 0.0:
            seq = float(buf[_IN_SEQ])
            if seq == last or int(seq) % 2 == 1:
                time.sleep(20e-6)
                continue
            q = buf[s0 : s0 + layout.nq].copy()
            v = buf[s0 + layout.nq : s0 + layout.nq + layout.nv].copy()
            tick = int(buf[_IN_TICK])
            if float(buf[_IN_SEQ]) != seq:  # the loop published a newer state meanwhile
                continue
            last = seq
            t0 = time.perf_counter()
            p = model.params(RobotState(robot, q, v, data), tick=tick)
            elapsed = time.perf_counter() - t0
            if tuple(a.shape for a in p.arrays()) != template_shapes:
                buf[_ERROR] = 1.0  # e.g. a contact Jacobian lost rank: null(W) changed size
                return
            slot = 1 - int(buf[_LATEST])
            buf[_SEQ[slot]] += 1.0  # odd: being written
            _write_slot(buf, layout, slot, p)
            buf[_TICK[slot]] = tick
            buf[_TIME[slot]] = elapsed
            buf[_SEQ[slot]] += 1.0  # even: complete
            buf[_LATEST] = slot
    finally:
        shm.close()


def _cleanup(proc: Any, shm: SharedMemory) -> None:
    """Stop the worker and release the shared memory (idempotent)."""
    try:
        buf = np.ndarray((_HEADER,), dtype=np.float64, buffer=shm.buf)
        buf[_STOP] = 1.0
    except (ValueError, TypeError, BufferError):
        pass
    if proc is not None:
        proc.join(timeout=2.0)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=2.0)
    try:
        shm.close()
    except BufferError:
        pass
    try:
        shm.unlink()
    except FileNotFoundError:
        pass


class ParameterServer:
    """Serves :class:`OsfParams` to a controller in one of the three modes.

    Use as a context manager or call :meth:`close`; ``get`` is called once per control tick.
    """

    def __init__(self, model: OsfModel, mode: str | ParamsMode, robot: Any) -> None:
        self.model = model
        self.mode = parse_params_mode(mode) if isinstance(mode, str) else mode
        self.robot = robot
        self._current: OsfParams | None = None
        self._shm: SharedMemory | None = None
        self._buf: np.ndarray | None = None
        self._layout: _Layout | None = None
        self._proc: Any = None
        self._in_seq = 0.0
        self._finalizer: weakref.finalize | None = None

    # -- lifecycle ------------------------------------------------------------------------------

    def __enter__(self) -> ParameterServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the worker process (async) and release the shared memory; safe to repeat."""
        if self._finalizer is not None:
            self._finalizer()
        self._finalizer = None
        self._proc = None
        self._buf = None
        self._shm = None

    @property
    def worker_alive(self) -> bool:
        return self._proc is not None and self._proc.is_alive()

    # -- per tick -----------------------------------------------------------------------------

    def get(
        self,
        state: RobotState,
        tick: int,
        jacobians: list[tuple[np.ndarray, np.ndarray]] | None = None,
    ) -> ParamsRead:
        """The parameters to use at control tick ``tick`` for ``state``.

        ``jacobians`` (J, J̇q̇ per level) avoids re-extracting them when the loop computes the
        parameters itself.
        """
        t0 = time.perf_counter()
        dyn0 = state.compute_time
        kind = self.mode.kind
        cur = self._current
        if (
            kind == "inline"
            or cur is None
            or (kind == "periodic" and tick - cur.tick >= self.mode.period)
        ):
            cur = self.model.params(state, jacobians, tick=tick)
            self._current = cur
            if kind == "async" and self._proc is None:
                self._start_worker(cur)
        elif kind == "async":
            self._publish(state, tick)
            cur = self._read_newest(cur)
            self._current = cur
        if kind == "async" and cur.tick == tick and self._buf is not None:
            self._publish(state, tick)
        loop = time.perf_counter() - t0 - (state.compute_time - dyn0)
        return ParamsRead(cur, loop, tick - cur.tick, cur.compute_time)

    # -- async internals ------------------------------------------------------------------------

    def _start_worker(self, template: OsfParams) -> None:
        shapes = tuple(a.shape for a in template.arrays())
        layout = _Layout(self.robot.pin_model.nq, self.robot.pin_model.nv, shapes)
        shm = SharedMemory(create=True, size=8 * layout.total)
        buf = np.ndarray((layout.total,), dtype=np.float64, buffer=shm.buf)
        buf[:] = 0.0
        buf[_LATEST] = 0.0
        ctx = mp.get_context("spawn")
        proc = ctx.Process(
            target=_worker,
            args=(self.model, self.robot, shm.name, layout, shapes),
            daemon=True,
            name="wbcbench-osf-params",
        )
        proc.start()
        self._shm, self._buf, self._layout, self._proc = shm, buf, layout, proc
        self._finalizer = weakref.finalize(self, _cleanup, proc, shm)
        deadline = time.monotonic() + FIRST_SET_TIMEOUT
        while buf[_READY] == 0.0:
            if not proc.is_alive() or time.monotonic() > deadline:
                self.close()
                raise ControllerError(
                    "the parameter worker process did not start; use params: inline"
                )
            time.sleep(0.01)

    def _publish(self, state: RobotState, tick: int) -> None:
        buf, layout = self._buf, self._layout
        assert buf is not None and layout is not None
        s0 = layout.state_offset
        self._in_seq += 1.0
        buf[_IN_SEQ] = self._in_seq  # odd: being written
        buf[s0 : s0 + layout.nq] = state.q
        buf[s0 + layout.nq : s0 + layout.nq + layout.nv] = state.v
        buf[_IN_TICK] = tick
        self._in_seq += 1.0
        buf[_IN_SEQ] = self._in_seq

    def _read_newest(self, fallback: OsfParams) -> OsfParams:
        """The newest complete set, or ``fallback`` when the worker has not produced a newer one."""
        buf, layout = self._buf, self._layout
        assert buf is not None and layout is not None
        if buf[_ERROR] != 0.0:
            raise ControllerError(
                "the parameter worker stopped: the operational-space parameters changed shape "
                "(a contact Jacobian lost rank?); use params: inline or periodic:N"
            )
        if not self.worker_alive:
            raise ControllerError("the parameter worker process died; use params: inline")
        for _ in range(100):
            slot = int(buf[_LATEST])
            seq = float(buf[_SEQ[slot]])
            if seq == 0.0:
                return fallback  # nothing written yet
            if int(seq) % 2 == 1:
                continue
            tick = int(buf[_TICK[slot]])
            if tick <= fallback.tick:
                return fallback
            start = layout.slot_offset(slot)
            flat = buf[start : start + layout.slot_size].copy()
            compute = float(buf[_TIME[slot]])
            if float(buf[_SEQ[slot]]) == seq:
                return fallback.from_arrays(layout.views(flat), tick, compute)
        return fallback
