"""RC-LQP: Table 3 and the DoF series."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results
from wbcbench.report.tables.common import (
    PaperTable,
    _machines,
    _metric,
    _one_impl,
    _pick_timing,
    _ratio,
    _recorder,
    _robot_dof,
    _run_status,
    _runs,
    impl_note,
    scenario_spec,
)

RC_LQP_COLUMNS = [  # Table 3 column → (our metric per controller, label)
    ("avg", {"lqp": ["t_total_mean_us"], "rc_lqp": ["t_total_mean_us"]}),
    ("max", {"lqp": ["t_total_max_us"], "rc_lqp": ["t_total_max_us"]}),
    ("dyn", {"lqp": ["t_dynamics_mean_us"], "rc_lqp": ["t_dynamics_mean_us", "t_reduced_mean_us"]}),
    ("LQP1", {"rc_lqp": ["t_lqp1_mean_us"]}),
    ("LQP2", {"rc_lqp": ["t_lqp2_mean_us"]}),
    ("QP", {"lqp": ["t_solve_mean_us"], "rc_lqp": ["t_solve_mean_us"]}),
    (
        "QP solver only",
        {
            "lqp": ["t_solve_setup_mean_us", "t_solve_native_mean_us"],
            "rc_lqp": ["t_solve_setup_mean_us", "t_solve_native_mean_us"],
        },
    ),
]


def _support(spec: Any) -> str:
    return "double" if spec is not None and len(spec.contacts) >= 2 else "single"


#: RC-LQP's solver the paper's way (its library's OSQP setting), then the modern way (OSQP hot)
RC_LQP_SOLVERS = ("osqp_libdwbc", "osqp")


def _pick_rc_lqp(runs: pd.DataFrame) -> pd.DataFrame:
    """The Table 3 runs: one per scenario × controller for each of :data:`RC_LQP_SOLVERS` the
    results hold (the paper's way and the modern way side by side), else the usual pick; one impl
    for all."""
    runs = _one_impl(runs)
    present = [s for s in RC_LQP_SOLVERS if (runs["solver"] == s).any()]
    if not present:
        return _pick_timing(runs, "osqp", "lqp")
    return pd.concat([_pick_timing(runs[runs["solver"] == s], s, "lqp") for s in present])


def table3_pairs(res: Results) -> list[tuple[str, str, pd.Series, pd.Series]]:
    """(support, solver, lqp run, rc_lqp run) of Table 3: per support, the paper's way
    (``osqp_libdwbc``) first, then the other solvers by name."""
    runs = _runs(res, "timing", "ahn_*")
    if runs.empty:
        return []
    runs = runs[[("dof" not in str(s)) for s in runs["scenario"]]]
    runs = _pick_rc_lqp(runs[runs["controller"].isin(["lqp", "rc_lqp"])])
    if runs.empty:
        return []
    runs = runs.assign(_support=[_support(scenario_spec(res, s)) for s in runs["scenario"]])
    order = {s: i for i, s in enumerate(RC_LQP_SOLVERS)}
    out = []
    for support in ("double", "single"):
        here = runs[runs["_support"] == support]
        for solver in sorted(set(here["solver"].astype(str)), key=lambda s: (order.get(s, 9), s)):
            group = here[here["solver"] == solver]
            conv, prop = group[group["controller"] == "lqp"], group[group["controller"] == "rc_lqp"]
            if len(conv) and len(prop):
                out.append((support, solver, conv.iloc[0], prop.iloc[0]))
    return out


def dof_runs(res: Results) -> pd.DataFrame:
    """The DoF series' timing runs of ``lqp`` and ``rc_lqp``, one setting."""
    runs = _runs(res, "timing", "ahn_*dof*")
    if runs.empty:
        return runs
    return _pick_timing(runs[runs["controller"].isin(["lqp", "rc_lqp"])], "osqp", "lqp")


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
        runs = _pick_rc_lqp(runs[runs["controller"].isin(["lqp", "rc_lqp"])])
        if not runs.empty:
            t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = (
            "Run timing of `lqp` and `rc_lqp` on the `ahn_*` double- and single-support scenarios "
            "(`record_with: [lqp]`)."
        )
        return t
    rows = []
    intervals: dict[tuple[str, str], dict[str, tuple[float, float]]] = {}
    for _, r in runs.iterrows():
        support = _support(scenario_spec(res, r["scenario"]))
        controller = str(r["controller"])
        method = "conventional" if controller == "lqp" else "proposed"
        ci = (
            _metric(res, r["run_id"], "t_total_median_ci_lo_us"),
            _metric(res, r["run_id"], "t_total_median_ci_hi_us"),
        )
        intervals.setdefault((support, str(r["solver"])), {})[controller] = ci
        paper = P.RC_LQP_TABLE3.get((support, method), {})
        row: dict[str, Any] = {
            "support": support,
            "solver": r["solver"],
            "method": f"{method} ({controller})",
            "run": f"{r['solver']} {r['mode']}, recorded by {_recorder(r) or '?'}, {r['status']}",
        }
        for column, metrics in RC_LQP_COLUMNS:
            names = metrics.get(controller)
            values = [_metric(res, r["run_id"], m) for m in names] if names else []
            row[f"paper {column} [µs]"] = paper.get(column)
            row[f"ours {column} [µs]"] = float(np.sum(values)) if values else np.nan
        rows.append(row)
    order = {s: i for i, s in enumerate(RC_LQP_SOLVERS)}
    frame = pd.DataFrame(rows).sort_values(["support", "method"], kind="stable")
    # one ratio per support, or per support × solver when the paper's way and the modern way
    # are both there
    side_by_side = frame["solver"].isin(RC_LQP_SOLVERS).all() and frame["solver"].nunique() > 1
    group = frame["solver"] if side_by_side else pd.Series("", index=frame.index)
    ratios = []
    for (support_key, solver), g in frame.groupby([frame["support"], group], sort=False):
        support = str(support_key)
        conv = g[g["method"].str.startswith("conventional")]
        prop = g[g["method"].str.startswith("proposed")]
        if not (len(conv) and len(prop)):
            continue
        ratio: dict[str, Any] = {
            "support": support,
            "solver": solver,
            "method": "ratio lqp / rc_lqp",
            "run": "",
        }
        for column in ("avg", "max", "QP", "QP solver only"):
            pc = P.RC_LQP_TABLE3[(support, "conventional")].get(column, np.nan)
            pp = P.RC_LQP_TABLE3[(support, "proposed")].get(column, np.nan)
            ratio[f"paper {column} [µs]"] = pc / pp
            ratio[f"ours {column} [µs]"] = _ratio(
                float(conv[f"ours {column} [µs]"].iloc[0]),
                float(prop[f"ours {column} [µs]"].iloc[0]),
            )
        ratios.append(ratio)
    both = pd.concat([frame, pd.DataFrame(ratios)], ignore_index=True)
    both = both.assign(_s=[order.get(s, len(order)) for s in both["solver"]])
    t.frame = both.sort_values(["support", "_s"], kind="stable").drop(columns="_s")
    t.frame = t.frame.reset_index(drop=True)
    t.notes += [
        "Ratio rows are unitless (conventional / proposed, the paper's speed-up).",
        "Solvers: `osqp_libdwbc` is OSQP the way the paper's library runs it (eps 1e-3, alpha "
        "1.0, warm-started, matrices re-sent every tick), `osqp` OSQP hot at its defaults; the "
        "table has both when the results do (the paper's way first).",
        "Ours: means and maxima of the replayed ticks, the paper's solver (OSQP) when timed; "
        "dyn = the dynamics stage (+ the reduced-dynamics calculation for rc_lqp); LQP1 / LQP2 = "
        "each lexicographic QP's formulation and solve; QP = every call into our QP layer; "
        "QP solver only = the solvers' set-up and native calls (the part the reduced QP sizes "
        "shrink; the rest of a step is Python formulation, see the README's limitations).",
        "Timing runs replay the states of the paper's baseline (`lqp`) when it was recorded.",
        *_overlap_notes(intervals),
        _machines(res, "rc_lqp"),
        f"Source: {P.RC_LQP_TABLE3_SOURCE}.",
    ]
    return t


def _overlap_notes(intervals: dict[tuple[str, str], dict[str, tuple[float, float]]]) -> list[str]:
    """Whether lqp's and rc_lqp's median step intervals (95 %) overlap, per support × solver."""
    notes = []
    for (support, solver), ci in intervals.items():
        if {"lqp", "rc_lqp"} <= set(ci) and all(np.isfinite(v) for c in ci.values() for v in c):
            (a0, a1), (b0, b1) = ci["lqp"], ci["rc_lqp"]
            apart = a1 < b0 or b1 < a0
            notes.append(
                f"{support}, {solver}: median step intervals lqp [{a0:.0f}, {a1:.0f}] µs and "
                f"rc_lqp [{b0:.0f}, {b1:.0f}] µs "
                + ("do not overlap: the difference is real." if apart else "overlap: within noise.")
            )
    return notes


def rc_lqp_dof(res: Results) -> PaperTable:
    t = PaperTable(
        "rc_lqp_dof",
        "RC-LQP DoF scaling (double support): conventional vs reduced-centroidal",
        "rc_lqp",
        None,
    )
    runs = dof_runs(res)
    if not runs.empty:
        t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = (
            "Run timing of `lqp` and `rc_lqp` on `ahn_dof_scaling` for each robot of the DoF "
            "family (`robots: [tocabi_dof20, …, tocabi_dof45]` in a timing matrix)."
        )
        return t
    rows: dict[int, dict[str, Any]] = {}
    for _, r in runs.iterrows():
        dof = _robot_dof(str(r["robot"]))
        paper = P.RC_LQP_DOF.get(dof, {})
        row = rows.setdefault(
            dof,
            {
                "DoF": dof,
                "robot": r["robot"],
                "paper conventional [µs]": paper.get("conventional"),
                "paper proposed [µs]": paper.get("proposed"),
                "ours lqp median [µs]": np.nan,
                "ours rc_lqp median [µs]": np.nan,
                "status": "",
            },
        )
        row[f"ours {r['controller']} median [µs]"] = _metric(res, r["run_id"], "t_total_median_us")
        if r["status"] != "ok":
            row["status"] = f"{row['status']} {r['controller']}: {_run_status(r)}".strip()
    frame = pd.DataFrame([rows[k] for k in sorted(rows)])
    frame["status"] = frame["status"].replace("", "ok")
    frame["paper ratio"] = frame["paper conventional [µs]"] / frame["paper proposed [µs]"]
    frame["ours ratio"] = frame["ours lqp median [µs]"] / frame["ours rc_lqp median [µs]"]
    t.frame = frame
    t.notes += [
        "Ratios: conventional (lqp) / proposed (rc_lqp). Ours: medians of the replayed ticks "
        "(whole step); solver: {} ({}, {}), the paper's (OSQP) when it was timed.".format(
            *runs.iloc[0][["solver", "tier", "mode"]]
        ),
        "The paper's text gives the 20 and 45 DoF end points (Fig. 5).",
        _machines(res, "rc_lqp"),
        f"Source: {P.RC_LQP_DOF_SOURCE}.",
    ]
    return t
