"""Timing runs: every controller × solver replays exactly the same recorded states.

Protocol (docs/timing.md): states of one closed-loop run per scenario are recorded once and cached
next to the results (``recordings/<scenario>-<hash>-<recorder>-<end>.npz``; when the planned
recorder falls or fails inside the window, the next of the matrix's ``record_with`` that applies
records it, and the rows name the recorder they replayed); each controller ×
solver × mode then steps a fresh controller through the same window of ``ticks`` states, open
loop, serially, with one BLAS thread. The first ``warmup`` ticks are discarded. For every stage
(``dynamics``, ``build``, ``solve``, ``solve_internal``, ``total``, and whatever further stages a
controller reports) and every hierarchy level (``solve.<level>``): median, IQR, p99, max, mean,
min and the deadline-miss rate at 1 kHz.

After each timed step (outside the timed region) every QP the solver reported ``solved`` is
checked independently (:mod:`wbcbench.bench.checks`): KKT residuals above ``check_factor`` ×
the accuracy the tier asks of the backend mark the tick failed with the message ``reported
solved but …``.
"""

from __future__ import annotations

import json
import os
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from wbcbench.bench.checks import SolverCapture, check_reported
from wbcbench.bench.guard import report_progress
from wbcbench.bench.provenance import CpuWatch, machine_conditions, speed_probe
from wbcbench.bench.runner import RunRecord, base_row, ended_record
from wbcbench.bench.sweep import HlsScalingSpec, Job
from wbcbench.errors import WbcBenchError
from wbcbench.metrics.timing import timing_stats
from wbcbench.qp import Problem, Solution
from wbcbench.runs import Run, plan_run
from wbcbench.scenarios.load import LoadedScenario
from wbcbench.sim.replay import Recording, record_states, replay

HLS_SCENARIO = "rqr_fig1_stack"


class TooSlow(WbcBenchError):
    """A combination exceeded the sweep's per-tick budget; it is recorded as skipped."""


# -- recordings


def recording_path(folder: Path, loaded: LoadedScenario, recorder: str, end: float) -> Path:
    return folder / "recordings" / f"{loaded.name}-{loaded.hash}-{recorder}-{end:g}s.npz"


def cached_recording(
    folder: str | Path, loaded: LoadedScenario, recorder: str, start: float, ticks: int
) -> Recording:
    """The recorded states of ``loaded`` from ``start`` for ``ticks`` ticks (recorded once).

    The closed-loop recording runs only up to the end of the window, with ``recorder`` and the
    default solver; it is cached on disk, keyed by the scenario hash, recorder and end time.
    """
    end = min(loaded.spec.duration, start + ticks * loaded.spec.dt)
    path = recording_path(Path(folder), loaded, recorder, end)
    if path.exists():
        rec = Recording.load(path)
    else:
        overrides = [*loaded.overrides, f"duration={end:.6g}"]
        rec = record_states(plan_run(loaded.path, recorder, overrides=overrides))
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        rec.save(tmp)
        tmp.replace(path)  # atomic: an interrupted recording leaves no half file
    return rec.window(start, ticks)


def recording_for(
    folder: str | Path, loaded: LoadedScenario, options: dict[str, Any]
) -> tuple[Recording, str]:
    """The window of the planned recorder (``options["recorder"]``), or of the first of
    ``options["fallback_recorders"]`` whose run covers it when the planned one fell or failed
    inside it; with none covering it, the longest. Returns the recording and its recorder."""
    recorders = [options["recorder"], *options.get("fallback_recorders", [])]
    start, ticks = float(options["start"]), int(options["ticks"])
    best: tuple[Recording, str] | None = None
    for name in recorders:
        rec = cached_recording(folder, loaded, name, start, ticks)
        if len(rec) >= ticks:
            return rec, name
        if best is None or len(rec) > len(best[0]):
            best = (rec, name)
    assert best is not None
    return best


# -- timing rows


def timing_metrics(stages: dict[str, np.ndarray], warmup: int) -> list[dict[str, Any]]:
    """Long-form statistics per stage (task ``*``) and per level (task = level name)."""
    rows: list[dict[str, Any]] = []
    for key, samples in stages.items():
        stage, _, level = key.partition(".")
        x = np.asarray(samples, dtype=float)[warmup:]
        stats = timing_stats(x)
        finite = x[np.isfinite(x)]
        stats["min_us"] = 1e6 * float(finite.min()) if finite.size else float("nan")
        for name, value in stats.items():
            metric = f"t_{stage}_miss_rate" if name == "miss_rate" else f"t_{stage}_{name}"
            unit = "-" if name == "miss_rate" else "us"
            rows.append(dict(task=level or "*", metric=metric, value=value, unit=unit))
    return rows


def skipped_record(job: Job, rid: str, version: str, reason: str) -> RunRecord:
    return ended_record(job.run, rid, version, "skipped", reason, job.kind, job.extra)


def guarded_timing_job(job: Job, rid: str, version: str, folder: str | Path) -> RunRecord:
    """:func:`run_timing_job` in a child process under the wall-clock guard
    (:mod:`wbcbench.bench.guard`): a run that hangs or crashes becomes a ``failed`` row."""
    from wbcbench.bench.guard import call_with_deadline, can_guard, timing_deadline
    from wbcbench.bench.results import printed_path

    if not can_guard():
        return run_timing_job(job, rid, version, folder)
    loaded, opts = job.run.scenario, job.options
    ticks, start = int(opts["ticks"]), float(opts["start"])
    end = min(loaded.spec.duration, start + ticks * loaded.spec.dt)
    cached = recording_path(Path(folder), loaded, opts["recorder"], end).exists()
    recorded = 0 if cached else round(end / loaded.spec.dt)
    seconds = opts.get("wall_limit_s") or timing_deadline(ticks, recorded)
    args = (job, rid, version, str(folder))
    doing = f"solver {job.run.settings.solver}"
    printed = printed_path(folder, rid)
    outcome = call_with_deadline(run_timing_job, args, seconds, printed, doing=doing)
    if outcome.ok:
        record: RunRecord = outcome.value
        return record
    return ended_record(job.run, rid, version, "failed", outcome.message, "timing", job.extra)


def run_timing_job(job: Job, rid: str, version: str, folder: str | Path) -> RunRecord:
    """Replay one controller × solver × mode on the scenario's recorded window; never raises."""
    loaded = job.run.scenario
    opts = job.options
    row = base_row(job.run, rid, version, "timing", job.extra)
    settings = job.run.settings
    base = dict(scenario=loaded.name, controller=settings.controller, solver=settings.solver)
    metrics: list[dict[str, Any]] = []
    log = None
    pairs: list[tuple[Problem, Solution]] = []
    totals: list[float] = []
    probe, limit = int(opts["probe_ticks"]), float(opts["max_step_ms"]) * 1e-3
    check_factor = opts.get("check_factor")

    def after_step(i: int, out: Any) -> str:
        report_progress(i + 1, int(opts["ticks"]))
        totals.append(out.timings.get("total", np.nan))
        if i + 1 == probe and float(np.nanmedian(totals)) > limit:
            raise TooSlow(
                f"median step {1e3 * float(np.nanmedian(totals)):.1f} ms over the first "
                f"{probe} ticks exceeds max_step_ms = {1e3 * limit:g} ms"
            )
        message = check_reported(pairs, check_factor) if check_factor else ""
        pairs.clear()
        return message

    wall0 = time.perf_counter()
    watch = CpuWatch()  # the rest of the machine's CPU use from here to the replay's end
    try:
        rec, recorder = recording_for(folder, loaded, opts)
        if recorder != opts["recorder"]:  # the row says whose states it replayed
            row["settings"] = json.dumps(
                {**json.loads(row["settings"]), "recorder": recorder}, sort_keys=True
            )
        if len(rec) <= int(opts["warmup"]):
            raise WbcBenchError(
                f"the recording by {recorder} has {len(rec)} states from "
                f"t = {opts['start']:g} s (it ended early: the recorder fell or failed); "
                "set `record_with` or `start` in the timing matrix"
            )
        load_before = round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else float("nan")
        probe_before = speed_probe()
        timings = replay(
            job.run,
            rec,
            on_step=after_step,
            wrap_solver=lambda handle: SolverCapture(handle, pairs),
        )
        # the row says what the machine was doing: the rest of the machine's CPU use over the
        # job, the load average before and after the replay, and how fast a fixed workload ran
        # just before and just after it
        conditions = {
            **machine_conditions(watch),
            "load_1min_before": load_before,
            "speed_probe_ms": [probe_before, speed_probe()],
        }
        row["settings"] = json.dumps(
            {**json.loads(row["settings"]), "conditions": conditions}, sort_keys=True
        )
        # a busy machine is said once per sweep (SweepReport.busy_line), not per row
        warmup = min(int(opts["warmup"]), max(0, len(rec) - 1))
        for m in timing_metrics(timings.stages, warmup):
            metrics.append(dict(run_id=rid, **base, **m))
        ticks = len(rec)
        # any failed tick fails the row: its statistics stay in the metrics, the message says
        # how many ticks failed and why
        status = "ok" if timings.failures == 0 else "failed"
        message = timings.message
        if timings.failures:
            message = f"{timings.failures} of {ticks} ticks failed; first: {message}"
        row.update(
            status=status,
            fell=False,
            message=message,
            ticks=ticks,
            sim_duration_s=ticks * loaded.spec.dt,
            failures=timings.failures,
        )
        if opts.get("keep_log", True):
            log = {f"time.{k}": v for k, v in timings.stages.items()}
            log["t"] = rec.t[: len(next(iter(timings.stages.values()), []))]
    except TooSlow as exc:
        row.update(status="skipped", fell=False, message=str(exc), ticks=0, failures=0)
    except WbcBenchError as exc:
        row.update(status="error", fell=False, message=str(exc), ticks=0, failures=0)
    except Exception as exc:  # one broken combination must not end the sweep
        last = traceback.format_exception_only(type(exc), exc)[-1].strip()
        row.update(status="error", fell=False, message=last, ticks=0, failures=0)
    row["wall_time_s"] = round(time.perf_counter() - wall0, 3)
    return RunRecord(row, metrics, None, log)


# -- QP dumps for the solver comparison


def dump_problems(
    folder: str | Path,
    run: Run,
    options: dict[str, Any],
    after: int,
    ticks: int,
) -> list[Path]:
    """Save the QPs of ``ticks`` consecutive replayed steps of ``run`` (after ``after`` ticks)
    as .npz.

    Files go to ``problems/<scenario>-<hash>/<controller>/t<tick>-<k>.npz``, and the QPs of the
    tick before the first as ``prime-t<tick>-<k>.npz``: the solver comparison solves those first,
    unrecorded, so that a warm or hot sequence starts from the previous tick's solution or
    solver object as the controller's handle did, not cold. An existing folder is reused as is.
    Returns the recorded files (not the primers) in tick order.
    """
    loaded, controller = run.scenario, run.controller
    target = Path(folder) / "problems" / f"{loaded.name}-{loaded.hash}" / controller
    if (target / "done").exists():
        return sorted(target.glob("t*.npz"))
    target.mkdir(parents=True, exist_ok=True)
    rec, _ = recording_for(folder, loaded, options)
    n = after + ticks
    rec = Recording(rec.scenario, rec.t[:n], rec.q[:n], rec.v[:n])
    saved: list[Path] = []
    # every QP the controller hands to a solver handle, whatever the controller
    pairs: list[tuple[Problem, Solution]] = []

    def keep(i: int, out: Any) -> str:
        captured = [problem for problem, _ in pairs]
        pairs.clear()
        if i < after - 1:
            return ""
        primer = i == after - 1
        for k, problem in enumerate(captured):
            problem.meta = {
                **problem.meta,
                "scenario": loaded.name,
                "scenario_hash": loaded.hash,
                "controller": controller,
                "robot": loaded.spec.robot,
                "dt": loaded.spec.dt,
                "tick": i,
                "index": k,
                **({"primer": True} if primer else {}),
            }
            path = target / f"{'prime-' if primer else ''}t{i:05d}-{k:02d}.npz"
            part = path.with_name(f".{path.name}")  # atomic: a kill leaves no half file
            problem.save(part)
            os.replace(part, path)
            if not primer:
                saved.append(path)
        return ""

    replay(run, rec, on_step=keep, wrap_solver=lambda handle: SolverCapture(handle, pairs))
    (target / "done").write_text(json.dumps({"files": len(saved)}) + "\n")
    return saved


# -- RQR-HQP Fig. 1


def run_hls_scaling(spec: HlsScalingSpec, store: Any, version: str) -> None:
    """Time reduced QR vs full-size QR vs SVD hierarchies against N; one row per algorithm and
    impl (``impl`` column; a native row is ``skipped`` where the module is not built)."""
    import hashlib

    from wbcbench import _native
    from wbcbench.qp.hls_baselines import ALGORITHMS, scaling_series

    settings = {"kind": "hls_scaling", "sizes": spec.sizes, "repeats": spec.repeats}
    done = store.done_run_ids()
    todo: list[tuple[str, str, str]] = []  # (algorithm, impl, run id)
    for wanted in spec.impls:
        for algorithm in ALGORITHMS:
            key = json.dumps([HLS_SCENARIO, algorithm, wanted, settings, version], sort_keys=True)
            rid = hashlib.sha256(key.encode()).hexdigest()[:16]
            if rid not in done:
                todo.append((algorithm, wanted, rid))
    if not todo:
        return
    runnable = sorted({impl for _, impl, _ in todo if impl == "python" or _native.BUILT})
    # one interleaved series for every algorithm and impl
    t0 = time.perf_counter()
    series = scaling_series(spec.sizes, repeats=spec.repeats, impls=runnable) if runnable else []
    wall = time.perf_counter() - t0
    for algorithm, impl, rid in todo:
        base = dict(scenario=HLS_SCENARIO, controller=algorithm, solver="-")
        metrics = []
        for r in series:
            if (r["algorithm"], r["impl"]) != (algorithm, impl):
                continue
            task = f"N={r['N']}"
            for name, value, unit in (
                ("t_solve_median_us", 1e6 * r["median_s"], "us"),
                ("t_solve_p25_us", 1e6 * r["p25_s"], "us"),
                ("t_solve_p75_us", 1e6 * r["p75_s"], "us"),
                ("t_call_median_us", 1e6 * r["call_median_s"], "us"),
                ("max_abs_diff", r["max_abs_diff"], "-"),
            ):
                metrics.append(
                    dict(run_id=rid, **base, task=task, metric=name, value=value, unit=unit)
                )
        ok = impl in runnable
        row = dict(
            run_id=rid,
            scenario=HLS_SCENARIO,
            scenario_hash="",
            robot="-",
            controller=algorithm,
            controller_config="{}",
            solver="-",
            tier="-",
            mode="-",
            impl=impl,
            seed=0,
            status="ok" if ok else "skipped",
            fell=False,
            message="" if ok else f"native module {_native.REASON}",
            ticks=0,
            wall_time_s=round(wall, 3),
            failures=0,
            code_version=version,
            kind="timing",
            settings=json.dumps(settings, sort_keys=True),
        )
        store.add_run(row, metrics)
