"""The QPs a sweep recorded, as a test set for QP solvers (qpbenchmark's layout).

``wbcbench export-qps RESULTS --out DIR`` reads the QPs dumped under ``RESULTS/problems/`` (every
QP a controller handed to its solver on consecutive replayed ticks; :func:`dump_problems`) and
writes:

* ``DIR/wbc_qps.parquet``: one row per QP in qpbenchmark's ``ProblemList`` columns ``P, q, G, h,
  A, b, lb, ub, name`` (matrices flattened row-major, as ``ProblemList`` writes them), plus
  columns of our own that qpbenchmark ignores: the sequence the QP belongs to and its position
  in it, the robot, scenario, controller, QP and tick, the control period (the tick's deadline)
  and a high-accuracy reference solution with its duals;
* ``DIR/wbc_qps.py``: the ``TestSet`` module, so that ``qpbenchmark DIR/wbc_qps.py run`` runs it
  as it runs its own sets;
* ``DIR/manifest.json``: counts, size on disk and provenance.

The problem is qpbenchmark's (qpsolvers') form, min ½ xᵀPx + qᵀx subject to Gx ≤ h, Ax = b,
lb ≤ x ≤ ub. A two-sided row l ≤ Cx ≤ u of ours becomes an equality row when l = u, else one
G row per finite side (Cx ≤ u, −Cx ≤ −l); rows infinite on both sides are dropped. Bounds keep
their infinite entries. Each hierarchy level is its own problem, and a *sequence* is one QP of a
controller (one level) over consecutive ticks: what a hot or warm solver sees in a controller.
"""

from __future__ import annotations

import json
import re
import time
import warnings
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.qp import Problem

TEST_SET = "wbc_qps"
#: the columns qpbenchmark's ProblemList reads, in its order
QPBENCHMARK_KEYS = ("P", "q", "G", "h", "A", "b", "lb", "ub", "name")
#: the reference solve's tolerances (qpsolvers' names per backend)
REFERENCE_SETTINGS: dict[str, dict[str, float]] = {
    "clarabel": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10},
    "proxqp": {"eps_abs": 1e-10, "eps_rel": 0.0},
}

TEST_SET_MODULE = '''"""wbcbench's whole-body-control QPs as a qpbenchmark test set.

Written by `wbcbench export-qps`; run it with `qpbenchmark wbc_qps.py run`, then
`qpbenchmark wbc_qps.py report`. The problems are in wbc_qps.parquet beside this file.
"""

from pathlib import Path

import qpbenchmark
from qpbenchmark.benchmark import main


class WbcQps(qpbenchmark.ParquetTestSet):
    """Whole-body-control QPs recorded by wbcbench, tick after tick."""

    @property
    def description(self) -> str:
        return (
            "Dense QPs that humanoid whole-body controllers (weighted QP, hierarchies, "
            "operational-space formulations) solved on consecutive 1 kHz control ticks, "
            "recorded by wbcbench ({count} problems in {sequences} sequences)"
        )

    @property
    def title(self) -> str:
        return "wbcbench whole-body-control test set"

    @property
    def sparse_only(self) -> bool:
        return False

    def __init__(self) -> None:
        super().__init__(Path(__file__).resolve().parent / "wbc_qps.parquet")


if __name__ == "__main__":
    main(test_set_path=Path(__file__).resolve())
'''


def qpsolvers_form(problem: Problem) -> dict[str, np.ndarray | None]:
    """``P, q, G, h, A, b, lb, ub`` of a QP of ours (``None`` where a part is empty)."""
    C, lo, hi = problem.C, problem.l, problem.u
    equal = np.isfinite(lo) & np.isfinite(hi) & (lo == hi)
    upper = np.isfinite(hi) & ~equal
    lower = np.isfinite(lo) & ~equal
    G = np.vstack([C[upper], -C[lower]])
    h = np.concatenate([hi[upper], -lo[lower]])
    A = np.vstack([problem.A, C[equal]])
    b = np.concatenate([problem.b, lo[equal]])
    return {
        "P": problem.H,
        "q": problem.g,
        "G": G if len(h) else None,
        "h": h if len(h) else None,
        "A": A if len(b) else None,
        "b": b if len(b) else None,
        "lb": problem.lb,
        "ub": problem.ub,
    }


def problem_from_row(row: pd.Series | dict[str, Any]) -> Problem:
    """The QP of one exported row, in our form (``G x ≤ h`` as ``−∞ ≤ G x ≤ h``)."""
    # copies: Parquet's arrays are read-only, and some backends write into their inputs
    q = np.array(row["q"], dtype=float)
    n = q.size

    def matrix(key: str) -> np.ndarray | None:
        value = row[key]
        if value is None or (np.ndim(value) == 0 and pd.isna(value)):
            return None
        return np.array(value, dtype=float).reshape(-1, n)  # a writable copy

    def vector(key: str) -> np.ndarray | None:
        value = row[key]
        if value is None or (np.ndim(value) == 0 and pd.isna(value)):
            return None
        return np.array(value, dtype=float)

    G, h = matrix("G"), vector("h")
    A, b = matrix("A"), vector("b")
    empty = np.zeros((0, n))
    return Problem(
        H=np.array(row["P"], dtype=float).reshape(n, n),
        g=q,
        A=empty if A is None else A,
        b=np.zeros(0) if b is None else b,
        C=empty if G is None else G,
        l=np.zeros(0) if h is None else np.full(h.size, -np.inf),
        u=np.zeros(0) if h is None else h,
        lb=vector("lb"),
        ub=vector("ub"),
        name=str(row["name"]),
    )


@dataclass
class Reference:
    """A high-accuracy solve of one exported QP (qpsolvers' sign conventions for the duals)."""

    solver: str
    found: bool
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    z: np.ndarray | None = None
    z_box: np.ndarray | None = None
    primal_residual: float = float("nan")
    dual_residual: float = float("nan")
    duality_gap: float = float("nan")


def reference_solve(form: dict[str, np.ndarray | None], solvers: tuple[str, ...]) -> Reference:
    """The first of ``solvers`` (qpsolvers names) that finds a solution at tight tolerances."""
    import qpsolvers

    problem = qpsolvers.Problem(**form)  # type: ignore[arg-type]
    last = Reference(solvers[0] if solvers else "", False)
    for name in solvers:
        if name not in qpsolvers.available_solvers:
            continue
        try:
            with warnings.catch_warnings():  # a status short of solved is read below
                warnings.simplefilter("ignore")
                settings = REFERENCE_SETTINGS.get(name, {})
                sol = qpsolvers.solve_problem(problem, solver=name, **settings)  # type: ignore[arg-type]
        except Exception:  # a backend that refuses the problem: the next one tries
            continue
        last = Reference(name, bool(sol.found))
        if sol.found:
            return Reference(
                name,
                True,
                sol.x,
                sol.y,
                sol.z,
                sol.z_box,
                float(sol.primal_residual()),
                float(sol.dual_residual()),
                float(sol.duality_gap()),
            )
    return last


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.]+", "_", text).strip("_")


@dataclass
class Dumped:
    """One dumped QP file and what it says about itself."""

    path: Path
    problem: Problem
    scenario: str
    controller: str
    index: int
    tick: int


def dumped_problems(results: str | Path) -> Iterator[Dumped]:
    """Every QP under ``results/problems/``, grouped by scenario and controller, in tick order."""
    for path in sorted(Path(results, "problems").glob("*/*/t*.npz")):
        problem = Problem.load(path)
        meta = problem.meta
        tick_text, index_text = path.stem[1:].split("-")
        yield Dumped(
            path,
            problem,
            str(meta.get("scenario", path.parts[-3].rsplit("-", 1)[0])),
            str(meta.get("controller", path.parts[-2])),
            int(meta.get("index", index_text)),
            int(meta.get("tick", tick_text)),
        )


def _scenario_facts(
    name: str, meta: dict[str, Any], cache: dict[str, tuple[str, float]]
) -> tuple[str, float]:
    """(robot, control period [s]) from the dump's own record, else from the scenario file."""
    if "robot" in meta and "dt" in meta:
        return str(meta["robot"]), float(meta["dt"])
    if name not in cache:
        from wbcbench.scenarios.load import load_scenario

        try:
            spec = load_scenario(name).spec
            cache[name] = (spec.robot, spec.dt)
        except Exception:  # a scenario no longer shipped: the facts are unknown
            cache[name] = ("unknown", float("nan"))
    return cache[name]


@dataclass
class ExportSummary:
    """What an export holds."""

    parquet: str
    module: str
    problems: int
    sequences: int
    robots: list[str]
    scenarios: list[str]
    controllers: list[str]
    bytes: int
    reference_found: int
    seconds: float
    sizes: dict[str, int] = field(default_factory=dict)

    def lines(self) -> list[str]:
        mb = self.bytes / 1e6
        return [
            f"{self.problems} QPs in {self.sequences} sequences, {mb:.1f} MB: {self.parquet}",
            f"robots: {', '.join(self.robots)}",
            f"scenarios ({len(self.scenarios)}): {', '.join(self.scenarios)}",
            f"controllers ({len(self.controllers)}): {', '.join(self.controllers)}",
            f"reference solutions found: {self.reference_found} of {self.problems}",
            f"sizes n: min {self.sizes.get('n_min', 0)}, median {self.sizes.get('n_median', 0)}, "
            f"max {self.sizes.get('n_max', 0)}",
            f"run it with qpbenchmark: qpbenchmark {self.module} run",
        ]


def export_qps(
    results: str | Path,
    out: str | Path,
    reference_solvers: tuple[str, ...] = ("clarabel", "proxqp"),
    show_progress: bool = True,
) -> ExportSummary:
    """Write the test set of the QPs ``results`` dumped into ``out`` (see the module docstring).

    The Parquet file is written to a temporary name and moved into place, so an interrupted
    export leaves no partial test set.
    """
    from tqdm import tqdm

    from wbcbench.errors import WbcBenchError

    t0 = time.perf_counter()
    dumped = list(dumped_problems(results))
    if not dumped:
        raise WbcBenchError(
            f"{results}: no dumped QPs under problems/; run a sweep with a solver_comparison "
            "section (its dump_ticks consecutive ticks per scenario × controller), e.g. "
            "`make qp-test-set`"
        )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    facts: dict[str, tuple[str, float]] = {}
    rows: list[dict[str, Any]] = []
    positions: dict[str, int] = {}
    for item in tqdm(dumped, desc="export-qps", disable=not show_progress):
        problem = item.problem
        robot, dt = _scenario_facts(item.scenario, problem.meta, facts)
        level = problem.name or f"qp{item.index}"
        # one QP of the controller: its index in the tick and its name (a controller whose
        # number of QPs varies with the tick, as rc_lqp's re-plans, shifts the indices)
        sequence = f"{item.scenario}/{item.controller}/{item.index:02d}-{_slug(level)}"
        position = positions.get(sequence, 0)
        positions[sequence] = position + 1
        form = qpsolvers_form(problem)
        ref = reference_solve(form, reference_solvers)
        flat = {
            k: None if v is None else np.asarray(v, dtype=float).ravel() for k, v in form.items()
        }
        name = "-".join(
            _slug(s) for s in (robot, item.scenario, item.controller, level, f"t{item.tick:05d}")
        )
        rows.append(
            {
                **flat,
                "name": name,
                "sequence": sequence,
                "position": position,
                "robot": robot,
                "scenario": item.scenario,
                "controller": item.controller,
                "qp": level,
                "qp_index": item.index,
                "tick": item.tick,
                "deadline_s": dt,
                "n": problem.n,
                "n_eq": 0 if form["b"] is None else int(np.size(form["b"])),
                "n_in": 0 if form["h"] is None else int(np.size(form["h"])),
                "source": str(Path(*item.path.parts[-3:])),
                "ref_solver": ref.solver,
                "ref_found": ref.found,
                "x_ref": ref.x,
                "y_ref": ref.y,
                "z_ref": ref.z,
                "z_box_ref": ref.z_box,
                "ref_primal_residual": ref.primal_residual,
                "ref_dual_residual": ref.dual_residual,
                "ref_duality_gap": ref.duality_gap,
            }
        )
    frame = pd.DataFrame(rows)
    columns = [*QPBENCHMARK_KEYS, *[c for c in frame.columns if c not in QPBENCHMARK_KEYS]]
    frame = frame[columns]
    parquet = out / f"{TEST_SET}.parquet"
    tmp = parquet.with_suffix(".tmp.parquet")
    frame.to_parquet(tmp, engine="pyarrow", index=False, compression="zstd")
    tmp.replace(parquet)
    module = out / f"{TEST_SET}.py"
    module.write_text(
        TEST_SET_MODULE.replace("{count}", str(len(frame))).replace(
            "{sequences}", str(frame["sequence"].nunique())
        )
    )
    summary = ExportSummary(
        parquet=str(parquet),
        module=str(module),
        problems=len(frame),
        sequences=int(frame["sequence"].nunique()),
        robots=sorted(frame["robot"].unique()),
        scenarios=sorted(frame["scenario"].unique()),
        controllers=sorted(frame["controller"].unique()),
        bytes=parquet.stat().st_size,
        reference_found=int(frame["ref_found"].sum()),
        seconds=round(time.perf_counter() - t0, 1),
        sizes={
            "n_min": int(frame["n"].min()),
            "n_median": int(frame["n"].median()),
            "n_max": int(frame["n"].max()),
        },
    )
    (out / "manifest.json").write_text(
        json.dumps({**asdict(summary), "results": str(Path(results).resolve())}, indent=1) + "\n"
    )
    return summary


def read_export(path: str | Path) -> pd.DataFrame:
    """An export's rows (``path``: the Parquet file or its folder), in sequence order."""
    path = Path(path)
    if path.is_dir():
        path = path / f"{TEST_SET}.parquet"
    frame = pd.read_parquet(path, engine="pyarrow")
    return frame.sort_values(["sequence", "position"], kind="stable").reset_index(drop=True)
