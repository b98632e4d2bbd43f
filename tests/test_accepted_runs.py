"""Accepted means runnable: scenarios at the edges of what validation accepts run a few ticks
with every controller that applies, on both impls, and end in a row, never in a raw
``TypeError`` or ``ValueError`` of the native tick or of the Python reference."""

from __future__ import annotations

import pytest

from tests.conftest import IMPLS
from wbcbench.bench.runner import compute_tracking
from wbcbench.controllers.registry import available_controllers, controller_class
from wbcbench.runs import Planner
from wbcbench.scenarios.schema import MAX_PRIORITY

#: a few ticks: enough to build every controller and run its tick
SHORT = ("duration=0.003", "metrics.window=[0, 0.003]", "metrics.timing_warmup=0")

#: edges of what validation accepts (each a set of overrides of the base scenario)
EDGES: dict[str, tuple[str, ...]] = {
    "the largest priority": (f"tasks.5.priority={MAX_PRIORITY}",),
    "priorities with gaps": ("tasks.2.priority=7", f"tasks.5.priority={MAX_PRIORITY - 1}"),
    "one task per priority": tuple(f"tasks.{i}.priority={i + 1}" for i in range(6)),
    "a single contact": ("contacts=[{frame: l_sole, mu: 0.5, fmin: 30}]",),
    "a zero minimum normal force": ("contacts.0.fmin=0", "contacts.1.fmin=0"),
}

PLANNER = Planner()


def controllers() -> list[str]:
    loaded, _ = PLANNER.scenario("tocabi_stand_sway", SHORT)
    return [c for c in available_controllers() if not controller_class(c).applies_to(loaded.spec)]


@pytest.mark.parametrize("impl", IMPLS)
@pytest.mark.parametrize("edge", sorted(EDGES))
def test_an_accepted_edge_runs_on_every_controller(edge: str, impl: str) -> None:
    raw, names = [], controllers()
    assert {"qp_wbc", "hqp", "to_osf", "osf_hqp", "lqp", "rc_lqp"} <= set(names)
    for controller in names:
        config = {"impl": impl} if controller_class(controller).has_native else {}
        run = PLANNER.run(
            "tocabi_stand_sway",
            controller,
            "daqp",
            config=config,
            overrides=(*SHORT, *EDGES[edge]),
        )
        row = compute_tracking(run, "edge", "test").row
        message = str(row["message"])
        if any(kind in message for kind in ("TypeError", "ValueError")):
            raw.append(f"{controller}: {row['status']}: {message}")
    assert not raw, "\n".join(raw)
