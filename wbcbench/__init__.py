"""wbcbench: compare humanoid whole-body control formulations and QP solvers on equal terms.

What a user script needs is exported here and imported on first use, so that
``import wbcbench`` stays light:

- runs: :func:`run` (scenarios × controllers × solvers, stored and returned),
  :func:`make_controller` (a scenario's controller to step by hand), :func:`load_results`;
- the plugin interface: :class:`Controller` (with :class:`ControllerConfig`,
  :class:`ControllerContext`, :class:`ControlOutput`), :class:`QPSolver`, :class:`Problem`,
  :class:`Solution`, and the ``register_*`` functions that add a controller, a QP backend or a
  robot (a :class:`RobotFile` with its :class:`RobotInfo`) from outside the package, for this
  process and its runs; a distribution adds them for every process with entry points
  (:mod:`wbcbench.plugins`).
"""

from importlib import import_module
from typing import Any

__version__ = "0.1.0"

#: public name → the module that defines it
_EXPORTS = {
    "run": "wbcbench.api",
    "make_controller": "wbcbench.api",
    "load_results": "wbcbench.api",
    "Results": "wbcbench.api",
    "Controller": "wbcbench.controllers.base",
    "ControllerConfig": "wbcbench.controllers.base",
    "ControllerContext": "wbcbench.controllers.base",
    "ControlOutput": "wbcbench.controllers.base",
    "QPSolver": "wbcbench.qp.base",
    "Problem": "wbcbench.qp.problem",
    "Solution": "wbcbench.qp.solution",
    "register_controller": "wbcbench.controllers.registry",
    "register_solver": "wbcbench.qp.registry",
    "register_robot": "wbcbench.robots.loader",
    "RobotFile": "wbcbench.robots.spec",
    "RobotInfo": "wbcbench.robots.spec",
    "PluginError": "wbcbench.plugins",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'wbcbench' has no attribute {name!r}")
    return getattr(import_module(module), name)


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
