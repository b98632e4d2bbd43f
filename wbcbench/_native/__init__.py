"""wbcbench's native real-time tick: the C++ mirror of the Python reference.

The compiled part is ``wbcbench._native._core`` (C++17, Eigen and Pinocchio, bound with
nanobind, built by scikit-build-core at ``pip install``). On a machine without a C++ compiler
the package installs without it: :data:`BUILT` is then false, :data:`REASON` says why, and
everything runs on the Python path.
"""

from __future__ import annotations

import importlib
from typing import Any

_core: Any
try:
    _core = importlib.import_module("wbcbench._native._core")
except ImportError as exc:  # no compiler at install time, or a broken build
    _core = None
    REASON = f"not built ({exc})"
else:
    REASON = ""

BUILT: bool = _core is not None


def status() -> dict[str, Any]:
    """Whether the module is built, and with which compiler and flags."""
    if _core is None:
        return {"built": False, "reason": REASON}
    return {"built": True, "compiler": _core.compiler, "flags": _core.cxx_flags.strip()}


def describe_status() -> str:
    """One line for ``wbcbench list``."""
    info = status()
    if not info["built"]:
        return f"{info['reason']}: every controller runs with impl: python"
    return f"built with {info['compiler']} ({info['flags']})"


def robot_dynamics(robot: Any, task_frames: list[str], contact_frames: list[str]) -> Any:
    """A native :class:`RobotDynamics` for ``robot`` (the mirror of ``RobotState``).

    The Pinocchio model crosses once, as Pinocchio's own serialisation, so the native side
    holds exactly the model the Python side uses.
    """
    if _core is None:
        raise RuntimeError(f"the native module is {REASON}")
    return _core.RobotDynamics(robot.pin_model.saveToString(), task_frames, contact_frames)
