"""Building the controller of a run from a scenario, the same way for every runner."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from wbcbench.controllers.base import Controller, ControllerContext
from wbcbench.controllers.registry import make_controller
from wbcbench.errors import WbcBenchError
from wbcbench.robots.loader import Robot
from wbcbench.scenarios.load import (
    LoadedScenario,
    build_contacts,
    build_tasks,
    controller_settings,
    torque_limits,
)
from wbcbench.tasks.collision import Box


@dataclass
class WrappingContext(ControllerContext):
    """A context whose solver handles pass through ``wrap`` (e.g. to record their solutions)."""

    wrap: Callable[[Any], Any] | None = None

    def new_solver(self) -> Any:
        handle = super().new_solver()
        return self.wrap(handle) if self.wrap is not None else handle


def scenario_obstacles(loaded: LoadedScenario) -> list[Box]:
    """The scenario's fixed boxes (``environment.obstacles``)."""
    return [Box.from_rpy(o.name, o.pos, o.size, o.rpy) for o in loaded.spec.environment.obstacles]


def scenario_context(
    loaded: LoadedScenario,
    robot: Robot,
    context_cls: type[ControllerContext] = ControllerContext,
    **options: Any,
) -> ControllerContext:
    """A controller context with the scenario's tasks, contacts, torque limits and period;
    ``options`` are further fields of ``context_cls`` (``solver``, ``tier``, ...)."""
    spec = loaded.spec
    return context_cls(
        robot=robot,
        tasks=build_tasks(spec, robot),
        contacts=build_contacts(spec, robot),
        tau_max=torque_limits(spec, robot),
        dt=spec.dt,
        **options,
    )


def build_controller(
    loaded: LoadedScenario,
    settings: Any,
    robot: Robot,
    context_cls: type[ControllerContext] = ControllerContext,
    **context_options: Any,
) -> Controller:
    """The run's controller: tasks, contacts and limits from the scenario, its settings merged
    with the run's overrides, and the scenario's obstacles handed to controllers that avoid them.

    ``settings`` is a :class:`wbcbench.sim.closed_loop.RunSettings`; ``context_options`` are
    extra fields of ``context_cls`` (``keep_problems``, ...).
    """
    spec = loaded.spec
    ctx = scenario_context(
        loaded,
        robot,
        context_cls,
        solver=settings.solver,
        tier=settings.tier,
        mode=settings.mode,
        **context_options,
    )
    cfg = {**controller_settings(loaded, settings.controller), **settings.controller_config}
    controller = make_controller(settings.controller, ctx, cfg)
    use_environment = getattr(controller, "use_environment", None)
    if use_environment is not None:
        use_environment(scenario_obstacles(loaded))
    elif spec.environment.obstacles:
        raise WbcBenchError(
            f"{loaded.path}: environment.obstacles: {settings.controller} cannot avoid obstacles"
        )
    return controller
