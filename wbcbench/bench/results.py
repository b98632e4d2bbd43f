"""The results store of one output folder.

``runs.csv`` holds one row per run, ``metrics.csv`` the metrics of every run in long form, both
appended as each run finishes (so a crash loses nothing) and mirrored to Parquet;
``logs/<run_id>.parquet`` holds each run's per-tick log and ``provenance.json`` the machine,
versions and code the results were measured with.

Crash safety. A run is written log first, then its metrics, then its row, each line appended
whole and flushed (one row is one line: line breaks in a message become spaces): the row is the
commit mark. ``provenance.json`` and the mirrors are written to a temporary file and renamed.
Opening a store repairs what a kill can leave: a torn last line (cut off), metrics whose run has
no row (removed, so the rerun that computes the run again does not duplicate them). Appending
costs O(1); the Parquet mirrors are rewritten atomically when a sweep ends and whenever a store
is opened whose mirror is older than its tables, so a mirror is never behind once a sweep has
finished or a store has been opened.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import Any

import pandas as pd

from wbcbench.bench.provenance import provenance

RUN_COLUMNS = (
    "run_id",
    "scenario",
    "scenario_hash",
    "robot",
    "controller",
    "controller_config",
    "solver",
    "tier",
    "mode",
    "impl",
    "seed",
    "status",
    "fell",
    "message",
    "ticks",
    "sim_duration_s",
    "wall_time_s",
    "failures",
    "code_version",
    "kind",
    "settings",
)
#: what a run row measures: a closed-loop run, or open-loop replay timing on recorded states
RUN_KINDS = ("tracking", "timing")
METRIC_COLUMNS = ("run_id", "scenario", "controller", "solver", "task", "metric", "value", "unit")


def printed_path(folder: str | Path, name: str) -> Path:
    """Where a guarded run's standard output goes (``logs/<name>.stdout.txt``, kept only when
    something was printed): native libraries' banners and debug lines, not the sweep's output."""
    return Path(folder) / "logs" / f"{name}.stdout.txt"


class ResultsStore:
    """Append-only tidy tables in one folder."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        (self.folder / "logs").mkdir(exist_ok=True)
        self.runs_csv = self.folder / "runs.csv"
        self.metrics_csv = self.folder / "metrics.csv"
        self.repaired = self._repair()
        self._write_provenance()

    def _write_provenance(self) -> None:
        path = self.folder / "provenance.json"
        info = provenance()
        previous: dict[str, Any] = {}
        if path.exists():
            try:
                previous = json.loads(path.read_text())
            except json.JSONDecodeError:
                previous = {}
        info["scenarios"] = previous.get("scenarios", {})
        # each earlier opening's provenance is kept: rows written then carry its code version
        history = previous.pop("history", [])
        previous.pop("scenarios", None)
        if previous and previous.get("source_hash") != info.get("source_hash"):
            history.append(previous)
        elif previous:
            info["first_opened"] = previous.get("first_opened", previous.get("date"))
        info["history"] = history
        self.provenance = info
        _write_atomically(path, json.dumps(info, indent=2, sort_keys=True) + "\n")

    def record_scenario(self, name: str, scenario_hash: str, path: str) -> None:
        self.provenance["scenarios"][name] = {"hash": scenario_hash, "file": path}
        _write_atomically(
            self.folder / "provenance.json",
            json.dumps(self.provenance, indent=2, sort_keys=True) + "\n",
        )

    @staticmethod
    def _append(path: Path, columns: tuple[str, ...], rows: list[dict[str, Any]]) -> None:
        new = not path.exists()
        if not new:
            with path.open(newline="") as fh:
                header = next(csv.reader(fh), [])
            if tuple(header) != columns:
                # a folder written by an older version: rewrite it once with the new columns
                # (missing ones empty) so appended rows line up with the header
                pd.read_csv(path).reindex(columns=list(columns)).to_csv(path, index=False)
        with path.open("a", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
            if new:
                writer.writeheader()
            writer.writerows(one_line(row) for row in rows)
            fh.flush()

    def add_run(
        self,
        run: dict[str, Any],
        metrics: list[dict[str, Any]],
        log: dict[str, Any] | None = None,
        attrs: dict[str, str] | None = None,
    ) -> None:
        """Append one run: its per-tick log (with ``attrs``, e.g. the walk it followed, in the
        Parquet file's metadata), its metrics, then its row (the commit mark)."""
        if log:
            path = self.folder / "logs" / f"{run['run_id']}.parquet"
            tmp = path.with_suffix(".parquet.tmp")
            frame = pd.DataFrame(log)
            frame.attrs.update(attrs or {})
            frame.to_parquet(tmp)
            os.replace(tmp, path)
        self._append(self.metrics_csv, METRIC_COLUMNS, metrics)
        self._append(self.runs_csv, RUN_COLUMNS, [run])

    def refresh_mirror(self) -> None:
        """Rewrite the Parquet mirrors of the tables (each to a temporary file, then renamed)."""
        for csv_path in (self.runs_csv, self.metrics_csv):
            if csv_path.exists():
                target = csv_path.with_suffix(".parquet")
                tmp = csv_path.with_suffix(".parquet.tmp")
                pd.read_csv(csv_path).to_parquet(tmp, index=False)
                os.replace(tmp, target)

    def _repair(self) -> list[str]:
        """Undo what a kill mid-write can leave; returns what was repaired (for the log)."""
        done: list[str] = []
        for csv_path in (self.runs_csv, self.metrics_csv):
            if not csv_path.exists():
                continue
            data = csv_path.read_bytes()
            if data and not data.endswith(b"\n"):
                keep = data[: data.rfind(b"\n") + 1]
                tmp = csv_path.with_suffix(".csv.tmp")
                tmp.write_bytes(keep)
                os.replace(tmp, csv_path)
                done.append(f"{csv_path.name}: cut a torn last line ({len(data) - len(keep)} B)")
        if self.metrics_csv.exists() and self.metrics_csv.stat().st_size:
            runs = set(self.runs()["run_id"]) if self.runs_csv.exists() else set()
            metrics = self.metrics()
            orphan = ~metrics["run_id"].isin(runs)
            if orphan.any():
                tmp = self.metrics_csv.with_suffix(".csv.tmp")
                metrics[~orphan].to_csv(tmp, index=False)
                os.replace(tmp, self.metrics_csv)
                done.append(f"metrics.csv: removed {int(orphan.sum())} metrics of unfinished runs")
        stale = any(
            csv_path.exists()
            and (
                not csv_path.with_suffix(".parquet").exists()
                or csv_path.with_suffix(".parquet").stat().st_mtime < csv_path.stat().st_mtime
            )
            for csv_path in (self.runs_csv, self.metrics_csv)
        )
        if done or stale:
            self.refresh_mirror()
        return done

    def runs(self) -> pd.DataFrame:
        if not self.runs_csv.exists():
            return pd.DataFrame()
        runs = pd.read_csv(self.runs_csv)
        if "kind" not in runs.columns:
            runs["kind"] = "tracking"
        runs["kind"] = runs["kind"].fillna("tracking")
        return runs

    def metrics(self) -> pd.DataFrame:
        return pd.read_csv(self.metrics_csv) if self.metrics_csv.exists() else pd.DataFrame()

    def done_run_ids(self) -> set[str]:
        runs = self.runs()
        return set(runs["run_id"]) if not runs.empty else set()

    def run_statuses(self) -> dict[str, str]:
        """The status of every stored run, by run id."""
        runs = self.runs()
        return dict(zip(runs["run_id"], runs["status"], strict=True)) if not runs.empty else {}

    def reuse(self, source: str | Path, wanted: dict[str, tuple[int, float]]) -> list[str]:
        """Copy into this folder the runs of ``source``, another results folder, that
        ``wanted`` names (run id → (keep every N-th tick of its log, the run's control period
        [s])) and this folder lacks; a row that ended in ``error`` is left to be recomputed.

        Run ids cover the scenario, the settings and the code version, so a copied run is the
        run this folder's sweep would compute. Each is appended as a finished run is: its log
        (thinned to every N-th tick where the source kept more), its metrics, then its row.
        Returns the ids copied.
        """
        source = Path(source)
        if not (source / "runs.csv").exists() or source.resolve() == self.folder.resolve():
            return []
        have = self.done_run_ids()
        runs = pd.read_csv(source / "runs.csv")
        runs = runs[runs["run_id"].isin(set(wanted) - have) & (runs["status"] != "error")]
        if runs.empty:
            return []
        metrics = pd.read_csv(source / "metrics.csv")
        metrics = metrics[metrics["run_id"].isin(set(runs["run_id"]))]
        by_run = dict(iter(metrics.groupby("run_id", sort=False)))
        copied = []
        for record in runs.to_dict("records"):
            row = {str(k): v for k, v in record.items()}
            rid = str(row["run_id"])
            log: dict[str, Any] | None = None
            attrs: dict[str, str] | None = None
            path = source / "logs" / f"{rid}.parquet"
            if path.exists():
                frame = pd.read_parquet(path)
                attrs = {str(k): str(v) for k, v in frame.attrs.items()}
                keep, dt = wanted[rid]
                if "t" in frame and len(frame) > 1:
                    kept = max(1, round(float(frame["t"].iloc[1] - frame["t"].iloc[0]) / dt))
                    if keep > kept and keep % kept == 0:
                        frame = frame.iloc[:: keep // kept]
                log = {c: frame[c].to_numpy() for c in frame.columns}
            group = by_run.get(rid)
            rows = [] if group is None else group.to_dict("records")
            self.add_run(row, [{str(k): v for k, v in r.items()} for r in rows], log, attrs)
            copied.append(rid)
        # the provenance says where the copied rows were measured
        try:
            theirs = json.loads((source / "provenance.json").read_text())
        except (OSError, ValueError):
            theirs = {}
        self.provenance["reused"] = {
            "from": str(source),
            "runs": len(copied),
            **{k: theirs.get(k) for k in ("date", "git_commit", "cpu", "cores", "source_hash")},
        }
        _write_atomically(
            self.folder / "provenance.json",
            json.dumps(self.provenance, indent=2, sort_keys=True) + "\n",
        )
        return copied

    def forget(self, run_ids: set[str]) -> int:
        """Remove runs (row, metrics, log) so that a sweep computes them again.

        Each table is rewritten to a temporary file and renamed over the old one, so a crash
        leaves either the old or the new table. Returns the number of runs removed.
        """
        runs = self.runs()
        if runs.empty or not run_ids:
            return 0
        gone = runs["run_id"].isin(run_ids)
        for csv_path, table in ((self.runs_csv, runs), (self.metrics_csv, self.metrics())):
            if table.empty:
                continue
            tmp = csv_path.with_suffix(".csv.tmp")
            table[~table["run_id"].isin(run_ids)].to_csv(tmp, index=False)
            os.replace(tmp, csv_path)
        for rid in run_ids:
            (self.folder / "logs" / f"{rid}.parquet").unlink(missing_ok=True)
        self.refresh_mirror()
        return int(gone.sum())


def one_line(row: dict[str, Any]) -> dict[str, Any]:
    """The row with line breaks in its text replaced by spaces: one row is one line of the file,
    so a write cut short by a kill is exactly a last line without its newline."""
    return {
        k: " ".join(v.splitlines()) if isinstance(v, str) and ("\n" in v or "\r" in v) else v
        for k, v in row.items()
    }


def _write_atomically(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
