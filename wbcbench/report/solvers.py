"""The QP solver comparison report (qpbenchmark style), read from a results folder's
``qp_solves.csv`` (written by :mod:`wbcbench.bench.solver_comparison`).

``wbcbench solvers RESULTS_DIR`` writes ``solver_report.md``: per tier the success rate (valid
solutions, checked independently of the reported status), the shifted geometric mean of the
solve time (a failure counted at the tier's time limit, normalised to the best solver) and its
median, iterations, residuals, duality gap and distance to a high-accuracy reference.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.metrics.timing import shifted_geometric_mean
from wbcbench.qp.settings import TIER_TIME_LIMIT

# -- the report


__all__ = ["KNOWN_LIMITATIONS", "summarize", "write_report"]


def summarize(solves: pd.DataFrame) -> pd.DataFrame:
    """Per solver × tier × mode: success rate, timing aggregates, iterations, residuals.

    ``wall sgm [µs]`` is qpbenchmark's aggregate: the shifted geometric mean (shift 10 µs) of
    set-up + solve time over the problems, a problem not solved validly counted at the tier's
    time limit; ``sgm vs best`` divides it by the best solver's of the same tier and mode."""
    if solves.empty:
        return solves
    ran = solves[solves["status"] != "skipped"]
    rows = []
    for (solver, tier, mode), g in ran.groupby(["solver", "tier", "mode"], sort=True):
        ok = g[g["valid"].astype(bool)]
        # qpbenchmark's convention: a problem not solved (validly) counts at the time limit
        limit_us = 1e6 * TIER_TIME_LIMIT.get(str(tier), TIER_TIME_LIMIT["default"])
        counted = (g["wall_us"] + g["setup_us"]).where(g["valid"].astype(bool), limit_us)
        rows.append(
            {
                "solver": solver,
                "tier": tier,
                "mode": mode,
                "problems": len(g),
                "success [%]": 100.0 * len(ok) / len(g),
                "reported solved [%]": 100.0 * g["reported_solved"].astype(bool).mean(),
                # qpbenchmark's aggregate: shifted geometric mean over problems (shift 10 µs)
                "wall sgm [µs]": shifted_geometric_mean(counted),
                "wall median [µs]": float(np.nanmedian(g["wall_us"] + g["setup_us"])),
                "internal median [µs]": _nanmedian(g["internal_us"]),
                "iterations median": _nanmedian(g["iterations"]),
                "primal res. max": _nanmax(ok["primal_residual"]),
                "dual res. max": _nanmax(ok["dual_residual"]),
                "gap max": _nanmax(ok["duality_gap"]),
                "dist. to ref. max": _nanmax(ok["dist_ref"]),
            }
        )
    table = pd.DataFrame(rows)
    # normalised to the best solver of the same tier and mode (1.0 is the best)
    best = table.groupby(["tier", "mode"])["wall sgm [µs]"].transform("min")
    column = list(table.columns).index("wall sgm [µs]") + 1
    table.insert(column, "sgm vs best", table["wall sgm [µs]"] / best)
    return table


def _nanmedian(x: pd.Series) -> float:
    v = pd.to_numeric(x, errors="coerce").to_numpy(dtype=float)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else float("nan")


def _nanmax(x: pd.Series) -> float:
    v = pd.to_numeric(x, errors="coerce").to_numpy(dtype=float)
    v = v[np.isfinite(v)]
    return float(np.max(v)) if v.size else float("nan")


KNOWN_LIMITATIONS = """\
- Times are Python wall times around each backend's native call (plus building or updating its
  object, `setup`), measured serially with one BLAS thread on the machine above; `internal` is
  each solver's own timer where it has one (quadprog, qpmad, eiquadprog and
  HiGHS-through-qpsolvers have none). eiquadprog has no Python binding: its rows are the C++
  library called through wbcbench's native module, `wall` timed in C++ around `solve_quadprog`,
  `setup` including the copy of the QP into the module's buffers.
- The `default` tier keeps each solver's own settings, so its rows are not iso-accuracy; their
  success is judged at 1e-6 × the data's magnitude. The other tiers set absolute tolerances
  (1e-3, 1e-6, 1e-9) that each backend translates as best its options allow (the active-set
  solvers quadprog, qpOASES, qpmad and eiquadprog have no such tolerance).
- The Goldfarb–Idnani solvers (quadprog, qpmad, eiquadprog) need a positive definite Hessian:
  a semidefinite one is solved as H + δI (the smallest δ = 1e-12 · 100^k · max(1, max |H_ii|)
  that factorises), which moves the optimum by O(δ); such rows say so in their message. They
  take no initial guess, so their `warm` rows are cold solves; `hot` keeps the solver object
  (and, for qpmad, the Hessian's Cholesky factor while H is unchanged).
- Validity is checked independently of the reported status (primal and dual residuals, duality
  gap) at the tier's tolerance scaled by max(1, |g|, |b|, finite bounds): WBC problems carry
  forces of hundreds of newtons and weights up to 1e3, so a purely absolute 1e-9 would fail every
  solver for round-off alone.
- Distance to the reference is ‖x − x_ref‖∞ to a `high`-tier solution; where a QP has several
  minimizers (a positive-semidefinite Hessian, as in hierarchy levels over slack variables),
  a large distance with valid residuals is not an error.
- Warm and hot rows start each sequence of consecutive ticks with a build: the first tick of a
  sequence is a cold solve (`rebuilt` in the table). With few dumped ticks this weighs on the
  warm / hot aggregates.
- The problems are a few consecutive ticks per scenario × controller (`problems/`), not a
  statistically representative sample of a whole run.
"""


def write_report(folder: str | Path) -> Path | None:
    """``solver_report.md`` (and ``solver_summary.csv``) from ``qp_solves.csv``; None if none."""
    from wbcbench.report.load import load_results

    res = load_results(folder)
    solves = res.qp_solves
    out = Path(folder) / "solver_report.md"
    if solves.empty:
        out.write_text(
            "# QP solver comparison\n\nNo solver comparison in this folder yet: run a sweep "
            "with a `solver_comparison` section, e.g. `wbcbench sweep sweeps/default.yaml`.\n"
        )
        return out
    summary = summarize(solves)
    summary.to_csv(Path(folder) / "solver_summary.csv", index=False)
    prov = res.provenance
    problems = solves.drop_duplicates("problem")
    lines = [
        "# QP solver comparison on whole-body-control problems",
        "",
        "| | |",
        "|---|---|",
        f"| CPU | {prov.get('cpu', '?')} ({prov.get('cores', '?')} cores) |",
        f"| OS | {prov.get('os', '?')} |",
        f"| Python | {prov.get('python', '?')} |",
        f"| wbcbench | {prov.get('wbcbench', '?')} @ {prov.get('git_commit', '?')} |",
        f"| date | {prov.get('date', '?')} |",
        "",
        "## Solvers",
        "",
        _solver_versions(sorted(solves["solver"].unique())),
        "",
        "## Problems",
        "",
        f"{len(problems)} QPs dumped from replayed control ticks "
        f"(`problems/`; replay one with `wbcbench replay PROBLEM.npz --solver NAME`):",
        "",
        problems.groupby(["scenario", "controller", "qp"])
        .agg(
            QPs=("problem", "count"),
            n=("n", "max"),
            n_eq=("n_eq", "max"),
            n_in=("n_in", "max"),
        )
        .reset_index()
        .to_markdown(index=False),
        "",
        "## Settings",
        "",
        "Tiers: `default` (solver defaults), `low` 1e-3, `mid` 1e-6, `high` 1e-9 (absolute "
        "primal / dual / gap). Modes: `cold` (fresh solver per problem), `warm` (previous "
        "solution as guess), `hot` (persistent solver updated in place). Success = a valid "
        "solution, checked independently of the reported status. A named setting (e.g. "
        "`osqp_libdwbc`, OSQP as the RC-LQP paper's library runs it; `qpoases_libdwbc`, "
        "qpOASES as the OSF papers' library runs it) runs at its own tier and mode only.",
        "",
    ]
    skipped = solves[solves["status"] == "skipped"].drop_duplicates(["solver", "tier", "mode"])
    for tier, g in summary.groupby("tier", sort=False):
        lines += [
            f"## Tier `{tier}`",
            "",
            g.drop(columns="tier").to_markdown(index=False, floatfmt=".3g"),
            "",
        ]
    if not skipped.empty:
        lines += [
            "## Skipped",
            "",
            skipped[["solver", "tier", "mode", "message"]].to_markdown(index=False),
            "",
        ]
    failures = solves[(solves["status"] != "skipped") & ~solves["valid"].astype(bool)]
    if not failures.empty:
        worst = failures.drop_duplicates(["solver", "tier", "mode"]).head(40)
        lines += [
            "## Failures (first per solver × tier × mode)",
            "",
            worst[["solver", "tier", "mode", "problem", "message"]].to_markdown(index=False),
            "",
        ]
    lines += ["## Known limitations", "", KNOWN_LIMITATIONS]
    out.write_text("\n".join(lines))
    return out


def _solver_versions(names: list[str]) -> str:
    from wbcbench.qp import all_solvers

    info: dict[str, dict[str, Any]] = {s["name"]: dict(s) for s in all_solvers()}
    rows = [
        {
            "solver": n,
            "what": info.get(n, {}).get("summary", "") or "-",
            "version": info.get(n, {}).get("version", "?"),
            "warm start": info.get(n, {}).get("warm_start", ""),
            "hot start": info.get(n, {}).get("hot_start", ""),
            "internal time covers": info.get(n, {}).get("internal_time", "") or "-",
        }
        for n in names
    ]
    return pd.DataFrame(rows).to_markdown(index=False)
