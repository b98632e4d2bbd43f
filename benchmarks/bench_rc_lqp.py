"""RC-LQP paper Table 3 and Fig. 5: conventional LQP (``lqp``) against the reduced-centroidal
LQP (``rc_lqp``) on the same recorded states.

Protocol (DESIGN.md §7): each scenario is run once in closed loop (``lqp``, quadprog) and its
states recorded; every controller × backend then replays the same 350 states from t = 1 s (the
motions run), solver handles hot, one thread, the first 50 ticks discarded. Columns as the
paper's Table 3: total mean ("avg") and max, the reduced-dynamics calculation ("dyn calc": the
``reduced`` stage, Pinocchio quantities first requested there included), LQP 1 and LQP 2
(formulation + solve of each), and the median with the ratio rc_lqp / lqp beside the paper's.
The DoF series (Fig. 5) replays ``scenarios/ahn_dof_scaling.yaml`` with ``robot`` overridden
per member of the TOCABI-like family.

Solver settings: the paper's library runs OSQP its own way — warm-started, eps_abs = eps_rel =
1e-3, alpha = 1.0, its Hessian and constraint matrix re-sent every tick — which is the named
setting ``osqp_libdwbc`` (:mod:`wbcbench.qp.backends.osqp_libdwbc`); ``osqp`` hot is OSQP the
way a modern backend runs it (solver defaults, only the changed data sent). The tables run both,
and a side-by-side table puts the paper's way next to the modern way, per-tick iterations and
rc_lqp's re-plans / full-model fallbacks included.

Run with ``make bench-micro`` (pytest-benchmark cases) or ``python benchmarks/bench_rc_lqp.py``
for the tables (the paper's setting, OSQP hot and the fastest installed backend);
``--side-by-side`` prints only the paper-vs-modern table, ``--backends`` only the table of every
installed backend with native beside python, ``--impl python`` times the Python reference
instead of each controller's default impl.
"""

from __future__ import annotations

import argparse
import functools
from dataclasses import dataclass, field

import numpy as np
import pytest

from wbcbench.qp import available_solvers
from wbcbench.runs import Run, plan_run
from wbcbench.scenarios.load import LoadedScenario, load_scenario
from wbcbench.sim.replay import Recording, ReplayTimings, record_states, replay

WARMUP = 50
TICKS = 350
START = 1.0  # [s]: the CoM and hand motions start here
CONTROLLERS = ("lqp", "rc_lqp")
TABLE3 = {"double": "ahn_double_support", "single": "ahn_single_support"}
DOFS = (20, 25, 29, 33, 39, 45)
#: RC-LQP Table 3 [µs]: (conventional avg, max), (proposed avg, max, dyn calc, LQP 1, LQP 2)
PAPER_TABLE3 = {
    "double": ((2176, 2473), (981, 1203, 34, 579, 273)),
    "single": ((1834, 2119), (613, 811, 36, 243, 270)),
}
#: RC-LQP Fig. 5 / §5.3 [µs]: DoF → (conventional, proposed), the two values the text gives
PAPER_DOF = {20: (754, 571), 45: (4081, 1319)}
CANDIDATES = ("quadprog", "daqp", "proxqp", "osqp", "piqp", "clarabel", "highs", "qpoases")
SOLVERS = [s for s in CANDIDATES if s in available_solvers()]
#: the paper's way (its library's OSQP setting) and the modern way (OSQP hot, solver defaults)
PAPER_SETTING = "osqp_libdwbc"
MODERN = "osqp"
SIDE_BY_SIDE = [s for s in (PAPER_SETTING, MODERN) if s in available_solvers()]
#: the impl the tables time: None = each controller's default (native where built)
IMPL: str | None = None


def dof_robot(dof: int) -> str:
    return "tocabi_like" if dof == 33 else f"tocabi_dof{dof}"


@functools.cache
def recording(scenario: str, robot: str = "") -> tuple[LoadedScenario, Recording]:
    """The scenario (robot overridden when given) and TICKS recorded states from START on."""
    overrides = [f"duration={START + (TICKS + 10) / 1000:.3f}"]
    if robot:
        overrides.append(f"robot={robot}")
    loaded = load_scenario(scenario, tuple(overrides))
    rec = record_states(plan_run(loaded, controller="lqp", solver="quadprog"))
    return loaded, rec.window(START, TICKS)


def _run(loaded: LoadedScenario, controller: str, solver: str, impl: str | None = None) -> Run:
    impl = impl or IMPL
    config = {"impl": impl} if impl else {}
    return plan_run(loaded, controller, solver, mode="hot", config=config, timing=True)


def run(
    scenario: str, controller: str, solver: str, robot: str = "", impl: str | None = None
) -> ReplayTimings:
    loaded, rec = recording(scenario, robot)
    return replay(_run(loaded, controller, solver, impl), rec)


@dataclass
class Counted:
    """A replay's timings and, per tick, the solver iterations (all QPs of the tick) and rc_lqp's
    ``replan`` / ``fallback`` diagnostics (0 for lqp)."""

    timings: ReplayTimings
    iterations: list[float] = field(default_factory=list)
    replans: list[float] = field(default_factory=list)
    fallbacks: list[float] = field(default_factory=list)

    def after_warmup(self, values: list[float]) -> np.ndarray:
        x = np.asarray(values[WARMUP:], dtype=float)
        return x[np.isfinite(x)]


def run_counted(scenario: str, controller: str, solver: str) -> Counted:
    """:func:`run` that also keeps each tick's iterations and re-plan / fallback flags."""
    loaded, rec = recording(scenario)
    counted = Counted(ReplayTimings())

    def keep(_: int, out: object) -> str:
        counted.iterations.append(float(getattr(out, "iterations", np.nan)))
        diagnostics = getattr(out, "diagnostics", {})
        counted.replans.append(float(diagnostics.get("replan", 0.0)))
        counted.fallbacks.append(float(diagnostics.get("fallback", 0.0)))
        return ""

    counted.timings = replay(_run(loaded, controller, solver), rec, on_step=keep)
    return counted


def columns(t: ReplayTimings) -> dict[str, float]:
    """Table 3's columns [µs] (NaN where the controller has no such stage) and the failures."""

    def stat(stage: str, fn: object) -> float:
        if stage not in t.stages:
            return float("nan")
        x = t.stages[stage][WARMUP:]
        x = x[np.isfinite(x)]
        return float(fn(x) * 1e6) if x.size else float("nan")  # type: ignore[operator]

    return {
        "avg": stat("total", np.mean),
        "max": stat("total", np.max),
        "median": stat("total", np.median),
        "p99": stat("total", lambda x: np.percentile(x, 99)),
        "dyn": stat("reduced", np.mean),
        "lqp1": stat("lqp1", np.mean),
        "lqp2": stat("lqp2", np.mean),
        "solve": stat("solve", np.mean),
        "failures": float(t.failures),
    }


# -- pytest-benchmark cases -------------------------------------------------------------------


@pytest.mark.parametrize("solver", list(dict.fromkeys([*SOLVERS, *SIDE_BY_SIDE])))
@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("support", list(TABLE3))
def test_table3(benchmark, support: str, controller: str, solver: str) -> None:
    t = benchmark.pedantic(run, args=(TABLE3[support], controller, solver), rounds=1)
    cols = columns(t)
    benchmark.extra_info.update({f"{k}_us": v for k, v in cols.items() if k != "failures"})
    assert t.failures == 0, t.message


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("dof", DOFS)
def test_dof_scaling(benchmark, dof: int, controller: str) -> None:
    args = ("ahn_dof_scaling", controller, "quadprog", dof_robot(dof))
    t = benchmark.pedantic(run, args=args, rounds=1)
    benchmark.extra_info.update({f"{k}_us": v for k, v in columns(t).items()})
    assert t.failures == 0, t.message


# -- tables -----------------------------------------------------------------------------------


def fastest_solver() -> str:
    """The backend with the smallest rc_lqp median on the double-support states."""
    medians = {}
    for solver in SOLVERS:
        t = run(TABLE3["double"], "rc_lqp", solver)
        if t.failures == 0:
            medians[solver] = columns(t)["median"]
    return min(medians, key=medians.__getitem__)


def table3(solver: str) -> None:
    impl = f", impl {IMPL}" if IMPL else ""
    print(
        f"\nTable 3 — {solver}, hot{impl}, {TICKS - WARMUP} recorded states [µs] (paper: OSQP, C++)"
    )
    head = (
        f"{'support':<7} {'method':<13} {'avg':>6} {'max':>6} {'median':>7} {'dyn':>5} "
        f"{'LQP1':>6} {'LQP2':>6} {'fail':>4} | {'paper avg':>9} {'max':>5} {'dyn':>4} "
        f"{'LQP1':>5} {'LQP2':>5}"
    )
    print(head)
    for support, scenario in TABLE3.items():
        res = {c: columns(run(scenario, c, solver)) for c in CONTROLLERS}
        (p_avg, p_max), proposed = PAPER_TABLE3[support]
        papers = {"lqp": (p_avg, p_max, "", "", ""), "rc_lqp": proposed}
        for c, label in (("lqp", "conventional"), ("rc_lqp", "proposed")):
            r = res[c]
            paper = " ".join(f"{v:>{w}}" for v, w in zip(papers[c], (9, 5, 4, 5, 5), strict=True))
            print(
                f"{support:<7} {label:<13} {r['avg']:6.0f} {r['max']:6.0f} {r['median']:7.0f} "
                f"{r['dyn']:5.0f} {r['lqp1']:6.0f} {r['lqp2']:6.0f} {int(r['failures']):4d} | "
                f"{paper}"
            )
        ratio = res["rc_lqp"]["median"] / res["lqp"]["median"]
        ratio_avg = res["rc_lqp"]["avg"] / res["lqp"]["avg"]
        paper_ratio = proposed[0] / p_avg
        print(
            f"{support:<7} rc_lqp / lqp: median {ratio:.2f}, avg {ratio_avg:.2f} "
            f"(paper {paper_ratio:.2f})"
        )


def table3_side_by_side(paper: str = PAPER_SETTING, modern: str = MODERN) -> None:
    """Table 3 the paper's way and the modern way on the same states: per support and method,
    the per-tick median / mean [µs] and median iterations of each, and the ratio."""
    impl = f", impl {IMPL}" if IMPL else ""
    print(
        f"\nTable 3, the paper's way ({paper}) vs the modern way ({modern}, hot, solver "
        f"defaults){impl}, {TICKS - WARMUP} recorded states: per-tick median / mean [µs], "
        "median iterations per tick (all QPs), rc_lqp re-plans / full-model fallbacks"
    )
    print(
        f"{'support':<7} {'method':<13} | {paper:>14} {'mean':>5} {'iter':>5} {'r/f':>7} | "
        f"{modern:>14} {'mean':>5} {'iter':>5} {'r/f':>7} | {'modern/paper':>12}"
    )
    for support, scenario in TABLE3.items():
        medians: dict[tuple[str, str], float] = {}
        for c, label in (("lqp", "conventional"), ("rc_lqp", "proposed")):
            cells = []
            for solver in (paper, modern):
                r = run_counted(scenario, c, solver)
                cols = columns(r.timings)
                medians[(solver, c)] = cols["median"]
                iters = r.after_warmup(r.iterations)
                rf = (
                    f"{int(sum(r.after_warmup(r.replans)))}/{int(sum(r.after_warmup(r.fallbacks)))}"
                )
                fail = f" ({int(cols['failures'])} failed)" if cols["failures"] else ""
                cells.append(
                    f"{cols['median']:14.0f} {cols['avg']:5.0f} "
                    f"{np.median(iters) if iters.size else np.nan:5.0f} {rf:>7}{fail}"
                )
            ratio = medians[(modern, c)] / medians[(paper, c)]
            print(f"{support:<7} {label:<13} | {cells[0]} | {cells[1]} | {ratio:12.2f}")
        p_ratio = PAPER_TABLE3[support][1][0] / PAPER_TABLE3[support][0][0]
        ours = "  ".join(
            f"{s}: {medians[(s, 'rc_lqp')] / medians[(s, 'lqp')]:.2f}" for s in (paper, modern)
        )
        print(f"{support:<7} rc_lqp / lqp medians: {ours} (paper, from its avg: {p_ratio:.2f})")


def per_backend(impls: tuple[str, ...] = ("native", "python")) -> None:
    """Table 3's columns for every installed backend, native beside python: per support, lqp's
    and rc_lqp's mean (avg), max and p99, rc_lqp's dyn calc, LQP 1 and LQP 2, the solver calls'
    share of each (``solve``: set-up + solve, what the backend costs) and the ratios of the step
    and of the solver calls alone (where the step shows no gain, the solver ratio says whether
    the backend does)."""
    print(f"\nTable 3 per backend, hot, {TICKS - WARMUP} recorded states, mean [µs]")
    print(
        f"{'backend':<13} {'impl':<6} {'sup':<6} {'lqp':>6} {'max':>6} {'p99':>6} | "
        f"{'rc_lqp':>6} {'max':>6} {'p99':>6} {'dyn':>4} {'LQP1':>5} {'LQP2':>5} | "
        f"{'solve lqp':>9} {'rc':>5} | {'step':>5} {'solve':>5}"
    )
    for solver in dict.fromkeys([*SIDE_BY_SIDE, *SOLVERS]):
        for impl in impls:
            for support, scenario in TABLE3.items():
                c = {ctrl: columns(run(scenario, ctrl, solver, impl=impl)) for ctrl in CONTROLLERS}
                a, r = c["lqp"], c["rc_lqp"]
                fails = int(a["failures"] + r["failures"])
                print(
                    f"{solver:<13} {impl:<6} {support:<6} {a['avg']:6.0f} {a['max']:6.0f} "
                    f"{a['p99']:6.0f} | {r['avg']:6.0f} {r['max']:6.0f} {r['p99']:6.0f} "
                    f"{r['dyn']:4.0f} {r['lqp1']:5.0f} {r['lqp2']:5.0f} | {a['solve']:9.0f} "
                    f"{r['solve']:5.0f} | {r['avg'] / a['avg']:5.2f} "
                    f"{r['solve'] / a['solve']:5.2f}" + (f"  failures {fails}" if fails else "")
                )
    print("(paper, OSQP in C++: step 0.45 double, 0.33 single)")


def dof_series(solver: str) -> None:
    impl = f", impl {IMPL}" if IMPL else ""
    print(f"\nDoF scaling (Fig. 5), double support — {solver}, hot{impl}, median [µs]")
    print(
        f"{'DoF':>4} {'n_uc':>5} {'lqp':>7} {'rc_lqp':>7} {'ratio':>6} | {'paper':>12} {'ratio':>6}"
    )
    for dof in DOFS:
        res = {c: columns(run("ahn_dof_scaling", c, solver, dof_robot(dof))) for c in CONTROLLERS}
        lqp, rc = res["lqp"]["median"], res["rc_lqp"]["median"]
        paper = PAPER_DOF.get(dof)
        p_txt = f"{paper[0]:>5} / {paper[1]:>4}" if paper else ""
        p_ratio = f"{paper[1] / paper[0]:6.2f}" if paper else ""
        print(
            f"{dof:>4} {dof - 12:>5} {lqp:7.0f} {rc:7.0f} {rc / lqp:6.2f} | {p_txt:>12} {p_ratio}"
        )


def main(argv: list[str] | None = None) -> None:
    global IMPL
    from threadpoolctl import threadpool_limits

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--side-by-side",
        action="store_true",
        help=f"only the paper's way ({PAPER_SETTING}) vs the modern way ({MODERN} hot) table",
    )
    parser.add_argument(
        "--impl", choices=["native", "python"], help="the impl to time (default: each's own)"
    )
    parser.add_argument(
        "--backends",
        action="store_true",
        help="only the per-backend table (every installed backend, native beside python)",
    )
    args = parser.parse_args(argv)
    IMPL = args.impl
    threadpool_limits(1)
    if args.backends:
        per_backend()
        return
    if len(SIDE_BY_SIDE) == 2:
        table3_side_by_side()
    if args.side_by_side:
        return
    fastest = fastest_solver()
    tables = [s for s in dict.fromkeys([*SIDE_BY_SIDE, fastest]) if s in available_solvers()]
    for solver in tables:
        table3(solver)
    per_backend()
    for solver in tables:
        dof_series(solver)


if __name__ == "__main__":
    main()
