"""Two results folders side by side (before and after a solver upgrade, a code change, another
machine): a summary first, then the change per combination, marked significant only when it
lies outside the noise.

* **Timing rows**: the median step time (``t_total_median_us``) of each combination in A and B
  and B / A; significant when the two medians' 95 % confidence intervals
  (:func:`~wbcbench.metrics.timing.median_ci`) do not overlap. Folders measured before the
  intervals were recorded compare without a verdict (``n/a``).
* **Tracking rows**: each task's mean error (``err_mean``) and the status; ``error changed`` when
  the relative difference exceeds 1e-9 (closed-loop runs are deterministic for every backend
  but ProxQP, whose README-stated spread is up to 1e-4); a status that differs is its own change
  (``status ok → fell``).

Rows are matched on :data:`KEYS`: what ran (kind, scenario, robot, controller and its config,
solver, tier, mode, impl) and how (the run's settings, split into ``duration``, ``ticks``,
``recorder``, ``overrides`` and the remaining ``settings``; never when or where it ran, nor the
machine's load). ``ignore`` drops keys from the match, so that runs that differ only in them
(``duration``: a 0.5 s run against a 1 s one) are compared. The summary counts the matched
rows, those within noise and those changed, the rows in one folder only, and, for each row in
one folder only, the keys in which it differs from its nearest row of the other (same kind,
scenario and controller): the keys that kept them apart.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.errors import WbcBenchError
from wbcbench.report.load import load_results

#: what a run ran: the columns of runs.csv a match compares
RUN_KEYS = [
    "kind",
    "scenario",
    "robot",
    "controller",
    "controller_config",
    "solver",
    "tier",
    "mode",
    "impl",
]
#: how it ran: facets of the run's settings
SETTING_KEYS = ["duration", "ticks", "recorder", "overrides", "settings"]
KEYS = [*RUN_KEYS, *SETTING_KEYS]
#: keys a user may leave out of the match (``--ignore``)
IGNORABLE = [k for k in KEYS if k != "kind"]
#: settings that say when and where a run ran or what it saved, not what it ran
VOLATILE = ("date", "host", "cpu", "conditions", "keep_log")
#: a tracking error change below this relative size is the same result
SAME = 1e-9
#: the change labels that count as "within noise" (timing) or "same" (tracking)
QUIET = ("within noise", "same")


def _facets(settings: object) -> dict[str, str]:
    """The run's settings split into the :data:`SETTING_KEYS` facets (each a JSON string)."""
    try:
        info = json.loads(str(settings)) if isinstance(settings, str) else {}
    except ValueError:
        info = {}
    if not isinstance(info, dict):
        info = {}
    info = {k: v for k, v in info.items() if k not in VOLATILE}
    overrides = [str(o) for o in info.pop("overrides", []) or []]
    timed = ("duration=", "metrics.window=")
    duration = {
        "duration_s": info.pop("duration_s", None),
        "set": [o for o in overrides if o.startswith(timed)],
    }
    ticks = {
        k: info.pop(k)
        for k in ("ticks", "warmup", "start", "probe_ticks", "interleave", "repeats", "sizes")
        if k in info
    }
    recorder = {k: info.pop(k) for k in ("recorder", "fallback_recorders") if k in info}

    def text(value: Any) -> str:
        return json.dumps(value, sort_keys=True)

    return {
        "duration": text(duration),
        "ticks": text(ticks),
        "recorder": text(recorder),
        "overrides": text([o for o in overrides if not o.startswith(timed)]),
        "settings": text(info),
    }


def _with_keys(runs: pd.DataFrame) -> pd.DataFrame:
    runs = runs.copy()
    for column in RUN_KEYS:
        if column not in runs:
            runs[column] = ""
        runs[column] = runs[column].astype(object).where(runs[column].notna(), "").astype(str)
    settings = runs["settings"] if "settings" in runs else pd.Series("{}", index=runs.index)
    facets = pd.DataFrame([_facets(s) for s in settings], index=runs.index, columns=SETTING_KEYS)
    # runs.csv's own `ticks` (how many ran) and `settings` give way to the facets
    runs = runs.drop(columns=[c for c in SETTING_KEYS if c in runs])
    return pd.concat([runs, facets], axis=1)


def _metric(metrics: pd.DataFrame, name: str, task: str = "*") -> pd.Series:
    m = metrics[(metrics["metric"] == name) & (metrics["task"].astype(str) == task)]
    return m.drop_duplicates("run_id").set_index("run_id")["value"]


def _timing(folder: Path) -> pd.DataFrame:
    res = load_results(folder)
    runs = res.of_kind("timing")
    if runs.empty:
        return pd.DataFrame(columns=[*KEYS, "status", "median", "lo", "hi"])
    runs = _with_keys(runs)[[*KEYS, "run_id", "status"]]
    for col, metric in (
        ("median", "t_total_median_us"),
        ("lo", "t_total_median_ci_lo_us"),
        ("hi", "t_total_median_ci_hi_us"),
    ):
        values = _metric(res.metrics, metric) if not res.metrics.empty else pd.Series(dtype=float)
        runs[col] = runs["run_id"].map(values)
    return runs.drop(columns="run_id")


def _tracking(folder: Path) -> pd.DataFrame:
    res = load_results(folder)
    runs = res.of_kind("tracking")
    if runs.empty or res.metrics.empty:
        return pd.DataFrame(columns=[*KEYS, "task", "status", "err"])
    err = res.metrics[res.metrics["metric"] == "err_mean"][["run_id", "task", "value"]]
    runs = _with_keys(runs)[[*KEYS, "run_id", "status"]]
    # a run without error metrics (it ended before its window) still takes part, task "*"
    out = runs.merge(err, on="run_id", how="left").rename(columns={"value": "err"})
    out["task"] = out["task"].fillna("*").astype(str)
    return out.drop(columns="run_id")


def _check_ignore(ignore: Sequence[str]) -> list[str]:
    bad = [k for k in ignore if k not in IGNORABLE]
    if bad:
        raise WbcBenchError(
            f"compare --ignore: unknown key {', '.join(map(repr, bad))}; valid choices: "
            + ", ".join(IGNORABLE)
        )
    return list(dict.fromkeys(ignore))


def _match(
    a: pd.DataFrame, b: pd.DataFrame, keys: list[str], extra: list[str]
) -> tuple[pd.DataFrame, int]:
    """Outer merge on ``keys + extra``; rows of one folder that share their key once keys are
    ignored are compared by their last. Returns the merge and how many rows were set aside."""
    on = [*keys, *extra]
    dropped = 0
    sides = []
    for frame in (a, b):
        dedup = frame.drop_duplicates(on, keep="last")
        dropped += len(frame) - len(dedup)
        sides.append(dedup)
    drop = [k for k in KEYS if k not in keys]
    merged = (
        sides[0]
        .drop(columns=drop)
        .merge(
            sides[1].drop(columns=drop), on=on, how="outer", suffixes=(" A", " B"), indicator=True
        )
    )
    return merged, dropped


def _timing_change(r: pd.Series) -> str:
    if r["_merge"] != "both":
        return "only in A" if r["_merge"] == "left_only" else "only in B"
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


def _tracking_change(r: pd.Series) -> str:
    if r["_merge"] != "both":
        return "only in A" if r["_merge"] == "left_only" else "only in B"
    if r["status A"] != r["status B"]:
        return f"status {r['status A']} → {r['status B']}"
    ea, eb = float(r["err A"]), float(r["err B"])
    if np.isnan(ea) and np.isnan(eb):
        return "same"
    if abs(eb - ea) <= SAME * max(1.0, abs(ea), abs(eb)):
        return "same"
    return "error changed"


def compare(
    a: str | Path, b: str | Path, ignore: Sequence[str] = ()
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(timing, tracking) comparison tables of folders ``a`` (before) and ``b`` (after), matched
    on :data:`KEYS` less ``ignore``."""
    keys = [k for k in KEYS if k not in _check_ignore(ignore)]
    timing, _ = _match(_timing(Path(a)), _timing(Path(b)), keys, [])
    timing["B / A"] = timing["median B"] / timing["median A"]
    timing["change"] = timing.apply(_timing_change, axis=1) if len(timing) else []
    timing = timing.drop(columns=["_merge", "lo A", "hi A", "lo B", "hi B"])
    tracking, _ = _match(_tracking(Path(a)), _tracking(Path(b)), keys, ["task"])
    tracking["change"] = tracking.apply(_tracking_change, axis=1) if len(tracking) else []
    tracking = tracking.drop(columns="_merge")
    return timing, tracking


def _apart(only: pd.DataFrame, other: pd.DataFrame, keys: list[str]) -> Counter[str]:
    """For each row of ``only``, the keys in which it differs from its nearest row of ``other``
    (same kind, scenario and controller; the one with the fewest differing keys)."""
    counts: Counter[str] = Counter()
    groups = {k: g for k, g in other.groupby(["kind", "scenario", "controller"], sort=False)}
    rest = [k for k in keys if k not in ("kind", "scenario", "controller")]
    for _, row in only.iterrows():
        group = groups.get((row["kind"], row["scenario"], row["controller"]))
        if group is None:
            counts["no run of its scenario × controller"] += 1
            continue
        differs = group[rest].ne(row[rest]).to_numpy()
        nearest = differs[int(differs.sum(axis=1).argmin())]
        for key, d in zip(rest, nearest, strict=True):
            if d:
                counts[key] += 1
    return counts


def summary(a: str | Path, b: str | Path, ignore: Sequence[str] = ()) -> dict[str, Any]:
    """The comparison's counts, one per run (a tracking run counts as changed when any of its
    tasks did): ``rows A``, ``rows B``, ``matched``, ``within noise``, ``changed`` (with
    ``changes``: each kind of change and its count), ``n/a``, ``only in A``, ``only in B``, and
    ``apart``: for the rows in one folder only, each key that kept them from their nearest row
    in the other, with how many rows it kept apart."""
    ignored = _check_ignore(ignore)
    keys = [k for k in KEYS if k not in ignored]
    timing, tracking = compare(a, b, ignored)
    per_run = [timing[[*keys, "change"]]]
    if len(tracking):
        rank = {"only in A": 0, "only in B": 0, "same": 1, "error changed": 3}
        worst = tracking.assign(_rank=[rank.get(c, 4) for c in tracking["change"]])
        worst = worst.sort_values("_rank").drop_duplicates(keys, keep="last")
        per_run.append(worst[[*keys, "change"]])
    runs = pd.concat(per_run, ignore_index=True)
    change = runs["change"]
    changed = change[~change.isin([*QUIET, "n/a", "only in A", "only in B"])]
    ta, tb = _timing(Path(a)), _timing(Path(b))
    ka, kb = _tracking(Path(a)), _tracking(Path(b))
    run_a = pd.concat([ta[KEYS], ka[KEYS]]).drop_duplicates()
    run_b = pd.concat([tb[KEYS], kb[KEYS]]).drop_duplicates()
    only_a = run_a.merge(run_b[keys].drop_duplicates(), on=keys, how="left", indicator=True)
    only_a = only_a[only_a["_merge"] == "left_only"]
    only_b = run_b.merge(run_a[keys].drop_duplicates(), on=keys, how="left", indicator=True)
    only_b = only_b[only_b["_merge"] == "left_only"]
    apart = _apart(only_a, run_b, keys) + _apart(only_b, run_a, keys)
    return {
        "rows A": len(run_a),
        "rows B": len(run_b),
        "matched": int((~change.isin(["only in A", "only in B"])).sum()),
        "within noise": int(change.isin(QUIET).sum()),
        "changed": len(changed),
        "changes": dict(Counter(changed)),
        "n/a": int((change == "n/a").sum()),
        "only in A": len(only_a),
        "only in B": len(only_b),
        "apart": dict(apart.most_common()),
        "ignored": ignored,
    }


def summary_text(s: dict[str, Any]) -> list[str]:
    """The summary as Markdown lines."""
    changes = ", ".join(f"{n} {what}" for what, n in sorted(s["changes"].items()))
    lines = [
        "## Summary",
        "",
        f"- runs: {s['rows A']} in A, {s['rows B']} in B"
        + (f" (matched ignoring {', '.join(s['ignored'])})" if s["ignored"] else ""),
        f"- matched: {s['matched']}: {s['within noise']} within noise, {s['changed']} changed"
        + (f" ({changes})" if changes else "")
        + (f", {s['n/a']} without intervals (n/a)" if s["n/a"] else ""),
        f"- only in A: {s['only in A']}; only in B: {s['only in B']}",
    ]
    if s["apart"]:
        keys = ", ".join(f"{k} ({n})" for k, n in s["apart"].items())
        lines.append(
            "- the keys that kept rows apart (each unmatched run against its nearest run of the "
            f"other folder): {keys}; `--ignore KEY` matches runs that differ only in such keys"
        )
    return [*lines, ""]


def markdown(a: str | Path, b: str | Path, ignore: Sequence[str] = ()) -> str:
    """The comparison as Markdown: the summary, then the timing and tracking tables."""
    timing, tracking = compare(a, b, ignore)
    lines = [f"# {a} (A) → {b} (B)", "", *summary_text(summary(a, b, ignore))]
    for title, frame in (("Timing (median step [µs])", timing), ("Tracking (err_mean)", tracking)):
        counts = frame["change"].value_counts() if len(frame) else pd.Series(dtype=int)
        line = ", ".join(f"{n} {what}" for what, n in counts.items()) or "nothing to compare"
        lines += [f"## {title}", "", line, ""]
        if len(frame):
            hidden = ["controller_config", "robot", *SETTING_KEYS]
            shown = frame.drop(columns=[c for c in hidden if c in frame])
            lines += [shown.to_markdown(index=False, floatfmt=".4g"), ""]
    return "\n".join(lines)
