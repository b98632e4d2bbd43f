"""A sweep killed (SIGKILL to the sweep's process alone) inside its solver comparison and resumed
at once, five times, leaves the ``qp_solves.csv`` of an uninterrupted sweep: no key lost or
written twice, no line unreadable, and no process of a killed sweep left running."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

KILLS = 5

SWEEP = """\
version: 1
solver_comparison:
  scenarios: [tocabi_stand_sway]
  controllers: [qp_wbc, hqp]
  solvers: [daqp, quadprog, osqp, proxqp]
  tiers: [default]
  modes: [cold, hot]
  dump_ticks: 2
  dump_after: 2
"""


def sweep(path: Path, out: Path) -> subprocess.Popen[bytes]:
    cli = [sys.executable, "-c", "import sys; from wbcbench.cli import main; sys.exit(main())"]
    return subprocess.Popen(
        [*cli, "sweep", str(path), "--out", str(out), "--no-progress"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its session id finds every process it started
    )


def alive_in_session(sid: int) -> list[int]:
    """The live (not zombie) processes of session ``sid``."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            out.append(int(stat.parent.name))
    return out


def rows(out: Path) -> int:
    path = out / "qp_solves.csv"
    return path.read_bytes().count(b"\n") - 1 if path.exists() else 0


def test_kills_inside_the_comparison_lose_and_duplicate_nothing(tmp_path: Path) -> None:
    path = tmp_path / "sweep.yaml"
    path.write_text(SWEEP)
    clean = tmp_path / "clean"
    # the uninterrupted sweep's own timeline on this machine, under its present load: from its
    # first committed row to its end is the comparison
    t0 = time.perf_counter()
    proc, first = sweep(path, clean), None
    while proc.poll() is None:
        if first is None and rows(clean) > 0:
            first = time.perf_counter() - t0
        time.sleep(0.005)
    assert proc.returncode == 0
    whole = time.perf_counter() - t0
    assert first is not None
    expected = pd.read_csv(clean / "qp_solves.csv")
    assert len(expected) > 40 and expected["key"].is_unique

    killed = tmp_path / "killed"
    rng = np.random.default_rng(7)
    proc, kills, orphans = sweep(path, killed), 0, []
    while kills < KILLS:
        # inside the comparison: after the sweep commits its first row of this process, within
        # the time the uninterrupted comparison took
        before, delay = rows(killed), float(rng.uniform(0.0, whole - first))
        while proc.poll() is None and rows(killed) == before:
            time.sleep(0.005)
        end = time.perf_counter() + delay
        while proc.poll() is None and time.perf_counter() < end:
            time.sleep(0.005)
        if proc.poll() is not None:  # finished before the kill: start over from nothing
            for f in sorted(killed.rglob("*"), reverse=True):
                f.unlink() if f.is_file() else f.rmdir()
            proc = sweep(path, killed)
            continue
        os.kill(proc.pid, signal.SIGKILL)  # the sweep alone: its children must follow it
        proc.wait()
        kills += 1
        old = proc.pid
        proc = sweep(path, killed)  # resumed at once, while the killed sweep's children end
        deadline = time.monotonic() + 5.0
        while alive_in_session(old) and time.monotonic() < deadline:
            time.sleep(0.01)
        orphans += alive_in_session(old)
        for pid in alive_in_session(old):  # leave nothing behind, whatever the verdict
            os.kill(pid, signal.SIGKILL)
    assert proc.wait(timeout=600) == 0
    assert not orphans, f"processes of killed sweeps still ran 5 s after the kill: {orphans}"

    got = pd.read_csv(killed / "qp_solves.csv")  # every line readable
    assert got["key"].notna().all() and got["solver"].notna().all()
    # a row is a problem file × solver × tier × mode (the key adds the file's checksum: the
    # dumped QPs of the two folders may differ in their last bits, from the recording's solver)
    solve = ["problem", "solver", "tier", "mode"]
    duplicated = got.duplicated(solve) | got["key"].duplicated()
    assert not duplicated.any(), got.loc[duplicated, solve].to_string()
    lost = set(map(tuple, expected[solve].values)) - set(map(tuple, got[solve].values))
    assert not lost, sorted(lost)
    assert len(got) == len(expected)
