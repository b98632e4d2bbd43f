"""recommendations.md: the fastest within budget, the most accurate and the most robust
controller × solver per robot and scenario family, from synthetic rows with known answers."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from wbcbench.report.load import Results
from wbcbench.report.recommend import family_of, recommendations, write_recommendations

SCENARIO = "tocabi_stand_sway"  # control_rate 1000 Hz: a 1000 µs budget


def _run(
    run_id: str, kind: str, controller: str, solver: str, status: str = "ok", **kw: object
) -> dict:
    return {
        "run_id": run_id,
        "scenario": SCENARIO,
        "robot": "tocabi_like",
        "controller": controller,
        "solver": solver,
        "tier": "default",
        "mode": "hot",
        "impl": "native",
        "status": status,
        "kind": kind,
        "ticks": kw.get("ticks", 100),
        "failures": kw.get("failures", 0),
    }


def _metric(run_id: str, task: str, metric: str, value: float) -> dict:
    return {"run_id": run_id, "task": task, "metric": metric, "value": value, "unit": "-"}


def synthetic(tmp_path: Path) -> Results:
    runs = [
        # timing: `a` is fastest but its p99 misses the budget; `b` fell in closed loop
        _run("t_a", "timing", "qp_wbc", "fast"),
        _run("t_b", "timing", "lqp", "daqp"),
        _run("t_c", "timing", "hqp", "daqp"),
        _run("t_d", "timing", "hqp", "osqp", status="failed"),
        # tracking
        _run("r_b", "tracking", "lqp", "quadprog", status="fell"),
        _run("r_c", "tracking", "hqp", "quadprog", failures=3),
        _run("r_e", "tracking", "osf_hqp", "quadprog"),
    ]
    metrics = [
        _metric("t_a", "*", "t_total_median_us", 100.0),
        _metric("t_a", "*", "t_total_p99_us", 1500.0),
        _metric("t_b", "*", "t_total_median_us", 200.0),
        _metric("t_b", "*", "t_total_p99_us", 400.0),
        _metric("t_c", "*", "t_total_median_us", 300.0),
        _metric("t_c", "*", "t_total_p99_us", 500.0),
        _metric("t_d", "*", "t_total_median_us", 10.0),
        _metric("t_d", "*", "t_total_p99_us", 20.0),
        # hqp: CoM 1e-6 (best), hands 4e-3 (4× the best); osf_hqp: CoM 2e-6, hands 1e-3:
        # geometric means 2 and √2; lqp fell with the best errors of all
        _metric("r_c", "com", "err_mean", 1e-6),
        _metric("r_c", "hands", "err_mean", 4e-3),
        _metric("r_e", "com", "err_mean", 2e-6),
        _metric("r_e", "hands", "err_mean", 1e-3),
        _metric("r_b", "com", "err_mean", 1e-9),
        _metric("r_b", "hands", "err_mean", 1e-9),
    ]
    return Results(tmp_path, pd.DataFrame(runs), pd.DataFrame(metrics), {"cpu": "test CPU"})


def test_each_pick_is_the_known_answer(tmp_path: Path) -> None:
    frame = recommendations(synthetic(tmp_path))
    assert len(frame) == 1
    row = frame.iloc[0]
    assert (row["robot"], row["family"]) == ("tocabi_like", "standing sway")
    fastest = row["fastest (p99 within budget)"]
    # qp_wbc misses the budget, hqp × osqp failed, lqp fell in closed loop: hqp × daqp
    assert fastest.startswith("`hqp` (native) × `daqp` (default, hot): median 300 µs, p99 500 µs")
    assert "next `lqp` (native) × `daqp` (default, hot): 200 µs" in fastest
    assert row["most accurate"].startswith(
        "`osf_hqp` (native) × `quadprog` (default, hot): errors 1.41×"
    )
    # no dumped QPs: the closed-loop ticks without a failure; hqp failed 3, lqp fell
    assert row["most robust"] == (
        "`osf_hqp` × `quadprog`: 100.0 % of 100 closed-loop ticks without a failure"
    )
    assert (
        "1 failed run left out" in row["caveats"] and "fell on a scenario: `lqp`" in row["caveats"]
    )


def test_the_page_is_written_beside_the_results(tmp_path: Path) -> None:
    path = write_recommendations(tmp_path, synthetic(tmp_path))
    text = path.read_text()
    assert path == tmp_path / "recommendations.md"
    assert text.startswith("# Which controller and solver to use")
    assert "## tocabi_like: standing sway" in text and "test CPU" in text


def test_families_group_the_papers_scenarios() -> None:
    assert family_of("lee2021access_s3_conflict") == family_of("lee2021access_table3")
    assert family_of("talos_stand_sway") == family_of("g1_stand_sway") == "standing sway"
    assert family_of("my_scenario") == "my_scenario"


def test_a_perturbed_run_is_no_evidence_of_accuracy_or_of_a_fall(tmp_path: Path) -> None:
    """A robustness run (its settings state perturbations) that fell, or tracked better than
    all, changes no pick: it is judged in the robustness tables."""
    import json

    base = synthetic(tmp_path)
    perturbed = {
        **_run("r_p", "tracking", "hqp", "daqp", status="fell"),
        "settings": json.dumps({"perturbations": {"sensing": {"delay": 5}}}),
    }
    runs = pd.concat([base.runs.assign(settings="{}"), pd.DataFrame([perturbed])])
    metrics = pd.concat([base.metrics, pd.DataFrame([_metric("r_p", "com", "err_mean", 1e-12)])])
    row = recommendations(Results(tmp_path, runs, metrics, base.provenance)).iloc[0]
    expected = recommendations(base).iloc[0]
    assert row["fastest (p99 within budget)"] == expected["fastest (p99 within budget)"]
    assert row["most accurate"] == expected["most accurate"]
    assert "`hqp`" not in row["caveats"].split("fell on a scenario:")[-1]
