"""Where a native tick's time goes, by library: the glue share, measured with ``perf``.

The timed region of a native controller step (its ``native_region``: ``tick.build``, one lean
solve per QP, the tick's ``level`` / ``finish`` calls, exactly what ``total`` covers) is repeated
over recorded states in a child process that ``perf record`` samples only while that loop runs
(set-up excluded through perf's control FIFO). Samples are then sorted by where they land:

* ``pinocchio`` — libpinocchio and Pinocchio's templates compiled into the module;
* ``linear algebra`` — Eigen's kernels in the module (GEMM, decompositions, triangular solves)
  and any BLAS / LAPACK library;
* ``solver`` — the QP backend's own library (OSQP's C functions, linked into the module);
* ``module code`` — the module's own functions (the ticks' loops and copies, Eigen expressions
  inlined into them);
* ``glue`` — everything else: the interpreter, NumPy, nanobind, the C library (allocation,
  copies), the kernel and the dynamic loader.

The glue share is ``glue`` over all samples. Needs ``perf`` (Linux) and the module's symbols (the
install keeps them).

    python benchmarks/glue_share.py [--controller osf_hqp] [--scenario lee2021iros_table1]
                                    [--solver daqp] [--states 100] [--repeats 20] [--top N]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

CATEGORIES = ("pinocchio", "linear algebra", "solver", "module code", "glue")
SOLVER_LIBS = (
    "daqp",
    "proxsuite",
    "qpoases",
    "osqp",
    "piqp",
    "clarabel",
    "highs",
    "quadprog",
    "qpmad",
    "eiquadprog",
)


def classify(dso: str, symbol: str) -> str:
    """The category of one sample, from its library and symbol."""
    lib = dso.lower()
    if "pinocchio" in lib or ("_core" in lib and "pinocchio::" in symbol):
        return "pinocchio"
    if "blas" in lib or "lapack" in lib:
        return "linear algebra"
    if any(name in lib for name in SOLVER_LIBS):
        return "solver"
    if "_core" in lib:
        if symbol.startswith("Eigen::"):
            return "linear algebra"
        # the module's own code is C++ in namespaces; its C functions are OSQP's (linked in)
        if "::" not in symbol and symbol[:1].isalpha():
            return "solver"
        return "module code"
    return "glue"


def inner(args: argparse.Namespace) -> None:
    """The child: the native tick's timed region, repeated."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_native import started_controller, states_for

    from wbcbench.controllers.native import NativeTimer
    from wbcbench.dynamics.state import RobotState

    setup, states = states_for(args.scenario, args.states)
    robot = setup[1]
    ctrl = started_controller(setup, args.controller, args.solver, "hot", "native", {})
    ctrl.step(RobotState(robot, *states[0][:2]), states[0][2])  # set-up done before sampling
    region = ctrl.native_region  # type: ignore[attr-defined]
    ctl, ack = os.environ["GLUE_CTL"], os.environ["GLUE_ACK"]

    def command(text: str) -> None:
        with open(ctl, "w") as f:
            f.write(text + "\n")
        with open(ack) as f:
            f.readline()

    command("enable")
    for _ in range(args.repeats):
        for q, v, t in states:
            region(q, v, t, NativeTimer())
    command("disable")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controller", default="osf_hqp")
    parser.add_argument("--scenario", default="lee2021iros_table1")
    parser.add_argument("--solver", default="daqp")
    parser.add_argument("--states", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--top", type=int, default=0, help="list the N largest symbols")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.inner:
        inner(args)
        return
    perf = shutil.which("perf")
    if perf is None:
        sys.exit("glue_share needs perf (linux-perf); it is not on PATH")
    with tempfile.TemporaryDirectory() as tmp:
        data, ctl, ack = (Path(tmp) / name for name in ("perf.data", "ctl", "ack"))
        os.mkfifo(ctl)
        os.mkfifo(ack)
        env = {
            **os.environ,
            "OPENBLAS_NUM_THREADS": "1",
            "OMP_NUM_THREADS": "1",
            "GLUE_CTL": str(ctl),
            "GLUE_ACK": str(ack),
        }
        child = [sys.executable, __file__, "--inner", *sys.argv[1:]]
        record = ["record", "-q", "-F", "4999", "-D", "-1", "--control", f"fifo:{ctl},{ack}"]
        subprocess.run(
            [perf, *record, "-o", str(data), "--", *child],
            check=True,
            env=env,
        )
        options = ["--stdio", "--no-children", "-q", "--sort", "dso,sym", "--percent-limit", "0"]
        report = subprocess.run(
            [perf, "report", "-i", str(data), *options],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    # lines: "  12.34%  libfoo.so  [.] symbol"
    line = re.compile(r"^\s*([\d.]+)%\s+(\S+)\s+\[.\]\s+(.*)$")
    shares: Counter[str] = Counter()
    lines: list[tuple[float, str, str]] = []
    glue_by_lib: Counter[str] = Counter()
    for text in report.splitlines():
        m = line.match(text)
        if m:
            pct, dso, sym = float(m.group(1)), m.group(2), m.group(3)
            cat = classify(dso, sym)
            shares[cat] += pct
            lines.append((pct, cat, sym))
            if cat == "glue":
                glue_by_lib[dso] += pct
    total = sum(shares.values()) or 1.0
    if args.top:
        print(f"the {args.top} largest symbols:")
        for pct, cat, sym in sorted(lines, reverse=True)[: args.top]:
            print(f"  {100 * pct / total:5.2f} %  {cat:15s} {sym[:90]}")
    print(
        f"{args.controller} · {args.scenario} · {args.solver} · hot, native, "
        f"{args.states} states × {args.repeats}, the timed region only"
    )
    for cat in CATEGORIES:
        print(f"  {cat:15s} {100 * shares[cat] / total:5.1f} %")
    print(f"glue share: {100 * shares['glue'] / total:.1f} %, of which:")
    for dso, pct in glue_by_lib.most_common(6):
        print(f"  {dso:40.40s} {100 * pct / total:5.1f} %")


if __name__ == "__main__":
    main()
