"""The wall-clock guard of sweep runs: hangs and native crashes end as failed rows."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pandas as pd
import pytest

from wbcbench.bench.guard import call_with_deadline
from wbcbench.bench.sweep import load_sweep_file, plan_sweep, run_sweep


def _hang(seconds: float) -> str:
    time.sleep(seconds)
    return "woke up"


def _abort() -> None:
    os.abort()


def _square(x: float) -> float:
    return x * x


def _print_natively_then_abort(lines: int) -> None:
    for _ in range(lines):  # as a native library does: straight to file descriptor 1
        os.write(1, b"error\n")
    os.abort()


def test_what_a_run_prints_goes_to_its_log_not_the_sweep_output(tmp_path: Path, capfd) -> None:
    printed = tmp_path / "logs" / "run.stdout.txt"
    printed.parent.mkdir()
    outcome = call_with_deadline(_print_natively_then_abort, (1000,), 30, printed)
    assert not outcome.ok
    assert outcome.message.endswith("(what it printed: logs/run.stdout.txt)")
    assert printed.read_text() == "error\n" * 1000
    assert "error" not in capfd.readouterr().out
    # a run that prints nothing leaves no file
    assert call_with_deadline(_square, (2.0,), 30, printed).value == 4.0
    assert not printed.exists()


def _guard_a_hang_in_a_daemon(queue) -> None:
    queue.put(call_with_deadline(_hang, (60.0,), 1.0).message)


def test_a_daemonic_process_guards_its_runs_too() -> None:
    """Dask workers are daemonic processes, which multiprocessing forbids to have children:
    the guard forks directly."""
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    daemon = ctx.Process(target=_guard_a_hang_in_a_daemon, args=(queue,), daemon=True)
    daemon.start()
    message = queue.get(timeout=60)
    daemon.join(10)
    assert message.startswith("exceeded the wall-clock guard of 1 s")


def test_a_result_within_the_deadline_comes_back() -> None:
    outcome = call_with_deadline(_square, (3.0,), 30)
    assert outcome.ok and outcome.value == 9.0


def test_a_hung_call_is_stopped_at_its_deadline() -> None:
    t0 = time.perf_counter()
    outcome = call_with_deadline(_hang, (60.0,), 1.0)
    assert not outcome.ok
    assert outcome.message.startswith("exceeded the wall-clock guard of 1 s")
    assert time.perf_counter() - t0 < 10


def test_a_native_abort_is_reported_not_fatal() -> None:
    outcome = call_with_deadline(_abort, (), 30)
    assert not outcome.ok
    assert "died of SIGABRT" in outcome.message


def test_an_exception_in_the_child_is_reported() -> None:
    outcome = call_with_deadline(_square, ("x",), 30)
    assert not outcome.ok
    assert outcome.message.startswith("the run raised TypeError")


SWEEP = """\
version: 1
tracking:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [daqp, quadprog]
    set: ["duration=0.05", "metrics.window=[0.0, 0.05]"]
timing:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [daqp, quadprog]
    modes: [cold]
    ticks: 8
    warmup: 2
    probe_ticks: 4
    set: ["duration=0.3"]
"""


def test_a_run_that_hangs_becomes_a_failed_row_and_the_sweep_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from wbcbench.qp.backends.daqp import DAQPSolver

    def hangs(self, problem, guess, keep):
        time.sleep(3600)

    monkeypatch.setattr(DAQPSolver, "_solve_fresh", hangs)
    text = SWEEP.replace("tracking:\n  - ", "tracking:\n  - wall_limit_s: 10\n    ")
    text = text.replace("timing:\n  - ", "timing:\n  - wall_limit_s: 30\n    ")
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    report = run_sweep(plan_sweep(*load_sweep_file(str(path))), tmp_path / "out",
                       show_progress=False)  # fmt: skip
    runs = pd.read_csv(tmp_path / "out" / "runs.csv").set_index(["kind", "solver"])
    for kind in ("tracking", "timing"):
        hung = runs.loc[(kind, "daqp")]
        assert hung["status"] == "failed"
        assert "exceeded the wall-clock guard" in hung["message"]
        assert runs.loc[(kind, "quadprog"), "status"] == "ok"
    assert len(report.failed) == 2
