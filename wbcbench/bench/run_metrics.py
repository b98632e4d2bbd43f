"""Metrics of one closed-loop run, in long form: (task, metric, value, unit).

* tracking: per task and error part, ``err_mean`` / ``err_max`` (``err_rot_mean`` … for the
  orientation part of pose tasks) over the scenario's window, and ``err_final``; in a run
  with perturbations, measured on the simulated robot (not the controller's noisy view of it);
* constraints: torque-limit excess (commanded), friction / CoP / normal-force violations of the
  predicted (commanded) and simulated wrenches, each the maximum over the window (friction,
  CoP and yaw on the ticks where the contact carries load; ``unloaded_contact_ticks_*`` counts
  the others); for kinematic runs instead, ``max_contact_drift`` [m] (the held contact frames'
  largest displacement since the start) and ``min_collision_distance`` [m];
* joint limits, over the whole run: ``joint_limit_violation`` [rad] and ``ticks_at_joint_limit``
  (a joint within 1e-3 rad of a position limit; the torque-level controllers do not hold
  position limits, so a task that needs such a joint gives way while every QP is solved);
* failures: failed control ticks;
* amendments: ``amend_mean`` / ``amend_max`` per task over the window, for controllers that
  report ``diag.amend.<task>`` (to_osf);
* level residuals: ``residual_mean`` / ``residual_max`` per level (task = the level's name)
  over the window, for velocity-level controllers that report ``diag.residual.<level>``
  (‖J q̇ − r‖ of a priority's tasks: kin_hqp, pink, mink);
* timing: per stage ``t_<stage>_median_us`` and friends, after the warm-up ticks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from wbcbench.metrics.timing import timing_stats
from wbcbench.sim.closed_loop import RunResult
from wbcbench.tasks.contacts import PlaneContact
from wbcbench.tasks.tasks import ERROR_UNITS
from wbcbench.tasks.walking import WalkPlan

WRENCH = ("fx", "fy", "fz", "mx", "my", "mz")
#: a joint closer than this to a position limit is at it [rad] (``ticks_at_joint_limit``)
JOINT_AT_LIMIT = 1e-3


@dataclass
class MetricRow:
    task: str
    metric: str
    value: float
    unit: str


def loaded_normal_force(contact: PlaneContact) -> float:
    """The normal force [N] from which a contact counts as carrying load: half its minimum
    normal force, and at least 1 N."""
    return max(1.0, 0.5 * contact.fmin)


def _metric_name(part: str, stat: str, parts: list[str]) -> str:
    """err_mean for a task's main part; err_rot_mean for the orientation of a pose task."""
    if part == "rot" and "pos" in parts:
        return f"err_rot_{stat}"
    return f"err_{stat}"


def run_metrics(
    result: RunResult,
    contacts: list[PlaneContact],
    window: tuple[float, float] | None,
    warmup: int,
) -> list[MetricRow]:
    cols = result.log.arrays()
    rows: list[MetricRow] = []
    if not cols:
        return rows
    t = cols["t"]
    mask = np.ones_like(t, dtype=bool) if window is None else (t >= window[0]) & (t <= window[1])
    # a perturbed run logs each task's error on the simulated robot beside the controller's
    # view of it (noisy, on its own model): the metrics are the robot's
    source = "true_err" if any(k.startswith("true_err.") for k in cols) else "err"
    for task, parts in result.task_parts.items():
        for part in parts:
            series = cols[f"{source}.{task}.{part}"]
            unit = ERROR_UNITS[part]
            w = series[mask]
            w = w[np.isfinite(w)]  # a swing task is not evaluated while its foot stands
            finite = series[np.isfinite(series)]
            for stat, value in (
                ("mean", float(np.mean(w)) if w.size else np.nan),
                ("max", float(np.max(w)) if w.size else np.nan),
                ("final", float(finite[-1]) if finite.size else np.nan),
            ):
                rows.append(MetricRow(task, _metric_name(part, stat, parts), value, unit))

    # Kinematic runs log no torques or wrenches, but joint margins and collision distances.
    # Constraint violations count inside the metrics window only (the touchdown before it is
    # not the controller's doing), and the friction / CoP / yaw ratios only on ticks where the
    # contact carries load: at f_z → 0 they are 0/0, not a violation.
    if all(f"tau.{j}" in cols for j in result.robot.joint_names):
        taus = np.column_stack([cols[f"tau.{j}"] for j in result.robot.joint_names])[mask]
        excess = np.max(np.abs(taus) - result.tau_max[None, :], initial=0.0)
        rows.append(MetricRow("*", "torque_limit_excess", max(0.0, float(excess)), "N·m"))
        for source in ("pred", "sim"):
            worst = {"normal": 0.0, "friction": 0.0, "cop": 0.0, "yaw": 0.0}
            unloaded = 0
            for contact in contacts:
                w6 = np.column_stack([cols[f"wrench_{source}.{contact.frame}.{c}"] for c in WRENCH])
                loaded = loaded_normal_force(contact)
                # a scheduled contact counts only while active and settled (not swinging,
                # unloading before lift-off or loading after touchdown)
                held = cols.get(f"active.{contact.frame}")
                held_mask = mask if held is None else mask & (held >= 1.0)
                for wrench in w6[held_mask]:
                    if not np.all(np.isfinite(wrench)):
                        continue
                    measured = contact.violation(wrench)
                    worst["normal"] = max(worst["normal"], measured["normal"])
                    if wrench[2] < loaded:
                        unloaded += 1
                        continue
                    for key in ("friction", "cop", "yaw"):
                        worst[key] = max(worst[key], measured[key])
            units = {"normal": "N", "friction": "-", "cop": "m", "yaw": "m"}
            for key, value in worst.items():
                rows.append(MetricRow("*", f"{key}_violation_{source}", value, units[key]))
            rows.append(MetricRow("*", f"unloaded_contact_ticks_{source}", unloaded, "ticks"))
    if "joint_margin" in cols:
        margin = cols["joint_margin"]
        violation = max(0.0, -float(np.min(margin, initial=np.inf)))
        rows.append(MetricRow("*", "joint_limit_violation", violation, "rad"))
        at_limit = float(np.sum(margin < JOINT_AT_LIMIT))
        rows.append(MetricRow("*", "ticks_at_joint_limit", at_limit, "ticks"))
    if "contact_drift" in cols:
        drift = float(np.max(cols["contact_drift"], initial=0.0))
        rows.append(MetricRow("*", "max_contact_drift", drift, "m"))
    if "collision_distance" in cols:
        rows.append(
            MetricRow("*", "min_collision_distance", float(np.min(cols["collision_distance"])), "m")
        )
    rows.append(MetricRow("*", "solve_failures", float(result.failures), "ticks"))
    if result.walk is not None:
        rows += walk_metrics(result.walk, cols, warmup, contacts)
    # task-reference amendments ‖ẍ_opt − ẍ*‖ of the optimising OSF controllers (to_osf), and
    # the velocity residual ‖J q̇ − r‖ of each level of the velocity-level controllers
    for key in cols:
        if key.startswith("diag.residual."):
            w = cols[key][mask]
            w = w[np.isfinite(w)]
            if w.size:
                level = key.removeprefix("diag.residual.")
                rows.append(MetricRow(level, "residual_mean", float(np.mean(w)), "m/s|rad/s"))
                rows.append(MetricRow(level, "residual_max", float(np.max(w)), "m/s|rad/s"))
        if key.startswith("diag.amend."):
            w = cols[key][mask]
            w = w[np.isfinite(w)]
            if w.size:
                task = key.removeprefix("diag.amend.")
                rows.append(MetricRow(task, "amend_mean", float(np.mean(w)), "m/s²|rad/s²"))
                rows.append(MetricRow(task, "amend_max", float(np.max(w)), "m/s²|rad/s²"))

    for stage in ("dynamics", "build", "params", "solve", "solve_internal", "total"):
        key = f"time.{stage}"
        if key not in cols:
            continue
        stats = timing_stats(cols[key][warmup:])
        for name, value in stats.items():
            unit = "-" if name == "miss_rate" else "us"
            metric = f"t_{stage}_{name}" if name != "miss_rate" else f"t_{stage}_miss_rate"
            rows.append(MetricRow("*", metric, value, unit))
    for key in cols:
        if key.startswith("time.solve."):
            level = key.removeprefix("time.solve.")
            stats = timing_stats(cols[key][warmup:])
            rows.append(MetricRow(level, "t_solve_median_us", stats["median_us"], "us"))
    return rows


def walk_phases(cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Masks of the ticks of a run with a contact schedule by phase: ``double`` (two or more
    contacts active), ``single`` (one), and ``transition`` (the active set differs from the
    previous tick's: where a warm start is lost), the last taken out of the other two."""
    active = np.column_stack([v > 0 for k, v in cols.items() if k.startswith("active.")])
    count = active.sum(axis=1)
    changed = np.zeros(len(count), dtype=bool)
    changed[1:] = np.any(active[1:] != active[:-1], axis=1)
    return {
        "double": (count >= 2) & ~changed,
        "single": (count == 1) & ~changed,
        "transition": changed,
    }


def walk_metrics(
    walk: dict[str, Any],
    cols: dict[str, np.ndarray],
    warmup: int = 0,
    contacts: list[PlaneContact] | None = None,
) -> list[MetricRow]:
    """The metrics of a walk (``walk`` is :func:`wbcbench.sim.closed_loop.walk_record`'s):

    * ``steps_completed`` of ``steps_planned`` (touchdowns confirmed);
    * ``landing_error_{mean,max}`` [m]: each landed foot's frame from its footstep, in 3-D, and
      ``landing_error_xy_*`` / ``landing_error_z_*`` its parts in and normal to the floor;
    * ``dcm_error_{mean,max}`` [m]: the measured DCM x + ẋ/ω (simulated CoM) from the plan's;
    * ``cop_margin_{min,mean}`` [m]: the simulated CoP's distance inside its sole's edge, over
      the ticks a contact is active and carries load (negative: outside, the foot tips);
    * ``slip_max`` [m]: the largest horizontal move of an active, settled contact's frame from
      where its stance began;
    * the tick's total time per phase (:func:`walk_phases`): ``t_total_<stat>_<phase>`` [µs].
    """
    planned = sum(1 for f in walk["footsteps"] if f["touch_down"] is not None)
    landings = walk.get("landings", [])
    rows = [
        MetricRow("*", "steps_completed", float(len(landings)), "steps"),
        MetricRow("*", "steps_planned", float(planned), "steps"),
    ]
    for key, suffix in (("error", ""), ("error_xy", "_xy"), ("error_z", "_z")):
        errors = [landing[key] for landing in landings if key in landing]
        if errors:
            rows.append(MetricRow("*", f"landing_error{suffix}_mean", float(np.mean(errors)), "m"))
            rows.append(MetricRow("*", f"landing_error{suffix}_max", float(np.max(errors)), "m"))
    if "com.vx" in cols:
        plan = WalkPlan.from_dict(walk)
        com = np.column_stack([cols["com.x"], cols["com.y"]])
        dcm = com + np.column_stack([cols["com.vx"], cols["com.vy"]]) / plan.omega
        planned_dcm = np.array([plan.dcm(float(t)) for t in cols["t"]])
        error = np.linalg.norm(dcm - planned_dcm, axis=1)
        rows.append(MetricRow("*", "dcm_error_mean", float(np.mean(error)), "m"))
        rows.append(MetricRow("*", "dcm_error_max", float(np.max(error)), "m"))
    margins: list[np.ndarray] = []
    slip = 0.0
    for contact in contacts or []:
        f = contact.frame
        if f"active.{f}" not in cols:
            continue
        settled = cols[f"active.{f}"] >= 1.0
        fz = cols[f"wrench_sim.{f}.fz"]
        loaded = settled & (fz >= loaded_normal_force(contact))
        cop_x = -cols[f"wrench_sim.{f}.my"][loaded] / fz[loaded]
        cop_y = cols[f"wrench_sim.{f}.mx"][loaded] / fz[loaded]
        (x0, x1), (y0, y1) = contact.x_range, contact.y_range
        margins.append(np.minimum.reduce([cop_x - x0, x1 - cop_x, cop_y - y0, y1 - cop_y]))
        if f"foot.{f}.x" in cols:
            xy = np.column_stack([cols[f"foot.{f}.x"], cols[f"foot.{f}.y"]])
            # each stance is a run of settled ticks; its slip is measured from its first tick
            edges = np.flatnonzero(np.diff(np.r_[0, settled.astype(np.int8), 0]))
            for begin, end in zip(edges[::2], edges[1::2], strict=True):
                moved = np.linalg.norm(xy[begin:end] - xy[begin], axis=1)
                slip = max(slip, float(np.max(moved, initial=0.0)))
    if contacts is not None and margins:
        margin = np.concatenate(margins)
        if margin.size:
            rows.append(MetricRow("*", "cop_margin_min", float(np.min(margin)), "m"))
            rows.append(MetricRow("*", "cop_margin_mean", float(np.mean(margin)), "m"))
        rows.append(MetricRow("*", "slip_max", slip, "m"))
    if "time.total" in cols and any(k.startswith("active.") for k in cols):
        after = np.arange(len(cols["t"])) >= warmup
        for phase, where in walk_phases(cols).items():
            stats = timing_stats(cols["time.total"][where & after])
            for name in ("median_us", "p99_us"):
                rows.append(MetricRow("*", f"t_total_{name}_{phase}", stats[name], "us"))
            rows.append(MetricRow("*", f"ticks_{phase}", float(np.sum(where & after)), "ticks"))
    return rows
