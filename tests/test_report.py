"""Paper tables, the solver report and the figures, on a small sweep and on synthetic rows."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from wbcbench.bench.results import ResultsStore
from wbcbench.bench.sweep import load_sweep_file, plan_sweep, run_sweep
from wbcbench.report import load_results
from wbcbench.report import papers as P
from wbcbench.report.plots import write_plots
from wbcbench.report.solvers import write_report
from wbcbench.report.tables import TABLES, build_tables, write_tables

SMOKE = Path(__file__).resolve().parents[1] / "sweeps" / "smoke.yaml"


@pytest.fixture(scope="module")
def smoke(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("smoke")
    run_sweep(plan_sweep(*load_sweep_file(SMOKE)), out, show_progress=False)
    return out


def test_load_results_reads_every_table_of_a_sweep(smoke: Path) -> None:
    res = load_results(smoke)
    assert set(res.runs["kind"]) == {"tracking", "timing"}
    assert {"run_id", "task", "metric", "value", "unit"} <= set(res.metrics.columns)
    tracking = res.of_kind("tracking")
    log = res.log(tracking["run_id"].iloc[0])
    assert "t" in log.columns and any(c.startswith("err.") for c in log.columns)
    assert res.provenance["cpu"] in res.machine
    assert not res.qp_solves.empty
    # timing rows carry per-stage statistics and the deadline-miss rate
    timing = res.of_kind("timing")
    ok = timing[(timing["status"] == "ok") & (timing["robot"] != "-")]
    names = set(res.metrics[res.metrics["run_id"] == ok["run_id"].iloc[0]]["metric"])
    for stage in ("dynamics", "build", "solve", "total"):
        for stat in ("median_us", "iqr_us", "p99_us", "max_us"):
            assert f"t_{stage}_{stat}" in names
        assert f"t_{stage}_miss_rate" in names


def test_every_table_is_written_and_missing_ones_say_which_runs_to_make(smoke: Path) -> None:
    index = write_tables(smoke)
    text = index.read_text()
    for name in TABLES:
        assert (smoke / "tables" / f"{name}.md").exists()
    fig1 = pd.read_csv(smoke / "tables" / "rqr_fig1.csv")
    assert list(fig1["N"]) == [10, 40]
    assert "full_qr / reduced_qr" in fig1.columns
    missing = [t for t in build_tables(smoke) if t.frame is None]
    assert all(t.missing for t in missing)
    assert "*No results yet.*" in text or not missing
    assert load_results(smoke).provenance["cpu"] in text


def test_osf_hqp_table_puts_the_papers_ratio_beside_ours(tmp_path: Path) -> None:
    """Synthetic timing rows: conventional levels 10× the proposed ones."""
    store = ResultsStore(tmp_path)
    for controller, scale in (("hqp", 10.0), ("osf_hqp", 1.0)):
        rid = f"{controller}-run"
        row = dict(
            run_id=rid,
            scenario="lee2021iros_table1",
            controller=controller,
            controller_config="{}",
            solver="qpoases",
            mode="hot",
            status="ok",
            kind="timing",
        )
        metrics = [
            dict(run_id=rid, task=f"level{i}", metric=m, value=scale * i, unit="us")
            for i in range(1, 6)
            for m in ("t_solve_mean_us", "t_solve_min_us", "t_solve_max_us")
        ]
        metrics += [
            dict(run_id=rid, task="*", metric="t_solve_mean_us", value=scale * 15, unit="us"),
            dict(run_id=rid, task="*", metric="t_total_mean_us", value=scale * 40, unit="us"),
        ]
        store.add_run(row, metrics)
    table = TABLES["osf_hqp_table3"](load_results(tmp_path))
    assert table.frame is not None
    frame = table.frame.set_index("level")
    assert frame.loc["T4", "ours ratio"] == pytest.approx(10.0)
    assert frame.loc["total", "paper ratio"] == pytest.approx(9.263 / 0.303)
    assert frame.loc["T2", "paper conv. [ms]"] == P.OSF_HQP_TABLE3["conventional"][1]
    assert frame.loc["T3", "ours OSF-HQP [ms]"] == pytest.approx(0.003)


def test_solver_report_states_machine_versions_and_limitations(smoke: Path) -> None:
    path = write_report(smoke)
    assert path is not None
    text = path.read_text()
    for part in ("CPU", "Python", "## Solvers", "## Known limitations", "Tier `mid`"):
        assert part in text
    summary = pd.read_csv(smoke / "solver_summary.csv")
    assert set(summary["solver"]) == {"proxqp", "daqp", "osqp"}
    assert set(summary["mode"]) == {"cold", "hot"}
    assert summary["success [%]"].between(0, 100).all()


def test_figures_are_written_as_png_and_svg(smoke: Path) -> None:
    paths = write_plots(smoke)
    names = {p.name for p in paths}
    for stem in ("tracking_tocabi_stand_sway", "levels", "solvers_success", "rqr_fig1"):
        assert f"{stem}.png" in names and f"{stem}.svg" in names
    assert all(p.stat().st_size > 1000 for p in paths)
