"""The QP test set: the export keeps each QP's feasible set and optimum, names and orders its
sequences, carries a reference solution that meets the KKT conditions, is solved tick after tick
by the sequence mode, and qpbenchmark itself runs it and agrees on which QPs a library solves."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from wbcbench.bench.qp_export import (
    QPBENCHMARK_KEYS,
    export_qps,
    problem_from_row,
    qpsolvers_form,
    read_export,
)
from wbcbench.bench.qp_sequences import (
    qpbenchmark_agreement,
    run_qpbenchmark,
    sequence_report,
    solve_sequences,
    summarize_sequences,
)
from wbcbench.bench.timing import dump_problems
from wbcbench.qp import Problem, make_solver
from wbcbench.runs import plan_run

TICKS = 3


def two_sided_problem(seed: int) -> Problem:
    """A QP with every kind of row: equalities, two-sided, one-sided either way, free rows,
    rows with l = u, and a box with infinite entries."""
    rng = np.random.default_rng(seed)
    n = 6
    M = rng.normal(size=(n, n))
    C = rng.normal(size=(6, n))
    lo = np.array([-1.0, -np.inf, -0.5, -np.inf, 0.2, -0.3])
    hi = np.array([1.0, 0.4, np.inf, np.inf, 0.2, 0.8])
    return Problem(
        H=M @ M.T + np.eye(n),
        g=rng.normal(size=n),
        A=rng.normal(size=(1, n)),
        b=np.array([0.1]),
        C=C,
        l=lo,
        u=hi,
        lb=np.array([-2.0, -np.inf, -1.0, -3.0, -np.inf, -1.0]),
        ub=np.array([2.0, 1.0, np.inf, 3.0, np.inf, 1.0]),
        name="level1",
    )


def feasible(problem: Problem, x: np.ndarray, tol: float = 1e-12) -> bool:
    lb, ub = problem.box()
    Cx = problem.C @ x
    return bool(
        np.all(np.abs(problem.A @ x - problem.b) <= tol)
        and np.all(Cx >= problem.l - tol)
        and np.all(Cx <= problem.u + tol)
        and np.all(x >= lb - tol)
        and np.all(x <= ub + tol)
    )


def violations(problem: Problem, x: np.ndarray) -> tuple[float, float]:
    """(largest equality residual, largest inequality violation) at x; a row with l = u is an
    equality."""
    lb, ub = problem.box()
    Cx = problem.C @ x
    equal = problem.l == problem.u
    eq = np.concatenate([problem.A @ x - problem.b, Cx[equal] - problem.l[equal]])
    ineq = np.concatenate(
        [problem.l[~equal] - Cx[~equal], Cx[~equal] - problem.u[~equal], lb - x, x - ub, [0.0]]
    )
    return float(np.abs(eq).max(initial=0.0)), float(ineq.max())


@pytest.mark.parametrize("seed", range(5))
def test_the_qpbenchmark_form_keeps_the_feasible_set_and_the_optimum(seed: int) -> None:
    ours = two_sided_problem(seed)
    form = qpsolvers_form(ours)
    # l = u rows become equalities; every finite side of the other rows one G row
    assert form["A"] is not None and form["A"].shape[0] == 2
    assert form["G"] is not None and form["G"].shape[0] == 6
    row = {k: (None if v is None else v.ravel()) for k, v in form.items()} | {"name": "x"}
    back = problem_from_row(row)
    # the same constraints: at any point, the same equality residual and inequality violation
    for x in np.random.default_rng(seed).normal(scale=0.7, size=(300, ours.n)):
        a, b = violations(ours, x), violations(back, x)
        assert a[0] == pytest.approx(b[0], abs=1e-12)
        assert a[1] == pytest.approx(b[1], abs=1e-12)
    # the same optimum, solved by one backend in each form
    a = make_solver("clarabel", tier="high").solve(ours)
    b = make_solver("clarabel", tier="high").solve(back)
    assert a.success and b.success
    np.testing.assert_allclose(a.x, b.x, atol=1e-6)
    assert ours.objective(a.x) == pytest.approx(back.objective(b.x), abs=1e-7)


@pytest.fixture(scope="module")
def export(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """QPs of 3 consecutive ticks of hqp and qp_wbc on the sway, exported."""
    folder = tmp_path_factory.mktemp("dump")
    options = {"recorder": "qp_wbc", "start": 0.0, "ticks": 2 + TICKS}
    for controller in ("qp_wbc", "hqp"):
        run = plan_run("tocabi_stand_sway", controller, "daqp", mode="hot", timing=True)
        dump_problems(folder, run, options, after=2, ticks=TICKS)
    out = folder / "export"
    export_qps(folder, out, show_progress=False)
    return out


def test_the_export_is_in_qpbenchmarks_layout_with_named_ordered_sequences(export: Path) -> None:
    frame = read_export(export)
    assert list(frame.columns[: len(QPBENCHMARK_KEYS)]) == list(QPBENCHMARK_KEYS)
    manifest = json.loads((export / "manifest.json").read_text())
    assert manifest["problems"] == len(frame)
    assert manifest["controllers"] == ["hqp", "qp_wbc"]
    # each level its own problem, each sequence one QP over consecutive ticks, in order
    for _, g in frame.groupby("sequence"):
        assert list(g["position"]) == list(range(TICKS))
        assert list(g["tick"]) == list(range(2, 2 + TICKS))
        assert g["qp"].nunique() == 1
    assert frame["sequence"].nunique() == 1 + frame[frame["controller"] == "hqp"]["qp"].nunique()
    first = frame.iloc[0]
    assert first["name"] == f"tocabi_like-tocabi_stand_sway-hqp-{first['qp']}-t00002"
    assert (frame["deadline_s"] == 1e-3).all() and (frame["robot"] == "tocabi_like").all()
    # P is n × n, flattened row-major, as qpbenchmark's ProblemList stores it
    n = int(first["n"])
    assert first["P"].size == n * n and first["q"].size == n


def test_every_reference_meets_the_kkt_conditions(export: Path) -> None:
    frame = read_export(export)
    assert frame["ref_found"].all()
    for _, row in frame.iterrows():
        problem = problem_from_row(row)
        x, z = np.asarray(row["x_ref"]), row["z_ref"]
        scale = max(1.0, float(np.abs(problem.H).max()), float(np.abs(problem.g).max()))
        assert feasible(problem, x, 1e-7 * scale)
        # stationarity with the reference's own duals (qpsolvers' signs)
        grad = problem.H @ x + problem.g
        if row["y_ref"] is not None:
            grad += problem.A.T @ np.asarray(row["y_ref"])
        if z is not None:
            grad += problem.C.T @ np.asarray(z)
        if row["z_box_ref"] is not None:
            grad += np.asarray(row["z_box_ref"])
        assert np.abs(grad).max() <= 1e-6 * scale


def test_the_sequence_mode_solves_in_order_and_measures_the_lost_warm_start(export: Path) -> None:
    rows = solve_sequences(export, ["daqp"], modes=["hot", "cold"], show_progress=False)
    frame = read_export(export)
    assert len(rows) == 2 * len(frame)
    assert rows["valid"].astype(bool).all()
    hot = rows[rows["mode"] == "hot"]
    # a fresh handle is timed beside the kept one on every QP after the first of its sequence
    assert hot[hot["position"] > 0]["fresh_call_us"].notna().all()
    assert hot[hot["position"] == 0]["fresh_call_us"].isna().all()
    summary = summarize_sequences(rows).set_index("mode")
    assert summary.loc["hot", "QPs"] == len(frame) and summary.loc["hot", "valid %"] == 100.0
    assert np.isnan(summary.loc["cold", "lost warm start µs"])
    assert "| daqp" in sequence_report(rows, export)


def test_qpbenchmark_runs_the_export_and_agrees_on_what_each_library_solves(
    export: Path, tmp_path: Path
) -> None:
    pytest.importorskip("qpbenchmark")
    libraries = ["daqp", "proxqp"]
    theirs = run_qpbenchmark(export, tmp_path / "qpbenchmark.csv", libraries, tier="mid")
    frame = read_export(export)
    assert sorted(theirs["solver"].unique()) == libraries
    assert set(theirs["problem"]) == set(frame["name"])
    ours = solve_sequences(
        export,
        [f"qpsolvers:{s}" for s in libraries],
        tiers=["mid"],
        modes=["cold"],
        show_progress=False,
    )
    table = qpbenchmark_agreement(ours, theirs, "mid").set_index("library")
    assert (table["QPs"] == len(frame)).all()
    # the same library on the same QPs: qpbenchmark's absolute tolerances and our scaled KKT
    # check agree on every QP of this set
    assert (table["only ours"] == 0).all() and (table["only qpbenchmark"] == 0).all()
    assert isinstance(theirs, pd.DataFrame)
