"""What the notebooks in ``notebooks/`` share: the results folder they read, each paper's
verdicts as a table, and conclusions drawn from the numbers (never written by hand).

Run a notebook with ``jupyter execute notebooks/<name>.ipynb`` (the ``dev`` extra installs
Jupyter), or open it in JupyterLab; ``WBCBENCH_RESULTS=<folder>`` points it at your own
``make bench`` output instead of the curated ``results/reference``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pandas as pd

from wbcbench.report.load import Results, load_results

__all__ = [
    "WALK_TARGET_MM",
    "notebook_results",
    "paper_verdicts",
    "robustness_conclusion",
    "solver_conclusion",
    "verdict_conclusion",
    "verdict_markdown",
    "walk_coverage",
    "walk_phase_times",
    "walk_verdicts",
    "walking_conclusion",
]

#: the largest CoM and landing errors [mm] a walk run may show to count as walking on target
#: (ours: no paper states one for these walks)
WALK_TARGET_MM = 5.0


def notebook_results() -> Results:
    """The results a notebook reads: ``$WBCBENCH_RESULTS`` when set, else the curated
    ``results/reference`` of this clone (found from the package, so any working directory
    works)."""
    reference = Path(__file__).resolve().parents[2] / "results" / "reference"
    return load_results(os.environ.get("WBCBENCH_RESULTS", reference))


def paper_verdicts(res: Results, paper: str) -> pd.DataFrame:
    """The verdict rows of one paper (``TO-OSF``, ``OSF-HQP``, ``RC-LQP``, ``RQR-HQP``), as
    ``tables/verdicts.md`` states them."""
    from wbcbench.report.tables import build_tables
    from wbcbench.report.verdicts import verdicts

    frame = verdicts(build_tables(res))
    return frame[frame["paper"] == paper].reset_index(drop=True)


def verdict_markdown(frame: pd.DataFrame) -> str:
    """The verdicts as a Markdown table: claim, the paper's value, ours, verdict, reason."""
    if frame.empty:
        return "*No verdicts: the results hold none of this paper's runs.*"
    columns = [c for c in ("claim", "paper_value", "ours", "verdict", "reason") if c in frame]
    shown = frame[columns].rename(columns={"paper_value": "paper"})
    return str(shown.to_markdown(index=False))


def verdict_conclusion(frame: pd.DataFrame) -> str:
    """A short conclusion from the verdicts: how many claims hold, which do not and why."""
    if frame.empty:
        return "No claim of this paper could be judged from these results."
    counts = frame["verdict"].value_counts()
    summary = ", ".join(f"{n} {verdict}" for verdict, n in counts.items())
    lines = [f"Of {len(frame)} claims: {summary}."]
    held = frame[frame["verdict"] == "reproduced"]
    if not held.empty:
        lines.append(
            "Reproduced: "
            + "; ".join(f"{r['claim']} (ours {r['ours']})" for _, r in held.iterrows())
            + "."
        )
    for _, r in frame[frame["verdict"] != "reproduced"].iterrows():
        lines.append(f"{r['verdict'].capitalize()}: {r['claim']}: {r['reason']}")
    return "\n\n".join(lines)


def solver_conclusion(summary: pd.DataFrame) -> str:
    """A short conclusion from the solver comparison's summary
    (:func:`wbcbench.report.solvers.summarize`): which backends return a valid solution on
    every QP at the ``default`` tier, the fastest of them, and which report more solved than
    the independent check accepts."""
    if summary.empty:
        return "No solver comparison in these results."
    default = summary[summary["tier"] == "default"]
    per = default.groupby("solver").agg(
        valid=("success [%]", "min"),
        reported=("reported solved [%]", "min"),
        sgm=("wall sgm [µs]", "min"),
        problems=("problems", "max"),
    )
    lines = []
    perfect = per[per["valid"] >= 100.0].sort_values("sgm")
    if perfect.empty:
        best = per.sort_values("valid", ascending=False).iloc[0]
        lines.append(
            "No backend is valid on every QP at the default tier; the best reaches "
            f"{best['valid']:.1f} %."
        )
    else:
        fastest = perfect.iloc[0]
        lines.append(
            f"{len(perfect)} of {len(per)} backends return a valid solution on all "
            f"{int(fastest['problems'])} QPs at the default tier in every mode: "
            + ", ".join(f"`{s}`" for s in perfect.index)
            + f". The fastest of them is `{perfect.index[0]}` (shifted geometric mean "
            f"{fastest['sgm']:.0f} µs in its best mode)."
        )
    lying = per[per["reported"] > per["valid"] + 1e-9]
    if not lying.empty:
        lines.append(
            "Reported solved more often than the check accepts: "
            + ", ".join(
                f"`{s}` ({r['reported']:.0f} % vs {r['valid']:.0f} %)" for s, r in lying.iterrows()
            )
            + ": trust their status only with the check on."
        )
    return "\n\n".join(lines)


def robustness_conclusion(push: pd.DataFrame, degradation: pd.DataFrame) -> str:
    """A short conclusion from a push-recovery study's brackets
    (:func:`wbcbench.bench.push_recovery.read_push_rows`) and a degradation table
    (:func:`wbcbench.report.robustness.degradation_table`): per robot and solver, which
    controller survives the largest push in its weakest direction and which falls first (with
    the run's message); per perturbation, who falls first or who degrades most."""
    from wbcbench.bench.push_recovery import WHY, falls_first
    from wbcbench.report.robustness import degradation_falls_first

    lines = []
    if push.empty:
        lines.append("No push-recovery study in these results.")
    for (scenario, solver), rows in push.groupby(["scenario", "solver"], sort=False):
        # a controller's weakest direction: the smallest impulse it survived among those run
        weakest = rows.groupby("controller", sort=False)["survived_Ns"].min()
        directions = rows["direction"].nunique()
        top = weakest.max()
        best = [f"`{c}`" for c, j in weakest.items() if j == top]
        text = (
            f"**{scenario}, {solver}**: of {len(weakest)} controllers, "
            f"{' and '.join(best)} {'survive' if len(best) > 1 else 'survives'} the largest "
            f"push in every one of the {directions} directions run ({top:g} N·s)"
        )
        first = falls_first(rows)
        if not first.empty:
            worst = first.iloc[int(first["at [N·s]"].astype(float).to_numpy().argmin())]
            names = worst["falls first"].split(", ")
            text += (
                f"; the first to fall {'are' if len(names) > 1 else 'is'} "
                + " and ".join(f"`{n}`" for n in names)
                + f", at {worst['at [N·s]']} N·s pushed {worst['direction']}: {worst[WHY]}"
            )
        lines.append(text + ".")
    if degradation.empty:
        lines.append("No degradation runs in these results.")
    else:
        for _, r in degradation_falls_first(degradation).iterrows():
            what = r["perturbation"].split(" [")[0]
            where = f"**{what[0].upper()}{what[1:]}** ({r['scenario']}, {r['solver']}, "
            where += f"{r['controllers compared']} controllers)"
            if r["falls first"] == "none":
                largest = r["at"].removeprefix("none up to ")
                lines.append(
                    f"{where}: none falls up to {largest}, the largest size run; "
                    f"{r[WHY].removeprefix('every run ok; ')}."
                )
            else:
                lines.append(f"{where}: `{r['falls first']}` falls first, at {r['at']}: {r[WHY]}.")
    return "\n\n".join(lines)


def _ticks(n: float, phase: str = "") -> str:
    return f"{n:.0f} {phase + ' ' if phase else ''}tick{'' if n == 1 else 's'}"


#: the columns that name a walk run in the notebook's tables
IDENTITY = ("robot", "scenario", "controller", "solver", "impl")


def _identity(run: pd.Series) -> dict[str, Any]:
    return {key: run[key] for key in IDENTITY}


def walk_verdicts(res: Results) -> pd.DataFrame:
    """One row per run of the walking table (:func:`wbcbench.report.tables.walking.walk_runs`):
    the steps it completed of those planned, whether it fell, the largest CoM and landing
    errors [mm], and its verdict against :data:`WALK_TARGET_MM`: ``walks`` (every planned step,
    no fall, both errors within the target), ``off target`` (every step, no fall, an error
    beyond it) or ``ends early`` (it fell, failed or was cut short), with why."""
    from wbcbench.report.tables.common import _metric, _run_status, run_spec
    from wbcbench.report.tables.walking import walk_runs

    rows = []
    for _, run in walk_runs(res).iterrows():
        rid = run["run_id"]
        spec = run_spec(res, run)
        done = _metric(res, rid, "steps_completed")
        planned = _metric(res, rid, "steps_planned")
        com = 1e3 * _metric(res, rid, "err_max", spec.walk.com_task if spec else "com")
        landing = 1e3 * _metric(res, rid, "landing_error_max")
        if run["status"] != "ok":
            verdict, why = "ends early", _run_status(run)
        elif not done >= planned:
            sim = float(run["sim_duration_s"])
            verdict, why = "ends early", f"cut short at {sim:.3g} s, before its last step"
        else:
            beyond = [
                f"{name} error up to {err:.3g} mm"
                for name, err in (("CoM", com), ("landing", landing))
                if not err <= WALK_TARGET_MM
            ]
            verdict = "off target" if beyond else "walks"
            why = (
                ", ".join(beyond) + f", beyond {WALK_TARGET_MM:g} mm"
                if beyond
                else f"every step, both errors within {WALK_TARGET_MM:g} mm"
            )
        rows.append(
            {
                **_identity(run),
                "steps": f"{done:.0f}/{planned:.0f}",
                "fell": run["status"] == "fell",
                "CoM err max [mm]": com,
                "landing err max [mm]": landing,
                "verdict": verdict,
                "why": why,
            }
        )
    columns = [*IDENTITY, "steps", "fell"]
    columns += ["CoM err max [mm]", "landing err max [mm]", "verdict", "why"]
    return pd.DataFrame(rows, columns=columns)


def walk_phase_times(res: Results) -> pd.DataFrame:
    """The whole tick's median and p99 [µs] per walk phase (``double``, ``single``,
    ``transition``: the ticks whose active contact set differs from the previous tick's) of
    each run of the walking table, with the number of ticks and the control period [µs], the
    deadline a tick must meet."""
    from wbcbench.report.tables.common import _metric, run_spec
    from wbcbench.report.tables.walking import PHASES, walk_runs

    rows = []
    for _, run in walk_runs(res).iterrows():
        spec = run_spec(res, run)
        for phase in PHASES:
            rows.append(
                {
                    **_identity(run),
                    "phase": phase,
                    "ticks": _metric(res, run["run_id"], f"ticks_{phase}"),
                    "median [µs]": _metric(res, run["run_id"], f"t_total_median_us_{phase}"),
                    "p99 [µs]": _metric(res, run["run_id"], f"t_total_p99_us_{phase}"),
                    "deadline [µs]": 1e6 / spec.control_rate if spec else float("nan"),
                }
            )
    columns = [*IDENTITY, "phase", "ticks"]
    columns += ["median [µs]", "p99 [µs]", "deadline [µs]"]
    return pd.DataFrame(rows, columns=columns)


def walk_coverage(res: Results) -> pd.DataFrame:
    """Every walk scenario of the ``scenarios/`` folder and of the results: its robot, the
    steps its file plans, how many closed-loop runs of it the results hold, how many of those
    stood still (ended ok before their first touchdown, as the sweeps' 0.5 s health checks
    do) and how many the walking table judges (one per controller × solver × impl)."""
    from wbcbench.report.tables.common import _metric, scenario_spec
    from wbcbench.report.tables.walking import walk_runs
    from wbcbench.scenarios.load import available_scenarios

    tracking = res.of_kind("tracking")
    in_results = [str(s) for s in tracking["scenario"].unique()] if not tracking.empty else []
    judged = walk_runs(res)
    rows = []
    for name in sorted(set(available_scenarios()) | set(in_results)):
        spec = scenario_spec(res, name)
        if spec is None or spec.walk is None:
            continue
        walk = spec.walk
        runs = tracking[tracking["scenario"] == name] if in_results else tracking.iloc[0:0]
        rows.append(
            {
                "scenario": name,
                "robot": spec.robot,
                "steps planned": walk.steps if walk.steps is not None else len(walk.footsteps),
                "runs": len(runs),
                "stood still": sum(
                    1
                    for _, r in runs.iterrows()
                    if r["status"] == "ok" and not _metric(res, r["run_id"], "steps_completed") > 0
                ),
                "judged": int((judged["scenario"] == name).sum()) if not judged.empty else 0,
            }
        )
    return pd.DataFrame(
        rows, columns=["scenario", "robot", "steps planned", "runs", "stood still", "judged"]
    )


def walking_conclusion(verdicts: pd.DataFrame, phases: pd.DataFrame, coverage: pd.DataFrame) -> str:
    """A short conclusion from :func:`walk_verdicts`, :func:`walk_phase_times` and
    :func:`walk_coverage`: which runs walk every step on target and their largest errors,
    which end early and why, the slowest phase at the median and the phases whose p99 misses
    the deadline, and which walk scenarios these results do not judge."""

    def who(r: pd.Series) -> str:
        return f"`{r['controller']}` × {r['solver']} ({r['impl']}) on {r['scenario']}"

    lines = []
    if verdicts.empty:
        lines.append("No walk run in these results took a step.")
    else:
        walks = verdicts[verdicts["verdict"] == "walks"]
        n, k = len(verdicts), len(walks)
        text = f"Of {n} walk run{'s' if n > 1 else ''}, {k} walk{'s' if k == 1 else ''} "
        text += "every planned step"
        if not walks.empty:
            text += (
                f" within the {WALK_TARGET_MM:g} mm targets: "
                + "; ".join(f"{who(r)}, {r['steps']} steps" for _, r in walks.iterrows())
                + f". {'Its' if len(walks) == 1 else 'Their'} CoM error is at most "
                f"{walks['CoM err max [mm]'].max():.3g} mm and "
                f"{'its' if len(walks) == 1 else 'their'} landing error at most "
                f"{walks['landing err max [mm]'].max():.3g} mm"
            )
        lines.append(text + ".")
        for _, r in verdicts[verdicts["verdict"] != "walks"].iterrows():
            lines.append(f"{who(r)} {r['verdict']}, {r['steps']} steps: {r['why']}.")
    timed = phases.dropna(subset=["median [µs]"])
    keys = ["scenario", "controller", "solver", "impl"]
    slowest_phase = timed.loc[timed.groupby(keys, sort=False)["median [µs]"].idxmax(), "phase"]
    if len(slowest_phase) > 1:
        counts = slowest_phase.value_counts()
        lines.append(
            "Slowest phase at the median: "
            + ", ".join(
                f"{phase} ticks in {k} of {len(slowest_phase)} runs" for phase, k in counts.items()
            )
            + "."
        )
    for _, run in timed.groupby(keys, sort=False):
        r = run.iloc[0]
        slowest = run.iloc[int(run["median [µs]"].to_numpy().argmax())]
        others = run[run["phase"] != slowest["phase"]]
        text = (
            f"{who(r)}: the {slowest['phase']} ticks are the slowest at the median "
            f"({slowest['median [µs]']:.0f} µs over {_ticks(slowest['ticks'])}, against "
            + " and ".join(f"{o['median [µs]']:.0f} µs {o['phase']}" for _, o in others.iterrows())
            + ")"
        )
        late = run[run["p99 [µs]"] > run["deadline [µs]"]]
        deadline = f"{r['deadline [µs]'] / 1e3:g} ms"
        if late.empty:
            text += f"; every phase's p99 is within the {deadline} deadline"
        else:
            text += f"; the p99 misses the {deadline} deadline in " + ", ".join(
                f"{o['phase']} ({o['p99 [µs]']:.0f} µs)" for _, o in late.iterrows()
            )
        few = run[run["ticks"] < 100]
        if not few.empty:
            text += (
                "; the p99 of "
                + " and ".join(f"{_ticks(o['ticks'], o['phase'])}" for _, o in few.iterrows())
                + " is close to their largest"
            )
        lines.append(text + ".")
    never = coverage[coverage["runs"] == 0]["scenario"].tolist()
    if never:
        lines.append("Not run in these results: " + ", ".join(f"`{s}`" for s in never) + ".")
    still = coverage[coverage["stood still"] > 0]
    if not still.empty:
        lines.append(
            "Not judged, having ended before their first touchdown: "
            + ", ".join(
                f"{r['stood still']} run{'s' if r['stood still'] > 1 else ''} of `{r['scenario']}`"
                for _, r in still.iterrows()
            )
            + "."
        )
    if not verdicts.empty:
        asked = verdicts.assign(asked=verdicts["steps"].str.split("/").str[1].astype(float))
        asked = asked.merge(coverage[["scenario", "steps planned"]], on="scenario")
        cut = asked[asked["asked"] < asked["steps planned"]]
        for (scenario, count, of), group in cut.groupby(["scenario", "asked", "steps planned"]):
            runs = f"The {len(group)} runs" if len(group) > 1 else "The run"
            lines.append(
                f"{runs} of `{scenario}` judged here {'were' if len(group) > 1 else 'was'} "
                f"asked for {count:.0f} of the {of} steps its scenario file plans."
            )
    return "\n\n".join(lines)
