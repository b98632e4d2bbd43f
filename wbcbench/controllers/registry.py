"""The explicit table of controller plugins.

Adding a controller: write ``wbcbench/controllers/<name>.py`` with a :class:`Controller`
subclass, add one line to ``CONTROLLERS`` below; the registry sweep test picks it up.
"""

from __future__ import annotations

from wbcbench.controllers.base import Controller, ControllerConfig, ControllerContext
from wbcbench.controllers.hqp import Hqp
from wbcbench.controllers.kin_hqp import KinHqp
from wbcbench.controllers.lqp import Lqp
from wbcbench.controllers.osf_hqp import OsfHqp
from wbcbench.controllers.qp_wbc import QpWbc
from wbcbench.controllers.rc_lqp import RcLqp
from wbcbench.controllers.to_osf import ToOsf
from wbcbench.errors import UnknownNameError

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
