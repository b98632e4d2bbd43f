"""The walking table: each torque-level controller walks ``tocabi_walk`` in closed loop.

Run with ``python benchmarks/bench_walking.py [--controllers a,b] [--solver daqp]
[--impls python,native]``. Prints controller × impl × {steps completed / planned, status, mean
and max CoM error, mean and max landing error, median and p99 total tick time per phase (double
support, single support, transition ticks) [µs]}, the machine load before and after, as a
Markdown table. A controller whose native tick holds a fixed contact set has no native row.

``--replay`` times the ticks on the same recorded states instead: one closed-loop walk of the
native ``qp_wbc`` is recorded, and every controller × impl steps through its states open loop,
in interleaved blocks of ticks (as the timing sweep does), so that all rows share the machine's
moments. It prints the median and p99 of the whole tick per phase, the transition ticks on their
own (the ticks whose contact set differs from the previous tick's: where a warm start is lost),
the ticks over the 1 ms control period, and each native row's speed-up over the Python
reference's median per phase.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

from wbcbench.bench.run_metrics import run_metrics, walk_phases
from wbcbench.controllers.registry import controller_class
from wbcbench.report.walking import walk_figure
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import build_contacts
from wbcbench.sim.closed_loop import run_closed_loop
from wbcbench.sim.replay import Replayer, record_states
from wbcbench.tasks.walking import WalkPlan

CONTROLLERS = ["qp_wbc", "hqp", "to_osf", "osf_hqp", "lqp", "rc_lqp"]
#: ticks each replayed row steps before the next row's turn, and the ticks left out at the start
BLOCK, WARMUP = 10, 50
PHASES = ("double", "single", "transition")


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


def tick_phases(active: list[tuple[int, ...]]) -> dict[str, np.ndarray]:
    """Masks of the ticks by phase (:func:`~wbcbench.bench.run_metrics.walk_phases`) from each
    tick's active contacts, as a run's ``active.<contact>`` columns."""
    contacts = sorted({i for a in active for i in a})
    return walk_phases({f"active.{i}": np.array([i in a for a in active]) for i in contacts})


def keep_active(replayer: Replayer, sets: list[tuple[int, ...]]) -> Any:
    """A replayer's ``on_step`` that keeps the contacts its controller held at each tick."""

    def on_step(i: int, out: Any) -> str:
        sets.append(tuple(replayer.controller.active_contacts))
        return ""

    return on_step


def replay_table(
    controllers: list[str], impls: list[str], solver: str, mode: str, overrides: list[str]
) -> None:
    """Every controller × impl on the same recorded walk, interleaved; one Markdown row each."""
    source = plan_run(
        "tocabi_walk", "qp_wbc", solver, config={"impl": "native"}, overrides=overrides
    )
    recording = record_states(source)
    replayers: dict[tuple[str, str], Replayer] = {}
    active: dict[tuple[str, str], list[tuple[int, ...]]] = {}
    for controller in controllers:
        cls = controller_class(controller)
        for impl in impls:
            if impl == "native" and not cls.native_schedule:
                continue  # its native tick holds a fixed contact set
            run = plan_run(
                "tocabi_walk",
                controller,
                solver,
                mode=mode,
                config={"impl": impl},
                overrides=overrides,
                timing=True,
            )
            key = (controller, impl)
            sets = active[key] = []
            replayer = Replayer(run, recording)
            replayer.on_step = keep_active(replayer, sets)
            replayers[key] = replayer
    keys = list(replayers)
    ticks = len(recording)
    for b, start in enumerate(range(0, ticks, BLOCK)):
        shift = b % len(keys)  # the row that goes first rotates
        for key in keys[shift:] + keys[:shift]:
            for i in range(start, min(start + BLOCK, ticks)):
                replayers[key].step(i)
    print(
        f"{ticks} recorded states of tocabi_walk (native qp_wbc, {solver}), replayed by every "
        f"row in turns of {BLOCK} ticks, the first {WARMUP} left out; mode {mode}; whole tick "
        "[µs]"
    )
    print(
        "| controller | impl | solver | failed ticks | double median / p99 | single median / "
        "p99 | transition median / p99 (ticks) | ticks > 1 ms | speed-up over python "
        "(double / single / transition) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    medians: dict[tuple[str, str], list[float]] = {}
    for key in keys:
        total = replayers[key].timings().stages["total"][WARMUP:] * 1e6
        masks = {p: m[WARMUP:] for p, m in tick_phases(active[key]).items()}
        cells, meds = [], []
        for phase in PHASES:
            x = total[masks[phase] & np.isfinite(total)]
            med = float(np.median(x)) if x.size else float("nan")
            p99 = float(np.quantile(x, 0.99)) if x.size else float("nan")
            meds.append(med)
            extra = f" ({x.size})" if phase == "transition" else ""
            cells.append(f"{med:.0f} / {p99:.0f}{extra}")
        medians[key] = meds
        finite = total[np.isfinite(total)]
        over = int(np.sum(finite > 1000.0))
        ref = medians.get((key[0], "python"))
        speedup = (
            " / ".join(f"{r / m:.1f}×" for r, m in zip(ref, meds, strict=True))
            if key[1] == "native" and ref is not None
            else "–"
        )
        print(
            f"| {key[0]} | {key[1]} | {solver} | {replayers[key].failures} | "
            + " | ".join(cells)
            + f" | {over} of {finite.size} | {speedup} |",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controllers", default=",".join(CONTROLLERS))
    parser.add_argument("--solver", default="daqp")
    parser.add_argument("--impls", default="python,native", help="python, native or both")
    parser.add_argument("--set", action="append", default=[], help="scenario override")
    parser.add_argument("--figure", default="", help="save the first controller's walk here")
    parser.add_argument(
        "--replay", action="store_true", help="time every row on the same recorded walk"
    )
    parser.add_argument("--mode", default="hot", help="solver mode of the replayed rows")
    args = parser.parse_args()
    print(f"load before: {os.getloadavg()}")
    if args.replay:
        impls = sorted(args.impls.split(","), key=lambda i: i != "python")  # python first
        replay_table(args.controllers.split(","), impls, args.solver, args.mode, args.set)
        print(f"load after: {os.getloadavg()}")
        return
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
