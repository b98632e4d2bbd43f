"""Run scenario × controller × solver combinations and record each as it finishes.

A run that raises, or whose solver keeps failing, becomes a row with status ``failed`` or
``error`` and its message; the other runs go on. A run already in the store (same scenario hash,
settings and code version) is skipped, so an interrupted command resumes where it stopped.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import platform
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from wbcbench.bench.checks import CHECK_FACTOR, ReportedCheck
from wbcbench.bench.provenance import cpu_model
from wbcbench.bench.results import ResultsStore
from wbcbench.bench.run_metrics import run_metrics
from wbcbench.errors import WbcBenchError
from wbcbench.runs import Run
from wbcbench.scenarios.load import build_contacts
from wbcbench.scenarios.schema import PerturbationsSpec
from wbcbench.sim.closed_loop import RunResult, run_closed_loop


def code_version(store: ResultsStore) -> str:
    """``<version>+src.<source hash>@<commit>[+dirty]``: the code a row was measured with.

    The part before ``@`` (package version and the content hash of its code, uncommitted
    edits included) is what :func:`run_id` keys on: any edit of the code recomputes a row,
    while a commit or an edit that touches only docs or tests resumes it.
    """
    info = store.provenance
    return f"{info['wbcbench']}+src.{info['source_hash']}@{info['git_commit']}"


def run_id(
    run: Run,
    version: str,
    seed: int = 0,
    extra: dict[str, Any] | None = None,
) -> str:
    """The key a rerun skips by; ``extra`` holds any further setting (e.g. a timing window)."""
    settings = run.settings
    seed = seed or run.scenario.spec.perturbations.seed
    parts: list[Any] = [
        run.scenario.name,
        run.scenario.hash,  # covers the perturbations too
        settings.controller,
        settings.controller_config,
        settings.solver,
        settings.tier,
        settings.mode,
        seed,
        version.split("@", 1)[0],
        run.impl,
    ]
    if extra:  # absent for plain tracking runs, so their ids stay what they were
        parts.append(extra)
    key = json.dumps(parts, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def base_row(
    run: Run,
    rid: str,
    version: str,
    kind: str = "tracking",
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The identifying columns of a run row. ``settings`` also keeps what produced it: the
    scenario's overrides and duration, the simulated feet when a contact replaces the model's
    geometry by its sole box, and when and where it ran."""
    loaded, settings = run.scenario, run.settings
    boxes = {c.frame: c.contact_geometry for c in loaded.spec.contacts}
    pert = loaded.spec.perturbations
    info = {
        "overrides": list(loaded.overrides),
        "duration_s": loaded.spec.duration,
        # the simulated feet, when a contact replaces the model's geometry by its sole box
        **({"contact_geometry": boxes} if "box" in boxes.values() else {}),
        # what differs from the ideal run, and the two models when they differ
        **({"perturbations": pert.summary(), **models_of(pert)} if pert.active else {}),
        **(extra or {}),
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "host": platform.node(),
        "cpu": cpu_model(),
    }
    return dict(
        run_id=rid,
        scenario=loaded.name,
        scenario_hash=loaded.hash,
        robot=loaded.spec.robot,
        controller=settings.controller,
        controller_config=settings.config_json,
        solver=settings.solver,
        tier=settings.tier,
        mode=settings.mode,
        impl=run.impl,
        seed=pert.seed,
        code_version=version,
        kind=kind,
        settings=json.dumps(info, sort_keys=True),
    )


def models_of(pert: PerturbationsSpec) -> dict[str, str]:
    """The simulated model and the controller's, in words, when either differs from the file."""
    m = pert.model
    sim = "the robot's file"
    if m.payload is not None:
        p = m.payload
        sim += f" + a {p.mass:g} kg payload on {p.body} at {list(p.offset)} m"
    if pert.actuation.lag:
        sim += f", motors with a {1e3 * pert.actuation.lag:g} ms first-order lag"
    own = []
    if m.mass_scale != 1:
        own.append(f"masses x{m.mass_scale:g}")
    inertia = m.mass_scale if m.inertia_scale is None else m.inertia_scale
    if inertia != 1:
        own.append(f"inertias x{inertia:g}")
    if any(m.com_offset):
        own.append(f"CoMs moved by {list(m.com_offset)} m")
    controller = "the robot's file" + (f" with {', '.join(own)}" if own else "")
    return {"simulated_model": sim, "controller_model": controller}


@dataclass
class RunRecord:
    row: dict[str, Any]
    metrics: list[dict[str, Any]]
    result: RunResult | None
    log: dict[str, Any] | None = None
    #: the walk the run followed (:func:`wbcbench.sim.closed_loop.walk_record`), or None
    walk: dict[str, Any] | None = None


def ended_record(
    run: Run,
    rid: str,
    version: str,
    status: str,
    message: str,
    kind: str = "tracking",
    extra: dict[str, Any] | None = None,
) -> RunRecord:
    """The row of a run that produced nothing (stopped by the guard, skipped): no metrics."""
    row = base_row(run, rid, version, kind, extra)
    row.update(status=status, fell=False, message=message, ticks=0, failures=0)
    return RunRecord(row, [], None)


def compute_tracking(
    run: Run,
    rid: str,
    version: str,
    progress: Callable[[int, int], None] | None = None,
    check_factor: float | None = None,
) -> RunRecord:
    """Run one closed-loop combination and return its row, metrics and log (nothing stored).

    With ``check_factor``, every QP the solver reports solved is checked after its step (outside
    the timed stages, :mod:`wbcbench.bench.checks`): one whose relative KKT residuals exceed
    ``check_factor`` × the accuracy its tier asks of the backend fails the tick, and the run
    ends ``failed`` with the message ``reported solved but …`` (or keeps a fall's status with
    that message appended).

    Never raises: an exception becomes a row with status ``error`` and its message.
    """
    spec, settings = run.scenario.spec, run.settings
    row = base_row(run, rid, version)
    base = dict(scenario=run.name, controller=settings.controller, solver=settings.solver)
    metrics: list[dict[str, Any]] = []
    result: RunResult | None = None
    log = None
    walk = None
    try:
        checker = ReportedCheck(check_factor) if check_factor else None
        result = run_closed_loop(
            run,
            progress=progress,
            wrap_solver=checker.wrap if checker else None,
            check=checker,
        )
        contacts = build_contacts(spec, run.robot)
        window = spec.metrics.window
        for m in run_metrics(result, contacts, window, spec.metrics.timing_warmup):
            metrics.append(dict(run_id=rid, **base, **m.__dict__))
        row.update(
            status=result.status,
            fell=result.fell,
            message=result.message,
            ticks=result.ticks,
            sim_duration_s=result.ticks * spec.dt,
            wall_time_s=round(result.wall_time, 3),
            failures=result.failures,
        )
        log = {k: v for k, v in result.log.arrays().items()}
        if result.walk is not None:  # with each sole's CoP box [m], for the walk's figure
            soles = {c.frame: [*c.x_range, *c.y_range] for c in contacts}
            walk = dict(result.walk, soles=soles)
    except WbcBenchError as exc:
        row.update(status="error", fell=False, message=str(exc), ticks=0, failures=0)
    except Exception as exc:  # a bug or a library error in one run must not end the sweep
        last = traceback.format_exception_only(type(exc), exc)[-1].strip()
        row.update(status="error", fell=False, message=last, ticks=0, failures=0)
    return RunRecord(row, metrics, result, log, walk)


def store_record(store: ResultsStore, run: Run, record: RunRecord) -> None:
    """Append a finished run to the store (with the scenario in the provenance)."""
    loaded = run.scenario
    store.record_scenario(loaded.name, loaded.hash, str(loaded.path))
    attrs = {"walk": json.dumps(record.walk)} if record.walk is not None else None
    store.add_run(record.row, record.metrics, record.log, attrs)


def execute(
    run: Run,
    store: ResultsStore,
    progress: Callable[[int, int], None] | None = None,
    skip_done: bool = True,
    check_factor: float | None = CHECK_FACTOR,
    wall_limit_s: float | None = None,
) -> RunRecord | None:
    """Run one combination and append it to the store (None when it was already there).

    As a sweep's runs: every QP reported solved is checked (``check_factor``, see
    :func:`compute_tracking`), and the run executes in a child process under the wall-clock
    guard (``wall_limit_s``, default :func:`~wbcbench.bench.guard.tracking_deadline`): a run
    that hangs or whose process dies is a ``failed`` row. The record then carries no
    ``RunResult`` (it does not cross processes)."""
    from wbcbench.bench.guard import call_with_deadline, can_guard, tracking_deadline
    from wbcbench.bench.results import printed_path

    version = code_version(store)
    rid = run_id(run, version)
    if skip_done and rid in store.done_run_ids():
        return None
    if can_guard():
        seconds = wall_limit_s or tracking_deadline(run.scenario.spec.duration)
        printed = printed_path(store.folder, rid)
        args = (run, rid, version, check_factor)
        outcome = call_with_deadline(
            _tracking_without_result, args, seconds, printed, progress=progress
        )
        if outcome.ok:
            record: RunRecord = outcome.value
        else:
            record = ended_record(run, rid, version, "failed", outcome.message)
    else:
        record = compute_tracking(run, rid, version, progress, check_factor)
    store_record(store, run, record)
    return record


def _tracking_without_result(
    run: Run,
    rid: str,
    version: str,
    check_factor: float | None,
    progress: Callable[[int, int], None] | None = None,
) -> RunRecord:
    record = compute_tracking(run, rid, version, progress, check_factor)
    record.result = None
    return record
