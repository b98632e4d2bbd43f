"""summary.md opens with the verdict counts, the failed rows and the suspect runs; a busy
machine is said once per sweep."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from wbcbench.bench.results import ResultsStore
from wbcbench.bench.sweep import SweepReport
from wbcbench.report.summary import SUSPECT_FACTOR, suspect_lines, suspects, write_summary


def _run(rid: str, controller: str, status: str = "ok", kind: str = "tracking", **extra) -> dict:
    row = dict(
        run_id=rid,
        scenario="tocabi_stand_sway",
        scenario_hash="h1",
        robot="tocabi_like",
        controller=controller,
        controller_config="{}",
        solver="quadprog",
        status=status,
        kind=kind,
        message="",
        sim_duration_s=0.5,
        settings="{}",
    )
    row.update(extra)
    return row


def _err(rid: str, task: str, value: float, unit: str = "rad") -> dict:
    return dict(run_id=rid, task=task, metric="err_mean", value=value, unit=unit)


def _store(folder: Path) -> ResultsStore:
    """Four controllers on one scenario: posture errors 0.9–1.0 rad, to_osf's 3.8 rad; CoM
    errors at round-off, one 100× the others but under the floor; a failed timing row."""
    store = ResultsStore(folder)
    posture = {"qp_wbc": 0.91, "lqp": 1.0, "hqp": 0.95, "to_osf": 3.78}
    for i, (controller, value) in enumerate(posture.items()):
        com = 1e-4 if controller == "lqp" else 1e-6
        store.add_run(
            _run(f"r{i}", controller),
            [_err(f"r{i}", "posture", value), _err(f"r{i}", "com", com, "m")],
        )
    # another scenario's run: not part of this one's usual error
    store.add_run(
        _run("other", "to_osf", scenario="g1_stand_sway", scenario_hash="h2"),
        [_err("other", "posture", 0.01)],
    )
    message = "40 of 40 ticks failed; first: tick 0: level L3: osqp: max_iter_reached"
    store.add_run(_run("t1", "osf_hqp", "failed", "timing", solver="osqp", message=message), [])
    return store


def test_a_run_ok_with_an_error_far_beyond_its_scenarios_usual_is_suspect(tmp_path: Path) -> None:
    store = _store(tmp_path)
    odd = suspects(store.runs(), store.metrics())
    assert odd[["controller", "task"]].values.tolist() == [["to_osf", "posture"]]
    row = odd.iloc[0]
    assert row["usual"] == 0.95 and row["others"] == 3  # the median of qp_wbc, lqp and hqp
    assert row["factor"] > SUSPECT_FACTOR
    assert suspect_lines(odd) == [
        "  suspect: tocabi_stand_sway · to_osf · quadprog: posture error 3.78 rad, 3.98× the "
        "usual 0.95 (median of 3 other runs)"
    ]


def test_summary_opens_with_verdict_counts_failed_rows_and_suspects(tmp_path: Path) -> None:
    store = _store(tmp_path)
    (tmp_path / "tables").mkdir()
    verdicts = pd.DataFrame({"verdict": ["reproduced", "reproduced", "inconclusive", "not run"]})
    verdicts.to_csv(tmp_path / "tables" / "verdicts.csv", index=False)
    text = write_summary(tmp_path, store.runs(), store.metrics()).read_text()
    assert text.splitlines()[2] == (
        "**Paper verdicts:** 4: 2 reproduced, 0 partly, 0 not, 1 inconclusive, 1 not run "
        "(`tables/papers.md`)."
    )
    assert "- 5 closed-loop runs: 5 ok" in text and "- 1 timing rows: 1 failed" in text
    failed = text[text.index("## Failed rows") : text.index("## Suspect runs")]
    assert "| timing | tocabi_stand_sway | osf_hqp      | osqp     | failed   | 40 of 40" in failed
    suspect = text[text.index("## Suspect runs") : text.index("## Closed-loop runs")]
    assert "to_osf" in suspect and "3.98" in suspect and "lqp" not in suspect
    compact = text[text.index("## Closed-loop runs") :]
    header = next(line for line in compact.splitlines() if line.startswith("| scenario"))
    assert header.count("|") == 8  # seven columns, not one per task
    assert "posture 3.78 rad (3.9× usual)" in compact  # its median includes itself


def test_a_busy_machine_is_one_line_with_the_worst_load() -> None:
    report = SweepReport(timed=574)
    assert report.busy_line() == ""
    report.busy = [
        {"busy": True, "load_1min": 3.1, "other_load_per_core": 1.05},
        {"busy": True, "load_1min": 6.27, "other_load_per_core": 2.64},
    ]
    line = report.busy_line()
    assert "\n" not in line
    assert line.startswith(
        "warning: 2 of 574 timing rows were timed on a busy machine (worst: load 6.27, other "
        "work 2.64 per core (load), above 0.5)"
    )
    # a row whose CPU was watched is judged on that, not on its trailing load average
    report.busy.append(
        {"busy": True, "load_1min": 2.0, "busy_basis": "cpu", "other_cpu_per_core": 0.97}
    )
    report.busy[0]["other_load_per_core"] = report.busy[1]["other_load_per_core"] = 0.6
    assert "(worst: load 2, other work 0.97 per core (CPU), above 0.5)" in report.busy_line()
