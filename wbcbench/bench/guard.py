"""A wall-clock guard for one sweep run: a child process with a deadline.

A solver's native loop or a native abort cannot be interrupted from Python inside the process
that runs it: a hung ``solve()`` holds the interpreter, and ``std::terminate`` ends it. So every
sweep run executes in a forked child process (it starts in milliseconds with everything the
parent has loaded: modules, robot caches), and the parent waits for its result until a
deadline. A child that misses it is killed; one that dies (a signal, an abort) is reported.
Either way the caller turns the outcome into a ``failed`` row and the sweep goes on.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

_context: Any = None


@dataclass
class Guarded:
    """The outcome of :func:`call_with_deadline`.

    Attributes:
        value: what the function returned (``None`` unless ``ok``).
        ok: the function returned within the deadline.
        message: why not, e.g. ``"exceeded the wall-clock guard of 600 s"``.
    """

    value: Any
    ok: bool
    message: str = ""


def _fork() -> Any:
    global _context
    if _context is None:
        _context = mp.get_context("fork")
    return _context


def can_guard() -> bool:
    """False inside a daemonic process (e.g. a worker of a remote dask cluster), which may not
    start children; such runs go unguarded."""
    return not mp.current_process().daemon


def _redirect_stdout(path: str) -> None:
    """Send this process's file descriptor 1 to ``path``: native libraries print there (a
    solver's banner or debug lines), bypassing Python, and a run's prints belong in its log, not
    in the sweep's output. Left as it is when the file cannot be opened."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    except OSError:
        return
    sys.stdout.flush()
    os.dup2(fd, 1)
    os.close(fd)


def _child(
    conn: Connection, fn: Callable[..., Any], args: tuple[Any, ...], stdout: str | None
) -> None:
    if stdout:
        _redirect_stdout(stdout)
    try:
        result: tuple[str, Any] = ("ok", fn(*args))
    except BaseException as exc:  # the parent reports it; the child must not die silently
        result = ("raised", f"{type(exc).__name__}: {exc}")
    conn.send(result)
    conn.close()


def _died(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"the run's process died of {name} (a native crash or abort) before it returned"
    return f"the run's process ended with exit code {exitcode} before it returned"


def call_with_deadline(
    fn: Callable[..., Any],
    args: tuple[Any, ...],
    seconds: float,
    stdout: str | Path | None = None,
) -> Guarded:
    """``fn(*args)`` in a child process, abandoned (killed) after ``seconds`` of wall time.

    ``fn`` and ``args`` must pickle (a module-level function and plain data); so must the
    result. Never raises for what happens in the child. ``stdout``: a file that receives what
    the child prints to its standard output (kept only when something was printed; a failed
    outcome's message then names it).
    """
    ctx = _fork()
    receiver, sender = ctx.Pipe(duplex=False)
    out = str(stdout) if stdout else None
    proc = ctx.Process(target=_child, args=(sender, fn, args, out), daemon=True)
    proc.start()
    sender.close()
    try:
        outcome = _wait(proc, receiver, seconds)
    finally:
        receiver.close()
        proc.join(5)
        if proc.is_alive():
            proc.kill()
    printed = Path(out) if out else None
    if printed is not None and printed.exists():
        if printed.stat().st_size == 0:
            printed.unlink()
        elif not outcome.ok:
            outcome.message += f" (what it printed: {printed.parent.name}/{printed.name})"
    return outcome


def _wait(proc: Any, receiver: Connection, seconds: float) -> Guarded:
    if not receiver.poll(seconds):
        proc.kill()
        return Guarded(
            None,
            False,
            f"exceeded the wall-clock guard of {seconds:g} s (a hung solver or native call); "
            "the run was stopped",
        )
    try:
        status, value = receiver.recv()
    except EOFError:
        proc.join(5)
        return Guarded(None, False, _died(proc.exitcode))
    if status == "raised":
        return Guarded(None, False, f"the run raised {value}")
    return Guarded(value, True)


def tracking_deadline(duration: float) -> float:
    """The default guard of a closed-loop run [s]: 120 × its simulated duration, at least 300 s
    (a 1 kHz tick may take up to 0.12 s before a run counts as hung)."""
    return max(300.0, 120.0 * duration)


def timing_deadline(window_end: float, ticks: int) -> float:
    """The default guard of a timing replay [s]: its recording (simulated up to the window's
    end) plus one second a replayed tick, at least 300 s."""
    return max(300.0, 120.0 * window_end + float(ticks))
