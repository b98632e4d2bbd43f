"""Where impl: native and impl: python disagree on whether a step is feasible.

Steps ``lqp`` (null-space and cascade) and ``rc_lqp``, both impls, through the perturbed
states of the equality tests (``tests/test_native_hierarchy.py``, ``tests/test_native_rc_lqp.py``:
the same cases, seed and perturbations; their first four states per case are the tests'), for
each backend at tier high, and lists every state on which exactly one impl's step fails: the
level, each impl's message, and the feasibility margin of that level's QP
(:func:`wbcbench.qp.validity.feasibility_margin`, in the failing impl and in the other) against
the band inside which the impls may differ (``tests.test_native_hierarchy.FEASIBILITY_BAND``).
Ends with the counts per controller × backend (``--margins``: and how many of the level QPs
of the states where the impls agree lie in the band). See docs/native.md, "Feasibility
verdicts".

    python benchmarks/native_feasibility.py [--states 4] [--solver daqp --solver clarabel ...]
                                            [--controller lqp --controller hqp ...] [--margins]

The (controller, backend, case) triples the tests skip as too slow are skipped here too.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests import test_native_rc_lqp
from tests.conftest import ANY_TIER_SOLVERS, grounded_state
from tests.test_native_equality import CASES as LQP_CASES
from tests.test_native_hierarchy import (
    CONTROLLERS,
    SLOW,
    QpRecorder,
    failed_level_margins,
    feasibility_band,
    in_band,
)
from wbcbench.controllers.registry import make_controller
from wbcbench.dynamics.state import RobotState
from wbcbench.qp.validity import feasibility_margin
from wbcbench.robots.loader import load_robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import load_scenario

Case = tuple[str, dict[str, Any], str, str, tuple[str, ...], str | None]


def cases(controllers: list[str]) -> list[Case]:
    """(controller, settings, case, scenario, overrides, keyframe) as the tests step them."""
    out: list[Case] = []
    for name, config, _ in CONTROLLERS:  # lqp and hqp, as tests/test_native_hierarchy.py
        if name in controllers:
            for case, (scenario, keyframe) in sorted(LQP_CASES.items()):
                out.append((name, config, case, scenario, (), keyframe))
    if "rc_lqp" in controllers:
        for case, (scenario, overrides) in sorted(test_native_rc_lqp.CASES.items()):
            out.append(("rc_lqp", {}, case, scenario, overrides, None))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--solver", action="append")
    parser.add_argument("--states", type=int, default=4)
    parser.add_argument(
        "--margins",
        action="store_true",
        help="also count the level QPs inside the band on the states where the impls agree",
    )
    parser.add_argument(
        "--controller", action="append", choices=["lqp", "rc_lqp", "hqp"], help="lqp, rc_lqp"
    )
    args = parser.parse_args()
    controllers = args.controller or ["lqp", "rc_lqp"]
    # level QPs of the Python steps on states where the impls agree: in the band, in all
    thin, level_qps = 0, 0
    solvers = args.solver or ANY_TIER_SOLVERS
    counts: Counter[tuple[str, str]] = Counter()
    mismatched: Counter[tuple[str, str]] = Counter()
    outside = 0
    recorder = QpRecorder()
    with threadpool_limits(1), recorder:
        for solver in solvers:
            backend = solver.removeprefix("qpsolvers:")
            for name, config, case, scenario, overrides, keyframe in cases(controllers):
                if case in SLOW.get((name, backend), set()):
                    continue
                loaded = load_scenario(scenario, overrides)
                robot = load_robot(loaded.spec.robot)
                keyframe = keyframe or loaded.spec.initial.keyframe
                pair = {}
                for impl in ("python", "native"):
                    ctx = scenario_context(
                        loaded, robot, solver=solver, tier="high", keep_problems=True
                    )
                    pair[impl] = make_controller(name, ctx, {**config, "impl": impl})
                    q0, v0 = robot.keyframe(keyframe)
                    pair[impl].start(RobotState(robot, q0, v0))
                frames = pair["python"].ctx.contact_frames
                rng = np.random.default_rng(7)
                window = loaded.spec.metrics.window or (0.0, loaded.spec.duration)
                label = " ".join([name, *map(str, config.values())])
                for k in range(args.states):
                    q, v = grounded_state(robot, keyframe, frames, rng, q_noise=0.05, v_noise=0.2)
                    t = float(rng.uniform(*window))
                    a = pair["native"].step(RobotState(robot, q, v), t)
                    recorder.clear()
                    b = pair["python"].step(RobotState(robot, q, v), t)
                    recorded_python = recorder.take()
                    counts[label, solver] += 1
                    if a.ok == b.ok:
                        if args.margins:
                            margins = [feasibility_margin(p) for p in recorded_python]
                            thin += sum(m < feasibility_band(solver) for m in margins)
                            level_qps += len(margins)
                        continue
                    mismatched[label, solver] += 1
                    level, margins = failed_level_margins(
                        a, b, pair["native"].native_problems(), recorded_python
                    )
                    band = in_band(a, margins, solver)
                    outside += not band
                    failed = "native" if not a.ok else "python"
                    message = re.sub(r"\s+", " ", (a.message or b.message))[:110]
                    shown = ", ".join(f"{k} {m:.1e}" for k, m in margins.items())
                    print(
                        f"{label:34s} {solver:20s} {case:11s} #{k}  {failed:6s} failed at "
                        f"{level}: margin {shown}, {'in' if band else 'OUTSIDE'} the band "
                        f"{feasibility_band(solver):.0e}\n"
                        f"    {message}",
                        flush=True,
                    )
    print(f"\n{'controller':34s} {'backend':20s} states mismatched")
    for key in sorted(counts):
        print(f"{key[0]:34s} {key[1]:20s} {counts[key]:6d} {mismatched[key]:10d}")
    total, bad = sum(counts.values()), sum(mismatched.values())
    print(f"total: {bad} of {total} states mismatched, {outside} outside the band")
    if args.margins:
        print(f"states where the impls agree: {thin} of {level_qps} level QPs inside the band")


if __name__ == "__main__":
    main()
