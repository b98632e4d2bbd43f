"""kin_hqp beside its velocity-level peers, pink and mink, on the kinematic scenarios."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report.load import Results
from wbcbench.report.tables.common import (
    PaperTable,
    _impl_of,
    _load_note,
    _metric,
    _prefer_full,
    _run_status,
    scenario_spec,
)

#: the controllers compared, the strict hierarchy first
PEERS = ("kin_hqp", "pink", "mink")


def _errors(res: Results, run_id: Any, tasks: list[str]) -> str:
    """``task mean / final unit`` of each task (position parts in mm, rotations in rad)."""
    m = res.metrics
    out = []
    for task in tasks:
        rows = m[(m["run_id"] == run_id) & (m["task"].astype(str) == task)]
        for part, mean, final in (
            ("", "err_mean", "err_final"),
            (" rot", "err_rot_mean", "err_rot_final"),
        ):
            sel = rows[rows["metric"] == mean]
            if sel.empty:
                continue
            unit = str(sel["unit"].iloc[0])
            scale, shown = (1e3, "mm") if unit == "m" else (1.0, unit)
            fin = rows[rows["metric"] == final]
            mean_v = scale * float(sel["value"].iloc[0])
            final_v = scale * float(fin["value"].iloc[0]) if len(fin) else float("nan")
            out.append(f"{task}{part} {mean_v:.3g} / {final_v:.3g} {shown}")
    return "; ".join(out) or "-"


def _top_residual(res: Results, run_id: Any, top: list[str]) -> str:
    """Mean / max of ‖J q̇ − r‖ of the priority-1 level over the window [m/s or rad/s]: how
    far the lower levels pulled the top one off its reference."""
    m = res.metrics
    rows = m[(m["run_id"] == run_id) & m["metric"].isin(["residual_mean", "residual_max"])]
    for level in rows["task"].astype(str).unique():
        if set(level.split("+")) <= set(top):
            sel = rows[rows["task"].astype(str) == level].set_index("metric")["value"]
            return f"{sel.get('residual_mean', np.nan):.3g} / {sel.get('residual_max', np.nan):.3g}"
    return "-"


def _tasks(res: Results, run_id: Any, spec: Any) -> tuple[list[str], list[str]]:
    """The run's tasks with errors: those of priority 1 (by the scenario), then the others
    (lower priorities and a controller's own tasks such as the gaze)."""
    m = res.metrics
    names = list(
        dict.fromkeys(m[(m["run_id"] == run_id) & (m["metric"] == "err_mean")]["task"].astype(str))
    )
    top = [t.name for t in spec.tasks if t.priority == 1] if spec is not None else names[:1]
    return [n for n in names if n in top], [n for n in names if n not in top]


def _times(res: Results, timing: pd.DataFrame, scenario: str, controller: str) -> dict[str, float]:
    """Median and p99 of the whole tick [µs] per impl, from the replay of recorded states."""
    out: dict[str, float] = {}
    rows = timing[(timing["scenario"] == scenario) & (timing["controller"] == controller)]
    for impl in ("python", "native"):
        sel = rows[_impl_of(rows) == impl] if not rows.empty else rows
        ok = sel[sel["status"] == "ok"]
        if "ticks" in ok.columns and len(ok):
            # the longest replay (the default sweep also times every controller for 40 ticks)
            ok = ok.assign(n=pd.to_numeric(ok["ticks"], errors="coerce")).sort_values("n")
        rid = ok["run_id"].iloc[-1] if len(ok) else None
        for stat in ("median", "p99"):
            value = _metric(res, rid, f"t_total_{stat}_us") if rid is not None else np.nan
            out[f"t {stat} {impl} [µs]"] = value
    return out


def peers_kinematic(res: Results) -> PaperTable:
    """Tracking, time per tick and hierarchy behaviour of kin_hqp, pink and mink."""
    t = PaperTable(
        "peers_kinematic",
        "Velocity-level peers: kin_hqp (strict levels) beside pink and mink (one weighted QP)",
        "",
        None,
    )
    tracking = res.of_kind("tracking")
    if not tracking.empty:
        tracking = tracking[
            tracking["controller"].isin(PEERS)
            & tracking["status"].isin(["ok", "failed", "fell"])
            & tracking["scenario"].map(
                lambda s: getattr(scenario_spec(res, str(s)), "kind", "") == "kinematic"
            )
        ]
    if tracking.empty or not set(tracking["controller"]) - {"kin_hqp"}:
        t.missing = (
            "Run kin_hqp, pink and mink on the kinematic scenarios (`sweeps/default.yaml` does; "
            "pink and mink need `pip install 'wbcbench[peers]'`)."
        )
        return t
    timing = res.of_kind("timing")
    rows = []
    for (scenario, controller), group in tracking.groupby(["scenario", "controller"], sort=False):
        run = _prefer_full(res, group).iloc[-1]
        spec = scenario_spec(res, str(scenario))
        top, lower = _tasks(res, run["run_id"], spec)
        distance = _metric(res, run["run_id"], "min_collision_distance")
        rows.append(
            {
                "scenario": scenario,
                "controller": controller,
                "status": _run_status(run),
                "priority 1 error mean / final": _errors(res, run["run_id"], top),
                "lower tasks' error mean / final": _errors(res, run["run_id"], lower),
                "priority 1 residual mean / max": _top_residual(res, run["run_id"], top),
                "joint-limit violation [rad]": _metric(res, run["run_id"], "joint_limit_violation"),
                "contact drift [mm]": 1e3 * _metric(res, run["run_id"], "max_contact_drift"),
                "min collision distance [mm]": 1e3 * distance,
                **(_times(res, timing, str(scenario), str(controller)) if not timing.empty else {}),
            }
        )
    order = {name: i for i, name in enumerate(PEERS)}
    frame = pd.DataFrame(rows)
    frame = frame.sort_values(
        ["scenario", "controller"], key=lambda c: c.map(order) if c.name == "controller" else c
    )
    t.frame = frame.reset_index(drop=True)
    t.notes += [
        "Tracking: closed-loop kinematic runs of the scenario as written where one exists; "
        "each task's mean over the metrics window and final error. Priority 1 is the top "
        "level: kin_hqp holds it strictly, pink and mink weigh the lower tasks "
        "priority_ratio^-(p-1) against it in one least-squares QP, so a conflicting lower task "
        "(the gaze of rqr_gaze and rqr_stress) may pull the top one off its reference. The "
        "priority 1 residual is ‖J q̇ − r‖ of the top level's tasks each tick (r = ẋ_d + λ e, "
        "capped; m/s or rad/s): what the controller gave up of the top level's reference.",
        "Collision distance: the smallest distance of kin_hqp's capsule pairs and obstacle "
        "pairs over the run, measured alike for all three; kin_hqp and mink avoid them, pink "
        "does not (pink has no collision limit). Contact drift: the held soles' largest "
        "displacement since the start.",
        "Times per tick (whole step, median and p99) from the replay of the same states "
        "recorded by kin_hqp; pink and mink run in Python around their libraries (kin_hqp's "
        "python impl is the like-for-like comparison, its native tick the C++ one).",
        f"Our machine: {res.machine}.{_load_note(res)}",
    ]
    return t
