"""Guards sized by the work: a run's deadline follows its ticks above a stated floor, a hung
solve in the solver comparison is stopped at its own deadline and the study goes on, and a
child stopped without progress says so, naming the solver it was in."""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd
import pytest

import wbcbench
from wbcbench import plugins
from wbcbench.bench import guard
from wbcbench.bench.solver_comparison import HUNG
from wbcbench.bench.sweep import SweepSpec, plan_sweep, run_sweep
from wbcbench.qp import Problem, Solution
from wbcbench.qp.backends.quadprog import QuadprogSolver


class HangingQuadprog(QuadprogSolver):
    """quadprog that never answers: a hung native call, as the guard sees it."""

    name = "hanging_quadprog"
    summary = "a solver that hangs (test only)"

    def solve(self, problem: Problem, *args: object, **kwargs: object) -> Solution:
        time.sleep(3600)
        raise AssertionError("unreachable")


@pytest.fixture
def hanging() -> object:
    wbcbench.register_solver(HangingQuadprog)
    yield
    plugins.unregister("wbcbench.solvers", "hanging_quadprog")


def test_deadlines_follow_the_work() -> None:
    assert guard.tracking_deadline(0.2) == pytest.approx(guard.START_S + 0.2 * 1000 * guard.TICK_S)
    assert guard.tracking_deadline(0.2, 500) < guard.tracking_deadline(0.2)
    assert guard.timing_deadline(40) == pytest.approx(guard.START_S + 40 * guard.TICK_S)
    assert guard.timing_deadline(40, 1000) > guard.timing_deadline(40)


@pytest.mark.usefixtures("hanging")
def test_a_hung_solve_fails_its_row_and_the_comparison_goes_on(tmp_path: Path) -> None:
    spec = SweepSpec.model_validate(
        {
            "version": 1,
            "solver_comparison": {
                "scenarios": ["tocabi_stand_sway"],
                "controllers": ["qp_wbc"],
                "solvers": ["hanging_quadprog", "daqp"],
                "tiers": ["default"],
                "modes": ["cold"],
                "dump_ticks": 2,
                "dump_after": 2,
                "solve_limit_s": 1.0,
            },
        }
    )
    run_sweep(plan_sweep("test", spec), tmp_path, show_progress=False)
    rows = pd.read_csv(tmp_path / "qp_solves.csv").sort_values("problem")
    hung = rows[rows["solver"] == "hanging_quadprog"]
    assert len(hung) == 2 and rows["key"].is_unique
    assert hung["status"].tolist() == ["failed", "skipped"]
    stopped = HUNG.format(limit=1.0)
    assert hung["message"].tolist() == [
        stopped,
        f"an earlier solve of this solver × tier × mode: {stopped}",
    ]
    # the study went on: the other solver solved every problem
    daqp = rows[rows["solver"] == "daqp"]
    assert len(daqp) == 2 and daqp["reported_solved"].all()


def _stuck(seconds: float) -> None:
    time.sleep(seconds)


def test_a_child_without_progress_says_so_and_names_its_solver() -> None:
    outcome = guard.call_with_deadline(_stuck, (60.0,), 1.0, doing="solver proxqp")
    assert not outcome.ok and not outcome.stalled
    assert outcome.message == (
        "exceeded the wall-clock guard of 1 s having made no progress, in solver proxqp: stuck "
        "before its first tick or solve; the run was stopped"
    )


def _late_step(before: float) -> None:
    time.sleep(before)
    guard.watch_step("step x", 0.5)
    time.sleep(60.0)


def test_a_stalled_step_says_how_long_it_ran_and_how_long_the_job_did() -> None:
    """A step stopped at its own deadline reports the time since the step began, not since
    the job began: a job that worked 1.5 s before a step that hung is stopped about 0.5 s into
    the step."""
    import re

    outcome = guard.call_with_deadline(_late_step, (1.5,), 60.0)
    assert not outcome.ok and outcome.stalled
    found = re.fullmatch(
        r"step x did not end within its own deadline of 0.5 s; stopped ([0-9.]+) s into it "
        r"\(([0-9.]+) s into the job\)",
        outcome.message,
    )
    assert found, outcome.message
    into, job = map(float, found.groups())
    assert 0.5 <= into < job and job >= 1.5 + 0.5
