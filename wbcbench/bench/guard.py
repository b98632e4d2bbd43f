"""A wall-clock guard for one sweep run: a child process with a deadline.

A solver's native loop or a native abort cannot be interrupted from Python inside the process
that runs it: a hung ``solve()`` holds the interpreter, and ``std::terminate`` ends it. So every
sweep run executes in a forked child process (it starts in milliseconds with everything the
parent has loaded: modules, robot caches), and the parent waits for its result until a
deadline. A child that misses it is killed; one that dies (a signal, an abort) is reported.
Either way the caller turns the outcome into a ``failed`` row and the sweep goes on.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any


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


def can_guard() -> bool:
    """Whether this platform can fork (POSIX): elsewhere runs go unguarded.

    The child is forked directly, not through :mod:`multiprocessing`, so that daemonic
    processes (the workers of a dask cluster, local or remote) guard their runs too."""
    return hasattr(os, "fork")


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
    write_fd: int, fn: Callable[..., Any], args: tuple[Any, ...], stdout: str | None
) -> None:
    """The forked child: run, send the pickled outcome, and leave without the parent's exit
    handlers (``os._exit``)."""
    try:
        if stdout:
            _redirect_stdout(stdout)
        try:
            result: tuple[str, Any] = ("ok", fn(*args))
        except BaseException as exc:  # the parent reports it; the child must not die silently
            result = ("raised", f"{type(exc).__name__}: {exc}")
        try:
            data = pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # an unpicklable result is the run's failure, not a crash
            data = pickle.dumps(("raised", f"its result does not pickle: {exc}"))
        with os.fdopen(write_fd, "wb") as pipe:
            pipe.write(data)
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(0)


def _died(status: int) -> str:
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        try:
            name = signal.Signals(number).name
        except ValueError:
            name = f"signal {number}"
        return f"the run's process died of {name} (a native crash or abort) before it returned"
    code = os.WEXITSTATUS(status) if os.WIFEXITED(status) else status
    return f"the run's process ended with exit code {code} before it returned"


def _read_until(read_fd: int, deadline: float) -> bytes | None:
    """Everything the child writes until it closes the pipe, or None at the deadline (the
    pipe is drained as it fills: a large result never blocks the child)."""
    chunks: list[bytes] = []
    while True:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([read_fd], [], [], left)[0]:
            return None
        chunk = os.read(read_fd, 1 << 20)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)


def call_with_deadline(
    fn: Callable[..., Any],
    args: tuple[Any, ...],
    seconds: float,
    stdout: str | Path | None = None,
) -> Guarded:
    """``fn(*args)`` in a forked child process, abandoned (killed) after ``seconds`` of wall
    time.

    The result must pickle. Never raises for what happens in the child. ``stdout``: a file that
    receives what the child prints to its standard output (kept only when something was
    printed; a failed outcome's message then names it).
    """
    out = str(stdout) if stdout else None
    read_fd, write_fd = os.pipe()
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        os.close(read_fd)
        _child(write_fd, fn, args, out)
    os.close(write_fd)
    try:
        data = _read_until(read_fd, time.monotonic() + seconds)
    finally:
        os.close(read_fd)
    if data is None:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        outcome = Guarded(
            None,
            False,
            f"exceeded the wall-clock guard of {seconds:g} s (a hung solver or native call); "
            "the run was stopped",
        )
    else:
        _, status = os.waitpid(pid, 0)
        outcome = _outcome(data, status)
    printed = Path(out) if out else None
    if printed is not None and printed.exists():
        if printed.stat().st_size == 0:
            printed.unlink()
        elif not outcome.ok:
            outcome.message += f" (what it printed: {printed.parent.name}/{printed.name})"
    return outcome


def _outcome(data: bytes, status: int) -> Guarded:
    if not data:
        return Guarded(None, False, _died(status))
    kind, value = pickle.loads(data)
    if kind == "raised":
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
