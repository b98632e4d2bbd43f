"""Hot starts of the strict hierarchy on recorded states, with an iterative backend.

A hot-started iterative backend (ProxQP keeps its own iterate from tick to tick) is where a
change of how the hierarchy hands its level QPs over shows first: handed over a null-space
basis of the hard equalities made afresh every tick, ProxQP declared `hqp`'s levels primal
infeasible on about one Table I tick in ten, where the stacked cascade solves every one. Each
impl replays the same recorded states and must solve every tick.

The null-space strategy's level QPs are over coordinates made afresh every tick (x = x_p + Z y):
a hot start from the previous tick's y starts from an unrelated x, and the directions only the
energy's 1e-8 ‖f‖² term fixes (how double support shares the weight) stay wherever that start
put them, within ProxQP's tolerance. Started from y = 0 (the levels above's answer), ``lqp``'s
wrench keeps to the exact one.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wbcbench.controllers.base import ControlOutput
from wbcbench.qp import available_solvers
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import load_scenario
from wbcbench.sim.replay import Recording, record_states, replay

pytestmark = pytest.mark.skipif("proxqp" not in available_solvers(), reason="proxqp not installed")


@pytest.fixture(scope="module")
def table1() -> tuple[Any, Any]:
    """The first 0.3 s of IROS Table I (its first failures were at ticks 129 and 166)."""
    loaded = load_scenario("lee2021iros_table1", ("duration=0.3",))
    return loaded, record_states(plan_run(loaded, "qp_wbc", "daqp", config={"impl": "native"}))


@pytest.mark.parametrize("impl", ["python", "native"])
def test_hqp_hot_proxqp_solves_every_recorded_tick(table1: tuple[Any, Any], impl: str) -> None:
    loaded, recording = table1
    run = plan_run(loaded, "hqp", "proxqp", mode="hot", config={"impl": impl}, timing=True)
    timings = replay(run, recording)
    assert (timings.failures, timings.message) == (0, "")


#: 60 states of ``tocabi_walk`` from the first landing (2.0 s), recorded in closed loop with
#: ``lqp`` × daqp, native: ``record_states`` then ``Recording.window(2.0, 60)``
LANDING = Path(__file__).parent / "data" / "tocabi_walk_landing_states.npz"


def _normal_forces(solver: str, mode: str, impl: str) -> tuple[Any, np.ndarray]:
    loaded = load_scenario("tocabi_walk", ("duration=2.1",))
    run = plan_run(loaded, "lqp", solver, mode=mode, config={"impl": impl}, timing=True)
    forces: list[np.ndarray] = []

    def keep(i: int, out: ControlOutput) -> str:
        forces.append(out.wrench[2::6].copy())
        return ""

    timings = replay(run, Recording.load(LANDING), on_step=keep)
    return timings, np.array(forces)


@pytest.mark.skipif("daqp" not in available_solvers(), reason="daqp not installed")
@pytest.mark.parametrize("impl", ["python", "native"])
def test_lqp_hot_proxqp_shares_the_weight_as_an_exact_solver(impl: str) -> None:
    """Double support after the first landing: hot ProxQP's normal forces stay within 20 N of
    DAQP's (started from the previous tick's y they stayed on the leaving foot, 460 N off)."""
    _, exact = _normal_forces("daqp", "cold", impl)
    timings, hot = _normal_forces("proxqp", "hot", impl)
    assert (timings.failures, timings.message) == (0, "")
    assert hot.shape == exact.shape == (60, 2)
    assert np.abs(hot - exact).max() < 20.0
