"""The ``wbcbench`` command line.

    wbcbench list
    wbcbench validate SCENARIO...
    wbcbench run SCENARIO [--controller NAME]... [--solver NAME]... [--out DIR] [--set KEY=VALUE]...
    wbcbench bench [--out DIR] [--sweep FILE] [--executor serial|dask]
    wbcbench sweep FILE [--out DIR] [--executor serial|dask] [--scheduler ADDRESS] [--dry-run]
    wbcbench sweep --scenario GLOB... --controller GLOB... --solver NAME... [--timing]
    wbcbench tables RESULTS_DIR      paper tables (Markdown + CSV) in RESULTS_DIR/tables
    wbcbench plots RESULTS_DIR       figures (PNG + SVG) in RESULTS_DIR/figures
    wbcbench solvers RESULTS_DIR     the solver report RESULTS_DIR/solver_report.md
    wbcbench solvers --sequences EXPORT_DIR [--solver NAME]... [--tier T]... [--mode M]...
    wbcbench export-qps RESULTS_DIR --out DIR   the dumped QPs as a qpbenchmark test set
    wbcbench replay PROBLEM.npz [--solver NAME]... [--tier T] [--mode M]

Errors a user can cause print one line (``error: …``) and exit with status 2; no traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
import scipy.linalg  # noqa: F401 - loads SciPy's own BLAS so that the thread limit reaches it
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from wbcbench.errors import WbcBenchError


def _cmd_list(args: argparse.Namespace) -> int:
    from wbcbench.bench.provenance import describe_lock_status, lock_status
    from wbcbench.controllers.registry import controller_class, controller_origins
    from wbcbench.qp import all_solvers
    from wbcbench.qp.hierarchy import STRATEGY_SUMMARY
    from wbcbench.robots.loader import available_robots, plugin_robots, third_party_robots
    from wbcbench.robots.third_party import THIRD_PARTY
    from wbcbench.scenarios.load import available_scenarios

    origins, broken = controller_origins()
    print("controllers:")
    for name, origin in origins.items():
        where = "" if origin.kind == "built-in" else f"  [{origin}]"
        print(f"  {name:<12} {controller_class(name).summary}{where}")
    for name, why in broken.items():
        print(f"  {name:<12} BROKEN: {why}")
    print("hierarchy strategies (hqp's `strategy`; lqp takes the QP ones):")
    for name, text in STRATEGY_SUMMARY.items():
        print(f"  {name:<12} {text}")
    print("solvers (every tier and mode, except where a named setting fixes its own):")
    for info in all_solvers():
        state = "available" if info["available"] else f"missing ({info.get('reason', '')})"
        line = f"  {info['name']:<20} {info.get('version') or '-':<12} {state:<9}"
        if info["summary"]:
            line += f"  {info['summary']}"
        if info["named_setting"] and info["available"]:
            line += f" [tier {', '.join(info['tiers'])}, mode {', '.join(info['modes'])} only]"
        if info["origin"] != "built-in":
            line += f"  [{info['origin']}]"
        print(line.rstrip())
    print("robots:")
    for name in available_robots():
        print(f"  {name}")
    for name, missing in third_party_robots().items():
        status = f"missing (pip install '{missing}')" if missing else "available"
        print(f"  {name:<14} {status}  {THIRD_PARTY[name].summary}")
    found, broken_robots = plugin_robots()
    for name, (robot, origin) in found.items():
        print(f"  {name:<14} {robot.summary}  [{origin}]")
    for name, why in broken_robots.items():
        print(f"  {name:<14} BROKEN: {why}")
    print("scenarios:")
    for name in available_scenarios():
        print(f"  {name}")
    from wbcbench import _native

    print(f"native module: {_native.describe_status()}")
    print("environment (installed packages against the lock):")
    for line in describe_lock_status(lock_status()):
        print(f"  {line}")
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    from wbcbench.robots.loader import simulation_model
    from wbcbench.robots.parity import PARITY_TOLERANCE, model_parity
    from wbcbench.runs import Planner
    from wbcbench.scenarios.initial import initial_state, self_collisions, sole_mismatches
    from wbcbench.scenarios.load import build_contact, sole_boxes
    from wbcbench.scenarios.preflight import (
        contact_rank,
        floor_collisions,
        sole_placements,
        task_reach,
    )

    planner = Planner()
    for loaded, robot in [planner.scenario(name, args.set) for name in args.scenarios]:
        spec = loaded.spec
        print(
            f"ok  {loaded.path}  ({spec.robot}, {len(spec.tasks)} tasks, "
            f"{len(spec.contacts)} contacts, {spec.duration:g} s, hash {loaded.hash})"
        )
        parity = model_parity(robot, states=5)
        print(
            f"    model: MuJoCo and Pinocchio agree to {parity.mass:.1e} (M), "
            f"{parity.bias:.1e} (bias forces), {parity.jacobian:.1e} (frame Jacobians), "
            f"relative, at {parity.states} random states"
        )
        if parity.worst > PARITY_TOLERANCE:
            print(
                f"    warning: the two libraries disagree by more than {PARITY_TOLERANCE:g}: the "
                "controllers' model is not the simulated one"
            )
        for note in robot.notes:
            print(f"    note: {note}")
        q0 = initial_state(loaded, robot)[0]
        contacts = [(build_contact(c, robot), c.contact_geometry) for c in spec.contacts]
        frames = [c.frame for c in spec.contacts]
        sim = simulation_model(robot, sole_boxes(spec, robot), spec.sim.excluded_pairs)
        for _, sentence in floor_collisions(sim, frames):
            print(f"    warning: {sentence}")
        geometry = [(c.frame, c.contact_geometry) for c in spec.contacts]
        for _, sentence in sole_placements(robot, q0, geometry):
            print(f"    warning: {sentence}")
        rank = contact_rank(robot, q0, [pc for pc, _ in contacts])
        if rank:
            print(f"    warning: {rank}")
        for _, sentence in task_reach(robot, q0, spec.tasks, [pc for pc, _ in contacts]):
            print(f"    warning: {sentence}")
        for _, sentence in sole_mismatches(robot, q0, contacts):
            print(f"    warning: {sentence}")
        overlaps = self_collisions(robot, q0)
        excluded = {frozenset(pair) for pair in spec.sim.excluded_pairs}
        overlaps = [o for o in overlaps if frozenset(o[:2]) not in excluded]
        if overlaps and spec.sim.self_collision:
            pairs = ", ".join(f"{a}–{b} {1e3 * depth:.1f} mm" for a, b, depth in overlaps)
            offered = [*spec.sim.excluded_pairs, *(o[:2] for o in overlaps)]
            listed = ", ".join(f"[{a}, {b}]" for a, b in offered)
            print(
                f"    note: at the initial posture {len(overlaps)} pairs of the robot's bodies "
                f"overlap ({pairs}); the simulation pushes them apart: set "
                f"'sim: {{self_collision: {{exclude: [{listed}]}}}}' to leave those pairs out, "
                "or 'sim: {self_collision: false}' to simulate contacts with the world only"
            )
    return 0


def _planned(
    scenarios: Sequence[str],
    controllers: Sequence[str],
    solvers: Sequence[str],
    tier: str,
    mode: str,
    overrides: Sequence[str] = (),
) -> list:
    """The runs of the matrix (:func:`wbcbench.runs.plan_matrix`), its notes printed."""
    from wbcbench.runs import plan_matrix

    runs, notes = plan_matrix(scenarios, controllers, solvers, tier, mode, overrides)
    for note in notes:
        print(f"note: {note}")
    return runs


def _run_matrix(runs: list, out: Path, show_progress: bool) -> pd.DataFrame:
    from wbcbench.bench.results import ResultsStore
    from wbcbench.bench.runner import code_version, execute, run_id

    store = ResultsStore(out)
    version, planned = code_version(store), []
    for i, run in enumerate(runs, 1):
        planned.append(run_id(run, version))
        label = f"[{i}/{len(runs)}] {run.name} · {run.controller} · {run.settings.solver}"
        n_ticks = round(run.scenario.spec.duration * run.scenario.spec.control_rate)
        with tqdm(
            total=n_ticks, desc=label, unit="tick", disable=not show_progress, leave=False
        ) as bar:

            def progress(done: int, total: int, bar: tqdm = bar) -> None:
                if done % 100 == 0 or done == total:
                    bar.n = done
                    bar.refresh()

            record = execute(run, store, progress=progress)
        if record is None:
            print(f"{label}: already in {out}, skipped")
        else:
            row = record.row
            note = f" — {row['message']}" if row.get("message") else ""
            print(f"{label}: {row['status']}{note}")
    store.refresh_mirror()
    runs_table = store.runs()  # this command's rows, not what the folder held before
    return summary_table(runs_table[runs_table["run_id"].isin(planned)], store.metrics())


def summary_table(runs: pd.DataFrame, metrics: pd.DataFrame) -> pd.DataFrame:
    """One line per run: status, each task's mean error, median step and solve times."""
    if runs.empty:
        return runs
    columns = ["run_id", "scenario", "controller", "solver", "status", "fell", "sim_duration_s"]
    table = runs[[c for c in columns if c in runs.columns]].copy()
    if not metrics.empty:
        err = metrics[metrics["metric"].isin(["err_mean"])]
        err = err.assign(col=err["task"] + " [" + err["unit"] + "]")
        # dropna=False: a run whose errors are all NaN (e.g. no tick in the window) still shows
        wide = err.pivot_table(
            index="run_id", columns="col", values="value", aggfunc="first", dropna=False
        )
        times = metrics[metrics["metric"].isin(["t_total_median_us", "t_solve_median_us"])]
        times = times[times["task"] == "*"]
        wide_t = times.pivot_table(index="run_id", columns="metric", values="value", dropna=False)
        table = table.join(wide, on="run_id").join(wide_t, on="run_id")
    return table.drop(columns=["run_id"])


def _print_table(table: pd.DataFrame) -> None:
    if table.empty:
        print("(no runs)")
        return
    with pd.option_context("display.width", 200, "display.max_columns", 50):
        print(table.to_string(index=False, float_format=lambda x: f"{x:.4g}"))


def _check_solvers(solvers: Sequence[str], tier: str, mode: str) -> None:
    """Look every solver name up (and its tier and mode) before anything runs."""
    from wbcbench.qp import make_solver

    for s in solvers:
        make_solver(s, tier=tier, mode=mode)


def _cmd_run(args: argparse.Namespace) -> int:
    from wbcbench.qp import default_solver

    controllers = args.controller or ["qp_wbc"]
    solvers = args.solver or [default_solver()]
    _check_solvers(solvers, args.tier, args.mode)
    runs = _planned([args.scenario], controllers, solvers, args.tier, args.mode, args.set)
    out = Path(args.out)
    table = _run_matrix(runs, out, not args.no_progress)
    _print_table(table)
    print(f"results in {out}/ (runs.csv, metrics.csv, logs/, provenance.json)")
    return 0 if (table["status"] == "ok").all() else 1


def _print_suspects(out: Path) -> None:
    """Say which runs of ``out`` ended ok with a suspect task error (summary.md lists them)."""
    from wbcbench.bench.results import ResultsStore
    from wbcbench.report.summary import SUSPECT_FACTOR, suspect_lines, suspects

    store = ResultsStore(out)
    odd = suspects(store.runs(), store.metrics())
    if len(odd):
        print(
            f"suspect: {len(odd)} runs ended ok with a task error over {SUSPECT_FACTOR:g}× "
            "their scenario's usual one"
        )
        for line in suspect_lines(odd):
            print(line)


def _run_plan(plan, args: argparse.Namespace, out: Path, bench: bool = False) -> int:
    """Run a plan and print what it did; the exit status: 1 when a planned row is ``failed``
    or ``error`` (for ``bench``, only ``error``), else 0."""
    from wbcbench.bench.sweep import run_sweep

    print(f"{len(plan.jobs)} runs planned ({plan.file})")
    for line in plan.not_applicable:
        print(f"  not applicable: {line}")
    if args.dry_run:
        for job in plan.jobs:
            print(f"  {job.label}" + (f"  [skip: {job.skip_reason}]" if job.skip_reason else ""))
        return 0
    report = run_sweep(
        plan,
        out,
        executor=args.executor,
        scheduler=args.scheduler,
        show_progress=not args.no_progress,
        rerun="all" if args.force else "failed" if args.retry_failed else "none",
        reuse=args.reuse,
    )
    reused = f", {report.reused} of them copied from {args.reuse}" if args.reuse else ""
    print(f"{report.computed} rows computed, {report.resumed} already in {out} (resumed{reused})")
    if report.busy_line():
        print(report.busy_line(), file=sys.stderr)
    _print_suspects(out)
    for line in report.failed[:5]:
        print(f"  failed: {line}")
    if len(report.failed) > 5:
        print(f"  … and {len(report.failed) - 5} more (runs.csv has every message)")
    if report.not_ok:
        counts = ", ".join(f"{n} {status}" for status, n in sorted(report.not_ok.items()))
        print(
            f"not ok: {counts} of {len(plan.jobs)} planned rows "
            "(--retry-failed recomputes them, --force recomputes every row)"
        )
    if bench:  # solver failures are findings of a benchmark; an exception is a defect
        return 1 if report.not_ok.get("error") else 0
    return 1 if report.not_ok else 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from wbcbench.bench.sweep import (
        DEFAULT_RECORDERS,
        load_sweep_file,
        plan_from_names,
        plan_sweep,
    )

    if args.file:
        if args.scenario or args.controller or args.solver:
            raise WbcBenchError("give a sweep FILE or --scenario/--controller/--solver, not both")
        plan = plan_sweep(*load_sweep_file(args.file))
    else:
        plan = plan_from_names(
            args.scenario or ["*"],
            args.controller or ["*"],
            args.solver or (["native"] if args.timing else ["default"]),
            [args.tier],
            [args.mode or ("hot" if args.timing else "cold")],
            args.set,
            kind="timing" if args.timing else "tracking",
            record_with=args.record_with or DEFAULT_RECORDERS,
        )
    return _run_plan(plan, args, Path(args.out))


def _files_backend() -> None:
    """Figures are written to files: matplotlib's Agg backend, chosen here and not at the
    report modules' import, so that a notebook importing them keeps its inline plots."""
    import matplotlib

    matplotlib.use("Agg")


def write_reports(out: Path) -> None:
    """Paper tables, summary, solver report and figures of a results folder."""
    _files_backend()
    from wbcbench.bench.results import ResultsStore
    from wbcbench.report.plots import write_plots
    from wbcbench.report.solvers import write_report
    from wbcbench.report.summary import write_summary
    from wbcbench.report.tables import write_tables

    store = ResultsStore(out)
    print(f"tables: {write_tables(out)}")
    print(f"summary: {write_summary(out, store.runs(), store.metrics())}")
    print(f"solver report: {write_report(out)}")
    print(f"figures: {len(write_plots(out))} files in {out / 'figures'}")
    from wbcbench.report.robustness import write_robustness

    robustness = write_robustness(out)
    if robustness:
        print(f"robustness: {', '.join(str(p.relative_to(out)) for p in robustness)}")


def _cmd_bench(args: argparse.Namespace) -> int:
    from wbcbench.bench.sweep import load_sweep_file, plan_sweep

    out = Path(args.out)
    if args.scenario or args.controller or args.solver:
        # the former matrix form: closed-loop runs of the named combinations
        from wbcbench.controllers.registry import available_controllers
        from wbcbench.qp import available_backends
        from wbcbench.scenarios.load import available_scenarios

        controllers = args.controller or available_controllers()
        solvers = args.solver or available_backends()
        _check_solvers(solvers, args.tier, args.mode)
        scenarios = args.scenario or available_scenarios()
        runs = _planned(scenarios, controllers, solvers, args.tier, args.mode)
        table = _run_matrix(runs, out, not args.no_progress)
        _print_table(table)
    else:
        plan = plan_sweep(*load_sweep_file(args.sweep))
        code = _run_plan(plan, args, out, bench=True)
        if args.dry_run:
            return 0
    write_reports(out)
    print(f"results in {out}/ (summary.md, runs.csv, metrics.csv, tables/, figures/, ...)")
    return code if not (args.scenario or args.controller or args.solver) else 0


def _cmd_tables(args: argparse.Namespace) -> int:
    from wbcbench.report.tables import write_tables

    path = write_tables(_results_dir(args.results))
    print(path.read_text() if args.print else f"tables in {path.parent}/")
    print(f"recommendations: {path.parents[1] / 'recommendations.md'}")
    return 0


def _cmd_plots(args: argparse.Namespace) -> int:
    _files_backend()
    from wbcbench.report.plots import write_plots

    paths = write_plots(_results_dir(args.results))
    print(f"{len(paths)} figure files in {Path(args.results) / 'figures'}/")
    return 0


def _cmd_solvers(args: argparse.Namespace) -> int:
    if args.sequences:
        return _solve_sequences(args)
    if args.results is None:
        raise WbcBenchError(
            "wbcbench solvers: give a results folder (the solver report) or --sequences "
            "EXPORT_DIR (an export of wbcbench export-qps)"
        )
    from wbcbench.report.solvers import write_report

    print(f"solver report: {write_report(_results_dir(args.results))}")
    return 0


def _solve_sequences(args: argparse.Namespace) -> int:
    from wbcbench.bench.qp_export import TEST_SET
    from wbcbench.bench.qp_sequences import sequence_report, solve_sequences
    from wbcbench.qp import available_backends
    from wbcbench.qp.settings import check_mode, check_tier

    export = Path(args.sequences)
    if not (export / f"{TEST_SET}.parquet").exists():
        raise WbcBenchError(
            f"{export}: no {TEST_SET}.parquet; make one with wbcbench export-qps RESULTS --out "
            f"{export}"
        )
    tiers, modes = args.tier or ["default"], args.mode or ["hot", "warm"]
    for tier in tiers:
        check_tier(tier)
    for mode in modes:
        check_mode(mode)
    from wbcbench.qp import solver_class

    solvers = args.solver or available_backends()
    for s in solvers:
        solver_class(s)  # an unknown name fails here, listing the installed ones
    rows = solve_sequences(export, solvers, tiers, modes, show_progress=not args.no_progress)
    rows.to_csv(export / "sequence_solves.csv", index=False)
    text = sequence_report(rows, export)
    (export / "sequence_report.md").write_text(text)
    print(text)
    print(f"rows: {export / 'sequence_solves.csv'}")
    return 0


def _cmd_export_qps(args: argparse.Namespace) -> int:
    from wbcbench.bench.qp_export import export_qps

    summary = export_qps(_results_dir(args.results), args.out, show_progress=not args.no_progress)
    print("\n".join(summary.lines()))
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from wbcbench.bench.solver_comparison import describe_problem, replay_problem
    from wbcbench.qp.settings import check_mode, check_tier

    path = Path(args.problem)
    if not path.exists():
        raise WbcBenchError(f"{path}: no such problem file")
    check_tier(args.tier)
    check_mode(args.mode)
    from wbcbench.qp import available_backends

    solvers = args.solver or available_backends()
    _check_solvers(solvers, args.tier, args.mode)
    print(describe_problem(path))
    _print_table(replay_problem(path, solvers, args.tier, args.mode))
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from wbcbench.report.compare import markdown

    ignore = [k.strip() for item in args.ignore or [] for k in item.split(",") if k.strip()]
    text = markdown(_results_dir(args.before), _results_dir(args.after), ignore)
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


def _results_dir(path: str) -> Path:
    folder = Path(path)
    if not folder.is_dir():
        raise WbcBenchError(f"{folder}: no such results folder")
    return folder


def add_set_option(p: argparse.ArgumentParser) -> None:
    """``--set KEY=VALUE``: a scenario override, validated like the file."""
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario field by its dotted path, validated like the file (repeatable)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="wbcbench", description="Benchmark humanoid whole-body controllers and QP solvers."
    )
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("list", help="controllers, solvers, robots and scenarios").set_defaults(
        func=_cmd_list
    )

    p = sub.add_parser("validate", help="validate scenario files against the schema and robot")
    p.add_argument(
        "scenarios", nargs="+", metavar="SCENARIO", help="scenario files or names in scenarios/"
    )
    add_set_option(p)
    p.set_defaults(func=_cmd_validate)

    def run_options(
        p: argparse.ArgumentParser, out_default: str, mode_default: str | None = "cold"
    ) -> None:
        p.add_argument(
            "--controller",
            action="append",
            metavar="NAME",
            help="a controller (repeatable; `wbcbench list` names them)",
        )
        p.add_argument(
            "--solver",
            action="append",
            metavar="NAME",
            help="a QP backend (repeatable; `default`, `native`, `all` or names); kin_hqp, "
            "which solves with its own hls, runs once whatever this says",
        )
        p.add_argument("--tier", default="default", help="accuracy tier: default, low, mid, high")
        p.add_argument(
            "--mode",
            default=mode_default,
            help="solver mode: cold, warm, hot "
            + (
                "(default: cold, hot with --timing)"
                if mode_default is None
                else "(default: %(default)s)"
            ),
        )
        p.add_argument("--out", default=out_default, metavar="DIR", help="results folder")
        p.add_argument(
            "--no-progress",
            action="store_true",
            help="no progress bar (it is off anyway when stdout is not a terminal)",
        )

    p = sub.add_parser("run", help="closed-loop runs of one scenario")
    p.add_argument("scenario", metavar="SCENARIO", help="a scenario file or a name in scenarios/")
    add_set_option(p)
    run_options(p, "results/run")
    p.set_defaults(func=_cmd_run)

    def sweep_options(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--executor",
            default="serial",
            choices=["serial", "dask"],
            help="where closed-loop runs execute (timing runs are always serial)",
        )
        p.add_argument(
            "--scheduler",
            metavar="ADDRESS",
            help="address of an existing dask scheduler (default: a local cluster)",
        )
        p.add_argument("--dry-run", action="store_true", help="validate and list the runs only")
        rerun = p.add_mutually_exclusive_group()
        rerun.add_argument(
            "--retry-failed",
            action="store_true",
            help="recompute the planned rows stored as failed or error (others resume)",
        )
        rerun.add_argument(
            "--force", action="store_true", help="recompute every planned row, stored or not"
        )
        p.add_argument(
            "--reuse",
            metavar="RESULTS_DIR",
            help="copy the closed-loop and timing rows another results folder holds for the "
            "same runs of the same code (e.g. make bench's results) instead of computing them",
        )

    p = sub.add_parser("bench", help="the default sweep, then tables, solver report and figures")
    p.add_argument(
        "--scenario",
        action="append",
        metavar="NAME",
        help="closed-loop runs of these scenarios instead of the sweep file (repeatable)",
    )
    p.add_argument(
        "--sweep", default="sweeps/default.yaml", metavar="FILE", help="the sweep file to run"
    )
    run_options(p, "results")
    sweep_options(p)
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("sweep", help="run a sweep file (or a matrix of names and globs)")
    p.add_argument("file", nargs="?", metavar="FILE", help="a sweep file (sweeps/*.yaml)")
    p.add_argument(
        "--scenario", action="append", metavar="GLOB", help="scenario names or globs (repeatable)"
    )
    add_set_option(p)
    p.add_argument(
        "--timing",
        action="store_true",
        help="open-loop replay timing runs (default mode hot, as in the sweep files)",
    )
    p.add_argument(
        "--record-with",
        action="append",
        metavar="CONTROLLER",
        help="with --timing: the controllers that record the replayed states, in order of "
        "preference (default: qp_wbc, then lqp, then to_osf, as the default sweep)",
    )
    run_options(p, "results", mode_default=None)
    sweep_options(p)
    p.set_defaults(func=_cmd_sweep)

    for name, func, text in (
        ("tables", _cmd_tables, "paper tables beside ours (Markdown + CSV)"),
        ("plots", _cmd_plots, "figures (PNG + SVG)"),
    ):
        p = sub.add_parser(name, help=text)
        p.add_argument("results", metavar="RESULTS_DIR", help="a results folder of a sweep")
        if name == "tables":
            p.add_argument("--print", action="store_true", help="print the tables")
        p.set_defaults(func=func)

    p = sub.add_parser(
        "solvers",
        help="the QP solver comparison report of a results folder, or (--sequences) the "
        "backends on an exported test set's sequences, solved tick after tick as a controller",
    )
    p.add_argument("results", metavar="RESULTS_DIR", nargs="?", help="a results folder")
    p.add_argument(
        "--sequences", metavar="EXPORT_DIR", help="a test set written by wbcbench export-qps"
    )
    p.add_argument("--solver", action="append", metavar="NAME", help="a QP backend (repeatable)")
    p.add_argument("--tier", action="append", help="accuracy tier (repeatable; default: default)")
    p.add_argument("--mode", action="append", help="hot, warm or cold (repeatable; hot and warm)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_solvers)

    p = sub.add_parser(
        "export-qps",
        help="the QPs a sweep dumped, as a qpbenchmark test set (Parquet + TestSet module)",
    )
    p.add_argument("results", metavar="RESULTS_DIR", help="a results folder with problems/")
    p.add_argument("--out", required=True, metavar="DIR", help="where the test set goes")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_export_qps)

    p = sub.add_parser(
        "compare",
        help="two results folders side by side (before / after a change): the change per "
        "combination, marked significant only outside the noise",
    )
    p.add_argument("before", metavar="A", help="the results folder before the change")
    p.add_argument("after", metavar="B", help="the results folder after the change")
    p.add_argument("--out", metavar="FILE.md", help="also write the comparison to this file")
    p.add_argument(
        "--ignore",
        action="append",
        metavar="KEY",
        help="match runs that differ only in this key (repeatable, or comma-separated): "
        "scenario, robot, controller, controller_config, solver, tier, mode, impl, duration, "
        "ticks, recorder, overrides, settings",
    )
    p.set_defaults(func=_cmd_compare)

    p = sub.add_parser("replay", help="solve a dumped QP (.npz) again with one or more solvers")
    p.add_argument("problem", metavar="PROBLEM.npz", help="a QP saved by a run or a sweep")
    p.add_argument("--solver", action="append", metavar="NAME", help="a QP backend (repeatable)")
    p.add_argument("--tier", default="default", help="accuracy tier: default, low, mid, high")
    p.add_argument("--mode", default="cold", help="solver mode: cold, warm, hot")
    p.set_defaults(func=_cmd_replay)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if hasattr(args, "no_progress") and not (sys.stdout.isatty() and sys.stderr.isatty()):
        args.no_progress = True  # a bar redrawn with \r only clutters a log file
    # One BLAS thread: the control loop's matrices are small, and a second BLAS thread on a
    # 2-core machine turns microsecond operations into millisecond spikes.
    threadpool_limits(1)
    try:
        code = int(args.func(args))
        sys.stdout.flush()  # a closed pipe is found here, not in the interpreter's last flush
        return code
    except WbcBenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: finished runs are saved; rerun to resume", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of the output went away (``wbcbench validate … | head``): stop quietly,
        # and send what Python would still flush at exit nowhere
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, what a shell reports for a command a closed pipe ended


if __name__ == "__main__":
    sys.exit(main())
