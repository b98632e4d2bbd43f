"""The wall-clock guard of sweep runs: hangs and native crashes end as failed rows."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
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
    the guard starts its fork server with subprocess."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    daemon = ctx.Process(target=_guard_a_hang_in_a_daemon, args=(queue,), daemon=True)
    daemon.start()
    message = queue.get(timeout=120)
    daemon.join(10)
    assert message.startswith("exceeded the wall-clock guard of 1 s")


# -- a library's threads in the caller never reach the guarded child ------------------------
#
# A child forked from a process whose native thread pool is running inherits the pool's
# bookkeeping but not its threads, and waits for them forever. Each case below first makes the
# library start its pool in this (the caller's) process, then runs the same library guarded.


def _clarabel(n: int) -> str:
    """A dense QP of ``n`` variables with Clarabel's faer solver, which runs on rayon's pool."""
    import clarabel
    import scipy.sparse as sp

    rng = np.random.default_rng(0)
    m = rng.standard_normal((n, n))
    P = sp.csc_matrix(np.triu(m @ m.T + np.eye(n)))
    A = sp.csc_matrix(np.vstack([np.eye(n), -np.eye(n)]))
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.direct_solve_method = "faer"
    cones = [clarabel.NonnegativeConeT(2 * n)]
    solver = clarabel.DefaultSolver(P, rng.standard_normal(n), A, np.ones(2 * n), cones, settings)
    return str(solver.solve().status)


def _openblas(n: int) -> float:
    from threadpoolctl import threadpool_limits

    with threadpool_limits(2):
        a = np.random.default_rng(0).standard_normal((n, n))
        return float(np.trace(a @ a))


def _openmp(batch: int) -> float:
    """Pinocchio's inverse dynamics over a batch of states on two OpenMP threads."""
    import pinocchio as pin

    model = pin.buildSampleModelHumanoid()
    pool = pin.ModelPool(model, 2)
    q = np.tile(pin.neutral(model)[:, None], (1, batch))
    v = np.ones((model.nv, batch))
    tau = np.zeros((model.nv, batch))
    pin.rneaInParallel(2, pool, q, v, np.zeros_like(v), tau)
    return float(np.abs(tau).sum())


def _mujoco(nthread: int) -> float:
    """MuJoCo's rollout on its own thread pool."""
    import mujoco
    from mujoco import rollout

    xml = "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    datas = [mujoco.MjData(model) for _ in range(nthread)]
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    state = np.zeros((4, size))
    state[:, 3] = 1.0
    states, _ = rollout.rollout(model, datas, state, nstep=20)
    return float(states[:, -1, 3].sum())


def _dask(n: int) -> int:
    import dask

    parts = [dask.delayed(sum)(range(i)) for i in range(n)]
    return int(sum(dask.compute(*parts, scheduler="threads", num_workers=2)))


@pytest.mark.parametrize(
    ("fn", "arg"),
    [(_clarabel, 200), (_openblas, 400), (_openmp, 16), (_mujoco, 2), (_dask, 20)],
    ids=["rayon-clarabel", "openblas", "openmp-pinocchio", "mujoco", "dask-threads"],
)
def test_a_threaded_library_in_the_caller_does_not_hang_the_guarded_run(fn, arg) -> None:
    expected = fn(arg)  # the library's threads now run in this process
    t0 = time.perf_counter()
    outcome = call_with_deadline(fn, (arg,), 60)
    assert outcome.ok, outcome.message
    # the same code on the same data, but not on as many threads (the child has one BLAS thread)
    if isinstance(expected, float):
        assert outcome.value == pytest.approx(expected, rel=1e-12)
    else:
        assert outcome.value == expected
    assert time.perf_counter() - t0 < 30


def test_the_fork_server_holds_one_thread() -> None:
    from wbcbench.bench.guard import thread_count

    outcome = call_with_deadline(thread_count, (), 60)
    assert outcome.ok and outcome.value == 1  # the child of a one-threaded server


def test_a_progress_callback_reaches_the_caller() -> None:
    seen: list[tuple[int, int]] = []
    outcome = call_with_deadline(_count_slowly, (5,), 60, progress=lambda *a: seen.append(a))
    assert outcome.ok and outcome.value == 5
    assert seen and seen[-1] == (5, 5)


def _count_slowly(n: int, progress=None) -> int:
    for i in range(1, n + 1):
        time.sleep(0.1)
        progress(i, n)
    return n


def _where_and_what() -> tuple[str, str | None]:
    return os.getcwd(), os.environ.get("WBCBENCH_GUARD_TEST")


def test_the_child_sees_the_callers_folder_and_environment_now(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert call_with_deadline(_square, (1.0,), 60).ok  # the fork server is running
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("WBCBENCH_GUARD_TEST", "set after the server started")
    outcome = call_with_deadline(_where_and_what, (), 60)
    assert outcome.value == (str(tmp_path), "set after the server started")


def test_arguments_that_do_not_pickle_are_a_failed_outcome() -> None:
    outcome = call_with_deadline(_square, (lambda: 1,), 30)
    assert not outcome.ok
    assert outcome.message.startswith("the run's arguments do not pickle")


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
    solvers: [daqp]
    set: ["duration=0.05", "metrics.window=[0.0, 0.05]"]
    wall_limit_s: 0.001
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [quadprog]
    set: ["duration=0.05", "metrics.window=[0.0, 0.05]"]
timing:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [daqp]
    modes: [cold]
    ticks: 8
    warmup: 2
    probe_ticks: 4
    set: ["duration=0.3"]
    wall_limit_s: 0.001
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [quadprog]
    modes: [cold]
    ticks: 8
    warmup: 2
    probe_ticks: 4
    set: ["duration=0.3"]
"""


def test_a_run_that_hangs_becomes_a_failed_row_and_the_sweep_goes_on(tmp_path: Path) -> None:
    """The DAQP runs cannot finish within their 1 ms guard: to the guard, a hung run."""
    path = tmp_path / "sweep.yaml"
    path.write_text(SWEEP)
    report = run_sweep(plan_sweep(*load_sweep_file(str(path))), tmp_path / "out",
                       show_progress=False)  # fmt: skip
    runs = pd.read_csv(tmp_path / "out" / "runs.csv").set_index(["kind", "solver"])
    for kind in ("tracking", "timing"):
        hung = runs.loc[(kind, "daqp")]
        assert hung["status"] == "failed"
        assert "exceeded the wall-clock guard of 0.001 s" in hung["message"]
        assert runs.loc[(kind, "quadprog"), "status"] == "ok"
    assert len(report.failed) == 2
