"""Each paper's key comparison as a figure, ours beside the paper's numbers, drawn from the same
paper tables as ``tables/papers.md`` (:mod:`wbcbench.report.tables`), so a figure never shows a
number its table does not:

* ``paper_to_osf_s1``: TO-OSF Scenario #1 mean errors per task, ours and the paper's, log axes,
  one facet per unit;
* ``paper_to_osf_s2``: TO-OSF Scenario #2, priority / identical weighting: the total amendment
  ratio beside the paper's ≈ 7.5, and each task's error ratio;
* ``paper_to_osf_s3``: TO-OSF Scenario #3, each task's mean error before and once T3 conflicts
  with T2, strict hierarchy against weighted QP-WBC (log axes, one facet per unit);
* ``paper_osf_hqp_table3``: OSF-HQP Table III per level, conventional vs proposed, the paper's
  and ours in two facets (log time axis), with the speed-ups above;
* ``paper_osf_hqp_backends``: the same per backend × mode that timed both controllers, one facet
  each;
* ``paper_rc_lqp_dof``: RC-LQP's gain (conventional / reduced) against the DoF: ours, the
  paper's two published points and the authors' C++ (libdwbc) measured on this project's
  machine; and the absolute medians.
"""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.pyplot as plt
import matplotlib.ticker as ticker
import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results, load_results
from wbcbench.report.tables import PaperTable, build_tables

PAPER, OURS = "#9e9e9e", "#1f77b4"
CONVENTIONAL, PROPOSED = "#d62728", "#2ca02c"


__all__ = ["FIGURES", "write_paper_figures"]


def _save(fig: plt.Figure, out: Path, name: str) -> list[Path]:
    paths = [out / f"{name}.png", out / f"{name}.svg"]
    for p in paths:
        fig.savefig(p, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return paths


def to_osf_s1(t: PaperTable, out: Path) -> list[Path]:
    f = t.frame
    assert f is not None
    units = [u for u in ("mm", "rad") if (f["unit"] == u).any()]
    fig, axes = plt.subplots(1, len(units), figsize=(5.2 * len(units), 3.0), squeeze=False)
    fig.subplots_adjust(wspace=0.75)
    for ax, unit in zip(axes[0], units, strict=True):
        g = f[f["unit"] == unit]
        y = np.arange(len(g))
        paper, ours = g["paper"].astype(float), g["ours"].astype(float)
        ax.hlines(y, ours, paper, color="#cccccc", lw=2, zorder=1)
        ax.plot(paper, y, "s", color=PAPER, ms=9, label="paper", zorder=2)
        ax.plot(ours, y, "o", color=OURS, ms=9, label="ours", zorder=3)
        ax.set_yticks(y, [str(task).split(" ", 1)[1] for task in g["task"]])
        ax.set_ylim(len(g) - 0.5, -0.5)
        ax.set_xscale("log")
        ax.set_xlabel(f"mean error over t = 9–19 s [{unit}] (log)")
        ax.grid(axis="x", which="both", alpha=0.3)
    fig.suptitle("TO-OSF Scenario #1: mean tracking errors, ours vs the paper's")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2)
    return _save(fig, out, "paper_to_osf_s1")


def to_osf_s2(t: PaperTable, out: Path) -> list[Path]:
    f = t.frame
    assert f is not None
    fig, (left, right) = plt.subplots(
        1, 2, figsize=(9.5, 3.6), gridspec_kw={"width_ratios": [1, 2.2]}
    )
    amend = f.iloc[0]
    left.bar(
        [0, 1],
        [float(amend["paper priority / identical"]), float(amend["ours priority / identical"])],
        color=[PAPER, OURS],
    )
    left.set_xticks([0, 1], ["paper", "ours"])
    left.set_ylabel("total amendment, priority / identical")
    left.set_title("identical weighting amends less by")
    left.grid(axis="y", alpha=0.3)
    errors = f.iloc[1:]
    x = np.arange(len(errors))
    ratio = errors["ours priority / identical"].astype(float).to_numpy()
    right.bar(x, ratio - 1.0, bottom=1.0, color=OURS)  # from 1: above, priority errs more
    right.axhline(1.0, color="k", lw=0.8)
    right.set_xticks(x, [str(q).replace(" error ", "\n") for q in errors["quantity"]], fontsize=8)
    right.set_yscale("log")
    right.set_ylabel("error, priority / identical (log)")
    right.set_title("per task (paper: T1, T2 below 1; T3, T4 above)")
    right.grid(axis="y", which="both", alpha=0.3)
    status = str(amend.get("status (priority; identical)", ""))
    title = "TO-OSF Scenario #2: priority vs identical weighting"
    if "fell" in status:
        title += "\n(both runs fell before the window's end; compared up to the first fall)"
    fig.suptitle(title, y=1.02 if "\n" in title else 0.98)
    fig.subplots_adjust(top=0.8, wspace=0.3)
    return _save(fig, out, "paper_to_osf_s2")


def to_osf_s3(t: PaperTable, out: Path) -> list[Path]:
    f = t.frame
    assert f is not None
    styles = {
        "to_osf": (PROPOSED, "strict hierarchy (to_osf)"),
        "qp_wbc": (CONVENTIONAL, "weighted QP-WBC (qp_wbc)"),
    }
    units = [u for u in ("m", "rad") if (f["unit"] == u).any()]
    fig, axes = plt.subplots(1, len(units), figsize=(5.0 * len(units), 3.6), squeeze=False)
    width = 0.38
    for ax, unit in zip(axes[0], units, strict=True):
        g = f[f["unit"] == unit]
        tasks = list(dict.fromkeys(g["task"]))
        x = np.arange(len(tasks))
        for k, (controller, (color, label)) in enumerate(styles.items()):
            c = g[g["controller"] == controller].set_index("task").reindex(tasks)
            at = x + (k - 0.5) * width
            ax.bar(at, c["after"].astype(float), width, color=color, label=f"{label}, after")
            ax.plot(
                at,
                c["before"].astype(float),
                "_",
                color="k",
                ms=14,
                mew=2,
                label="before" if k == 0 else None,
            )
        roles = dict(zip(g["task"], g["role"], strict=False))
        ax.set_xticks(x, [f"{task.split(' ')[0]}\n{roles[task]}" for task in tasks], fontsize=8)
        ax.set_yscale("log")
        ax.set_ylabel(f"mean error norm [{unit}] (log)")
        ax.grid(axis="y", which="both", alpha=0.3)
    fig.suptitle(
        "TO-OSF Scenario #3: T3 (left hand) held 0.2 m beyond what T2 (elbow pose) allows\n"
        "paper: the strict hierarchy leaves T1/T2 alone; the weighted QP lets T3 pull them",
        fontsize=10,
    )
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.02), ncol=3, fontsize=8)
    fig.subplots_adjust(top=0.82, wspace=0.3)
    return _save(fig, out, "paper_to_osf_s3")


def _solvers(t: PaperTable) -> str:
    """The solvers behind a timing table's numbers: its solver column, else its note."""
    f = t.frame
    assert f is not None
    for column in ("solver", "backend"):
        if column in f.columns:
            return ", ".join(dict.fromkeys(str(v) for v in f[column].dropna()))
    for note in t.notes:
        found = re.search(r"solvers?:\s*([^.;]+)", note)
        if found:
            return found.group(1).strip()
    return "solver not recorded"


def osf_hqp_table3(t: PaperTable, out: Path) -> list[Path]:
    f = t.frame
    assert f is not None
    levels = f[f["level"].astype(str).str.fullmatch(r"T\d")]
    x = np.arange(len(levels))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for ax, who in zip(axes, ("paper", "ours"), strict=True):
        conv = levels[f"{who} conv. [ms]"].astype(float).to_numpy()
        prop = levels[f"{who} OSF-HQP [ms]"].astype(float).to_numpy()
        ax.bar(x - 0.2, conv, 0.4, color=CONVENTIONAL, label="conventional HQP")
        ax.bar(x + 0.2, prop, 0.4, color=PROPOSED, label="OSF-HQP")
        for xi, c, p in zip(x, conv, prop, strict=True):
            ax.annotate(f"{c / p:.0f}×", (xi, c), ha="center", va="bottom", fontsize=8)
        ax.set_xticks(x, list(levels["level"]))
        ax.set_yscale("log")
        total = _row(f, "total")
        ax.set_title(
            f"{who}: all QPs {float(total[f'{who} conv. [ms]']):.3g} vs "
            f"{float(total[f'{who} OSF-HQP [ms]']):.3g} ms "
            f"({float(total[f'{who} ratio']):.3g}×)"
        )
        ax.grid(axis="y", which="both", alpha=0.3)
    axes[0].set_ylabel("QP time per level [ms] (log)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2)
    fig.suptitle(
        "OSF-HQP Table III: time per priority level (T5 = the wrench QP)\n"
        f"paper: qpOASES; ours: {_solvers(t)}",
        y=1.02,
    )
    fig.subplots_adjust(top=0.80)
    return _save(fig, out, "paper_osf_hqp_table3")


def osf_hqp_backends(t: PaperTable, out: Path) -> list[Path]:
    f = t.frame
    assert f is not None
    backends = list(dict.fromkeys(f["backend"]))
    ncols = min(3, len(backends))
    nrows = -(-len(backends) // ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(max(6.0, 4.2 * ncols), 3.4 * nrows + 0.4), sharey=True, squeeze=False
    )
    for ax in axes.ravel()[len(backends) :]:
        ax.set_visible(False)
    for ax, backend in zip(axes.ravel(), backends, strict=False):
        g = f[(f["backend"] == backend) & f["level"].astype(str).str.fullmatch(r"T\d")]
        x = np.arange(len(g))
        conv, prop = g["conv. [ms]"].astype(float), g["OSF-HQP [ms]"].astype(float)
        ax.bar(x - 0.2, conv, 0.4, color=CONVENTIONAL, label="conventional HQP")
        ax.bar(x + 0.2, prop, 0.4, color=PROPOSED, label="OSF-HQP")
        for xi, r in zip(x, g["ratio"].astype(float), strict=True):
            top = max(float(conv.iloc[xi]), float(prop.iloc[xi]))
            label = f"{r:.0f}×" if r >= 10 else f"{r:.2g}×"
            ax.annotate(label, (xi, top), ha="center", va="bottom", fontsize=7)
        ax.set_xticks(x, list(g["level"]))
        ax.set_yscale("log")
        total = f[(f["backend"] == backend) & (f["level"] == "total")]
        ratio = f" (all QPs {float(total['ratio'].iloc[0]):.3g}×)" if len(total) else ""
        ax.set_title(f"{backend}{ratio}", fontsize=9)
        ax.grid(axis="y", which="both", alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("QP time per level [ms] (log)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2)
    paper = P.OSF_HQP_TABLE3["conventional"][-1] / P.OSF_HQP_TABLE3["proposed"][-1]
    fig.suptitle(
        "OSF-HQP Table III per backend: conventional vs proposed per level\n"
        f"(the paper, qpOASES: {paper:.3g}× over all QPs)",
        fontsize=10,
    )
    fig.tight_layout()
    return _save(fig, out, "paper_osf_hqp_backends")


def _row(f: pd.DataFrame, level: str) -> pd.Series:
    return f[f["level"].astype(str) == level].iloc[0]


def rc_lqp_dof(t: PaperTable, out: Path) -> list[Path]:
    f = t.frame
    assert f is not None
    dof = f["DoF"].astype(int).to_numpy()
    fig, (gain, times) = plt.subplots(1, 2, figsize=(10, 3.8))
    gain.plot(dof, f["ours ratio"].astype(float), "o-", color=OURS, label="ours")
    paper = sorted(P.RC_LQP_DOF.items())
    gain.plot(
        [d for d, _ in paper],
        [v["conventional"] / v["proposed"] for _, v in paper],
        "s",
        color=PAPER,
        ms=8,
        label="paper (§5.3)",
    )
    measured = sorted(P.RC_LQP_DOF_LIBDWBC.items())
    gain.plot(
        [d for d, _ in measured],
        [1.0 / r for _, r in measured],
        "^--",
        color="#ff7f0e",
        label=f"authors' C++ (libdwbc), once on a {P.RC_LQP_DOF_LIBDWBC_MEASURED}",
    )
    gain.axhline(1.0, color="k", lw=0.8)
    gain.set_xlabel("DoF")
    gain.set_ylabel("conventional / reduced step time")
    gain.set_title("the reduced model's speed-up")
    gain.grid(alpha=0.3)
    gain.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2)
    for controller, method, label, color in (
        ("lqp", "conventional", "conventional", CONVENTIONAL),
        ("rc_lqp", "proposed", "reduced", PROPOSED),
    ):
        ours = f[f"ours {controller} median [µs]"].astype(float)
        times.plot(dof, ours, "o-", color=color, label=f"ours, {controller}")
        published = [v[method] for _, v in paper]
        times.plot(
            [d for d, _ in paper],
            published,
            "s",
            mfc="none",
            color=color,
            ms=8,
            label=f"paper, {label}",
        )
    times.set_yscale("log")
    times.yaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    times.yaxis.set_minor_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    times.set_xlabel("DoF")
    times.set_ylabel("median step [µs] (log)")
    times.set_title("absolute times (the paper's on another CPU)")
    times.grid(alpha=0.3, which="both")
    times.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2)
    fig.suptitle(
        "RC-LQP Fig. 5: double support, against the number of DoF\n"
        f"paper: OSQP; ours: {_solvers(t)}",
        y=1.04,
    )
    fig.subplots_adjust(top=0.84, wspace=0.35)
    return _save(fig, out, "paper_rc_lqp_dof")


#: paper table name → the function drawing its key figure from the table (into a folder)
FIGURES = {
    "to_osf_s1": to_osf_s1,
    "to_osf_s2": to_osf_s2,
    "to_osf_s3": to_osf_s3,
    "osf_hqp_table3": osf_hqp_table3,
    "osf_hqp_backends": osf_hqp_backends,
    "rc_lqp_dof": rc_lqp_dof,
}


def write_paper_figures(folder: str | Path, res: Results | None = None) -> list[Path]:
    """The key figure of each paper whose table has results, into ``<folder>/figures``."""
    res = res if res is not None else load_results(folder)
    out = Path(folder) / "figures"
    out.mkdir(exist_ok=True)
    paths: list[Path] = []
    for table in build_tables(res):
        draw = FIGURES.get(table.name)
        if draw is not None and table.frame is not None and not table.frame.empty:
            paths += draw(table, out)
    return paths
