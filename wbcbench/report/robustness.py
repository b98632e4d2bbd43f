"""Robustness: tracking degradation against model error, sensing noise and delay, and the
push-recovery table (written by :mod:`wbcbench.bench.push_recovery`).

The degradation curves come from tracking runs whose rows state their perturbations
(``settings.perturbations``): each perturbed run is placed on one axis (the mass error [%],
the noise as a multiple of :data:`ENCODER_Q_STD` / :data:`ENCODER_V_STD`, the delay [ticks]),
and a run of the same scenario, controller, solver and duration without perturbations is the
point at 0 of every axis. Runs that combine perturbations of two axes are left out.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from wbcbench.report.load import Results, load_results

__all__ = [
    "AXES",
    "ENCODER_Q_STD",
    "ENCODER_V_STD",
    "degradation_falls_first",
    "degradation_figure",
    "degradation_grid",
    "degradation_table",
    "perturbation_axis",
    "write_robustness",
]

#: a typical joint encoder: a 17-bit absolute encoder's quantisation noise (2π / 2¹⁷ / √12)
#: [rad], and that of its backward difference at 1 kHz (√2 × the former / 1 ms) [rad/s]
ENCODER_Q_STD = 2 * np.pi / 2**17 / np.sqrt(12)
ENCODER_V_STD = np.sqrt(2) * ENCODER_Q_STD / 1e-3

AXES = {
    "mass": "controller's mass error [%]",
    "noise": "sensing noise [× a typical encoder's]",
    "delay": "delay [control ticks]",
}


def perturbation_axis(settings: str) -> tuple[str, float] | None:
    """``(axis, value)`` of a run from its row's ``settings``: ``("", 0)`` for a run without
    perturbations, None for one that is not on a single axis."""
    info = json.loads(settings) if isinstance(settings, str) and settings else {}
    pert: dict[str, Any] = info.get("perturbations") or {}
    if not pert:
        return ("", 0.0)
    keys = {k for k in pert if k != "seed"}
    sensing = pert.get("sensing", {})
    model = pert.get("model", {})
    if keys == {"model"} and set(model) <= {"mass_scale", "inertia_scale"}:
        scale = model.get("mass_scale", 1.0)
        if model.get("inertia_scale", scale) == scale:
            return ("mass", round(100 * (scale - 1), 6))
    if keys == {"sensing"} and set(sensing) == {"delay"}:
        return ("delay", float(sensing["delay"]))
    if keys == {"sensing"} and set(sensing) == {"q_noise", "v_noise"}:
        k = sensing["q_noise"] / ENCODER_Q_STD
        if np.isclose(sensing["v_noise"] / ENCODER_V_STD, k, rtol=1e-3):
            return ("noise", round(float(k), 3))
    return None


def degradation_table(res: Results, task: str = "com") -> pd.DataFrame:
    """One row per scenario × controller × solver × axis × value: the task's mean error
    (``err_mean``, on the simulated robot) over the window, the run's status and message."""
    runs = res.of_kind("tracking")
    if runs.empty or res.metrics.empty or "settings" not in runs:
        return pd.DataFrame()
    places = [perturbation_axis(s) for s in runs["settings"]]
    on_axis = [p is not None for p in places]
    placed = runs[on_axis]
    kept = [p for p in places if p is not None]
    placed = placed.assign(
        axis=[p[0] for p in kept],
        value=[p[1] for p in kept],
        duration_s=[json.loads(s).get("duration_s") for s in placed["settings"]],
    )
    err = res.metrics[(res.metrics["task"] == task) & (res.metrics["metric"] == "err_mean")]
    placed = placed.join(err.set_index("run_id")["value"].rename("err_mean"), on="run_id")
    group = ["scenario", "controller", "solver", "duration_s"]
    perturbed = placed[placed["axis"] != ""]
    families = perturbed[group].drop_duplicates()
    base = placed[placed["axis"] == ""].merge(families, on=group)
    rows = [perturbed]
    for axis in sorted(perturbed["axis"].unique()):
        having = perturbed.loc[perturbed["axis"] == axis, group].drop_duplicates()
        rows.append(base.merge(having, on=group).assign(axis=axis))
    out = pd.concat(rows, ignore_index=True)
    columns = [*group, "axis", "value", "err_mean", "status", "message"]
    out = out[columns].sort_values([*group, "axis", "value"]).reset_index(drop=True)
    return out.drop_duplicates([*group, "axis", "value"], keep="last")


def degradation_grid(table: pd.DataFrame, axis: str) -> pd.DataFrame:
    """One axis of :func:`degradation_table` as a grid: a row per scenario × controller ×
    solver, a column per perturbation size, each cell the mean error [mm] or how the run
    ended when it was not ``ok``."""
    d = table[table["axis"] == axis]
    if d.empty:
        return pd.DataFrame()
    cell = [
        f"{1e3 * e:.3g}" if status == "ok" else str(status)
        for e, status in zip(d["err_mean"], d["status"], strict=True)
    ]
    grid = d.assign(cell=cell).pivot_table(
        index=["scenario", "controller", "solver"],
        columns="value",
        values="cell",
        aggfunc="last",
        sort=False,
    )
    grid.columns = [f"{v:g}" for v in grid.columns]
    return grid.reset_index().fillna("not run")


def degradation_falls_first(table: pd.DataFrame) -> pd.DataFrame:
    """Per scenario × solver × axis: the controller(s) whose run falls or fails at the smallest
    perturbation, with the run's own message; when none does, the one whose error grows most
    [mm] from its unperturbed run to the largest perturbation (degrades most)."""
    from wbcbench.bench.push_recovery import WHY

    if table.empty:
        return pd.DataFrame()
    out = []
    order = {axis: k for k, axis in enumerate(AXES)}
    table = table.sort_values("axis", key=lambda a: a.map(order), kind="stable")
    for key, d in table.groupby(["scenario", "solver", "axis"], sort=False):
        scenario, solver, axis = (str(k) for k in key)
        bad = d[d["status"] != "ok"]
        n = d["controller"].nunique()
        if not bad.empty:
            at = float(bad["value"].min())
            first = bad[bad["value"] == at].drop_duplicates("controller")
            many = len(first) > 1
            out.append(
                {
                    "scenario": scenario,
                    "solver": solver,
                    "perturbation": AXES[axis],
                    "falls first": ", ".join(first["controller"]),
                    "at": f"{at:g}",
                    "controllers compared": n,
                    WHY: "; ".join(
                        f"{c}: {st}: {m}" if many else f"{st}: {m}"
                        for c, st, m in zip(
                            first["controller"], first["status"], first["message"], strict=True
                        )
                    ),
                }
            )
            continue
        top = float(d["value"].max())
        growth: dict[str, tuple[float, float]] = {}  # controller → (unperturbed, largest) [m]
        for name, c in d.groupby("controller", sort=False):
            base = c.loc[c["value"] == 0, "err_mean"]
            worst = c.loc[c["value"] == top, "err_mean"]
            if not base.empty and not worst.empty:
                growth[str(name)] = (float(base.iloc[0]), float(worst.iloc[0]))
        most = max(growth, key=lambda k: growth[k][1] - growth[k][0]) if growth else ""
        out.append(
            {
                "scenario": scenario,
                "solver": solver,
                "perturbation": AXES[axis],
                "falls first": "none",
                "at": f"none up to {top:g}",
                "controllers compared": n,
                WHY: (
                    f"every run ok; degrades most: {most} (from {1e3 * growth[most][0]:.3g} to "
                    f"{1e3 * growth[most][1]:.3g} mm at {top:g})"
                    if most
                    else "every run ok"
                ),
            }
        )
    return pd.DataFrame(out)


def degradation_figure(table: pd.DataFrame, out: Path, task: str = "com") -> list[Path]:
    """One panel per axis: the task's mean error against the perturbation's size, one line per
    controller (solver), each with its own colour and marker (one legend under the panels); a
    run that fell or failed is a cross of its colour above the panel's curves."""
    if table.empty:
        return []
    axes_present = [a for a in AXES if a in set(table["axis"])]
    fig, axes = plt.subplots(1, len(axes_present), figsize=(4.6 * len(axes_present), 4.4))
    axes = np.atleast_1d(axes)
    series: list[tuple[str, str, str]] = list(
        dict.fromkeys(
            (str(a), str(b), str(c))
            for a, b, c in table[["scenario", "controller", "solver"]].values
        )
    )
    markers = "osD^vP*Xh<>p"
    for ax, axis in zip(axes, axes_present, strict=True):
        d = table[table["axis"] == axis]
        top = 1e3 * float(np.nanmax(d["err_mean"])) if d["err_mean"].notna().any() else 1.0
        for k, key in enumerate(series):
            scenario, controller, solver = key
            s = d[(d["scenario"] == scenario) & (d["controller"] == controller)]
            s = s[s["solver"] == solver]
            if s.empty:
                continue
            color = plt.get_cmap("tab10")(k % 10)
            ok = s[s["status"] == "ok"]
            style = {"marker": markers[k % len(markers)], "ms": 5, "lw": 1.4, "alpha": 0.85}
            label = f"{controller} ({solver})"
            ax.plot(ok["value"], 1e3 * ok["err_mean"], "-", color=color, label=label, **style)
            bad = s[s["status"] != "ok"]
            if not bad.empty:
                # the crosses of each controller on a row of their own above the curves
                y = top * 1.6 * 1.35**k
                ax.plot(bad["value"], [y] * len(bad), "x", color=color, ms=8, mew=2)
        ax.set_xlabel(AXES[axis])
        ax.set_ylabel(f"{task} mean error [mm]")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    scenarios = ", ".join(sorted(set(table["scenario"])))
    fig.suptitle(f"Tracking degradation on {scenarios} (×: the run fell or failed)", fontsize=11)
    handles, labels = [], []
    for ax in axes:
        for h, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if label not in labels:
                handles.append(h)
                labels.append(label)
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 6), fontsize=9)
    fig.tight_layout(rect=(0, 0.09 if handles else 0, 1, 1))
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "degradation.png", out / "degradation.svg"]
    for p in paths:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return paths


def write_robustness(folder: str | Path) -> list[Path]:
    """``tables/degradation.md`` and ``figures/degradation.{png,svg}`` when the folder holds
    perturbed tracking runs, and ``tables/push_recovery.md`` when it holds a push study."""
    from wbcbench.bench.push_recovery import write_push_table

    folder = Path(folder)
    written: list[Path] = []
    push = write_push_table(folder)
    if push is not None:
        written.append(push)
    res = load_results(folder)
    table = degradation_table(res)
    if table.empty:
        return written
    text = [
        "# Tracking degradation",
        "",
        "Mean CoM error [mm] over each run's window, measured on the simulated robot, against "
        "the controller's mass error [%], sensing noise [× a typical encoder's: "
        f"{ENCODER_Q_STD:.3g} rad, {ENCODER_V_STD:.3g} rad/s] and delay [control ticks]. "
        "A run without perturbations is the point at 0 of each axis; a run that did not end "
        "`ok` shows how it ended (its message is in the runs table, and below for the first).",
        "",
    ]
    for axis, title in AXES.items():
        grid = degradation_grid(table, axis)
        if not grid.empty:
            text += [f"## {title[0].upper()}{title[1:]}", "", grid.to_markdown(index=False), ""]
    first = degradation_falls_first(table)
    text += [
        "## Which controller falls first",
        "",
        "Per perturbation, the controller whose run falls or fails at the smallest size, and "
        "why, in the run's own words.",
        "",
        first.to_markdown(index=False),
        "",
    ]
    path = folder / "tables" / "degradation.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(text))
    written.append(path)
    written += degradation_figure(table, folder / "figures")
    return written
