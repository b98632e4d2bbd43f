"""TO-OSF: Scenario #1 errors and the pseudo-inverse ablation, Scenario #2's amendments,
Scenario #3's conflict, Scenario #4's times, COD vs SVD, Table 3."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results
from wbcbench.report.tables.common import (
    PaperTable,
    _config,
    _errors,
    _find_task,
    _full_length,
    _has,
    _machines,
    _metric,
    _ms,
    _pick_timing,
    _prefer_full,
    _ratio,
    _run_status,
    _runs,
    _to_paper_unit,
    impl_note,
    run_spec,
    scenario_spec,
)


def to_osf_s1(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_s1", "TO-OSF Scenario #1: mean tracking errors (t = 9–19 s)", "to_osf", None
    )
    runs = _runs(res, "tracking", "lee2021access_s1*", "to_osf")
    runs = runs[[not _has(r, "pinv") and not _has(r, "svd") for _, r in runs.iterrows()]]
    runs = _prefer_full(res, runs)
    if runs.empty:
        t.missing = (
            "Run `to_osf` on the `lee2021access_s1*` scenarios (`wbcbench sweep sweeps/full.yaml`)."
        )
        return t
    run = runs.iloc[-1]
    spec = scenario_spec(res, run["scenario"])
    rows = []
    for paper, (task, value, metric) in zip(P.TO_OSF_S1, _errors(res, run, spec), strict=True):
        ours = _to_paper_unit(value, paper.unit)
        rows.append(
            {
                "task": f"{paper.row} {paper.column}",
                "our task": f"{task} ({metric})" if metric else "not found",
                "unit": paper.unit,
                "paper": paper.value,
                "ours": ours,
                "ours / paper": _ratio(ours, paper.value or float("nan")),
            }
        )
    t.frame = pd.DataFrame(rows)
    t.notes += [
        f"Scenario `{run['scenario']}`, solver {run['solver']}, status {_run_status(run)}.",
        *_length_note(res, run, spec),
        "Paper: COMAN+ in V-REP/Vortex; ours: the COMAN+-like model in MuJoCo (soft contacts).",
        f"Source: {P.TO_OSF_S1[0].source}.",
    ]
    return t


def _length_note(res: Results, run: pd.Series, spec: Any) -> list[str]:
    """A note when a run's scenario was shortened: its errors are not over the paper's window."""
    if _full_length(res, run):
        return []
    window = spec.metrics.window if spec is not None else None
    return [
        f"This run was shortened ({run.get('sim_duration_s', '?')} s simulated): its errors are "
        f"over the shortened run's window, not t = {window[0]:g}–{window[1]:g} s."
        if window
        else "This run was shortened: its errors are not over the paper's window."
    ]


def to_osf_pinv(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_pinv",
        "TO-OSF Scenario #1 ablation: pseudo-inverse vs dynamically consistent inverse",
        "to_osf",
        None,
    )
    runs = _runs(res, "tracking", "lee2021access_s1*", "to_osf")
    runs = _prefer_full(res, runs)
    pinv = runs[[_has(r, "pinv") for _, r in runs.iterrows()]]
    dc = runs[[not _has(r, "pinv") and not _has(r, "svd") for _, r in runs.iterrows()]]
    if not pinv.empty and not dc.empty:  # both of the same length when there is such a pair
        same = dc[dc["scenario_hash"].isin(pinv["scenario_hash"])]
        dc = same if not same.empty else dc
        pinv = pinv[pinv["scenario_hash"].isin(dc["scenario_hash"])] if not same.empty else pinv
    if pinv.empty or dc.empty:
        t.missing = (
            "Needs `to_osf` on `lee2021access_s1*` with its default inverse and with a config "
            "selecting the pseudo-inverse (see `sweeps/full.yaml`)."
        )
        return t
    a, b = dc.iloc[-1], pinv.iloc[-1]
    spec = scenario_spec(res, a["scenario"])
    rows = []
    for paper, (task, v_dc, _), (_, v_pinv, _) in zip(
        P.TO_OSF_S1, _errors(res, a, spec), _errors(res, b, spec), strict=True
    ):
        rows.append(
            {
                "task": f"{paper.row} {paper.column}",
                "our task": task,
                f"DC inverse mean [{paper.unit}]": _to_paper_unit(v_dc, paper.unit),
                f"pinv mean [{paper.unit}]": _to_paper_unit(v_pinv, paper.unit),
                "pinv / DC": _ratio(v_pinv, v_dc),
            }
        )
    found = _find_task(spec, [r"r(ight)?_?hand"], "rot")
    peak = float("nan")
    if found:
        peak = _metric(res, b["run_id"], found[1].replace("mean", "max"), found[0])
    rows.append(
        {
            "task": "T5 right-hand orientation peak (pinv)",
            "our task": found[0] if found else "-",
            "DC inverse mean [rad]": float("nan"),
            "pinv mean [rad]": peak,
            "pinv / DC": float("nan"),
            "paper [rad]": P.TO_OSF_PINV_PEAK_RHAND_ORI.value,
        }
    )
    t.frame = pd.DataFrame(rows)
    t.notes += [
        f"Scenario `{a['scenario']}`, solver {a['solver']}; status: DC inverse "
        f"{_run_status(a)}, pinv {_run_status(b)}.",
        *_length_note(res, a, spec),
        "Paper: errors grow sharply with the pseudo-inverse; right-hand orientation peak "
        "0.988 rad (Fig. 6).",
    ]
    return t


def _amendment_total(res: Results, run: pd.Series, window: tuple[float, float] | None) -> float:
    """Mean over the logged ticks in ``window`` of Σ over tasks of ‖ẍ_opt − ẍ*‖."""
    log = res.log(run["run_id"])
    cols = [c for c in log.columns if c.startswith("diag.amend.")]
    if log.empty or not cols:
        return float("nan")
    if window is not None:
        log = log[(log["t"] >= window[0]) & (log["t"] <= window[1])]
    return float(log[cols].sum(axis=1).mean()) if len(log) else float("nan")


def _weights(res: Results, row: pd.Series) -> list[float] | None:
    """The task weights a to_osf run used: its config override, else its scenario's."""
    try:
        cfg = json.loads(_config(row) or "{}")
    except ValueError:
        cfg = {}
    spec = scenario_spec(res, str(row["scenario"]))
    own = (spec.controllers.get("to_osf") or {}) if spec is not None else {}
    merged = {**own, **cfg}
    weights = merged.get("weights")
    if not weights:
        return None
    if merged.get("weighting") == "identical":  # every task weighted by the first
        weights = weights[:1]
    return [float(w) for w in weights]


def _identical_weighting(res: Results, row: pd.Series) -> bool:
    """A run with one weight for every task (by its config or a name saying so)."""
    if _has(row, "identical") or _has(row, "uniform"):
        return True
    weights = _weights(res, row)
    return weights is not None and len(set(weights)) == 1


def _common_window(
    res: Results, a: pd.Series, b: pd.Series, window: tuple[float, float] | None
) -> tuple[tuple[float, float] | None, str]:
    """The metrics window cut to where both runs have logged ticks, and what was done."""
    ends = []
    for run in (a, b):
        simulated = pd.to_numeric(pd.Series([run.get("sim_duration_s")]), errors="coerce").iloc[0]
        if np.isfinite(simulated):
            ends.append(float(simulated))
            continue
        log = res.log(run["run_id"])
        ends.append(float(log["t"].max()) if not log.empty and "t" in log.columns else 0.0)
    end = min(ends)
    if window is None:
        return (0.0, end), f"t = 0–{end:.3g} s (whole runs)"
    if end >= window[1]:
        return window, f"t = {window[0]:g}–{window[1]:g} s (the paper's window)"
    if end > window[0]:
        return (window[0], end), (
            f"t = {window[0]:g}–{end:.3g} s: a run stopped before the window's end "
            f"({window[1]:g} s)"
        )
    return (0.0, end), (
        f"t = 0–{end:.3g} s: a run stopped before the window ({window[0]:g}–{window[1]:g} s) "
        "began, so the whole common span is compared"
    )


def to_osf_s2(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_s2",
        "TO-OSF Scenario #2: total amendment, priority vs identical weighting",
        "to_osf",
        None,
    )
    runs = _prefer_full(res, _runs(res, "tracking", "lee2021access_s2*", "to_osf"))
    is_ident = [_identical_weighting(res, r) for _, r in runs.iterrows()]
    ident = runs[is_ident] if len(runs) else runs
    prio = runs.drop(ident.index)
    if not ident.empty and not prio.empty:  # a pair of the same scenario length when possible
        same = prio[prio["scenario_hash"].isin(ident["scenario_hash"])]
        if not same.empty:
            prio = same
            ident = ident[ident["scenario_hash"].isin(same["scenario_hash"])]
    if ident.empty or prio.empty:
        t.missing = (
            "Needs `to_osf` on `lee2021access_s2*` with priority weighting and with identical "
            "weighting (the config `{weighting: identical}` or one weight for every task, as "
            "`sweeps/default.yaml` runs)."
        )
        return t
    a, b = prio.iloc[-1], ident.iloc[-1]
    spec = scenario_spec(res, a["scenario"])
    window, how = _common_window(res, a, b, spec.metrics.window if spec is not None else None)
    amend_p, amend_i = _amendment_total(res, a, window), _amendment_total(res, b, window)
    status = {"priority": _run_status(a), "identical": _run_status(b)}
    rows = [
        {
            "quantity": "mean total amendment Σ‖ẍ_opt − ẍ*‖",
            "priority weighting": amend_p,
            "identical weighting": amend_i,
            "ours priority / identical": _ratio(amend_p, amend_i),
            "paper priority / identical": P.TO_OSF_S2_AMENDMENT_RATIO.value,
            "status (priority; identical)": f"{status['priority']}; {status['identical']}",
        }
    ]
    for paper, (task, v_p, _), (_, v_i, _) in zip(
        P.TO_OSF_S1[:4],
        _errors(res, a, spec)[:4],
        _errors(res, b, scenario_spec(res, b["scenario"]))[:4],
        strict=True,
    ):
        rows.append(
            {
                "quantity": f"{paper.row} error ({task}) [{paper.unit}]",
                "priority weighting": _to_paper_unit(v_p, paper.unit),
                "identical weighting": _to_paper_unit(v_i, paper.unit),
                "ours priority / identical": _ratio(v_p, v_i),
                "paper priority / identical": float("nan"),
                "status (priority; identical)": "",
            }
        )
    t.frame = pd.DataFrame(rows)
    weights = {k: _weights(res, r) for k, r in (("priority", a), ("identical", b))}
    t.notes += [
        f"Scenario `{a['scenario']}`, solver {a['solver']}; weights: priority "
        f"{weights['priority']}, identical {weights['identical']}.",
        f"Amendments averaged over {how}; task errors are the runs' metrics window.",
        *_length_note(res, a, spec),
        "Paper: identical weighting gives ≈ 7.5× smaller total amendment; T1/T2 errors "
        "larger, T3/T4 smaller.",
        f"Source: {P.TO_OSF_S2_AMENDMENT_RATIO.source}.",
    ]
    return t


#: Scenario #3's phases [s], half-open: before the hand is asked to move, and once it is
#: asked to hold 0.2 m further forward (the move is t = 11–14 s; the run ends at 16 s)
S3_BEFORE, S3_AFTER = (9.0, 11.0), (14.0, 16.001)
#: the strict hierarchy's tasks that must not move when T3 conflicts, and T3
S3_HIGHER, S3_CONFLICTED = ("com", "trunk", "l_elbow"), "l_hand"


def _phase_mean(log: pd.DataFrame, column: str, window: tuple[float, float]) -> float:
    """The mean of ``column`` over ``window[0] ≤ t < window[1]`` (NaN when nothing is in it)."""
    inside = log[(log["t"] >= window[0]) & (log["t"] < window[1])]
    return float(inside[column].mean()) if len(inside) and column in inside else float("nan")


def to_osf_s3(res: Results) -> PaperTable:
    """Scenario #3: each task's mean error before the conflict and once T3 asks for what T2
    leaves it no room for, strict hierarchy (to_osf) against weighted QP-WBC (qp_wbc)."""
    t = PaperTable(
        "to_osf_s3",
        "TO-OSF Scenario #3: conflicting T3, strict hierarchy vs weighted QP-WBC (Fig. 13 vs 15)",
        "to_osf",
        None,
    )
    picked = []
    for controller in ("to_osf", "qp_wbc"):
        runs = _prefer_full(res, _runs(res, "tracking", "lee2021access_s3*", controller))
        runs = runs[[_full_length(res, r) and not _config(r) for _, r in runs.iterrows()]]
        if not runs.empty:
            picked.append(runs.iloc[-1])
    if len(picked) < 2:
        t.missing = (
            "Run `to_osf` and `qp_wbc` on `lee2021access_s3_conflict` at full length "
            "(`make bench` does)."
        )
        return t
    rows = []
    for run in picked:
        log = res.log(run["run_id"])
        for column in [c for c in log.columns if c.startswith("err.")]:
            task, part = column.split(".")[1:3]
            if task == "posture":
                continue
            before = _phase_mean(log, column, S3_BEFORE)
            after = _phase_mean(log, column, S3_AFTER)
            role = "T3" if task == S3_CONFLICTED else "T1/T2" if task in S3_HIGHER else ""
            rows.append(
                {
                    "controller": run["controller"],
                    "task": f"{task} ({part})",
                    "role": role,
                    "unit": "m" if part == "pos" else "rad",
                    "before": before,
                    "after": after,
                    "after / before": _ratio(after, before),
                }
            )
    t.frame = pd.DataFrame(rows)
    higher = t.frame[t.frame["role"] == "T1/T2"].groupby(["controller", "unit"])["after"].max()
    nan = float("nan")
    ours = "; ".join(
        f"{c} {higher.get((c, 'm'), nan):.2g} m, {higher.get((c, 'rad'), nan):.2g} rad"
        for c in ("to_osf", "qp_wbc")
    )
    t.notes += [
        f"Mean error norms over t = {S3_BEFORE[0]:g}–{S3_BEFORE[1]:g} s (before) and "
        f"{S3_AFTER[0]:g}–{S3_AFTER[1]:g} s (after: T3, the left hand, held 0.2 m forward, "
        "which the elbow pose T2 leaves no room for).",
        "The paper (§IV-C, Fig. 13 vs §V-A, Fig. 15): the strict hierarchy sacrifices T3 and "
        "leaves T1/T2 as they were; the weighted QP-WBC lets T3 pull T1/T2 along. Ours, the "
        f"largest T1/T2 error after: {ours}. (A ratio of errors near round-off, ~1e-9, means "
        "little.)",
        *(f"{r['controller']}: {r['solver']}, status {_run_status(r)}." for r in picked),
    ]
    return t


def s4_runs(res: Results) -> pd.DataFrame:
    """The Scenario #4 timing runs of ``to_osf`` with its default inverse, one setting."""
    runs = _runs(res, "timing", "lee2021access_s4*", "to_osf")
    runs = runs[[_config(r) == "" for _, r in runs.iterrows()]] if not runs.empty else runs
    return _pick_timing(runs, "qpoases")


def to_osf_s4(res: Results) -> PaperTable:
    t = PaperTable("to_osf_s4", "TO-OSF Scenario #4: time vs contacts and tasks", "to_osf", None)
    runs = s4_runs(res)
    if not runs.empty:
        t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = "Run timing of `to_osf` on the `lee2021access_s4*` scenarios."
        return t
    rows = []
    for _, r in runs.iterrows():
        spec = run_spec(res, r)
        row: dict[str, Any] = {
            "scenario": r["scenario"],
            "contact DoF": 6 * len(spec.contacts) if spec else np.nan,
            "tasks": len(spec.tasks) if spec else np.nan,
            "solver": f"{r['solver']} ({r['mode']})",
        }
        for stage in _stages(res, r["run_id"]):
            row[f"{stage} mean [ms]"] = _ms(_metric(res, r["run_id"], f"t_{stage}_mean_us"))
        rows.append(row)
    t.frame = pd.DataFrame(rows).sort_values(["contact DoF", "tasks"], kind="stable")
    t.notes += [
        "Paper: RT-thread QP < 0.5 ms up to 24 contact DoF; non-RT parameters < 2 ms (Fig. 14).",
        _machines(res, "to_osf"),
    ]
    return t


def _stages(res: Results, run_id: Any) -> list[str]:
    m = res.metrics
    names = m[(m["run_id"] == run_id) & (m["task"] == "*")]["metric"]
    stages = [n[2:-8] for n in names if n.startswith("t_") and n.endswith("_mean_us")]
    return list(dict.fromkeys(stages))


def cod_svd_runs(res: Results) -> tuple[pd.Series, pd.Series] | None:
    """The (COD, SVD) timing runs of ``to_osf`` on one scenario, or None."""
    runs = _pick_timing(_runs(res, "timing", "lee2021access_*", "to_osf"), "qpoases")
    if runs.empty:
        return None
    svd = runs[[_has(r, "svd") for _, r in runs.iterrows()]]
    cod = runs[[not _has(r, "svd") and not _has(r, "pinv") for _, r in runs.iterrows()]]
    same = "scenario_hash" if "scenario_hash" in runs.columns else "scenario"
    cod = cod[cod[same].isin(svd[same])]  # the same scenario, tasks and contacts
    if svd.empty or cod.empty:
        return None
    return cod.iloc[-1], svd.iloc[-1]


def to_osf_cod_svd(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_cod_svd",
        "TO-OSF: COD vs SVD dynamically consistent inverse (5 tasks, two feet)",
        "to_osf",
        None,
    )
    runs = _pick_timing(_runs(res, "timing", "lee2021access_*", "to_osf"), "qpoases")
    if not runs.empty:
        t.notes.append(impl_note(runs))
    pair = cod_svd_runs(res)
    if pair is None:
        t.missing = (
            "Needs timing of `to_osf` with the default (COD) and an SVD inverse config on one "
            "`lee2021access_*` scenario."
        )
        return t
    a, b = pair
    rows = []
    for stage in _stages(res, a["run_id"]):
        va = _metric(res, a["run_id"], f"t_{stage}_mean_us")
        vb = _metric(res, b["run_id"], f"t_{stage}_mean_us")
        rows.append(
            {
                "stage": stage,
                "COD [ms]": _ms(va),
                "SVD [ms]": _ms(vb),
                "ours SVD / COD": _ratio(vb, va),
            }
        )
    rows.append(
        {
            "stage": "paper (parameters)",
            "COD [ms]": P.TO_OSF_COD_SVD[0].value,
            "SVD [ms]": P.TO_OSF_COD_SVD[1].value,
            "ours SVD / COD": _ratio(
                P.TO_OSF_COD_SVD[1].value or 0, P.TO_OSF_COD_SVD[0].value or 0
            ),
        }
    )
    t.frame = pd.DataFrame(rows)
    t.notes += [f"Scenario `{a['scenario']}`.", _machines(res, "to_osf")]
    return t


def table3_runs(res: Results) -> pd.DataFrame:
    """The Table 3 timing runs of ``hqp`` and ``to_osf`` (1…5 tasks), one setting."""
    runs = _runs(res, "timing", "lee2021access_*t*3*")
    if runs.empty:
        return runs
    return _pick_timing(runs[runs["controller"].isin(["hqp", "to_osf"])], "qpoases")


def to_osf_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_table3", "TO-OSF Table 3: HQP vs TO-OSF time for 1…5 tasks", "to_osf", None
    )
    runs = table3_runs(res)
    if not runs.empty:
        t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = (
            "Run timing of `hqp` and `to_osf` on the `lee2021access_table3*` scenarios (1…5 tasks)."
        )
        return t
    rows: dict[int, dict[str, Any]] = {}
    for _, r in runs.iterrows():
        spec = run_spec(res, r)
        n = len(spec.tasks) if spec else -1
        row = rows.setdefault(n, {"tasks": n, "paper HQP [ms]": None, "paper TO-OSF [ms]": None})
        row[f"ours {r['controller']} [ms]"] = _ms(_metric(res, r["run_id"], "t_total_mean_us"))
    frame = pd.DataFrame([rows[k] for k in sorted(rows)])
    if {"ours hqp [ms]", "ours to_osf [ms]"} <= set(frame.columns):
        frame["ours HQP / TO-OSF"] = frame["ours hqp [ms]"] / frame["ours to_osf [ms]"]
    t.frame = frame
    t.notes += [P.TO_OSF_TABLE3_NOTE, _machines(res, "to_osf")]
    return t
