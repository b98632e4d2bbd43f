"""Two results folders side by side (before and after a solver upgrade or a code change): the
change per combination, marked significant only when it lies outside the noise.

* **Timing rows**: the median step time (``t_total_median_us``) of each combination in A and B
  and B / A; significant when the two medians' 95 % confidence intervals
  (:func:`~wbcbench.metrics.timing.median_ci`) do not overlap. Folders measured before the
  intervals were recorded compare without a verdict (``n/a``).
* **Tracking rows**: each task's mean error (``err_mean``) and the status; a change counts when
  the relative difference exceeds 1e-9 (closed-loop runs are deterministic for every backend
  but ProxQP, whose README-stated spread is up to 1e-4) or the status differs.

Combinations are matched on kind, scenario, robot, controller and its config, solver, tier, mode,
impl and the run's settings (overrides, variant, recorder; not when or where it ran); those in
one folder only are listed as added or removed.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from wbcbench.report.load import load_results

KEY = [
    "kind",
    "scenario",
    "robot",
    "controller",
    "controller_config",
    "solver",
    "tier",
    "mode",
    "impl",
    "variant",
]
#: settings that say when and where a run ran, not what it ran
VOLATILE = ("date", "host", "cpu", "conditions")
#: a tracking error change below this relative size is the same result
SAME = 1e-9


def _variant(settings: object) -> str:
    try:
        info = json.loads(str(settings)) if isinstance(settings, str) else {}
    except ValueError:
        info = {}
    return json.dumps({k: v for k, v in info.items() if k not in VOLATILE}, sort_keys=True)


def _with_variant(runs: pd.DataFrame) -> pd.DataFrame:
    runs = runs.copy()
    runs["variant"] = runs["settings"].map(_variant) if "settings" in runs else "{}"
    return runs


def _metric(metrics: pd.DataFrame, name: str, task: str = "*") -> pd.Series:
    m = metrics[(metrics["metric"] == name) & (metrics["task"] == task)]
    return m.drop_duplicates("run_id").set_index("run_id")["value"]


def _timing(folder: Path) -> pd.DataFrame:
    res = load_results(folder)
    runs = _with_variant(res.of_kind("timing"))
    if runs.empty:
        return pd.DataFrame(columns=[*KEY, "status", "median", "lo", "hi"])
    runs = runs[[c for c in KEY if c in runs] + ["run_id", "status"]].copy()
    for col, metric in (
        ("median", "t_total_median_us"),
        ("lo", "t_total_median_ci_lo_us"),
        ("hi", "t_total_median_ci_hi_us"),
    ):
        runs[col] = runs["run_id"].map(_metric(res.metrics, metric))
    # a combination stored more than once (rerun by another code version): its latest row
    return runs.drop(columns="run_id").drop_duplicates(_key(runs, []), keep="last")


def _tracking(folder: Path) -> pd.DataFrame:
    res = load_results(folder)
    runs = res.of_kind("tracking")
    if runs.empty or res.metrics.empty:
        return pd.DataFrame(columns=[*KEY, "task", "status", "err"])
    err = res.metrics[res.metrics["metric"] == "err_mean"][["run_id", "task", "value"]]
    runs = _with_variant(runs)
    runs = runs[[c for c in KEY if c in runs] + ["run_id", "status"]]
    out = runs.merge(err, on="run_id").rename(columns={"value": "err"})
    return out.drop(columns="run_id").drop_duplicates(_key(out, ["task"]), keep="last")


def _key(frame: pd.DataFrame, extra: list[str]) -> list[str]:
    return [c for c in [*KEY, *extra] if c in frame.columns]


def compare(a: str | Path, b: str | Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(timing, tracking) comparison tables of folders ``a`` (before) and ``b`` (after)."""
    ta, tb = _timing(Path(a)), _timing(Path(b))
    keys = [k for k in _key(ta, []) if k in tb.columns]
    timing = ta.merge(tb, on=keys, how="outer", suffixes=(" A", " B"), indicator=True)
    timing["B / A"] = timing["median B"] / timing["median A"]

    def verdict(r: pd.Series) -> str:
        if r["_merge"] != "both":
            return "removed" if r["_merge"] == "left_only" else "added"
        if r["status A"] != r["status B"]:
            return f"status {r['status A']} → {r['status B']}"
        bounds = [r["lo A"], r["hi A"], r["lo B"], r["hi B"]]
        if not np.all(np.isfinite(np.asarray(bounds, dtype=float))):
            return "n/a"
        if r["hi B"] < r["lo A"]:
            return "faster"
        if r["lo B"] > r["hi A"]:
            return "slower"
        return "within noise"

    timing["change"] = timing.apply(verdict, axis=1) if len(timing) else []
    timing = timing.drop(columns=["_merge", "lo A", "hi A", "lo B", "hi B"])

    ka, kb = _tracking(Path(a)), _tracking(Path(b))
    keys = [k for k in _key(ka, ["task"]) if k in kb.columns]
    tracking = ka.merge(kb, on=keys, how="outer", suffixes=(" A", " B"), indicator=True)

    def changed(r: pd.Series) -> str:
        if r["_merge"] != "both":
            return "removed" if r["_merge"] == "left_only" else "added"
        if r["status A"] != r["status B"]:
            return f"status {r['status A']} → {r['status B']}"
        ea, eb = float(r["err A"]), float(r["err B"])
        if np.isnan(ea) and np.isnan(eb):
            return "same"
        if abs(eb - ea) <= SAME * max(1.0, abs(ea), abs(eb)):
            return "same"
        return "changed"

    tracking["change"] = tracking.apply(changed, axis=1) if len(tracking) else []
    tracking = tracking.drop(columns="_merge")
    return timing, tracking


def markdown(a: str | Path, b: str | Path) -> str:
    """The comparison as Markdown: a summary line, then the timing and tracking tables."""
    timing, tracking = compare(a, b)
    lines = [f"# {a} (A) → {b} (B)", ""]
    for title, frame in (("Timing (median step [µs])", timing), ("Tracking (err_mean)", tracking)):
        counts = frame["change"].value_counts() if len(frame) else pd.Series(dtype=int)
        summary = ", ".join(f"{n} {what}" for what, n in counts.items()) or "nothing to compare"
        lines += [f"## {title}", "", summary, ""]
        if len(frame):
            hidden = ("controller_config", "robot", "variant")
            shown = frame.drop(columns=[c for c in hidden if c in frame])
            lines += [shown.to_markdown(index=False, floatfmt=".4g"), ""]
    return "\n".join(lines)
