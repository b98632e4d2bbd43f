"""The explicit table of controller plugins.

Adding a controller: write ``wbcbench/controllers/<name>.py`` with a :class:`Controller`
subclass, add one line to ``CONTROLLERS`` below; the registry sweep test picks it up.
"""

from __future__ import annotations

from typing import Any

from pydantic import ValidationError

from wbcbench.controllers.base import Controller, ControllerConfig, ControllerContext
from wbcbench.controllers.hqp import Hqp
from wbcbench.controllers.kin_hqp import KinHqp
from wbcbench.controllers.lqp import Lqp
from wbcbench.controllers.osf_hqp import OsfHqp
from wbcbench.controllers.qp_wbc import QpWbc
from wbcbench.controllers.rc_lqp import RcLqp
from wbcbench.controllers.to_osf import ToOsf
from wbcbench.errors import ScenarioError, UnknownNameError
from wbcbench.robots.loader import Robot
from wbcbench.scenarios.load import LoadedScenario, validation_error

CONTROLLERS: dict[str, type[Controller]] = {
    QpWbc.name: QpWbc,
    ToOsf.name: ToOsf,
    OsfHqp.name: OsfHqp,
    Hqp.name: Hqp,
    Lqp.name: Lqp,
    RcLqp.name: RcLqp,
    KinHqp.name: KinHqp,
}


def available_controllers() -> list[str]:
    return sorted(CONTROLLERS)


def controller_class(name: str) -> type[Controller]:
    """The class registered under ``name``; unknown names list the valid ones."""
    try:
        return CONTROLLERS[name]
    except KeyError:
        raise UnknownNameError(
            "controller", name, CONTROLLERS, hint="see `wbcbench list` for what each one does"
        ) from None


def make_controller(
    name: str, ctx: ControllerContext, config: dict | ControllerConfig | None = None
) -> Controller:
    """Build a controller from its name, the run context and its settings (dict or model)."""
    cls = controller_class(name)
    if config is None or isinstance(config, ControllerConfig):
        return cls(ctx, config)
    return cls(ctx, cls.Config.model_validate(config))


def validated_config(
    cls: type[Controller],
    loaded: LoadedScenario,
    variant: dict[str, Any] | None = None,
    file: str | None = None,
    key: str | None = None,
) -> ControllerConfig:
    """The controller's settings for a run: the scenario's ``controllers.<name>``, then
    ``variant`` on top, validated by the controller's Config.

    Raises:
        ScenarioError: at ``file`` and ``key`` (default: the scenario file and
            ``controllers.<name>``), naming the key and the valid choices.
    """
    merged = {**loaded.spec.controllers.get(cls.name, {}), **(variant or {})}
    try:
        return cls.Config.model_validate(merged)
    except ValidationError as exc:
        raise validation_error(
            file or str(loaded.path), exc, cls.Config, key or f"controllers.{cls.name}"
        ) from None


def check_scenario_settings(loaded: LoadedScenario, robot: Robot) -> None:
    """Every ``controllers.<name>`` section of a scenario names a registered controller, its
    settings validate, and the names in them (tasks, bodies) exist in the scenario and robot.

    Raises:
        ScenarioError: at ``controllers.<name>[.<key>]`` of the scenario file.
    """
    file = str(loaded.path)
    for name in loaded.spec.controllers:
        try:
            cls = controller_class(name)
        except UnknownNameError as exc:
            raise ScenarioError(file, f"controllers.{name}", str(exc)) from None
        config = validated_config(cls, loaded)
        for key, message in config.robot_errors(loaded.spec, robot):
            raise ScenarioError(file, f"controllers.{name}.{key}", message)
