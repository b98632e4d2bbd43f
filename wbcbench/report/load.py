"""Read a results folder through one API (tables, logs, provenance), never by ad-hoc parsing."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import pandas as pd


@dataclass
class Results:
    """The contents of a results folder.

    Attributes:
        folder: the folder.
        runs: one row per run (``kind`` = ``tracking`` or ``timing``).
        metrics: long form ``run_id, scenario, controller, solver, task, metric, value, unit``.
        provenance: machine, versions, commit, date, scenario hashes.
    """

    folder: Path
    runs: pd.DataFrame
    metrics: pd.DataFrame
    provenance: dict[str, Any] = field(default_factory=dict)

    @cached_property
    def qp_solves(self) -> pd.DataFrame:
        """The solver comparison's rows (empty when the folder has none)."""
        from wbcbench.bench.solver_comparison import SolveTable

        return SolveTable(self.folder).read()

    def log(self, run_id: str) -> pd.DataFrame:
        """The per-tick log of one run (empty when it has none)."""
        path = self.folder / "logs" / f"{run_id}.parquet"
        return pd.read_parquet(path) if path.exists() else pd.DataFrame()

    def of_kind(self, kind: str) -> pd.DataFrame:
        """Runs of one kind (``tracking`` or ``timing``)."""
        if self.runs.empty:
            return self.runs
        return self.runs[self.runs["kind"] == kind]

    def wide(self, kind: str, metric_names: list[str] | None = None) -> pd.DataFrame:
        """Runs of ``kind`` joined with their metrics, one column per ``task:metric``."""
        runs = self.of_kind(kind)
        if runs.empty or self.metrics.empty:
            return runs
        m = self.metrics[self.metrics["run_id"].isin(runs["run_id"])]
        if metric_names is not None:
            m = m[m["metric"].isin(metric_names)]
        m = m.assign(col=m["task"].astype(str) + ":" + m["metric"])
        wide = m.pivot_table(index="run_id", columns="col", values="value", aggfunc="first")
        return runs.join(wide, on="run_id")

    @property
    def machine(self) -> str:
        """CPU and core count the results were measured on."""
        prov = self.provenance
        return f"{prov.get('cpu', 'unknown CPU')}, {prov.get('cores', '?')} cores"


def load_results(path: str | Path) -> Results:
    """Load a results folder written by ``wbcbench sweep`` / ``run`` / ``bench``."""
    folder = Path(path)
    if not folder.is_dir():
        from wbcbench.errors import WbcBenchError

        raise WbcBenchError(f"{folder}: no such results folder")
    runs = pd.DataFrame()
    if (folder / "runs.csv").exists():
        runs = pd.read_csv(folder / "runs.csv")
        # folders written before timing runs existed hold tracking runs only
        kind = runs["kind"] if "kind" in runs.columns else pd.Series(index=runs.index, dtype=object)
        runs["kind"] = kind.fillna("tracking")
        # a folder written before duplicates were merged may repeat a run: keep the first
        runs = runs.drop_duplicates("run_id")
    metrics = pd.read_csv(folder / "metrics.csv") if (folder / "metrics.csv").exists() else None
    if metrics is not None:
        metrics = metrics.drop_duplicates(["run_id", "task", "metric"])
    prov_path = folder / "provenance.json"
    prov = json.loads(prov_path.read_text()) if prov_path.exists() else {}
    return Results(folder, runs, metrics if metrics is not None else pd.DataFrame(), prov)
