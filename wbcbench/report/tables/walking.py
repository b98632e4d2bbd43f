"""Walking: each controller × solver on the walk scenarios, per robot.

Not a paper's table: the walks are ours (:mod:`wbcbench.tasks.walking`). A row is a closed-loop
run of a scenario with a ``walk:`` block; the longest run of each scenario × controller × solver
× impl is shown, so a walk cut short by a sweep's ``max_duration`` is used only when no whole one
was made.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report.load import Results
from wbcbench.report.tables.common import (
    PaperTable,
    _impl_of,
    _metric,
    _prefer_full,
    _run_status,
    scenario_spec,
)

#: the walk's phases, in the order the table shows them (see ``run_metrics.walk_phases``)
PHASES = ("double", "single", "transition")


def _walk_spec(res: Results, scenario: str) -> Any:
    spec = scenario_spec(res, scenario)
    return spec if spec is not None and getattr(spec, "walk", None) is not None else None


def _mm(res: Results, run_id: Any, metric: str, task: str = "*") -> float:
    return 1e3 * _metric(res, run_id, metric, task)


def _row(res: Results, run: pd.Series, com_task: str) -> dict[str, Any]:
    rid = run["run_id"]
    done, planned = _metric(res, rid, "steps_completed"), _metric(res, rid, "steps_planned")
    row: dict[str, Any] = {
        "robot": run["robot"],
        "scenario": run["scenario"],
        "controller": run["controller"],
        "solver": run["solver"],
        "impl": _impl_of(pd.DataFrame([run])).iloc[0],
        "steps": f"{done:.0f}/{planned:.0f}" if np.isfinite(planned) else "-",
        "status": _run_status(run),
        "CoM err mean / max [mm]": (
            f"{_mm(res, rid, 'err_mean', com_task):.3g} / {_mm(res, rid, 'err_max', com_task):.3g}"
        ),
        "DCM err mean / max [mm]": (
            f"{_mm(res, rid, 'dcm_error_mean'):.3g} / {_mm(res, rid, 'dcm_error_max'):.3g}"
        ),
        "landing err mean / max [mm]": (
            f"{_mm(res, rid, 'landing_error_mean'):.3g} / {_mm(res, rid, 'landing_error_max'):.3g}"
        ),
        "landing err xy / z max [mm]": (
            f"{_mm(res, rid, 'landing_error_xy_max'):.3g} / "
            f"{_mm(res, rid, 'landing_error_z_max'):.3g}"
        ),
        "CoP margin min [mm]": _mm(res, rid, "cop_margin_min"),
        "slip max [mm]": _mm(res, rid, "slip_max"),
    }
    for phase in PHASES:
        median = _metric(res, rid, f"t_total_median_us_{phase}")
        p99 = _metric(res, rid, f"t_total_p99_us_{phase}")
        row[f"{phase} median / p99 [µs]"] = f"{median:.0f} / {p99:.0f}"
    row["deadline misses [%]"] = 100.0 * _metric(res, rid, "t_total_miss_rate")
    return row


def _walk_scenarios(res: Results) -> dict[str, Any]:
    """The scenarios of these results' tracking runs that have a ``walk:`` block, with their
    specs."""
    tracking = res.of_kind("tracking")
    return {
        str(s): spec
        for s in (tracking["scenario"].unique() if not tracking.empty else [])
        if (spec := _walk_spec(res, str(s))) is not None
    }


def _walk_candidates(res: Results, walks: dict[str, Any]) -> pd.DataFrame:
    tracking = res.of_kind("tracking")
    runs = tracking[tracking["scenario"].isin(list(walks))] if walks else tracking.iloc[0:0]
    return runs[runs["status"].isin(["ok", "failed", "fell"])] if not runs.empty else runs


def walk_runs(res: Results) -> pd.DataFrame:
    """The run each row of the walking table shows: per walk scenario × controller × solver ×
    impl, the longest run that took a step or fell or failed (runs that stood still, such as
    the sweeps' 0.5 s health checks, are left out), with ``impl`` filled in; in the order of
    the results."""
    runs = _walk_candidates(res, _walk_scenarios(res))
    if runs.empty:
        return runs
    steps = runs["run_id"].map(lambda rid: _metric(res, rid, "steps_completed"))
    runs = runs[(runs["status"] != "ok") | (steps > 0)]
    if runs.empty:
        return runs
    keys = ["scenario", "controller", "solver", runs.pipe(_impl_of).rename("impl_")]
    chosen = [_prefer_full(res, group).iloc[-1] for _, group in runs.groupby(keys, sort=False)]
    frame = pd.DataFrame(chosen)
    return frame.assign(impl=_impl_of(frame)).reset_index(drop=True)


def walking(res: Results) -> PaperTable:
    """Steps, falls, CoM / DCM / landing errors, CoP margin, slip and time per phase of every
    walk run, grouped by robot."""
    t = PaperTable("walking", "Walking: each controller × solver on the walk scenarios", "", None)
    walks = _walk_scenarios(res)
    if _walk_candidates(res, walks).empty:
        t.missing = (
            "Run a walk scenario in closed loop, e.g. `wbcbench run scenarios/tocabi_walk.yaml "
            "--controller qp_wbc` or `make bench` (the `walks` matrix of sweeps/default.yaml)."
        )
        return t
    runs = walk_runs(res)
    if runs.empty:
        t.missing = "No walk run got as far as its first step; run one at full length."
        return t
    rows = [_row(res, run, walks[str(run["scenario"])].walk.com_task) for _, run in runs.iterrows()]
    frame = pd.DataFrame(rows).sort_values(["robot", "scenario"], kind="stable")
    t.frame = frame.reset_index(drop=True)
    t.notes += [
        "Steps: touchdowns confirmed (the foot carries load within the touchdown tolerance) "
        "of those planned. CoM error: the walk's CoM task against the LIPM / DCM plan. DCM "
        "error: ‖(x + ẋ/ω) − ξ_plan‖ in the floor plane, from the simulated CoM. Landing "
        "error: the landed sole frame's distance to its footstep at touchdown, in 3-D and "
        "split into its horizontal and vertical parts.",
        "CoP margin: the smallest distance of the simulated CoP inside its sole's edge over "
        "the ticks a settled contact carries load (negative: outside, the foot tips). Slip: "
        "the largest horizontal move of a settled contact's frame since its stance began.",
        "Time per tick (whole step, µs) by phase: double and single support, and the "
        "transition ticks, whose active contact set differs from the previous tick's (where a "
        "warm start is lost). Deadline misses: ticks over the control period, all phases. "
        "Closed-loop wall times: compare them within one run only.",
    ]
    return t
