"""What the notebooks in ``notebooks/`` share: the results folder they read, each paper's
verdicts as a table, and conclusions drawn from the numbers (never written by hand).

Run a notebook with ``jupyter execute notebooks/<name>.ipynb`` (the ``dev`` extra installs
Jupyter), or open it in JupyterLab; ``WBCBENCH_RESULTS=<folder>`` points it at your own
``make bench`` output instead of the curated ``results/reference``.
"""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from wbcbench.report.load import Results, load_results

__all__ = [
    "notebook_results",
    "paper_verdicts",
    "robustness_conclusion",
    "solver_conclusion",
    "verdict_conclusion",
    "verdict_markdown",
]


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
