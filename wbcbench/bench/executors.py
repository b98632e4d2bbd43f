"""Where closed-loop tracking runs execute: in this process, or on a dask cluster.

Both executors yield ``(job, record)`` as each run finishes; the caller appends the record to
the results store in this process, so a store only ever has one writer. Timing runs never go
through a parallel executor: parallel runs perturb each other's timings.

Tracking numbers do not depend on the executor: a closed-loop run is deterministic given the
scenario, the settings and the libraries, and every worker runs with one BLAS thread like the
serial executor.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from types import TracebackType
from typing import TYPE_CHECKING, Any

from wbcbench.errors import UnknownNameError

if TYPE_CHECKING:
    from wbcbench.bench.runner import RunRecord
    from wbcbench.bench.sweep import Job
    from wbcbench.runs import Run

EXECUTORS = ("serial", "dask")


def run_tracking(
    run: Run,
    rid: str,
    version: str,
    log_every: int = 1,
    check_factor: float | None = None,
) -> RunRecord:
    """One closed-loop run (what a dask worker receives: the run pickles without its robot,
    which the worker loads again).

    The record carries no ``RunResult`` (it holds the robot's native models, which do not
    pickle); its per-tick log keeps every ``log_every``-th tick. ``check_factor``: see
    :func:`wbcbench.bench.runner.compute_tracking`.
    """
    from threadpoolctl import threadpool_limits

    from wbcbench.bench.guard import report_progress
    from wbcbench.bench.runner import compute_tracking

    with threadpool_limits(1):
        record = compute_tracking(run, rid, version, report_progress, check_factor)
    record.result = None
    if record.log and log_every > 1:
        record.log = {k: v[::log_every] for k, v in record.log.items()}
    return record


def run_tracking_guarded(
    run: Run,
    rid: str,
    version: str,
    log_every: int,
    check_factor: float | None,
    wall_limit_s: float | None,
    folder: str | None = None,
) -> RunRecord:
    """:func:`run_tracking` in a child process under the wall-clock guard
    (:mod:`wbcbench.bench.guard`): a run that hangs or crashes becomes a ``failed`` row.

    ``wall_limit_s`` defaults to :func:`~wbcbench.bench.guard.tracking_deadline` of the
    scenario's duration. What the run prints goes to ``folder``'s ``logs/<rid>.stdout.txt``.
    """
    from wbcbench.bench.guard import call_with_deadline, can_guard, tracking_deadline
    from wbcbench.bench.results import printed_path
    from wbcbench.bench.runner import ended_record

    args = (run, rid, version, log_every, check_factor)
    if not can_guard():
        return run_tracking(*args)
    spec = run.scenario.spec
    seconds = wall_limit_s or tracking_deadline(spec.duration, spec.control_rate)
    printed = printed_path(folder, rid) if folder else None
    doing = f"solver {run.settings.solver}"
    outcome = call_with_deadline(run_tracking, args, seconds, printed, doing=doing)
    if outcome.ok:
        record: RunRecord = outcome.value
        return record
    return ended_record(run, rid, version, "failed", outcome.message)


def _arguments(job: Job, rid: str, version: str, folder: str | None) -> tuple[Any, ...]:
    return (
        job.run,
        rid,
        version,
        int(job.options.get("log_every", 1)),
        job.options.get("check_factor"),
        job.options.get("wall_limit_s"),
        folder,
    )


class SerialExecutor:
    """Runs one job after the other in this process (the default, and always for timing)."""

    def __enter__(self) -> SerialExecutor:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        return None

    def run(
        self, jobs: Sequence[tuple[Job, str]], version: str, folder: str | None = None
    ) -> Iterator[tuple[Job, Any]]:
        """Each job's record as it finishes; ``folder``: the results folder (for its logs)."""
        for job, rid in jobs:
            yield job, run_tracking_guarded(*_arguments(job, rid, version, folder))


class DaskExecutor:
    """Runs jobs on a dask.distributed cluster: a local one, or the scheduler at ``address``.

    The local cluster has one single-threaded worker process per core, so runs never share an
    interpreter (MuJoCo and the solvers hold the GIL for most of a tick).
    """

    def __init__(self, address: str | None = None, n_workers: int | None = None) -> None:
        self.address = address
        self.n_workers = n_workers
        self._cluster: Any = None
        self._client: Any = None

    def __enter__(self) -> DaskExecutor:
        from dask.distributed import Client, LocalCluster

        if self.address:
            self._client = Client(self.address)
        else:
            self._cluster = LocalCluster(
                n_workers=self.n_workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
            )
            self._client = Client(self._cluster)
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def run(
        self, jobs: Sequence[tuple[Job, str]], version: str, folder: str | None = None
    ) -> Iterator[tuple[Job, Any]]:
        """As :meth:`SerialExecutor.run`; the workers must see ``folder`` (a local cluster)."""
        from dask.distributed import as_completed

        from wbcbench.plugins import pickled_call, run_pickled

        futures = {}
        for job, rid in jobs:
            # the registrations of this process are made on the worker before the run is
            # unpickled; pure=False: identical arguments must still run (a rerun after a code
            # change)
            call = pickled_call(run_tracking_guarded, *_arguments(job, rid, version, folder))
            future = self._client.submit(run_pickled, *call, pure=False)
            futures[future] = job
        try:
            for future in as_completed(futures):
                yield futures[future], future.result()
        finally:
            for future in futures:
                future.cancel()


def make_executor(name: str, scheduler: str | None = None) -> SerialExecutor | DaskExecutor:
    """``serial`` or ``dask`` (``scheduler``: the address of an existing dask scheduler)."""
    if name == "serial":
        return SerialExecutor()
    if name == "dask":
        return DaskExecutor(scheduler)
    raise UnknownNameError("executor", name, EXECUTORS)
