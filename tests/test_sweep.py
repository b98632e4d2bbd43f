"""Sweeps: validation before running, resume after an interruption, failures as rows, dask."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from wbcbench.bench.sweep import load_sweep_file, plan_sweep, run_sweep
from wbcbench.errors import ScenarioError
from wbcbench.qp import Solution, SolutionStatus

TINY = """\
version: 1
tracking:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [{tracking_solvers}]
    set: ["duration=0.06", "metrics.window=[0.0, 0.06]", "metrics.timing_warmup=5"]
timing:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [{timing_solvers}]
    modes: [cold]
    ticks: 12
    warmup: 2
    probe_ticks: 5
    set: ["duration=0.3"]
"""


def write(tmp_path: Path, text: str, name: str = "sweep.yaml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def tiny(tmp_path: Path, tracking: str = "proxqp, daqp", timing: str = "proxqp, daqp") -> str:
    return write(tmp_path, TINY.format(tracking_solvers=tracking, timing_solvers=timing))


def plan(path: str):
    return plan_sweep(*load_sweep_file(path))


@pytest.mark.parametrize(
    ("text", "key", "words"),
    [
        ("version: 1\ntracking:\n  - scenario: [x]\n", "tracking[0].scenario", ["unknown key"]),
        (
            "version: 1\ntracking:\n  - controllers: [nope]\n",
            "tracking[0].controllers[0]",
            ["unknown controller 'nope'", "qp_wbc"],
        ),
        (
            "version: 1\ntiming:\n  - solvers: [proxqp, nope]\n",
            "timing[0].solvers[1]",
            ["unknown solver 'nope'", "proxqp", "native"],
        ),
        (
            "version: 1\ntracking:\n  - modes: [tepid]\n",
            "tracking[0].modes[0]",
            ["'cold'", "'hot'"],
        ),
        (
            "version: 1\ntracking:\n  - scenarios: [tocabi_stand_sway]\n    set: [duratoin=3]\n",
            "tracking[0].variants[0]",
            ["tocabi_stand_sway", "duratoin"],
        ),
        (
            "version: 1\ntracking:\n  - scenarios: [tocabi_stand_sway]\n"
            "    configs: {qp_wbc: [{variables: half}]}\n",
            "tracking[0].configs.qp_wbc[0].variables",
            ["'full'", "'eliminated'"],
        ),
        (
            "version: 1\ntracking:\n  - scenarios: [no_such]\n",
            "tracking[0].scenarios[0]",
            ["no_such"],
        ),
        (
            "version: 1\ntiming:\n  - scenarios: [ahn_dof_scaling]\n"
            "    robots: [tocabi_dof20, tocabi_dof99]\n",
            "timing[0].robots[1]",
            ["unknown robot 'tocabi_dof99'", "valid choices: comanplus_like", "tocabi_dof45"],
        ),
        (
            "version: 1\ntiming:\n  - scenarios: [ahn_dof_scaling]\n    record_with: [lpq]\n",
            "timing[0].record_with[0]",
            ["unknown controller 'lpq'", "lqp", "rc_lqp"],
        ),
        (
            "version: 1\ntiming:\n  - solvers: [osqp, osqp_libdwbc]\n    modes: [cold, warm]\n",
            "timing[0].solvers[1]",
            [
                "osqp_libdwbc runs at tier default and mode hot only",
                "tiers default × modes cold, warm",
                "`osqp` runs OSQP at any tier",
            ],
        ),
        (
            "version: 1\nsolver_comparison:\n  reference_solver: osqp_libdwbc\n",
            "solver_comparison.reference_solver",
            ["osqp_libdwbc does not run at tier high"],
        ),
        (
            "version: 1\nsolver_comparison:\n  dump_solver: dapq\n",
            "solver_comparison.dump_solver[0]",
            ["unknown solver 'dapq'", "daqp", "or one of default, native, all"],
        ),
        (
            "version: 1\ntracking:\n  - scenarios: [ahn_dof_scaling]\n    check_factor: -1\n",
            "tracking[0].check_factor",
            ["greater than 0"],
        ),
        (
            "version: 1\ntracking:\n  - scenarios: [lee2021access_s2_feasibility]\n"
            "    configs: {to_osf: [{weights: []}]}\n",
            "tracking[0].configs.to_osf[0].weights",
            ["non-empty list of positive numbers"],
        ),
    ],
)
def test_a_bad_sweep_file_names_the_file_the_key_and_the_choices(
    tmp_path: Path, text: str, key: str, words: list[str]
) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as err:
        plan(path)
    message = str(err.value)
    assert message.startswith(f"{path}: {key}:"), message
    for word in words:
        assert word in message


def test_a_named_setting_is_planned_at_its_own_tier_and_mode_and_runs_by_name(
    tmp_path: Path,
) -> None:
    """``solvers: [osqp, osqp_libdwbc]`` over modes the setting does not all run at: the others
    are dropped (and said so), the setting's runs are rows under its name."""
    text = """\
version: 1
tracking:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [osqp, osqp_libdwbc]
    tiers: [default, mid]
    modes: [cold, hot]
    set: ["duration=0.03", "metrics.window=[0.0, 0.03]", "metrics.timing_warmup=5"]
solver_comparison:
  solvers: [all]
"""
    p = plan(write(tmp_path, text))
    planned = {(j.run.settings.solver, j.run.settings.tier, j.run.settings.mode) for j in p.jobs}
    assert {x for x in planned if x[0] == "osqp_libdwbc"} == {("osqp_libdwbc", "default", "hot")}
    assert len({x for x in planned if x[0] == "osqp"}) == 4
    note = (
        " · osqp_libdwbc: runs at tier default, mode hot only; the matrix's other tiers × "
        "modes are not planned"
    )
    assert f"tracking[0]{note}" in p.not_applicable
    assert f"solver_comparison{note}" in p.not_applicable
    assert "osqp_libdwbc" in p.comparison_solvers
    # run only the setting's row
    p.jobs = [j for j in p.jobs if j.run.settings.solver == "osqp_libdwbc"]
    p.comparison = None
    report = run_sweep(p, tmp_path / "out", show_progress=False)
    assert report.computed == 1 and not report.failed
    runs = pd.read_csv(tmp_path / "out" / "runs.csv")
    assert runs[["solver", "tier", "mode", "status"]].values.tolist() == [
        ["osqp_libdwbc", "default", "hot", "ok"]
    ]


def test_every_controller_that_applies_is_planned_and_skips_are_recorded(tmp_path: Path) -> None:
    from wbcbench.controllers.registry import CONTROLLERS
    from wbcbench.scenarios.load import load_scenario

    path = write(
        tmp_path,
        "version: 1\ntiming:\n  - scenarios: [tocabi_stand_sway]\n    solvers: [proxqp, daqp]\n"
        "    skip: [{solver: daqp, reason: not today}]\n",
    )
    p = plan(path)
    spec = load_scenario("tocabi_stand_sway").spec
    applies = {n for n, cls in CONTROLLERS.items() if not cls.applies_to(spec)}
    assert {j.run.settings.controller for j in p.jobs} == applies
    assert {(j.run.settings.solver, j.skip_reason) for j in p.jobs} == {
        ("proxqp", ""),
        ("daqp", "not today"),
    }


def test_a_controller_with_its_own_solver_runs_once_whatever_the_backends(tmp_path: Path) -> None:
    """kin_hqp solves its hierarchy itself: one row under its solver's name, at tier default,
    and a note that the named backends do not apply to it."""
    path = write(
        tmp_path,
        "version: 1\ntracking:\n  - scenarios: [rqr_reach]\n    controllers: [kin_hqp]\n"
        "    solvers: [proxqp, daqp]\n    tiers: [default, high]\n    impls: [python]\n",
    )
    p = plan(path)
    assert [(j.run.settings.solver, j.run.settings.tier) for j in p.jobs] == [("hls", "default")]
    assert "tracking[0] · kin_hqp: solves with its own hls; solvers do not apply" in (
        p.not_applicable
    )


def final_table(out: Path) -> pd.DataFrame:
    """Rows by run id; tracking metrics exact, timing metrics by name only (times vary)."""
    runs = pd.read_csv(out / "runs.csv").set_index("run_id").sort_index()
    metrics = pd.read_csv(out / "metrics.csv")
    tracking = metrics[metrics["run_id"].isin(runs.index[runs["kind"] == "tracking"])]
    tracking = tracking[tracking["metric"].str.startswith("err")]
    tracking = tracking.assign(col=tracking["task"] + ":" + tracking["metric"])
    errors = tracking.pivot_table(index="run_id", columns="col", values="value")
    names = metrics.groupby("run_id")["metric"].apply(lambda m: ",".join(sorted(set(m))))
    table = runs[["kind", "controller", "solver", "status", "ticks"]].join(names)
    return table.join(errors)


def test_an_interrupted_sweep_resumes_without_losing_or_repeating_rows(tmp_path: Path) -> None:
    path = tiny(tmp_path)
    complete, interrupted = tmp_path / "complete", tmp_path / "interrupted"
    run_sweep(plan(path), complete, show_progress=False)

    first = run_sweep(plan(path), interrupted, show_progress=False, max_jobs=2)
    assert first.computed == 2
    kept = pd.read_csv(interrupted / "runs.csv")
    assert len(kept) == 2
    second = run_sweep(plan(path), interrupted, show_progress=False)
    assert second.resumed == 2 and second.computed == 2
    after = pd.read_csv(interrupted / "runs.csv")
    # the finished rows are untouched and none is computed twice
    pd.testing.assert_frame_equal(after.iloc[:2], kept)
    assert after["run_id"].is_unique
    pd.testing.assert_frame_equal(final_table(interrupted), final_table(complete))
    # a third run has nothing left to do
    assert run_sweep(plan(path), interrupted, show_progress=False).computed == 0


def test_a_sweep_reuses_another_folders_rows_of_the_same_runs(tmp_path: Path) -> None:
    """The reference sweep copies make bench's rows of its runs instead of computing them: the
    same rows, metrics and logs (thinned to its own log_every), and nothing else."""
    bench, reference = tmp_path / "bench", tmp_path / "reference"
    run_sweep(plan(tiny(tmp_path, "daqp", "daqp")), bench, show_progress=False)
    # the reference: a subset (daqp only of the tracking, no proxqp), a sparser log
    text = TINY.format(tracking_solvers="daqp, proxqp", timing_solvers="daqp")
    text = text.replace('timing_warmup=5"]', 'timing_warmup=5"]\n    log_every: 3')
    report = run_sweep(
        plan(write(tmp_path, text, "reference.yaml")), reference, show_progress=False, reuse=bench
    )
    assert report.reused == 2  # daqp's closed loop and its timing row
    assert report.computed == 1  # proxqp's closed loop, which make bench did not run
    ours, theirs = pd.read_csv(reference / "runs.csv"), pd.read_csv(bench / "runs.csv")
    copied = ours[ours["run_id"].isin(set(theirs["run_id"]))]
    assert len(copied) == 2
    pd.testing.assert_frame_equal(
        copied.reset_index(drop=True),
        theirs.set_index("run_id").loc[copied["run_id"]].reset_index()[copied.columns],
    )
    m_ours, m_theirs = pd.read_csv(reference / "metrics.csv"), pd.read_csv(bench / "metrics.csv")
    for rid in copied["run_id"]:
        pd.testing.assert_frame_equal(
            m_ours[m_ours["run_id"] == rid].reset_index(drop=True),
            m_theirs[m_theirs["run_id"] == rid].reset_index(drop=True),
        )
    tracking = copied[copied["kind"] == "tracking"]["run_id"].iloc[0]
    full = pd.read_parquet(bench / "logs" / f"{tracking}.parquet")
    thinned = pd.read_parquet(reference / "logs" / f"{tracking}.parquet")
    pd.testing.assert_frame_equal(thinned, full.iloc[::3].reset_index(drop=True))
    provenance = json.loads((reference / "provenance.json").read_text())
    assert provenance["reused"]["from"] == str(bench) and provenance["reused"]["runs"] == 2
    # a second reuse has nothing left to copy
    again = run_sweep(
        plan(write(tmp_path, text, "reference.yaml")), reference, show_progress=False, reuse=bench
    )
    assert (again.reused, again.computed, again.resumed) == (0, 0, 3)
    # --force recomputes every row: nothing is copied in its place
    forced = run_sweep(
        plan(write(tmp_path, text, "reference.yaml")),
        reference,
        show_progress=False,
        reuse=bench,
        rerun="all",
    )
    assert (forced.reused, forced.computed) == (0, 3)


@pytest.mark.usefixtures("runs_in_process")
def test_a_solver_that_raises_or_lies_becomes_a_failure_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from wbcbench.qp.backends.daqp import DAQPSolver
    from wbcbench.qp.backends.quadprog import QuadprogSolver

    def raises(self, problem, guess, keep):
        raise RuntimeError("injected backend crash")

    def lies(self, problem, guess, keep):
        return Solution(SolutionStatus.SOLVED, x=np.zeros(problem.n), message="optimal")

    monkeypatch.setattr(DAQPSolver, "_solve_fresh", raises)
    # (the crash is injected into the Python handle: its C++ counterpart would bypass it)
    monkeypatch.setattr(DAQPSolver, "native_solver", lambda self: None)
    monkeypatch.setattr(QuadprogSolver, "_solve_fresh", lies)
    text = TINY.format(tracking_solvers="daqp, proxqp", timing_solvers="quadprog, proxqp")
    text = text.replace("duration=0.06", "duration=0.05").replace("0.0, 0.06]", "0.0, 0.05]") + (
        "solver_comparison:\n  scenarios: [tocabi_stand_sway]\n  controllers: [qp_wbc]\n"
        "  solvers: [quadprog, proxqp]\n  tiers: [default]\n  modes: [cold]\n"
        "  dump_ticks: 1\n  dump_after: 1\n"
    )
    report = run_sweep(plan(write(tmp_path, text)), tmp_path / "out", show_progress=False)
    runs = pd.read_csv(tmp_path / "out" / "runs.csv").set_index(["kind", "solver"])
    crash = runs.loc[("tracking", "daqp")]
    assert crash["status"] == "failed"
    assert "RuntimeError: injected backend crash" in crash["message"]
    lie = runs.loc[("timing", "quadprog")]
    assert lie["status"] == "failed"
    assert "reported solved but relative primal residual" in lie["message"]
    assert "(quadprog, " in lie["message"]
    # the sweep went on: the healthy solver's rows are there and fine
    assert runs.loc[("tracking", "proxqp"), "status"] == "ok"
    assert runs.loc[("timing", "proxqp"), "status"] == "ok"
    assert len(report.failed) == 2
    solves = pd.read_csv(tmp_path / "out" / "qp_solves.csv").set_index("solver")
    assert not solves.loc["quadprog", "valid"]
    assert solves.loc["quadprog", "message"].startswith("reported solved but primal residual")
    assert solves.loc["proxqp", "valid"]


def test_dask_and_serial_executors_give_the_same_tracking_numbers(tmp_path: Path) -> None:
    path = tiny(tmp_path, tracking="proxqp, daqp")
    run_sweep(plan_tracking_only(path), tmp_path / "serial", show_progress=False)
    run_sweep(plan_tracking_only(path), tmp_path / "dask", executor="dask", show_progress=False)
    a = pd.read_csv(tmp_path / "serial" / "metrics.csv")
    b = pd.read_csv(tmp_path / "dask" / "metrics.csv")
    key = ["run_id", "task", "metric"]
    a = a[a["metric"].str.startswith("err")].sort_values(key).reset_index(drop=True)
    b = b[b["metric"].str.startswith("err")].sort_values(key).reset_index(drop=True)
    assert len(a) > 0
    pd.testing.assert_frame_equal(a, b)


def plan_tracking_only(path: str):
    p = plan(path)
    p.jobs = [j for j in p.jobs if j.kind == "tracking"]
    return p


def test_robots_run_a_scenario_once_per_robot_each_its_own_hash_and_recording(
    tmp_path: Path,
) -> None:
    from wbcbench.bench.runner import run_id

    path = write(
        tmp_path,
        "version: 1\ntiming:\n  - scenarios: [ahn_dof_scaling]\n"
        "    robots: [tocabi_dof20, tocabi_like, tocabi_dof45, tocabi_dof20]\n"
        "    controllers: [lqp, rc_lqp]\n    solvers: [osqp]\n    record_with: [lqp]\n",
    )
    p = plan(path)
    robots = [j.run.scenario.spec.robot for j in p.jobs]
    assert robots == ["tocabi_dof20"] * 2 + ["tocabi_like"] * 2 + ["tocabi_dof45"] * 2
    assert [j.run.scenario.overrides for j in p.jobs[::2]] == [
        ("robot=tocabi_dof20",),
        ("robot=tocabi_like",),
        ("robot=tocabi_dof45",),
    ]
    assert len({j.run.scenario.hash for j in p.jobs}) == 3
    assert {j.options["recorder"] for j in p.jobs} == {"lqp"}
    # the row's settings keep the overrides, so a report can rebuild each run's scenario
    assert p.jobs[-1].extra["overrides"] == ["robot=tocabi_dof45"]
    ids = {run_id(j.run, "v", extra=j.extra) for j in p.jobs}
    assert len(ids) == 6  # resume tells every robot's rows apart
    # one recording per robot: the cache key is the scenario hash
    assert len(p.timing_by_scenario) == 3


@pytest.mark.usefixtures("runs_in_process")
def test_a_closed_loop_run_rejects_a_qp_reported_solved_that_is_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A backend wrapper that perturbs x on every third solve and still reports it solved."""
    from dataclasses import replace

    from wbcbench.controllers.base import ControllerContext

    class Liar:
        def __init__(self, inner) -> None:
            self.inner, self.calls = inner, 0

        def solve(self, problem, *args, **kwargs):
            sol = self.inner.solve(problem, *args, **kwargs)
            self.calls += 1
            if sol.success and self.calls % 3 == 1:
                return replace(sol, x=sol.x + 1.0)
            return sol

        def native_solver(self):
            return None  # the lie is told here: a C++ counterpart would bypass it

        def __getattr__(self, name):
            return getattr(self.inner, name)

    honest = ControllerContext.new_solver

    def new_solver(self, kind="task"):
        handle = honest(self, kind)
        return Liar(handle) if self.solver == "daqp" else handle

    monkeypatch.setattr(ControllerContext, "new_solver", new_solver)
    text = TINY.format(tracking_solvers="daqp, proxqp", timing_solvers="proxqp")
    text = text[: text.index("timing:")]
    report = run_sweep(plan(write(tmp_path, text)), tmp_path / "out", show_progress=False)
    runs = pd.read_csv(tmp_path / "out" / "runs.csv").set_index("solver")
    lie = runs.loc["daqp"]
    assert lie["status"] == "failed"
    assert lie["message"].startswith("reported solved but relative primal residual"), lie["message"]
    assert "(daqp, " in lie["message"] and "at t = 0.000 s" in lie["message"]
    assert "(20 of 60 ticks rejected)" in lie["message"]
    assert lie["failures"] == 20 and lie["ticks"] == 60
    # the sweep went on and the honest run is fine
    assert runs.loc["proxqp", "status"] == "ok"
    assert report.failed == [
        f"tracking tocabi_stand_sway · qp_wbc · daqp · cold: failed: {lie['message']}"
    ]
    log = pd.read_parquet(tmp_path / "out" / "logs" / f"{lie['run_id']}.parquet")
    assert list(log["ok"][:4]) == [0.0, 1.0, 1.0, 0.0]


@pytest.mark.usefixtures("runs_in_process")
def test_a_recorder_that_falls_inside_the_window_hands_over_to_the_next(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """record_with: [qp_wbc, lqp] with qp_wbc's run ending early: lqp records the window, the
    timing row is computed on its states and says so; a rerun resumes from the cache."""
    import json

    import wbcbench.bench.timing as timing

    real = timing.record_states

    def falls_early(run):
        rec = real(run)
        if run.controller == "qp_wbc":  # as if it fell after 0.1 s
            return rec.window(0.0, 100)
        return rec

    monkeypatch.setattr(timing, "record_states", falls_early)
    text = TINY.split("timing:")[0].format(tracking_solvers="quadprog") + (
        "timing:\n  - scenarios: [tocabi_stand_sway]\n    controllers: [qp_wbc]\n"
        "    solvers: [quadprog]\n    ticks: 12\n    warmup: 2\n    start: 0.2\n"
        "    record_with: [qp_wbc, lqp]\n    set: [duration=0.3]\n"
    )
    p = plan(write(tmp_path, text))
    p.jobs = [j for j in p.jobs if j.kind == "timing"]
    assert p.jobs[0].options["recorder"] == "qp_wbc"
    assert p.jobs[0].options["fallback_recorders"] == ["lqp"]
    run_sweep(p, tmp_path / "out", show_progress=False)
    row = pd.read_csv(tmp_path / "out" / "runs.csv").iloc[0]
    assert row["status"] == "ok", row["message"]
    assert row["ticks"] == 12
    assert json.loads(row["settings"])["recorder"] == "lqp"
    recordings = sorted(path.name for path in (tmp_path / "out" / "recordings").glob("*.npz"))
    assert [name.split("-")[-2] for name in recordings] == ["lqp", "qp_wbc"]


def test_the_resume_key_follows_the_code_not_the_commit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An edit of the code, committed or not, recomputes a stored row; docs do not count."""
    from wbcbench.bench import provenance

    tree = tmp_path / "pkg"
    (tree / "controllers").mkdir(parents=True)
    source = tree / "controllers" / "qp_wbc.py"
    source.write_text("tau = solve()\n")
    (tree / "README.md").write_text("docs\n")
    before = provenance.tree_hash(tree).hexdigest()
    (tree / "README.md").write_text("docs, edited\n")
    assert provenance.tree_hash(tree).hexdigest() == before
    source.write_text("tau = 0 * solve()\n")  # the zero-torque edit, not committed
    assert provenance.tree_hash(tree).hexdigest() != before

    path = tiny(tmp_path, tracking="daqp")
    p = plan_tracking_only(path)
    first = run_sweep(p, tmp_path / "out", show_progress=False)
    again = run_sweep(p, tmp_path / "out", show_progress=False)
    assert (first.computed, again.computed, again.resumed) == (1, 0, 1)
    monkeypatch.setattr(provenance, "source_hash", lambda: "0123456789ab")
    edited = run_sweep(p, tmp_path / "out", show_progress=False)
    assert (edited.computed, edited.resumed) == (1, 0)
    runs = pd.read_csv(tmp_path / "out" / "runs.csv")
    assert runs["code_version"].iloc[-1].startswith("0.1.0+src.0123456789ab@")


def test_a_store_repairs_what_a_kill_mid_write_leaves(tmp_path: Path) -> None:
    """A torn last line is cut and metrics without a run row are dropped, so the rerun
    matches an uninterrupted sweep: no row lost, duplicated or unreadable."""
    from wbcbench.bench.results import ResultsStore

    path = tiny(tmp_path, tracking="daqp, quadprog")
    clean = tmp_path / "clean"
    run_sweep(plan_tracking_only(path), clean, show_progress=False)
    killed = tmp_path / "killed"
    run_sweep(plan_tracking_only(path), killed, show_progress=False, max_jobs=1)
    # a kill after the metrics of the second run but before its row, then one mid-line
    stored = pd.read_csv(clean / "metrics.csv")
    second = stored[~stored["run_id"].isin(pd.read_csv(killed / "runs.csv")["run_id"])]
    with (killed / "metrics.csv").open("a") as fh:
        fh.write(second.to_csv(index=False, header=False))
    with (killed / "runs.csv").open("a") as fh:
        fh.write("deadbeef,tocabi_stand_sway,abc")  # torn: no newline
    store = ResultsStore(killed)
    assert any("torn" in r for r in store.repaired)
    assert any("unfinished runs" in r for r in store.repaired)
    report = run_sweep(plan_tracking_only(path), killed, show_progress=False)
    assert (report.computed, report.resumed) == (1, 1)
    runs_a, runs_b = (pd.read_csv(f / "runs.csv") for f in (clean, killed))
    assert sorted(runs_a["run_id"]) == sorted(runs_b["run_id"]) and runs_b["run_id"].is_unique
    key = ["run_id", "task", "metric"]
    a = pd.read_csv(clean / "metrics.csv").sort_values(key).reset_index(drop=True)
    b = pd.read_csv(killed / "metrics.csv").sort_values(key).reset_index(drop=True)
    assert len(a) == len(b)
    err = a["metric"].str.startswith("err")
    pd.testing.assert_frame_equal(a[err], b[err])
    mirror = pd.read_parquet(killed / "runs.parquet")
    assert len(mirror) == len(runs_b)


def test_impls_run_each_impl_of_a_native_controller_once_and_a_python_one_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from wbcbench.controllers.kin_hqp import KinHqp

    # every registered controller has a native impl: kin_hqp stands in for one without
    monkeypatch.setattr(KinHqp, "has_native", False)
    path = write(
        tmp_path,
        "version: 1\ntiming:\n  - scenarios: [tocabi_stand_sway, rqr_reach]\n"
        "    controllers: [qp_wbc, kin_hqp]\n    solvers: [daqp]\n    modes: [hot]\n"
        "    impls: [native, python, default]\n",
    )
    configs = sorted(
        (j.run.controller, json.dumps(j.run.settings.controller_config)) for j in plan(path).jobs
    )
    assert configs == [
        ("kin_hqp", "{}"),
        ("qp_wbc", '{"impl": "native"}'),
        ("qp_wbc", '{"impl": "python"}'),
        ("qp_wbc", "{}"),
    ]
    bad = write(tmp_path, "version: 1\ntiming:\n  - impls: [fast]\n", "bad.yaml")
    with pytest.raises(ScenarioError) as err:
        plan(bad)
    assert "timing[0].impls[0]" in str(err.value) and "'native'" in str(err.value)


def test_a_hung_solver_comparison_does_not_hang_the_sweep(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A comparison that cannot finish within its 10 ms guard: to the guard, a hung one."""
    import time

    text = (
        "version: 1\nsolver_comparison:\n  scenarios: [tocabi_stand_sway]\n"
        "  controllers: [qp_wbc]\n  solvers: [daqp]\n  wall_limit_s: 0.01\n"
    )
    t0 = time.perf_counter()
    run_sweep(plan(write(tmp_path, text)), tmp_path / "out", show_progress=False)
    assert time.perf_counter() - t0 < 60
    assert "solver comparison: exceeded the wall-clock guard of 0.01 s" in capsys.readouterr().out


def test_a_timing_row_records_what_the_machine_was_doing(tmp_path: Path) -> None:
    text = TINY.format(tracking_solvers="daqp", timing_solvers="daqp")
    text = "version: 1\n" + text[text.index("timing:") :]
    report = run_sweep(plan(write(tmp_path, text)), tmp_path / "out", show_progress=False)
    row = pd.read_csv(tmp_path / "out" / "runs.csv").iloc[0]
    conditions = json.loads(row["settings"])["conditions"]
    # the sweep's report counts the timing rows and keeps the busy ones' conditions, for one
    # line at the end instead of one per row
    assert report.timed == 1 and report.busy == ([conditions] if conditions["busy"] else [])
    assert {
        "load_1min",
        "load_1min_before",
        "load_per_core",
        "other_load_per_core",
        "other_cpu_per_core",
        "busy",
        "cpu",
        "cpu_mhz",
        "blas_threads",
    } <= set(conditions)
    assert conditions["blas_threads"] == 1  # the sweep times with one BLAS thread
    assert conditions["load_1min"] >= 0
    # busy is judged on the rest of the machine's CPU use over the timing itself, not on the
    # load average, which trails by a minute
    assert conditions["busy_basis"] == "cpu"
    assert conditions["busy"] == (conditions["other_cpu_per_core"] > 0.5)
    # and how fast a fixed workload ran just before and just after the replay [ms]
    before, after = conditions["speed_probe_ms"]
    assert before > 0 and after > 0


def test_a_cpu_watch_sees_other_processes_work_not_its_own() -> None:
    import os
    import subprocess
    import sys
    import time

    from wbcbench.bench.provenance import CpuWatch, machine_conditions

    cores = os.cpu_count() or 1
    watch = CpuWatch()
    # every core kept busy by other processes for a second: the watch sees (nearly) all of it
    spin = "import time\nt = time.perf_counter()\nwhile time.perf_counter() - t < 1.0: pass"
    procs = [subprocess.Popen([sys.executable, "-c", spin]) for _ in range(cores)]
    for proc in procs:
        proc.wait()
    conditions = machine_conditions(watch)
    assert conditions["busy_basis"] == "cpu" and conditions["busy"]
    assert 0.5 < conditions["other_cpu_per_core"] <= 1.0
    # the watch's own process is left out: what it spins on one core is not other work, so the
    # rest of the machine can have used at most the other cores (and jiffy rounding)
    own = CpuWatch()
    t, cpu = time.perf_counter(), time.process_time()
    while time.perf_counter() - t < 0.5:
        pass
    share = (time.process_time() - cpu) / ((time.perf_counter() - t) * cores)
    assert 0.0 <= own.other_per_core() <= 1.0 - share + 0.05


def test_provenance_keeps_each_code_version_that_wrote_to_a_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from wbcbench.bench import provenance as prov
    from wbcbench.bench import results

    results.ResultsStore(tmp_path)
    results.ResultsStore(tmp_path)  # same code: no new entry
    first = json.loads((tmp_path / "provenance.json").read_text())
    assert first["history"] == []
    monkeypatch.setattr(results, "provenance", lambda: {**prov.provenance(), "source_hash": "x"})
    results.ResultsStore(tmp_path)
    info = json.loads((tmp_path / "provenance.json").read_text())
    assert info["source_hash"] == "x"
    assert [h["source_hash"] for h in info["history"]] == [first["source_hash"]]


def test_the_controllers_of_one_scenario_and_solver_are_timed_together_interleaved(
    tmp_path: Path,
) -> None:
    """Two controllers on one scenario and solver are one group: they replay the same states
    in turns of ``interleave`` ticks, their rows name the group and its block, and they share
    the machine conditions (the probes around the whole group). With ``interleave: 0`` each
    row is timed alone."""
    text = TINY.format(tracking_solvers="daqp", timing_solvers="daqp")
    text = "version: 1\n" + text[text.index("timing:") :]
    text = text.replace("controllers: [qp_wbc]", "controllers: [qp_wbc, hqp]")
    report = run_sweep(plan(write(tmp_path, text)), tmp_path / "out", show_progress=False)
    assert report.timed == 2
    runs = pd.read_csv(tmp_path / "out" / "runs.csv")
    assert sorted(runs["controller"]) == ["hqp", "qp_wbc"] and set(runs["status"]) == {"ok"}
    conditions = [json.loads(s)["conditions"] for s in runs["settings"]]
    assert conditions[0] == conditions[1]
    group = conditions[0]["interleaved"]
    assert group["rows"] == 2 and group["block_ticks"] == 10 and len(group["group"]) == 12
    # every tick of each was replayed and timed
    assert list(runs["ticks"]) == [12, 12]

    alone = text.replace("probe_ticks: 5", "probe_ticks: 5\n    interleave: 0")
    run_sweep(plan(write(tmp_path, alone, "alone.yaml")), tmp_path / "alone", show_progress=False)
    runs = pd.read_csv(tmp_path / "alone" / "runs.csv")
    conditions = [json.loads(s)["conditions"] for s in runs["settings"]]
    assert all("interleaved" not in c for c in conditions)


def test_interleaved_rows_step_in_turns_of_the_block_each_in_tick_order() -> None:
    """The group steps block after block, the row that goes first rotating; each row's
    replayer sees its ticks in order (it asserts so)."""
    from wbcbench.bench import timing as T

    order: list[tuple[str, int, int]] = []

    class Row:
        def __init__(self, name: str, n: int) -> None:
            self.name, self.n, self.done = name, n, 0

        @property
        def running(self) -> bool:
            return self.done < self.n

        def step_block(self, first: int, last: int) -> None:
            assert first == self.done
            self.done = min(last, self.n)
            order.append((self.name, first, self.done))

    rows = [Row("a", 25), Row("b", 25)]
    T.step_interleaved(rows, block=10)  # type: ignore[arg-type]
    assert order == [
        ("a", 0, 10),
        ("b", 0, 10),
        ("b", 10, 20),
        ("a", 10, 20),
        ("a", 20, 25),
        ("b", 20, 25),
    ]
