"""The top view of a walk: footprints, and the ZMP, DCM and CoM paths, planned and measured."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from wbcbench.tasks.walking import WalkPlan

__all__ = ["measured_paths", "walk_figure"]

FOOT_COLOURS = ("tab:blue", "tab:red")


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
