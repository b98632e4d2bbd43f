"""A verdict per published claim: what the paper says, what we measured, whether it was
reproduced, and the command that reproduces it.

Accuracy claims read the paper tables (:mod:`wbcbench.report.tables`). Speed claims read the
timing runs those tables pick, on the paper's own stage (the parameters for COD vs SVD, the QPs
for OSF-HQP Table III, the whole step for RC-LQP), as medians of the replayed ticks with 95 %
bootstrap intervals (:mod:`wbcbench.report.evidence`). The rules:

* a **speed-up** (the paper's ratio > 1) is ``reproduced`` when ours is at least half the paper's
  (a larger gain than the paper's is reproduced too, and says so), ``partly`` when ours is a gain
  (> 1) below half the paper's, ``not`` when it is no gain (≤ 1);
* a **time bound** (the paper's "under 0.5 ms") is ``reproduced`` when the interval lies below
  it, ``not`` when above; a time measured on the paper's robot is ``reproduced`` when ours is at
  most twice it (faster is reproduced: another CPU, and simulation), ``partly`` when slower;
* a speed verdict is ``inconclusive`` when its interval contains a threshold of its rule (the
  data cannot tell which side it lies), or when a run behind it was timed on a busy machine
  (the load its row records), with the reason; the interval is widened by the spread of the
  machine's speed around runs that were not timed together (:mod:`wbcbench.report.evidence`);
* a claim whose speed depends on the solver gets one row per solver timed, the paper's first
  and named (``qpoases (paper's)``);
* an **accuracy** claim is ``reproduced`` when our errors are at or below the paper's;
* a claim whose table has no results is ``not run``, with what is missing;
* a verdict whose numbers come from a run that fell or failed says so in its reason.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from wbcbench.report import evidence as E
from wbcbench.report import papers as P
from wbcbench.report.evidence import Estimate
from wbcbench.report.load import Results
from wbcbench.report.tables import PaperTable
from wbcbench.report.tables import osf_hqp as T_osf
from wbcbench.report.tables import rc_lqp as T_rc
from wbcbench.report.tables import to_osf as T_to

VERDICTS = ("reproduced", "partly", "not", "inconclusive", "not run")


@dataclass
class Verdict:
    paper: str
    claim: str
    paper_value: str
    ours: str
    verdict: str
    reason: str
    command: str


def within_factor_two(ours: float, paper: float) -> str:
    """The verdict of a ratio that is no speed (Scenario #2's amendment ratio): reproduced
    within a factor 2 of the paper's, partly above 1 outside it, not at or below 1."""
    if not np.isfinite(ours):
        return "not run"
    if ours <= 1.0:
        return "not"
    return "reproduced" if 0.5 <= ours / paper <= 2.0 else "partly"


def judge_gain(est: Estimate, paper: float, busy: str = "") -> tuple[str, str]:
    """(verdict, why) of a measured speed-up against the paper's (both conventional /
    proposed)."""
    if not est.finite:
        return "not run", "no finite times"
    if busy:
        return "inconclusive", busy
    half = paper / 2.0
    for threshold, meaning in ((1.0, "no gain"), (half, "half the paper's gain")):
        if est.straddles(threshold):
            return "inconclusive", f"its 95 % interval contains {threshold:.3g}× ({meaning})"
    if est.hi < 1.0:
        return "not", "no gain: the proposed method is slower"
    if est.value < half:
        return "partly", "a gain, but less than half the paper's"
    if est.value > 2.0 * paper:
        return "reproduced", "a larger gain than the paper's"
    return "reproduced", "within a factor 2 of the paper's gain"


def judge_bound(est: Estimate, bound: float, busy: str = "") -> tuple[str, str]:
    """(verdict, why) of a median time [µs] against an upper bound [µs] the paper states."""
    if not est.finite:
        return "not run", "no finite times"
    if busy:
        return "inconclusive", busy
    if est.straddles(bound):
        return "inconclusive", f"its 95 % interval contains the bound {bound / 1e3:.3g} ms"
    return ("reproduced", "below the bound") if est.hi < bound else ("not", "above the bound")


def judge_robot_time(est: Estimate, paper: float, busy: str = "") -> tuple[str, str]:
    """(verdict, why) of a median time [µs] against a time the paper measured on its robot."""
    if not est.finite:
        return "not run", "no finite times"
    if busy:
        return "inconclusive", busy
    limit = 2.0 * paper
    if est.straddles(limit):
        return "inconclusive", f"its 95 % interval contains twice the paper's time ({limit:.3g})"
    if est.hi < paper / 2.0:
        return "reproduced", "much faster than the paper's robot (another CPU; simulation)"
    if est.hi <= limit:
        return "reproduced", "within a factor 2 of the paper's robot"
    return "partly", "more than twice the paper's robot time"


def _ended(rows: list[pd.Series]) -> str:
    """A sentence when a run behind a verdict did not end ok."""
    bad = [r for r in rows if str(r.get("status", "ok")) != "ok"]
    if not bad:
        return ""
    what = "; ".join(
        f"{r['controller']} {r['status']}: {str(r.get('message') or '')[:80]}" for r in bad
    )
    return f" A run behind it did not end ok ({what})."


def _source(*estimates: Estimate) -> str:
    """Where the intervals come from, and how much the machine's speed widened them."""
    finite = [e for e in estimates if e.finite]
    out = ""
    if any(e.source == "stored intervals" for e in finite):
        out += " Intervals from the runs' stored intervals (no per-tick times kept)."
    widest = max(finite, key=lambda e: e.widened, default=None)
    if widest is not None and widest.note:
        which = "Its interval is" if len(finite) == 1 else "The widest interval is"
        out += f" {which} {widest.note}."
    return out


@dataclass
class Outcome:
    """One verdict row's measured part: a suffix to the claim, ours, the verdict, the reason."""

    suffix: str
    ours: str
    verdict: str
    reason: str


TimedRule = Callable[[Results], list[Outcome]]


def _solver_label(solver: str, paper_solver: str) -> str:
    return f"{solver} (paper's)" if solver == paper_solver else solver


# -- the claims read from a paper table


def _fell(table: PaperTable) -> str:
    """A note when a run behind the table's numbers fell (its cells or its notes say so)."""
    assert table.frame is not None
    cells = [str(v) for v in table.frame.to_numpy().ravel() if isinstance(v, str)]
    if any("fell" in text for text in [*cells, *table.notes]):
        return " A run behind these numbers fell (its table says when)."
    return ""


def _row(frame: pd.DataFrame, column: str, label: str) -> pd.Series:
    return frame[frame[column].astype(str) == label].iloc[0]


Rule = Callable[[pd.DataFrame], tuple[str, str, str]]  # frame -> (ours, verdict, reason)


def _s1(f: pd.DataFrame) -> tuple[str, str, str]:
    worst = float(f["ours / paper"].max())
    below = int((f["ours / paper"] <= 1.0).sum())
    verdict = "reproduced" if below == len(f) else ("partly" if below else "not")
    ours = ", ".join(f"{v:.2g}" for v in f["ours"])
    return ours, verdict, f"{below} of {len(f)} errors at or below the paper's (worst {worst:.2g}×)"


def _pinv(f: pd.DataFrame) -> tuple[str, str, str]:
    grow = f["pinv / DC"].dropna()
    least = float(grow.min())
    verdict = "reproduced" if least > 10 else ("partly" if least > 1 else "not")
    reason = f"every error grows with the pseudo-inverse, by {least:.3g}× at least"
    return f"pinv / DC ≥ {least:.3g}", verdict, reason


def _s2(f: pd.DataFrame) -> tuple[str, str, str]:
    row = f.iloc[0]
    ours, paper = float(row["ours priority / identical"]), float(row["paper priority / identical"])
    status = str(row.get("status (priority; identical)", ""))
    fell = " Both runs fell before the window's end; the amendments are averaged up to it." * (
        "fell" in status
    )
    # the paper: with identical weighting T1/T2 errors are larger, T3/T4 smaller, i.e. the
    # priority / identical error ratio is below 1 for T1, T2 and above 1 for T3, T4
    errors = f.iloc[1:5]["ours priority / identical"].astype(float).to_numpy()
    expected = np.array([False, False, True, True])[: len(errors)]
    agree = int(((errors > 1.0) == expected).sum())
    verdict = within_factor_two(ours, paper)
    if verdict == "reproduced" and agree < len(errors):
        verdict = "partly"
    reason = (
        f"identical weighting amends {ours:.3g}× less (paper {paper:g}×); "
        f"{agree} of {len(errors)} task errors move the way the paper's do.{fell}"
    )
    return f"{ours:.3g}×", verdict, reason


#: a ratio to the reduced QR within this of 1 is a tie in Fig. 1's ordering
FIG1_TIE = 0.05


def _fig1(f: pd.DataFrame) -> tuple[str, str, str]:
    # the native runs where there are any: their times are the algorithms', not the interpreter's
    impl = "native" if "full_qr / reduced_qr (native)" in f else "python"
    full = f[f"full_qr / reduced_qr ({impl})"].astype(float).to_numpy()
    svd = f[f"svd / reduced_qr ({impl})"].astype(float).to_numpy()
    # a baseline within FIG1_TIE of the reduced QR ties with it (the paper, too, sees "no
    # significant difference" where the curves meet)
    fastest = bool((full > 1 - FIG1_TIE).all() and (svd > 1 - FIG1_TIE).all())
    ties = [
        f"N = {int(n)}: {name} within {100 * abs(1 - r):.1f} %"
        for n, a, b in zip(f["N"], full, svd, strict=True)
        for name, r in (("full QR", a), ("SVD", b))
        if abs(1 - r) <= FIG1_TIE
    ]
    growing = bool(full[-1] > full[0] and svd[-1] > svd[0])
    svd_slowest = bool((svd > full).all())
    verdict = (
        "reproduced" if fastest and growing and svd_slowest else ("partly" if fastest else "not")
    )
    slowest_from = next(
        (int(n) for i, n in enumerate(f["N"]) if bool((svd[i:] > full[i:]).all())), None
    )
    tied = f"; ties, {', '.join(ties)}" if ties else ""
    reason = (
        f"{impl} runs: reduced QR fastest at every N ({'yes' if fastest else 'no'}{tied}), the "
        f"gap growing with N ({'yes' if growing else 'no'}), SVD slowest "
        f"({'yes' if svd_slowest else f'from N = {slowest_from} on' if slowest_from else 'no'})"
    )
    return (
        f"full {full[-1]:.2g}×, SVD {svd[-1]:.2g}× at N = {int(f['N'].iloc[-1])} ({impl})",
        verdict,
        reason,
    )


# -- the timed claims


def _s4(res: Results) -> list[Outcome]:
    runs = T_to.s4_runs(res)
    if runs.empty:
        return []
    rows = [r for _, r in runs.iterrows()]

    def slowest(stage: str) -> Estimate:
        found = [e for e in (E.median(res, r, stage) for r in rows) if e.finite]
        return max(found, key=lambda e: e.value) if found else E.NAN

    qp, params = slowest("solve"), slowest("params")
    busy = E.busy(rows)
    vq, why_q = judge_bound(qp, 500.0, busy)
    vp, why_p = judge_bound(params, 2000.0, busy)
    both = {vq, vp}
    if "inconclusive" in both or "not run" in both:
        verdict = "inconclusive" if "inconclusive" in both else "not run"
    else:
        verdict = {2: "reproduced", 1: "partly", 0: "not"}[
            (vq == "reproduced") + (vp == "reproduced")
        ]
    reason = (
        f"slowest of {len(rows)} task counts: QP median {qp.text(' µs')} ({why_q}), parameters "
        f"{params.text(' µs')} ({why_p})." + _ended(rows) + _source(qp, params)
    )
    ours = f"{qp.value / 1e3:.3g} / {params.value / 1e3:.3g} ms"
    return [Outcome(f" — {rows[0]['solver']}", ours, verdict, reason)]


def _cod_svd(res: Results) -> list[Outcome]:
    pair = T_to.cod_svd_runs(res)
    if pair is None:
        return []
    cod, svd = pair
    stage = "params"
    est = E.ratio(res, svd, cod, stage)
    if not est.finite:  # a controller config without a separate parameter stage
        stage = "total"
        est = E.ratio(res, svd, cod, stage)
    paper = (P.TO_OSF_COD_SVD[1].value or np.nan) / (P.TO_OSF_COD_SVD[0].value or np.nan)
    verdict, why = judge_gain(est, paper, E.busy([cod, svd]))
    where = "the parameters (the paper's stage)" if stage == "params" else "the whole step"
    reason = (
        f"SVD / COD median time of {where}: {est.text()} against the paper's {paper:.3g}×; "
        f"{why}." + _ended([cod, svd]) + _source(est)
    )
    return [Outcome("", f"{est.value:.3g}×", verdict, reason)]


def _to_osf_table3(res: Results) -> list[Outcome]:
    runs = T_to.table3_runs(res)
    if runs.empty:
        return []
    by_count: dict[int, dict[str, pd.Series]] = {}
    for _, r in runs.iterrows():
        spec = T_to.run_spec(res, r)
        by_count.setdefault(len(spec.tasks) if spec else -1, {})[str(r["controller"])] = r
    pairs = [(n, c["hqp"], c["to_osf"]) for n, c in sorted(by_count.items()) if len(c) == 2]
    if not pairs:
        return []
    rows = [r for _, a, b in pairs for r in (a, b)]
    busy = E.busy(rows)
    ests = [(n, E.ratio(res, a, b)) for n, a, b in pairs]
    faster = [n for n, e in ests if e.finite and e.lo > 1.0]
    slower = [n for n, e in ests if e.finite and e.hi < 1.0]
    unclear = [n for n, e in ests if n not in faster and n not in slower]
    if busy:
        verdict, why = "inconclusive", busy
    elif slower:
        verdict = "partly" if faster else "not"
        why = f"TO-OSF slower with {', '.join(map(str, slower))} tasks"
    elif unclear:
        verdict = "inconclusive"
        why = f"the interval contains 1× with {', '.join(map(str, unclear))} tasks"
    else:
        verdict, why = "reproduced", f"TO-OSF faster for all {len(ests)} task counts"
    series = ", ".join(f"{n}: {e.text()}" for n, e in ests)
    values = [e.value for _, e in ests]
    reason = (
        f"HQP / TO-OSF median step per task count {series}; {why}; the paper's per-count "
        "times were not extracted." + _ended(rows) + _source(*(e for _, e in ests))
    )
    ours = f"{min(values):.3g}–{max(values):.3g}×"
    return [Outcome(f" — {pairs[0][1]['solver']}", ours, verdict, reason)]


def _level_sentence(res: Results, solver: str, conv: pd.Series, prop: pd.Series) -> str:
    """Which level of the proposed hierarchy takes most of its QP time, and its ratio."""
    levels = T_osf.level_names(res, conv, prop)
    if not levels:
        return ""
    shares = []
    for i, (label, lc, lp) in enumerate(levels):
        c, p = E.median(res, conv, "solve", lc).value, E.median(res, prop, "solve", lp).value
        paper = P.OSF_HQP_TABLE3["conventional"][i] / P.OSF_HQP_TABLE3["proposed"][i]
        shares.append((p, label, lp, c / p if p > 0 else np.nan, paper))
    total = sum(s[0] for s in shares if np.isfinite(s[0]))
    p, label, lp, r, paper = max(shares, key=lambda s: s[0] if np.isfinite(s[0]) else -1)
    return (
        f" With {solver}, osf_hqp's slowest level is {label}"
        + (f" ({lp})" if lp != label else "")
        + f": {100 * p / total:.0f} % of "
        f"its level QP time, where the ratio is {r:.3g}× (paper {paper:.3g}×)."
    )


def _osf_table3(stage: str, paper: float) -> TimedRule:
    def rule(res: Results) -> list[Outcome]:
        out = []
        for solver, conv, prop in T_osf.table3_pairs(res):
            est = E.ratio(res, conv, prop, stage)
            verdict, why = judge_gain(est, paper, E.busy([conv, prop]))
            reason = (
                f"hqp / osf_hqp median {'QP' if stage == 'solve' else 'step'} time "
                f"{est.text()} against the paper's {paper:.3g}×; {why}."
                + (_level_sentence(res, solver, conv, prop) if stage == "solve" else "")
                + _ended([conv, prop])
                + _source(est)
            )
            label = _solver_label(solver, T_osf.PAPER_SOLVER)
            out.append(Outcome(f" — {label}", f"{est.value:.3g}×", verdict, reason))
        return out

    return rule


def _table2(res: Results) -> list[Outcome]:
    paper = 1e3 * P.OSF_HQP_TABLE2["average"][-1]
    out = []
    for solver, _conv, prop in T_osf.table3_pairs(res):
        est = E.median(res, prop, "solve")
        verdict, why = judge_robot_time(est, paper, E.busy([prop]))
        reason = (
            f"osf_hqp's median QP time {est.text(' µs')} against {paper:.3g} µs (average) on "
            f"the paper's robot; {why}." + _ended([prop]) + _source(est)
        )
        label = _solver_label(solver, T_osf.PAPER_SOLVER)
        out.append(Outcome(f" — {label}", f"{est.value / 1e3:.3g} ms", verdict, reason))
    return out


def _rc_lqp(support: str) -> TimedRule:
    def rule(res: Results) -> list[Outcome]:
        conv = P.RC_LQP_TABLE3[(support, "conventional")]["avg"]
        prop = P.RC_LQP_TABLE3[(support, "proposed")]["avg"]
        paper = conv / prop
        out = []
        for where, solver, lqp, rc in T_rc.table3_pairs(res):
            if where != support:
                continue
            est = E.ratio(res, lqp, rc)
            solve = E.ratio(res, lqp, rc, "solve")
            verdict, why = judge_gain(est, paper, E.busy([lqp, rc]))
            reason = (
                f"lqp / rc_lqp median step {est.text()} against the paper's {paper:.3g}× "
                f"(means); {why}. The QP calls alone: {solve.text()}."
                + _ended([lqp, rc])
                + _source(est)
            )
            label = _solver_label(solver, T_rc.RC_LQP_SOLVERS[0])
            out.append(Outcome(f" — {label}", f"{est.value:.3g}×", verdict, reason))
        return out

    return rule


def _dof(res: Results) -> list[Outcome]:
    runs = T_rc.dof_runs(res)
    if runs.empty:
        return []
    pairs: dict[int, dict[str, pd.Series]] = {}
    for _, r in runs.iterrows():
        pairs.setdefault(T_rc._robot_dof(str(r["robot"])), {})[str(r["controller"])] = r
    series = [(d, p["lqp"], p["rc_lqp"]) for d, p in sorted(pairs.items()) if len(p) == 2]
    if not series:
        return []
    ests = [(d, E.ratio(res, a, b)) for d, a, b in series]
    values = np.array([e.value for _, e in ests])
    rising = bool(np.all(np.diff(values) > -0.05))
    last_dof, last = ests[-1]
    ends = P.RC_LQP_DOF[max(P.RC_LQP_DOF)]
    paper = ends["conventional"] / ends["proposed"]
    rows = [r for _, a, b in series for r in (a, b)]
    verdict, why = judge_gain(last, paper, E.busy(rows))
    if verdict == "reproduced" and not rising:
        verdict = "partly"
    trend = "grows" if rising else "does not grow steadily"
    reason = (
        f"the gain {trend} with DoF: {', '.join(f'{v:.2g}' for v in values)}; at {last_dof} DoF "
        f"{last.text()} against the paper's {paper:.3g}× at {max(P.RC_LQP_DOF)}; {why}."
        + _ended(rows)
        + _source(last)
    )
    solver = str(series[0][1]["solver"])
    return [Outcome(f" — {solver}", f"{last.value:.3g}× at {last_dof} DoF", verdict, reason)]


def solver_spread(res: Results) -> str:
    """What drives Table III's spread over solvers: the level whose hqp / osf_hqp ratio varies
    most between them, with each solver's ratio and osf_hqp's time there."""
    pairs = T_osf.table3_pairs(res)
    if len(pairs) < 2:
        return ""
    per_level: dict[str, list[tuple[str, float, float, float]]] = {}
    totals = []
    for solver, conv, prop in pairs:
        totals.append((solver, E.ratio(res, conv, prop, "solve").value))
        for label, lc, lp in T_osf.level_names(res, conv, prop):
            c, p = E.median(res, conv, "solve", lc).value, E.median(res, prop, "solve", lp).value
            if np.isfinite(c) and np.isfinite(p) and p > 0:
                per_level.setdefault(label, []).append((solver, c / p, c, p))
    spread = {
        label: max(r for _, r, _, _ in v) / min(r for _, r, _, _ in v)
        for label, v in per_level.items()
        if len(v) == len(pairs)
    }
    if not spread:
        return ""
    level = max(spread, key=lambda k: spread[k])
    finite = [r for _, r in totals if np.isfinite(r)]
    each = ", ".join(
        f"{s} {r:.3g}× (hqp {c:.3g} µs, osf_hqp {p:.3g} µs)" for s, r, c, p in per_level[level]
    )
    return (
        f"Table III's QP ratio ranges {min(finite):.3g}–{max(finite):.3g}× over "
        f"{len(pairs)} solvers. The level that varies most is {level}: {each}. Timing runs "
        "record no iteration counts; the solver comparison (`solver_report.md`) has them per QP."
    )


RUN = "wbcbench bench (make bench)"
T3_COMMAND = (
    "wbcbench sweep --scenario lee2021iros_table1 --controller hqp --controller osf_hqp "
    "--timing --solver qpoases --out results/t3"
)


@dataclass(frozen=True)
class Claim:
    """A published claim: the table that shows it and the rule that judges it (``rule`` on the
    table's frame, or ``timed`` on the timing runs; neither: measured on the robot only)."""

    paper: str
    claim: str
    paper_value: str
    table: str
    command: str = RUN
    rule: Rule | None = None
    timed: TimedRule | None = field(default=None)


#: one claim per row of the papers' published numbers we check
CLAIMS: list[Claim] = [
    Claim(
        "TO-OSF",
        "S1 mean tracking errors",
        "0.045, 0.281 mm; 0.0003, 0.0006, 0.0192 rad",
        "to_osf_s1",
        "wbcbench run lee2021access_s1_accuracy --controller to_osf --solver quadprog",
        rule=_s1,
    ),
    Claim(
        "TO-OSF",
        "S1 pseudo-inverse: errors grow sharply",
        "r-hand orientation peak 0.988 rad",
        "to_osf_pinv",
        "wbcbench run lee2021access_s1_accuracy --controller to_osf "
        "--set controllers.to_osf.inverse=pinv --solver quadprog",
        rule=_pinv,
    ),
    Claim(
        "TO-OSF",
        "S2 identical vs priority weighting: total amendment",
        "≈ 7.5× smaller",
        "to_osf_s2",
        rule=_s2,
    ),
    Claim(
        "TO-OSF",
        "S4 RT QP and non-RT parameter times",
        "QP < 0.5 ms, parameters < 2 ms",
        "to_osf_s4",
        timed=_s4,
    ),
    Claim(
        "TO-OSF",
        "COD vs SVD inverse, parameters (5 tasks, two feet)",
        "1.55 vs 4.27 ms",
        "to_osf_cod_svd",
        timed=_cod_svd,
    ),
    Claim(
        "TO-OSF",
        "Table 3: HQP vs TO-OSF, 1…5 tasks",
        "TO-OSF faster",
        "to_osf_table3",
        timed=_to_osf_table3,
    ),
    Claim(
        "OSF-HQP",
        "Table III: QP time, conventional / proposed",
        "30.5×",
        "osf_hqp_table3",
        T3_COMMAND,
        timed=_osf_table3(
            "solve", P.OSF_HQP_TABLE3["conventional"][-1] / P.OSF_HQP_TABLE3["proposed"][-1]
        ),
    ),
    Claim(
        "OSF-HQP",
        "OSF parameters + single-thread step vs conventional",
        "9.8×",
        "osf_hqp_table3",
        timed=_osf_table3("total", P.OSF_HQP_SINGLE_THREAD[2].value or np.nan),
    ),
    Claim(
        "OSF-HQP",
        "Table II (robot): proposed QP time",
        "0.253 ms total (0.205–0.417)",
        "osf_hqp_table2",
        timed=_table2,
    ),
    Claim("OSF-HQP", "tracking on the robot (40 s)", "CoM 5.5 mm, hands 35 mm, …", "", ""),
    Claim(
        "RC-LQP",
        "Table 3 double support: conventional / reduced",
        "2176 / 981 µs = 2.22×",
        "rc_lqp_table3",
        "python benchmarks/bench_rc_lqp.py --backends",
        timed=_rc_lqp("double"),
    ),
    Claim(
        "RC-LQP",
        "Table 3 single support: conventional / reduced",
        "1834 / 613 µs = 2.99×",
        "rc_lqp_table3",
        "python benchmarks/bench_rc_lqp.py --backends",
        timed=_rc_lqp("single"),
    ),
    Claim(
        "RC-LQP",
        "DoF scaling: the gain grows with DoF",
        "1.32× at 20, 3.09× at 45 DoF",
        "rc_lqp_dof",
        "python benchmarks/bench_rc_lqp.py",
        timed=_dof,
    ),
    Claim(
        "RQR-HQP",
        "Fig. 1: reduced QR < full QR < SVD, gap growing with N",
        "curves",
        "rqr_fig1",
        "python benchmarks/bench_hls.py",
        rule=_fig1,
    ),
]


def _from_table(claim: Claim, table: PaperTable | None) -> Verdict:
    c = claim
    if table is None or table.frame is None or table.frame.empty:
        missing = table.missing if table is not None else "no such table"
        return Verdict(
            c.paper, c.claim, c.paper_value, "—", "not run", missing or "no results", c.command
        )
    assert c.rule is not None
    try:
        ours, verdict, reason = c.rule(table.frame)
        fell = "" if "fell" in reason else _fell(table)
        if fell:
            reason = reason.rstrip(".") + "." + fell
    except (KeyError, IndexError, ValueError) as exc:
        ours, verdict, reason = "—", "not run", f"its table lacks {exc}"
    return Verdict(c.paper, c.claim, c.paper_value, ours, verdict, reason, c.command)


def verdicts(tables: list[PaperTable], res: Results | None = None) -> pd.DataFrame:
    """One row per claim (per solver where the claim's speed depends on it): paper, claim, paper
    value, ours, verdict, reason, command. The timed claims need ``res``, the results folder the
    tables were built from; without it they are ``not run``. ``frame.attrs["notes"]`` holds
    what drives the solvers' spread."""
    by_name = {t.name: t for t in tables}
    rows: list[Verdict] = []
    for c in CLAIMS:
        table = by_name.get(c.table)
        if c.rule is None and c.timed is None:
            reason = "measured on the real robot; a simulation cannot reproduce it"
            rows.append(Verdict(c.paper, c.claim, c.paper_value, "—", "not run", reason, c.command))
        elif c.rule is not None:
            rows.append(_from_table(c, table))
        else:
            assert c.timed is not None
            outcomes = c.timed(res) if res is not None else []
            if not outcomes:
                missing = (table.missing if table is not None else "") or "no timing results"
                rows.append(
                    Verdict(c.paper, c.claim, c.paper_value, "—", "not run", missing, c.command)
                )
            for o in outcomes:
                rows.append(
                    Verdict(
                        c.paper,
                        c.claim + o.suffix,
                        c.paper_value,
                        o.ours,
                        o.verdict,
                        o.reason,
                        c.command,
                    )
                )
    assert all(v.verdict in VERDICTS for v in rows)
    frame = pd.DataFrame([asdict(v) for v in rows])
    spread = solver_spread(res) if res is not None else ""
    frame.attrs["notes"] = [spread] if spread else []
    return frame


def markdown(frame: pd.DataFrame) -> str:
    """The verdict table as it opens ``papers.md``."""
    counts = frame["verdict"].value_counts()
    summary = ", ".join(f"{counts.get(v, 0)} {v}" for v in VERDICTS)
    lines = [
        "## What was reproduced",
        "",
        f"{len(frame)} verdicts: {summary}. Speed claims are judged on the paper's own stage, on "
        "medians of the replayed ticks with 95 % bootstrap intervals: a speed-up is reproduced "
        "at half the paper's ratio or more, partly when it is a smaller gain; a verdict whose "
        "interval contains its threshold, or whose runs were timed on a busy machine, is "
        "inconclusive; the rows a ratio compares are timed together, interleaved, and an "
        "interval over runs timed apart is widened by the spread of the machine's speed "
        "around them; a claim whose speed depends on the solver has one row per solver, the "
        "paper's first. An accuracy claim is reproduced when our errors are at or below the "
        "paper's. The tables below hold the numbers.",
        "",
        frame.rename(columns={"paper_value": "paper value"}).to_markdown(index=False),
        "",
        *[f"{note}\n" for note in frame.attrs.get("notes", [])],
    ]
    return "\n".join(lines)
