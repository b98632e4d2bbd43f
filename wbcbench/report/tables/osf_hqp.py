"""OSF-HQP: Table III (per level, conventional vs proposed), the same per backend, and
Table II."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results
from wbcbench.report.tables.common import (
    PaperTable,
    _config,
    _levels,
    _machines,
    _metric,
    _ms,
    _one_impl,
    _pick_timing,
    _ratio,
    _runs,
    impl_note,
)

#: the OSF-HQP paper's solver, first among the per-solver verdicts
PAPER_SOLVER = "qpoases"


def table3_pairs(res: Results) -> list[tuple[str, pd.Series, pd.Series]]:
    """(solver, hqp run, osf_hqp run) for every solver that timed both controllers on Table III's
    scenario (OSF-HQP's default config; one impl, tier and mode each): the paper's solver first,
    then by name."""
    runs = _runs(res, "timing", "lee2021iros_table1*")
    if runs.empty:
        return []
    runs = runs[runs["controller"].isin(["hqp", "osf_hqp"])]
    runs = runs[[_config(r) == "" for _, r in runs.iterrows()]]
    out = []
    for solver in sorted(set(runs["solver"].astype(str)), key=lambda s: (s != PAPER_SOLVER, s)):
        picked = _pick_timing(runs[runs["solver"] == solver], solver)
        conv = picked[picked["controller"] == "hqp"]
        prop = picked[picked["controller"] == "osf_hqp"]
        if len(conv) and len(prop):
            out.append((solver, conv.iloc[0], prop.iloc[0]))
    return out


def level_names(res: Results, conv: pd.Series, prop: pd.Series) -> list[tuple[str, str, str]]:
    """(paper level, hqp's level, osf_hqp's level) for Table III's five levels the runs report."""
    lc, lp = _levels(res, conv["run_id"]), _levels(res, prop["run_id"])
    return [
        (label, lc[i], lp[i])
        for i, label in enumerate(P.OSF_HQP_LEVELS[:-1])
        if i < len(lc) and i < len(lp)
    ]


def osf_hqp_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "osf_hqp_table3",
        "OSF-HQP Table III: per-level and total time, conventional HQP vs OSF-HQP",
        "osf_hqp",
        None,
    )
    runs = _runs(res, "timing", "lee2021iros_table1*")
    if not runs.empty:
        runs = runs[runs["controller"].isin(["hqp", "osf_hqp"])]
    runs = _pick_timing(runs, "qpoases")
    if not runs.empty:
        t.notes.append(impl_note(runs))
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
    native = ["t_solve_setup_mean_us", "t_solve_native_mean_us"]
    vc = sum(_metric(res, c["run_id"], m) for m in native)
    vp = sum(_metric(res, p_run["run_id"], m) for m in native)
    rows.append(
        {
            "level": "total, solver only",
            "our levels": "set-up + native call of all QPs",
            "paper conv. [ms]": P.OSF_HQP_TABLE3["conventional"][-1],
            "paper OSF-HQP [ms]": P.OSF_HQP_TABLE3["proposed"][-1],
            "paper ratio": P.OSF_HQP_TABLE3["conventional"][-1] / P.OSF_HQP_TABLE3["proposed"][-1],
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
    t.notes += [
        f"Means over the replayed ticks; solvers: conventional {c['solver']} ({c['mode']}), "
        f"OSF-HQP {p_run['solver']} ({p_run['mode']}). Per level: the whole call into our QP "
        "layer (validation, change detection, the solver's set-up or update, the native call); "
        "'solver only' leaves out our Python layer's share (the paper's includes formulating "
        "the QP).",
        _machines(res, "osf_hqp"),
        f"Source: {P.OSF_HQP_TABLE3_SOURCE}, §V.",
    ]
    return t


def osf_hqp_backends(res: Results) -> PaperTable:
    """Table III's per-level times for every backend × tier × mode that timed both
    controllers, each ratio within one such setting (and one impl)."""
    t = PaperTable(
        "osf_hqp_backends",
        "OSF-HQP Table III per backend: QP time per level, conventional HQP vs OSF-HQP",
        "osf_hqp",
        None,
    )
    runs = _runs(res, "timing", "lee2021iros_table1*")
    if not runs.empty:
        runs = runs[runs["controller"].isin(["hqp", "osf_hqp"])]
        runs = _one_impl(runs[[_config(r) == "" for _, r in runs.iterrows()]])
    rows = []
    if not runs.empty:
        runs = runs.assign(
            tier=runs["tier"].astype(object).fillna("default") if "tier" in runs else "default"
        )
        for (solver, tier, mode), group in runs.groupby(["solver", "tier", "mode"]):
            conv = group[group["controller"] == "hqp"]
            prop = group[group["controller"] == "osf_hqp"]
            if conv.empty or prop.empty:
                continue
            c, p = conv.iloc[0]["run_id"], prop.iloc[0]["run_id"]
            lc, lp = _levels(res, c), _levels(res, p)
            for i, label in enumerate(P.OSF_HQP_LEVELS):
                if label == "total":
                    vc, vp = (_metric(res, r, "t_solve_mean_us") for r in (c, p))
                elif i < len(lc) and i < len(lp):
                    vc = _metric(res, c, "t_solve_mean_us", lc[i])
                    vp = _metric(res, p, "t_solve_mean_us", lp[i])
                else:
                    continue
                rows.append(
                    {
                        "backend": f"{solver} · {mode}"
                        + (f" · {tier}" if tier != "default" else ""),
                        "level": label,
                        "conv. [ms]": _ms(vc),
                        "OSF-HQP [ms]": _ms(vp),
                        "ratio": _ratio(vc, vp),
                    }
                )
    if not rows:
        t.missing = (
            "Run timing of `hqp` and `osf_hqp` on `lee2021iros_table1` with the backends to "
            "compare (`make bench` times daqp, proxqp and osqp)."
        )
        return t
    t.frame = pd.DataFrame(rows)
    t.notes += [
        impl_note(runs),
        f"Paper (qpOASES, C++): all QPs {P.OSF_HQP_TABLE3['conventional'][-1]:.3g} vs "
        f"{P.OSF_HQP_TABLE3['proposed'][-1]:.3g} ms. Means over the replayed ticks; each row "
        "divides times of one backend, tier, mode and impl.",
        _machines(res, "osf_hqp"),
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
    if not runs.empty:
        t.notes.append(impl_note(runs))
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
    t.notes += [
        "Paper: the real robot (Table II); ours: replay of the simulated scenario.",
        _machines(res, "osf_hqp"),
    ]
    return t
