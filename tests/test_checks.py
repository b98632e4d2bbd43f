"""The independent check of what a backend reports (:mod:`wbcbench.bench.checks`).

Each lie a backend could tell (an answer shifted in the torques by 0.5 or 5 N·m, x = 0, x + 10,
all reported ``solved``) is caught on every path that steps a controller: ``wbcbench run``
(:func:`~wbcbench.bench.runner.execute`), a sweep's closed-loop run and its timing replay; and
the QPs a native tick solves in C++ reach the check as well as those solved through Python.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from wbcbench import _native
from wbcbench.bench.checks import CHECK_FACTOR, SolverCapture, check_reported
from wbcbench.bench.results import ResultsStore
from wbcbench.bench.runner import execute
from wbcbench.bench.sweep import load_sweep_file, plan_sweep, run_sweep
from wbcbench.controllers.base import ControllerContext
from wbcbench.controllers.registry import make_controller
from wbcbench.dynamics.state import RobotState
from wbcbench.qp import Problem, make_solver
from wbcbench.qp.validity import relative_kkt
from wbcbench.robots.loader import load_robot
from wbcbench.runs import plan_run, scenario_context
from wbcbench.scenarios.load import load_scenario

SCENARIO = "tocabi_stand_sway"
SHORT = ["duration=0.05", "metrics.window=[0.0, 0.05]", "metrics.timing_warmup=5"]
NV = load_robot("tocabi_like").nv  # qp_wbc's variables: (q̈ (nv), Γ (k), f)
K = load_robot("tocabi_like").k


def torque_shift(delta: float) -> Callable[[np.ndarray], np.ndarray]:
    def lie(x: np.ndarray) -> np.ndarray:
        out = x.copy()
        out[NV : NV + K] += delta
        return out

    return lie


LIES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "torque + 0.5 N·m": torque_shift(0.5),
    "torque + 5 N·m": torque_shift(5.0),
    "x = 0": np.zeros_like,
    "x + 10": lambda x: x + 10.0,
}


class Liar:
    """A solver handle that reports ``solved`` for a changed answer on every solve."""

    def __init__(self, inner: Any, lie: Callable[[np.ndarray], np.ndarray]) -> None:
        self.inner, self.lie = inner, lie

    def solve(self, problem: Problem, *args: Any, **kwargs: Any) -> Any:
        sol = self.inner.solve(problem, *args, **kwargs)
        return replace(sol, x=self.lie(sol.x)) if sol.success else sol

    def native_solver(self) -> None:  # through Python, where the lie is told
        return None

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


@pytest.fixture
def lying_daqp(monkeypatch: pytest.MonkeyPatch) -> Callable[[str], None]:
    def install(lie: str) -> None:
        honest = ControllerContext.new_solver

        def new_solver(self: ControllerContext, kind: str = "task") -> Any:
            handle = honest(self, kind)
            return Liar(handle, LIES[lie]) if self.solver == "daqp" else handle

        monkeypatch.setattr(ControllerContext, "new_solver", new_solver)

    return install


def test_relative_residuals_of_an_honest_and_a_shifted_answer() -> None:
    H = np.diag([2.0, 1.0, 1e-3])
    problem = Problem(
        H=H,
        g=np.array([-1.0, 0.0, 1.0]),
        A=np.array([[1.0, 1.0, 1.0]]),
        b=np.array([300.0]),
        C=np.array([[1.0, -1.0, 0.0]]),
        l=np.array([-np.inf]),
        u=np.array([50.0]),
    )
    sol = make_solver("quadprog").solve(problem)
    prim, dual, gap = relative_kkt(problem, sol)
    assert prim <= 1e-14 and dual is not None and dual <= 1e-12 and gap is not None and gap <= 1e-12
    shifted = replace(sol, x=sol.x + np.array([0.5, 0.0, 0.0]))
    prim, _, _ = relative_kkt(problem, shifted)
    # 0.5 over 1 + max(|Ax|, |b|, |Cx|, |u|) = 1 + 300.5
    assert prim == pytest.approx(0.5 / 301.5)
    assert check_reported([(problem, sol)], CHECK_FACTOR) == ""
    message = check_reported([(problem, shifted)], CHECK_FACTOR)
    assert message.startswith("reported solved but relative primal residual 1.7e-03 > 1e-08")
    assert message.endswith("(quadprog, QP)")


@pytest.mark.parametrize("lie", list(LIES))
@pytest.mark.usefixtures("runs_in_process")
def test_wbcbench_run_catches_every_lie(
    tmp_path: Path, lying_daqp: Callable[[str], None], lie: str
) -> None:
    lying_daqp(lie)
    loaded = load_scenario(SCENARIO, SHORT)
    run = plan_run(loaded, "qp_wbc", "daqp", config={"impl": "python"})
    record = execute(run, ResultsStore(tmp_path))
    assert record is not None
    assert record.row["status"] in ("failed", "fell"), record.row
    assert "reported solved but relative primal residual" in record.row["message"]
    assert "(daqp, qp_wbc)" in record.row["message"]


SWEEP = """\
version: 1
tracking:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [daqp]
    set: ["duration=0.05", "metrics.window=[0.0, 0.05]", "metrics.timing_warmup=5"]
timing:
  - scenarios: [tocabi_stand_sway]
    controllers: [qp_wbc]
    solvers: [daqp]
    record_with: [lqp]
    modes: [hot]
    ticks: 12
    warmup: 2
    probe_ticks: 5
    set: ["duration=0.3"]
"""


@pytest.mark.usefixtures("runs_in_process")
def test_a_sweep_catches_half_a_newton_metre_on_both_paths(
    tmp_path: Path, lying_daqp: Callable[[str], None]
) -> None:
    lying_daqp("torque + 0.5 N·m")
    path = tmp_path / "sweep.yaml"
    path.write_text(SWEEP)
    run_sweep(plan_sweep(*load_sweep_file(str(path))), tmp_path / "out", show_progress=False)
    runs = pd.read_csv(tmp_path / "out" / "runs.csv").set_index("kind")
    for kind in ("tracking", "timing"):
        row = runs.loc[kind]
        assert row["status"] == "failed", (kind, row["message"])
        assert "reported solved but relative primal residual" in row["message"], kind


native = pytest.mark.skipif(not _native.BUILT, reason=f"the native module is {_native.REASON}")


def captured_step(controller: str, solver: str) -> list[tuple[Problem, Any]]:
    """One step of ``controller`` (impl native, its QPs solved in C++) with its handles wrapped
    for the check: what reached the check."""
    loaded = load_scenario(SCENARIO)
    robot = load_robot(loaded.spec.robot)
    ctx = scenario_context(loaded, robot, solver=solver, mode="hot")
    pairs: list[tuple[Problem, Any]] = []
    honest = ctx.new_solver
    ctx.new_solver = lambda kind="task": SolverCapture(honest(kind), pairs)  # type: ignore[method-assign]
    ctrl = make_controller(controller, ctx, {"impl": "native", "solver_calls": "native"})
    q, v = robot.keyframe("stand")
    ctrl.start(RobotState(robot, q, v))
    out = ctrl.step(RobotState(robot, q, v), 0.0)
    assert out.ok, out.message
    return pairs


@native
@pytest.mark.parametrize("solver", ["osqp", "qpoases"])
@pytest.mark.parametrize("controller", ["qp_wbc", "lqp", "hqp"])
def test_qps_solved_in_cpp_reach_the_check(controller: str, solver: str) -> None:
    pairs = captured_step(controller, solver)
    assert pairs, "no QP solved in C++ reached the check"
    for problem, sol in pairs:
        assert sol.success and sol.solver == solver
        assert sol.x is not None and sol.x.shape == (problem.n,)
        assert sol.y is not None and sol.z is not None
        # copies: the next tick's solve does not change them
        assert not np.shares_memory(sol.x, problem.H)
    assert check_reported(pairs, CHECK_FACTOR) == ""


@native
def test_a_wrong_cpp_answer_is_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    from wbcbench.controllers import native as native_side

    honest = native_side.answered

    def lying(sol: Any, cpp: Any) -> Any:
        told = honest(sol, cpp)
        return replace(told, x=torque_shift(0.5)(told.x))

    monkeypatch.setattr(native_side, "answered", lying)
    pairs = captured_step("qp_wbc", "qpoases")  # (OSQP's own accuracy, 1e-3, would hide it)
    assert check_reported(pairs, CHECK_FACTOR).startswith(
        "reported solved but relative primal residual"
    )


def test_wrong_duals_get_a_second_opinion_on_the_objective() -> None:
    """Duals that miss their limit fail the QP only when x is not optimal: an optimal x with
    wrong duals passes (a reference backend's optimum has its objective), a feasible but
    suboptimal x with them fails."""
    problem = Problem(
        H=np.diag([2.0, 2.0]),
        g=np.array([-2.0, -6.0]),
        A=np.zeros((0, 2)),
        b=np.zeros(0),
        C=np.array([[1.0, 1.0]]),
        l=np.array([-np.inf]),
        u=np.array([2.0]),
    )
    sol = make_solver("daqp").solve(problem)  # x = (0, 2), z = 2
    assert check_reported([(problem, sol)], CHECK_FACTOR) == ""
    wrong_duals = replace(sol, z=np.array([0.5]))
    assert check_reported([(problem, wrong_duals)], CHECK_FACTOR) == ""
    feasible_not_optimal = replace(sol, x=np.array([0.5, 1.5]))
    message = check_reported([(problem, feasible_not_optimal)], CHECK_FACTOR)
    assert message.startswith("reported solved but relative dual residual"), message
    assert "above quadprog's (daqp, QP)" in message
