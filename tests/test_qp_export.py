"""The dumped QPs (docs/qp_export.md): the .npz round trip, warm and hot sequences primed with
the tick before them, and DAQP on a semidefinite level QP of the kind lqp and rc_lqp hand it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import wbcbench.bench.solver_comparison as comparison
from wbcbench.qp import Problem, available_backends, make_solver
from wbcbench.qp.examples import random_qp

DATA = Path(__file__).resolve().parent / "data"


def _dump(folder: Path, primer: bool) -> list[Problem]:
    """Three ticks of one QP (a slowly moving random QP) as dump_problems writes them."""
    target = folder / "problems" / "sway-0123456789ab" / "qp_wbc"
    target.mkdir(parents=True)
    base = random_qp(3, n=12, n_eq=3, n_in=8)
    problems = []
    for tick in (19, 20, 21):
        p = Problem(
            H=base.H,
            g=base.g + 1e-3 * (tick - 20),
            A=base.A,
            b=base.b,
            C=base.C,
            l=base.l,
            u=base.u,
            lb=base.lb,
            ub=base.ub,
            name="L1",
            meta={"scenario": "sway", "controller": "qp_wbc", "tick": tick, "index": 0},
        )
        if tick == 19:
            if not primer:
                continue
            p.meta["primer"] = True
        p.save(target / f"{'prime-' if tick == 19 else ''}t{tick:05d}-00.npz")
        problems.append(p)
    return problems


def test_the_npz_round_trip_keeps_every_array_and_the_meta(tmp_path: Path) -> None:
    p = random_qp(0, n=9, n_eq=2, n_in=5)
    p.meta = {"scenario": "s", "tick": 7, "index": 1}
    p.save(tmp_path / "t00007-01.npz")
    q = Problem.load(tmp_path / "t00007-01.npz")
    for key in ("H", "g", "A", "b", "C", "l", "u", "lb", "ub"):
        assert np.array_equal(getattr(p, key), getattr(q, key), equal_nan=True), key
    assert q.meta == p.meta and q.name == p.name
    with np.load(tmp_path / "t00007-01.npz") as data:
        assert set(data.files) == {"H", "g", "A", "b", "C", "l", "u", "lb", "ub", "name", "meta"}


@pytest.mark.parametrize("primer", [True, False])
def test_a_hot_sequence_starts_from_its_primer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, primer: bool
) -> None:
    """The handle of a warm or hot sequence solves the tick before first, unrecorded; a cold
    handle never sees it; without a primer the sequence starts with its first tick."""
    problems = _dump(tmp_path, primer)
    seen: list[tuple[str, int, bool]] = []
    real = comparison.make_solver

    def spying(name: str, **kw: object) -> object:
        handle = real(name, **kw)
        solve = handle.solve

        def spy(problem: Problem, *a: object, **k: object) -> object:
            seen.append((str(kw["mode"]), int(problem.meta["tick"]), id(handle) in handles))
            handles.add(id(handle))
            return solve(problem, *a, **k)

        handle.solve = spy  # type: ignore[method-assign]
        return handle

    handles: set[int] = set()
    monkeypatch.setattr(comparison, "make_solver", spying)
    written = comparison.compare_on_problems(
        tmp_path, ["quadprog"], ["default"], ["cold", "hot"], show_progress=False
    )
    assert written == 4  # ticks 20 and 21, cold and hot: the primer is never a row
    rows = pd.read_csv(tmp_path / "qp_solves.csv")
    assert sorted(rows["tick"]) == [20, 20, 21, 21] and rows["valid"].all()
    hot = [(tick, reused) for mode, tick, reused in seen if mode == "hot"]
    cold = [tick for mode, tick, _ in seen if mode == "cold"]
    assert cold == [20, 21]
    assert hot == ([(19, False), (20, True), (21, True)] if primer else [(20, False), (21, True)])
    assert len(problems) == (3 if primer else 2)


@pytest.mark.skipif("daqp" not in available_backends(), reason="daqp is not installed")
def test_daqp_solves_a_semidefinite_level_qp_to_the_check() -> None:
    """The first priority level of ``lqp`` on ``tocabi_stand_sway`` (tick 20: 33 variables, 88
    inequality rows, H of rank < n): DAQP's proximal iterations at |eps_prox| = 1e-6 reach the
    optimum in a few iterations; a large proximal term (|eps_prox| = 1) crawled for 700 and
    stopped at a duality gap the independent check refuses, reported optimal."""
    p = Problem.load(DATA / "daqp_semidefinite_lqp_level.npz")
    assert np.linalg.eigvalsh(p.H).min() < 1e-12 * np.linalg.eigvalsh(p.H).max()
    ref, _ = comparison.reference_solution(p, "clarabel")
    row = comparison.solve_row(p, make_solver("daqp").solve(p), "default", ref)
    assert row["valid"], row["message"]
    assert row["iterations"] < 50
