"""What every paper table shares: the table type, run selection, metrics, labels and notes."""

from __future__ import annotations

import fnmatch
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results

MODE_ORDER = ("hot", "warm", "cold")
TIER_ORDER = ("default", "mid", "high", "low")


@dataclass
class PaperTable:
    """One generated table: the frame (None when its runs are missing) and notes."""

    name: str
    title: str
    paper: str
    frame: pd.DataFrame | None
    notes: list[str] = field(default_factory=list)
    missing: str = ""

    def markdown(self) -> str:
        lines = [f"## {self.title}", ""]
        if self.frame is None or self.frame.empty:
            lines += [f"*No results yet.* {self.missing}", ""]
        else:
            lines += [self.frame.to_markdown(index=False, floatfmt=".4g"), ""]
        lines += [f"- {n}" for n in self.notes]
        return "\n".join(lines) + "\n"


# -- selection helpers


def _runs(res: Results, kind: str, scenario: str, controller: str | None = None) -> pd.DataFrame:
    runs = res.of_kind(kind)
    if runs.empty:
        return runs
    sel = runs[[fnmatch.fnmatchcase(str(s), scenario) for s in runs["scenario"]]]
    if controller is not None:
        sel = sel[sel["controller"] == controller]
    return sel[sel["status"].isin(["ok", "failed", "fell"])]


def _config(row: pd.Series) -> str:
    """The row's controller config as JSON without its ``impl`` (the impl column says it), or
    "" when nothing else is set."""
    cfg = row.get("controller_config", "{}")
    if pd.isna(cfg) or cfg in ("", "{}"):
        return ""
    try:
        parsed = json.loads(str(cfg))
    except ValueError:
        return str(cfg)
    if not isinstance(parsed, dict):
        return str(cfg)
    parsed.pop("impl", None)
    return json.dumps(parsed, sort_keys=True) if parsed else ""


def _has(row: pd.Series, word: str) -> bool:
    return word in _config(row).lower() or word in str(row["scenario"]).lower()


def _recorder(row: pd.Series) -> str:
    """The controller whose closed-loop run a timing row replayed (from its settings)."""
    try:
        return str(json.loads(str(row.get("settings") or "{}")).get("recorder", ""))
    except ValueError:
        return ""


def _impl_of(runs: pd.DataFrame) -> pd.Series:
    """Each row's impl (rows from before the impl column ran the Python path)."""
    if "impl" not in runs.columns:
        return pd.Series("python", index=runs.index)
    impl = runs["impl"].astype(object).where(runs["impl"].notna(), "python").astype(str)
    return impl.replace({"": "python", "nan": "python"})


def _one_impl(runs: pd.DataFrame) -> pd.DataFrame:
    """The rows of one impl, so that no ratio mixes them: native where every controller among
    the rows has native ones, else python."""
    if runs.empty:
        return runs
    impl = _impl_of(runs)
    native = set(runs.loc[impl == "native", "controller"])
    chosen = "native" if set(runs["controller"]) <= native else "python"
    return runs[impl == chosen]


def impl_note(runs: pd.DataFrame) -> str:
    """The sentence a timing table carries about the impl its times come from."""
    impls = sorted(set(_impl_of(runs))) if not runs.empty else []
    if impls == ["native"]:
        return "Times of the native ticks (`impl: native`), every controller on the same impl."
    if impls == ["python"]:
        return "Times of the Python path (`impl: python`), every controller on the same impl."
    return f"Impls: {', '.join(impls) or 'none'}."


def _pick_timing(
    runs: pd.DataFrame, paper_solver: str, recorder: str | None = None
) -> pd.DataFrame:
    """One timing run per (scenario, robot, controller, config), all of one impl (see
    :func:`_one_impl`) and one solver × tier × mode, so that no ratio between two of them mixes
    settings. The setting is the one with runs for the most of those keys; among equals the
    paper's solver, else the default, then tier ``default`` and hot before warm before cold.
    With ``recorder``, runs that replay that controller's recording come first."""
    from wbcbench.qp.registry import default_solver

    runs = _one_impl(runs)
    if runs.empty:
        return runs
    for column, value in (("scenario_hash", ""), ("robot", ""), ("tier", "default")):
        filled = runs[column].astype(object).fillna(value) if column in runs.columns else value
        runs = runs.assign(**{column: filled})
    runs = runs.assign(_config=[_config(r) for _, r in runs.iterrows()])
    key = ["scenario", "scenario_hash", "robot", "controller", "_config"]
    prefer = [paper_solver.lower(), default_solver()]

    def order(value: str, choices: Sequence[str]) -> int:
        return choices.index(value) if value in choices else len(choices)

    def setting_rank(item: tuple[Any, pd.DataFrame]) -> tuple[int, int, int, int]:
        (solver, tier, mode), group = item
        covered = len(group.drop_duplicates(key))
        return (-covered, order(solver, prefer), order(tier, TIER_ORDER), order(mode, MODE_ORDER))

    _, chosen = min(runs.groupby(["solver", "tier", "mode"]), key=setting_rank)
    if recorder is not None:
        first = [0 if _recorder(r) == recorder else 1 for _, r in chosen.iterrows()]
        chosen = chosen.assign(_first=first).sort_values("_first", kind="stable")
        chosen = chosen.drop(columns=["_first"])
    return chosen.drop_duplicates(key).drop(columns=["_config"])


@cache
def _spec_with(file: str, overrides: tuple[str, ...]) -> Any:
    from wbcbench.scenarios.load import load_scenario

    try:
        return load_scenario(file, list(overrides)).spec
    except Exception:  # a scenario file since removed, renamed or changed
        return None


def run_spec(res: Results, row: pd.Series) -> Any:
    """The scenario a run used: its file with the overrides a timing row records."""
    try:
        overrides = tuple(json.loads(str(row.get("settings") or "{}")).get("overrides", []))
    except ValueError:
        overrides = ()
    if not overrides:
        return scenario_spec(res, str(row["scenario"]))
    info = res.provenance.get("scenarios", {}).get(str(row["scenario"]), {})
    file = info.get("file") or str(row["scenario"])
    return _spec_with(file if Path(file).exists() else str(row["scenario"]), overrides)


@cache
def _base_hash(file: str) -> str:
    from wbcbench.scenarios.load import load_scenario

    try:
        return load_scenario(file).hash
    except Exception:
        return ""


def _full_length(res: Results, row: pd.Series) -> bool:
    """Whether a run used its scenario as written (not shortened or otherwise overridden)."""
    info = res.provenance.get("scenarios", {}).get(str(row["scenario"]), {})
    file = info.get("file") or str(row["scenario"])
    if not Path(file).exists():
        file = str(row["scenario"])
    return str(row.get("scenario_hash", "")) == _base_hash(file)


def _prefer_full(res: Results, runs: pd.DataFrame) -> pd.DataFrame:
    """Tracking runs ordered best last: runs of the scenario as written after shortened ones,
    then the longest simulated (so ``.iloc[-1]`` is the one a paper table should use)."""
    if runs.empty:
        return runs
    full = [_full_length(res, r) for _, r in runs.iterrows()]
    column = runs["sim_duration_s"] if "sim_duration_s" in runs.columns else runs["scenario"]
    simulated = pd.to_numeric(column, errors="coerce").fillna(0.0).to_numpy()
    key = pd.DataFrame({"full": full, "sim": simulated}, index=runs.index)
    return runs.loc[key.sort_values(["full", "sim"], kind="stable").index]


def _run_status(row: pd.Series) -> str:
    """``ok``, or the status with how far the run got and why it stopped."""
    status = str(row.get("status", "?"))
    if status == "ok":
        return "ok"
    sim = pd.to_numeric(pd.Series([row.get("sim_duration_s")]), errors="coerce").iloc[0]
    reached = f" after {sim:.3g} s" if np.isfinite(sim) else ""
    message = str(row.get("message") or "")
    return f"{status}{reached}: {message}" if message else f"{status}{reached}"


def _metric(res: Results, run_id: Any, metric: str, task: Any = "*") -> float:
    m = res.metrics
    if m.empty:
        return float("nan")
    sel = m[(m["run_id"] == run_id) & (m["metric"] == metric) & (m["task"].astype(str) == task)]
    return float(sel["value"].iloc[0]) if len(sel) else float("nan")


def _levels(res: Results, run_id: Any) -> list[str]:
    """Hierarchy levels a timing run reports, in natural order (level2 before level10)."""
    m = res.metrics
    tasks = m[(m["run_id"] == run_id) & (m["metric"] == "t_solve_mean_us")]["task"].astype(str)
    levels = [t for t in tasks.unique() if t != "*"]
    return sorted(
        levels, key=lambda s: [int(x) if x.isdigit() else x for x in re.split(r"(\d+)", s)]
    )


@cache
def _spec(file: str) -> Any:
    from wbcbench.scenarios.load import load_scenario

    try:
        return load_scenario(file).spec
    except Exception:  # a scenario file since removed or renamed
        return None


def scenario_spec(res: Results, name: str) -> Any:
    """The scenario's spec (from the file provenance names, else the scenarios/ folder)."""
    info = res.provenance.get("scenarios", {}).get(name, {})
    file = info.get("file") or name
    return _spec(file) if Path(file).exists() else _spec(name)


@cache
def _robot_dof(robot: str) -> int:
    from wbcbench.robots.loader import load_robot

    try:
        return int(load_robot(robot).k)
    except Exception:
        digits = re.findall(r"\d+", robot)
        return int(digits[-1]) if digits else -1


def _ratio(a: float, b: float) -> float:
    return a / b if b and np.isfinite(a) and np.isfinite(b) else float("nan")


def _ms(us: float) -> float:
    return us / 1e3


def _machines(res: Results, paper: str) -> str:
    return f"Paper times: {P.PAPERS[paper].machine}. Our times: {res.machine}.{_load_note(res)}"


def _load_note(res: Results) -> str:
    """How many timing rows were taken on a busy machine (their ``settings.conditions``)."""
    runs = res.runs
    if runs.empty or "kind" not in runs or "settings" not in runs:
        return ""
    timing = runs[(runs["kind"] == "timing") & (runs["status"] == "ok")]
    busy, loads = 0, []
    for text in timing["settings"].dropna():
        try:
            conditions = json.loads(text).get("conditions")
        except (TypeError, ValueError):
            continue
        if conditions:
            busy += bool(conditions.get("busy"))
            loads.append(float(conditions.get("load_1min", float("nan"))))
    if not loads:
        return ""
    note = f" Load average while timing: {min(loads):g}–{max(loads):g}"
    if busy:
        note += (
            f"; {busy} of {len(loads)} timing rows on a busy machine (other work > 0.5 per core)"
        )
    return note + "."


# -- task matching for tracking tables


def _find_task(spec: Any, patterns: list[str], want: str) -> tuple[str, str] | None:
    """(task name, metric) of the first task whose name or frame matches, for part ``want``.

    ``want`` is ``pos`` or ``rot``; a pose task gives ``err_mean`` for its position and
    ``err_rot_mean`` for its orientation.
    """
    if spec is None:
        return None
    for pattern in patterns:
        for t in sorted(spec.tasks, key=lambda t: t.priority):
            label = f"{t.name} {t.frame or ''}".lower()
            if not re.search(pattern, label) and not (pattern == "com" and t.type == "com"):
                continue
            if want == "pos" and t.type in ("com", "frame_position", "frame_pose"):
                return t.name, "err_mean"
            if want == "rot" and t.type == "frame_orientation":
                return t.name, "err_mean"
            if want == "rot" and t.type == "frame_pose":
                return t.name, "err_rot_mean"
    return None


S1_TASKS = [  # paper row → (name / frame patterns, part)
    (["com"], "pos"),
    ([r"r(ight)?_?hand"], "pos"),
    (["trunk", "pelvis", "waist"], "rot"),
    (["torso", "upper"], "rot"),
    ([r"r(ight)?_?hand"], "rot"),
]


def _errors(res: Results, run: pd.Series, spec: Any) -> list[tuple[str, float, str]]:
    out = []
    for patterns, part in S1_TASKS:
        found = _find_task(spec, patterns, part)
        if found is None:
            out.append(("-", float("nan"), ""))
            continue
        task, metric = found
        value = _metric(res, run["run_id"], metric, task)
        out.append((task, value, metric))
    return out


def _to_paper_unit(value: float, unit: str) -> float:
    return value * 1e3 if unit == "mm" else value
