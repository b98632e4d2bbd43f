"""The command line: sweep, tables, plots, solvers, replay."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from wbcbench.cli import main


def test_every_sweep_file_is_valid_and_a_dry_run_lists_the_runs(capsys) -> None:
    from wbcbench.bench.sweep import SWEEP_DIR, load_sweep_file

    files = sorted(SWEEP_DIR.glob("*.yaml"))
    assert {"default", "full", "reference", "smoke"} <= {f.stem for f in files}
    for path in files:
        load_sweep_file(path)  # schema only: the scenarios may be mid-edit
    assert main(["sweep", str(SWEEP_DIR / "smoke.yaml"), "--dry-run", "--out", "unused"]) == 0
    printed = capsys.readouterr().out
    assert "runs planned" in printed and "[skip: example of a recorded skip]" in printed


def test_a_bad_sweep_file_is_one_line_and_status_2(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\ntracking:\n  - solvers: [nope]\n")
    assert main(["sweep", str(bad), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {bad}: tracking[0].solvers[0]: unknown solver 'nope'")


def test_sweep_from_globs_then_reports_and_replay(tmp_path: Path, capsys) -> None:
    out = tmp_path / "res"
    args = ["sweep", "--scenario", "tocabi_stand*", "--controller", "qp_wbc", "--solver", "daqp"]
    args += ["--set", "duration=0.05", "--out", str(out), "--no-progress"]
    assert main(args) == 0
    runs = pd.read_csv(out / "runs.csv")
    assert list(runs["solver"]) == ["daqp"] and list(runs["kind"]) == ["tracking"]
    assert main(args) == 0
    assert "0 rows computed, 1 already in" in capsys.readouterr().out
    assert main(["tables", str(out)]) == 0
    assert (out / "tables" / "papers.md").exists()
    assert main(["solvers", str(out)]) == 0
    assert "No solver comparison" in (out / "solver_report.md").read_text()
    assert main(["plots", str(out)]) == 0
    assert (out / "figures" / "tracking_tocabi_stand_sway.png").exists()
    assert main(["tables", str(tmp_path / "nowhere")]) == 2


def test_replay_solves_a_dumped_problem_again(tmp_path: Path, capsys) -> None:
    from wbcbench.qp.examples import random_qp

    path = tmp_path / "p.npz"
    random_qp(1, n=12, n_eq=4, n_in=6).save(path)
    assert main(["replay", str(path), "--solver", "daqp", "--solver", "proxqp"]) == 0
    printed = capsys.readouterr().out
    assert "daqp" in printed and "proxqp" in printed and "solved" in printed


TINY_SET = ["--set", "duration=0.05", "--set", "metrics.window=[0.0, 0.05]"]


@pytest.mark.usefixtures("runs_in_process")
def test_sweep_exit_codes_retry_failed_and_force(
    tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    from wbcbench.qp.backends.daqp import DAQPSolver

    out = str(tmp_path / "out")
    args = ["sweep", "--scenario", "tocabi_stand_sway", "--controller", "qp_wbc", *TINY_SET]
    args += ["--solver", "daqp", "--solver", "quadprog", "--out", out]
    real = DAQPSolver._solve_fresh

    def raises(self, problem, guess, keep):
        raise RuntimeError("injected backend crash")

    monkeypatch.setattr(DAQPSolver, "_solve_fresh", raises)
    # (the crash is injected into the Python handle: its C++ counterpart would bypass it)
    monkeypatch.setattr(DAQPSolver, "native_solver", lambda self: None)
    assert main(args) == 1  # one row failed: the sweep says so in its exit code
    text = capsys.readouterr().out
    assert "not ok: 1 failed of 2 planned rows" in text
    assert main(args) == 1  # a rerun resumes the failed row and still reports it
    assert "0 rows computed, 2 already in" in capsys.readouterr().out

    monkeypatch.setattr(DAQPSolver, "_solve_fresh", real)
    assert main([*args, "--retry-failed"]) == 0  # only the failed row is recomputed
    assert "1 rows computed, 1 already in" in capsys.readouterr().out
    runs = pd.read_csv(Path(out) / "runs.csv")
    assert len(runs) == 2 and (runs["status"] == "ok").all()
    assert main([*args, "--force"]) == 0  # every row is recomputed, none duplicated
    assert "2 rows computed, 0 already in" in capsys.readouterr().out
    runs = pd.read_csv(Path(out) / "runs.csv")
    assert len(runs) == 2 and runs["run_id"].is_unique


def test_cli_timing_falls_back_to_a_recorder_that_stands(tmp_path: Path, capsys) -> None:
    """qp_wbc falls on the Ahn scenarios: the default chain records with lqp instead."""
    out = tmp_path / "t"
    args = ["sweep", "--scenario", "ahn_double_support", "--controller", "lqp", "--timing"]
    args += ["--solver", "osqp", "--set", "duration=2.5", "--out", str(out)]
    assert main(args) == 0
    runs = pd.read_csv(out / "runs.csv")
    assert (runs["status"] == "ok").all()
    assert (runs["mode"] == "hot").all()
    assert runs["settings"].str.contains('"recorder": "lqp"').all()


def test_list_names_each_solver_with_its_summary_and_a_named_settings_choices(capsys) -> None:
    from wbcbench.qp import available_solvers

    if "osqp_libdwbc" not in available_solvers():
        pytest.skip("osqp not installed")
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    line = next(x for x in lines if x.strip().startswith("osqp_libdwbc "))
    assert "OSQP as RC-LQP's libdwbc runs it" in line
    assert line.endswith("[tier default, mode hot only]")
    assert any(x.strip().startswith("osqp ") and "OSQP (ADMM" in x for x in lines)


def test_run_a_scenario_with_a_named_setting(tmp_path: Path, capsys) -> None:
    """Chosen by name like a backend; the CLI's default mode (cold) is not one it runs at."""
    from wbcbench.qp import available_solvers

    if "osqp_libdwbc" not in available_solvers():
        pytest.skip("osqp not installed")
    out = str(tmp_path / "run")
    args = ["run", "tocabi_stand_sway", "--controller", "qp_wbc", "--solver", "osqp_libdwbc"]
    args += [*TINY_SET, "--out", out, "--no-progress"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: osqp_libdwbc does not run at mode 'cold'; valid choices: hot")
    assert main([*args, "--mode", "hot"]) == 0
    runs = pd.read_csv(Path(out) / "runs.csv")
    assert runs[["solver", "mode", "status"]].values.tolist() == [["osqp_libdwbc", "hot", "ok"]]


def test_a_run_row_records_its_overrides_duration_and_when(tmp_path: Path, capsys) -> None:
    import json

    out = str(tmp_path / "run")
    args = ["run", "tocabi_stand_sway", "--solver", "daqp", *TINY_SET, "--out", out]
    assert main([*args, "--no-progress"]) == 0
    assert "sim_duration_s" in capsys.readouterr().out  # the summary says how long each ran
    settings = json.loads(pd.read_csv(Path(out) / "runs.csv")["settings"].iloc[0])
    assert settings["overrides"] == [s for s in TINY_SET if s != "--set"]
    assert settings["duration_s"] == pytest.approx(float(TINY_SET[1].split("=")[1]))
    assert {"date", "host", "cpu"} <= set(settings)


def test_compare_marks_changes_outside_the_noise(tmp_path: Path, capsys) -> None:
    import shutil

    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        "version: 1\ntracking:\n  - scenarios: [tocabi_stand_sway]\n    controllers: [qp_wbc]\n"
        "    solvers: [daqp]\n    set: ['duration=0.05', 'metrics.window=[0.0, 0.05]']\n"
        "timing:\n  - scenarios: [tocabi_stand_sway]\n    controllers: [qp_wbc]\n"
        "    solvers: [daqp, quadprog]\n    modes: [hot]\n    ticks: 30\n    warmup: 5\n"
        "    set: ['duration=0.3']\n"
    )
    a, b = tmp_path / "A", tmp_path / "B"
    assert main(["sweep", str(sweep), "--out", str(a), "--no-progress"]) == 0
    shutil.copytree(a, b)
    metrics = pd.read_csv(b / "metrics.csv")
    runs = pd.read_csv(b / "runs.csv")
    slow = runs[(runs["kind"] == "timing") & (runs["solver"] == "daqp")]["run_id"].iloc[0]
    timed = (metrics["run_id"] == slow) & metrics["metric"].str.startswith("t_total_median")
    metrics.loc[timed, "value"] *= 3.0  # daqp three times slower, intervals apart
    metrics.loc[metrics["metric"] == "err_mean", "value"] *= 1.01
    metrics.to_csv(b / "metrics.csv", index=False)
    capsys.readouterr()
    assert main(["compare", str(a), str(b), "--out", str(tmp_path / "c.md")]) == 0
    out = capsys.readouterr().out
    assert "1 slower, 1 within noise" in out or "1 within noise, 1 slower" in out
    assert (tmp_path / "c.md").read_text() + "\n" == out
    tracking = out[out.index("## Tracking") :]
    assert "changed" in tracking and "same" not in tracking.splitlines()[2]
    timing = out[out.index("## Timing") : out.index("## Tracking")]
    assert "| daqp " in timing and "slower" in timing
