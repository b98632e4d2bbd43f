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
from wbcbench.sim.replay import Recording, Replayer, record_states, replay

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


def timing_groups(jobs: list[tuple[Job, str]]) -> list[list[tuple[Job, str]]]:
    """The timing jobs in the groups that are timed together, in plan order: the rows of one
    scenario (same robot and overrides), window (start, ticks, warm-up, recorder), solver,
    tier, mode and impl, which differ in the controller or its configuration (or in a budget
    such as ``max_step_ms``), interleave in blocks (the ``interleave`` option, in ticks). A row
    with ``interleave: 0`` is timed alone."""
    groups: dict[str, list[tuple[Job, str]]] = {}
    for job, rid in jobs:
        s = job.run.settings
        block = int(job.options.get("interleave", 0))
        if not block:
            groups[rid] = [(job, rid)]
            continue
        window = [job.options.get(k) for k in ("start", "ticks", "warmup", "recorder")]
        key = json.dumps(
            [job.run.scenario.hash, s.solver, s.tier, s.mode, job.run.impl, window, block],
            default=str,
        )
        groups.setdefault(key, []).append((job, rid))
    return list(groups.values())


def group_id(rids: list[str]) -> str:
    """A short name of a group of timing rows timed together (from their run ids)."""
    import hashlib

    return hashlib.sha256(" ".join(sorted(rids)).encode()).hexdigest()[:12]


def guarded_timing_group(
    group: list[tuple[Job, str]], version: str, folder: str | Path
) -> list[RunRecord]:
    """:func:`run_timing_group` in a child process under the wall-clock guard
    (:mod:`wbcbench.bench.guard`). When the group's child hangs or crashes, each of its rows is
    timed again alone, so that only the row that hangs or crashes becomes a ``failed`` row."""
    from wbcbench.bench.guard import call_with_deadline, can_guard, timing_deadline
    from wbcbench.bench.results import printed_path

    if not can_guard():
        return run_timing_group(group, version, folder)
    job, rid = group[0]
    loaded, opts = job.run.scenario, job.options
    ticks, start = int(opts["ticks"]), float(opts["start"])
    end = min(loaded.spec.duration, start + ticks * loaded.spec.dt)
    cached = recording_path(Path(folder), loaded, opts["recorder"], end).exists()
    recorded = 0 if cached else round(end / loaded.spec.dt)
    limit = opts.get("wall_limit_s")
    # each row's own guard, the closed-loop recording counted once
    seconds = sum(
        limit or timing_deadline(ticks, recorded if k == 0 else 0) for k in range(len(group))
    )
    doing = f"solver {job.run.settings.solver}"  # one solver per group
    printed = printed_path(
        folder, rid if len(group) == 1 else f"group-{group_id([r for _, r in group])}"
    )
    outcome = call_with_deadline(
        run_timing_group, (group, version, str(folder)), seconds, printed, doing=doing
    )
    if outcome.ok:
        records: list[RunRecord] = outcome.value
        return records
    if len(group) > 1:  # time each alone: the one that hangs or crashes fails, the rest are kept
        return [r for member in group for r in guarded_timing_group([member], version, folder)]
    return [ended_record(job.run, rid, version, "failed", outcome.message, "timing", job.extra)]


class TimedRow:
    """One timing row of a group: its replayer, the checks after each step, and its row."""

    def __init__(self, job: Job, rid: str, version: str, folder: str | Path) -> None:
        self.job, self.rid, self.folder = job, rid, folder
        self.row = base_row(job.run, rid, version, "timing", job.extra)
        self.pairs: list[tuple[Problem, Solution]] = []
        self.totals: list[float] = []
        self.replayer: Replayer | None = None
        self.rec: Recording | None = None
        self.seconds = 0.0  # wall time of its own set-up and steps [s]
        self.ended = False  # stopped early: skipped (too slow) or an error

    @property
    def done(self) -> int:
        """Ticks stepped."""
        return self.replayer.done if self.replayer is not None else 0

    @property
    def running(self) -> bool:
        return (
            self.replayer is not None and not self.ended and self.replayer.done < len(self.replayer)
        )

    def prepare(self) -> None:
        """Load (or record) the states and build the controller; an error ends the row."""
        opts = self.job.options
        t0 = time.perf_counter()
        try:
            rec, recorder = recording_for(self.folder, self.job.run.scenario, opts)
            if recorder != opts["recorder"]:  # the row says whose states it replayed
                self.row["settings"] = json.dumps(
                    {**json.loads(self.row["settings"]), "recorder": recorder}, sort_keys=True
                )
            if len(rec) <= int(opts["warmup"]):
                raise WbcBenchError(
                    f"the recording by {recorder} has {len(rec)} states from "
                    f"t = {opts['start']:g} s (it ended early: the recorder fell or failed); "
                    "set `record_with` or `start` in the timing matrix"
                )
            self.rec = rec
            self.replayer = Replayer(
                self.job.run,
                rec,
                on_step=self.after_step,
                wrap_solver=lambda handle: SolverCapture(handle, self.pairs),
            )
        except Exception as exc:  # one broken combination must not end the sweep
            self.end(exc)
        self.seconds += time.perf_counter() - t0

    def after_step(self, i: int, out: Any) -> str:
        opts = self.job.options
        probe, limit = int(opts["probe_ticks"]), float(opts["max_step_ms"]) * 1e-3
        self.totals.append(out.timings.get("total", np.nan))
        if i + 1 == probe and float(np.nanmedian(self.totals)) > limit:
            raise TooSlow(
                f"median step {1e3 * float(np.nanmedian(self.totals)):.1f} ms over the first "
                f"{probe} ticks exceeds max_step_ms = {1e3 * limit:g} ms"
            )
        check_factor = opts.get("check_factor")
        message = check_reported(self.pairs, check_factor) if check_factor else ""
        self.pairs.clear()
        return message

    def step_block(self, first: int, last: int) -> None:
        """Step ticks ``first`` … ``last - 1`` (as many as the recording has)."""
        assert self.replayer is not None
        t0 = time.perf_counter()
        try:
            for i in range(first, min(last, len(self.replayer))):
                self.replayer.step(i)
        except Exception as exc:
            self.end(exc)
        self.seconds += time.perf_counter() - t0

    def end(self, exc: BaseException) -> None:
        """End the row early: ``skipped`` when too slow, else ``error`` with the message."""
        self.ended = True
        if isinstance(exc, TooSlow):
            self.row.update(status="skipped", message=str(exc))
        elif isinstance(exc, WbcBenchError):
            self.row.update(status="error", message=str(exc))
        else:
            last = traceback.format_exception_only(type(exc), exc)[-1].strip()
            self.row.update(status="error", message=last)
        self.row.update(fell=False, ticks=0, failures=0)

    def record(self, conditions: dict[str, Any]) -> RunRecord:
        """The row, its statistics and its per-tick log (when kept)."""
        self.row["wall_time_s"] = round(self.seconds, 3)
        if self.ended or self.replayer is None or self.rec is None:
            return RunRecord(self.row, [], None, None)
        loaded, settings, opts = self.job.run.scenario, self.job.run.settings, self.job.options
        # the row says what the machine was doing (see run_timing_group)
        self.row["settings"] = json.dumps(
            {**json.loads(self.row["settings"]), "conditions": conditions}, sort_keys=True
        )
        timings = self.replayer.timings()
        ticks = len(self.rec)
        base = dict(scenario=loaded.name, controller=settings.controller, solver=settings.solver)
        warmup = min(int(opts["warmup"]), max(0, ticks - 1))
        metrics = [
            dict(run_id=self.rid, **base, **m) for m in timing_metrics(timings.stages, warmup)
        ]
        # any failed tick fails the row: its statistics stay in the metrics, the message says
        # how many ticks failed and why
        message = timings.message
        if timings.failures:
            message = f"{timings.failures} of {ticks} ticks failed; first: {message}"
        self.row.update(
            status="ok" if timings.failures == 0 else "failed",
            fell=False,
            message=message,
            ticks=ticks,
            sim_duration_s=ticks * loaded.spec.dt,
            failures=timings.failures,
        )
        log = None
        if opts.get("keep_log", True):
            log = {f"time.{k}": v for k, v in timings.stages.items()}
            log["t"] = self.rec.t[: len(next(iter(timings.stages.values()), []))]
        return RunRecord(self.row, metrics, None, log)


def step_interleaved(rows: list[TimedRow], block: int, total: int = 0) -> None:
    """Step ``rows`` in turns of ``block`` ticks until none is running; the row that goes
    first moves on by one each round, so that none always follows the same one."""
    first = 0
    while running := [r for r in rows if r.running]:
        shift = (first // block) % len(running)
        for r in running[shift:] + running[:shift]:
            r.step_block(first, first + block)
        first += block
        if total:
            report_progress(sum(r.done for r in rows), total)


def run_timing_group(
    group: list[tuple[Job, str]], version: str, folder: str | Path
) -> list[RunRecord]:
    """Replay the group's controller × solver × mode rows on the scenario's recorded window,
    interleaved: each steps ``interleave`` ticks in turn (the first to go rotating from block to
    block) until all are done, so that a change in the machine's speed (another process, the
    clock, the host of a virtual machine) falls on every row of the group alike and their
    ratios hold. A row alone steps straight through. Never raises."""
    watch = CpuWatch()  # the rest of the machine's CPU use from here to the replays' end
    rows = [TimedRow(job, rid, version, folder) for job, rid in group]
    for r in rows:
        r.prepare()
    block = int(group[0][0].options.get("interleave", 0)) or max(
        (len(r.replayer) for r in rows if r.replayer is not None), default=1
    )
    total = sum(len(r.replayer) for r in rows if r.replayer is not None)
    load_before = round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else float("nan")
    probe_before = speed_probe()
    step_interleaved(rows, block, total)
    # the rows say what the machine was doing: the rest of the machine's CPU use over the
    # group, the load average before and after the replays, how fast a fixed workload ran just
    # before and just after them, and which rows were timed together
    conditions: dict[str, Any] = {
        **machine_conditions(watch),
        "load_1min_before": load_before,
        "speed_probe_ms": [probe_before, speed_probe()],
    }
    if len(rows) > 1:
        conditions["interleaved"] = {
            "group": group_id([rid for _, rid in group]),
            "rows": len(rows),
            "block_ticks": block,
        }
    # a busy machine is said once per sweep (SweepReport.busy_line), not per row
    return [r.record(conditions) for r in rows]


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
