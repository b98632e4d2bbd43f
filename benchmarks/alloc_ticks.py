"""Heap allocations per native tick of each torque-level controller on a recorded walk.

Run with ``LD_PRELOAD=<the counter> python benchmarks/alloc_ticks.py [--controllers a,b]
[--solver daqp] [--mode hot] [--json]``, the counter being the library ``make native``
builds next to the module (``wbcbench/_native/libwbcbench_alloc_counter.so``);
:func:`counter_path` finds it. A short walk of the native ``qp_wbc`` is recorded once, then
every controller steps through its states with the native tick, and each ``Controller.step`` is
counted: the calls to malloc, calloc, realloc and the aligned allocators made from the native
module (``_core``: the ticks, the C++ solver calls, OSQP compiled in, the nanobind glue), from
libstdc++ (``operator new``, whoever calls it during the step) and from the QP backends' shared
libraries (DAQP, built next to the module; qpOASES, eiquadprog). Python's and NumPy's own
allocations are not counted.

Ticks are split into *steady* ticks (the contact set is the previous tick's), *change* ticks (a
lift-off or a touchdown to a set the tick held before in the run) and *first* ticks (to a set
held for the first time: the first lift-off of each foot, whose QPs' solvers build their
objects then), the first ``WARMUP`` ticks left out (the first solves build the solvers'
objects). Prints, per controller and kind of tick, the ticks counted and the
mean and max allocations per tick by library; ``--json`` prints the same as one JSON object
(what ``tests/test_native_alloc.py`` reads).
"""

from __future__ import annotations

import argparse
import ctypes
import importlib.util
import json
import os
import sys
from pathlib import Path
from typing import Any

CONTROLLERS = ["qp_wbc", "hqp", "to_osf", "osf_hqp", "lqp", "rc_lqp"]
#: the shared objects whose allocations are counted (by the start of their file name)
LIBRARIES = {
    "core": "_core",
    "libstdc++": "libstdc++",
    "daqp": "libwbcbench_daqp",
    "qpOASES": "libqpOASES",
    "eiquadprog": "libeiquadprog",
}
#: the kinds of tick: the contact set is the last tick's, a set the tick held before, a set held
#: for the first time in the run
KINDS = ("steady", "change", "first")
#: ticks left out at the start (the solvers' first objects), and the walk recorded
WARMUP = 20
OVERRIDES = [
    "walk.steps=2",
    "walk.start=0.2",
    "walk.single=0.5",
    "walk.double=0.2",
    "duration=1.1",
    "metrics.window=[0,1.1]",
]


def counter_path() -> Path:
    """The allocation counter ``make native`` builds next to the module."""
    spec = importlib.util.find_spec("wbcbench._native._core")
    if spec is None or spec.origin is None:
        raise SystemExit("the native module is not built (make native)")
    path = Path(spec.origin).with_name("libwbcbench_alloc_counter.so")
    if not path.exists():
        raise SystemExit(f"{path} is missing: rebuild the module (make native)")
    return path


def watch(counter: Any) -> list[str]:
    """Point the counter's ranges at the loaded libraries of :data:`LIBRARIES`; their names."""
    spans: dict[str, tuple[int, int]] = {}
    with open("/proc/self/maps") as maps:
        for line in maps:
            fields = line.split()
            # code only: a caller's address is in its library's executable mapping (the spans
            # of whole libraries may interleave)
            if len(fields) < 6 or "x" not in fields[1] or not fields[5].startswith("/"):
                continue
            file = fields[5].rsplit("/", 1)[-1]
            name = next((k for k, v in LIBRARIES.items() if file.startswith(v)), None)
            if name is None:
                continue
            lo, hi = (int(x, 16) for x in fields[0].split("-"))
            a, b = spans.get(name, (lo, hi))
            spans[name] = (min(a, lo), max(b, hi))
    names = sorted(spans)
    for i, name in enumerate(names):
        counter.wbcbench_alloc_watch(
            i, ctypes.c_size_t(spans[name][0]), ctypes.c_size_t(spans[name][1])
        )
    return names


def count(controllers: list[str], solver: str, mode: str) -> dict[str, Any]:
    """Per controller: ``{"steady"|"change": {"ticks": n, "mean": {lib: a}, "max": {lib: a}}}``."""
    from wbcbench.dynamics.state import RobotState
    from wbcbench.runs import plan_run
    from wbcbench.sim.replay import record_states

    try:
        counter = ctypes.CDLL(None)
        counter.wbcbench_alloc_take.restype = ctypes.c_long
    except AttributeError:
        raise SystemExit(f"run with LD_PRELOAD={counter_path()}") from None
    source = plan_run(
        "tocabi_walk", "qp_wbc", "daqp", config={"impl": "native"}, overrides=OVERRIDES
    )
    rec = record_states(source)
    out: dict[str, Any] = {}
    for name in controllers:
        run = plan_run(
            "tocabi_walk", name, solver, mode=mode, config={"impl": "native"}, overrides=OVERRIDES
        )
        ctrl = run.make_controller()
        data = ctrl.ctx.robot.pin_model.createData()
        libs: list[str] = []
        ticks: dict[str, list[dict[str, int]]] = {kind: [] for kind in KINDS}
        held: set[Any] = set()
        failed: list[str] = []
        for i in range(len(rec)):
            state = RobotState(ctrl.ctx.robot, rec.q[i], rec.v[i], data)
            if i == 0:
                ctrl.start(state)
                libs = watch(counter)  # the module and the backends are loaded by now
            before = ctrl.tick_contacts
            held.add(before)
            for k in range(len(libs)):
                counter.wbcbench_alloc_take(k)
            counter.wbcbench_alloc_count(1)
            result = ctrl.step(state, float(rec.t[i]))
            counter.wbcbench_alloc_count(0)
            counts = {lib: int(counter.wbcbench_alloc_take(k)) for k, lib in enumerate(libs)}
            if not result.ok:
                failed.append(f"tick {i}: {result.message}")
            elif i >= WARMUP:  # (a failed tick's solver starts afresh: not a tick to count)
                kind = "steady" if ctrl.tick_contacts == before else "change"
                if kind == "change" and ctrl.tick_contacts not in held:
                    kind = "first"
                ticks[kind].append(counts)
        out[name] = {
            kind: {
                "ticks": len(rows),
                "mean": {lib: sum(r[lib] for r in rows) / max(len(rows), 1) for lib in libs},
                "max": {lib: max((r[lib] for r in rows), default=0) for lib in libs},
            }
            for kind, rows in ticks.items()
        }
        out[name]["failed"] = failed
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--controllers", default=",".join(CONTROLLERS))
    parser.add_argument("--solver", default="daqp")
    parser.add_argument("--mode", default="hot")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--counter", action="store_true", help="print the counter library's path and exit"
    )
    args = parser.parse_args(argv)
    if args.counter:
        print(counter_path())
        return
    if "alloc_counter" not in os.environ.get("LD_PRELOAD", ""):
        raise SystemExit(f"run with LD_PRELOAD={counter_path()}")
    result = count(args.controllers.split(","), args.solver, args.mode)
    if args.json:
        json.dump(result, sys.stdout)
        print()
        return
    print(f"allocations per native tick ({args.solver}, {args.mode}; mean / max per tick)")
    for name, kinds in result.items():
        failed = kinds.pop("failed")
        if failed:
            print(f"{name:8s} {len(failed)} failed ticks, the first {failed[0]}")
        for kind, row in kinds.items():
            cells = ", ".join(
                f"{lib} {row['mean'][lib]:.1f} / {row['max'][lib]}" for lib in sorted(row["mean"])
            )
            print(f"{name:8s} {kind:6s} {row['ticks']:4d} ticks: {cells}")


if __name__ == "__main__":
    main()
