"""A sweep killed (SIGKILL, its whole process group) at random points, then rerun until it
finishes, leaves the same results folder as an uninterrupted sweep: no row lost, duplicated or
unreadable, and every run's metrics stored once."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from wbcbench.bench.results import ResultsStore

KILLS = 20

SWEEP = """\
version: 1
tracking:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc, to_osf]
    solvers: [daqp, quadprog, osqp]
    set: ["duration=0.03", "metrics.window=[0.0, 0.03]", "metrics.timing_warmup=2"]
  - scenarios: [ahn_double_support]
    controllers: [lqp]
    solvers: [daqp, quadprog]
    set: ["duration=0.03", "metrics.window=[0.0, 0.03]", "metrics.timing_warmup=2"]
"""


def sweep(path: Path, out: Path) -> subprocess.Popen[bytes]:
    cli = [sys.executable, "-c", "import sys; from wbcbench.cli import main; sys.exit(main())"]
    return subprocess.Popen(
        [*cli, "sweep", str(path), "--out", str(out), "--no-progress"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its own process group: the kill takes its run children too
    )


def test_twenty_kills_lose_duplicate_and_corrupt_nothing(tmp_path: Path) -> None:
    path = tmp_path / "sweep.yaml"
    path.write_text(SWEEP)
    clean = tmp_path / "clean"
    # when an uninterrupted sweep on this machine, under its present load, stores its first
    # run and when it ends: half the kills fall in its start-up (imports, planning, the first
    # run), half while runs are being stored
    t0 = time.perf_counter()
    proc, first = sweep(path, clean), None
    while proc.poll() is None:
        if first is None and any((clean / "logs").glob("*.parquet")):
            first = time.perf_counter() - t0
        time.sleep(0.02)
    assert proc.returncode == 0
    whole = time.perf_counter() - t0
    first = whole if first is None else first
    planned = len(pd.read_csv(clean / "runs.csv"))
    assert planned == 8

    killed = tmp_path / "killed"
    rng = np.random.default_rng(3)
    rows_seen, kills = [], 0
    while kills < KILLS:
        proc = sweep(path, killed)
        window = (0.05 * first, first) if kills % 2 == 0 else (first, whole)
        time.sleep(float(rng.uniform(*window)))
        if proc.poll() is not None:  # finished before the kill: start over from nothing
            for f in killed.glob("*"):
                if f.is_file():
                    f.unlink()
            for f in (killed / "logs").glob("*"):
                f.unlink()
            continue
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        kills += 1
        store = ResultsStore(killed)  # opening repairs; every table readable afterwards
        runs = store.runs()
        rows_seen.append(len(runs))
        assert runs.empty or runs["run_id"].is_unique
    assert sweep(path, killed).wait(timeout=600) == 0

    runs_a, runs_b = (pd.read_csv(f / "runs.csv") for f in (clean, killed))
    assert runs_b["run_id"].is_unique and sorted(runs_a["run_id"]) == sorted(runs_b["run_id"])
    key = ["run_id", "task", "metric"]
    a = pd.read_csv(clean / "metrics.csv").sort_values(key).reset_index(drop=True)
    b = pd.read_csv(killed / "metrics.csv").sort_values(key).reset_index(drop=True)
    assert not b.duplicated(key).any()
    assert len(a) == len(b)
    tracking = a["metric"].str.startswith("err")
    pd.testing.assert_frame_equal(a[tracking], b[tracking])
    assert len(pd.read_parquet(killed / "runs.parquet")) == planned
    for rid in runs_b["run_id"]:
        assert (killed / "logs" / f"{rid}.parquet").exists()
    # the kills landed all along the sweep, not only before its first row
    assert min(rows_seen) < max(rows_seen)
