"""Every notebook in notebooks/ executes on the curated reference results (so none rots), with
matplotlib's inline backend as Jupyter gives it: every figure renders as a picture, the tables
as tables, the verdicts come first and the conclusion last."""

from __future__ import annotations

import re
from pathlib import Path

import nbformat
import pandas as pd
import pytest
from nbclient import NotebookClient

from wbcbench.report.load import Results
from wbcbench.report.notebook import (
    walk_coverage,
    walk_phase_times,
    walk_verdicts,
    walking_conclusion,
)
from wbcbench.scenarios.load import available_scenarios

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
REFERENCE = ROOT / "results" / "reference"


def test_there_is_a_notebook_per_paper_and_one_each_for_solvers_robustness_and_walking() -> None:
    names = {p.name for p in NOTEBOOKS}
    assert {
        "to_osf_lee2021.ipynb",
        "osf_hqp_lee2021.ipynb",
        "rc_lqp_ahn.ipynb",
        "rqr_hqp.ipynb",
        "solver_comparison.ipynb",
        "robustness.ipynb",
        "walking.ipynb",
    } <= names


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes(path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """From another working directory and without WBCBENCH_RESULTS: each notebook finds the
    curated results relative to the package."""
    assert (REFERENCE / "runs.csv").exists(), "results/reference is missing: run `make reference`"
    monkeypatch.delenv("WBCBENCH_RESULTS", raising=False)
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel's own: inline
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    code = [cell for cell in nb.cells if cell.cell_type == "code"]
    outputs = [o for cell in code for o in cell.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    # the notebook loaded the results and printed what it found
    assert any("runs measured on" in o.get("text", "") for o in outputs)

    def markdown(cell: nbformat.NotebookNode) -> str:
        return "".join(o.get("data", {}).get("text/markdown", "") for o in cell.get("outputs", []))

    # opens with its verdicts (a Markdown table), ends with a conclusion drawn from them
    assert re.search(r"## Verdicts?\n", markdown(code[0])), "the first cell shows no verdicts"
    assert markdown(code[-1]).strip(), "the last cell draws no conclusion"
    # every cell that draws a figure shows it as a picture
    for cell in code:
        if "def " not in cell.source and re.search(r"figure\(|plt\.show\(\)", cell.source):
            assert any("image/png" in o.get("data", {}) for o in cell.get("outputs", [])), (
                f"no picture from: {cell.source.splitlines()[0]}"
            )
    # tables render as tables (Markdown pipes), never as printed text
    assert any("|---" in markdown(cell) or "|:--" in markdown(cell) for cell in code)
    assert not any("|:--" in o.get("text", "") for o in outputs), "a table printed as text"


# -- the walking notebook's helpers, on hand-made results of tocabi_walk (10 steps, 1 kHz)


def _walk_run(run_id: str, controller: str, solver: str, status: str, sim: float, msg: str = ""):
    return {
        "run_id": run_id,
        "scenario": "tocabi_walk",
        "scenario_hash": "",
        "robot": "tocabi_like",
        "controller": controller,
        "solver": solver,
        "impl": "python",
        "status": status,
        "message": msg or None,
        "sim_duration_s": sim,
        "kind": "tracking",
        "settings": "{}",
    }


def _walk_metrics(run_id: str, done: int, com_mm: float = 0.5, landing_mm: float = 0.9):
    values = {
        "steps_completed": done,
        "steps_planned": 4,
        "landing_error_max": landing_mm * 1e-3,
        "t_total_median_us_double": 700.0,
        "t_total_p99_us_double": 900.0,
        "ticks_double": 3600,
        "t_total_median_us_single": 650.0,
        "t_total_p99_us_single": 1200.0,
        "ticks_single": 3000,
        "t_total_median_us_transition": 800.0,
        "t_total_p99_us_transition": 950.0,
        "ticks_transition": 8,
    }
    com = {"run_id": run_id, "task": "com", "metric": "err_max", "value": com_mm * 1e-3}
    return [
        com,
        *({"run_id": run_id, "task": "*", "metric": k, "value": v} for k, v in values.items()),
    ]


@pytest.fixture
def walks(tmp_path: Path) -> Results:
    runs = [
        _walk_run("a", "qp_wbc", "daqp", "ok", 6.7),
        _walk_run("b", "hqp", "daqp", "ok", 6.7),
        _walk_run("c", "lqp", "daqp", "fell", 2.53, "contact 'l_sole' moved 20.3 mm"),
        _walk_run("d", "qp_wbc", "quadprog", "ok", 3.0),
        _walk_run("e", "to_osf", "daqp", "ok", 0.5),  # a health check: it stood still
    ]
    metrics = _walk_metrics("a", 4) + _walk_metrics("b", 4, com_mm=7.0)
    metrics += _walk_metrics("c", 1) + _walk_metrics("d", 2) + _walk_metrics("e", 0)
    return Results(tmp_path, pd.DataFrame(runs), pd.DataFrame(metrics))


def test_walk_verdicts_judge_steps_falls_and_the_5_mm_targets(walks: Results) -> None:
    v = walk_verdicts(walks).set_index(["controller", "solver"])
    assert list(v.index) == [
        ("qp_wbc", "daqp"),
        ("hqp", "daqp"),
        ("lqp", "daqp"),
        ("qp_wbc", "quadprog"),
    ]
    assert v.loc[("qp_wbc", "daqp"), "verdict"] == "walks"
    assert v.loc[("qp_wbc", "daqp"), "CoM err max [mm]"] == pytest.approx(0.5)
    assert v.loc[("qp_wbc", "daqp"), "landing err max [mm]"] == pytest.approx(0.9)
    assert v.loc[("hqp", "daqp"), "verdict"] == "off target"
    assert v.loc[("hqp", "daqp"), "why"] == "CoM error up to 7 mm, beyond 5 mm"
    assert v.loc[("lqp", "daqp"), ["steps", "fell", "verdict"]].tolist() == [
        "1/4",
        True,
        "ends early",
    ]
    assert v.loc[("lqp", "daqp"), "why"] == "fell after 2.53 s: contact 'l_sole' moved 20.3 mm"
    assert v.loc[("qp_wbc", "quadprog"), "verdict"] == "ends early"
    assert v.loc[("qp_wbc", "quadprog"), "why"] == "cut short at 3 s, before its last step"


def test_walk_phase_times_hold_each_phase_and_the_control_period(walks: Results) -> None:
    p = walk_phase_times(walks)
    assert len(p) == 4 * 3
    first = p[(p["controller"] == "qp_wbc") & (p["solver"] == "daqp")]
    assert first["phase"].tolist() == ["double", "single", "transition"]
    assert first["median [µs]"].tolist() == [700.0, 650.0, 800.0]
    assert first["ticks"].tolist() == [3600, 3000, 8]
    assert set(p["deadline [µs]"]) == {1000.0}  # tocabi_walk runs at 1 kHz


def test_walk_coverage_lists_every_walk_scenario_with_its_runs(walks: Results) -> None:
    c = walk_coverage(walks).set_index("scenario")
    assert "tocabi_walk" in c.index and "tocabi_stand_sway" not in c.index
    assert set(c.index) <= set(available_scenarios())
    assert c.loc["tocabi_walk"].tolist() == ["tocabi_like", 10, 5, 1, 4]
    assert (c.drop(index="tocabi_walk")["runs"] == 0).all()


def test_walking_conclusion_says_who_walks_what_ends_early_and_the_slowest_phase(
    walks: Results,
) -> None:
    verdicts, coverage = walk_verdicts(walks), walk_coverage(walks)
    text = walking_conclusion(verdicts, walk_phase_times(walks), coverage)
    paragraphs = text.split("\n\n")
    assert paragraphs[0] == (
        "Of 4 walk runs, 1 walks every planned step within the 5 mm targets: `qp_wbc` × daqp "
        "(python) on tocabi_walk, 4/4 steps. Its CoM error is at most 0.5 mm and its landing "
        "error at most 0.9 mm."
    )
    assert paragraphs[1] == (
        "`hqp` × daqp (python) on tocabi_walk off target, 4/4 steps: CoM error up to 7 mm, "
        "beyond 5 mm."
    )
    assert paragraphs[2].startswith("`lqp` × daqp (python) on tocabi_walk ends early, 1/4 steps")
    assert (
        "`qp_wbc` × daqp (python) on tocabi_walk: the transition ticks are the slowest at the "
        "median (800 µs over 8 ticks, against 700 µs double and 650 µs single); the p99 misses "
        "the 1 ms deadline in single (1200 µs); the p99 of 8 transition ticks is close to "
        "their largest."
    ) in paragraphs
    others = sorted(set(coverage["scenario"]) - {"tocabi_walk"})
    assert "Not run in these results: " + ", ".join(f"`{s}`" for s in others) + "." in paragraphs
    assert "Not judged, having ended before their first touchdown: 1 run of `tocabi_walk`." in (
        paragraphs
    )
    assert "Slowest phase at the median: transition ticks in 4 of 4 runs." in paragraphs
    assert (
        "The 4 runs of `tocabi_walk` judged here were asked for 4 of the 10 steps its scenario "
        "file plans."
    ) in paragraphs


def test_walking_conclusion_without_walks(tmp_path: Path) -> None:
    empty = Results(tmp_path, pd.DataFrame(), pd.DataFrame())
    verdicts, coverage = walk_verdicts(empty), walk_coverage(empty)
    assert verdicts.empty and walk_phase_times(empty).empty
    text = walking_conclusion(verdicts, walk_phase_times(empty), coverage)
    assert text.split("\n\n")[0] == "No walk run in these results took a step."
    assert "Not run in these results: " in text
