"""`wbcbench compare`: the summary (matched, within noise, changed, in one folder only) and the
keys that kept unmatched runs apart, and matching while ignoring keys."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from wbcbench.bench.results import ResultsStore
from wbcbench.cli import main
from wbcbench.errors import WbcBenchError
from wbcbench.report.compare import IGNORABLE, summary


def _timing(rid: str, controller: str, ticks: int, median: float) -> tuple[dict, list[dict]]:
    settings = {"ticks": ticks, "warmup": 10, "recorder": "qp_wbc", "date": rid, "host": rid}
    row = dict(
        run_id=rid,
        scenario="tocabi_stand_sway",
        robot="tocabi_like",
        controller=controller,
        controller_config="{}",
        solver="daqp",
        tier="default",
        mode="hot",
        impl="native",
        status="ok",
        kind="timing",
        settings=json.dumps(settings),
    )
    metrics = [
        dict(run_id=rid, task="*", metric=f"t_total_{name}_us", value=value, unit="us")
        for name, value in (
            ("median", median),
            ("median_ci_lo", 0.95 * median),
            ("median_ci_hi", 1.05 * median),
        )
    ]
    return row, metrics


def _tracking(rid: str, controller: str, duration: float, err: float) -> tuple[dict, list[dict]]:
    overrides = [f"duration={duration:g}", f"metrics.window=[0, {duration:g}]"]
    settings = {"duration_s": duration, "overrides": overrides, "cpu": rid}
    row = dict(
        run_id=rid,
        scenario="tocabi_stand_sway",
        robot="tocabi_like",
        controller=controller,
        controller_config="{}",
        solver="quadprog",
        tier="default",
        mode="cold",
        impl="native",
        status="ok",
        kind="tracking",
        settings=json.dumps(settings),
    )
    return row, [dict(run_id=rid, task="com", metric="err_mean", value=err, unit="m")]


def _folder(path: Path, runs: list[tuple[dict, list[dict]]]) -> Path:
    store = ResultsStore(path)
    for row, metrics in runs:
        store.add_run(row, metrics)
    return path


@pytest.fixture
def folders(tmp_path: Path) -> tuple[Path, Path]:
    """A: qp_wbc timed (60 ticks) and tracked (1 s), lqp timed. B: qp_wbc timed with 40 ticks
    and tracked for 0.5 s, lqp timed 3× slower (intervals apart), osf_hqp timed (B only)."""
    a = _folder(
        tmp_path / "A",
        [
            _timing("a1", "qp_wbc", 60, 100.0),
            _tracking("a2", "qp_wbc", 1.0, 1e-3),
            _timing("a3", "lqp", 40, 200.0),
        ],
    )
    b = _folder(
        tmp_path / "B",
        [
            _timing("b1", "qp_wbc", 40, 101.0),
            _tracking("b2", "qp_wbc", 0.5, 1e-3),
            _timing("b3", "lqp", 40, 600.0),
            _timing("b4", "osf_hqp", 40, 300.0),
        ],
    )
    return a, b


def test_the_summary_counts_and_names_the_keys_that_kept_rows_apart(
    folders: tuple[Path, Path],
) -> None:
    a, b = folders
    s = summary(a, b)
    assert (s["rows A"], s["rows B"]) == (3, 4)
    assert (s["matched"], s["within noise"], s["changed"]) == (1, 0, 1)
    assert s["changes"] == {"slower": 1}
    assert (s["only in A"], s["only in B"]) == (2, 3)
    # qp_wbc's timing differs in its ticks, its tracking in its duration; osf_hqp has no twin
    assert s["apart"] == {
        "ticks": 2,
        "duration": 2,
        "no run of its scenario × controller": 1,
    }


def test_ignoring_the_keys_matches_the_runs_they_kept_apart(folders: tuple[Path, Path]) -> None:
    a, b = folders
    s = summary(a, b, ["duration", "ticks"])
    assert (s["matched"], s["within noise"], s["changed"]) == (3, 2, 1)
    assert (s["only in A"], s["only in B"]) == (0, 1)
    assert s["apart"] == {"no run of its scenario × controller": 1}


def test_compare_prints_the_summary_first_and_refuses_an_unknown_key(
    folders: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = folders
    assert main(["compare", str(a), str(b), "--ignore", "duration,ticks"]) == 0
    out = capsys.readouterr().out
    assert out.index("## Summary") < out.index("## Timing")
    assert "- matched: 3: 2 within noise, 1 changed (1 slower)" in out
    assert "(matched ignoring duration, ticks)" in out
    with pytest.raises(WbcBenchError) as err:
        summary(a, b, ["durations"])
    assert str(err.value) == (
        "compare --ignore: unknown key 'durations'; valid choices: " + ", ".join(IGNORABLE)
    )
