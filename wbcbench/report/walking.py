"""The top view of a walk: footprints, and the ZMP, DCM and CoM paths, planned and measured;
and the time per tick of each walk phase against the control period."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from wbcbench.tasks.walking import WalkPlan

__all__ = ["measured_paths", "walk_figure", "walk_phase_figure"]

FOOT_COLOURS = ("tab:blue", "tab:red")
PHASE_COLOURS = {"double": "tab:blue", "single": "tab:orange", "transition": "tab:red"}


def _footprint(
    position: tuple[float, float, float],
    yaw: float,
    sole: tuple[tuple[float, float], tuple[float, float]],
) -> np.ndarray:
    (x0, x1), (y0, y1) = sole
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    c, s = math.cos(yaw), math.sin(yaw)
    return corners @ np.array([[c, s], [-s, c]]) + np.array(position[:2])


def measured_paths(
    log: pd.DataFrame, soles: dict[str, tuple[tuple[float, float], tuple[float, float]]]
) -> dict[str, np.ndarray]:
    """The simulated CoM and CoP of a walk run's log, as world (x, y) paths [m].

    The CoP is the normal-force-weighted mean of each loaded sole's (``soles``: frame → its CoP
    box, whose contacts count as loaded from 1 N) centre of pressure, taken from the simulated
    wrench in the sole's frame and placed by the sole's position and yaw (a sole lies flat
    while it carries load); NaN where no sole carries load.
    """
    out: dict[str, np.ndarray] = {}
    if {"com.x", "com.y"} <= set(log.columns):
        out["CoM"] = log[["com.x", "com.y"]].to_numpy()
    total = np.zeros(len(log))
    weighted = np.zeros((len(log), 2))
    for frame in soles:
        needed = [f"wrench_sim.{frame}.{c}" for c in ("fz", "mx", "my")]
        needed += [f"foot.{frame}.{c}" for c in ("x", "y", "yaw")]
        if not set(needed) <= set(log.columns):
            continue
        fz = log[f"wrench_sim.{frame}.fz"].to_numpy()
        loaded = fz >= 1.0
        safe = np.where(loaded, fz, 1.0)
        local = (
            np.column_stack(
                [
                    -log[f"wrench_sim.{frame}.my"].to_numpy(),
                    log[f"wrench_sim.{frame}.mx"].to_numpy(),
                ]
            )
            / safe[:, None]
        )
        yaw = log[f"foot.{frame}.yaw"].to_numpy()
        c, s = np.cos(yaw), np.sin(yaw)
        world = np.column_stack(
            [
                log[f"foot.{frame}.x"].to_numpy() + c * local[:, 0] - s * local[:, 1],
                log[f"foot.{frame}.y"].to_numpy() + s * local[:, 0] + c * local[:, 1],
            ]
        )
        weight = np.where(loaded, fz, 0.0)
        total += weight
        weighted += weight[:, None] * world
    if np.any(total > 0):
        with np.errstate(invalid="ignore", divide="ignore"):
            out["CoP"] = np.where(total[:, None] > 0, weighted / total[:, None], np.nan)
    return out


def walk_figure(
    plan: WalkPlan,
    sole: tuple[tuple[float, float], tuple[float, float]] = ((-0.1, 0.1), (-0.05, 0.05)),
    measured: dict[str, np.ndarray] | None = None,
    title: str = "",
) -> Figure:
    """A walk seen from above.

    Args:
        plan: the planned walk.
        sole: the sole's (x, y) extent in its contact frame [m], drawn at every footstep.
        measured: optional paths recorded in a run, by name (``"CoM"``, ``"CoP"``, …), each an
            (n, 2) array of world (x, y) [m]; drawn dashed beside the plan (``"CoP"``, which
            jumps from tick to tick, as points).
        title: the figure's title.
    """
    points = np.array([f.position[:2] for f in plan.footsteps])
    span = np.ptp(points, axis=0) + 0.3
    fig = Figure(figsize=(10.0, float(np.clip(7.0 * span[1] / span[0], 3.0, 7.0))))
    ax: Axes = fig.add_subplot()
    colours = dict(zip(plan.feet, FOOT_COLOURS, strict=False))
    for k, step in enumerate(plan.footsteps):
        colour = colours[step.foot]
        ax.add_patch(
            Polygon(
                _footprint(step.position, step.yaw, sole),
                closed=True,
                facecolor=colour,
                alpha=0.12 if step.is_initial else 0.25,
                edgecolor=colour,
                linewidth=1.0,
            )
        )
        if not step.is_initial:
            ax.annotate(str(k - 1), step.position[:2], ha="center", va="center", fontsize=8)
    for foot, colour in colours.items():
        ax.plot([], [], color=colour, linewidth=6, alpha=0.3, label=f"{foot} footprints")
    t = np.linspace(0.0, plan.duration, 600)
    zmp = np.array([plan.zmp(x) for x in t])
    dcm = np.array([plan.dcm(x) for x in t])
    com = np.array([plan.com(x)[0][:2] for x in t])
    ax.plot(zmp[:, 0], zmp[:, 1], color="tab:green", linewidth=1.2, label="ZMP (plan)")
    ax.plot(dcm[:, 0], dcm[:, 1], color="tab:purple", linewidth=1.0, label="DCM (plan)")
    ax.plot(com[:, 0], com[:, 1], color="black", linewidth=1.5, label="CoM (plan)")
    for (name, path), colour in zip(
        (measured or {}).items(), ("tab:orange", "tab:olive", "tab:cyan"), strict=False
    ):
        if name == "CoP":  # jumps from tick to tick under soft contacts: points, not a line
            ax.plot(path[:, 0], path[:, 1], ".", color=colour, ms=1.5, alpha=0.4, label="CoP (run)")
        else:
            ax.plot(path[:, 0], path[:, 1], "--", color=colour, lw=1.2, label=f"{name} (run)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    steps = len(plan.swings)
    ax.set_title(
        title or f"{steps} steps, {plan.duration:.1f} s, CoM height {plan.com_height:.3f} m"
    )
    fig.tight_layout()
    return fig


def walk_phase_figure(phases: pd.DataFrame) -> Figure:
    """The whole tick per walk phase, one group of bars per run: the median as a bar, the p99
    as a triangle, the control period as a dashed line; on a log scale when the times span
    more than a factor 20.

    Args:
        phases: one row per run × phase, with ``scenario``, ``controller``, ``solver``,
            ``impl``, ``phase``, ``median [µs]``, ``p99 [µs]`` and ``deadline [µs]``
            (:func:`wbcbench.report.notebook.walk_phase_times`).
    """
    keys = ["scenario", "controller", "solver", "impl"]
    runs = list(phases.groupby(keys, sort=False))
    fig = Figure(figsize=(max(5.0, 1.6 * len(runs) + 2.5), 4.0))
    ax: Axes = fig.add_subplot()
    names = list(dict.fromkeys(phases["phase"]))
    width = 0.8 / max(len(names), 1)
    for k, phase in enumerate(names):
        rows = [run[run["phase"] == phase] for _, run in runs]
        median = [float(r["median [µs]"].iloc[0]) if len(r) else np.nan for r in rows]
        p99 = [float(r["p99 [µs]"].iloc[0]) if len(r) else np.nan for r in rows]
        x = np.arange(len(runs)) + (k - (len(names) - 1) / 2) * width
        colour = PHASE_COLOURS.get(phase, "tab:gray")
        ax.bar(x, median, width, color=colour, alpha=0.8, label=f"{phase} (median)")
        ax.plot(x, p99, "v", color=colour, markeredgecolor="black", ms=6)
    ax.plot([], [], "v", color="white", markeredgecolor="black", label="p99")
    for deadline in phases["deadline [µs]"].dropna().unique():
        ax.axhline(deadline, color="black", ls="--", lw=1.0)
        ax.annotate(
            f"deadline {deadline / 1e3:g} ms",
            (1.0, deadline),
            xycoords=("axes fraction", "data"),
            ha="right",
            va="bottom",
            fontsize=8,
        )
    ax.set_xticks(np.arange(len(runs)))
    ax.set_xticklabels([f"{c} × {s}\n({i}, {sc})" for (sc, c, s, i), _ in runs], fontsize=8)
    values = phases[["median [µs]", "p99 [µs]"]].to_numpy(dtype=float)
    values = values[np.isfinite(values) & (values > 0)]
    if values.size and values.max() > 20.0 * values.min():  # times of different scales
        ax.set_yscale("log")
    else:
        ax.set_ylim(bottom=0.0)
    ax.set_ylabel("whole tick [µs]")
    ax.set_title("Time per tick by walk phase", fontsize=10)
    ax.grid(alpha=0.3, axis="y", which="both")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    return fig
