"""Micro-benchmarks of every installed QP backend in each mode on the WBC-like problem.

Run with ``pytest benchmarks/bench_solvers.py --benchmark-enable --benchmark-only``.

Each round solves the next problem of a 20-tick sequence (``wbc_like_sequence``: 70 variables,
45 equalities, 60 inequalities, rank-deficient PSD H, data drifting as in consecutive control
ticks), so ``warm`` and ``hot`` see realistic, not identical, successive problems. The handle
is primed on the first tick before timing. The benchmark times the whole ``QPSolver.solve``
call (our conversion overhead included); the medians of the native ``wall_time``,
``setup_time`` and the solver-internal time are stored in ``extra_info``. Tier ``mid``
(iso-accuracy 1e-6) is the comparison; ``default`` is also measured for reference.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

import wbcbench.qp as qp
from wbcbench.qp.examples import wbc_like_sequence

SEQUENCE = wbc_like_sequence(20)
INSTALLED = qp.available_solvers()


@pytest.mark.parametrize("tier", ["mid", "default"])
@pytest.mark.parametrize("mode", qp.MODES)
@pytest.mark.parametrize("name", INSTALLED)
def test_solve_wbc_like(benchmark: Any, name: str, mode: str, tier: str) -> None:
    solver = qp.make_solver(name, tier=tier, mode=mode)
    solver.solve(SEQUENCE[0])
    ticks = itertools.cycle(SEQUENCE[1:])
    solutions: list[qp.Solution] = []

    def step() -> qp.Solution:
        sol = solver.solve(next(ticks))
        solutions.append(sol)
        return sol

    benchmark.group = f"wbc_like {tier}"
    benchmark.name = f"{name} {mode}"
    benchmark(step)
    benchmark.extra_info.update(
        {
            "effective_mode": solver.mode,
            "statuses": sorted({s.status.value for s in solutions}),
            "wall_time_median_s": float(np.median([s.wall_time for s in solutions])),
            "setup_time_median_s": float(np.median([s.setup_time for s in solutions])),
            "internal_time_median_s": (
                float(np.median([s.internal_time for s in solutions]))
                if all(s.internal_time is not None for s in solutions)
                else None
            ),
            "internal_time_covers": solutions[-1].internal_time_covers,
            "iterations_median": (
                float(np.median([s.iterations for s in solutions]))
                if all(s.iterations is not None for s in solutions)
                else None
            ),
        }
    )
