"""Paper verdicts: medians with bootstrap intervals, ``inconclusive`` where the interval or the
machine's load cannot decide, one row per solver, and the same answer whatever the tick order."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from wbcbench.bench.results import ResultsStore
from wbcbench.report import evidence as E
from wbcbench.report import load_results
from wbcbench.report import papers as P
from wbcbench.report.tables import build_tables
from wbcbench.report.verdicts import (
    CLAIMS,
    VERDICTS,
    judge_bound,
    judge_gain,
    judge_robot_time,
    verdicts,
)

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "results" / "reference"
T3_PAPER = P.OSF_HQP_TABLE3["conventional"][-1] / P.OSF_HQP_TABLE3["proposed"][-1]


def _conditions(busy: bool, probes: tuple[float, float] = (10.0, 10.2)) -> dict:
    load = 6.3 if busy else 1.0
    return {
        "busy": busy,
        "load_1min": load,
        "other_load_per_core": (load - 1) / 2,
        "speed_probe_ms": list(probes),
    }


def _table3_folder(
    folder: Path,
    ratios: dict[str, float],
    busy: bool = False,
    probes: dict[str, tuple[float, float]] | None = None,
    together: bool = False,
) -> Path:
    """hqp and osf_hqp timed on Table III's scenario with each solver of ``ratios``: 60 ticks
    (10 of warm-up) of noisy tick times whose medians stand in the given ratio."""
    store = ResultsStore(folder)
    rng = np.random.default_rng(3)
    for solver, ratio in ratios.items():
        noise = 1.0 + 0.05 * rng.standard_normal(60)
        for controller, scale in (("hqp", ratio), ("osf_hqp", 1.0)):
            rid = f"{controller}-{solver}"
            conditions = _conditions(busy, (probes or {}).get(controller, (10.0, 10.2)))
            if together:  # the pair was timed interleaved, in one group
                conditions["interleaved"] = {"group": solver, "rows": 2, "block_ticks": 10}
            settings = {"warmup": 10, "recorder": "qp_wbc", "conditions": conditions}
            solve = 1e-4 * scale * noise * rng.uniform(0.97, 1.03, 60)
            log = {"t": np.arange(60) * 1e-3, "time.solve": solve, "time.total": 2 * solve}
            row = dict(
                run_id=rid,
                scenario="lee2021iros_table1",
                scenario_hash="h",
                robot="tocabi_like",
                controller=controller,
                controller_config='{"impl": "native"}',
                impl="native",
                solver=solver,
                tier="default",
                mode="hot",
                status="ok",
                kind="timing",
                settings=json.dumps(settings),
            )
            store.add_run(row, [], log)
    return folder


def _rows(folder: Path, claim: str) -> pd.DataFrame:
    res = load_results(folder)
    frame = verdicts(build_tables(res), res)
    return frame[frame["claim"].str.startswith(claim)]


def test_a_ratio_whose_interval_straddles_its_threshold_is_inconclusive(tmp_path: Path) -> None:
    """Half the paper's Table III ratio is the line between reproduced and partly: a median
    ratio on that line cannot be either; one well above it is reproduced, one far above it too
    (a larger gain than the paper's), and the paper's solver comes first, named."""
    ratios = {"qpoases": T3_PAPER / 2, "daqp": T3_PAPER, "proxqp": 4 * T3_PAPER}
    rows = _rows(_table3_folder(tmp_path, ratios), "Table III").set_index("claim")
    assert list(rows.index) == [
        "Table III: QP time, conventional / proposed — qpoases (paper's)",
        "Table III: QP time, conventional / proposed — daqp",
        "Table III: QP time, conventional / proposed — proxqp",
    ]
    borderline = rows.iloc[0]
    assert borderline["verdict"] == "inconclusive"
    assert f"contains {T3_PAPER / 2:.3g}× (half the paper's gain)" in borderline["reason"]
    assert rows.iloc[1]["verdict"] == "reproduced"
    assert rows.iloc[2]["verdict"] == "reproduced"
    assert "a larger gain than the paper's" in rows.iloc[2]["reason"]


def test_a_speed_timed_on_a_busy_machine_is_inconclusive_with_its_load(tmp_path: Path) -> None:
    rows = _rows(_table3_folder(tmp_path, {"qpoases": T3_PAPER}, busy=True), "Table III")
    assert list(rows["verdict"]) == ["inconclusive"]
    assert "2 of 2 runs behind it were timed on a busy machine (load 6.3" in rows.iloc[0]["reason"]


def test_a_ratio_of_runs_timed_apart_is_widened_by_the_machines_speed_spread(
    tmp_path: Path,
) -> None:
    """A fixed workload that ran 40 % slower around one run than around the other: the ratio
    of the two runs timed apart mixes two machines' speeds, so its interval is widened by
    that spread, and a ratio 1.3 times half the paper's can no longer be told from half. The
    same two rows timed together, interleaved, met the same speeds: their ratio is decided."""
    probes = {"hqp": (10.0, 10.5), "osf_hqp": (14.0, 13.8)}
    ratio = {"qpoases": 0.65 * T3_PAPER}
    rows = _rows(_table3_folder(tmp_path / "apart", ratio, probes=probes), "Table III")
    assert list(rows["verdict"]) == ["inconclusive"]
    reason = rows.iloc[0]["reason"]
    assert f"contains {T3_PAPER / 2:.3g}× (half the paper's gain)" in reason
    assert (
        "Its interval is widened by ±40 %, the spread of the machine's speed around the runs."
        in reason
    )
    rows = _rows(
        _table3_folder(tmp_path / "together", ratio, probes=probes, together=True), "Table III"
    )
    assert list(rows["verdict"]) == ["reproduced"]
    assert "widened" not in rows.iloc[0]["reason"]


def test_a_median_is_widened_by_the_speed_spread_around_its_run() -> None:
    row = pd.Series(
        {"run_id": "r", "settings": json.dumps({"conditions": {"speed_probe_ms": [10.0, 12.5]}})}
    )
    assert E.speed_spread([row]) == pytest.approx(0.25)
    est = E.Estimate(100.0, 90.0, 110.0, "ticks").widen(0.25)
    assert (est.value, est.lo, est.hi, est.widened) == (100.0, 72.0, 137.5, 0.25)
    assert E.Estimate(100.0, 90.0, 110.0, "ticks").widen(0.0).note == ""
    # rows of one interleaved group are timed together; a row alone is not
    together = {"conditions": {"interleaved": {"group": "g1"}}}
    a = pd.Series({"settings": json.dumps(together)})
    assert E.timed_together([a, a.copy()])
    assert not E.timed_together([a])
    assert not E.timed_together([a, row])


def test_the_judges_thresholds() -> None:
    def est(value: float, width: float) -> E.Estimate:
        return E.Estimate(value, value - width, value + width, "ticks")

    assert judge_gain(est(1.0, 0.1), 3.0)[0] == "inconclusive"  # no gain or a small one
    assert judge_gain(est(0.8, 0.1), 3.0)[0] == "not"
    assert judge_gain(est(1.2, 0.1), 3.0)[0] == "partly"
    assert judge_gain(est(12.0, 0.5), 3.0) == ("reproduced", "a larger gain than the paper's")
    assert judge_bound(est(400.0, 50.0), 500.0)[0] == "reproduced"
    assert judge_bound(est(480.0, 50.0), 500.0)[0] == "inconclusive"
    assert judge_bound(est(600.0, 50.0), 500.0)[0] == "not"
    # five times faster than the paper's robot is reproduced, never "not"
    assert judge_robot_time(est(50.0, 5.0), 253.0)[0] == "reproduced"
    assert judge_robot_time(est(800.0, 50.0), 253.0)[0] == "partly"
    assert judge_gain(E.NAN, 3.0)[0] == "not run"


def test_an_interval_depends_on_the_tick_times_not_their_order() -> None:
    rng = np.random.default_rng(0)
    x = rng.gamma(4.0, 25.0, 90)
    row = pd.Series({"run_id": "a", "settings": "{}"})

    class Logs:
        def __init__(self, values: np.ndarray) -> None:
            self.values = values
            self.metrics = pd.DataFrame()

        def log(self, run_id: str) -> pd.DataFrame:
            return pd.DataFrame({"time.total": self.values * 1e-6})

    one = E.median(Logs(x), row)  # type: ignore[arg-type]
    two = E.median(Logs(rng.permutation(x)), row)  # type: ignore[arg-type]
    assert one == two and one.lo < one.value < one.hi and one.source == "ticks"


def _shuffle_ticks(folder: Path, seed: int) -> int:
    """Put every timing run's ticks after the warm-up in another order; how many runs."""
    res = load_results(folder)
    rng = np.random.default_rng(seed)
    shuffled = 0
    for _, row in res.of_kind("timing").iterrows():
        path = folder / "logs" / f"{row['run_id']}.parquet"
        if not path.exists():
            continue
        log = pd.read_parquet(path)
        warmup = min(int(json.loads(row["settings"]).get("warmup", 0)), len(log))
        order = np.r_[np.arange(warmup), warmup + rng.permutation(len(log) - warmup)]
        log.iloc[order].reset_index(drop=True).to_parquet(path)
        shuffled += 1
    return shuffled


def _all_verdicts(folder: Path) -> pd.DataFrame:
    res = load_results(folder)
    return verdicts(build_tables(res), res)


def test_reshuffled_ticks_give_the_same_verdicts(tmp_path: Path) -> None:
    """Borderline, clear and far-off ratios: every verdict, number and reason stays as it was
    when each run's ticks come in another order."""
    ratios = {"qpoases": T3_PAPER / 2, "daqp": T3_PAPER, "proxqp": 1.0}
    folder = _table3_folder(tmp_path, ratios)
    before = _all_verdicts(folder)
    assert _shuffle_ticks(folder, 1) == 6
    after = _all_verdicts(folder)
    pd.testing.assert_frame_equal(before, after)
    assert "inconclusive" in set(after["verdict"])


def _has_timing_logs(folder: Path) -> bool:
    if not (folder / "runs.csv").exists():
        return False
    runs = pd.read_csv(folder / "runs.csv")
    ids = runs.loc[runs["kind"] == "timing", "run_id"]
    return any((folder / "logs" / f"{rid}.parquet").exists() for rid in ids)


@pytest.mark.skipif(
    not _has_timing_logs(REFERENCE), reason="results/reference keeps no per-tick timing logs"
)
def test_the_references_verdicts_do_not_depend_on_its_tick_order(tmp_path: Path) -> None:
    folder = tmp_path / "reference"
    shutil.copytree(REFERENCE, folder, ignore=shutil.ignore_patterns("figures", "tables"))
    before = _all_verdicts(folder)
    timed = [c.claim for c in CLAIMS if c.timed is not None]
    reasons = before[before["claim"].str.startswith(tuple(timed))]["reason"]
    assert not reasons.str.contains("stored intervals").any()  # the ticks were used
    assert _shuffle_ticks(folder, 2)
    pd.testing.assert_frame_equal(before, _all_verdicts(folder))
    assert set(before["verdict"]) <= set(VERDICTS)


def test_readme_quotes_no_table_iii_ratio_the_reference_contradicts() -> None:
    """Each ratio the README's known limitations quote for OSF-HQP Table III ("N× …" in its
    paragraph) is one of the reference's per-solver ratios, to its quoted precision."""
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## Known limitations") :]
    start = section.index("- OSF-HQP Table III")
    paragraph = section[start : section.index("\n- ", start + 1)]
    res = load_results(REFERENCE)
    frame = verdicts(build_tables(res), res)
    rows = frame[frame["claim"].str.startswith("Table III")]
    measured = {
        str(claim).split(" — ")[-1].split(" ")[0]: float(str(ours).rstrip("×"))
        for claim, ours in zip(rows["claim"], rows["ours"], strict=True)
        if ours != "—"
    }
    quoted = re.findall(r"reference: ([0-9.]+)× with (\w+)", paragraph)
    assert quoted, "the paragraph quotes no reference ratio"
    for value, solver in quoted:
        digits = len(value.replace(".", "").lstrip("0"))
        assert solver in measured, (solver, measured)
        assert f"{measured[solver]:.{digits}g}" == value, (value, solver, measured)
