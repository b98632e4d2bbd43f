"""The controllers: the built-in table, then registrations and plugins.

Adding a built-in controller: write ``wbcbench/controllers/<name>.py`` with a
:class:`Controller` subclass, add one line to ``CONTROLLERS`` below; the registry sweep test
picks it up. From outside the package: an entry point of the group ``wbcbench.controllers``, or
:func:`register_controller` in a script (:mod:`wbcbench.plugins`).
"""

from __future__ import annotations

from typing import Any

from pydantic import ValidationError

from wbcbench import plugins
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


GROUP = "wbcbench.controllers"


def _check(name: str, obj: object) -> str:
    """Why ``obj`` cannot be the controller ``name`` ("" when it can)."""
    if not (isinstance(obj, type) and issubclass(obj, Controller)):
        return f"{obj!r} is not a subclass of wbcbench.Controller"
    if obj.name != name:
        return f"its class says name = {obj.name!r}; the entry's name must be the same"
    if name in CONTROLLERS:
        return f"{name!r} is a built-in controller; choose another name"
    return ""


def available_controllers() -> list[str]:
    """The built-in controllers, then the registered and plugin ones that load."""
    return sorted({*CONTROLLERS, *plugins.external(GROUP, _check)[0]})


def controller_origins() -> tuple[dict[str, plugins.Origin], dict[str, str]]:
    """Every controller's origin (built-in, registered, a plugin's distribution), and the
    plugin entries that do not load, with why."""
    found, broken = plugins.external(GROUP, _check)
    origins = {name: plugins.BUILT_IN for name in CONTROLLERS}
    origins.update({name: origin for name, (_, origin) in found.items()})
    return dict(sorted(origins.items())), broken


def controller_class(name: str) -> type[Controller]:
    """The class of controller ``name``: built in, registered, or a plugin's.

    Raises:
        UnknownNameError: no such controller (listing the valid ones).
        PluginError: a plugin entry of that name that does not load (naming its distribution).
    """
    if name in CONTROLLERS:
        return CONTROLLERS[name]
    found = plugins.find(GROUP, name, _check)
    if found is None:
        raise UnknownNameError(
            "controller",
            name,
            available_controllers(),
            hint="see `wbcbench list` for what each one does",
        )
    cls: type[Controller] = found[0]
    return cls


def register_controller(cls: type[Controller], replace: bool = False) -> None:
    """Add a controller class under its ``name`` for this process and its runs (a guarded
    child, a Dask worker of a sweep). The class must be importable by its module and name.

    Raises:
        PluginError: not a Controller subclass, a built-in name, a name registered already
            (without ``replace``), or a class that cannot be imported by name.
    """
    problem = _check(getattr(cls, "name", ""), cls)
    if problem:
        raise plugins.PluginError(f"register_controller({cls!r}): {problem}")
    plugins.register(GROUP, cls.name, cls, replace)


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
