"""OSF timing: OSF-HQP Table III, TO-OSF Scenario #4, COD vs SVD, TO-OSF Table 3.

Protocol (DESIGN §7): every controller steps through the SAME recorded states (open-loop replay)
with the same backend (daqp, the fastest here), one BLAS thread, the first ticks discarded;
medians per stage. ``python benchmarks/bench_osf.py`` prints the tables with the papers' numbers
beside ours; ``make bench-micro`` runs the pytest-benchmark entries.

* Table III (``lee2021iros_table1``, TOCABI-like, 5 levels): osf_hqp per level and total QP time,
  its parameter time and full step, against the conventional cascade hqp (finals: wrench).
* Scenario #4 (``lee2021access_s4_cost``): to_osf QP time and parameter time against 1…4 contact
  planes and 1…5 tasks.
* COD vs SVD: parameter time of the dynamically consistent inverse, 5 tasks, two feet.
* Table 3 (``lee2021access_table3``): hqp vs to_osf step time for 1…5 tasks, double support.

``--authors-cycle`` times the OSF-HQP cycle of the authors' own library instead
(``libdwbc_osf_cycle``: pelvis 6-D, then upper-body rotation 3-D, then the contact-wrench QP,
``params: periodic:1``), native, per stage, with each qpOASES usage and DAQP, beside the stage
times of libdwbc built and run on a 2-vCPU AMD EPYC VM (:data:`LIBDWBC_CYCLE`); then Table I
with ``params: inline`` (osf_hqp and to_osf, median and p99) and the Table III ratio with
``qpoases_libdwbc`` per level, each over the same recorded states in one run. docs/qpoases.md
explains the numbers.
"""

from __future__ import annotations

import argparse
import functools
import os
from typing import Any

import numpy as np
import pytest
import scipy.linalg  # noqa: F401  (its BLAS must be loaded before threads are limited)
from threadpoolctl import threadpool_limits

from wbcbench.qp import available_solvers
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import LoadedScenario, load_scenario
from wbcbench.scenarios.schema import ContactSpec, CopBox
from wbcbench.sim.replay import Recording, record_states, replay

threadpool_limits(1)
WARMUP = 50
SOLVER = "daqp"
#: backends of the per-backend Table III ratio (qpOASES is the papers' solver)
COMPARE = ("daqp", "quadprog", "proxqp", "qpoases", "piqp")


@functools.cache
def recording(scenario: str, t0: float, t1: float) -> tuple[LoadedScenario, Recording]:
    """States of a closed-loop osf_hqp run of ``scenario`` kept for t0 ≤ t < t1."""
    loaded = load_scenario(scenario, (f"duration={t1}",))
    rec = record_states(plan_run(loaded, controller="osf_hqp", solver=SOLVER))
    keep = (rec.t >= t0) & (rec.t < t1)
    return loaded, Recording(rec.scenario, rec.t[keep], rec.q[keep], rec.v[keep])


def medians(
    loaded: LoadedScenario,
    rec: Recording,
    controller: str,
    config: dict[str, Any],
    solver: str = SOLVER,
    mode: str = "cold",
    ticks: dict[str, np.ndarray] | None = None,
) -> dict[str, float]:
    """Median [µs] of every stage the controller reports, over the recording; ``<stage>.iqr``
    and ``<stage>.p99`` beside each. ``ticks``, when given, receives every stage's per-tick
    seconds."""
    run = plan_run(loaded, controller, solver, mode=mode, config=config, timing=True)
    timings = replay(run, rec)
    if ticks is not None:
        ticks.update({stage: x[WARMUP:] for stage, x in timings.stages.items()})
    out = {stage: timings.median_us(stage, WARMUP) for stage in timings.stages}
    for stage in timings.stages:
        q25, q75 = (timings.quantile_us(stage, q, WARMUP) for q in (0.25, 0.75))
        out[f"{stage}.iqr"] = q75 - q25
        out[f"{stage}.p99"] = timings.quantile_us(stage, 0.99, WARMUP)
    out["failures"] = float(timings.failures)
    return out


@functools.cache
def table3_iros(
    solver: str = SOLVER, impl: str = "native", mode: str = "cold"
) -> dict[str, dict[str, float]]:
    """Table III's controllers on the same states, both in the given impl."""
    loaded, rec = recording("lee2021iros_table1", 3.0, 4.0)
    osf = {"params": "inline", "impl": impl}
    return {
        "osf_hqp_cod": medians(loaded, rec, "osf_hqp", osf, solver, mode),
        "osf_hqp_svd": medians(loaded, rec, "osf_hqp", {**osf, "inverse": "svd"}, solver, mode),
        "hqp": medians(loaded, rec, "hqp", {"finals": ["wrench"], "impl": impl}, solver, mode),
    }


def native(stages: dict[str, float]) -> float:
    """The solver's own share of the QP time [µs]: set-up (or update) plus the native call."""
    return stages["solve_setup"] + stages["solve_native"]


def subset(
    loaded: LoadedScenario, n_tasks: int, contacts: list[ContactSpec] | None = None
) -> LoadedScenario:
    """The scenario with its first ``n_tasks`` tasks (and other contacts when given)."""
    spec = loaded.spec
    update: dict[str, Any] = {"tasks": spec.tasks[:n_tasks]}
    if contacts is not None:
        update["contacts"] = contacts
    return LoadedScenario(spec.model_copy(update=update), loaded.path, loaded.overrides)


def scenario4() -> dict[str, list[dict[str, float]]]:
    loaded, rec = recording("lee2021access_s4_cost", 0.5, 1.0)
    fourth = ContactSpec(
        frame="r_hand", mu=0.5, fmin=30, cop=CopBox(x=(-0.02, 0.02), y=(-0.02, 0.02))
    )
    planes = [*loaded.spec.contacts, fourth]
    cfg = {
        "params": "inline",
        "weights": [1e7],
        "wrench_weights": [1, 1, 0, 1, 1, 1],
        "impl": "native",
    }
    by_contacts = [
        {"planes": n, **medians(subset(loaded, 5, planes[:n]), rec, "to_osf", cfg)}
        for n in range(1, 5)
    ]
    by_tasks = [{"tasks": n, **medians(subset(loaded, n), rec, "to_osf", cfg)} for n in range(1, 6)]
    return {"contacts": by_contacts, "tasks": by_tasks}


def table3_access() -> list[dict[str, float]]:
    loaded, rec = recording("lee2021access_table3", 0.2, 0.7)
    rows = []
    for n in range(1, 6):
        sub = subset(loaded, n)
        osf = medians(sub, rec, "to_osf", {"params": "inline", "impl": "python"})
        rows.append(
            {
                "tasks": n,
                "dofs": sum(len(t.selected_axes) for t in sub.spec.tasks),
                "hqp": medians(sub, rec, "hqp", {"finals": ["torque"]})["total"],
                "to_osf": osf["total"],
                "to_osf_rt": osf["total"] - osf["params"],
            }
        )
    return rows


# -- pytest-benchmark entries -----------------------------------------------------------------


@pytest.mark.parametrize("entry", ["table3_iros", "table3_access"])
def test_osf_tables(benchmark, entry: str) -> None:
    fn = {"table3_iros": table3_iros, "table3_access": table3_access}[entry]
    result = benchmark.pedantic(fn, rounds=1, iterations=1)
    if isinstance(result, dict):
        for name, stages in result.items():
            benchmark.extra_info.update({f"{name}.{k}_us": v for k, v in stages.items()})
            assert stages["failures"] == 0
    else:
        benchmark.extra_info["rows"] = result


# -- tables ------------------------------------------------------------------------------------

PAPER_T3 = {"T1": 0.059, "T2": 0.068, "T3": 0.041, "T4": 0.099, "wrench": 0.038}
PAPER_CONV = {"T1": 1.416, "T2": 1.764, "T3": 1.380, "T4": 3.176, "wrench": 1.527}


def side_by_side(rows: dict[str, dict[str, float]], stages: list[str]) -> None:
    """Median / IQR / p99 [µs] per stage for each named column (e.g. impls)."""
    names = list(rows)
    print(f"{'stage':<14}" + "".join(f"{n + ' median/IQR/p99':>30}" for n in names))
    for stage in stages:
        if all(stage not in r for r in rows.values()):
            continue
        cells = []
        for r in rows.values():
            if stage in r:
                cells.append(f"{r[stage]:10.1f}{r[stage + '.iqr']:9.1f}{r[stage + '.p99']:11.1f}")
            else:
                cells.append(f"{'—':>30}")
        print(f"{stage:<14}" + "".join(cells))


STAGES = [
    "dynamics", "params", "build", "solve", "solve_native",
    "solve.T1", "solve.T2", "solve.T3", "solve.T4", "solve.wrench", "crossing", "total",
]  # fmt: skip


def table3_iros_table(t: dict[str, dict[str, float]], solver: str, impl: str) -> None:
    """OSF-HQP Table III: per level, the QP total and the full step, beside the paper's."""
    o, h = t["osf_hqp_cod"], t["hqp"]
    print(f"OSF-HQP Table III (TOCABI-like, same recorded states, {solver}, both impl: {impl})")
    print(f"{'level':<8} {'hqp':>9} {'osf_hqp':>9} {'ratio':>7}   paper conv / proposed [ms]")
    for lv in ("T1", "T2", "T3", "T4", "wrench"):
        hk = "solve.wrench" if lv == "wrench" else f"solve.L{lv[1:]}"
        hv = h.get(hk, h.get(f"solve.{lv}", float("nan")))
        ov = o.get(f"solve.{lv}", float("nan"))
        paper = f"{PAPER_CONV[lv]:.3f} / {PAPER_T3[lv]:.3f}"
        print(f"{lv:<8} {hv:9.1f} {ov:9.1f} {hv / ov:7.1f}   {paper}")
    print(
        f"{'QP sum':<8} {h['solve']:9.1f} {o['solve']:9.1f} {h['solve'] / o['solve']:7.1f}"
        "   9.263 / 0.303 (30.5x)"
    )
    print(
        f"full step: hqp {h['total']:.1f} µs (p99 {h['total.p99']:.1f}), osf_hqp "
        f"{o['total']:.1f} µs (p99 {o['total.p99']:.1f}), ratio {h['total'] / o['total']:.1f} "
        "(paper 9.8x, osf 0.94 ms)"
    )
    print(
        f"QP time without our Python layer (set-up + native call): hqp {native(h):.1f} µs, "
        f"osf_hqp {native(o):.1f} µs, ratio {native(h) / native(o):.1f}"
    )
    print(f"failures: hqp {h['failures']:.0f}, osf_hqp {o['failures']:.0f}")
    print()


# -- the authors' cycle -----------------------------------------------------------------------

#: libdwbc's OSF-HQP cycle (example/main.cpp's loop: kinematics and dynamics, contact space,
#: two task QPs, the contact QP) built from the authors' repository and run on a 2-vCPU AMD EPYC
#: VM of this project's kind, with qpOASES: the range of medians over its runs [µs]
LIBDWBC_CYCLE: dict[str, tuple[float, float]] = {
    "kinematics + dynamics": (43, 45),
    "contact space (params)": (78, 81),
    "task QPs": (104, 110),
    "contact QP": (14, 15),
    "total": (240, 252),
}

#: (solver, mode) of the cycle and of Table I: qpOASES as `wbcbench run` calls it by default
#: (cold: CasADi's usage on a fresh object every tick), CasADi's usage hot, the authors' usage,
#: and DAQP
USAGES: tuple[tuple[str, str], ...] = (
    ("qpoases", "cold"),
    ("qpoases", "hot"),
    ("qpoases_libdwbc", "hot"),
    ("daqp", "cold"),
    ("daqp", "hot"),
)
#: Table I leaves cold qpOASES out: its initial homotopy takes 10-90 ms a tick on to_osf's QP
#: (benchmarks/bench_qpoases.py measures it per level)
TABLE1_USAGES = tuple(u for u in USAGES if u != ("qpoases", "cold"))


def cycle_stages(r: dict[str, float]) -> dict[str, tuple[float, float]]:
    """Our stages in the authors' split (median, p99) [µs]: dynamics; parameters; the task QPs
    (solve of T1 and T2, with the build of their data); the contact QP; total."""
    tasks = r["solve.T1"] + r["solve.T2"] + r["build"]
    return {
        "kinematics + dynamics": (r["dynamics"], r["dynamics.p99"]),
        "contact space (params)": (r["params"], r["params.p99"]),
        "task QPs": (tasks, float("nan")),
        "contact QP": (r["solve.wrench"], r["solve.wrench.p99"]),
        "total": (r["total"], r["total.p99"]),
    }


def authors_cycle(repeats: int) -> None:
    """libdwbc's OSF-HQP cycle, native, per stage, each usage ``repeats`` times interleaved."""
    loaded, rec = recording("libdwbc_osf_cycle", 0.0, 2.0)
    print(
        f"The authors' OSF-HQP cycle (libdwbc_osf_cycle, {len(rec)} recorded states, native, "
        "params periodic:1), median [µs] (p99) per run"
    )
    runs: dict[tuple[str, str], list[dict[str, float]]] = {u: [] for u in USAGES}
    for _ in range(repeats):
        for solver, mode in USAGES:
            if solver in available_solvers():
                cfg = {"impl": "native", "params": "periodic:1"}
                runs[(solver, mode)].append(medians(loaded, rec, "osf_hqp", cfg, solver, mode))
    head = "".join(f"{s + ' ' + m:>26}" for (s, m), r in runs.items() if r)
    print(f"{'stage':<24}{'libdwbc (EPYC VM)':>20}{head}")
    for stage, (lo, hi) in LIBDWBC_CYCLE.items():
        cells = ""
        for r in runs.values():
            if not r:
                continue
            vals = [cycle_stages(x)[stage] for x in r]
            med = " / ".join(f"{v[0]:.0f}" for v in vals)
            p99 = max(v[1] for v in vals)
            cells += f"{med + (f' ({p99:.0f})' if p99 == p99 else ''):>26}"
        print(f"{stage:<24}{f'{lo:.0f}-{hi:.0f}':>20}{cells}")
    fails = {f"{s} {m}": sum(x["failures"] for x in r) for (s, m), r in runs.items() if r}
    print(f"failures: {fails}")
    print()


def table1_inline(repeats: int) -> None:
    """OSF-HQP Table I, closed-loop states 0-5 s, native, params inline: osf_hqp and to_osf."""
    loaded, rec = recording("lee2021iros_table1", 0.0, 5.0)
    print(
        f"Table I (lee2021iros_table1, {len(rec)} recorded states, native, params inline): "
        "median (p99) total and QP time [µs], per run"
    )
    print(f"{'usage':<22}{'osf_hqp total':>24}{'QP':>16}{'to_osf total':>24}{'QP':>16}")
    for solver, mode in TABLE1_USAGES:
        if solver not in available_solvers():
            continue
        for _ in range(repeats):
            cells = ""
            for controller in ("osf_hqp", "to_osf"):
                cfg = {"impl": "native", "params": "inline"}
                r = medians(loaded, rec, controller, cfg, solver, mode)
                cells += f"{r['total']:>14.0f} ({r['total.p99']:>6.0f}){r['solve']:>16.0f}"
                if r["failures"]:
                    cells += f" [{r['failures']:.0f} failed]"
            print(f"{solver + ' ' + mode:<22}{cells}")
    print()


def table3_libdwbc() -> None:
    """Table III with the paper's solver as its authors run it: hqp / osf_hqp per level, the
    ratio of medians and its interquartile range over the ticks (same states)."""
    loaded, rec = recording("lee2021iros_table1", 3.0, 4.0)
    solver, mode = "qpoases_libdwbc", "hot"
    ht: dict[str, np.ndarray] = {}
    ot: dict[str, np.ndarray] = {}
    h = medians(loaded, rec, "hqp", {"finals": ["wrench"], "impl": "native"}, solver, mode, ht)
    o = medians(loaded, rec, "osf_hqp", {"params": "inline", "impl": "native"}, solver, mode, ot)
    print(f"OSF-HQP Table III with {solver} (hot), {len(rec)} recorded states, both native")
    print(f"{'level':<8}{'hqp':>9}{'osf_hqp':>9}{'ratio':>7}{'per-tick IQR':>16}   paper [ms]")
    for lv in ("T1", "T2", "T3", "T4", "wrench"):
        hk = "solve.wrench" if lv == "wrench" else f"solve.L{lv[1:]}"
        hk = hk if hk in ht else f"solve.{lv}"
        ok = f"solve.{lv}"
        if hk not in ht or ok not in ot:
            continue
        q = np.quantile(ht[hk] / ot[ok], [0.25, 0.75])
        print(
            f"{lv:<8}{h[hk]:9.1f}{o[ok]:9.1f}{h[hk] / o[ok]:7.1f}{f'[{q[0]:.1f}, {q[1]:.1f}]':>16}"
            f"   {PAPER_CONV[lv]:.3f} / {PAPER_T3[lv]:.3f} ({PAPER_CONV[lv] / PAPER_T3[lv]:.1f}x)"
        )
    q = np.quantile(ht["solve"] / ot["solve"], [0.25, 0.75])
    print(
        f"{'QP sum':<8}{h['solve']:9.1f}{o['solve']:9.1f}{h['solve'] / o['solve']:7.1f}"
        f"{f'[{q[0]:.1f}, {q[1]:.1f}]':>16}   9.263 / 0.303 (30.5x)"
    )
    print(f"failures: hqp {h['failures']:.0f}, osf_hqp {o['failures']:.0f}")
    print()


def authors(repeats: int) -> None:
    print(f"load average {os.getloadavg()[0]:.2f} (2-core machine: compare within one run)")
    authors_cycle(repeats)
    table1_inline(repeats)
    table3_libdwbc()
    print(f"load average {os.getloadavg()[0]:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--authors-cycle",
        action="store_true",
        help="the authors' OSF-HQP cycle per stage, Table I inline and Table III with the "
        "paper's solver as they run it (qpoases_libdwbc)",
    )
    parser.add_argument("--repeats", type=int, default=3, help="runs per usage (--authors-cycle)")
    args = parser.parse_args()
    if args.authors_cycle:
        authors(args.repeats)
        return
    print(f"load average {os.getloadavg()[0]:.2f} (2-core machine: compare within one run)")
    for solver in ("daqp", "qpoases"):
        if solver not in available_solvers():
            continue
        for impl in ("python", "native"):
            table3_iros_table(table3_iros(solver, impl), solver, impl)
    print()
    for solver in ("daqp", "qpoases"):
        if solver not in available_solvers():
            continue
        runs = {impl: table3_iros(solver, impl) for impl in ("python", "native")}
        print(f"osf_hqp full tick, Table I, {solver}, params inline — per stage [µs]")
        side_by_side({impl: r["osf_hqp_cod"] for impl, r in runs.items()}, STAGES)
        for impl, r in runs.items():
            cod, svd = r["osf_hqp_cod"]["params"], r["osf_hqp_svd"]["params"]
            print(
                f"  {impl}: COD vs SVD parameter time {cod:.1f} vs {svd:.1f} µs, ratio "
                f"{svd / cod:.2f} (paper 1.55 vs 4.27 ms, 2.75); failures "
                f"{r['osf_hqp_cod']['failures']:.0f}"
            )
        print()
    print("Table III hqp / osf_hqp by backend (same states, impl: native): QP time, solver's")
    print("own share (set-up + native call), full step [µs]")
    print(
        f"{'backend':<10} {'hqp QP':>9} {'osf QP':>9} {'ratio':>6} {'own':>6}"
        f" {'hqp step':>9} {'osf step':>9} {'ratio':>6}  failures"
    )
    for solver in COMPARE:
        if solver not in available_solvers():
            continue
        r = table3_iros(solver, "native")
        h, o = r["hqp"], r["osf_hqp_cod"]
        print(
            f"{solver:<10} {h['solve']:9.1f} {o['solve']:9.1f} {h['solve'] / o['solve']:6.1f}"
            f" {native(h) / native(o):6.1f} {h['total']:9.1f} {o['total']:9.1f}"
            f" {h['total'] / o['total']:6.1f}  hqp {h['failures']:.0f}, osf_hqp {o['failures']:.0f}"
        )
    print()
    s4 = scenario4()
    print("TO-OSF Scenario #4 — to_osf (impl native) median [µs]: RT part (total − params)")
    for row in s4["contacts"]:
        print(
            f"  {row['planes']} planes: RT {row['total'] - row['params']:8.1f}"
            f"  QP {row['solve']:7.1f}  params {row['params']:7.1f}"
        )
    for row in s4["tasks"]:
        print(
            f"  {row['tasks']} tasks : RT {row['total'] - row['params']:8.1f}"
            f"  QP {row['solve']:7.1f}  params {row['params']:7.1f}"
        )
    print()
    print("TO-OSF Table 3 — step time [µs], double support, home posture (impl: python)")
    for row in table3_access():
        print(
            f"  {row['tasks']} tasks ({row['dofs']:2d} DoF): hqp {row['hqp']:8.1f}"
            f"  to_osf {row['to_osf']:8.1f}  (RT part {row['to_osf_rt']:7.1f})"
        )
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
