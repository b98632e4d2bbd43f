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


def degradation_figure(table: pd.DataFrame, out: Path, task: str = "com") -> list[Path]:
    """One panel per axis: the task's mean error against the perturbation's size, one line per
    controller (solver); a run that fell or failed is a cross at the top of its panel."""
    if table.empty:
        return []
    axes_present = [a for a in AXES if a in set(table["axis"])]
    fig, axes = plt.subplots(1, len(axes_present), figsize=(4.2 * len(axes_present), 3.6))
    axes = np.atleast_1d(axes)
    series: list[tuple[str, str, str]] = sorted(
        {(str(a), str(b), str(c)) for a, b, c in table[["scenario", "controller", "solver"]].values}
    )
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
            ax.plot(ok["value"], 1e3 * ok["err_mean"], "o-", color=color, ms=4,
                    label=f"{controller} ({solver})")  # fmt: skip
            bad = s[s["status"] != "ok"]
            if not bad.empty:
                ax.plot(bad["value"], [1.3 * top] * len(bad), "x", color=color, ms=8, mew=2)
        ax.set_xlabel(AXES[axis])
        ax.set_ylabel(f"{task} mean error [mm]")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    scenarios = ", ".join(sorted(set(table["scenario"])))
    fig.suptitle(f"Tracking degradation on {scenarios} (x: fell or failed)", fontsize=10)
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        axes[-1].legend(handles, labels, fontsize=7, loc="best")
    fig.tight_layout()
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
    shown = table.assign(
        err_mean_mm=1e3 * table["err_mean"], message=table["message"].fillna("")
    ).drop(columns=["err_mean"])
    text = [
        "# Tracking degradation",
        "",
        "Mean CoM error [mm] over each run's window, measured on the simulated robot, against "
        "the controller's mass error [%], sensing noise [× a typical encoder's: "
        f"{ENCODER_Q_STD:.3g} rad, {ENCODER_V_STD:.3g} rad/s] and delay [control ticks]. "
        "A run without perturbations is the point at 0 of each axis.",
        "",
        shown.to_markdown(index=False, floatfmt=".4g"),
        "",
    ]
    path = folder / "tables" / "degradation.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(text))
    written.append(path)
    written += degradation_figure(table, folder / "figures")
    return written
