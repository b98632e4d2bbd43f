"""Which controller × solver to use: per robot and scenario family, the fastest within the
control budget, the most accurate and the most robust, each with its numbers and caveats
(``recommendations.md``, written beside the paper tables by ``wbcbench tables``).

* **fastest**: open-loop replay timing (``kind = timing``) of runs that did not fail; the p99 of
  the whole step must be within the control period (1 / ``control_rate``) on every scenario of
  the family the combination was timed on; among the combinations timed on the most scenarios,
  the smallest median of the per-scenario median steps [µs];
* **most accurate**: closed-loop tracking runs (``kind = tracking``) without perturbations
  (those are the robustness study's); per scenario and task, each
  combination's mean error is divided by the best combination's on that task, and the
  combination with the smallest geometric mean of those ratios over the family wins (1.0 = best
  on every task). A combination that fell on a scenario of the family is ranked after those
  that held;
* **most robust**: the share of the controller's dumped QPs that the solver answered with a
  solution the independent check accepts (the solver comparison, tier ``default``, every mode),
  ties broken by fewer failed ticks in the runs, then by the faster solve; where the family has
  no dumped QPs, the share of ticks that did not fail in its runs.

Every figure is from the folder's own runs, so a recommendation holds for that folder's machine,
durations and sweep; the caveats say how much data each rests on.
"""

from __future__ import annotations

from fnmatch import fnmatch
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report.load import Results, load_results

__all__ = [
    "FAMILIES",
    "family_of",
    "recommendations",
    "recommendations_markdown",
    "write_recommendations",
]

#: scenario-name pattern → family, first match wins; a scenario matching none is its own family
FAMILIES: tuple[tuple[str, str], ...] = (
    ("rqr_*", "kinematic reaching (RQR-HQP)"),
    ("*stand_sway*", "standing sway"),
    ("lee2021access_*", "TO-OSF scenarios (Lee 2021, multi-contact)"),
    ("lee2021iros_*", "OSF-HQP scenario (Lee 2021, hands and CoM)"),
    ("ahn_*", "RC-LQP scenarios (Ahn, double and single support)"),
)

KEY = ["controller", "impl", "solver", "tier", "mode"]


def family_of(scenario: str) -> str:
    """The scenario's family (see :data:`FAMILIES`)."""
    for pattern, name in FAMILIES:
        if fnmatch(scenario, pattern):
            return name
    return scenario


def _combo(row: pd.Series) -> str:
    impl = row.get("impl")
    impl = f" ({impl})" if isinstance(impl, str) and impl not in ("", "-") else ""
    return f"`{row['controller']}`{impl} × `{row['solver']}` ({row['tier']}, {row['mode']})"


def _with_family(runs: pd.DataFrame) -> pd.DataFrame:
    runs = runs[runs["robot"].astype(str) != "-"]
    if "impl" not in runs.columns:
        runs = runs.assign(impl="")
    return runs.assign(
        family=[family_of(str(s)) for s in runs["scenario"]],
        impl=runs["impl"].fillna("").astype(str),
        tier=runs["tier"].fillna("-").astype(str),
        mode=runs["mode"].fillna("-").astype(str),
    )


def _metric(res: Results, metric: str) -> pd.Series:
    m = res.metrics
    if m.empty:
        return pd.Series(dtype=float)
    m = m[(m["task"] == "*") & (m["metric"] == metric)]
    return m.drop_duplicates("run_id").set_index("run_id")["value"].astype(float)


def _budget_us(res: Results, scenario: str) -> float:
    from wbcbench.report.tables import scenario_spec

    try:
        spec = scenario_spec(res, scenario)
    except Exception:  # a scenario file since removed: the usual 1 kHz loop
        spec = None
    return 1e6 / float(spec.control_rate) if spec is not None else 1000.0


def _n(count: int, word: str) -> str:
    return f"{count} {word}" + ("" if count == 1 else "s")


def _fastest(res: Results, timing: pd.DataFrame, fell: set[str]) -> tuple[str, str]:
    """The fastest combination within budget, and the caveat. A controller that fell in a
    closed-loop run of the family (``fell``) ranks after those that held."""
    ok = timing[timing["status"] == "ok"]
    failed = len(timing) - len(ok)
    median, p99 = _metric(res, "t_total_median_us"), _metric(res, "t_total_p99_us")
    ok = ok[ok["run_id"].isin(median.index) & ok["run_id"].isin(p99.index)]
    if ok.empty:
        return "no timing runs", "time a matrix with `timing: true` on these scenarios"
    ok = ok.assign(
        median=median.reindex(ok["run_id"]).to_numpy(),
        p99=p99.reindex(ok["run_id"]).to_numpy(),
        budget=[_budget_us(res, str(s)) for s in ok["scenario"]],
    )
    rows = []
    for key, g in ok.groupby(KEY):
        per = g.groupby("scenario").agg(median=("median", "median"), p99=("p99", "max"))
        within = bool((g["p99"] <= g["budget"]).all())
        rows.append(
            {
                **dict(zip(KEY, key, strict=True)),
                "scenarios": len(per),
                "median": float(per["median"].median()),
                "p99": float(per["p99"].max()),
                "budget": float(g["budget"].min()),
                "within": within,
            }
        )
    table = pd.DataFrame(rows)
    inside = table[table["within"]]
    if inside.empty:
        best = table.sort_values("p99").iloc[0]
        return (
            f"none within the {best['budget']:.0f} µs budget; lowest p99 {_combo(best)}: "
            f"{best['p99']:.0f} µs",
            f"{len(table)} combinations timed",
        )
    inside = inside[inside["scenarios"] == inside["scenarios"].max()]
    inside = inside.assign(fell=inside["controller"].isin(fell)).sort_values(["fell", "median"])
    best = inside.iloc[0]
    text = (
        f"{_combo(best)}: median {best['median']:.0f} µs, p99 {best['p99']:.0f} µs "
        f"(budget {best['budget']:.0f} µs)"
    )
    if best["fell"]:
        text += "; it fell in a closed-loop run of this family, as every faster one did"
    if len(inside) > 1:
        second = inside.iloc[1]
        text += f"; next {_combo(second)}: {second['median']:.0f} µs"
    caveat = (
        f"{_n(len(table), 'combination')} timed on {_n(int(best['scenarios']), 'scenario')} "
        f"each, {len(table) - len(table[table['within']])} over budget"
    )
    if failed:
        caveat += f", {_n(failed, 'failed run')} left out"
    return text, caveat


def _accurate(res: Results, tracking: pd.DataFrame) -> tuple[str, str]:
    """The most accurate combination, and the caveat."""
    if tracking.empty or res.metrics.empty:
        return "no tracking runs", "run the family's scenarios closed loop"
    m = res.metrics[
        res.metrics["run_id"].isin(tracking["run_id"])
        & (res.metrics["metric"] == "err_mean")
        & (res.metrics["task"] != "*")
    ][["run_id", "task", "value"]]
    if m.empty:
        return "no tracking errors", ""
    m = m.merge(tracking[["run_id", "scenario", "status", *KEY]], on="run_id")
    # per scenario and task the best error of the runs that held (a run that fell is no
    # standard); zero errors (a task held exactly) count as the floor
    m = m.assign(value=m["value"].astype(float).clip(lower=1e-15))
    held_values = m["value"].where(m["status"] == "ok")
    best = held_values.groupby([m["scenario"], m["task"]]).transform("min")
    best = best.fillna(m.groupby(["scenario", "task"])["value"].transform("min"))
    m = m.assign(ratio=m["value"] / best)
    scores = []
    for key, g in m.groupby(KEY):
        held = g[g["status"] == "ok"]
        fell = int(g.loc[g["status"] != "ok", "scenario"].nunique())
        if held.empty:
            continue
        worst = held.iloc[int(np.argmax(held["ratio"].to_numpy()))]
        scores.append(
            {
                **dict(zip(KEY, key, strict=True)),
                "fell": fell,
                "scenarios": int(held["scenario"].nunique()),
                "score": float(np.exp(np.log(held["ratio"]).mean())),
                "worst": f"{worst['task']} on {worst['scenario']} {worst['ratio']:.2g}×",
            }
        )
    if not scores:
        return "every run fell", f"{tracking['run_id'].nunique()} runs"
    table = pd.DataFrame(scores).sort_values(
        ["fell", "scenarios", "score"], ascending=[True, False, True]
    )
    top = table.iloc[0]
    text = (
        f"{_combo(top)}: errors {top['score']:.3g}× the best per task (geometric mean over "
        f"{_n(int(top['scenarios']), 'scenario')}); its worst: {top['worst']}"
    )
    solvers = sorted(set(tracking["solver"].astype(str)))
    caveat = f"{_n(len(table), 'combination')}, solvers: {', '.join(solvers)}"
    fallen = sorted(set(tracking.loc[tracking["status"] != "ok", "controller"].astype(str)))
    if fallen:
        caveat += "; fell on a scenario: " + ", ".join(f"`{c}`" for c in fallen)
    return text, caveat


def _robust(res: Results, runs: pd.DataFrame, scenarios: set[str]) -> tuple[str, str]:
    """The most robust combination, and the caveat."""
    failed_ticks: dict[tuple[str, str], float] = {}
    for _, r in runs.iterrows():
        key = (str(r["controller"]), str(r["solver"]))
        failures = float(r["failures"]) if pd.notna(r["failures"]) else 0.0
        failed_ticks[key] = failed_ticks.get(key, 0.0) + failures
    q = res.qp_solves
    if not q.empty:
        q = q[q["scenario"].astype(str).isin(scenarios) & (q["tier"] == "default")]
    if not q.empty:
        rows = []
        for (controller, solver), g in q.groupby(["controller", "solver"]):
            rows.append(
                {
                    "controller": controller,
                    "solver": solver,
                    "valid": 100.0 * float(g["valid"].astype(bool).mean()),
                    "reported": 100.0 * float(g["reported_solved"].astype(bool).mean()),
                    "problems": int(g["problem"].nunique()),
                    "failed_ticks": failed_ticks.get((str(controller), str(solver)), 0.0),
                    "wall": float(g["wall_us"].median()),
                }
            )
        table = pd.DataFrame(rows).sort_values(
            ["valid", "failed_ticks", "wall"], ascending=[False, True, True]
        )
        top = table.iloc[0]
        tied = table[table["valid"] == top["valid"]]
        text = (
            f"`{top['controller']}` × `{top['solver']}`: {top['valid']:.1f} % valid of "
            f"{top['problems']} dumped QPs (reported solved {top['reported']:.1f} %), median "
            f"solve {top['wall']:.0f} µs"
        )
        lies = table[table["reported"] > table["valid"] + 1e-9]
        caveat = (
            f"solver comparison, tier default, every mode; {len(tied)} of {len(table)} "
            f"combinations reach {top['valid']:.1f} %"
        )
        if not lies.empty:
            caveat += "; reported solved more often than valid: " + ", ".join(
                f"`{r['solver']}` on `{r['controller']}` "
                f"({r['reported']:.0f} vs {r['valid']:.0f} %)"
                for _, r in lies.head(4).iterrows()
            )
        return text, caveat
    # no dumped QPs: the closed-loop runs, a fall ranking last
    closed = runs[runs["kind"] == "tracking"]
    if closed.empty:
        return "no closed-loop runs", ""
    closed = closed.assign(
        failures=closed["failures"].fillna(0).astype(float),
        ticks=closed["ticks"].fillna(0).astype(float),
        fell=closed["status"] != "ok",
    )
    per = closed.groupby(["controller", "solver"]).agg(
        failures=("failures", "sum"), ticks=("ticks", "sum"), fell=("fell", "sum")
    )
    per = per[per["ticks"] > 0]
    if per.empty:
        return "no closed-loop ticks", ""
    per = per.assign(rate=100.0 * (1.0 - per["failures"] / per["ticks"]))
    per = per.sort_values(["fell", "rate", "ticks"], ascending=[True, False, False])
    (controller, solver), top = per.index[0], per.iloc[0]
    text = (
        f"`{controller}` × `{solver}`: {top['rate']:.1f} % of {int(top['ticks'])} closed-loop "
        "ticks without a failure"
    )
    if top["fell"]:
        text += f", but it fell in {int(top['fell'])} run(s), as every other did"
    return (
        text,
        "no dumped QPs for this family: from the closed-loop runs' failed ticks (which include "
        "the independent check's refusals), a run that fell ranking last",
    )


def recommendations(res: Results | str | Path) -> pd.DataFrame:
    """One row per robot and scenario family: ``robot, family, scenarios, fastest,
    most accurate, most robust, caveats``."""
    if not isinstance(res, Results):
        res = load_results(res)
    if res.runs.empty:
        return pd.DataFrame()
    runs = _with_family(res.runs)
    rows = []
    for (robot, family), g in runs.groupby(["robot", "family"]):
        scenarios = set(g["scenario"].astype(str))
        tracking = g[g["kind"] == "tracking"]
        if "settings" in tracking:
            # a perturbed run measures robustness (wbcbench.report.robustness), not accuracy
            perturbed = tracking["settings"].fillna("").astype(str).str.contains('"perturbations"')
            tracking = tracking[~perturbed]
        fell = set(tracking.loc[tracking["status"] != "ok", "controller"].astype(str))
        fastest, fast_caveat = _fastest(res, g[g["kind"] == "timing"], fell)
        accurate, acc_caveat = _accurate(res, tracking)
        robust, rob_caveat = _robust(res, g, scenarios)
        caveats: list[Any] = [
            f"fastest: {fast_caveat}" if fast_caveat else "",
            f"accurate: {acc_caveat}" if acc_caveat else "",
            f"robust: {rob_caveat}" if rob_caveat else "",
        ]
        rows.append(
            {
                "robot": robot,
                "family": family,
                "scenarios": ", ".join(sorted(scenarios)),
                "fastest (p99 within budget)": fastest,
                "most accurate": accurate,
                "most robust": robust,
                "caveats": "; ".join(c for c in caveats if c),
            }
        )
    return pd.DataFrame(rows)


def recommendations_markdown(res: Results) -> str:
    """``recommendations.md``: per robot and family, the three picks and their caveats."""
    frame = recommendations(res)
    lines = [
        "# Which controller and solver to use",
        "",
        f"From the runs in this folder, measured on {res.machine} "
        f"({res.provenance.get('date', 'date unknown')}). Fastest: the smallest median step "
        "[µs] of open-loop replay among the combinations whose p99 stays within the control "
        "period on every scenario they were timed on. Most accurate: the smallest geometric "
        "mean, over the family's closed-loop runs, of each task's mean error divided by the "
        "best combination's (1 = best everywhere); runs that fell rank last. Most robust: the "
        "share of the controller's dumped QPs the solver answered with a solution the "
        "independent check accepts. The three picks are separate answers: a fast combination "
        "may track worse (a controller that fell in closed loop ranks last for speed). A pick "
        "rests only on the combinations this folder holds: the caveats say how many.",
        "",
    ]
    if frame.empty:
        return "\n".join([*lines, "*No runs yet.*", ""])
    for _, row in frame.iterrows():
        lines += [
            f"## {row['robot']}: {row['family']}",
            "",
            f"Scenarios: {row['scenarios']}.",
            "",
            f"- **Fastest** (p99 within budget): {row['fastest (p99 within budget)']}",
            f"- **Most accurate**: {row['most accurate']}",
            f"- **Most robust**: {row['most robust']}",
            f"- *Caveats*: {row['caveats']}.",
            "",
        ]
    return "\n".join(lines)


def write_recommendations(folder: str | Path, res: Results | None = None) -> Path:
    """``<folder>/recommendations.md`` from the folder's runs; returns its path."""
    res = res if res is not None else load_results(folder)
    path = Path(folder) / "recommendations.md"
    path.write_text(recommendations_markdown(res))
    return path
