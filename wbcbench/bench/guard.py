"""A wall-clock guard for one sweep run: a child process with a deadline.

A solver's native loop or a native abort cannot be interrupted from Python inside the process
that runs it: a hung ``solve()`` holds the interpreter, and ``std::terminate`` ends it. So every
sweep run executes in a child process, and the caller waits for its result until a deadline. A
child that misses it is killed; one that dies (a signal, an abort) is reported. Either way the
caller turns the outcome into a ``failed`` row and the sweep goes on.

The child never comes from forking the caller. The caller may hold the threads of a native
library (rayon in Clarabel, OpenBLAS, OpenMP, MuJoCo's or Dask's pools); a forked child inherits
their locks and bookkeeping but not the threads, and waits for them forever. So each process
that guards runs starts one *fork server*: a fresh interpreter (``python -m
wbcbench.bench.guard``), with one BLAS and one OpenMP thread, that imports wbcbench's modules
and then only forks. It runs no solver code itself, and it checks before every fork that it is
still single-threaded. A run's child starts in milliseconds with the modules loaded; the server
costs one interpreter start per guarding process (about 2 s).

The server is started with :mod:`subprocess`, not :mod:`multiprocessing`, so that daemonic
processes (the workers of a dask cluster, local or remote) guard their runs too: multiprocessing
forbids them children.

Nothing outlives its caller. On Linux the server asks the kernel for SIGKILL when the thread
that started it ends (``prctl(PR_SET_PDEATHSIG)``), and so does every child it forks, for when
the server ends: a sweep killed by any means takes its server and its running child with it
within milliseconds, and a resume never meets a writer of the killed sweep (see also
:mod:`wbcbench.bench.lock`). Elsewhere the server still kills its child when the caller's end
of its request pipe closes.
"""

from __future__ import annotations

import atexit
import importlib
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from wbcbench import plugins

#: modules the fork server imports before its first fork: what the guarded runs call
PRELOAD = (
    "wbcbench.bench.runner",
    "wbcbench.bench.timing",
    "wbcbench.bench.executors",
    "wbcbench.bench.sweep",
    "wbcbench.controllers.registry",
    "wbcbench.qp.registry",
)

#: the server's environment: one thread per numerical library, as every run of the project has
#: (see ``threadpool_limits(1)`` in the CLI and the executors), and no background thread of
#: Arrow's jemalloc (pandas imports pyarrow), so that importing leaves the server one thread
SERVER_ENV = {
    "OPENBLAS_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "JE_ARROW_MALLOC_CONF": "background_thread:false",
}

#: how long the fork server may take to import :data:`PRELOAD` [s]
SERVER_START_S = 300.0


@dataclass
class Guarded:
    """The outcome of :func:`call_with_deadline`.

    Attributes:
        value: what the function returned (``None`` unless ``ok``).
        ok: the function returned within the deadline.
        message: why not, e.g. ``"exceeded the wall-clock guard of 600 s"``.
        stalled: the child was stopped because one step outlasted its own deadline
            (:func:`watch_step`); the rest of its work may go on in a new child.
    """

    value: Any
    ok: bool
    message: str = ""
    stalled: bool = False


def can_guard() -> bool:
    """Whether this platform can fork (POSIX): elsewhere runs go unguarded."""
    return hasattr(os, "fork")


#: ``PR_SET_PDEATHSIG`` of ``<linux/prctl.h>``
PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int) -> None:
    """Have the kernel send this process SIGKILL when its parent ``parent`` ends (Linux; a no-op
    elsewhere). Exits at once when ``parent`` has already ended (this process was re-parented
    before the request took effect)."""
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != parent:
        os._exit(1)


# -- the child: one run ---------------------------------------------------------------------


#: a watch file: ticks done and total (``qq``), then the step under way: its deadline on the
#: system's monotonic clock, its length [s] and what it is (``dd200s``)
_TICKS, _STEP = struct.Struct("qq"), struct.Struct("dd200s")
WATCH_SIZE = _TICKS.size + _STEP.size


@dataclass
class Watched:
    """What a guarded child last said it was doing (see :class:`ProgressFile`)."""

    done: int
    total: int
    until: float  # the step's deadline (time.monotonic); 0: no step under way
    limit: float  # the step's own deadline [s]
    doing: str  # the step, e.g. "solver osqp (mid, hot) on problems/…/t00021-00.npz"


class ProgressFile:
    """What a guarded child is doing, written to a small file for the caller to read while it
    waits (a callback of the caller's own does not cross processes): ticks done as a
    ``progress(done, total)`` callback, and the step under way with its own deadline
    (:meth:`step`), past which the caller stops the child."""

    def __init__(self, path: str) -> None:
        self.path = path
        self._fd: int | None = None  # opened on the first call, in the child (called per tick)

    def __getstate__(self) -> dict[str, Any]:
        return {"path": self.path, "_fd": None}

    def _write(self, data: bytes, offset: int) -> None:
        if self._fd is None:
            self._fd = os.open(self.path, os.O_WRONLY)
        os.pwrite(self._fd, data, offset)

    def __call__(self, done: int, total: int) -> None:
        self._write(_TICKS.pack(done, total), 0)

    def step(self, doing: str, seconds: float) -> None:
        """A step begins that must end within ``seconds`` (``doing``: what it is, e.g. which
        solver); ``seconds`` 0: the step ended."""
        until = time.monotonic() + seconds if seconds > 0 else 0.0
        self._write(_STEP.pack(until, seconds, doing.encode()[:200]), _TICKS.size)

    def read(self) -> Watched | None:
        try:
            data = Path(self.path).read_bytes()
        except OSError:
            return None
        if len(data) != WATCH_SIZE:
            return None
        done, total = _TICKS.unpack_from(data)
        until, limit, doing = _STEP.unpack_from(data, _TICKS.size)
        return Watched(done, total, until, limit, doing.rstrip(b"\0").decode(errors="replace"))


#: set in the environment of a child that takes over the work of one stopped at a step's deadline
STOPPED_ENV = "WBCBENCH_STOPPED_STEP"

#: the watch of this process when it is a guarded child (None elsewhere)
_watch: ProgressFile | None = None


def report_progress(done: int, total: int) -> None:
    """In a guarded child: ``done`` of ``total`` ticks (or solves) are done (a no-op
    elsewhere)."""
    if _watch is not None:
        _watch(done, total)


def watch_step(doing: str, seconds: float) -> None:
    """In a guarded child: the step ``doing`` begins and must end within ``seconds``; 0 ends it
    (a no-op elsewhere). The caller stops a child whose step outlasts its deadline."""
    if _watch is not None:
        _watch.step(doing, seconds)


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


def _run_child(payload: bytes, server: int) -> None:
    """In the forked child of the fork server ``server``: unpickle the call, run it, write the
    pickled outcome to the result file, and leave without the server's exit handlers
    (``os._exit``)."""
    try:
        die_with_parent(server)
        stdout, result_path, watch, path, cwd, env, saved, call = pickle.loads(payload)
        # the module the run's code imports (the server runs this file as __main__)
        from wbcbench.bench import guard as imported

        imported._watch = ProgressFile(watch)
        # the caller's now, not when the server started: its modules, working folder and
        # environment (a test's or a notebook's changes included)
        sys.path[:] = path
        os.chdir(cwd)
        os.environ.clear()
        os.environ.update({**env, **SERVER_ENV})
        if stdout:
            _redirect_stdout(stdout)
        result: tuple[str, Any]
        try:
            result = ("ok", plugins.run_pickled(saved, call))
        except BaseException as exc:  # the caller reports it; the child must not die silently
            result = ("raised", f"{type(exc).__name__}: {exc}")
        try:
            data = pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # an unpicklable result is the run's failure, not a crash
            data = pickle.dumps(("raised", f"its result does not pickle: {exc}"))
        with open(result_path, "wb") as out:
            out.write(data)
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(0)


# -- the fork server ------------------------------------------------------------------------


def thread_count() -> int:
    """The threads of this process, native ones included (Linux: ``/proc/self/task``; 1
    elsewhere, where it cannot be read)."""
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return 1


def _wait_or_kill(pid: int, requests: Connection) -> int:
    """Wait for the child ``pid``; a ``"kill"`` request, or the caller closing its end, kills
    it first. Returns its wait status."""
    pidfd = os.pidfd_open(pid) if hasattr(os, "pidfd_open") else None
    try:
        while True:
            watched: list[Any] = [requests.fileno()] + ([pidfd] if pidfd is not None else [])
            ready = select.select(watched, [], [], None if pidfd is not None else 0.05)[0]
            if requests.fileno() in ready:
                try:
                    requests.recv_bytes()  # "kill": the deadline passed
                except EOFError:  # the caller is gone: leave no orphan running
                    pass
                os.kill(pid, signal.SIGKILL)
                return os.waitpid(pid, 0)[1]
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                return status
    finally:
        if pidfd is not None:
            os.close(pidfd)


def serve(request_fd: int, reply_fd: int, caller: int) -> None:
    """The fork server's loop: import :data:`PRELOAD`, then for every request fork a child that
    runs it, reply ``("started", pid)`` and, once it ends, ``("ended", status)``. Ends when the
    caller (process ``caller``) closes its end of the request pipe, or ends."""
    die_with_parent(caller)
    requests = Connection(request_fd, writable=False)
    replies = Connection(reply_fd, readable=False)
    for name in PRELOAD:
        importlib.import_module(name)
    replies.send(("ready", thread_count()))
    while True:
        try:
            payload = requests.recv_bytes()
        except EOFError:
            return
        threads = thread_count()
        if threads > 1:  # never fork a process that holds other threads
            replies.send(("refused", f"the fork server holds {threads} threads"))
            continue
        sys.stdout.flush()
        sys.stderr.flush()
        server = os.getpid()
        pid = os.fork()
        if pid == 0:
            requests.close()
            replies.close()
            _run_child(payload, server)
        replies.send(("started", pid))
        replies.send(("ended", _wait_or_kill(pid, requests)))


class ForkServer:
    """The caller's handle on one fork server process (see the module's docstring)."""

    def __init__(self) -> None:
        request_r, request_w = os.pipe()
        reply_r, reply_w = os.pipe()
        env = {**os.environ, **SERVER_ENV}
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "wbcbench.bench.guard",
                str(request_r),
                str(reply_w),
                str(os.getpid()),
            ],
            pass_fds=(request_r, reply_w),
            stdin=subprocess.DEVNULL,
            env=env,
        )
        os.close(request_r)
        os.close(reply_w)
        self.requests = Connection(request_w, readable=False)
        self.replies = Connection(reply_r, writable=False)
        self.pid = os.getpid()
        kind, threads = self._reply(SERVER_START_S, "start")
        if kind != "ready" or threads != 1:
            self.close()
            raise RuntimeError(f"the fork server started with {threads} threads, not 1")

    def _reply(self, seconds: float, what: str) -> tuple[str, Any]:
        if not self.replies.poll(seconds):
            self.close()
            raise RuntimeError(f"the fork server did not {what} within {seconds:g} s")
        try:
            kind, value = self.replies.recv()
        except EOFError:
            code = self.process.wait()
            raise RuntimeError(f"the fork server ended (exit code {code})") from None
        return kind, value

    def run(self, payload: bytes, seconds: float, waiting: Callable[[], bool] | None) -> int | None:
        """Fork a child for ``payload``; its wait status, or None when it was killed at the
        deadline. ``waiting`` is called about five times a second meanwhile; when it returns
        True the child is killed at once."""
        deadline = time.monotonic() + seconds
        self.requests.send_bytes(payload)
        kind, value = self._reply(SERVER_START_S, "fork")
        if kind == "refused":
            raise RuntimeError(value)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            if self.replies.poll(min(left, 0.2)):
                return int(self._reply(0, "reply")[1])
            if waiting is not None and waiting():
                break
        self.requests.send_bytes(b"kill")
        self._reply(60.0, "stop its child")
        return None

    def alive(self) -> bool:
        return self.pid == os.getpid() and self.process.poll() is None

    def close(self) -> None:
        """End the server (it exits when its request pipe closes)."""
        if self.pid != os.getpid():
            return
        self.requests.close()
        self.replies.close()
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


_servers: dict[int, ForkServer] = {}
_servers_lock = threading.Lock()


def fork_server() -> ForkServer:
    """This thread's fork server, started on first use (one per thread: each waits on its own
    runs)."""
    key = threading.get_ident()
    with _servers_lock:
        server = _servers.get(key)
    if server is None or not server.alive():
        server = ForkServer()
        with _servers_lock:
            _servers[key] = server
    return server


@atexit.register
def _close_servers() -> None:
    with _servers_lock:
        servers = list(_servers.values())
        _servers.clear()
    for server in servers:
        server.close()


# -- the caller's side ----------------------------------------------------------------------


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


def call_with_deadline(
    fn: Callable[..., Any],
    args: tuple[Any, ...],
    seconds: float,
    stdout: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
    doing: str = "",
) -> Guarded:
    """``fn(*args)`` in a child of this thread's fork server, killed after ``seconds`` of wall
    time, or as soon as a step it announced (:func:`watch_step`) outlasts that step's own
    deadline.

    ``fn`` (a function of an importable module: not of a script's ``__main__``), ``args`` and
    the result must pickle. Never raises for what happens in the child. ``stdout``: a file that
    receives what the child prints to its standard output (kept only when something was
    printed; a failed outcome's message then names it). ``progress``: passed on as ``fn``'s
    ``progress`` keyword; the child's calls reach it through :class:`ProgressFile`.
    ``doing``: what the child works with (e.g. ``"solver proxqp"``), named when it is stopped
    and reported no step of its own.
    """
    out = str(stdout) if stdout else None
    fd, result_path = tempfile.mkstemp(prefix="wbcbench-guard-", suffix=".pickle")
    os.close(fd)
    fd, watch_path = tempfile.mkstemp(prefix="wbcbench-watch-")
    os.write(fd, bytes(WATCH_SIZE))
    os.close(fd)
    watch = ProgressFile(watch_path)
    kwargs: dict[str, Any] = {}
    if progress is not None:
        kwargs["progress"] = ProgressFile(watch_path)
    stalled: list[Watched] = []

    def waiting() -> bool:
        seen = watch.read()
        if seen is None:
            return False
        if progress is not None and seen.total:
            progress(seen.done, seen.total)
        if seen.until and time.monotonic() > seen.until:
            stalled.append(seen)
            return True
        return False

    try:
        try:
            saved, call = plugins.pickled_call(fn, *args, **kwargs)
        except Exception as exc:
            return Guarded(None, False, f"the run's arguments do not pickle: {exc}")
        caller = (sys.path, os.getcwd(), dict(os.environ))
        payload = pickle.dumps(
            (out, result_path, watch_path, *caller, saved, call), pickle.HIGHEST_PROTOCOL
        )
        started = time.monotonic()
        try:
            status = fork_server().run(payload, seconds, waiting)
        except (RuntimeError, OSError) as exc:  # the server could not start or died
            return Guarded(None, False, f"the wall-clock guard failed: {exc}")
        if status is None:
            outcome = _stopped(stalled, watch.read(), seconds, time.monotonic() - started, doing)
        else:
            waiting()
            outcome = _outcome(Path(result_path).read_bytes(), status)
    finally:
        Path(result_path).unlink(missing_ok=True)
        Path(watch_path).unlink(missing_ok=True)
    printed = Path(out) if out else None
    if printed is not None and printed.exists():
        if printed.stat().st_size == 0:
            printed.unlink()
        elif not outcome.ok:
            outcome.message += f" (what it printed: {printed.parent.name}/{printed.name})"
    return outcome


def _stopped(
    stalled: list[Watched], seen: Watched | None, seconds: float, waited: float, doing: str
) -> Guarded:
    """The outcome of a child stopped at a deadline: which one, and what it was doing."""
    if stalled:
        step = stalled[0]
        into = time.monotonic() - (step.until - step.limit)  # since the step began
        return Guarded(
            None,
            False,
            f"{step.doing} did not end within its own deadline of {step.limit:g} s; stopped "
            f"{into:.1f} s into it ({waited:.1f} s into the job)",
            stalled=True,
        )
    where = seen.doing if seen is not None and seen.doing else doing
    inside = f", in {where}" if where else ""
    if seen is None or seen.done == 0:
        total = f" (0 of {seen.total})" if seen is not None and seen.total else ""
        return Guarded(
            None,
            False,
            f"exceeded the wall-clock guard of {seconds:g} s having made no progress{total}"
            f"{inside}: stuck before its first tick or solve; the run was stopped",
        )
    return Guarded(
        None,
        False,
        f"exceeded the wall-clock guard of {seconds:g} s after {seen.done} of {seen.total} "
        f"ticks{inside}; the run was stopped",
    )


def _outcome(data: bytes, status: int) -> Guarded:
    if not data:
        return Guarded(None, False, _died(status))
    kind, value = pickle.loads(data)
    if kind == "raised":
        return Guarded(None, False, f"the run raised {value}")
    return Guarded(value, True)


#: what every guarded run may take beyond its ticks [s]: the child's start, loading its robot
#: and building its controller, on a loaded machine
START_S = 60.0
#: what one control tick may take before a run counts as hung [s] (a tick takes 1-20 ms)
TICK_S = 0.12


def tracking_deadline(duration: float, control_rate: float = 1000.0) -> float:
    """The default guard of a closed-loop run [s]: :data:`START_S` plus :data:`TICK_S` per
    control tick of its simulated ``duration`` [s] (a 0.2 s run at 1 kHz: 84 s)."""
    return START_S + TICK_S * duration * control_rate


def timing_deadline(replayed: int, recorded: int = 0) -> float:
    """The default guard of a timing job [s]: :data:`START_S` plus :data:`TICK_S` per tick it
    replays and per tick it must first record in closed loop (0 once the recording is cached:
    40 replayed ticks get 64.8 s)."""
    return START_S + TICK_S * (replayed + recorded)


if __name__ == "__main__":
    serve(int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]))
