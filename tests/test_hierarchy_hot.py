"""Hot starts of the strict hierarchy on recorded states, with an iterative backend.

A hot-started iterative backend (ProxQP keeps its own iterate from tick to tick) is where a
change of how the hierarchy hands its level QPs over shows first: handed over a null-space
basis of the hard equalities made afresh every tick, ProxQP declared `hqp`'s levels primal
infeasible on about one Table I tick in ten, where the stacked cascade solves every one. Each
impl replays the same recorded states and must solve every tick.
"""

from __future__ import annotations

from typing import Any

import pytest

from wbcbench.qp import available_solvers
from wbcbench.runs import plan_run
from wbcbench.scenarios.load import load_scenario
from wbcbench.sim.replay import record_states, replay

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
