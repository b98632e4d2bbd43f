"""impl: native against impl: python, per stage, on the same states in one run.

Each controller that has a native tick is stepped by both implementations through the same
sequence of states (perturbed keyframes with the soles on the ground, times inside the
scenario's metrics window), with the same backend and mode, single-threaded BLAS. Printed per
stage: median, IQR and p99 [µs], and the python / native ratio of the medians. The load average
is printed before and after: compare only numbers from one run.

    python benchmarks/bench_native.py [--scenario S] [--solver daqp --solver proxqp ...]
                                      [--mode hot] [--states 300] [--controller qp_wbc ...]
                                      [--set params=periodic:5 --set inverse=svd ...]

The controller's settings are the scenario's (``controllers:``) with ``--set`` on top.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from threadpoolctl import threadpool_limits

from wbcbench import _native
from wbcbench.controllers.registry import CONTROLLERS, make_controller
from wbcbench.dynamics.state import RobotState
from wbcbench.robots.loader import load_robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import controller_settings, load_scenario

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.conftest import grounded_state

STAGES = (
    "dynamics",
    "build",
    "params",
    "reduced",
    "lqp1",
    "lqp2",
    "fallback",
    "solve",
    "solve_native",
    "crossing",
    "total",
)


def states_for(scenario: str, n: int, seed: int = 0) -> tuple[Any, list[tuple[Any, ...]]]:
    loaded = load_scenario(scenario)
    robot = load_robot(loaded.spec.robot)
    frames = [c.frame for c in loaded.spec.contacts]
    keyframe = loaded.spec.initial.keyframe
    rng = np.random.default_rng(seed)
    window = loaded.spec.metrics.window or (0.0, loaded.spec.duration)
    out = []
    for _ in range(n):
        q, v = grounded_state(robot, keyframe, frames, rng, q_noise=0.03, v_noise=0.1)
        out.append((q, v, float(rng.uniform(*window))))
    return (loaded, robot, keyframe), out


def started_controller(
    setup: tuple[Any, ...], name: str, solver: str, mode: str, impl: str, sets: dict[str, Any]
) -> Any:
    """The scenario's controller with its settings, ``sets`` on top, started at the keyframe."""
    loaded, robot, keyframe = setup
    ctx = scenario_context(loaded, robot, solver=solver, mode=mode)
    config = {**controller_settings(loaded, name), **sets, "impl": impl}
    controller = make_controller(name, ctx, config)
    controller.start(RobotState(robot, *robot.keyframe(keyframe)))
    return controller


def run(
    setup: tuple[Any, ...],
    states: list[tuple[Any, ...]],
    name: str,
    solver: str,
    mode: str,
    impl: str,
    sets: dict[str, Any],
) -> dict[str, np.ndarray]:
    robot = setup[1]
    controller = started_controller(setup, name, solver, mode, impl, sets)
    rows: dict[str, list[float]] = {}
    failures = 0
    for q, v, t in states:
        out = controller.step(RobotState(robot, q, v), t)
        failures += not out.ok
        for key, value in out.timings.items():
            rows.setdefault(key, []).append(value)
    controller.close()
    warm = len(states) // 10
    result = {k: 1e6 * np.asarray(v[warm:]) for k, v in rows.items()}
    result["failures"] = np.array([failures])
    return result


def stats(x: np.ndarray) -> tuple[float, float, float]:
    q25, q50, q75, q99 = np.percentile(x, [25, 50, 75, 99])
    return float(q50), float(q75 - q25), float(q99)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="tocabi_stand_sway")
    parser.add_argument("--solver", action="append")
    parser.add_argument("--mode", default="hot")
    parser.add_argument("--states", type=int, default=300)
    parser.add_argument("--controller", action="append")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    sets = {}
    for item in args.set:
        key, _, value = item.partition("=")
        sets[key] = yaml.safe_load(value)
    if not _native.BUILT:
        sys.exit(f"the native module is {_native.REASON}")
    names = args.controller or [n for n, c in CONTROLLERS.items() if c.has_native]
    solvers = args.solver or ["daqp", "proxqp", "qpoases"]
    setup, states = states_for(args.scenario, args.states)
    print(f"load average before: {os.getloadavg()[0]:.2f} (2-core machine: compare within a run)")
    print(f"{args.scenario}: {len(states)} states, first {len(states) // 10} discarded\n")
    with threadpool_limits(1):
        for name in names:
            for solver in solvers:
                res = {
                    impl: run(setup, states, name, solver, args.mode, impl, sets)
                    for impl in ("python", "native")
                }
                fails = {impl: int(r["failures"][0]) for impl, r in res.items()}
                shown = " ".join(f"{k}={v}" for k, v in sets.items())
                print(f"## {name} · {solver} · {args.mode} {shown}  failed ticks: {fails}")
                head = ("stage", "python median/IQR/p99 µs", "native median/IQR/p99 µs", "ratio")
                print(f"{head[0]:14s} {head[1]:>28s} {head[2]:>28s} {head[3]:>6s}")
                for stage in STAGES:
                    if stage not in res["native"] and stage not in res["python"]:
                        continue
                    cells = []
                    for impl in ("python", "native"):
                        x = res[impl].get(stage)
                        cells.append(
                            "—" if x is None else "{:8.0f} {:7.0f} {:8.0f}".format(*stats(x))
                        )
                    ratio = ""
                    if stage in res["native"] and stage in res["python"]:
                        ratio = "%.2f" % (
                            np.median(res["python"][stage])
                            / max(np.median(res["native"][stage]), 1e-9)
                        )
                    print(f"{stage:14s} {cells[0]:>28s} {cells[1]:>28s} {ratio:>6s}")
                print()
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
