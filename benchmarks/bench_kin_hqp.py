"""Speed of the prioritized kinematic controller (RQR-HQP paper, §IV and Fig. 1).

Run with ``pytest benchmarks/bench_kin_hqp.py --benchmark-enable`` (pytest-benchmark), or as a
script, ``python benchmarks/bench_kin_hqp.py``, for:

* the per-iteration time of the three scenarios in kinematic closed loop (median, p99, max of
  the whole step and of each hierarchy level; the paper's target is real time at 200 Hz, 5 ms);
* the Fig. 1 study: reduced QR vs full-size QR vs SVD hierarchy against the problem size N
  (``scaling_series``), and the same three algorithms in closed loop on rqr_gaze with the
  inequalities off (the baselines take equalities only).

BLAS runs single-threaded (``threadpool_limits(1)``): at these sizes threads cost more than they
save and make the timings depend on the machine's load.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wbcbench.controllers.base import ControllerContext
from wbcbench.controllers.kin_hqp import KinHqp, KinHqpConfig
from wbcbench.dynamics.state import RobotState
from wbcbench.qp.hls_baselines import default_impls, scaling_series
from wbcbench.robots.loader import load_robot
from wbcbench.runs import plan_run, scenario_obstacles
from wbcbench.scenarios.initial import initial_state
from wbcbench.scenarios.load import (
    build_contacts,
    build_tasks,
    controller_settings,
    load_scenario,
    torque_limits,
)
from wbcbench.sim.closed_loop import run_closed_loop

SCENARIOS = ("rqr_reach", "rqr_gaze", "rqr_stress")
FIG1_SIZES = (10, 20, 40, 60, 80, 100)
#: the equality-only hierarchy the three algorithms share in closed loop
EQUALITY_ONLY = {"inequalities": False}


def controller(scenario: str, **overrides: Any) -> tuple[KinHqp, RobotState]:
    """kin_hqp for a scenario, started at its initial state."""
    loaded = load_scenario(scenario)
    spec = loaded.spec
    robot = load_robot(spec.robot)
    ctx = ControllerContext(
        robot=robot,
        tasks=build_tasks(spec, robot),
        contacts=build_contacts(spec, robot),
        tau_max=torque_limits(spec, robot),
        dt=spec.dt,
    )
    cfg = {**controller_settings(loaded, "kin_hqp"), **overrides}
    ctrl = KinHqp(ctx, KinHqpConfig.model_validate(cfg))
    ctrl.use_environment(scenario_obstacles(loaded))
    q, v = initial_state(loaded, robot)
    state = RobotState(robot, q, v)
    ctrl.start(state)
    return ctrl, state


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_step_at_start(benchmark: Any, scenario: str) -> None:
    ctrl, state = controller(scenario)
    benchmark.group = "kin_hqp step (initial state)"
    with threadpool_limits(1):
        out = benchmark(lambda: ctrl.step(RobotState(state.robot, state.q, state.v), 0.0))
    assert out.ok, out.message


@pytest.mark.parametrize("hierarchy", ["rqr", "full_qr", "svd"])
def test_hierarchy_in_the_loop(benchmark: Any, hierarchy: str) -> None:
    ctrl, state = controller("rqr_gaze", hierarchy=hierarchy, **EQUALITY_ONLY)
    benchmark.group = "kin_hqp rqr_gaze, equality-only hierarchy"
    with threadpool_limits(1):
        out = benchmark(lambda: ctrl.step(RobotState(state.robot, state.q, state.v), 0.0))
    assert out.ok, out.message


def _stats_us(x: np.ndarray) -> str:
    x = x[np.isfinite(x)] * 1e6
    return f"median {np.median(x):8.1f}  p99 {np.percentile(x, 99):8.1f}  max {x.max():8.1f} us"


def closed_loop_table() -> None:
    """Per-iteration times of the three scenarios in both impls (warm-up ticks dropped)."""
    for scenario in SCENARIOS:
        loaded = load_scenario(scenario)
        for impl in default_impls():
            cfg = {**controller_settings(loaded, "kin_hqp"), "impl": impl}
            with threadpool_limits(1):
                result = run_closed_loop(plan_run(loaded, controller="kin_hqp", config=cfg))
            _print_run(scenario, impl, loaded, result)


def _print_run(scenario: str, impl: str, loaded: Any, result: Any) -> None:
    cols = result.log.arrays()
    warm = loaded.spec.metrics.timing_warmup
    n_eq, n_in = int(cols["diag.n_eq"][0]), int(cols["diag.n_ineq"][0])
    print(
        f"{scenario} ({impl}): {result.status}, {result.ticks} ticks, {n_eq} eq / {n_in} ineq rows"
    )
    levels = sorted(k for k in cols if k.startswith("time.solve."))
    stages = ["time.total", "time.dynamics", "time.build", "time.solve", "time.solve_internal"]
    for key in [*stages, *levels]:
        if key in cols:
            print(f"  {key:<24} {_stats_us(cols[key][warm:])}")
    iters = cols["iterations"][warm:]
    active = cols["diag.active"][warm:]
    print(
        f"  active-set iterations: median {np.median(iters):.0f}, max {iters.max():.0f}; "
        f"active rows: median {np.median(active):.0f}, max {active.max():.0f}"
    )


def fig1_table() -> None:
    """Median time of the three hierarchy algorithms vs N, and their ratios."""
    with threadpool_limits(1):
        rows = scaling_series(FIG1_SIZES, repeats=200)
    med = {(r["N"], r["algorithm"], r["impl"]): r["median_s"] for r in rows}
    for impl in default_impls():
        print(
            f"{impl}: {'N':>4} {'reduced_qr':>11} {'full_qr':>11} {'svd':>11} {'full/red':>9} "
            f"{'svd/red':>8}"
        )
        for n in FIG1_SIZES:
            red, full, svd = (med[(n, a, impl)] * 1e6 for a in ("reduced_qr", "full_qr", "svd"))
            times = f"{red:>9.1f}us {full:>9.1f}us {svd:>9.1f}us"
            print(f"{n:>4} {times} {full / red:>9.2f} {svd / red:>8.2f}")
    print("closed loop, rqr_gaze, equality-only hierarchy (solve stage per tick):")
    for hierarchy in ("rqr", "full_qr", "svd"):
        loaded = load_scenario("rqr_gaze")
        cfg = {**controller_settings(loaded, "kin_hqp"), "hierarchy": hierarchy, **EQUALITY_ONLY}
        with threadpool_limits(1):
            result = run_closed_loop(plan_run(loaded, controller="kin_hqp", config=cfg))
        cols = result.log.arrays()
        print(
            f"  {hierarchy:<8} {_stats_us(cols['time.solve'][10:])}  "
            f"hand err_final {cols['err.hand.pos'][-1] * 1e3:.3f} mm"
        )


def main() -> None:
    closed_loop_table()
    fig1_table()


if __name__ == "__main__":
    main()
