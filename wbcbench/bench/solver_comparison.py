"""QP solver comparison on the WBC problems of every controller (qpbenchmark style): running it.

The QPs of a few consecutive replayed control ticks of each scenario × controller are dumped
with :meth:`Problem.save` (``problems/``), then every backend solves every problem under every
accuracy tier and mode:

* ``cold``: a fresh handle per problem;
* ``warm`` / ``hot``: one handle per sequence of the same QP (same controller and QP index) over
  consecutive ticks, each tick starting from the previous one's solution or solver object. The
  handle first solves, unrecorded, the same QP of the tick before the sequence (its *primer*,
  ``prime-t<tick>-<k>.npz``), so that the first recorded solve starts warm or hot as the
  controller's did; a folder dumped without primers starts its sequences cold.

A named setting (``osqp_libdwbc``, ``qpoases_libdwbc``) runs at its own tier and mode only.

Each solve is one row of ``qp_solves.csv`` (committed as it finishes, keyed; a rerun skips the
rows it has and never writes a key twice): the reported status, whether the solution is *valid*
— checked independently of the status with :func:`wbcbench.qp.validated` at the tier's
tolerance scaled by the data's magnitude — the wall, set-up and solver-internal times,
iterations, primal / dual residuals, duality gap and the distance to a high-accuracy reference
solution. :mod:`wbcbench.report.solvers` reads the table.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.bench.results import one_line
from wbcbench.qp import Problem, Solution, check_solution, make_solver, validated
from wbcbench.qp.registry import DEFAULT_SOLVER
from wbcbench.qp.settings import TIER_EPS

SOLVES_CSV = "qp_solves.csv"
SOLVE_COLUMNS = (
    "key",
    "problem",
    "scenario",
    "controller",
    "qp",
    "tick",
    "n",
    "n_eq",
    "n_in",
    "solver",
    "tier",
    "mode",
    "status",
    "reported_solved",
    "valid",
    "message",
    "wall_us",
    "setup_us",
    "internal_us",
    "internal_covers",
    "iterations",
    "primal_residual",
    "dual_residual",
    "duality_gap",
    "dist_ref",
    "reference_ok",
    "rebuilt",
    "code_version",
)
#: success tolerance of the ``default`` tier (each solver's own settings are not iso-accuracy)
DEFAULT_TIER_EPS = 1e-6


def tier_tolerance(tier: str, problem: Problem) -> float:
    """Absolute tolerance of a tier, scaled by the magnitude of the problem's data."""
    from wbcbench.bench.checks import data_scale

    return TIER_EPS.get(tier, DEFAULT_TIER_EPS) * data_scale(problem)


def problem_sequences(folder: str | Path) -> list[list[Path]]:
    """Dumped problems grouped into sequences of the same QP over consecutive ticks."""
    groups: dict[tuple[str, str], list[Path]] = {}
    for path in sorted(Path(folder, "problems").glob("*/*/t*.npz")):
        index = path.stem.split("-")[-1]
        groups.setdefault((str(path.parent), index), []).append(path)
    return [sorted(paths) for _, paths in sorted(groups.items())]


def primer_of(path: Path) -> Path | None:
    """The QP of the tick before ``path``'s sequence, solved first to prime a warm or hot
    handle (see :func:`wbcbench.bench.timing.dump_problems`); None when it was not dumped."""
    index = path.stem.split("-")[-1]
    found = sorted(path.parent.glob(f"prime-t*-{index}.npz"))
    return found[-1] if found else None


def file_key(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12]


class SolveTable:
    """The append-only ``qp_solves.csv`` of one results folder, keyed by ``key`` (problem file ×
    solver × tier × mode × code version).

    Each row is committed alone, as one whole line in one ``write`` to the file opened for
    appending, and only when its key is not stored yet: a kill loses at most the solve under
    way, and leaves at most a torn last line, which the next writer cuts (:meth:`done`) and
    readers ignore. One writer at a time (the sweep's lock, :mod:`wbcbench.bench.lock`).
    """

    def __init__(self, folder: str | Path) -> None:
        self.path = Path(folder) / SOLVES_CSV
        self._keys: set[str] | None = None

    def _whole_lines(self) -> bytes:
        data = self.path.read_bytes() if self.path.exists() else b""
        return data[: data.rfind(b"\n") + 1]

    def done(self) -> set[str]:
        """The stored keys, after cutting a torn last line (for the writer only)."""
        if self.path.exists():
            data = self.path.read_bytes()
            if not data.endswith(b"\n"):
                tmp = self.path.with_suffix(".csv.tmp")
                tmp.write_bytes(data[: data.rfind(b"\n") + 1])
                os.replace(tmp, self.path)
        table = self.read()
        self._keys = set(table["key"]) if "key" in table.columns else set()
        return set(self._keys)

    def add(self, row: dict[str, Any]) -> bool:
        """Commit one row unless its key is stored; whether it was written."""
        if self._keys is None:
            self.done()
        assert self._keys is not None
        if row["key"] in self._keys:
            return False
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=SOLVE_COLUMNS, extrasaction="ignore")
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            if os.fstat(fd).st_size == 0:
                writer.writeheader()
            writer.writerow(one_line(row))
            os.write(fd, text.getvalue().encode())
        finally:
            os.close(fd)
        self._keys.add(row["key"])
        return True

    def append(self, rows: Iterable[dict[str, Any]]) -> int:
        """:meth:`add` each row; how many were written."""
        return sum(self.add(row) for row in rows)

    def read(self) -> pd.DataFrame:
        """The stored rows (a torn last line, of a write under way, left out)."""
        data = self._whole_lines()
        # read whole (low_memory=False): columns such as reported_solved hold booleans and
        # blanks, which chunked reading would type differently chunk by chunk
        return pd.read_csv(io.BytesIO(data), low_memory=False) if data else pd.DataFrame()


def reference_solution(problem: Problem, solver: str) -> tuple[np.ndarray | None, bool]:
    """A high-accuracy solution: ``solver`` at tier ``high``, else the default backend's, else
    Clarabel's; (x, valid)."""
    for name in dict.fromkeys([solver, DEFAULT_SOLVER, "clarabel"]):
        try:
            sol = make_solver(name, tier="high").solve(problem)
        except Exception:  # a missing backend: try the next one
            continue
        if validated(problem, sol, tol=1e-6 * max(1.0, _scale(problem))).success:
            return sol.x, True
    return None, False


def _scale(problem: Problem) -> float:
    from wbcbench.bench.checks import data_scale

    return data_scale(problem)


def solve_row(problem: Problem, sol: Solution, tier: str, ref: np.ndarray | None) -> dict[str, Any]:
    """One row's measures of a solution (validity independent of the reported status)."""
    tol = tier_tolerance(tier, problem)
    check = check_solution(problem, sol, tol=tol)
    verdict = validated(problem, sol, tol=tol)
    valid = verdict.success
    message = verdict.message if sol.success and not valid else sol.message
    if not sol.success:
        message = f"{sol.status}: {sol.message}" if sol.message else str(sol.status)
    return dict(
        status=str(sol.status),
        reported_solved=sol.success,
        valid=valid,
        message=message[:300],
        wall_us=1e6 * sol.wall_time,
        setup_us=1e6 * sol.setup_time,
        internal_us=np.nan if sol.internal_time is None else 1e6 * sol.internal_time,
        internal_covers=sol.internal_time_covers,
        iterations=np.nan if sol.iterations is None else sol.iterations,
        primal_residual=check.primal_residual,
        dual_residual=np.nan if check.dual_residual is None else check.dual_residual,
        duality_gap=np.nan if check.duality_gap is None else check.duality_gap,
        dist_ref=np.nan if ref is None else check.distance_to(ref),
        rebuilt=sol.rebuilt,
    )


def compare_on_problems(
    folder: str | Path,
    solvers: list[str],
    tiers: list[str],
    modes: list[str],
    reference_solver: str = "clarabel",
    max_solve_ms: float = 250.0,
    skip: Iterable[Any] = (),
    version: str = "",
    show_progress: bool = True,
    solve_limit_s: float = 10.0,
) -> int:
    """Solve every dumped problem with every solver × tier × mode the solver runs at (a named
    setting runs at its own only); append rows; return count.

    In a guarded child each solve has a deadline of ``solve_limit_s``: the caller stops a child
    whose solve outlasts it and starts the comparison again, which records that solve (named
    in ``qp_solves.pending.json`` before it began) as failed and skips the rest of its solver ×
    tier × mode.
    """
    from tqdm import tqdm

    from wbcbench.bench.guard import report_progress, watch_step
    from wbcbench.qp import solver_class

    table = SolveTable(folder)
    table.done()
    written = _record_hung(folder, table)
    done = table.done()
    hung = _hung_combos(table)
    sequences = problem_sequences(folder)
    loaded = {p: Problem.load(p) for seq in sequences for p in seq}
    keys = {p: file_key(p) for p in loaded}
    refs: dict[Path, tuple[np.ndarray | None, bool]] = {}
    combos = [
        (s, t, m) for s in solvers for t in tiers for m in modes if solver_class(s).offers(t, m)
    ]
    skip_rules = list(skip)
    todo = len(combos) * sum(len(seq) for seq in sequences)
    count = 0
    with tqdm(total=len(combos), desc="solver comparison", disable=not show_progress) as bar:
        for solver, tier, mode in combos:
            bar.update()
            reason = next(
                (
                    r.reason
                    for r in skip_rules
                    if all(
                        _match(v, pat)
                        for v, pat in ((solver, r.solver), (mode, r.mode), (tier, r.tier))
                    )
                ),
                "",
            )
            too_slow = hung.get((solver, tier, mode), "")
            for seq in sequences:
                handle = None
                for path in seq:
                    count += 1
                    report_progress(count, todo)
                    problem = loaded[path]
                    key = f"{keys[path]}:{solver}:{tier}:{mode}:{version.split('@', 1)[0]}"
                    if key in done:
                        handle = None  # a resumed sequence restarts its handle
                        continue
                    base = _base(path, problem, solver, tier, mode, key, version)
                    if reason or too_slow:
                        row = {**base, "status": "skipped", "valid": False}
                        written += table.add({**row, "message": reason or too_slow})
                        continue
                    if handle is None or mode == "cold":
                        handle = make_solver(solver, tier=tier, mode=mode)
                        primer = primer_of(path) if mode != "cold" else None
                        if primer is not None:
                            handle.solve(Problem.load(primer))  # unrecorded: the tick before
                    if path not in refs:
                        watch_step(f"reference {reference_solver} on {base['problem']}", 60.0)
                        refs[path] = reference_solution(problem, reference_solver)
                    ref, ref_ok = refs[path]
                    doing = f"solver {solver} ({tier}, {mode}) on {base['problem']}"
                    _pending(folder, base, solve_limit_s)
                    watch_step(doing, solve_limit_s)
                    t0 = time.perf_counter()
                    sol = handle.solve(problem)
                    elapsed = time.perf_counter() - t0
                    watch_step("", 0.0)
                    measured = solve_row(problem, sol, tier, ref)
                    written += table.add({**base, **measured, "reference_ok": ref_ok})
                    if elapsed * 1e3 > max_solve_ms:
                        too_slow = (
                            f"one solve took {1e3 * elapsed:.0f} ms > max_solve_ms = "
                            f"{max_solve_ms:g} ms; the rest of this solver × tier × mode skipped"
                        )
    return written


PENDING_JSON = "qp_solves.pending.json"
#: the message of a solve stopped at its deadline
HUNG = "no answer within the per-solve deadline of {limit:g} s; stopped"


def _pending(folder: str | Path, base: dict[str, Any], limit: float) -> None:
    """Name the solve about to begin (atomically), for a comparison that resumes after it."""
    path = Path(folder) / PENDING_JSON
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps({"row": base, "limit": limit}, default=str))
    os.replace(tmp, path)


def _record_hung(folder: str | Path, table: SolveTable) -> int:
    """A failed row for the solve named pending when the caller stopped it at its deadline
    (after a kill of the sweep it is solved again). Returns the rows written."""
    path = Path(folder) / PENDING_JSON
    if not path.exists():
        return 0
    pending = json.loads(path.read_text())
    path.unlink()
    from wbcbench.bench.guard import STOPPED_ENV

    if not os.environ.get(STOPPED_ENV):
        return 0
    row = {**pending["row"], "status": "failed", "valid": False}
    return int(table.add({**row, "message": HUNG.format(limit=pending["limit"])}))


def _hung_combos(table: SolveTable) -> dict[tuple[str, str, str], str]:
    """Solver × tier × mode with a solve stopped at its deadline: why the rest is skipped."""
    rows = table.read()
    if rows.empty:
        return {}
    prefix = HUNG.split("{", 1)[0]
    stopped = rows[rows["message"].astype(str).str.startswith(prefix)]
    return {
        (str(r.solver), str(r.tier), str(r.mode)): f"an earlier solve of this solver × tier × "
        f"mode: {r.message}"
        for r in stopped.itertuples()
    }


def _match(value: str, pattern: str) -> bool:
    import fnmatch

    return fnmatch.fnmatchcase(value, pattern)


def _base(
    path: Path, problem: Problem, solver: str, tier: str, mode: str, key: str, version: str
) -> dict[str, Any]:
    meta = problem.meta
    return dict(
        key=key,
        problem=str(Path(*path.parts[-3:])),
        scenario=meta.get("scenario", path.parts[-3]),
        controller=meta.get("controller", path.parts[-2]),
        qp=problem.name or f"qp{meta.get('index', '')}",
        tick=meta.get("tick", -1),
        n=problem.n,
        n_eq=problem.n_eq,
        n_in=problem.n_in,
        solver=solver,
        tier=tier,
        mode=mode,
        code_version=version,
    )


def run_solver_comparison(plan: Any, folder: str | Path, show_progress: bool = True) -> int:
    """Dump the QPs of the plan's targets, then compare every solver on them."""
    from wbcbench.bench.results import ResultsStore
    from wbcbench.bench.runner import code_version
    from wbcbench.bench.timing import dump_problems

    spec = plan.comparison
    for run, options in plan.comparison_targets:
        try:
            dump_problems(folder, run, options, spec.dump_after, spec.dump_ticks)
        except Exception as exc:  # a controller that cannot replay: say so, go on
            print(f"solver comparison: no QPs from {run.name} · {run.controller}: {exc}")
    version = code_version(ResultsStore(folder))
    return compare_on_problems(
        folder,
        plan.comparison_solvers,
        list(spec.tiers),
        list(spec.modes),
        spec.reference_solver,
        spec.max_solve_ms,
        spec.skip,
        version,
        show_progress,
        spec.solve_limit_s,
    )


def replay_problem(path: str | Path, solvers: list[str], tier: str, mode: str) -> pd.DataFrame:
    """Solve one dumped QP with each solver; one row per solver (for ``wbcbench replay``)."""
    problem = Problem.load(path)
    ref, ref_ok = reference_solution(problem, "clarabel")
    rows = []
    for name in solvers:
        sol = make_solver(name, tier=tier, mode=mode).solve(problem)
        r = solve_row(problem, sol, tier, ref)
        rows.append({"solver": name, **r, "reference_ok": ref_ok})
    cols = ["solver", "status", "valid", "wall_us", "setup_us", "internal_us", "iterations"]
    cols += ["primal_residual", "dual_residual", "duality_gap", "dist_ref", "message"]
    return pd.DataFrame(rows)[cols]


def describe_problem(path: str | Path) -> str:
    p = Problem.load(path)
    return f"{Path(path).name}: {p.name or 'QP'} n={p.n} n_eq={p.n_eq} n_in={p.n_in} " + json.dumps(
        p.meta, sort_keys=True, default=str
    )
