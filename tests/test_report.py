"""Paper tables, the solver report and the figures, on a small sweep and on synthetic rows."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from wbcbench import _native
from wbcbench.bench.results import ResultsStore
from wbcbench.bench.sweep import load_sweep_file, plan_sweep, run_sweep
from wbcbench.report import load_results
from wbcbench.report import papers as P
from wbcbench.report.plots import write_plots
from wbcbench.report.solvers import write_report
from wbcbench.report.tables import TABLES, build_tables, write_tables
from wbcbench.scenarios.load import LoadedScenario

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
    assert "full_qr / reduced_qr (python)" in fig1.columns
    assert fig1["ordering (python)"].str.contains("Fig. 1").all()
    if _native.BUILT:
        assert "svd native median [µs]" in fig1.columns
        assert "svd / reduced_qr (native)" in fig1.columns
    missing = [t for t in build_tables(smoke) if t.frame is None]
    assert all(t.missing for t in missing)
    assert "*No results yet.*" in text or not missing
    assert load_results(smoke).provenance["cpu"] in text


def test_osf_hqp_table_puts_the_papers_ratio_beside_ours(tmp_path: Path) -> None:
    """Synthetic timing rows: conventional levels 10× the proposed ones."""
    store = ResultsStore(tmp_path)
    for controller, scale in (("hqp", 10.0), ("osf_hqp", 1.0)):
        rid = f"{controller}-run"
        row = _timing_row(rid, "lee2021iros_table1", controller, solver="qpoases")
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


def test_osf_hqp_per_backend_divides_times_of_one_backend(tmp_path: Path) -> None:
    """qpOASES times both controllers (10×), DAQP both (4×), OSQP only the conventional one:
    one facet per backend that timed both, and no ratio across backends."""
    store = ResultsStore(tmp_path)
    for controller, solver, scale in (
        ("hqp", "qpoases", 10.0),
        ("osf_hqp", "qpoases", 1.0),
        ("hqp", "daqp", 4.0),
        ("osf_hqp", "daqp", 1.0),
        ("hqp", "osqp", 2.0),
    ):
        rid = f"{controller}-{solver}"
        row = _timing_row(rid, "lee2021iros_table1", controller, solver=solver)
        metrics = [
            dict(run_id=rid, task=f"level{i}", metric="t_solve_mean_us", value=scale * i, unit="us")
            for i in range(1, 6)
        ]
        metrics.append(
            dict(run_id=rid, task="*", metric="t_solve_mean_us", value=scale * 15, unit="us")
        )
        store.add_run(row, metrics)
    table = TABLES["osf_hqp_backends"](load_results(tmp_path))
    assert table.frame is not None
    frame = table.frame.set_index(["backend", "level"])
    assert set(table.frame["backend"]) == {"qpoases · hot", "daqp · hot"}
    assert frame.loc[("qpoases · hot", "T3"), "ratio"] == pytest.approx(10.0)
    assert frame.loc[("daqp · hot", "total"), "ratio"] == pytest.approx(4.0)


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


def _timing_row(rid: str, scenario: str, controller: str, **extra: object) -> dict:
    row = dict(
        run_id=rid,
        scenario=scenario,
        robot="tocabi_like",
        controller=controller,
        controller_config="{}",
        solver="osqp",
        mode="hot",
        status="ok",
        kind="timing",
        settings='{"kind": "timing", "recorder": "lqp"}',
    )
    row.update(extra)
    return row


def _stages(rid: str, **values: float) -> list[dict]:
    return [
        dict(run_id=rid, task="*", metric=f"t_{name}_us", value=value, unit="us")
        for name, value in values.items()
    ]


def test_rc_lqp_table3_has_both_supports_every_column_and_the_ratios(tmp_path: Path) -> None:
    """Synthetic rows: the lqp-recorded runs win over a qp_wbc-recorded decoy."""
    store = ResultsStore(tmp_path)
    for support in ("double", "single"):
        scenario = f"ahn_{support}_support"
        store.add_run(
            _timing_row(f"{support}-lqp", scenario, "lqp"),
            _stages(f"{support}-lqp", total_mean=3000.0, total_max=6000.0, dynamics_mean=100.0),
        )
        store.add_run(
            _timing_row(f"{support}-rc", scenario, "rc_lqp"),
            _stages(
                f"{support}-rc",
                total_mean=1500.0,
                total_max=2000.0,
                dynamics_mean=100.0,
                reduced_mean=20.0,
                lqp1_mean=600.0,
                lqp2_mean=300.0,
            ),
        )
    decoy = _timing_row("decoy", "ahn_single_support", "rc_lqp", settings='{"recorder": "qp_wbc"}')
    store.add_run(decoy, _stages("decoy", total_mean=1.0, total_max=1.0))
    table = TABLES["rc_lqp_table3"](load_results(tmp_path))
    assert table.frame is not None
    frame = table.frame.set_index(["support", "method"])
    prop = frame.loc[("double", "proposed (rc_lqp)")]
    assert prop["ours avg [µs]"] == 1500.0 and prop["paper avg [µs]"] == 981
    assert prop["ours max [µs]"] == 2000.0 and prop["paper max [µs]"] == 1203
    assert prop["ours dyn [µs]"] == 120.0 and prop["paper dyn [µs]"] == 34
    assert prop["ours LQP1 [µs]"] == 600.0 and prop["paper LQP1 [µs]"] == 579
    assert prop["ours LQP2 [µs]"] == 300.0 and prop["paper LQP2 [µs]"] == 273
    conv = frame.loc[("single", "conventional (lqp)")]
    assert conv["ours avg [µs]"] == 3000.0 and conv["paper avg [µs]"] == 1834
    assert pd.isna(conv["ours LQP1 [µs]"])
    assert frame.loc[("single", "proposed (rc_lqp)"), "ours avg [µs]"] == 1500.0  # not the decoy
    for support in ("double", "single"):
        ratio = frame.loc[(support, "ratio lqp / rc_lqp")]
        assert ratio["ours avg [µs]"] == pytest.approx(2.0)
        assert ratio["ours max [µs]"] == pytest.approx(3.0)
    assert frame.loc[("double", "ratio lqp / rc_lqp"), "paper avg [µs]"] == pytest.approx(
        2176 / 981
    )
    assert frame.loc[("single", "ratio lqp / rc_lqp"), "paper max [µs]"] == pytest.approx(
        2119 / 811
    )


def test_rc_lqp_table3_puts_the_papers_osqp_setting_beside_osqp_hot(tmp_path: Path) -> None:
    """With runs of both, each support has the paper's way (osqp_libdwbc) first, then osqp,
    each with its own ratio row."""
    store = ResultsStore(tmp_path)
    for support in ("double", "single"):
        scenario = f"ahn_{support}_support"
        for solver, conv, prop in (("osqp", 3000.0, 1500.0), ("osqp_libdwbc", 4000.0, 1000.0)):
            for controller, total in (("lqp", conv), ("rc_lqp", prop)):
                rid = f"{support}-{solver}-{controller}"
                store.add_run(
                    _timing_row(rid, scenario, controller, solver=solver),
                    _stages(rid, total_mean=total, total_max=total),
                )
    table = TABLES["rc_lqp_table3"](load_results(tmp_path))
    assert table.frame is not None
    frame = table.frame
    double = frame[frame["support"] == "double"]
    assert double[["solver", "method"]].values.tolist() == [
        ["osqp_libdwbc", "conventional (lqp)"],
        ["osqp_libdwbc", "proposed (rc_lqp)"],
        ["osqp_libdwbc", "ratio lqp / rc_lqp"],
        ["osqp", "conventional (lqp)"],
        ["osqp", "proposed (rc_lqp)"],
        ["osqp", "ratio lqp / rc_lqp"],
    ]
    ratios = frame[frame["method"] == "ratio lqp / rc_lqp"].set_index(["support", "solver"])
    assert ratios.loc[("single", "osqp_libdwbc"), "ours avg [µs]"] == pytest.approx(4.0)
    assert ratios.loc[("single", "osqp"), "ours avg [µs]"] == pytest.approx(2.0)
    assert any("osqp_libdwbc" in note for note in table.notes)


def test_rc_lqp_dof_table_has_one_row_per_robot_with_both_medians(tmp_path: Path) -> None:
    store = ResultsStore(tmp_path)
    medians = {"tocabi_dof20": (800.0, 400.0), "tocabi_dof45": (4000.0, 1000.0)}
    for robot, (conv, prop) in medians.items():
        for controller, value in (("lqp", conv), ("rc_lqp", prop)):
            rid = f"{robot}-{controller}"
            row = _timing_row(rid, "ahn_dof_scaling", controller, robot=robot)
            store.add_run(row, _stages(rid, total_median=value))
    failed = _timing_row(
        "fail", "ahn_dof_scaling", "lqp", robot="tocabi_dof29", status="failed", message="boom"
    )
    store.add_run(failed, _stages("fail", total_median=2000.0))
    table = TABLES["rc_lqp_dof"](load_results(tmp_path))
    assert table.frame is not None
    frame = table.frame.set_index("DoF")
    assert list(frame.index) == [20, 29, 45]
    assert frame.loc[20, "ours lqp median [µs]"] == 800.0
    assert frame.loc[45, "ours rc_lqp median [µs]"] == 1000.0
    assert frame.loc[20, "ours ratio"] == pytest.approx(2.0)
    assert frame.loc[45, "ours ratio"] == pytest.approx(4.0)
    assert frame.loc[20, "paper ratio"] == pytest.approx(754 / 571)
    assert frame.loc[45, "paper ratio"] == pytest.approx(4081 / 1319)
    assert frame.loc[20, "status"] == "ok"
    assert frame.loc[29, "status"].startswith("lqp: failed") and "boom" in frame.loc[29, "status"]
    assert pd.isna(frame.loc[29, "ours ratio"])


def _s2_row(loaded: LoadedScenario, rid: str, config: str, **extra: object) -> dict:
    """A to_osf tracking row of Scenario #2 (19 s, ok unless ``extra`` says otherwise)."""
    row = dict(
        run_id=rid,
        scenario=loaded.name,
        scenario_hash=loaded.hash,
        controller="to_osf",
        controller_config=config,
        solver="proxqp",
        mode="cold",
        status="ok",
        sim_duration_s=19.0,
        kind="tracking",
    )
    row.update(extra)
    return row


def test_to_osf_s2_ratio_of_total_amendments_with_the_run_status(tmp_path: Path) -> None:
    """Priority weighting amends 3 per tick, identical 0.5; the identical run fell at 10 s."""
    import numpy as np

    from wbcbench.scenarios.load import load_scenario

    loaded = load_scenario("lee2021access_s2_feasibility")
    store = ResultsStore(tmp_path)
    store.record_scenario(loaded.name, loaded.hash, str(loaded.path))
    for rid, config, amend, end, status in (
        ("prio", "{}", 1.5, 19.0, "ok"),
        ("ident", '{"weights": [10000000.0]}', 0.25, 10.0, "fell"),
    ):
        t = np.arange(0.0, end, 0.005)
        log = {"t": t, "diag.amend.com": np.full(t.size, amend)}
        log["diag.amend.r_hand_pos"] = np.where(t >= 9.0, amend, 100.0)
        message = "base height 0.3 m at t = 10.000 s" if status == "fell" else ""
        row = _s2_row(loaded, rid, config, status=status, message=message, sim_duration_s=end)
        store.add_run(row, [], log)
    shortened = dict(row, run_id="short", status="ok", scenario_hash="other", sim_duration_s=0.5)
    store.add_run(shortened, [], {"t": np.zeros(1), "diag.amend.com": np.ones(1)})
    table = TABLES["to_osf_s2"](load_results(tmp_path))
    assert table.frame is not None
    first = table.frame.iloc[0]
    assert first["priority weighting"] == pytest.approx(3.0)
    assert first["identical weighting"] == pytest.approx(0.5)
    assert first["ours priority / identical"] == pytest.approx(6.0)
    assert first["paper priority / identical"] == 7.5
    assert first["status (priority; identical)"] == (
        "ok; fell after 10 s: base height 0.3 m at t = 10.000 s"
    )
    notes = " ".join(table.notes)
    assert "a run stopped before the window's end" in notes
    assert "identical [10000000.0]" in notes


def test_to_osf_s3_compares_each_tasks_error_before_and_after_the_conflict(
    tmp_path: Path,
) -> None:
    """Synthetic logs: the strict hierarchy keeps the elbow's error, the weighted QP lets it
    grow 1000×; both give the hand up; a shortened run is not picked."""
    import numpy as np

    from wbcbench.scenarios.load import load_scenario

    loaded = load_scenario("lee2021access_s3_conflict")
    store = ResultsStore(tmp_path)
    store.record_scenario(loaded.name, loaded.hash, str(loaded.path))
    t = np.arange(0.0, 16.0, 0.01)
    conflict = t >= 11.0
    for controller, elbow_after in (("to_osf", 1e-6), ("qp_wbc", 1e-3)):
        log = {
            "t": t,
            "err.l_elbow.pos": np.where(conflict, elbow_after, 1e-6),
            "err.l_hand.pos": np.where(conflict, 0.2, 1e-6),
            "err.posture.joint": np.ones(t.size),
        }
        row = _s2_row(loaded, controller, "{}", controller=controller, sim_duration_s=16.0)
        store.add_run(row, [], log)
    short = _s2_row(loaded, "short", "{}", scenario_hash="other", sim_duration_s=0.5)
    store.add_run(short, [], {"t": np.zeros(1), "err.l_hand.pos": np.ones(1)})
    table = TABLES["to_osf_s3"](load_results(tmp_path))
    assert table.frame is not None
    f = table.frame.set_index(["controller", "task"])
    assert list(f.index) == [
        ("to_osf", "l_elbow (pos)"),
        ("to_osf", "l_hand (pos)"),
        ("qp_wbc", "l_elbow (pos)"),
        ("qp_wbc", "l_hand (pos)"),
    ]
    assert f.loc[("to_osf", "l_elbow (pos)"), "after / before"] == pytest.approx(1.0)
    assert f.loc[("qp_wbc", "l_elbow (pos)"), "after / before"] == pytest.approx(1000.0)
    assert f.loc[("qp_wbc", "l_hand (pos)"), "role"] == "T3"
    assert f.loc[("to_osf", "l_hand (pos)"), "after"] == pytest.approx(0.2)
    assert "to_osf 1e-06 m, nan rad; qp_wbc 0.001 m, nan rad" in " ".join(table.notes)


def test_to_osf_table3_has_one_row_per_task_count_from_the_runs_overrides(tmp_path: Path) -> None:
    """Timing rows of the first task only (an override in their settings) and of all five."""
    store = ResultsStore(tmp_path)
    one = '{"overrides": ["tasks=[{name: com, type: com, priority: 1}]"], "recorder": "qp_wbc"}'
    for rid, controller, settings, total in (
        ("hqp-1", "hqp", one, 900.0),
        ("to_osf-1", "to_osf", one, 300.0),
        ("hqp-5", "hqp", "{}", 4000.0),
        ("to_osf-5", "to_osf", "{}", 1000.0),
    ):
        row = _timing_row(
            rid,
            "lee2021access_table3",
            controller,
            solver="proxqp",
            settings=settings,
            scenario_hash=rid[-1],
        )
        store.add_run(row, _stages(rid, total_mean=total))
    table = TABLES["to_osf_table3"](load_results(tmp_path))
    assert table.frame is not None
    frame = table.frame.set_index("tasks")
    assert list(frame.index) == [1, 5]
    assert frame.loc[1, "ours hqp [ms]"] == pytest.approx(0.9)
    assert frame.loc[1, "ours HQP / TO-OSF"] == pytest.approx(3.0)
    assert frame.loc[5, "ours HQP / TO-OSF"] == pytest.approx(4.0)


def test_to_osf_s2_recognises_the_identical_weighting_config(tmp_path: Path) -> None:
    import numpy as np

    from wbcbench.scenarios.load import load_scenario

    loaded = load_scenario("lee2021access_s2_feasibility")
    store = ResultsStore(tmp_path)
    store.record_scenario(loaded.name, loaded.hash, str(loaded.path))
    for rid, config, amend in (("p", "{}", 2.0), ("i", '{"weighting": "identical"}', 0.5)):
        t = np.arange(0.0, 19.0, 0.01)
        row = _s2_row(loaded, rid, config)
        store.add_run(row, [], {"t": t, "diag.amend.com": np.full(t.size, amend)})
    table = TABLES["to_osf_s2"](load_results(tmp_path))
    assert table.frame is not None
    assert table.frame.iloc[0]["ours priority / identical"] == pytest.approx(4.0)
    assert table.frame.iloc[0]["status (priority; identical)"] == "ok; ok"
    assert "identical [10000000.0]" in " ".join(table.notes)
    assert "t = 9–19 s (the paper's window)" in " ".join(table.notes)


def test_timing_tables_never_mix_impls() -> None:
    from wbcbench.report.tables.common import _config, _one_impl, impl_note

    runs = pd.DataFrame(
        {
            "controller": ["hqp", "to_osf", "to_osf"],
            "impl": ["python", "native", "python"],
            "controller_config": ["{}", '{"impl": "native"}', '{"impl": "python"}'],
        }
    )
    # hqp has no native tick: the comparison is made on the Python path
    both = _one_impl(runs)
    assert list(both["impl"]) == ["python", "python"]
    assert impl_note(both).startswith("Times of the Python path")
    alone = _one_impl(runs[runs["controller"] == "to_osf"])
    assert list(alone["impl"]) == ["native"]
    assert impl_note(alone).startswith("Times of the native ticks")
    # the impl is a column of its own, not part of the config a table selects on
    assert [_config(r) for _, r in runs.iterrows()] == ["", "", ""]


def test_papers_md_opens_with_a_verdict_for_every_claim(tmp_path: Path) -> None:
    import shutil

    from wbcbench.report.tables import write_tables
    from wbcbench.report.verdicts import CLAIMS, VERDICTS

    folder = tmp_path / "reference"
    shutil.copytree(Path(__file__).resolve().parents[1] / "results" / "reference", folder)
    papers = write_tables(folder).read_text()
    first_section = papers[papers.index("\n## ") :]
    assert first_section.startswith("\n## What was reproduced")
    table = pd.read_csv(folder / "tables" / "verdicts.csv")
    # every claim has a row, the solver-dependent ones one per solver
    assert len(CLAIMS) == 14
    for claim in CLAIMS:
        assert table["claim"].str.startswith(claim.claim).any(), claim.claim
    assert set(table["verdict"]) <= set(VERDICTS)
    assert table["reason"].notna().all()
    # a run that fell is said where its numbers are used
    s2 = table[table["claim"].str.startswith("S2")].iloc[0]
    assert "fell" in s2["reason"]


def test_the_median_comes_with_a_block_bootstrap_interval() -> None:
    import numpy as np

    from wbcbench.metrics.timing import median_ci, timing_stats

    rng = np.random.default_rng(5)
    x = rng.gamma(5.0, 1e-4, 2000)
    lo, hi = median_ci(x)
    assert lo < float(np.median(x)) < hi and median_ci(x) == (lo, hi)  # seeded
    narrow = median_ci(x[:2000])
    wide = median_ci(x[:100])
    assert narrow[1] - narrow[0] < wide[1] - wide[0]
    stats = timing_stats(x)
    assert stats["median_ci_lo_us"] == pytest.approx(1e6 * lo)
    # a series whose halves differ (a slow drift) gets a wider interval than its shuffled self
    drift = np.concatenate([x[:1000], 1.5 * x[1000:]])
    shuffled = rng.permutation(drift)
    d, s = median_ci(drift), median_ci(shuffled)
    assert d[1] - d[0] > s[1] - s[0]


def test_each_papers_key_figure_is_drawn_from_its_table(tmp_path: Path) -> None:
    import shutil

    from wbcbench.report.paper_figures import FIGURES, write_paper_figures

    folder = tmp_path / "reference"
    shutil.copytree(Path(__file__).resolve().parents[1] / "results" / "reference", folder)
    names = {p.name for p in write_paper_figures(folder)}
    for table in FIGURES:
        assert f"paper_{table}.png" in names and f"paper_{table}.svg" in names


def test_timing_picks_pair_runs_of_one_solver_tier_mode_and_impl() -> None:
    """hqp was timed with qpOASES and DAQP, osf_hqp with DAQP only: a ratio between them must
    divide DAQP by DAQP (the paper's qpOASES is preferred only where it covers both)."""
    from wbcbench.report.tables import _pick_timing

    def row(rid: str, controller: str, solver: str, mode: str = "hot") -> dict:
        return dict(
            run_id=rid,
            scenario="lee2021iros_table1",
            scenario_hash="h",
            robot="tocabi_like",
            controller=controller,
            controller_config='{"impl": "native"}',
            impl="native",
            solver=solver,
            tier="default",
            mode=mode,
        )

    runs = pd.DataFrame(
        [
            row("a", "hqp", "qpoases"),
            row("b", "hqp", "daqp"),
            row("c", "osf_hqp", "daqp"),
            row("d", "osf_hqp", "daqp", mode="cold"),
        ]
    )
    picked = _pick_timing(runs, "qpoases")
    assert sorted(picked["run_id"]) == ["b", "c"]
    both = pd.concat([runs, pd.DataFrame([row("e", "osf_hqp", "qpoases")])])
    assert sorted(_pick_timing(both, "qpoases")["run_id"]) == ["a", "e"]


def test_fig1_verdict_counts_a_baseline_within_five_percent_as_a_tie() -> None:
    """At N = 10 SVD is 1.4 % faster than the reduced QR: a tie, not a reversal; SVD is the
    slowest only from N = 40 on, so the verdict is partly."""
    from wbcbench.report.verdicts import _fig1

    frame = pd.DataFrame(
        {
            "N": [10, 40, 100],
            "full_qr / reduced_qr (native)": [1.73, 2.45, 2.80],
            "svd / reduced_qr (native)": [0.986, 2.51, 2.95],
        }
    )
    ours, verdict, reason = _fig1(frame)
    assert verdict == "partly"
    assert "fastest at every N (yes; ties, N = 10: SVD within 1.4 %)" in reason
    assert "SVD slowest (from N = 40 on)" in reason
    assert ours == "full 2.8×, SVD 3× at N = 100 (native)"
    frame["svd / reduced_qr (native)"] = [0.90, 2.51, 2.95]  # 10 % faster: a reversal
    assert _fig1(frame)[1] == "not"


def test_a_solver_heatmap_row_compares_solvers_on_one_scenario_set() -> None:
    from wbcbench.report.plots import solver_cells

    rows = [
        # three solvers timed on scenarios a and b (daqp also on c), one native backend on a only,
        # and one whose every run failed
        *(("a", solver, 100.0 * k) for k, solver in enumerate(("daqp", "osqp", "proxqp"), 1)),
        *(("b", solver, 300.0 * k) for k, solver in enumerate(("daqp", "osqp", "proxqp"), 1)),
        ("c", "daqp", 5000.0),
        ("a", "eiquadprog", 50.0),
    ]
    t = pd.DataFrame(rows, columns=["scenario", "solver", "median_us"]).assign(
        label="qp_wbc (native) · hot", status="ok"
    )
    t = pd.concat(
        [
            t,
            pd.DataFrame(
                [
                    {
                        "scenario": "a",
                        "solver": "highs",
                        "median_us": 9.0,
                        "label": "qp_wbc (native) · hot",
                        "status": "failed",
                    }
                ]
            ),
        ]
    )
    values, text, used = solver_cells(t)
    row = "qp_wbc (native) · hot"
    # daqp's median is over a and b, the row's set, not over its extra scenario c
    assert used == {"a", "b"}
    assert values.loc[row, "daqp"] == 200.0 and text.loc[row, "daqp"] == "200\nn=2"
    assert values.loc[row, "osqp"] == 400.0 and text.loc[row, "osqp"] == "400\nn=2"
    # a backend timed on fewer scenarios keeps its own median, marked
    assert values.loc[row, "eiquadprog"] == 50.0 and text.loc[row, "eiquadprog"] == "50\nn=1*"
    assert pd.isna(values.loc[row, "highs"]) and text.loc[row, "highs"] == "failed"
