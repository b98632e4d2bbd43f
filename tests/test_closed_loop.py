"""Closed-loop runs in MuJoCo, the results store and the `run` command."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from wbcbench.bench.results import ResultsStore
from wbcbench.bench.runner import execute
from wbcbench.cli import main
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import load_scenario
from wbcbench.sim.closed_loop import run_closed_loop


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["tocabi_stand_sway", "comanplus_stand_sway"])
def test_stand_sway_tracks_the_com_within_half_a_millimetre(scenario: str, tmp_path: Path) -> None:
    loaded = load_scenario(scenario)
    store = ResultsStore(tmp_path)
    record = execute(plan_run(loaded, controller="qp_wbc", solver="proxqp"), store)
    assert record is not None
    assert record.row["status"] == "ok", record.row["message"]
    assert not record.row["fell"]
    metrics = {(m["task"], m["metric"]): m["value"] for m in record.metrics}
    assert metrics[("com", "err_mean")] < 0.5e-3
    assert metrics[("*", "torque_limit_excess")] == 0.0
    assert metrics[("*", "solve_failures")] == 0.0
    # the commanded wrenches respect the cone; the simulated ones carry the load
    assert metrics[("*", "cop_violation_pred")] <= 1e-6
    # the simulated contact, over the window and while loaded: finite and within the box
    for key in ("cop", "friction", "yaw"):
        assert np.isfinite(metrics[("*", f"{key}_violation_sim")]), key
    assert metrics[("*", "cop_violation_sim")] <= 1e-3
    assert metrics[("*", "unloaded_contact_ticks_sim")] == 0
    log = pd.read_parquet(next((tmp_path / "logs").glob("*.parquet")))
    simulated = log["wrench_sim.l_sole.fz"] + log["wrench_sim.r_sole.fz"]
    predicted = log["wrench_pred.l_sole.fz"] + log["wrench_pred.r_sole.fz"]
    assert np.median(simulated) == pytest.approx(np.median(predicted), rel=0.02)


def test_motors_too_weak_to_stand_end_in_a_fall() -> None:
    # at 2 % of the torque limits the QP is infeasible; with the failures tolerated it falls
    loaded = load_scenario(
        "tocabi_stand_sway",
        ("duration=3", "limits.torque_scale=0.02", "sim.max_consecutive_failures=5000"),
    )
    result = run_closed_loop(plan_run(loaded, "qp_wbc", "proxqp"))
    assert result.status in ("fell", "failed")
    assert result.fell or result.failures > 0


def test_solver_failures_hold_the_last_torque_and_are_counted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """After 20 good ticks every solve fails: the torque is held, then the run stops."""
    from wbcbench.qp import Solution, SolutionStatus, base

    loaded = load_scenario("tocabi_stand_sway", ("duration=0.2", "sim.max_consecutive_failures=15"))
    real_solve = base.QPSolver.solve
    calls = {"n": 0}

    def flaky(self, problem, x0=None, raise_on_failure=False, **kwargs):
        calls["n"] += 1
        if calls["n"] <= 20:
            return real_solve(self, problem, x0, raise_on_failure, **kwargs)
        return Solution(SolutionStatus.FAILED, solver="proxqp", message="injected failure")

    monkeypatch.setattr(base.QPSolver, "solve", flaky)
    result = run_closed_loop(plan_run(loaded, "qp_wbc", "proxqp"))
    assert result.status == "failed"
    assert result.failures == 15
    assert "15 failed ticks in a row: proxqp: failed: injected failure" in result.message
    log = result.log.arrays()
    assert list(log["ok"][19:21]) == [1.0, 0.0]
    # the held torque is the last good one
    tau = np.column_stack([log[f"tau.{j}"] for j in result.robot.joint_names])
    np.testing.assert_array_equal(tau[20:], np.repeat(tau[19:20], len(tau) - 20, axis=0))


def test_a_torque_beyond_its_limit_fails_the_tick(monkeypatch: pytest.MonkeyPatch) -> None:
    """After 20 good ticks the controller commands twice the knee's limit: a failed tick, as a
    solver failure is (the last torque held), though the step reports success."""
    from wbcbench.runs import Run

    loaded = load_scenario("tocabi_stand_sway", ("duration=0.2", "sim.max_consecutive_failures=15"))
    real_build = Run.make_controller

    def build(*args, **kwargs):
        controller = real_build(*args, **kwargs)
        real_step, calls = controller.step, {"n": 0}
        knee = controller.ctx.robot.joint_index("L_Knee")

        def step(state, t):
            out = real_step(state, t)
            calls["n"] += 1
            if calls["n"] > 20:
                out.tau[knee] = 2 * controller.ctx.tau_max[knee]
            return out

        controller.step = step
        return controller

    monkeypatch.setattr(Run, "make_controller", build)
    result = run_closed_loop(plan_run(loaded, "qp_wbc", "proxqp"))
    assert result.status == "failed" and result.failures == 15
    limit = result.tau_max[result.robot.joint_index("L_Knee")]
    assert result.message == (
        f"15 failed ticks in a row: commanded torque {2 * limit:.4g} N·m on L_Knee beyond its "
        f"limit {limit:.4g} N·m"
    )
    log = result.log.arrays()
    assert list(log["ok"][19:21]) == [1.0, 0.0]
    assert np.all(np.abs(log["tau.L_Knee"]) <= limit)


def test_run_command_writes_tables_and_resumes(tmp_path: Path, capsys) -> None:
    out = tmp_path / "res"
    args = [
        "run",
        "tocabi_stand_sway",
        "--set",
        "duration=0.3",
        "--solver",
        "proxqp",
        "--solver",
        "daqp",
        "--out",
        str(out),
        "--no-progress",
    ]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "qp_wbc" in printed and "daqp" in printed
    runs = pd.read_csv(out / "runs.csv")
    assert {"scenario", "robot", "controller", "solver", "status", "fell"} <= set(runs.columns)
    assert list(runs["solver"]) == ["proxqp", "daqp"]
    metrics = pd.read_csv(out / "metrics.csv")
    assert {"controller", "solver", "task", "metric", "value", "unit"} <= set(metrics.columns)
    names = set(metrics["metric"])
    for name in (
        "err_mean",
        "err_max",
        "t_total_median_us",
        "t_solve_median_us",
        "t_solve_internal_median_us",
    ):
        assert name in names
    assert (out / "runs.parquet").exists() and (out / "provenance.json").exists()
    assert len(list((out / "logs").glob("*.parquet"))) == 2
    # a rerun resumes: nothing recomputed
    assert main(args) == 0
    assert "skipped" in capsys.readouterr().out
    assert len(pd.read_csv(out / "runs.csv")) == 2


def test_run_log_pads_columns_a_tick_does_not_report() -> None:
    from wbcbench.sim.closed_loop import RunLog

    log = RunLog()
    log.add({"t": 0.0, "diag.a": 1.0})
    log.add({"t": 0.001})
    log.add({"t": 0.002, "diag.b": 2.0})
    arrays = log.arrays()
    assert {k: len(v) for k, v in arrays.items()} == {"t": 3, "diag.a": 3, "diag.b": 3}
    np.testing.assert_array_equal(arrays["diag.a"], [1.0, np.nan, np.nan])
    np.testing.assert_array_equal(arrays["diag.b"], [np.nan, np.nan, 2.0])


def test_cross3_is_the_cross_product() -> None:
    from wbcbench.sim.closed_loop import cross3

    rng = np.random.default_rng(3)
    for _ in range(200):
        a, b = rng.normal(size=3) * 10.0 ** rng.integers(-3, 4), rng.normal(size=3)
        np.testing.assert_allclose(
            cross3(a, b), np.cross(a, b), rtol=0, atol=1e-14 * np.abs(a).max()
        )
    e = np.eye(3)
    np.testing.assert_array_equal(cross3(e[0], e[1]), e[2])
