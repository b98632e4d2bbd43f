"""Controller step time on recorded closed-loop states, split into dynamics / build / solve.

Run with ``make bench-micro`` (or ``python benchmarks/bench_controllers.py`` for the table only).
Every backend times the same 1000 recorded states of ``tocabi_stand_sway`` (t = 2–3 s, during
the CoM move); the first 50 ticks of each replay are warm-up.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from wbcbench.controllers.registry import available_controllers
from wbcbench.qp import available_solvers
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import load_scenario
from wbcbench.sim.replay import Recording, record_states, replay

WARMUP = 50
SOLVERS = [s for s in available_solvers() if ":" not in s]


@functools.cache
def recording(scenario: str = "tocabi_stand_sway") -> tuple[object, Recording]:
    loaded = load_scenario(scenario, ("duration=3",))
    rec = record_states(plan_run(loaded, "qp_wbc"))
    keep = rec.t >= 2.0
    return loaded, Recording(rec.scenario, rec.t[keep], rec.q[keep], rec.v[keep])


def split(controller: str, solver: str, mode: str = "hot") -> dict[str, float]:
    loaded, rec = recording()
    timings = replay(plan_run(loaded, controller, solver, mode=mode, timing=True), rec)
    out = {s: timings.median_us(s, WARMUP) for s in ("dynamics", "build", "solve", "total")}
    out["solve_internal"] = timings.median_us("solve_internal", WARMUP)
    out["failures"] = float(timings.failures)
    return out


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("controller", available_controllers())
@pytest.mark.parametrize("mode", ["cold", "hot"])
def test_step(benchmark, controller: str, solver: str, mode: str) -> None:
    result = benchmark.pedantic(split, args=(controller, solver, mode), rounds=1, iterations=1)
    benchmark.extra_info.update({f"{k}_median_us": v for k, v in result.items()})
    assert result["failures"] == 0


def main() -> None:
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    rows = []
    for controller in available_controllers():
        for solver in SOLVERS:
            for mode in ("cold", "hot"):
                r = split(controller, solver, mode)
                rows.append((controller, solver, mode, r))
    print("median per control step on tocabi_like [µs] (same 1000 recorded states)")
    print(
        f"{'controller':<10} {'solver':<9} {'mode':<5} {'dynamics':>9} {'build':>8} "
        f"{'solve':>8} {'internal':>9} {'total':>8} {'fail':>5}"
    )
    for controller, solver, mode, r in sorted(rows, key=lambda x: x[3]["total"]):
        print(
            f"{controller:<10} {solver:<9} {mode:<5} {r['dynamics']:9.1f} {r['build']:8.1f} "
            f"{r['solve']:8.1f} {r['solve_internal']:9.1f} {r['total']:8.1f} "
            f"{int(r['failures']):5d}"
        )
    np.set_printoptions(precision=1)


if __name__ == "__main__":
    main()
