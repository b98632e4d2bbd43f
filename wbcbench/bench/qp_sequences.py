"""Sequences of exported QPs solved as a controller solves them (``wbcbench solvers --sequences``).

A QP solver benchmark that solves each problem from scratch measures a cold start. A
whole-body controller solves the same QP (one hierarchy level) again every tick with slightly
new data, and keeps its solver object (hot) or its last solution (warm) between ticks. Here each
backend × tier × mode solves every sequence of an export (:mod:`wbcbench.bench.qp_export`) in
tick order with one handle, as :class:`~wbcbench.controllers.base.ControllerContext` gives a
controller one handle per QP, and reports:

* **valid**: the share of solutions that pass the independent check (the KKT conditions at the
  tier's tolerance scaled by the data, :func:`wbcbench.bench.solver_comparison.solve_row`),
  whatever the backend reported;
* the median and p99 of the time a controller pays per QP (``call_us``: the whole solve call,
  validation and update of the object included) and of the native call alone (``wall_us``);
* **deadline misses**: the share of QPs whose call alone exceeds the tick's control period;
* **the cost of a lost warm start**: each QP after the first of its sequence is also solved by a
  fresh handle; the median of (fresh − kept) call time, paired QP by QP;
* the first QP of each sequence (a cold object even in hot mode) apart from the rest.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.bench.qp_export import problem_from_row, read_export
from wbcbench.qp import make_solver, solver_class

SEQUENCE_COLUMNS = (
    "solver",
    "tier",
    "mode",
    "sequence",
    "position",
    "name",
    "n",
    "deadline_s",
    "reported_solved",
    "valid",
    "message",
    "call_us",
    "wall_us",
    "fresh_call_us",
    "iterations",
    "rebuilt",
)


def solve_sequences(
    export: str | Path,
    solvers: Sequence[str],
    tiers: Sequence[str] = ("default",),
    modes: Sequence[str] = ("hot", "warm"),
    max_solve_ms: float = 250.0,
    show_progress: bool = True,
) -> pd.DataFrame:
    """One row per QP × backend × tier × mode the backend offers (see the module docstring).

    A backend × tier × mode whose one solve takes longer than ``max_solve_ms`` stops there: its
    remaining QPs are rows with ``message`` saying so and no times.
    """
    from tqdm import tqdm

    from wbcbench.bench.solver_comparison import solve_row

    frame = read_export(export)  # in sequence order, positions ascending
    records = [{str(k): v for k, v in r.items()} for r in frame.to_dict("records")]
    problems = [problem_from_row(row) for row in records]
    sequences = frame.groupby("sequence", sort=True).indices
    combos = [
        (s, t, m) for s in solvers for t in tiers for m in modes if solver_class(s).offers(t, m)
    ]
    rows: list[dict[str, Any]] = []
    with tqdm(total=len(combos), desc="sequences", disable=not show_progress) as bar:
        for solver, tier, mode in combos:
            bar.update()
            too_slow = ""
            for sequence, index in sequences.items():
                handle = make_solver(solver, tier=tier, mode=mode)
                for i in index:
                    problem, info = problems[i], records[i]
                    base = {
                        "solver": solver,
                        "tier": tier,
                        "mode": mode,
                        "sequence": sequence,
                        "position": int(info["position"]),
                        "name": info["name"],
                        "n": int(info["n"]),
                        "deadline_s": float(info["deadline_s"]),
                    }
                    if too_slow:
                        rows.append({**base, "valid": False, "message": too_slow})
                        continue
                    t0 = time.perf_counter()
                    sol = handle.solve(problem)
                    elapsed = time.perf_counter() - t0
                    fresh = np.nan
                    if mode != "cold" and int(info["position"]) > 0:
                        fresh = (
                            1e6 * make_solver(solver, tier=tier, mode=mode).solve(problem).call_time
                        )
                    measured = solve_row(problem, sol, tier, None)
                    rows.append(
                        {
                            **base,
                            "reported_solved": sol.success,
                            "valid": measured["valid"],
                            "message": measured["message"],
                            "call_us": 1e6 * sol.call_time,
                            "wall_us": 1e6 * sol.wall_time,
                            "fresh_call_us": fresh,
                            "iterations": measured["iterations"],
                            "rebuilt": sol.rebuilt,
                        }
                    )
                    if elapsed * 1e3 > max_solve_ms:
                        too_slow = (
                            f"one solve took {1e3 * elapsed:.0f} ms > max_solve_ms = "
                            f"{max_solve_ms:g} ms; the rest of this backend × tier × mode skipped"
                        )
    return pd.DataFrame(rows, columns=list(SEQUENCE_COLUMNS))


def summarize_sequences(rows: pd.DataFrame) -> pd.DataFrame:
    """Per backend × tier × mode: QPs, valid %, times after the first tick, misses, lost start."""
    out = []
    for (solver, tier, mode), g in rows.groupby(["solver", "tier", "mode"], sort=False):
        timed = g[g["call_us"].notna()]
        later = timed[timed["position"] > 0]
        first = timed[timed["position"] == 0]
        lost = later["fresh_call_us"] - later["call_us"]
        out.append(
            {
                "solver": solver,
                "tier": tier,
                "mode": mode,
                "QPs": len(g),
                "valid %": 100.0 * float(g["valid"].fillna(False).astype(bool).mean()),
                "median µs": later["call_us"].median(),
                "p99 µs": later["call_us"].quantile(0.99) if len(later) else np.nan,
                "native median µs": later["wall_us"].median(),
                "first tick median µs": first["call_us"].median(),
                "deadline misses %": 100.0
                * float((timed["call_us"] > 1e6 * timed["deadline_s"]).mean())
                if len(timed)
                else np.nan,
                "lost warm start µs": lost.median() if lost.notna().any() else np.nan,
            }
        )
    return pd.DataFrame(out)


def sequence_report(rows: pd.DataFrame, export: str | Path) -> str:
    """Markdown: what was solved, the summary table, and how to read it."""
    summary = summarize_sequences(rows)
    frame = read_export(export)
    lines = [
        "# QP sequences solved as a controller solves them",
        "",
        f"{len(frame)} QPs in {frame['sequence'].nunique()} sequences "
        f"({frame['scenario'].nunique()} scenarios, {frame['controller'].nunique()} "
        f"controllers), from `{export}`. Times are per QP, over the QPs after the first of each "
        "sequence; the first (a fresh object even in hot mode) is its own column. A deadline "
        "miss is one QP's call alone longer than its tick's control period. The lost warm start "
        "is the median of (a fresh handle's call − the kept handle's call) on the same QPs.",
        "",
        summary.to_markdown(index=False, floatfmt=".1f") if len(summary) else "(no solves)",
        "",
    ]
    return "\n".join(lines)


#: qpbenchmark's settings group for each of our tiers, with its absolute tolerance on the primal
#: and dual residuals and the duality gap (qpbenchmark's ``TestSet.define_tolerances``)
QPBENCHMARK_SETTINGS = {
    "low": ("low_accuracy", 1e-3),
    "mid": ("mid_accuracy", 1e-6),
    "high": ("high_accuracy", 1e-9),
}


def run_qpbenchmark(
    export: str | Path, results_csv: str | Path, solvers: Sequence[str], tier: str = "mid"
) -> pd.DataFrame:
    """Run qpbenchmark itself on an export: ``solvers`` (qpsolvers names) at the settings group
    of ``tier``; its results table (one row per problem × solver)."""
    import importlib.util
    import sys

    from qpbenchmark.results import Results
    from qpbenchmark.run import run

    from wbcbench.bench.qp_export import TEST_SET

    settings, _ = QPBENCHMARK_SETTINGS[tier]
    path = Path(export) / f"{TEST_SET}.py"
    spec = importlib.util.spec_from_file_location(TEST_SET, path)
    if spec is None or spec.loader is None:
        raise FileNotFoundError(f"{path}: no test set module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[TEST_SET] = module
    spec.loader.exec_module(module)
    test_set = module.WbcQps()
    results = Results(str(results_csv), test_set)
    for solver in solvers:
        run(test_set, results, only_settings=settings, only_solver=solver)
    return pd.read_csv(results_csv)


def qpbenchmark_agreement(ours: pd.DataFrame, theirs: pd.DataFrame, tier: str) -> pd.DataFrame:
    """Which QPs each library solves, by our independent check and by qpbenchmark's.

    ``ours``: rows of :func:`solve_sequences` in mode cold through qpsolvers
    (``qpsolvers:<name>``), so both sides run the same code on the same problem; ``theirs``:
    qpbenchmark's results table. qpbenchmark counts a QP solved when the solver found a solution
    whose primal residual, dual residual and duality gap are each at most the settings' absolute
    tolerance; ours checks the KKT conditions at the tier's tolerance scaled by the data.
    """
    settings, tol = QPBENCHMARK_SETTINGS[tier]
    mine = ours[(ours["mode"] == "cold") & (ours["tier"] == tier)].copy()
    mine = mine[mine["solver"].str.startswith("qpsolvers:")]
    mine["library"] = mine["solver"].str.split(":", n=1).str[1]
    theirs = theirs[theirs["settings"] == settings].copy()
    theirs["solved"] = (
        theirs["found"].astype(bool)
        & (theirs["primal_residual"] <= tol)
        & (theirs["dual_residual"] <= tol)
        & (theirs["duality_gap"] <= tol)
    )
    both = mine.merge(theirs, left_on=["name", "library"], right_on=["problem", "solver"])
    ours_ok = both["valid"].fillna(False).astype(bool)
    rows = []
    for library, g in both.assign(ours_ok=ours_ok).groupby("library"):
        rows.append(
            {
                "library": library,
                "QPs": len(g),
                "both solved": int((g["ours_ok"] & g["solved"]).sum()),
                "only ours": int((g["ours_ok"] & ~g["solved"]).sum()),
                "only qpbenchmark": int((~g["ours_ok"] & g["solved"]).sum()),
                "neither": int((~g["ours_ok"] & ~g["solved"]).sum()),
            }
        )
    return pd.DataFrame(rows)
