"""Why qpOASES is slow or fast here: the OSF QPs of recorded ticks, solved again per usage.

Protocol (DESIGN §7): the closed-loop states of ``lee2021iros_table1`` (t = 3–4 s, osf_hqp with
daqp) are replayed through native ``osf_hqp`` and ``to_osf`` (``params: inline``); every QP they
hand to their solver is kept, per level, in the order solved. Each level's sequence is then
solved again by one qpOASES object per usage (the native module's ``QpOasesSolver``), call after
call as a control loop would, so every usage solves the same QPs:

* ``casadi cold``: a fresh object per call (``wbcbench run``'s default mode): ``init``, the
  initial homotopy from an empty working set, every tick;
* ``casadi hot``: one object, CasADi's matrix hotstart with every field;
* ``libdwbc``: ``qpoases_libdwbc`` (setToMPC for task QPs, setToReliable for the wrench QP, the
  working set kept, matrices re-sent when they changed);
* ``libdwbc cold``: libdwbc's options, but ``init`` every call (the options alone; each init
  starts the bounds inactive, as ``qpoases_libdwbc``'s first one does); for the wrench QP also
  ``libdwbc cold, initialStatusBounds=-1``, setToReliable's own start at the lower bounds;
* ``casadi cold`` with one option of setToMPC's at a time (what each option contributes to a
  solve from scratch).

Per usage and level: the median wall time of the qpOASES call [µs], its p99, the median and
maximum nWSR (working-set changes) and what the calls were (init / hotstart / matrix hotstart /
reinit). ``python benchmarks/bench_qpoases.py`` prints the tables; docs/qpoases.md quotes them.
"""

from __future__ import annotations

import argparse
import collections
import os
from typing import Any

import numpy as np
import scipy.linalg  # noqa: F401  (its BLAS must be loaded before threads are limited)
from threadpoolctl import threadpool_limits

from wbcbench import _native
from wbcbench.bench.checks import SolverCapture
from wbcbench.controllers.native import frozen
from wbcbench.qp.backends._common import fill_buffers
from wbcbench.qp.problem import Problem
from wbcbench.runs import plan_run
from wbcbench.sim.replay import replay

threadpool_limits(1)
WARMUP = 20

#: what setToMPC changes in Options::setToDefault() (qpOASES 3.2): the MPC value of each
MPC_CHANGES: dict[str, float] = {
    "enableRamping": 0.0,
    "enableFlippingBounds": 0.0,
    "enableRegularisation": 1.0,
    "enableNZCTests": 0.0,
    "enableDriftCorrection": 0.0,
    "terminationTolerance": 1e9 * 2.221e-16,  # qpOASES EPS
    "initialStatusBounds": 0.0,
    "numRegularisationSteps": 1.0,
    "numRefinementSteps": 0.0,
}


class FreezingCapture(SolverCapture):
    """A capture that keeps a copy of each problem when it is solved."""

    def solve(self, problem: Problem, *args: Any, **kwargs: Any) -> Any:
        sol = self._inner.solve(problem, *args, **kwargs)
        self.sink.append((frozen(problem), sol))
        return sol


def level_sequences(controller: str, t0: float, t1: float) -> dict[str, list[Problem]]:
    """The QPs a native ``controller`` hands its solver on the recorded states, per level."""
    from bench_osf import recording  # the same recorded states as Table III

    loaded, rec = recording("lee2021iros_table1", t0, t1)
    pairs: list[tuple[Problem, Any]] = []
    run = plan_run(
        loaded, controller, "daqp", mode="hot", config={"params": "inline", "impl": "native"}
    )
    replay(run, rec, wrap_solver=lambda handle: FreezingCapture(handle, pairs))
    out: dict[str, list[Problem]] = collections.defaultdict(list)
    for problem, _ in pairs:  # (copies: a lean solve's problem is a view of the tick's buffers)
        out[problem.name or controller].append(frozen(problem))
    return dict(out)


def solve_sequence(
    problems: list[Problem], mode: str, profile: str, options: dict[str, float]
) -> dict[str, Any]:
    """Solve ``problems`` in order with one qpOASES object (a fresh one per call when cold)."""
    core = _native.core()
    solver = core.QpOasesSolver(mode, options, profile=profile)
    buffers = core.QpBuffers()
    walls, nwsr, calls, failures = [], [], collections.Counter(), 0
    for i, problem in enumerate(problems):
        fill_buffers(buffers, problem)
        status, _, _, wall, _, _, _, _ = solver.solve(buffers)
        if status != "solved":
            failures += 1
        if i >= WARMUP:
            walls.append(wall * 1e6)
            nwsr.append(solver.last_nwsr)
            calls[solver.last_call] += 1
    w = np.array(walls)
    return {
        "median": float(np.median(w)),
        "p99": float(np.quantile(w, 0.99)),
        "nwsr": float(np.median(nwsr)),
        "nwsr_max": int(np.max(nwsr)),
        "calls": dict(calls),
        "failures": failures,
    }


def usages(level: str) -> dict[str, tuple[str, str, dict[str, float]]]:
    """name → (mode, profile, option overrides) for a level (``wrench``: the contact QP)."""
    lib = "libdwbc_wrench" if level == "wrench" else "libdwbc_task"
    out = {
        "casadi cold": ("cold", "casadi", {}),
        "casadi hot": ("hot", "casadi", {}),
        "libdwbc": ("hot", lib, {}),
        "libdwbc cold": ("cold", lib, {}),
    }
    if level == "wrench":  # libdwbc's init of the contact QP, which cycles (docs/qpoases.md)
        out["libdwbc cold, initialStatusBounds=-1"] = ("cold", lib, {"initialStatusBounds": -1.0})
    for key, value in MPC_CHANGES.items():
        out[f"casadi cold, {key}={value:g}"] = ("cold", "casadi", {key: value})
    return out


def table(controller: str, t0: float, t1: float, options: bool) -> None:
    sequences = level_sequences(controller, t0, t1)
    for level, problems in sequences.items():
        p = problems[0]
        print(
            f"{controller} {level}: {len(problems)} QPs, n = {p.n}, {p.n_eq} equalities, "
            f"{p.n_in} inequality rows, box {'yes' if p.has_box else 'no'}"
        )
        print(f"  {'usage':<44} {'median':>8} {'p99':>8} {'nWSR':>6} {'max':>5}  calls")
        for name, (mode, profile, opts) in usages(level).items():
            if not options and "=" in name:
                continue
            r = solve_sequence(problems, mode, profile, opts)
            calls = ", ".join(f"{k} {v}" for k, v in sorted(r["calls"].items()))
            fail = f", {r['failures']} failed" if r["failures"] else ""
            print(
                f"  {name:<44} {r['median']:8.1f} {r['p99']:8.1f} {r['nwsr']:6.0f}"
                f" {r['nwsr_max']:5d}  {calls}{fail}"
            )
        print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controller", action="append", choices=["osf_hqp", "to_osf"])
    parser.add_argument(
        "--options", action="store_true", help="one row per setToMPC option, from scratch"
    )
    parser.add_argument("--t0", type=float, default=3.0)
    parser.add_argument("--t1", type=float, default=4.0)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} (2-core machine: compare within one run)")
    for controller in args.controller or ["osf_hqp", "to_osf"]:
        table(controller, args.t0, args.t1, args.options)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
