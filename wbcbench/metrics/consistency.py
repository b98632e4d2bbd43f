"""Hierarchy and dynamic-consistency metrics of one control tick, from the oracle.

A hierarchical controller's torque is a sum of per-level contributions. Applying the cumulative
torque of the levels down to l, and then the whole torque, in the rigid-contact forward-dynamics
oracle tells how much the levels below l change what the levels down to l realise: zero for a
strictly hierarchical, dynamically consistent controller. The oracle is independent of the
controller's own formulas; the metrics cost one forward-dynamics solve per level, so controllers
compute them only when asked (``consistency: true``), never in timing runs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from wbcbench.dynamics.state import RobotState
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.tasks.contacts import PlaneContact, frame_wrenches
from wbcbench.tasks.osf import OsfParams


def hierarchy_leak(
    state: RobotState,
    frames: Sequence[str | PlaneContact],
    partial: Sequence[np.ndarray],
    extra: np.ndarray,
    level_tasks: Sequence[Sequence[tuple[str, np.ndarray, np.ndarray]]],
    predicted_wrench: np.ndarray | None = None,
) -> dict[str, float]:
    """Oracle residuals of one tick.

    Args:
        state: the true state of the tick.
        frames: the contacts (a frame name for a flat one).
        partial: cumulative task torques Γ_{≤1}, …, Γ_{≤L} (k,) [N·m].
        extra: torque added to every partial one (the wrench distribution, in null(W)) (k,).
        level_tasks: per level, (task name, J (m, n), J̇q̇ (m,)) of each task.
        predicted_wrench: the controller's predicted force variable (c,), to compare with the
            oracle's (as wrenches at the contact frames).

    Returns:
        ``leak.<task>``: the largest change of the task's realised acceleration caused by the
        levels below its own [m/s², rad/s²]; ``contact_acc``: the largest contact acceleration
        under the full torque; ``wrench_residual``: ‖predicted − realised wrench‖ [N] when a
        prediction is given; ``leak_max``: the largest leak.
    """
    if not partial:
        return {}
    final = forward_dynamics(state, partial[-1] + extra, frames)
    # q̈ change when the levels below l are left out, l = 1 … L − 1
    missing = [forward_dynamics(state, tau + extra, frames).qdd - final.qdd for tau in partial[:-1]]
    out: dict[str, float] = {}
    leak_max = 0.0
    for lvl, tasks in enumerate(level_tasks):
        worst = dict.fromkeys((name for name, _, _ in tasks), 0.0)
        for dq in missing[lvl:]:
            for name, J, _ in tasks:
                change = float(np.linalg.norm(J @ dq))
                worst[name] = max(worst[name], change)
        for name, value in worst.items():
            out[f"leak.{name}"] = value
            leak_max = max(leak_max, value)
    out["leak_max"] = leak_max
    out["contact_acc"] = float(np.abs(final.contact_acc).max()) if final.contact_acc.size else 0.0
    if predicted_wrench is not None and predicted_wrench.size:
        contacts = [PlaneContact(frame=c) if isinstance(c, str) else c for c in frames]
        predicted = frame_wrenches(contacts, predicted_wrench)
        out["wrench_residual"] = float(np.linalg.norm(predicted - final.wrench))
    return out


def dc_error(params: OsfParams) -> float:
    """Dynamic-consistency error of the parameters: how much the torque directions of each level
    accelerate the tasks above it, relative to how much they accelerate their own,
    ``max_{j<i} ‖Ĵ_j E_i‖_F / ‖Ĵ_i E_i‖_F`` (0 for dynamically consistent inverses)."""
    worst = 0.0
    for i, lv in enumerate(params.levels):
        own = float(np.linalg.norm(lv.Jhat @ lv.E))
        if own == 0.0:
            continue
        for upper in params.levels[:i]:
            worst = max(worst, float(np.linalg.norm(upper.Jhat @ lv.E)) / own)
    return worst
