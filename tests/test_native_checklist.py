"""docs/native.md's "Adding a native controller", kept true.

* A controller declared as the checklist says (its Python half is a :class:`NativeController`
  declaration, its tick an existing C++ type, so nothing is compiled here) runs through the
  same native-vs-python assertions as the real ones (:func:`tests.test_native_equality.compare`).
* Every registered controller with a native tick has what the checklist names: its tick in
  ``src/controllers/<name>.hpp`` and ``.cpp``, its binding in ``src/bind/<name>.cpp`` registered
  in the module's controller layer, and an equality test; docs/native.md names the same pieces.
* Where the module is not built, every entry point raises the one error with the one message.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import Field

from wbcbench import _native
from wbcbench.controllers.base import (
    ControllerConfig,
    ControllerContext,
    ControlOutput,
    NativeConfig,
    StageTimer,
)
from wbcbench.controllers.native import NativeController, QpCall, set_limits
from wbcbench.controllers.registry import CONTROLLERS, make_controller
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import NativeModuleError
from wbcbench.qp import Problem, available_solvers
from wbcbench.qp.hls_native import NativeHls
from wbcbench.robots.loader import load_robot
from wbcbench.runs import scenario_context
from wbcbench.scenarios.load import load_scenario
from wbcbench.tasks.contacts import stack_wrench_constraints

from . import test_kin_hqp, test_native_equality, test_native_hierarchy, test_native_rc_lqp
from .test_native_equality import CASES, compare

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "wbcbench" / "_native" / "src"

#: the registered controllers that have a native tick
NATIVE = sorted(name for name, cls in CONTROLLERS.items() if cls.has_native)

needs_native = pytest.mark.skipif(not _native.BUILT, reason=f"native module {_native.REASON}")


# -- a controller declared as the checklist says ---------------------------------------------------


class ToyConfig(NativeConfig):
    """Settings of the toy controller."""

    weight: float = Field(1.0, gt=0, description="the weight of every task row")


class Toy(NativeController):
    """Every task row weighted alike, the torque eliminated: min Σ w ‖J q̈ + J̇ q̇ − ẍ*‖² +
    ε (‖q̈‖² + ‖Γ‖² + ‖f‖²) over x = (q̈, f), subject to the floating-base rows of the dynamics,
    stationary contacts, the wrench inequalities and the torque limits, Γ = G x + γ.

    Its native tick is qp_wbc's (``QpWbcTick``, torque eliminated), so that the declaration is
    all this controller adds; its Python step is an independent reference."""

    name = "toy"
    summary = "test-only: one weight for every task, torque eliminated"
    Config = ToyConfig
    config: ToyConfig
    tick_type = "QpWbcTick"
    #: ε, the regularisation of q̈, Γ and f
    EPS = 1e-6

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.solver = ctx.new_solver()
        self.Cw, self.lw, self.uw = stack_wrench_constraints(ctx.contacts)
        self.nc = 6 * len(ctx.contacts)

    def configure_tick(self, tick: Any) -> None:
        s = _native.core().QpWbcSettings()
        s.eliminated = True
        s.row_weights = np.full(sum(task.dim for task in self.ctx.tasks), self.config.weight)
        s.acceleration_weight = s.torque_weight = s.wrench_weight = self.EPS
        set_limits(s, self.ctx.tau_max, self.Cw, self.lw, self.uw, self.nc)
        tick.configure(s)

    def qp_calls(self, tick: Any) -> list[QpCall]:
        return [QpCall(tick.qp, "toy", self.solver, self.config.solver_calls)]

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        timer = StageTimer(state)
        n, nc, eps, frames = state.n, self.nc, self.EPS, self.ctx.contact_frames
        terms = self.evaluate_tasks(state, t)
        J = np.vstack([term.J for term in terms])
        r = np.concatenate([term.acc_ref - term.drift for term in terms])
        M, h, Jc = state.M, state.h, state.contact_jacobian(frames)
        G = np.hstack([M[6:], -Jc[:, 6:].T])  # Γ = G x + γ
        gamma = h[6:]
        H = eps * (G.T @ G)
        H[:n, :n] += self.config.weight * (J.T @ J)
        H[np.diag_indices(n + nc)] += eps
        g = eps * (G.T @ gamma)
        g[:n] -= self.config.weight * (J.T @ r)
        A = np.block([[M[:6], -Jc[:, :6].T], [Jc, np.zeros((nc, nc))]])
        b = np.concatenate([-h[:6], -state.contact_drift(frames)])
        C = np.vstack([np.hstack([np.zeros((self.Cw.shape[0], n)), self.Cw]), G])
        tau_max = self.ctx.tau_max
        lower = np.concatenate([self.lw, -tau_max - gamma])
        upper = np.concatenate([self.uw, tau_max - gamma])
        problem = Problem(H, g, A, b, C, lower, upper, name="toy")
        sol = self.solver.solve(problem)
        timer.add_solution(sol)
        ok = sol.success and sol.x is not None
        x = sol.x if ok and sol.x is not None else np.zeros(n + nc)
        return ControlOutput(
            tau=G @ x + gamma if ok else np.zeros(state.k),
            qdd=x[:n],
            wrench=x[n:],
            terms=terms,
            timings=timer.finish(),
            ok=ok,
            message="" if ok else f"{sol.solver}: {sol.status.value}: {sol.message}",
            iterations=timer.iterations,
            problems=[problem],
        )


#: the backends the toy is compared with: exact active-set solves, qpOASES also from C++
TOY_SOLVERS = [s for s in ("daqp", "quadprog", "qpoases") if s in available_solvers()]


@needs_native
@pytest.mark.parametrize("solver_calls", ["python", "native"])
@pytest.mark.parametrize("solver", TOY_SOLVERS)
@pytest.mark.parametrize("case", ["double", "single", "wall"])
def test_a_declared_controller_equals_its_python_reference(
    case: str, solver: str, solver_calls: str
) -> None:
    scenario, keyframe = CASES[case]
    loaded = load_scenario(scenario)
    robot = load_robot(loaded.spec.robot)
    pair: dict[str, Any] = {"robot": robot, "loaded": loaded}
    for impl in ("python", "native"):
        ctx = scenario_context(loaded, robot, solver=solver, tier="high", keep_problems=True)
        pair[impl] = Toy(ctx, ToyConfig(impl=impl, solver_calls=solver_calls, weight=10.0))
    worst = compare(pair, keyframe, n_states=4, seed=7, tolerance=1e-8, data_tolerance=1e-12)
    assert worst <= 1.0


@needs_native
def test_the_declaration_is_the_whole_native_half() -> None:
    """The toy defines no native step, region or output of its own, yet its native step runs
    the tick, keeps its QP and reports the native stages."""
    for method in ("make_native", "native_step", "native_region", "native_output"):
        assert method not in Toy.__dict__, method
    loaded = load_scenario("tocabi_stand_sway")
    robot = load_robot(loaded.spec.robot)
    ctx = scenario_context(loaded, robot, solver="daqp", keep_problems=True)
    toy = Toy(ctx, ToyConfig())
    assert toy.impl == "native" and Toy.has_native
    state = RobotState(robot, *robot.keyframe("stand"))
    toy.start(state)
    out = toy.step(state, 0.0)
    assert out.ok, out.message
    assert [p.name for p in out.problems] == ["toy"]
    assert {"dynamics", "build", "solve", "crossing", "total"} <= set(out.timings)
    assert out.timings["crossing"] >= 0.0


# -- every native controller has what the checklist names ------------------------------------------


def equality_tested() -> set[str]:
    """The controllers the native-vs-python equality tests step: the tables they are
    parametrized over."""
    return {
        *test_native_equality.CONTROLLERS,
        *(name for name, _, _ in test_native_hierarchy.CONTROLLERS),
        test_native_rc_lqp.CONTROLLER,
        test_kin_hqp.CONTROLLER,
    }


@pytest.mark.parametrize("name", NATIVE)
def test_every_native_controller_follows_the_checklist(name: str) -> None:
    cls = CONTROLLERS[name]
    assert issubclass(cls, NativeController), f"{name}: not a NativeController"
    tick = cls.tick_type
    header, source = SRC / "controllers" / f"{name}.hpp", SRC / "controllers" / f"{name}.cpp"
    assert re.search(rf"\bclass {tick}\b", header.read_text()), f"{header} declares no {tick}"
    assert f"{tick}::" in source.read_text(), f"{source} defines nothing of {tick}"
    binding = (SRC / "bind" / f"{name}.cpp").read_text()
    assert f"WBCBENCH_BIND({name}, kController, m)" in binding, f"bind/{name}.cpp registers none"
    assert re.search(rf"nb::class_<{tick}\b", binding), f"bind/{name}.cpp does not bind {tick}"
    assert name in equality_tested(), f"{name} has no native-vs-python equality test"


@needs_native
def test_the_module_binds_every_registered_part_once_in_layer_order() -> None:
    bound = [tuple(part) for part in _native.core().bindings]
    names = [name for name, _ in bound]
    assert len(names) == len(set(names))
    layers = [layer for _, layer in bound]
    order = ("core", "base", "controller")
    assert layers == sorted(layers, key=order.index)
    assert {name for name, layer in bound if layer == "controller"} == set(NATIVE)
    # every file of src/bind/ registers itself: the module binds exactly those parts
    files = {path.stem for path in (SRC / "bind").glob("*.cpp")}
    assert set(names) == files
    for name in NATIVE:
        assert hasattr(_native.core(), CONTROLLERS[name].tick_type)


def test_the_docs_name_what_the_checklist_test_checks() -> None:
    text = (ROOT / "docs" / "native.md").read_text()
    start = text.index("## Adding a native controller")
    section = text[start : text.find("\n## ", start)]
    for piece in (
        "wbcbench/_native/src/controllers/<name>.hpp",
        "wbcbench/_native/src/bind/<name>.cpp",
        "WBCBENCH_BIND(<name>, kController, m)",
        "NativeController",
        "tick_type",
        "configure_tick",
        "qp_calls",
        "level_solve",
        "native_step",
        "tests/test_native_equality.py",
        "tests/test_native_checklist.py",
    ):
        assert piece in section, piece


# -- the module not built --------------------------------------------------------------------------


def test_not_built_is_one_error_with_one_message(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_native, "_core", None)
    monkeypatch.setattr(_native, "BUILT", False)
    monkeypatch.setattr(_native, "REASON", "not built (no compiler)")
    message = (
        "impl: native needs the native module, which is not built (no compiler); valid choices "
        "here: python (or install a C++ compiler and rebuild: make native)"
    )
    loaded = load_scenario("tocabi_stand_sway")
    robot = load_robot(loaded.spec.robot)
    ctx = scenario_context(loaded, robot, solver="daqp")
    assert make_controller("qp_wbc", ctx).impl == "python"  # the default follows the build
    entry_points = [
        lambda: make_controller("qp_wbc", ctx, {"impl": "native"}),
        lambda: make_controller("kin_hqp", ctx, {"impl": "native"}),
        lambda: Toy(ctx, ToyConfig(impl="native")),
        NativeHls,
        lambda: _native.robot_dynamics(robot, [], []),
        _native.core,
    ]
    for call in entry_points:
        with pytest.raises(NativeModuleError) as err:
            call()
        assert str(err.value) == message
