"""One writer per results folder: a sweep's lock, and its children's.

A sweep appends to its folder, and so do the guarded children it starts (the solver comparison
appends ``qp_solves.csv``, the hierarchy scaling its rows). A second sweep on the same folder,
or a resume started while a killed sweep's child is still finishing a write, would interleave
its rows with theirs. Two ``flock`` locks keep the writers apart; the kernel releases a lock
when its process ends, however it ends, so a killed sweep never leaves a stale one:

* ``.sweep.lock``: held exclusively by the sweep for as long as it runs (the file holds its
  process id, for the message a second sweep gets);
* ``.writers.lock``: held shared by every process that writes to the folder on a sweep's behalf.
  A sweep takes it exclusively once before it reads or repairs anything, so it starts only
  when no writer of an earlier sweep is alive, then releases it to its own children.

A guarded child dies with its parent (see :mod:`wbcbench.bench.guard`), so after a kill the
wait is a few milliseconds; :data:`WAIT_S` bounds it.
"""

from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path
from types import TracebackType

from wbcbench.errors import WbcBenchError

SWEEP_LOCK = ".sweep.lock"
WRITERS_LOCK = ".writers.lock"
#: how long a sweep waits for an earlier sweep's processes to end before it refuses [s]
WAIT_S = 10.0


class FolderBusyError(WbcBenchError):
    """Another process writes to the results folder."""


def _take(fd: int, how: int, wait_s: float) -> bool:
    """``flock(fd, how)``, retried for ``wait_s`` seconds; whether it was taken."""
    end = time.monotonic() + wait_s
    while True:
        try:
            fcntl.flock(fd, how | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() >= end:
                return False
            time.sleep(0.01)


def _holder(path: Path) -> str:
    try:
        pid = path.read_text().strip()
    except OSError:
        return "another process"
    return f"process {pid}" if pid.isdigit() else "another process"


class SweepLock:
    """The sweep's hold on its results folder (a context manager).

    Raises:
        FolderBusyError: on entering, when another sweep still runs on the folder, or a
            process an earlier sweep started still writes to it, after :data:`WAIT_S`.
    """

    def __init__(self, folder: str | Path, wait_s: float = WAIT_S) -> None:
        self.folder = Path(folder)
        self.wait_s = wait_s
        self._fd: int | None = None

    def __enter__(self) -> SweepLock:
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / SWEEP_LOCK
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        if not _take(fd, fcntl.LOCK_EX, self.wait_s):
            os.close(fd)
            raise FolderBusyError(
                f"{self.folder}: another sweep ({_holder(path)}) is writing to this results "
                "folder; wait for it to end or stop it, or give another --out"
            )
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        writers = os.open(self.folder / WRITERS_LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            if not _take(writers, fcntl.LOCK_EX, self.wait_s):
                os.close(fd)
                raise FolderBusyError(
                    f"{self.folder}: a process started by an earlier sweep still writes to "
                    f"this results folder after {self.wait_s:g} s; stop it and run again"
                )
        finally:
            os.close(writers)  # unlocks: the folder's writers are this sweep's from now on
        self._fd = fd
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def hold_as_writer(folder: str | Path, sweep_pid: int) -> int:
    """In a process that writes to ``folder`` for the sweep ``sweep_pid``: take the shared
    writers' lock and keep it until this process ends (the descriptor is returned, never to be
    closed).

    Raises:
        FolderBusyError: the folder's sweep is no longer ``sweep_pid`` (it was killed and
            another one resumed): this process must not write.
    """
    fd = os.open(Path(folder) / WRITERS_LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_SH)
    holder = _holder(Path(folder) / SWEEP_LOCK)
    if holder != f"process {sweep_pid}":
        os.close(fd)
        raise FolderBusyError(
            f"{folder}: the sweep that started this writer (process {sweep_pid}) no longer "
            f"holds the folder ({holder} does)"
        )
    return fd
