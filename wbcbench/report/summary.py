"""``summary.md``: what a reader of a results folder needs first — the verdict counts, the rows
that failed and why, the runs that ended ok with a suspect error — then one compact line per
closed-loop run.

A run is **suspect** when it ended ``ok`` but one of its tasks' mean error is more than
:data:`SUSPECT_FACTOR` times the usual error of that task on that scenario — the median over
the other ok runs of the same scenario (same file and overrides) and task, at least
:data:`SUSPECT_MIN_OTHERS` of them — and above :data:`SUSPECT_FLOOR` (an error under 1 cm or
0.01 rad is never suspect, whatever the ratio: many tasks of a strict hierarchy track to
round-off, and a lower priority's millimetres are no sign of trouble).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

#: a task error this many times its scenario's usual one makes an ok run suspect
SUSPECT_FACTOR = 3.0
#: errors below this (in the task's unit, m or rad) are never suspect
SUSPECT_FLOOR = 1e-2
#: the usual error needs at least this many other runs of the scenario and task
SUSPECT_MIN_OTHERS = 2
#: failure messages are cut to this many characters in the summary
MESSAGE_CHARS = 160


def suspects(runs: pd.DataFrame, metrics: pd.DataFrame) -> pd.DataFrame:
    """The ok closed-loop runs with a task error beyond :data:`SUSPECT_FACTOR` × the usual:
    columns scenario, controller, solver, config, task, error, unit, usual, others, factor."""
    columns = ["scenario", "controller", "solver", "config", "task", "error", "unit", "usual"]
    columns += ["others", "factor"]
    if runs.empty or metrics.empty or "kind" not in runs:
        return pd.DataFrame(columns=columns)
    tracking = runs[runs["kind"] == "tracking"]
    ok = tracking[tracking["status"] == "ok"]
    err = metrics[(metrics["metric"] == "err_mean") & metrics["run_id"].isin(ok["run_id"])]
    group = "scenario_hash" if "scenario_hash" in ok else "scenario"
    info = ok.set_index("run_id")
    err = err.assign(_group=err["run_id"].map(info[group].astype(str)))
    out = []
    for (_, task), g in err.groupby(["_group", "task"]):
        values = g["value"].to_numpy(dtype=float)
        for i, (_, m) in enumerate(g.iterrows()):
            others = np.delete(values, i)
            others = others[np.isfinite(others)]
            if others.size < SUSPECT_MIN_OTHERS or not np.isfinite(values[i]):
                continue
            usual = float(np.median(others))
            if values[i] > max(SUSPECT_FACTOR * usual, SUSPECT_FLOOR):
                run = info.loc[m["run_id"]]
                config = str(run.get("controller_config", "") or "")
                out.append(
                    {
                        "scenario": run["scenario"],
                        "controller": run["controller"],
                        "solver": run["solver"],
                        "config": "" if config in ("{}", "nan") else config,
                        "task": task,
                        "error": values[i],
                        "unit": m.get("unit", ""),
                        "usual": usual,
                        "others": int(others.size),
                        "factor": values[i] / usual if usual > 0 else np.inf,
                    }
                )
    return pd.DataFrame(out, columns=columns)


def suspect_lines(frame: pd.DataFrame, limit: int = 5) -> list[str]:
    """Console lines for the suspect runs (at most ``limit``, then a count)."""
    lines = [
        f"  suspect: {r['scenario']} · {r['controller']} · {r['solver']}: {r['task']} error "
        f"{r['error']:.3g} {r['unit']}, {r['factor']:.3g}× the usual {r['usual']:.3g} "
        f"(median of {r['others']} other runs)"
        for _, r in frame.head(limit).iterrows()
    ]
    if len(frame) > limit:
        lines.append(f"  … and {len(frame) - limit} more (summary.md lists every one)")
    return lines


def _compact(runs: pd.DataFrame, metrics: pd.DataFrame) -> pd.DataFrame:
    """One line per closed-loop run: status, simulated time, the task error furthest above its
    scenario's usual (the median over the runs of that scenario and task), the median step."""
    tracking = runs[runs["kind"] == "tracking"] if "kind" in runs else runs
    err = metrics[(metrics["metric"] == "err_mean") & metrics["run_id"].isin(tracking["run_id"])]
    group = "scenario_hash" if "scenario_hash" in tracking else "scenario"
    err = err.assign(_group=err["run_id"].map(tracking.set_index("run_id")[group].astype(str)))
    usual = err.groupby(["_group", "task"])["value"].transform("median")
    err = err.assign(_times=err["value"] / usual.where(usual > 0))
    worst: dict[str, str] = {}
    for run_id, e in err.groupby("run_id"):
        ranked = e.dropna(subset=["value"]).sort_values("_times", na_position="first")
        if len(ranked):
            top = ranked.iloc[-1]
            times = f" ({top['_times']:.2g}× usual)" if np.isfinite(top["_times"]) else ""
            worst[str(run_id)] = f"{top['task']} {top['value']:.3g} {top['unit']}{times}"
    steps = metrics[(metrics["metric"] == "t_total_median_us") & (metrics["task"] == "*")]
    step: dict[str, float] = {
        str(k): float(v) for k, v in steps.drop_duplicates("run_id")[["run_id", "value"]].values
    }
    return pd.DataFrame(
        {
            "scenario": tracking["scenario"],
            "controller": tracking["controller"],
            "solver": tracking["solver"],
            "status": tracking["status"],
            "simulated [s]": tracking.get("sim_duration_s", np.nan),
            "task error furthest above its usual": [
                worst.get(str(r), "—") for r in tracking["run_id"]
            ],
            "median step [µs]": [step.get(str(r), np.nan) for r in tracking["run_id"]],
        }
    )


def write_summary(folder: str | Path, runs: pd.DataFrame, metrics: pd.DataFrame) -> Path:
    """Write ``summary.md`` (reads ``tables/verdicts.csv`` when the tables were written)."""
    folder = Path(folder)
    lines = ["# wbcbench results", ""]
    verdicts_csv = folder / "tables" / "verdicts.csv"
    if verdicts_csv.exists():
        from wbcbench.report.verdicts import VERDICTS

        verdicts = pd.read_csv(verdicts_csv)
        counts = verdicts["verdict"].value_counts()
        text = ", ".join(f"{counts.get(v, 0)} {v}" for v in VERDICTS)
        lines += [f"**Paper verdicts:** {len(verdicts)}: {text} (`tables/papers.md`).", ""]
    kinds = runs["kind"].value_counts() if "kind" in runs and len(runs) else pd.Series(dtype=int)
    for kind in ("tracking", "timing"):
        here = runs[runs["kind"] == kind] if kind in kinds else runs.iloc[0:0]
        if len(here):
            statuses = ", ".join(f"{n} {s}" for s, n in here["status"].value_counts().items())
            what = "closed-loop runs" if kind == "tracking" else "timing rows"
            lines.append(f"- {len(here)} {what}: {statuses}")
    lines.append("")
    failed = runs[runs["status"].isin(["failed", "error"])] if len(runs) else runs
    lines += ["## Failed rows", ""]
    if failed.empty:
        lines += ["None.", ""]
    else:
        shown = failed[["kind", "scenario", "controller", "solver", "status"]].copy()
        shown["reason"] = [
            str(m)[:MESSAGE_CHARS] + ("…" if len(str(m)) > MESSAGE_CHARS else "")
            for m in failed["message"].fillna("")
        ]
        lines += [shown.to_markdown(index=False), ""]
    odd = suspects(runs, metrics)
    lines += [
        "## Suspect runs",
        "",
        f"Ended ok, but a task's mean error is more than {SUSPECT_FACTOR:g}× the usual on its "
        f"scenario (the median of the other ok runs of that scenario and task, at least "
        f"{SUSPECT_MIN_OTHERS}) and above {SUSPECT_FLOOR:g}.",
        "",
        odd.to_markdown(index=False, floatfmt=".3g") if len(odd) else "None.",
        "",
        "## Closed-loop runs",
        "",
        "The largest mean tracking error over each scenario's metric window and the median step "
        "time. Open-loop timing: `tables/papers.md`; solvers: `solver_report.md`; every column: "
        "`runs.csv`, `metrics.csv`; figures: `figures/`.",
        "",
    ]
    compact = _compact(runs, metrics) if len(runs) and len(metrics) else pd.DataFrame()
    lines += [compact.to_markdown(index=False, floatfmt=".4g") if len(compact) else "(no runs)", ""]
    path = folder / "summary.md"
    path.write_text("\n".join(lines))
    return path
