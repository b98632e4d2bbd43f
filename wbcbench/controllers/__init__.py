"""Controller plugins and their registry."""

from wbcbench.controllers.base import (
    Controller,
    ControllerConfig,
    ControllerContext,
    ControlOutput,
)
from wbcbench.controllers.registry import (
    CONTROLLERS,
    available_controllers,
    controller_class,
    make_controller,
)

__all__ = [
    "CONTROLLERS",
    "ControlOutput",
    "Controller",
    "ControllerConfig",
    "ControllerContext",
    "available_controllers",
    "controller_class",
    "make_controller",
]
