"""Paper tables: the papers' numbers beside ours, with the ratios.

Each table is built from a results folder (:func:`wbcbench.report.load_results`). It finds its
runs by scenario-name pattern and controller name, so scenarios and controllers added later are
picked up as they land; a table whose runs are missing says which runs to make instead of
failing. Absolute times are labelled with the machine they were measured on: the papers' from
:mod:`wbcbench.report.papers`, ours from the folder's provenance.

Timing values are from open-loop replay (``kind = timing``) and prefer, for each controller, the
paper's own solver when it was timed, else the default solver; hot mode before warm before cold.
"""

from __future__ import annotations

import fnmatch
import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results, load_results

MODE_ORDER = ("hot", "warm", "cold")


@dataclass
class PaperTable:
    """One generated table: the frame (None when its runs are missing) and notes."""

    name: str
    title: str
    paper: str
    frame: pd.DataFrame | None
    notes: list[str] = field(default_factory=list)
    missing: str = ""

    def markdown(self) -> str:
        lines = [f"## {self.title}", ""]
        if self.frame is None or self.frame.empty:
            lines += [f"*No results yet.* {self.missing}", ""]
        else:
            lines += [self.frame.to_markdown(index=False, floatfmt=".4g"), ""]
        lines += [f"- {n}" for n in self.notes]
        return "\n".join(lines) + "\n"


# -- selection helpers


def _runs(res: Results, kind: str, scenario: str, controller: str | None = None) -> pd.DataFrame:
    runs = res.of_kind(kind)
    if runs.empty:
        return runs
    sel = runs[[fnmatch.fnmatchcase(str(s), scenario) for s in runs["scenario"]]]
    if controller is not None:
        sel = sel[sel["controller"] == controller]
    return sel[sel["status"].isin(["ok", "failed", "fell"])]


def _config(row: pd.Series) -> str:
    cfg = row.get("controller_config", "{}")
    return "" if pd.isna(cfg) or cfg == "{}" else str(cfg)


def _has(row: pd.Series, word: str) -> bool:
    return word in _config(row).lower() or word in str(row["scenario"]).lower()


def _pick_timing(runs: pd.DataFrame, paper_solver: str) -> pd.DataFrame:
    """One timing run per (scenario, controller, config): paper's solver, else the default."""
    from wbcbench.bench.sweep import default_solver

    if runs.empty:
        return runs
    prefer = [paper_solver.lower(), default_solver()]

    def rank(row: pd.Series) -> tuple[int, int]:
        s = prefer.index(row["solver"]) if row["solver"] in prefer else len(prefer)
        m = MODE_ORDER.index(row["mode"]) if row["mode"] in MODE_ORDER else 3
        return (s, m)

    ranks: list[Any] = [rank(r) for _, r in runs.iterrows()]
    runs = runs.assign(_rank=ranks)
    runs = runs.sort_values("_rank")
    return runs.drop_duplicates(["scenario", "controller", "controller_config"]).drop(
        columns="_rank"
    )


def _metric(res: Results, run_id: Any, metric: str, task: Any = "*") -> float:
    m = res.metrics
    if m.empty:
        return float("nan")
    sel = m[(m["run_id"] == run_id) & (m["metric"] == metric) & (m["task"].astype(str) == task)]
    return float(sel["value"].iloc[0]) if len(sel) else float("nan")


def _levels(res: Results, run_id: Any) -> list[str]:
    """Hierarchy levels a timing run reports, in natural order (level2 before level10)."""
    m = res.metrics
    tasks = m[(m["run_id"] == run_id) & (m["metric"] == "t_solve_mean_us")]["task"].astype(str)
    levels = [t for t in tasks.unique() if t != "*"]
    return sorted(
        levels, key=lambda s: [int(x) if x.isdigit() else x for x in re.split(r"(\d+)", s)]
    )


@cache
def _spec(file: str) -> Any:
    from wbcbench.scenarios.load import load_scenario

    try:
        return load_scenario(file).spec
    except Exception:  # a scenario file since removed or renamed
        return None


def scenario_spec(res: Results, name: str) -> Any:
    """The scenario's spec (from the file provenance names, else the scenarios/ folder)."""
    info = res.provenance.get("scenarios", {}).get(name, {})
    file = info.get("file") or name
    return _spec(file) if Path(file).exists() else _spec(name)


@cache
def _robot_dof(robot: str) -> int:
    from wbcbench.robots.loader import load_robot

    try:
        return int(load_robot(robot).k)
    except Exception:
        digits = re.findall(r"\d+", robot)
        return int(digits[-1]) if digits else -1


def _ratio(a: float, b: float) -> float:
    return a / b if b and np.isfinite(a) and np.isfinite(b) else float("nan")


def _ms(us: float) -> float:
    return us / 1e3


def _machines(res: Results, paper: str) -> str:
    return f"Paper times: {P.PAPERS[paper].machine}. Our times: {res.machine} (Python)."


# -- task matching for tracking tables


def _find_task(spec: Any, patterns: list[str], want: str) -> tuple[str, str] | None:
    """(task name, metric) of the first task whose name or frame matches, for part ``want``.

    ``want`` is ``pos`` or ``rot``; a pose task gives ``err_mean`` for its position and
    ``err_rot_mean`` for its orientation.
    """
    if spec is None:
        return None
    for pattern in patterns:
        for t in sorted(spec.tasks, key=lambda t: t.priority):
            label = f"{t.name} {t.frame or ''}".lower()
            if not re.search(pattern, label) and not (pattern == "com" and t.type == "com"):
                continue
            if want == "pos" and t.type in ("com", "frame_position", "frame_pose"):
                return t.name, "err_mean"
            if want == "rot" and t.type == "frame_orientation":
                return t.name, "err_mean"
            if want == "rot" and t.type == "frame_pose":
                return t.name, "err_rot_mean"
    return None


S1_TASKS = [  # paper row → (name / frame patterns, part)
    (["com"], "pos"),
    ([r"r(ight)?_?hand"], "pos"),
    (["trunk", "pelvis", "waist"], "rot"),
    (["torso", "upper"], "rot"),
    ([r"r(ight)?_?hand"], "rot"),
]


def _errors(res: Results, run: pd.Series, spec: Any) -> list[tuple[str, float, str]]:
    out = []
    for patterns, part in S1_TASKS:
        found = _find_task(spec, patterns, part)
        if found is None:
            out.append(("-", float("nan"), ""))
            continue
        task, metric = found
        value = _metric(res, run["run_id"], metric, task)
        out.append((task, value, metric))
    return out


def _to_paper_unit(value: float, unit: str) -> float:
    return value * 1e3 if unit == "mm" else value


# -- TO-OSF


def to_osf_s1(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_s1", "TO-OSF Scenario #1: mean tracking errors (t = 9–19 s)", "to_osf", None
    )
    runs = _runs(res, "tracking", "lee2021access_s1*", "to_osf")
    runs = runs[[not _has(r, "pinv") and not _has(r, "svd") for _, r in runs.iterrows()]]
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
    t.notes = [
        f"Scenario `{run['scenario']}`, solver {run['solver']}, status {run['status']}.",
        "Paper: COMAN+ in V-REP/Vortex; ours: the COMAN+-like model in MuJoCo (soft contacts).",
        f"Source: {P.TO_OSF_S1[0].source}.",
    ]
    return t


def to_osf_pinv(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_pinv",
        "TO-OSF Scenario #1 ablation: pseudo-inverse vs dynamically consistent inverse",
        "to_osf",
        None,
    )
    runs = _runs(res, "tracking", "lee2021access_s1*", "to_osf")
    pinv = runs[[_has(r, "pinv") for _, r in runs.iterrows()]]
    dc = runs[[not _has(r, "pinv") and not _has(r, "svd") for _, r in runs.iterrows()]]
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
    t.notes = [
        "Paper: errors grow sharply with the pseudo-inverse; right-hand orientation peak "
        "0.988 rad (Fig. 6)."
    ]
    return t


def _amendment_total(res: Results, run: pd.Series, window: tuple[float, float] | None) -> float:
    log = res.log(run["run_id"])
    cols = [c for c in log.columns if c.startswith("diag.amend.")]
    if log.empty or not cols:
        return float("nan")
    if window is not None:
        log = log[(log["t"] >= window[0]) & (log["t"] <= window[1])]
    return float(log[cols].sum(axis=1).mean())


def to_osf_s2(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_s2",
        "TO-OSF Scenario #2: total amendment, priority vs identical weighting",
        "to_osf",
        None,
    )
    runs = _runs(res, "tracking", "lee2021access_s2*", "to_osf")
    ident = runs[[_has(r, "identical") or _has(r, "uniform") for _, r in runs.iterrows()]]
    prio = runs.drop(ident.index)
    if ident.empty or prio.empty:
        t.missing = (
            "Needs `to_osf` on `lee2021access_s2*` with priority weighting and with identical "
            "weighting (a scenario or config named `identical`/`uniform`)."
        )
        return t
    a, b = prio.iloc[-1], ident.iloc[-1]
    spec = scenario_spec(res, a["scenario"])
    window = spec.metrics.window if spec is not None else None
    amend_p, amend_i = _amendment_total(res, a, window), _amendment_total(res, b, window)
    rows = [
        {
            "quantity": "mean total amendment Σ‖ẍ_opt − ẍ*‖",
            "priority weighting": amend_p,
            "identical weighting": amend_i,
            "ours priority / identical": _ratio(amend_p, amend_i),
            "paper priority / identical": P.TO_OSF_S2_AMENDMENT_RATIO.value,
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
            }
        )
    t.frame = pd.DataFrame(rows)
    t.notes = [
        "Paper: identical weighting gives ≈ 7.5× smaller total amendment; T1/T2 errors "
        "larger, T3/T4 smaller."
    ]
    return t


def to_osf_s4(res: Results) -> PaperTable:
    t = PaperTable("to_osf_s4", "TO-OSF Scenario #4: time vs contacts and tasks", "to_osf", None)
    runs = _pick_timing(_runs(res, "timing", "lee2021access_s4*", "to_osf"), "qpoases")
    if runs.empty:
        t.missing = "Run timing of `to_osf` on the `lee2021access_s4*` scenarios."
        return t
    rows = []
    for _, r in runs.iterrows():
        spec = scenario_spec(res, r["scenario"])
        row: dict[str, Any] = {
            "scenario": r["scenario"],
            "contact DoF": 6 * len(spec.contacts) if spec else np.nan,
            "tasks": len(spec.tasks) if spec else np.nan,
            "solver": f"{r['solver']} ({r['mode']})",
        }
        for stage in _stages(res, r["run_id"]):
            row[f"{stage} mean [ms]"] = _ms(_metric(res, r["run_id"], f"t_{stage}_mean_us"))
        rows.append(row)
    t.frame = pd.DataFrame(rows)
    t.notes = [
        "Paper: RT-thread QP < 0.5 ms up to 24 contact DoF; non-RT parameters < 2 ms (Fig. 14).",
        _machines(res, "to_osf"),
    ]
    return t


def _stages(res: Results, run_id: Any) -> list[str]:
    m = res.metrics
    names = m[(m["run_id"] == run_id) & (m["task"] == "*")]["metric"]
    stages = [n[2:-8] for n in names if n.startswith("t_") and n.endswith("_mean_us")]
    return list(dict.fromkeys(stages))


def to_osf_cod_svd(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_cod_svd",
        "TO-OSF: COD vs SVD dynamically consistent inverse (5 tasks, two feet)",
        "to_osf",
        None,
    )
    runs = _pick_timing(_runs(res, "timing", "lee2021access_*", "to_osf"), "qpoases")
    svd = runs[[_has(r, "svd") for _, r in runs.iterrows()]]
    cod = runs[[not _has(r, "svd") and not _has(r, "pinv") for _, r in runs.iterrows()]]
    cod = cod[cod["scenario"].isin(svd["scenario"])]
    if svd.empty or cod.empty:
        t.missing = (
            "Needs timing of `to_osf` with the default (COD) and an SVD inverse config on one "
            "`lee2021access_*` scenario."
        )
        return t
    a, b = cod.iloc[-1], svd.iloc[-1]
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
    t.notes = [f"Scenario `{a['scenario']}`.", _machines(res, "to_osf")]
    return t


def to_osf_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_table3", "TO-OSF Table 3: HQP vs TO-OSF time for 1…5 tasks", "to_osf", None
    )
    runs = _runs(res, "timing", "lee2021access_*t*3*")
    runs = (
        _pick_timing(runs[runs["controller"].isin(["hqp", "to_osf"])], "qpoases")
        if not runs.empty
        else runs
    )
    if runs.empty:
        t.missing = (
            "Run timing of `hqp` and `to_osf` on the `lee2021access_table3*` scenarios (1…5 tasks)."
        )
        return t
    rows: dict[int, dict[str, Any]] = {}
    for _, r in runs.iterrows():
        spec = scenario_spec(res, r["scenario"])
        n = len(spec.tasks) if spec else -1
        row = rows.setdefault(n, {"tasks": n, "paper HQP [ms]": None, "paper TO-OSF [ms]": None})
        row[f"ours {r['controller']} [ms]"] = _ms(_metric(res, r["run_id"], "t_total_mean_us"))
    frame = pd.DataFrame([rows[k] for k in sorted(rows)])
    if {"ours hqp [ms]", "ours to_osf [ms]"} <= set(frame.columns):
        frame["ours HQP / TO-OSF"] = frame["ours hqp [ms]"] / frame["ours to_osf [ms]"]
    t.frame = frame
    t.notes = [P.TO_OSF_TABLE3_NOTE, _machines(res, "to_osf")]
    return t


# -- OSF-HQP


def osf_hqp_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "osf_hqp_table3",
        "OSF-HQP Table III: per-level and total time, conventional HQP vs OSF-HQP",
        "osf_hqp",
        None,
    )
    runs = _pick_timing(_runs(res, "timing", "lee2021iros_table1*"), "qpoases")
    conv = runs[runs["controller"] == "hqp"] if not runs.empty else runs
    prop = runs[runs["controller"] == "osf_hqp"] if not runs.empty else runs
    if conv.empty or prop.empty:
        t.missing = (
            "Run timing of `hqp` and `osf_hqp` on `lee2021iros_table1` "
            "(`wbcbench sweep sweeps/full.yaml`)."
        )
        return t
    c = conv.iloc[0]
    p = prop[[_config(r) == "" for _, r in prop.iterrows()]]
    p_run = p.iloc[0] if not p.empty else prop.iloc[0]
    lc, lp = _levels(res, c["run_id"]), _levels(res, p_run["run_id"])
    rows = []
    for i, label in enumerate(P.OSF_HQP_LEVELS):
        if label == "total":
            vc = _metric(res, c["run_id"], "t_solve_mean_us")
            vp = _metric(res, p_run["run_id"], "t_solve_mean_us")
        else:
            vc = _metric(res, c["run_id"], "t_solve_mean_us", lc[i]) if i < len(lc) else np.nan
            vp = _metric(res, p_run["run_id"], "t_solve_mean_us", lp[i]) if i < len(lp) else np.nan
        pc, pp = P.OSF_HQP_TABLE3["conventional"][i], P.OSF_HQP_TABLE3["proposed"][i]
        rows.append(
            {
                "level": label,
                "our levels": f"{lc[i] if i < len(lc) else '-'} / {lp[i] if i < len(lp) else '-'}"
                if label != "total"
                else "all QPs",
                "paper conv. [ms]": pc,
                "paper OSF-HQP [ms]": pp,
                "paper ratio": pc / pp,
                "ours conv. [ms]": _ms(vc),
                "ours OSF-HQP [ms]": _ms(vp),
                "ours ratio": _ratio(vc, vp),
            }
        )
    vc = _metric(res, c["run_id"], "t_total_mean_us")
    vp = _metric(res, p_run["run_id"], "t_total_mean_us")
    rows.append(
        {
            "level": "whole step, single thread",
            "our levels": "dynamics + build + solve",
            "paper conv. [ms]": P.OSF_HQP_TABLE3["conventional"][-1],
            "paper OSF-HQP [ms]": P.OSF_HQP_SINGLE_THREAD[1].value,
            "paper ratio": P.OSF_HQP_SINGLE_THREAD[2].value,
            "ours conv. [ms]": _ms(vc),
            "ours OSF-HQP [ms]": _ms(vp),
            "ours ratio": _ratio(vc, vp),
        }
    )
    for _, r in prop.iterrows():
        if _config(r) == "":
            continue
        v = _metric(res, r["run_id"], "t_total_mean_us")
        rows.append(
            {
                "level": f"whole step, {_config(r)}",
                "our levels": "control loop",
                "paper conv. [ms]": np.nan,
                "paper OSF-HQP [ms]": P.OSF_HQP_TABLE3["proposed"][-1],
                "paper ratio": P.OSF_HQP_SINGLE_THREAD[3].value,
                "ours conv. [ms]": _ms(vc),
                "ours OSF-HQP [ms]": _ms(v),
                "ours ratio": _ratio(vc, v),
            }
        )
    t.frame = pd.DataFrame(rows)
    t.notes = [
        f"Means over the replayed ticks; solvers: conventional {c['solver']} ({c['mode']}), "
        f"OSF-HQP {p_run['solver']} ({p_run['mode']}). Per level: the QP solver's wall time "
        "(the paper's includes formulating the QP).",
        _machines(res, "osf_hqp"),
        f"Source: {P.OSF_HQP_TABLE3_SOURCE}, §V.",
    ]
    return t


def osf_hqp_table2(res: Results) -> PaperTable:
    t = PaperTable(
        "osf_hqp_table2",
        "OSF-HQP Table II: OSF-HQP per-level time, min / max / average",
        "osf_hqp",
        None,
    )
    runs = _pick_timing(_runs(res, "timing", "lee2021iros_table1*", "osf_hqp"), "qpoases")
    runs = runs[[_config(r) == "" for _, r in runs.iterrows()]] if not runs.empty else runs
    if runs.empty:
        t.missing = "Run timing of `osf_hqp` on `lee2021iros_table1`."
        return t
    r = runs.iloc[0]
    levels = _levels(res, r["run_id"])
    rows = []
    for i, label in enumerate(P.OSF_HQP_LEVELS):
        task = "*" if label == "total" else (levels[i] if i < len(levels) else None)
        row: dict[str, Any] = {"level": label, "our level": task or "-"}
        for stat, ours in (("min", "min"), ("max", "max"), ("average", "mean")):
            row[f"paper {stat} [ms]"] = P.OSF_HQP_TABLE2[stat][i]
            row[f"ours {stat} [ms]"] = (
                _ms(_metric(res, r["run_id"], f"t_solve_{ours}_us", task)) if task else np.nan
            )
        rows.append(row)
    t.frame = pd.DataFrame(rows)
    t.notes = [
        "Paper: the real robot (Table II); ours: replay of the simulated scenario.",
        _machines(res, "osf_hqp"),
    ]
    return t


# -- RC-LQP


def rc_lqp_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "rc_lqp_table3",
        "RC-LQP Table 3: conventional LQP vs reduced-centroidal LQP",
        "rc_lqp",
        None,
    )
    runs = _runs(res, "timing", "ahn_*")
    if not runs.empty:
        runs = runs[[("dof" not in str(s)) for s in runs["scenario"]]]
        runs = _pick_timing(runs[runs["controller"].isin(["lqp", "rc_lqp"])], "osqp")
    if runs.empty:
        t.missing = (
            "Run timing of `lqp` and `rc_lqp` on the `ahn_*` double- and single-support scenarios."
        )
        return t
    rows = []
    for _, r in runs.iterrows():
        spec = scenario_spec(res, r["scenario"])
        support = "double" if spec is not None and len(spec.contacts) >= 2 else "single"
        method = "conventional" if r["controller"] == "lqp" else "proposed"
        paper = P.RC_LQP_TABLE3.get((support, method), {})
        levels = _levels(res, r["run_id"])
        rows.append(
            {
                "support": support,
                "method": method,
                "scenario": r["scenario"],
                "paper avg [µs]": paper.get("avg"),
                "ours avg [µs]": _metric(res, r["run_id"], "t_total_mean_us"),
                "paper max [µs]": paper.get("max"),
                "ours max [µs]": _metric(res, r["run_id"], "t_total_max_us"),
                "paper dyn [µs]": paper.get("dyn"),
                "ours dyn [µs]": _metric(res, r["run_id"], "t_dynamics_mean_us"),
                "paper LQP1 [µs]": paper.get("LQP1"),
                "ours level 1 [µs]": _metric(res, r["run_id"], "t_solve_mean_us", levels[0])
                if levels
                else np.nan,
                "paper LQP2 [µs]": paper.get("LQP2"),
                "ours level 2 [µs]": _metric(res, r["run_id"], "t_solve_mean_us", levels[1])
                if len(levels) > 1
                else np.nan,
            }
        )
    frame = pd.DataFrame(rows).sort_values(["support", "method"])
    ratios = []
    for support_key, g in frame.groupby("support"):
        support = str(support_key)
        conv, prop = g[g["method"] == "conventional"], g[g["method"] == "proposed"]
        if len(conv) and len(prop):
            pc, pp = (
                P.RC_LQP_TABLE3[(support, "conventional")]["avg"],
                P.RC_LQP_TABLE3[(support, "proposed")]["avg"],
            )
            ratios.append(
                {
                    "support": support,
                    "method": "conventional / proposed",
                    "paper avg [µs]": pc / pp,
                    "ours avg [µs]": conv["ours avg [µs]"].iloc[0] / prop["ours avg [µs]"].iloc[0],
                }
            )
    t.frame = pd.concat([frame, pd.DataFrame(ratios)], ignore_index=True)
    t.notes = [
        "Ratio rows compare averages (unitless).",
        _machines(res, "rc_lqp"),
        f"Source: {P.RC_LQP_TABLE3_SOURCE}.",
    ]
    return t


def rc_lqp_dof(res: Results) -> PaperTable:
    t = PaperTable(
        "rc_lqp_dof",
        "RC-LQP DoF scaling (double support): conventional vs reduced-centroidal",
        "rc_lqp",
        None,
    )
    runs = _runs(res, "timing", "ahn_*dof*")
    if not runs.empty:
        runs = _pick_timing(runs[runs["controller"].isin(["lqp", "rc_lqp"])], "osqp")
    if runs.empty:
        t.missing = "Run timing of `lqp` and `rc_lqp` on the `ahn_*dof*` scenarios (20…45 DoF)."
        return t
    rows: dict[int, dict[str, Any]] = {}
    for _, r in runs.iterrows():
        dof = _robot_dof(str(r["robot"]))
        paper = P.RC_LQP_DOF.get(dof, {})
        row = rows.setdefault(
            dof,
            {
                "DoF": dof,
                "paper conventional [µs]": paper.get("conventional"),
                "paper proposed [µs]": paper.get("proposed"),
            },
        )
        key = "conventional" if r["controller"] == "lqp" else "proposed"
        row[f"ours {key} [µs]"] = _metric(res, r["run_id"], "t_total_mean_us")
    frame = pd.DataFrame([rows[k] for k in sorted(rows)])
    frame["paper ratio"] = frame["paper conventional [µs]"] / frame["paper proposed [µs]"]
    if {"ours conventional [µs]", "ours proposed [µs]"} <= set(frame.columns):
        frame["ours ratio"] = frame["ours conventional [µs]"] / frame["ours proposed [µs]"]
    t.frame = frame
    t.notes = [
        "The paper's text gives the 20 and 45 DoF end points (Fig. 5).",
        _machines(res, "rc_lqp"),
    ]
    return t


# -- RQR-HQP


def rqr_fig1(res: Results) -> PaperTable:
    from wbcbench.bench.timing import HLS_SCENARIO

    t = PaperTable("rqr_fig1", "RQR-HQP Fig. 1: hierarchy time vs problem size N", "rqr_hqp", None)
    runs = _runs(res, "timing", HLS_SCENARIO)
    if runs.empty:
        t.missing = "Run a sweep with an `hls_scaling` section (`sweeps/default.yaml` has one)."
        return t
    m = res.metrics[
        res.metrics["run_id"].isin(runs["run_id"]) & (res.metrics["metric"] == "t_solve_median_us")
    ]
    wide = m.pivot_table(index="task", columns="controller", values="value", aggfunc="first")
    wide.index = [int(str(i).split("=")[1]) for i in wide.index]
    wide = wide.sort_index()
    frame = pd.DataFrame({"N": wide.index})
    for algo in wide.columns:
        frame[f"{algo} median [µs]"] = wide[algo].to_numpy()
    if "reduced_qr" in wide.columns:
        for algo in wide.columns:
            if algo != "reduced_qr":
                frame[f"{algo} / reduced_qr"] = (wide[algo] / wide["reduced_qr"]).to_numpy()
    t.frame = frame
    t.notes = [P.RQR_FIG1_NOTE, _machines(res, "rqr_hqp")]
    return t


TABLES: dict[str, Callable[[Results], PaperTable]] = {
    "to_osf_s1": to_osf_s1,
    "to_osf_pinv": to_osf_pinv,
    "to_osf_s2": to_osf_s2,
    "to_osf_s4": to_osf_s4,
    "to_osf_cod_svd": to_osf_cod_svd,
    "to_osf_table3": to_osf_table3,
    "osf_hqp_table3": osf_hqp_table3,
    "osf_hqp_table2": osf_hqp_table2,
    "rc_lqp_table3": rc_lqp_table3,
    "rc_lqp_dof": rc_lqp_dof,
    "rqr_fig1": rqr_fig1,
}


def build_tables(res: Results | str | Path) -> list[PaperTable]:
    """Every paper table from a results folder (or loaded results)."""
    if not isinstance(res, Results):
        res = load_results(res)
    out = []
    for name, fn in TABLES.items():
        try:
            out.append(fn(res))
        except Exception as exc:  # one table's bug must not hide the others
            out.append(PaperTable(name, name, "", None, missing=f"could not be built: {exc}"))
    return out


def write_tables(folder: str | Path) -> Path:
    """``tables/<name>.md`` and ``.csv`` for each table, and ``tables/papers.md`` with all."""
    res = load_results(folder)
    out = Path(folder) / "tables"
    out.mkdir(exist_ok=True)
    tables = build_tables(res)
    parts = [
        "# The papers' numbers beside ours",
        "",
        f"Our results: {res.machine}; wbcbench {res.provenance.get('wbcbench', '?')} @ "
        f"{res.provenance.get('git_commit', '?')}, {res.provenance.get('date', '?')}. "
        "Compare ratios; absolute times come from different CPUs and languages (the papers: C++).",
        "",
    ]
    for table in tables:
        md = table.markdown()
        (out / f"{table.name}.md").write_text(md)
        if table.frame is not None:
            table.frame.to_csv(out / f"{table.name}.csv", index=False)
        parts.append(md)
    path = out / "papers.md"
    path.write_text("\n".join(parts))
    (out / "index.json").write_text(
        json.dumps(
            {t.name: {"title": t.title, "has_results": t.frame is not None} for t in tables},
            indent=2,
        )
        + "\n"
    )
    return path
