"""Push recovery: the largest push each controller × solver survives, per direction.

A push is a constant horizontal force on a body (the pelvis or the torso) over ``duration``
from ``start`` (the phase), of impulse J [N·s] (force J / duration); the simulation applies it,
the controller is never told (:mod:`wbcbench.sim.perturbations`). A run **survives** when it
ends ``ok`` (no fall, and the run was not stopped by failed ticks), with no failed tick at all,
and the robot's CoM (on the simulated robot) is back within ``recover_distance`` of its
reference at the end of ``recover_time`` after the push.

The largest survived impulse is found by bisection on [0, ``max_impulse``]: the unpushed run
first (a controller that does not stand unpushed has no bracket), then ``max_impulse`` (survived:
the bracket is open above), then midpoints until the bracket [survived, failed] is at most
``resolution`` wide. Bisection assumes survival is monotonic in the impulse; a controller whose
survival is not (it survives a larger push that it fails at a smaller one) is reported by the
bracket the bisection found, which is a bracket of a transition, not the only one.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from wbcbench.errors import WbcBenchError
from wbcbench.runs import Planner, Run
from wbcbench.sim.closed_loop import RunResult, run_closed_loop

__all__ = [
    "DIRECTIONS",
    "WHY",
    "PushBracket",
    "PushStudy",
    "falls_first",
    "largest_push",
    "push_table",
    "read_push_rows",
    "run_push_study",
    "write_push_table",
]

#: the push directions a study can name: unit vectors in the world's horizontal plane
DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
}

CSV = "push_recovery.csv"

#: the column of the "falls first" tables that quotes the failed run's own message
WHY = "why (the run's message)"


@dataclass(frozen=True)
class PushStudy:
    """The settings of a study (the sweep file's ``push_recovery``; see the module docstring).

    Attributes:
        body: the pushed body [name].
        start: when the push starts [s] (settling first, if the scenario settles).
        duration: how long it lasts [s].
        recover_time: how long after the push the CoM has to be back [s].
        recover_distance: how close to its reference the CoM has to be then [m].
        max_impulse: the upper end of the search [N·s].
        resolution: the widest bracket reported [N·s].
    """

    body: str = "pelvis"
    start: float = 0.5
    duration: float = 0.1
    recover_time: float = 1.0
    recover_distance: float = 0.02
    max_impulse: float = 80.0
    resolution: float = 5.0

    @property
    def run_duration(self) -> float:
        return self.start + self.duration + self.recover_time


@dataclass
class Trial:
    impulse: float  # [N·s]
    survived: bool
    why: str  # the run's own message, or how far the CoM was; "" when survived


@dataclass
class PushBracket:
    """The result of one controller × solver × direction: survived ≤ J* < failed."""

    scenario: str
    controller: str
    solver: str
    impl: str
    direction: str
    survived_Ns: float  # NaN: falls without a push
    failed_Ns: float  # NaN: survived max_impulse
    failure: str  # why the smallest failed push failed
    trials: list[Trial] = field(default_factory=list)
    wall_time_s: float = 0.0


def com_task(run: Run) -> str:
    """The name of the scenario's CoM task (the CoM the recovery is judged by)."""
    for task in run.scenario.spec.tasks:
        if task.type == "com":
            return task.name
    raise WbcBenchError(
        f"{run.scenario.path}: push recovery needs a com task; the scenario has none"
    )


def push_overrides(study: PushStudy, direction: str, impulse: float) -> list[str]:
    """The scenario overrides of one trial: its duration, window and push."""
    force = [impulse / study.duration * c for c in DIRECTIONS[direction]]
    push = {
        "body": study.body,
        "start": study.start,
        "duration": study.duration,
        "force": force,
    }
    return [
        f"duration={study.run_duration}",
        f"metrics.window=[0.0, {study.run_duration}]",
        f"perturbations.pushes=[{json.dumps(push)}]" if impulse > 0 else "perturbations.pushes=[]",
    ]


def judge(result: RunResult, study: PushStudy, task: str) -> tuple[bool, str]:
    """Whether a trial survived, and why not."""
    if result.status != "ok":
        return False, f"{result.status}: {result.message}"
    if result.failures:
        return False, f"{result.failures} failed ticks"
    log = result.log.arrays()
    err = log.get(f"true_err.{task}.pos", log[f"err.{task}.pos"])
    if not err[-1] <= study.recover_distance:
        t = study.run_duration
        return False, (
            f"CoM {1e3 * err[-1]:.1f} mm from its reference at t = {t:g} s "
            f"(at most {1e3 * study.recover_distance:g} mm)"
        )
    return True, ""


def largest_push(
    planner: Planner,
    scenario: str,
    controller: str,
    solver: str,
    direction: str,
    study: PushStudy,
    overrides: tuple[str, ...] = (),
) -> PushBracket:
    """Bisect the largest impulse in ``direction`` that ``controller`` with ``solver``
    survives (see the module docstring)."""
    wall0 = time.perf_counter()
    trials: list[Trial] = []
    impl = ""

    def trial(impulse: float) -> Trial:
        nonlocal impl
        ov = (*overrides, *push_overrides(study, direction, impulse))
        run = planner.run(scenario, controller, solver, overrides=ov)
        impl = run.impl
        survived, why = judge(run_closed_loop(run), study, com_task(run))
        trials.append(Trial(round(impulse, 6), survived, why))
        return trials[-1]

    def bracket(lo: float, hi: float, failure: str) -> PushBracket:
        loaded = planner.scenario(scenario, overrides)[0]
        return PushBracket(
            loaded.name,
            controller,
            solver,
            impl,
            direction,
            lo,
            hi,
            failure,
            trials,
            round(time.perf_counter() - wall0, 2),
        )

    unpushed = trial(0.0)
    if not unpushed.survived:
        return bracket(np.nan, 0.0, unpushed.why)
    top = trial(study.max_impulse)
    if top.survived:
        return bracket(study.max_impulse, np.nan, "")
    lo, hi, failure = 0.0, study.max_impulse, top.why
    while hi - lo > study.resolution:
        mid = (lo + hi) / 2
        t = trial(mid)
        if t.survived:
            lo = mid
        else:
            hi, failure = mid, t.why
    return bracket(lo, hi, failure)


def study_key(study: PushStudy, scenario_hash: str, controller: str, solver: str, d: str) -> str:
    """What a stored bracket is resumed by (the code version is added by the caller)."""
    text = json.dumps([asdict(study), scenario_hash, controller, solver, d], sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_push_study(
    targets: list[tuple[str, str, str, str]],
    directions: list[str],
    study: PushStudy,
    out: Path,
    version: str,
    show_progress: bool = True,
) -> pd.DataFrame:
    """Every (scenario, controller, solver, pushed body) of ``targets`` × direction, appended to
    ``out/push_recovery.csv`` as each finishes (a bracket already there for the same code is
    kept, not recomputed), and the table ``out/tables/push_recovery.md``. Returns the rows."""
    planner = Planner()
    path = out / CSV
    done = pd.read_csv(path) if path.exists() else pd.DataFrame()
    code = version.split("@", 1)[0]
    for scenario, controller, solver, body in targets:
        loaded = planner.scenario(scenario)[0]
        pushed = dataclasses.replace(study, body=body)
        for d in directions:
            key = study_key(pushed, loaded.hash, controller, solver, d)
            if not done.empty and ((done["key"] == key) & (done["code"] == code)).any():
                continue
            b = largest_push(planner, scenario, controller, solver, d, pushed)
            if show_progress:
                print(
                    f"push recovery · {b.scenario} · {controller} · {solver} · {d}: "
                    f"{bracket_text(b.survived_Ns, b.failed_Ns)} N·s ({b.wall_time_s:.0f} s)",
                    flush=True,
                )
            row = {
                "key": key,
                "code": code,
                **{k: v for k, v in asdict(b).items() if k != "trials"},
                "body": body,
                "push_duration_s": study.duration,
                "resolution_Ns": study.resolution,
                "trials": json.dumps([asdict(t) for t in b.trials]),
            }
            done = pd.concat([done, pd.DataFrame([row])], ignore_index=True)
            done.to_csv(path, index=False)
    write_push_table(out)
    return done


def bracket_text(survived: float, failed: float) -> str:
    """``J [lo, hi]``: the survived impulse and its bracket [N·s]."""
    if np.isnan(survived):
        return "falls unpushed"
    if np.isnan(failed):
        return f"≥ {survived:g}"
    return f"{survived:g} [{survived:g}, {failed:g})"


def push_table(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per scenario × controller × solver, one column per direction: the largest
    survived impulse [N·s] with its bracket [survived, failed)."""
    if rows.empty:
        return pd.DataFrame()
    rows = rows.assign(
        cell=[
            bracket_text(s, f) for s, f in zip(rows["survived_Ns"], rows["failed_Ns"], strict=True)
        ]
    )
    table = rows.pivot_table(
        index=["scenario", "controller", "solver", "impl"],
        columns="direction",
        values="cell",
        aggfunc="last",
        sort=False,
    )
    table = table[[d for d in DIRECTIONS if d in table.columns]]
    return table.reset_index().rename_axis(columns=None).fillna("not run")


def falls_first(rows: pd.DataFrame) -> pd.DataFrame:
    """Per scenario × solver × direction, the controller(s) with the smallest failed impulse
    [N·s] (a controller that falls unpushed fails at 0; one that survived ``max_impulse`` never
    fails), with why that push failed (the run's own message); rows where every controller
    survived the largest push are left out."""
    if rows.empty:
        return pd.DataFrame()
    out = []
    for (scenario, solver, direction), group in rows.groupby(
        ["scenario", "solver", "direction"], sort=False
    ):
        failed = group[group["failed_Ns"].notna()]
        if failed.empty:
            continue
        at = float(failed["failed_Ns"].min())
        first = failed[failed["failed_Ns"] == at]
        n = group["controller"].nunique()
        out.append(
            {
                "scenario": scenario,
                "solver": solver,
                "direction": direction,
                "falls first": ", ".join(first["controller"]),
                "at [N·s]": f"{at:g}",
                "controllers compared": n,
                WHY: "; ".join(
                    f"{c}: {w}" if len(first) > 1 else str(w)
                    for c, w in zip(first["controller"], first["failure"], strict=True)
                ),
            }
        )
    return pd.DataFrame(out)


def read_push_rows(folder: str | Path) -> pd.DataFrame:
    """The study's brackets stored in ``folder`` (empty when it holds no push study)."""
    path = Path(folder) / CSV
    return pd.read_csv(path) if path.exists() else pd.DataFrame()


def write_push_table(out: Path) -> Path | None:
    """``out/tables/push_recovery.md`` from ``out/push_recovery.csv``: the brackets, the study's
    settings, the wall time, and why the smallest failed push of each failed."""
    path = out / CSV
    if not path.exists():
        return None
    rows = pd.read_csv(path)
    table = push_table(rows)
    first = rows.iloc[0]
    lines = [
        "# Push recovery",
        "",
        f"Largest survived impulse [N·s] of a {first['push_duration_s']:g} s push on "
        f"{', '.join(f'`{b}`' for b in rows['body'].unique())} (the robot's pelvis) in each world "
        f"direction, by bisection to {first['resolution_Ns']:g} "
        "N·s: `J [survived, failed)`. Survival: no fall, no failed tick, the CoM back within "
        "the study's distance of its reference at the end of the run (see docs/robustness.md).",
        "",
        table.to_markdown(index=False),
        "",
        f"Wall time of the study: {rows['wall_time_s'].sum():.0f} s.",
        "",
    ]
    first_falls = falls_first(rows)
    if not first_falls.empty:
        lines += [
            "## Which controller falls first",
            "",
            "Per robot, solver and direction, the controller whose smallest failed push is the "
            "smallest (all of them on a tie), and why that push failed, in the run's own words.",
            "",
            first_falls.to_markdown(index=False),
            "",
        ]
    lines += ["## Why the smallest failed push failed", ""]
    for _, r in rows.iterrows():
        if isinstance(r["failure"], str) and r["failure"]:
            lines.append(
                f"- {r['scenario']} · {r['controller']} · {r['solver']} · {r['direction']} "
                f"at {r['failed_Ns']:g} N·s: {r['failure']}"
            )
    target = out / "tables" / "push_recovery.md"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text("\n".join(lines) + "\n")
    return target
