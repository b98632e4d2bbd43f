"""Figures a reader of the papers expects, from a results folder (PNG and SVG).

Importing this module chooses no matplotlib backend, so a notebook keeps its inline plots; the
command line (``wbcbench plots``) writes the files with the Agg backend. Every timing figure
names its solver, leaves failed runs out of its axis scaling (and marks them), and is in µs.

* ``tracking_<scenario>``: tracking-error norms over time per task, one line per controller;
* ``amendments_<scenario>``: TO-OSF amendment norms ``‖ẍ_opt − ẍ*‖`` per task;
* ``time_vs_size``: median step time against the number of tasks, contacts and DoF;
* ``levels``: mean QP time per hierarchy level and controller, with its solver;
* ``timing_solvers``: median step time per controller and solver, over the scenarios every
  solver of a row ran (the count in each cell);
* ``solvers_success`` / ``solvers_time``: the solver comparison, heatmaps of solver × setting;
* ``rqr_fig1``: hierarchy time against the problem size N;
* ``peers_kinematic``: kin_hqp beside pink and mink: the top level's error and residual while a
  lower level conflicts (rqr_gaze), the collision distance on rqr_stress, and time per tick;
* ``walk_<scenario>``: a walk seen from above: footprints, the planned ZMP, DCM and CoM, and
  the simulated CoM and CoP of one run (:mod:`wbcbench.report.walking`);
* ``degradation``: tracking error against mass error, sensing noise and delay
  (:mod:`wbcbench.report.robustness`);
* ``paper_*``: each paper's key comparison beside the paper's numbers
  (:mod:`wbcbench.report.paper_figures`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import LogNorm, Normalize
from matplotlib.ticker import FuncFormatter, MaxNLocator

from wbcbench.report.load import Results, load_results
from wbcbench.tasks.tasks import ERROR_UNITS

__all__ = [
    "hls_figure",
    "level_figure",
    "size_figures",
    "solver_figures",
    "timing_solver_figure",
    "tracking_figures",
    "walk_figures",
    "write_plots",
]

MAX_POINTS = 800  # per line: keeps the SVG files small


def _save(fig: Any, out: Path, name: str) -> list[Path]:
    # leave the suptitle its own band (tight_layout alone lets the top axes' labels reach it)
    top = 1.0 - 0.32 / fig.get_figheight() if getattr(fig, "_suptitle", None) else 1.0
    fig.tight_layout(rect=(0.0, 0.0, 1.0, top))
    paths = [out / f"{name}.png", out / f"{name}.svg"]
    for p in paths:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return paths


def _label(row: pd.Series) -> str:
    cfg = row.get("controller_config", "{}")
    cfg = "" if pd.isna(cfg) or cfg == "{}" else f" {cfg}"
    return f"{row['controller']}{cfg} ({row['solver']})"


def _labels(rows: list[pd.Series]) -> list[str]:
    """:func:`_label` of each row, with the simulated duration where two would read the same
    (e.g. a shortened health check beside the full-length run)."""
    labels = [_label(r) for r in rows]
    return [
        f"{label}, {float(r.get('sim_duration_s', float('nan'))):g} s"
        if labels.count(label) > 1
        else label
        for label, r in zip(labels, rows, strict=True)
    ]


LINESTYLES = ("-", "--", ":", "-.")


def _style(k: int) -> dict[str, Any]:
    """The k-th series' colour and line style: ten colours × four styles before a repeat."""
    return {"color": plt.get_cmap("tab10")(k % 10), "linestyle": LINESTYLES[(k // 10) % 4]}


def _window(res: Results, scenario: str) -> tuple[float, float] | None:
    from wbcbench.report.tables import scenario_spec

    spec = scenario_spec(res, scenario)
    return None if spec is None or spec.metrics.window is None else tuple(spec.metrics.window)


def _shade(ax: Any, window: tuple[float, float] | None) -> None:
    if window is not None:
        ax.axvspan(*window, color="#f2e6b3", alpha=0.5, lw=0, zorder=0)


def _window_in_data(
    window: tuple[float, float] | None, logs: list[pd.DataFrame]
) -> tuple[tuple[float, float] | None, str]:
    """The metrics window cut to the time the logs cover, and the words for the title.

    A shortened run (a health check) may end before the scenario's window starts: then nothing
    is shaded and the title says where the window lies."""
    if window is None:
        return None, ""
    times = [lg["t"] for lg in logs if "t" in lg.columns and not lg.empty]
    if not times:
        return None, ""
    lo, hi = (
        max(window[0], min(float(t.min()) for t in times)),
        min(window[1], max(float(t.max()) for t in times)),
    )
    if lo >= hi:
        return None, f"metrics window {window[0]:g}–{window[1]:g} s: beyond these runs"
    if (lo, hi) != tuple(window):
        return (lo, hi), f"shaded: the metrics window {window[0]:g}–{window[1]:g} s where logged"
    return (lo, hi), "shaded: metrics window"


def _thin(df: pd.DataFrame) -> pd.DataFrame:
    step = max(1, len(df) // MAX_POINTS)
    return df.iloc[::step]


def tracking_figures(res: Results, out: Path) -> list[Path]:
    paths: list[Path] = []
    runs = res.of_kind("tracking")
    if runs.empty:
        return paths
    # perturbed runs have their own figure (wbcbench.report.robustness)
    if "settings" in runs:
        runs = runs[~runs["settings"].fillna("").astype(str).str.contains('"perturbations"')]
    for scenario, group in runs.groupby("scenario"):
        logs = [(row, res.log(row["run_id"])) for _, row in group.iterrows()]
        logs = [(r, lg) for r, lg in logs if not lg.empty]
        if not logs:
            continue
        # a run that fell or failed says so in its label
        labels = [
            label if row["status"] == "ok" else f"{label} — {row['status']}"
            for label, (row, _) in zip(_labels([row for row, _ in logs]), logs, strict=True)
        ]
        err_cols = sorted({c for _, lg in logs for c in lg.columns if c.startswith("err.")})
        window, window_note = _window_in_data(_window(res, str(scenario)), [lg for _, lg in logs])
        if err_cols:
            fig, axes = plt.subplots(
                len(err_cols), 1, figsize=(8, 1.7 * len(err_cols) + 0.8), sharex=True, squeeze=False
            )
            for ax, col in zip(axes[:, 0], err_cols, strict=True):
                task, part = col.split(".")[1:3]
                for k, ((_, lg), label) in enumerate(zip(logs, labels, strict=True)):
                    if col in lg.columns:
                        d = _thin(lg)
                        y = d[col].where(d[col] > 0)  # a log axis: exact zeros are not drawn
                        ax.plot(d["t"], y, label=label, lw=1, **_style(k))
                name = task if part == task else f"{task} ({part})"
                ax.set_ylabel(f"{name}\n[{ERROR_UNITS.get(part, '-')}] (log)", fontsize=8)
                ax.set_yscale("log")
                ax.grid(alpha=0.3, which="both")
                _shade(ax, window)
            axes[-1, 0].set_xlabel("time [s]")
            axes[0, 0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
            note = f" ({window_note})" if window_note else ""
            fig.suptitle(f"Tracking-error norms — {scenario}{note}", fontsize=10)
            paths += _save(fig, out, f"tracking_{scenario}")
        amend = sorted({c for _, lg in logs for c in lg.columns if c.startswith("diag.amend.")})
        if amend:
            fig, ax = plt.subplots(figsize=(8, 3.2))
            k = 0
            for (_, lg), label in zip(logs, labels, strict=True):
                d = _thin(lg)
                for c in amend:
                    if c in d.columns:
                        ax.plot(
                            d["t"],
                            d[c].where(d[c] > 0),
                            lw=1,
                            label=f"{c.removeprefix('diag.amend.')} — {label}",
                            **_style(k),
                        )
                        k += 1
            ax.set_xlabel("time [s]")
            ax.set_ylabel("‖ẍ_opt − ẍ*‖ [m/s² or rad/s²] (log)")
            ax.set_yscale("log")  # a fall's spike does not flatten the rest
            note = f" ({window_note})" if window_note else ""
            ax.set_title(f"Task-acceleration amendments — {scenario}{note}", fontsize=9)
            ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0))
            ax.grid(alpha=0.3, which="both")
            _shade(ax, window)
            paths += _save(fig, out, f"amendments_{scenario}")
    return paths


def _timing_table(res: Results) -> pd.DataFrame:
    """Timing runs with their mean total and the scenario's size (tasks, contacts, DoF)."""
    from wbcbench.report.tables import _impl_of, _robot_dof, scenario_spec

    runs = res.of_kind("timing")
    if runs.empty or res.metrics.empty:
        return pd.DataFrame()
    runs = runs[runs["robot"] != "-"]
    # a controller's two impls are two series, never one
    impl = _impl_of(runs)
    runs = runs.assign(impl=impl, series=runs["controller"] + " (" + impl + ")")
    m = res.metrics[(res.metrics["task"] == "*")]
    med = m[m["metric"] == "t_total_median_us"].set_index("run_id")["value"]
    rows = []
    for _, r in runs.iterrows():
        if r["run_id"] not in med.index:
            continue
        spec = scenario_spec(res, r["scenario"])
        rows.append(
            {
                **r.to_dict(),
                "median_us": float(med.loc[r["run_id"]]),
                "tasks": len(spec.tasks) if spec else np.nan,
                "contacts": len(spec.contacts) if spec else np.nan,
                "dof": _robot_dof(str(r["robot"])),
            }
        )
    return pd.DataFrame(rows)


def size_figures(res: Results, out: Path) -> list[Path]:
    t = _timing_table(res)
    if t.empty:
        return []
    from wbcbench.qp.registry import default_solver

    t = t[~_failed(t)]  # a failed run's times are no timing of the controller
    t = (
        t[(t["solver"] == default_solver()) & (t["mode"] == "hot")]
        if (t["mode"] == "hot").any()
        else t
    )
    if t.empty:
        return []
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.4), sharey=True)
    for ax, (col, label) in zip(
        axes,
        (("tasks", "number of tasks"), ("contacts", "number of contacts"), ("dof", "actuated DoF")),
        strict=True,
    ):
        for name, g in t.groupby("series"):
            series = g.groupby(col)["median_us"].median().sort_index()
            # markers only: points of different scenarios differ in more than this size
            ax.plot(series.index, series.to_numpy(), "o", label=name, alpha=0.8)
        ax.set_xlabel(label)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("median step time [µs] (log)")
    axes[0].set_yscale("log")
    axes[0].yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axes[0].yaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axes[-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.suptitle(
        f"Compute time vs problem size ({default_solver()}, hot, open-loop replay; "
        "runs that failed left out)",
        fontsize=10,
    )
    return _save(fig, out, "time_vs_size")


def _heatmap(
    ax: Any,
    values: pd.DataFrame,
    text: pd.DataFrame,
    norm: Any,
    cmap: str,
    colorbar_label: str,
) -> None:
    """``values`` as coloured cells (rows × columns) with ``text`` written in each; a missing
    value is a grey cell with its text (e.g. ``failed``) or a dash."""
    data = np.ma.masked_invalid(values.to_numpy(dtype=float))
    colours = plt.get_cmap(cmap).with_extremes(bad="#e0e0e0")
    image = ax.imshow(data, cmap=colours, norm=norm, aspect="auto")
    for i in range(values.shape[0]):
        for j in range(values.shape[1]):
            cell = data[i, j]
            dark = not np.ma.is_masked(cell) and norm(float(cell)) < 0.35
            ax.text(
                j,
                i,
                text.iat[i, j] or "–",
                ha="center",
                va="center",
                fontsize=7,
                color="white" if dark else "black",
            )
    ax.set_xticks(range(values.shape[1]), [str(c) for c in values.columns], rotation=35, ha="right")
    ax.set_yticks(range(values.shape[0]), [str(r) for r in values.index])
    ax.tick_params(labelsize=8)
    ax.figure.colorbar(image, ax=ax, label=colorbar_label, fraction=0.04, pad=0.02)


def _log_norm(values: pd.DataFrame) -> Any:
    """A logarithmic colour scale over the finite positive values (any scale when none)."""
    v = values.to_numpy(dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return LogNorm(vmin=1.0, vmax=10.0)
    return LogNorm(vmin=float(v.min()), vmax=max(float(v.max()), float(v.min()) * 1.01))


def _failed(runs: pd.DataFrame) -> pd.Series:
    """Whether each run failed (its numbers are not a timing of a working controller)."""
    return runs["status"].astype(str) != "ok"


def level_figure(res: Results, out: Path) -> list[Path]:
    runs = res.of_kind("timing")
    if runs.empty:
        return []
    m = res.metrics[
        res.metrics["run_id"].isin(runs["run_id"]) & (res.metrics["metric"] == "t_solve_mean_us")
    ]
    m = m[m["task"] != "*"]
    if m.empty:
        return []
    from wbcbench.report.tables import _impl_of, _pick_timing

    picked = _pick_timing(runs[runs["run_id"].isin(m["run_id"])], "qpoases")
    m = m[m["run_id"].isin(picked["run_id"])]
    # one facet per hierarchical controller, its scenarios side by side, its levels stacked
    controllers = sorted(picked["controller"].unique())
    ncols = min(3, len(controllers))
    nrows = -(-len(controllers) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.6 * ncols, 4.6 * nrows), squeeze=False)
    for ax in axes.ravel()[len(controllers) :]:
        ax.set_visible(False)
    for ax, controller in zip(axes.ravel(), controllers, strict=False):
        # one bar per scenario (a scenario's variants and robots: its first)
        runs_c = picked[picked["controller"] == controller].drop_duplicates("scenario")
        scenarios = [str(s) for s in runs_c["scenario"]]
        failed = _failed(runs_c).to_numpy()
        levels = sorted(m[m["run_id"].isin(runs_c["run_id"])]["task"].astype(str).unique())
        bottom = np.zeros(len(runs_c))
        for k, level in enumerate(levels):
            vals = np.array(
                [
                    float(m[(m["run_id"] == rid) & (m["task"] == level)]["value"].sum())
                    for rid in runs_c["run_id"]
                ]
            )
            vals[failed] = 0.0  # a failed run's times are not drawn, nor scale the axis
            ax.bar(range(len(vals)), vals, bottom=bottom, label=level, color=_level_color(k))
            bottom += vals
        for x, (_, run) in enumerate(runs_c.iterrows()):
            if failed[x]:
                ax.annotate(
                    f"✗ {run['status']}\n{int(run['failures'])}/{int(run['ticks'])} ticks",
                    (x, 0),
                    xytext=(0, 4),
                    textcoords="offset points",
                    ha="center",
                    va="bottom",
                    fontsize=6,
                    color="#b00020",
                    rotation=90,
                )
        ax.set_xticks(range(len(scenarios)), scenarios, rotation=35, ha="right", fontsize=7)
        setting = runs_c.iloc[0]
        ax.set_title(
            f"{controller} — {setting['solver']} ({setting['tier']}, {setting['mode']})",
            fontsize=9,
        )
        ax.set_ylabel("mean QP time per level [µs]", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.0, 1.0), title="level")
    impl = ", ".join(sorted(set(_impl_of(picked))))
    fig.suptitle(
        f"Per-level QP solve time, stacked (impl: {impl}; ✗: a failed run, not drawn)", fontsize=10
    )
    return _save(fig, out, "levels")


def _level_color(k: int) -> Any:
    return plt.get_cmap("tab20")(k % 20)


def solver_cells(t: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, set[str]]:
    """The cells of the solver heatmap from timing rows (``label``, ``solver``, ``scenario``,
    ``status``, ``median_us``): each row label × solver's median over the row's scenario set,
    its text (value, ``n``, ``*`` when over the solver's own set) and the scenarios used (see
    :func:`timing_solver_figure`)."""
    t = t.assign(failed=_failed(t))
    rows, solvers = sorted(t["label"].unique()), sorted(t["solver"].unique())
    values = pd.DataFrame(np.nan, index=rows, columns=solvers)
    text = pd.DataFrame("", index=rows, columns=solvers)
    used: set[str] = set()
    for label, g in t.groupby("label"):
        ok = g[~g["failed"]]
        sets = {str(solver): set(s["scenario"]) for solver, s in ok.groupby("solver")}
        broad = [v for v in sets.values() if len(v) > 1] or list(sets.values())
        common = set.intersection(*broad) if broad else set()
        used |= common
        for solver, s in g.groupby("solver"):
            mine = sets.get(str(solver), set())
            own = not (common and common <= mine)
            good = s[~s["failed"] & s["scenario"].isin(mine if own else common)]
            if good.empty:
                text.loc[label, solver] = "failed" if s["failed"].all() else ""
                continue
            value = float(good.groupby("scenario")["median_us"].median().median())
            values.loc[label, solver] = value
            n = good["scenario"].nunique()
            text.loc[label, solver] = f"{value:.0f}\nn={n}{'*' if own else ''}"
    return values, text, used


def timing_solver_figure(res: Results, out: Path) -> list[Path]:
    """Median step time per controller (impl) · mode and solver, as a heatmap.

    A row's cells are medians over the same scenarios, the row's set: those that every solver
    of the row timed on more than one scenario timed without failing (the count in each cell),
    so a solver timed on one easy scenario is never set beside one timed on fourteen as if
    alike. A solver timed on fewer scenarios than the row's set (such as the one-scenario run of
    every native backend) shows its median over its own, marked ``*``. A combination whose every
    run failed reads ``failed``."""
    t = _timing_table(res)
    if t.empty:
        return []
    values, text, used = solver_cells(t.assign(label=t["series"] + " · " + t["mode"]))
    rows, solvers = list(values.index), list(values.columns)
    fig, ax = plt.subplots(figsize=(1.0 * len(solvers) + 4.5, 0.42 * len(rows) + 1.8))
    norm = _log_norm(values)
    _heatmap(ax, values, text, norm, "viridis", "median step time [µs] (log)")
    ax.set_xlabel("solver")
    ax.set_ylabel("controller (impl) · mode")
    ax.set_title(
        "Open-loop replay: median step time [µs] per solver; n = the scenarios of the median, the\n"
        "same for every solver of a row that timed more than one (those each timed without a "
        "failure);\n* = a solver timed on fewer, over its own"
        + (f":\n{', '.join(sorted(used))}" if 0 < len(used) <= 4 else ""),
        fontsize=9,
    )
    return _save(fig, out, "timing_solvers")


def _setting_order(labels: list[str]) -> list[str]:
    from wbcbench.report.tables.common import MODE_ORDER, TIER_ORDER

    def key(label: str) -> tuple[int, int, str]:
        tier, _, mode = label.partition(" · ")
        return (
            TIER_ORDER.index(tier) if tier in TIER_ORDER else len(TIER_ORDER),
            MODE_ORDER.index(mode) if mode in MODE_ORDER else len(MODE_ORDER),
            label,
        )

    return sorted(labels, key=key)


def solver_figures(res: Results, out: Path) -> list[Path]:
    """The solver comparison's valid-solution rate and shifted geometric mean solve time as
    heatmaps of solver × tier · mode (``solvers_success``, ``solvers_time``) into ``out``; none
    without solves. The time of a setting with no valid solution is left grey."""
    from wbcbench.report.solvers import summarize

    s = summarize(res.qp_solves)
    if s.empty:
        return []
    paths = []
    s = s.assign(label=s["tier"].astype(str) + " · " + s["mode"].astype(str))
    columns = _setting_order(list(s["label"].unique()))
    problems = int(s["problems"].max())
    for value, name, bar, title in (
        (
            "success [%]",
            "solvers_success",
            "valid solutions [%]",
            f"Valid solutions [%] of {problems} whole-body-control QPs (the independent check)",
        ),
        (
            "wall sgm [µs]",
            "solvers_time",
            "shifted geometric mean [µs] (log)",
            "Solve time [µs], shifted geometric mean over the same QPs",
        ),
    ):
        pivot = s.pivot_table(index="solver", columns="label", values=value, aggfunc="first")
        pivot = pivot.reindex(columns=columns)
        if value == "success [%]":
            norm: Any = Normalize(vmin=0.0, vmax=100.0)
            cmap, text = "RdYlGn", pivot.map(lambda v: "" if pd.isna(v) else f"{v:.0f}")
        else:
            norm = _log_norm(pivot)
            cmap, text = "viridis", pivot.map(lambda v: "" if pd.isna(v) else f"{v:.3g}")
        fig, ax = plt.subplots(figsize=(0.75 * len(columns) + 4.0, 0.38 * len(pivot) + 2.0))
        _heatmap(ax, pivot, text, norm, cmap, bar)
        ax.set_xlabel("accuracy tier · mode")
        ax.set_ylabel("solver")
        ax.set_title(title, fontsize=9)
        paths += _save(fig, out, name)
    return paths


def hls_figure(res: Results, out: Path) -> list[Path]:
    """RQR-HQP Fig. 1: median hierarchy solve time against the problem size N per algorithm
    and impl (``rqr_fig1``) into ``out``; none without the scaling rows."""
    from wbcbench.report.tables import rqr_fig1

    table = rqr_fig1(res)
    if table.frame is None:
        return []
    f = table.frame
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    colors: dict[str, str] = {}
    for col in [c for c in f.columns if c.endswith("median [µs]")]:
        algo, impl = col.split(" ")[:2]
        color = colors.setdefault(algo, f"C{len(colors)}")  # one colour per algorithm
        style = "o-" if impl == "native" else "s--"
        ax.plot(f["N"], f[col], style, color=color, label=f"{algo} ({impl})")
    ax.set_xlabel("problem size N [variables]")
    ax.set_ylabel("median time [µs]")
    ax.set_yscale("log")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title("Hierarchy solve time vs N (RQR-HQP Fig. 1)", fontsize=10)
    return _save(fig, out, "rqr_fig1")


PEER_COLORS = {"kin_hqp": "C0", "pink": "C1", "mink": "C2"}
#: kin_hqp drawn wide and solid, so that a peer that follows it exactly shows on top of it
PEER_LINES = {"kin_hqp": ("-", 2.4), "pink": ("--", 1.3), "mink": (":", 1.6)}


def _peer_logs(res: Results, scenario: str) -> list[tuple[str, pd.DataFrame]]:
    """Per controller of the peers table, the log of its preferred run of ``scenario``."""
    from wbcbench.report.tables.common import _prefer_full

    runs = res.of_kind("tracking")
    out = []
    for controller in PEER_COLORS:
        sel = runs[(runs["scenario"] == scenario) & (runs["controller"] == controller)]
        if sel.empty:
            continue
        log = res.log(_prefer_full(res, sel).iloc[-1]["run_id"])
        if not log.empty:
            out.append((controller, log))
    return out


def peers_figure(res: Results, out: Path) -> list[Path]:
    """kin_hqp, pink and mink: hierarchy, constraints and time per tick in one figure."""
    from wbcbench.report.tables.peers import peers_kinematic

    table = peers_kinematic(res)
    if table.frame is None:
        return []
    fig, axes = plt.subplots(2, 2, figsize=(11, 7))
    gaze = _peer_logs(res, "rqr_gaze")
    panels = (
        (axes[0, 0], gaze, "err.hand.pos", 1e3, "rqr_gaze: hand error (priority 1) [mm]", True),
        (
            axes[0, 1],
            gaze,
            "diag.residual.hand",
            1.0,
            "rqr_gaze: ‖J q̇ − r‖ of the hand level [m/s]\n(what the gaze below took from it)",
            True,
        ),
        (
            axes[1, 0],
            _peer_logs(res, "rqr_stress"),
            "collision_distance",
            1e3,
            "rqr_stress: smallest capsule distance [mm]\n(arm threaded through two frames)",
            False,
        ),
    )
    for ax, logs, col, scale, title, log_y in panels:
        drawn = [(c, lg) for c, lg in logs if col in lg.columns]
        if not drawn:
            ax.text(0.5, 0.5, "no runs", ha="center", va="center", transform=ax.transAxes)
            ax.set_title(title, fontsize=9)
            continue
        for controller, lg in drawn:
            if col in lg.columns:
                d = _thin(lg)
                y = scale * d[col]
                ax.plot(
                    d["t"],
                    y.where(y > 0) if log_y else y,
                    lw=PEER_LINES[controller][1],
                    linestyle=PEER_LINES[controller][0],
                    label=controller,
                    color=PEER_COLORS[controller],
                )
        if log_y:
            ax.set_yscale("log")
        else:
            ax.axhline(0.0, color="k", lw=0.8)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    ax = axes[1, 1]
    f = table.frame
    scenarios = list(dict.fromkeys(f["scenario"]))
    series = [(c, "python") for c in PEER_COLORS] + [("kin_hqp", "native")]
    width = 0.8 / len(series)
    timed = False
    for k, (controller, impl) in enumerate(series):
        rows = f[f["controller"] == controller].set_index("scenario").reindex(scenarios)
        median = rows.get(f"t median {impl} [µs]")
        p99 = rows.get(f"t p99 {impl} [µs]")
        if median is None or not np.isfinite(median.to_numpy(dtype=float)).any():
            continue
        x = np.arange(len(scenarios)) + (k - (len(series) - 1) / 2) * width
        ax.bar(
            x,
            median,
            width,
            color=PEER_COLORS[controller],
            label=f"{controller} ({impl})",
            hatch="//" if impl == "native" else None,
            edgecolor="white",
        )
        if p99 is not None:
            ax.plot(x, p99, "v", color="k", ms=4)
        timed = True
    if not timed:
        ax.text(0.5, 0.5, "no runs", ha="center", va="center", transform=ax.transAxes)
    ax.set_xticks(np.arange(len(scenarios)))
    ax.set_xticklabels([s.replace("_kinematic", "\n(kinematic)") for s in scenarios], fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel("time per tick [µs] (bar: median, ▼: p99)")
    ax.set_title("Replay of the same recorded states", fontsize=9)
    ax.grid(alpha=0.3, axis="y", which="both")
    if timed:
        ax.legend(fontsize=7)
    fig.suptitle(
        "Velocity-level peers: kin_hqp (strict levels) beside pink and mink (one weighted QP)",
        fontsize=10,
    )
    return _save(fig, out, "peers_kinematic")


def _walk_run(runs: pd.DataFrame) -> pd.Series:
    """The run a walk figure shows: the one that got furthest in time (a walk that failed at
    its third step before a short check that stood), among equals an ok one before a fall."""
    key = pd.DataFrame(
        {
            "ok": (runs["status"] == "ok").astype(int),
            "sim": pd.to_numeric(runs["sim_duration_s"], errors="coerce").fillna(0.0),
        },
        index=runs.index,
    )
    return runs.loc[key.sort_values(["sim", "ok"], kind="stable").index[-1]]


def walk_figures(res: Results, out: Path) -> list[Path]:
    """``walk_<scenario>``: each walk scenario seen from above, with the simulated CoM and CoP
    of its furthest run (the plan is the one the run followed, kept with its log)."""
    import json

    from wbcbench.report.walking import measured_paths, walk_figure
    from wbcbench.tasks.walking import WalkPlan

    paths: list[Path] = []
    runs = res.of_kind("tracking")
    if runs.empty:
        return paths
    runs = runs[runs["status"].isin(["ok", "fell", "failed"])]
    if "settings" in runs:
        runs = runs[~runs["settings"].fillna("").astype(str).str.contains('"perturbations"')]
    for scenario, group in runs.groupby("scenario"):
        run = _walk_run(group)
        log = res.log(str(run["run_id"]))
        if log.empty or "walk" not in log.attrs:
            continue
        walk = json.loads(log.attrs["walk"])
        plan = WalkPlan.from_dict(walk)
        soles = {f: (tuple(b[:2]), tuple(b[2:])) for f, b in walk.get("soles", {}).items()}
        sole = soles.get(plan.feet[0], ((-0.1, 0.1), (-0.05, 0.05)))
        done = len(walk.get("landings", []))
        status = "" if run["status"] == "ok" else f", {run['status']}"
        title = (
            f"{scenario}: {run['controller']} × {run['solver']} ({run.get('impl', '')}), "
            f"{done} of {len(plan.swings)} steps in {float(run['sim_duration_s']):.1f} s{status}"
        )
        fig = walk_figure(plan, sole, measured_paths(log, soles), title)
        paths += _save(fig, out, f"walk_{scenario}")
    return paths


def write_plots(folder: str | Path) -> list[Path]:
    """Every figure the results allow, into ``<folder>/figures``."""
    res = load_results(folder)
    out = Path(folder) / "figures"
    out.mkdir(exist_ok=True)
    paths: list[Path] = []
    for fn in (
        tracking_figures,
        size_figures,
        level_figure,
        timing_solver_figure,
        solver_figures,
        hls_figure,
        peers_figure,
        walk_figures,
    ):
        paths += fn(res, out)
    from wbcbench.report.paper_figures import write_paper_figures
    from wbcbench.report.robustness import degradation_figure, degradation_table

    paths += degradation_figure(degradation_table(res), out)
    return paths + write_paper_figures(folder, res)
