"""Paper tables: the papers' numbers beside ours, with the ratios.

Each table is built from a results folder (:func:`wbcbench.report.load_results`). It finds its
runs by scenario-name pattern and controller name, so scenarios and controllers added later are
picked up as they land; a table whose runs are missing says which runs to make instead of
failing. Absolute times are labelled with the machine they were measured on: the papers' from
:mod:`wbcbench.report.papers`, ours from the folder's provenance.

Timing values are from open-loop replay (``kind = timing``) and prefer, for each controller, the
paper's own solver when it was timed, else the default solver; hot mode before warm before cold.
"""

from __future__ import annotations

import fnmatch
import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results, load_results

MODE_ORDER = ("hot", "warm", "cold")


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
    :func:`_one_impl`): paper's solver, else the default; with ``recorder``, runs that replay
    that controller's recording first."""
    from wbcbench.bench.sweep import default_solver

    runs = _one_impl(runs)
    if runs.empty:
        return runs
    prefer = [paper_solver.lower(), default_solver()]

    def rank(row: pd.Series) -> tuple[int, int, int]:
        r = 0 if recorder is None or _recorder(row) == recorder else 1
        s = prefer.index(row["solver"]) if row["solver"] in prefer else len(prefer)
        m = MODE_ORDER.index(row["mode"]) if row["mode"] in MODE_ORDER else 3
        return (r, s, m)

    ranks: list[Any] = [rank(r) for _, r in runs.iterrows()]
    runs = runs.assign(_rank=ranks)
    if "scenario_hash" not in runs.columns:
        runs = runs.assign(scenario_hash="")
    if "robot" not in runs.columns:
        runs = runs.assign(robot="")
    runs = runs.sort_values("_rank", kind="stable")
    runs = runs.assign(_config=[_config(r) for _, r in runs.iterrows()])
    key = ["scenario", "scenario_hash", "robot", "controller", "_config"]
    return runs.drop_duplicates(key).drop(columns=["_rank", "_config"])


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
        note += f"; {busy} of {len(loads)} timing rows on a busy machine (> 0.5 per core)"
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


# -- TO-OSF


def to_osf_s1(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_s1", "TO-OSF Scenario #1: mean tracking errors (t = 9–19 s)", "to_osf", None
    )
    runs = _runs(res, "tracking", "lee2021access_s1*", "to_osf")
    runs = runs[[not _has(r, "pinv") and not _has(r, "svd") for _, r in runs.iterrows()]]
    runs = _prefer_full(res, runs)
    if runs.empty:
        t.missing = (
            "Run `to_osf` on the `lee2021access_s1*` scenarios (`wbcbench sweep sweeps/full.yaml`)."
        )
        return t
    run = runs.iloc[-1]
    spec = scenario_spec(res, run["scenario"])
    rows = []
    for paper, (task, value, metric) in zip(P.TO_OSF_S1, _errors(res, run, spec), strict=True):
        ours = _to_paper_unit(value, paper.unit)
        rows.append(
            {
                "task": f"{paper.row} {paper.column}",
                "our task": f"{task} ({metric})" if metric else "not found",
                "unit": paper.unit,
                "paper": paper.value,
                "ours": ours,
                "ours / paper": _ratio(ours, paper.value or float("nan")),
            }
        )
    t.frame = pd.DataFrame(rows)
    t.notes += [
        f"Scenario `{run['scenario']}`, solver {run['solver']}, status {_run_status(run)}.",
        *_length_note(res, run, spec),
        "Paper: COMAN+ in V-REP/Vortex; ours: the COMAN+-like model in MuJoCo (soft contacts).",
        f"Source: {P.TO_OSF_S1[0].source}.",
    ]
    return t


def _length_note(res: Results, run: pd.Series, spec: Any) -> list[str]:
    """A note when a run's scenario was shortened: its errors are not over the paper's window."""
    if _full_length(res, run):
        return []
    window = spec.metrics.window if spec is not None else None
    return [
        f"This run was shortened ({run.get('sim_duration_s', '?')} s simulated): its errors are "
        f"over the shortened run's window, not t = {window[0]:g}–{window[1]:g} s."
        if window
        else "This run was shortened: its errors are not over the paper's window."
    ]


def to_osf_pinv(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_pinv",
        "TO-OSF Scenario #1 ablation: pseudo-inverse vs dynamically consistent inverse",
        "to_osf",
        None,
    )
    runs = _runs(res, "tracking", "lee2021access_s1*", "to_osf")
    runs = _prefer_full(res, runs)
    pinv = runs[[_has(r, "pinv") for _, r in runs.iterrows()]]
    dc = runs[[not _has(r, "pinv") and not _has(r, "svd") for _, r in runs.iterrows()]]
    if not pinv.empty and not dc.empty:  # both of the same length when there is such a pair
        same = dc[dc["scenario_hash"].isin(pinv["scenario_hash"])]
        dc = same if not same.empty else dc
        pinv = pinv[pinv["scenario_hash"].isin(dc["scenario_hash"])] if not same.empty else pinv
    if pinv.empty or dc.empty:
        t.missing = (
            "Needs `to_osf` on `lee2021access_s1*` with its default inverse and with a config "
            "selecting the pseudo-inverse (see `sweeps/full.yaml`)."
        )
        return t
    a, b = dc.iloc[-1], pinv.iloc[-1]
    spec = scenario_spec(res, a["scenario"])
    rows = []
    for paper, (task, v_dc, _), (_, v_pinv, _) in zip(
        P.TO_OSF_S1, _errors(res, a, spec), _errors(res, b, spec), strict=True
    ):
        rows.append(
            {
                "task": f"{paper.row} {paper.column}",
                "our task": task,
                f"DC inverse mean [{paper.unit}]": _to_paper_unit(v_dc, paper.unit),
                f"pinv mean [{paper.unit}]": _to_paper_unit(v_pinv, paper.unit),
                "pinv / DC": _ratio(v_pinv, v_dc),
            }
        )
    found = _find_task(spec, [r"r(ight)?_?hand"], "rot")
    peak = float("nan")
    if found:
        peak = _metric(res, b["run_id"], found[1].replace("mean", "max"), found[0])
    rows.append(
        {
            "task": "T5 right-hand orientation peak (pinv)",
            "our task": found[0] if found else "-",
            "DC inverse mean [rad]": float("nan"),
            "pinv mean [rad]": peak,
            "pinv / DC": float("nan"),
            "paper [rad]": P.TO_OSF_PINV_PEAK_RHAND_ORI.value,
        }
    )
    t.frame = pd.DataFrame(rows)
    t.notes += [
        f"Scenario `{a['scenario']}`, solver {a['solver']}; status: DC inverse "
        f"{_run_status(a)}, pinv {_run_status(b)}.",
        *_length_note(res, a, spec),
        "Paper: errors grow sharply with the pseudo-inverse; right-hand orientation peak "
        "0.988 rad (Fig. 6).",
    ]
    return t


def _amendment_total(res: Results, run: pd.Series, window: tuple[float, float] | None) -> float:
    """Mean over the logged ticks in ``window`` of Σ over tasks of ‖ẍ_opt − ẍ*‖."""
    log = res.log(run["run_id"])
    cols = [c for c in log.columns if c.startswith("diag.amend.")]
    if log.empty or not cols:
        return float("nan")
    if window is not None:
        log = log[(log["t"] >= window[0]) & (log["t"] <= window[1])]
    return float(log[cols].sum(axis=1).mean()) if len(log) else float("nan")


def _weights(res: Results, row: pd.Series) -> list[float] | None:
    """The task weights a to_osf run used: its config override, else its scenario's."""
    try:
        cfg = json.loads(_config(row) or "{}")
    except ValueError:
        cfg = {}
    spec = scenario_spec(res, str(row["scenario"]))
    own = (spec.controllers.get("to_osf") or {}) if spec is not None else {}
    merged = {**own, **cfg}
    weights = merged.get("weights")
    if not weights:
        return None
    if merged.get("weighting") == "identical":  # every task weighted by the first
        weights = weights[:1]
    return [float(w) for w in weights]


def _identical_weighting(res: Results, row: pd.Series) -> bool:
    """A run with one weight for every task (by its config or a name saying so)."""
    if _has(row, "identical") or _has(row, "uniform"):
        return True
    weights = _weights(res, row)
    return weights is not None and len(set(weights)) == 1


def _common_window(
    res: Results, a: pd.Series, b: pd.Series, window: tuple[float, float] | None
) -> tuple[tuple[float, float] | None, str]:
    """The metrics window cut to where both runs have logged ticks, and what was done."""
    ends = []
    for run in (a, b):
        simulated = pd.to_numeric(pd.Series([run.get("sim_duration_s")]), errors="coerce").iloc[0]
        if np.isfinite(simulated):
            ends.append(float(simulated))
            continue
        log = res.log(run["run_id"])
        ends.append(float(log["t"].max()) if not log.empty and "t" in log.columns else 0.0)
    end = min(ends)
    if window is None:
        return (0.0, end), f"t = 0–{end:.3g} s (whole runs)"
    if end >= window[1]:
        return window, f"t = {window[0]:g}–{window[1]:g} s (the paper's window)"
    if end > window[0]:
        return (window[0], end), (
            f"t = {window[0]:g}–{end:.3g} s: a run stopped before the window's end "
            f"({window[1]:g} s)"
        )
    return (0.0, end), (
        f"t = 0–{end:.3g} s: a run stopped before the window ({window[0]:g}–{window[1]:g} s) "
        "began, so the whole common span is compared"
    )


def to_osf_s2(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_s2",
        "TO-OSF Scenario #2: total amendment, priority vs identical weighting",
        "to_osf",
        None,
    )
    runs = _prefer_full(res, _runs(res, "tracking", "lee2021access_s2*", "to_osf"))
    is_ident = [_identical_weighting(res, r) for _, r in runs.iterrows()]
    ident = runs[is_ident] if len(runs) else runs
    prio = runs.drop(ident.index)
    if not ident.empty and not prio.empty:  # a pair of the same scenario length when possible
        same = prio[prio["scenario_hash"].isin(ident["scenario_hash"])]
        if not same.empty:
            prio = same
            ident = ident[ident["scenario_hash"].isin(same["scenario_hash"])]
    if ident.empty or prio.empty:
        t.missing = (
            "Needs `to_osf` on `lee2021access_s2*` with priority weighting and with identical "
            "weighting (the config `{weighting: identical}` or one weight for every task, as "
            "`sweeps/default.yaml` runs)."
        )
        return t
    a, b = prio.iloc[-1], ident.iloc[-1]
    spec = scenario_spec(res, a["scenario"])
    window, how = _common_window(res, a, b, spec.metrics.window if spec is not None else None)
    amend_p, amend_i = _amendment_total(res, a, window), _amendment_total(res, b, window)
    status = {"priority": _run_status(a), "identical": _run_status(b)}
    rows = [
        {
            "quantity": "mean total amendment Σ‖ẍ_opt − ẍ*‖",
            "priority weighting": amend_p,
            "identical weighting": amend_i,
            "ours priority / identical": _ratio(amend_p, amend_i),
            "paper priority / identical": P.TO_OSF_S2_AMENDMENT_RATIO.value,
            "status (priority; identical)": f"{status['priority']}; {status['identical']}",
        }
    ]
    for paper, (task, v_p, _), (_, v_i, _) in zip(
        P.TO_OSF_S1[:4],
        _errors(res, a, spec)[:4],
        _errors(res, b, scenario_spec(res, b["scenario"]))[:4],
        strict=True,
    ):
        rows.append(
            {
                "quantity": f"{paper.row} error ({task}) [{paper.unit}]",
                "priority weighting": _to_paper_unit(v_p, paper.unit),
                "identical weighting": _to_paper_unit(v_i, paper.unit),
                "ours priority / identical": _ratio(v_p, v_i),
                "paper priority / identical": float("nan"),
                "status (priority; identical)": "",
            }
        )
    t.frame = pd.DataFrame(rows)
    weights = {k: _weights(res, r) for k, r in (("priority", a), ("identical", b))}
    t.notes += [
        f"Scenario `{a['scenario']}`, solver {a['solver']}; weights: priority "
        f"{weights['priority']}, identical {weights['identical']}.",
        f"Amendments averaged over {how}; task errors are the runs' metrics window.",
        *_length_note(res, a, spec),
        "Paper: identical weighting gives ≈ 7.5× smaller total amendment; T1/T2 errors "
        "larger, T3/T4 smaller.",
        f"Source: {P.TO_OSF_S2_AMENDMENT_RATIO.source}.",
    ]
    return t


def to_osf_s4(res: Results) -> PaperTable:
    t = PaperTable("to_osf_s4", "TO-OSF Scenario #4: time vs contacts and tasks", "to_osf", None)
    runs = _runs(res, "timing", "lee2021access_s4*", "to_osf")
    runs = runs[[_config(r) == "" for _, r in runs.iterrows()]] if not runs.empty else runs
    runs = _pick_timing(runs, "qpoases")
    if not runs.empty:
        t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = "Run timing of `to_osf` on the `lee2021access_s4*` scenarios."
        return t
    rows = []
    for _, r in runs.iterrows():
        spec = run_spec(res, r)
        row: dict[str, Any] = {
            "scenario": r["scenario"],
            "contact DoF": 6 * len(spec.contacts) if spec else np.nan,
            "tasks": len(spec.tasks) if spec else np.nan,
            "solver": f"{r['solver']} ({r['mode']})",
        }
        for stage in _stages(res, r["run_id"]):
            row[f"{stage} mean [ms]"] = _ms(_metric(res, r["run_id"], f"t_{stage}_mean_us"))
        rows.append(row)
    t.frame = pd.DataFrame(rows).sort_values(["contact DoF", "tasks"], kind="stable")
    t.notes += [
        "Paper: RT-thread QP < 0.5 ms up to 24 contact DoF; non-RT parameters < 2 ms (Fig. 14).",
        _machines(res, "to_osf"),
    ]
    return t


def _stages(res: Results, run_id: Any) -> list[str]:
    m = res.metrics
    names = m[(m["run_id"] == run_id) & (m["task"] == "*")]["metric"]
    stages = [n[2:-8] for n in names if n.startswith("t_") and n.endswith("_mean_us")]
    return list(dict.fromkeys(stages))


def to_osf_cod_svd(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_cod_svd",
        "TO-OSF: COD vs SVD dynamically consistent inverse (5 tasks, two feet)",
        "to_osf",
        None,
    )
    runs = _pick_timing(_runs(res, "timing", "lee2021access_*", "to_osf"), "qpoases")
    if not runs.empty:
        t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = (
            "Needs timing of `to_osf` with the default (COD) and an SVD inverse config on one "
            "`lee2021access_*` scenario."
        )
        return t
    svd = runs[[_has(r, "svd") for _, r in runs.iterrows()]]
    cod = runs[[not _has(r, "svd") and not _has(r, "pinv") for _, r in runs.iterrows()]]
    same = "scenario_hash" if "scenario_hash" in runs.columns else "scenario"
    cod = cod[cod[same].isin(svd[same])]  # the same scenario, tasks and contacts
    if svd.empty or cod.empty:
        t.missing = (
            "Needs timing of `to_osf` with the default (COD) and an SVD inverse config on one "
            "`lee2021access_*` scenario."
        )
        return t
    a, b = cod.iloc[-1], svd.iloc[-1]
    rows = []
    for stage in _stages(res, a["run_id"]):
        va = _metric(res, a["run_id"], f"t_{stage}_mean_us")
        vb = _metric(res, b["run_id"], f"t_{stage}_mean_us")
        rows.append(
            {
                "stage": stage,
                "COD [ms]": _ms(va),
                "SVD [ms]": _ms(vb),
                "ours SVD / COD": _ratio(vb, va),
            }
        )
    rows.append(
        {
            "stage": "paper (parameters)",
            "COD [ms]": P.TO_OSF_COD_SVD[0].value,
            "SVD [ms]": P.TO_OSF_COD_SVD[1].value,
            "ours SVD / COD": _ratio(
                P.TO_OSF_COD_SVD[1].value or 0, P.TO_OSF_COD_SVD[0].value or 0
            ),
        }
    )
    t.frame = pd.DataFrame(rows)
    t.notes += [f"Scenario `{a['scenario']}`.", _machines(res, "to_osf")]
    return t


def to_osf_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "to_osf_table3", "TO-OSF Table 3: HQP vs TO-OSF time for 1…5 tasks", "to_osf", None
    )
    runs = _runs(res, "timing", "lee2021access_*t*3*")
    runs = (
        _pick_timing(runs[runs["controller"].isin(["hqp", "to_osf"])], "qpoases")
        if not runs.empty
        else runs
    )
    if not runs.empty:
        t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = (
            "Run timing of `hqp` and `to_osf` on the `lee2021access_table3*` scenarios (1…5 tasks)."
        )
        return t
    rows: dict[int, dict[str, Any]] = {}
    for _, r in runs.iterrows():
        spec = run_spec(res, r)
        n = len(spec.tasks) if spec else -1
        row = rows.setdefault(n, {"tasks": n, "paper HQP [ms]": None, "paper TO-OSF [ms]": None})
        row[f"ours {r['controller']} [ms]"] = _ms(_metric(res, r["run_id"], "t_total_mean_us"))
    frame = pd.DataFrame([rows[k] for k in sorted(rows)])
    if {"ours hqp [ms]", "ours to_osf [ms]"} <= set(frame.columns):
        frame["ours HQP / TO-OSF"] = frame["ours hqp [ms]"] / frame["ours to_osf [ms]"]
    t.frame = frame
    t.notes += [P.TO_OSF_TABLE3_NOTE, _machines(res, "to_osf")]
    return t


# -- OSF-HQP


def osf_hqp_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "osf_hqp_table3",
        "OSF-HQP Table III: per-level and total time, conventional HQP vs OSF-HQP",
        "osf_hqp",
        None,
    )
    runs = _runs(res, "timing", "lee2021iros_table1*")
    if not runs.empty:
        runs = runs[runs["controller"].isin(["hqp", "osf_hqp"])]
    runs = _pick_timing(runs, "qpoases")
    if not runs.empty:
        t.notes.append(impl_note(runs))
    conv = runs[runs["controller"] == "hqp"] if not runs.empty else runs
    prop = runs[runs["controller"] == "osf_hqp"] if not runs.empty else runs
    if conv.empty or prop.empty:
        t.missing = (
            "Run timing of `hqp` and `osf_hqp` on `lee2021iros_table1` "
            "(`wbcbench sweep sweeps/full.yaml`)."
        )
        return t
    c = conv.iloc[0]
    p = prop[[_config(r) == "" for _, r in prop.iterrows()]]
    p_run = p.iloc[0] if not p.empty else prop.iloc[0]
    lc, lp = _levels(res, c["run_id"]), _levels(res, p_run["run_id"])
    rows = []
    for i, label in enumerate(P.OSF_HQP_LEVELS):
        if label == "total":
            vc = _metric(res, c["run_id"], "t_solve_mean_us")
            vp = _metric(res, p_run["run_id"], "t_solve_mean_us")
        else:
            vc = _metric(res, c["run_id"], "t_solve_mean_us", lc[i]) if i < len(lc) else np.nan
            vp = _metric(res, p_run["run_id"], "t_solve_mean_us", lp[i]) if i < len(lp) else np.nan
        pc, pp = P.OSF_HQP_TABLE3["conventional"][i], P.OSF_HQP_TABLE3["proposed"][i]
        rows.append(
            {
                "level": label,
                "our levels": f"{lc[i] if i < len(lc) else '-'} / {lp[i] if i < len(lp) else '-'}"
                if label != "total"
                else "all QPs",
                "paper conv. [ms]": pc,
                "paper OSF-HQP [ms]": pp,
                "paper ratio": pc / pp,
                "ours conv. [ms]": _ms(vc),
                "ours OSF-HQP [ms]": _ms(vp),
                "ours ratio": _ratio(vc, vp),
            }
        )
    native = ["t_solve_setup_mean_us", "t_solve_native_mean_us"]
    vc = sum(_metric(res, c["run_id"], m) for m in native)
    vp = sum(_metric(res, p_run["run_id"], m) for m in native)
    rows.append(
        {
            "level": "total, solver only",
            "our levels": "set-up + native call of all QPs",
            "paper conv. [ms]": P.OSF_HQP_TABLE3["conventional"][-1],
            "paper OSF-HQP [ms]": P.OSF_HQP_TABLE3["proposed"][-1],
            "paper ratio": P.OSF_HQP_TABLE3["conventional"][-1] / P.OSF_HQP_TABLE3["proposed"][-1],
            "ours conv. [ms]": _ms(vc),
            "ours OSF-HQP [ms]": _ms(vp),
            "ours ratio": _ratio(vc, vp),
        }
    )
    vc = _metric(res, c["run_id"], "t_total_mean_us")
    vp = _metric(res, p_run["run_id"], "t_total_mean_us")
    rows.append(
        {
            "level": "whole step, single thread",
            "our levels": "dynamics + build + solve",
            "paper conv. [ms]": P.OSF_HQP_TABLE3["conventional"][-1],
            "paper OSF-HQP [ms]": P.OSF_HQP_SINGLE_THREAD[1].value,
            "paper ratio": P.OSF_HQP_SINGLE_THREAD[2].value,
            "ours conv. [ms]": _ms(vc),
            "ours OSF-HQP [ms]": _ms(vp),
            "ours ratio": _ratio(vc, vp),
        }
    )
    for _, r in prop.iterrows():
        if _config(r) == "":
            continue
        v = _metric(res, r["run_id"], "t_total_mean_us")
        rows.append(
            {
                "level": f"whole step, {_config(r)}",
                "our levels": "control loop",
                "paper conv. [ms]": np.nan,
                "paper OSF-HQP [ms]": P.OSF_HQP_TABLE3["proposed"][-1],
                "paper ratio": P.OSF_HQP_SINGLE_THREAD[3].value,
                "ours conv. [ms]": _ms(vc),
                "ours OSF-HQP [ms]": _ms(v),
                "ours ratio": _ratio(vc, v),
            }
        )
    t.frame = pd.DataFrame(rows)
    t.notes += [
        f"Means over the replayed ticks; solvers: conventional {c['solver']} ({c['mode']}), "
        f"OSF-HQP {p_run['solver']} ({p_run['mode']}). Per level: the whole call into our QP "
        "layer (validation, change detection, the solver's set-up or update, the native call); "
        "'solver only' leaves out our Python layer's share (the paper's includes formulating "
        "the QP).",
        _machines(res, "osf_hqp"),
        f"Source: {P.OSF_HQP_TABLE3_SOURCE}, §V.",
    ]
    return t


def osf_hqp_table2(res: Results) -> PaperTable:
    t = PaperTable(
        "osf_hqp_table2",
        "OSF-HQP Table II: OSF-HQP per-level time, min / max / average",
        "osf_hqp",
        None,
    )
    runs = _pick_timing(_runs(res, "timing", "lee2021iros_table1*", "osf_hqp"), "qpoases")
    if not runs.empty:
        t.notes.append(impl_note(runs))
    runs = runs[[_config(r) == "" for _, r in runs.iterrows()]] if not runs.empty else runs
    if runs.empty:
        t.missing = "Run timing of `osf_hqp` on `lee2021iros_table1`."
        return t
    r = runs.iloc[0]
    levels = _levels(res, r["run_id"])
    rows = []
    for i, label in enumerate(P.OSF_HQP_LEVELS):
        task = "*" if label == "total" else (levels[i] if i < len(levels) else None)
        row: dict[str, Any] = {"level": label, "our level": task or "-"}
        for stat, ours in (("min", "min"), ("max", "max"), ("average", "mean")):
            row[f"paper {stat} [ms]"] = P.OSF_HQP_TABLE2[stat][i]
            row[f"ours {stat} [ms]"] = (
                _ms(_metric(res, r["run_id"], f"t_solve_{ours}_us", task)) if task else np.nan
            )
        rows.append(row)
    t.frame = pd.DataFrame(rows)
    t.notes += [
        "Paper: the real robot (Table II); ours: replay of the simulated scenario.",
        _machines(res, "osf_hqp"),
    ]
    return t


# -- RC-LQP


RC_LQP_COLUMNS = [  # Table 3 column → (our metric per controller, label)
    ("avg", {"lqp": ["t_total_mean_us"], "rc_lqp": ["t_total_mean_us"]}),
    ("max", {"lqp": ["t_total_max_us"], "rc_lqp": ["t_total_max_us"]}),
    ("dyn", {"lqp": ["t_dynamics_mean_us"], "rc_lqp": ["t_dynamics_mean_us", "t_reduced_mean_us"]}),
    ("LQP1", {"rc_lqp": ["t_lqp1_mean_us"]}),
    ("LQP2", {"rc_lqp": ["t_lqp2_mean_us"]}),
    ("QP", {"lqp": ["t_solve_mean_us"], "rc_lqp": ["t_solve_mean_us"]}),
    (
        "QP solver only",
        {
            "lqp": ["t_solve_setup_mean_us", "t_solve_native_mean_us"],
            "rc_lqp": ["t_solve_setup_mean_us", "t_solve_native_mean_us"],
        },
    ),
]


def _support(spec: Any) -> str:
    return "double" if spec is not None and len(spec.contacts) >= 2 else "single"


#: RC-LQP's solver the paper's way (its library's OSQP setting), then the modern way (OSQP hot)
RC_LQP_SOLVERS = ("osqp_libdwbc", "osqp")


def _pick_rc_lqp(runs: pd.DataFrame) -> pd.DataFrame:
    """The Table 3 runs: one per scenario × controller for each of :data:`RC_LQP_SOLVERS` the
    results hold (the paper's way and the modern way side by side), else the usual pick; one impl
    for all."""
    runs = _one_impl(runs)
    present = [s for s in RC_LQP_SOLVERS if (runs["solver"] == s).any()]
    if not present:
        return _pick_timing(runs, "osqp", "lqp")
    return pd.concat([_pick_timing(runs[runs["solver"] == s], s, "lqp") for s in present])


def rc_lqp_table3(res: Results) -> PaperTable:
    t = PaperTable(
        "rc_lqp_table3",
        "RC-LQP Table 3: conventional LQP vs reduced-centroidal LQP",
        "rc_lqp",
        None,
    )
    runs = _runs(res, "timing", "ahn_*")
    if not runs.empty:
        runs = runs[[("dof" not in str(s)) for s in runs["scenario"]]]
        runs = _pick_rc_lqp(runs[runs["controller"].isin(["lqp", "rc_lqp"])])
        if not runs.empty:
            t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = (
            "Run timing of `lqp` and `rc_lqp` on the `ahn_*` double- and single-support scenarios "
            "(`record_with: [lqp]`)."
        )
        return t
    rows = []
    intervals: dict[tuple[str, str], dict[str, tuple[float, float]]] = {}
    for _, r in runs.iterrows():
        support = _support(scenario_spec(res, r["scenario"]))
        controller = str(r["controller"])
        method = "conventional" if controller == "lqp" else "proposed"
        ci = (
            _metric(res, r["run_id"], "t_total_median_ci_lo_us"),
            _metric(res, r["run_id"], "t_total_median_ci_hi_us"),
        )
        intervals.setdefault((support, str(r["solver"])), {})[controller] = ci
        paper = P.RC_LQP_TABLE3.get((support, method), {})
        row: dict[str, Any] = {
            "support": support,
            "solver": r["solver"],
            "method": f"{method} ({controller})",
            "run": f"{r['solver']} {r['mode']}, recorded by {_recorder(r) or '?'}, {r['status']}",
        }
        for column, metrics in RC_LQP_COLUMNS:
            names = metrics.get(controller)
            values = [_metric(res, r["run_id"], m) for m in names] if names else []
            row[f"paper {column} [µs]"] = paper.get(column)
            row[f"ours {column} [µs]"] = float(np.sum(values)) if values else np.nan
        rows.append(row)
    order = {s: i for i, s in enumerate(RC_LQP_SOLVERS)}
    frame = pd.DataFrame(rows).sort_values(["support", "method"], kind="stable")
    # one ratio per support, or per support × solver when the paper's way and the modern way
    # are both there
    side_by_side = frame["solver"].isin(RC_LQP_SOLVERS).all() and frame["solver"].nunique() > 1
    group = frame["solver"] if side_by_side else pd.Series("", index=frame.index)
    ratios = []
    for (support_key, solver), g in frame.groupby([frame["support"], group], sort=False):
        support = str(support_key)
        conv = g[g["method"].str.startswith("conventional")]
        prop = g[g["method"].str.startswith("proposed")]
        if not (len(conv) and len(prop)):
            continue
        ratio: dict[str, Any] = {
            "support": support,
            "solver": solver,
            "method": "ratio lqp / rc_lqp",
            "run": "",
        }
        for column in ("avg", "max", "QP", "QP solver only"):
            pc = P.RC_LQP_TABLE3[(support, "conventional")].get(column, np.nan)
            pp = P.RC_LQP_TABLE3[(support, "proposed")].get(column, np.nan)
            ratio[f"paper {column} [µs]"] = pc / pp
            ratio[f"ours {column} [µs]"] = _ratio(
                float(conv[f"ours {column} [µs]"].iloc[0]),
                float(prop[f"ours {column} [µs]"].iloc[0]),
            )
        ratios.append(ratio)
    both = pd.concat([frame, pd.DataFrame(ratios)], ignore_index=True)
    both = both.assign(_s=[order.get(s, len(order)) for s in both["solver"]])
    t.frame = both.sort_values(["support", "_s"], kind="stable").drop(columns="_s")
    t.frame = t.frame.reset_index(drop=True)
    t.notes += [
        "Ratio rows are unitless (conventional / proposed, the paper's speed-up).",
        "Solvers: `osqp_libdwbc` is OSQP the way the paper's library runs it (eps 1e-3, alpha "
        "1.0, warm-started, matrices re-sent every tick), `osqp` OSQP hot at its defaults; the "
        "table has both when the results do (the paper's way first).",
        "Ours: means and maxima of the replayed ticks, the paper's solver (OSQP) when timed; "
        "dyn = the dynamics stage (+ the reduced-dynamics calculation for rc_lqp); LQP1 / LQP2 = "
        "each lexicographic QP's formulation and solve; QP = every call into our QP layer; "
        "QP solver only = the solvers' set-up and native calls (the part the reduced QP sizes "
        "shrink; the rest of a step is Python formulation, see the README's limitations).",
        "Timing runs replay the states of the paper's baseline (`lqp`) when it was recorded.",
        *_overlap_notes(intervals),
        _machines(res, "rc_lqp"),
        f"Source: {P.RC_LQP_TABLE3_SOURCE}.",
    ]
    return t


def _overlap_notes(intervals: dict[tuple[str, str], dict[str, tuple[float, float]]]) -> list[str]:
    """Whether lqp's and rc_lqp's median step intervals (95 %) overlap, per support × solver."""
    notes = []
    for (support, solver), ci in intervals.items():
        if {"lqp", "rc_lqp"} <= set(ci) and all(np.isfinite(v) for c in ci.values() for v in c):
            (a0, a1), (b0, b1) = ci["lqp"], ci["rc_lqp"]
            apart = a1 < b0 or b1 < a0
            notes.append(
                f"{support}, {solver}: median step intervals lqp [{a0:.0f}, {a1:.0f}] µs and "
                f"rc_lqp [{b0:.0f}, {b1:.0f}] µs "
                + ("do not overlap: the difference is real." if apart else "overlap: within noise.")
            )
    return notes


def rc_lqp_dof(res: Results) -> PaperTable:
    t = PaperTable(
        "rc_lqp_dof",
        "RC-LQP DoF scaling (double support): conventional vs reduced-centroidal",
        "rc_lqp",
        None,
    )
    runs = _runs(res, "timing", "ahn_*dof*")
    if not runs.empty:
        runs = _pick_timing(runs[runs["controller"].isin(["lqp", "rc_lqp"])], "osqp", "lqp")
        if not runs.empty:
            t.notes.append(impl_note(runs))
    if runs.empty:
        t.missing = (
            "Run timing of `lqp` and `rc_lqp` on `ahn_dof_scaling` for each robot of the DoF "
            "family (`robots: [tocabi_dof20, …, tocabi_dof45]` in a timing matrix)."
        )
        return t
    rows: dict[int, dict[str, Any]] = {}
    for _, r in runs.iterrows():
        dof = _robot_dof(str(r["robot"]))
        paper = P.RC_LQP_DOF.get(dof, {})
        row = rows.setdefault(
            dof,
            {
                "DoF": dof,
                "robot": r["robot"],
                "paper conventional [µs]": paper.get("conventional"),
                "paper proposed [µs]": paper.get("proposed"),
                "ours lqp median [µs]": np.nan,
                "ours rc_lqp median [µs]": np.nan,
                "status": "",
            },
        )
        row[f"ours {r['controller']} median [µs]"] = _metric(res, r["run_id"], "t_total_median_us")
        if r["status"] != "ok":
            row["status"] = f"{row['status']} {r['controller']}: {_run_status(r)}".strip()
    frame = pd.DataFrame([rows[k] for k in sorted(rows)])
    frame["status"] = frame["status"].replace("", "ok")
    frame["paper ratio"] = frame["paper conventional [µs]"] / frame["paper proposed [µs]"]
    frame["ours ratio"] = frame["ours lqp median [µs]"] / frame["ours rc_lqp median [µs]"]
    t.frame = frame
    t.notes += [
        "Ratios: conventional (lqp) / proposed (rc_lqp). Ours: medians of the replayed ticks "
        "(whole step), the paper's solver (OSQP) when timed.",
        "The paper's text gives the 20 and 45 DoF end points (Fig. 5).",
        _machines(res, "rc_lqp"),
        f"Source: {P.RC_LQP_DOF_SOURCE}.",
    ]
    return t


# -- RQR-HQP


#: the paper's Fig. 1 ordering, fastest first
FIG1_ORDER = ("reduced_qr", "full_qr", "svd")


def _fig1_order(times: dict[str, float]) -> str:
    """``reduced < full < svd`` style ordering of one N's medians, and whether it is the
    paper's."""
    present = {a: t for a, t in times.items() if np.isfinite(t)}
    if len(present) < len(FIG1_ORDER):
        return ""
    order = sorted(present, key=present.__getitem__)
    text = " < ".join(a.removesuffix("_qr") for a in order)
    return f"{text} ({'as' if tuple(order) == FIG1_ORDER else 'not as'} Fig. 1)"


def rqr_fig1(res: Results) -> PaperTable:
    from wbcbench.bench.timing import HLS_SCENARIO

    t = PaperTable("rqr_fig1", "RQR-HQP Fig. 1: hierarchy time vs problem size N", "rqr_hqp", None)
    runs = _runs(res, "timing", HLS_SCENARIO)
    if runs.empty:
        t.missing = "Run a sweep with an `hls_scaling` section (`sweeps/default.yaml` has one)."
        return t
    # rows of results made before the native series have no impl: the Python reference's
    impls_of_runs = runs["impl"] if "impl" in runs else pd.Series([""] * len(runs))
    impl_of = {
        rid: (impl if isinstance(impl, str) and impl else "python")
        for rid, impl in zip(runs["run_id"], impls_of_runs, strict=True)
    }
    m = res.metrics[
        res.metrics["run_id"].isin(runs["run_id"]) & (res.metrics["metric"] == "t_solve_median_us")
    ].copy()
    m["impl"] = m["run_id"].map(impl_of)
    wide = m.pivot_table(
        index="task", columns=["impl", "controller"], values="value", aggfunc="first"
    )
    wide.index = [int(str(i).split("=")[1]) for i in wide.index]
    wide = wide.sort_index()
    frame = pd.DataFrame({"N": wide.index})
    impls = [i for i in ("native", "python") if i in wide.columns.get_level_values(0)]
    algos = [a for a in FIG1_ORDER if a in wide.columns.get_level_values(1)]
    for impl in impls:
        for algo in algos:
            if (impl, algo) in wide.columns:
                frame[f"{algo} {impl} median [µs]"] = wide[(impl, algo)].to_numpy()
    for impl in impls:
        if (impl, "reduced_qr") not in wide.columns:
            continue
        for algo in algos[1:]:
            if (impl, algo) in wide.columns:
                ratio = wide[(impl, algo)] / wide[(impl, "reduced_qr")]
                frame[f"{algo} / reduced_qr ({impl})"] = ratio.to_numpy()
        frame[f"ordering ({impl})"] = [
            _fig1_order({a: float(row.get((impl, a), np.nan)) for a in FIG1_ORDER})
            for _, row in wide.iterrows()
        ]
    t.frame = frame
    t.notes += [
        P.RQR_FIG1_NOTE,
        "native: the C++ mirror of the three algorithms, timed inside the module (no "
        "interpreter); python: the reference, timed around the call. `ordering` gives each "
        "N's medians fastest first and whether that is the paper's (reduced QR < full-size QR "
        "< SVD).",
        _machines(res, "rqr_hqp"),
    ]
    return t


TABLES: dict[str, Callable[[Results], PaperTable]] = {
    "to_osf_s1": to_osf_s1,
    "to_osf_pinv": to_osf_pinv,
    "to_osf_s2": to_osf_s2,
    "to_osf_s4": to_osf_s4,
    "to_osf_cod_svd": to_osf_cod_svd,
    "to_osf_table3": to_osf_table3,
    "osf_hqp_table3": osf_hqp_table3,
    "osf_hqp_table2": osf_hqp_table2,
    "rc_lqp_table3": rc_lqp_table3,
    "rc_lqp_dof": rc_lqp_dof,
    "rqr_fig1": rqr_fig1,
}


def build_tables(res: Results | str | Path) -> list[PaperTable]:
    """Every paper table from a results folder (or loaded results)."""
    if not isinstance(res, Results):
        res = load_results(res)
    out = []
    for name, fn in TABLES.items():
        try:
            out.append(fn(res))
        except Exception as exc:  # one table's bug must not hide the others
            out.append(PaperTable(name, name, "", None, missing=f"could not be built: {exc}"))
    return out


def write_tables(folder: str | Path) -> Path:
    """``tables/<name>.md`` and ``.csv`` for each table, and ``tables/papers.md`` with all."""
    res = load_results(folder)
    out = Path(folder) / "tables"
    out.mkdir(exist_ok=True)
    tables = build_tables(res)
    parts = [
        "# The papers' numbers beside ours",
        "",
        f"Our results: {res.machine}; wbcbench {res.provenance.get('wbcbench', '?')} @ "
        f"{res.provenance.get('git_commit', '?')}, {res.provenance.get('date', '?')}. "
        "Compare ratios; absolute times come from different CPUs and languages (the papers: C++).",
        "",
    ]
    from wbcbench.report.verdicts import markdown, verdicts

    verdict_frame = verdicts(tables)
    verdict_frame.to_csv(out / "verdicts.csv", index=False)
    (out / "verdicts.md").write_text(markdown(verdict_frame))
    parts.append(markdown(verdict_frame))
    for table in tables:
        md = table.markdown()
        (out / f"{table.name}.md").write_text(md)
        if table.frame is not None:
            table.frame.to_csv(out / f"{table.name}.csv", index=False)
        parts.append(md)
    path = out / "papers.md"
    path.write_text("\n".join(parts))
    (out / "index.json").write_text(
        json.dumps(
            {t.name: {"title": t.title, "has_results": t.frame is not None} for t in tables},
            indent=2,
        )
        + "\n"
    )
    return path
