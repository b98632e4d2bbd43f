"""The walking table: each torque-level controller walks ``tocabi_walk`` in closed loop.

Run with ``python benchmarks/bench_walking.py [--controllers a,b] [--solver daqp]
[--impls python,native]``. Prints controller × impl × {steps completed / planned, status, mean
and max CoM error, mean and max landing error, median and p99 total tick time per phase (double
support, single support, transition ticks) [µs]}, the machine load before and after, as a
Markdown table. A controller whose native tick holds a fixed contact set has no native row.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from wbcbench.bench.run_metrics import run_metrics
from wbcbench.controllers.registry import controller_class
from wbcbench.report.walking import walk_figure
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import build_contacts
from wbcbench.sim.closed_loop import run_closed_loop
from wbcbench.tasks.walking import WalkPlan

CONTROLLERS = ["qp_wbc", "hqp", "to_osf", "osf_hqp", "lqp", "rc_lqp"]


def walk_row(
    controller: str, impl: str, solver: str, overrides: list[str], figure: str = ""
) -> str:
    run = plan_run("tocabi_walk", controller, solver, config={"impl": impl}, overrides=overrides)
    t0 = time.perf_counter()
    result = run_closed_loop(run)
    wall = time.perf_counter() - t0
    spec = run.scenario.spec
    if figure and result.walk is not None:
        log = result.log.arrays()
        com = np.column_stack([log["com.x"], log["com.y"]])
        title = f"tocabi_walk · {controller} · {solver}: plan and simulated CoM"
        fig = walk_figure(WalkPlan.from_dict(result.walk), measured={"CoM": com}, title=title)
        fig.savefig(figure, dpi=110, bbox_inches="tight")
    metrics = {
        (m.task, m.metric): m.value
        for m in run_metrics(
            result, build_contacts(spec, run.robot), spec.metrics.window, spec.metrics.timing_warmup
        )
    }

    def get(task: str, name: str, scale: float = 1.0) -> str:
        value = metrics.get((task, name))
        return "–" if value is None or value != value else f"{scale * value:.3g}"

    steps = f"{get('*', 'steps_completed')}/{get('*', 'steps_planned')}"
    phases = " | ".join(
        f"{get('*', f't_total_median_us_{p}')} / {get('*', f't_total_p99_us_{p}')}"
        for p in ("double", "single", "transition")
    )
    return (
        f"| {controller} | {impl} | {solver} | {steps} | {result.status} | "
        f"{get('com', 'err_mean', 1e3)} / {get('com', 'err_max', 1e3)} | "
        f"{get('*', 'landing_error_mean', 1e3)} / {get('*', 'landing_error_max', 1e3)} | "
        f"{phases} | {wall:.0f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controllers", default=",".join(CONTROLLERS))
    parser.add_argument("--solver", default="daqp")
    parser.add_argument("--impls", default="python,native", help="python, native or both")
    parser.add_argument("--set", action="append", default=[], help="scenario override")
    parser.add_argument("--figure", default="", help="save the first controller's walk here")
    args = parser.parse_args()
    print(f"load before: {os.getloadavg()}")
    print(
        "| controller | impl | solver | steps | status | CoM err mean / max [mm] | landing err "
        "mean / max [mm] | double median / p99 [µs] | single median / p99 [µs] | transition "
        "median / p99 [µs] | wall [s] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    figure = args.figure
    for controller in args.controllers.split(","):
        cls = controller_class(controller)
        for impl in args.impls.split(","):
            if impl == "native" and not cls.native_schedule:
                continue  # its native tick holds a fixed contact set
            print(walk_row(controller, impl, args.solver, args.set, figure), flush=True)
            figure = ""
    print(f"load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
