"""wbcbench's native real-time tick: the C++ mirror of the Python reference.

The compiled part is ``wbcbench._native._core`` (C++17, Eigen and Pinocchio, bound with
nanobind, built by scikit-build-core at ``pip install``). On a machine without a C++ compiler
the package installs without it: :data:`BUILT` is then false, :data:`REASON` says why, and
everything runs on the Python path.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from wbcbench.errors import NativeModuleError

if TYPE_CHECKING:
    from wbcbench.dynamics.chains import ChainSplit

_core: Any
try:
    _core = importlib.import_module("wbcbench._native._core")
except ImportError as exc:  # no compiler at install time, or a broken build
    _core = None
    REASON = f"not built ({exc})"
else:
    REASON = ""

BUILT: bool = _core is not None


def core() -> Any:
    """The compiled module, for everything that needs it; where it is not built, the one error
    that says so (:class:`~wbcbench.errors.NativeModuleError`), naming why and the way out."""
    if _core is None:
        raise NativeModuleError(
            f"impl: native needs the native module, which is {REASON}; valid choices here: "
            "python (or install a C++ compiler and rebuild: make native)"
        )
    return _core


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
    return core().RobotDynamics(robot.pin_model.saveToString(), task_frames, contact_frames)


def split_spec(split: ChainSplit) -> Any:
    """The native :class:`SplitSpec` of a :class:`~wbcbench.dynamics.chains.ChainSplit`: its
    contact frames, plain coordinates and, per chain, velocity indices, root and parent joints
    (the chain split itself is computed in Python, once)."""
    module = core()
    spec = module.SplitSpec()
    spec.contact_frames = list(split.contact_frames)
    spec.plain = split.plain.tolist()
    chains = []
    for chain in split.chains:
        native = module.ChainSpec()
        native.idx = chain.idx.tolist()
        native.root_joints = list(chain.root_joints)
        native.parent_joint = chain.parent_joint
        chains.append(native)
    spec.chains = chains
    return spec


def reduced_dynamics(
    robot: Any, split: ChainSplit, task_frames: list[str] | None = None, dynamics: Any = None
) -> Any:
    """A native :class:`ReducedDynamics` for ``robot`` and ``split`` (the mirror of
    :class:`wbcbench.dynamics.reduced.ReducedDynamics`).

    It reads a native :class:`RobotDynamics` with the split's contact frames: ``dynamics`` when
    given (to share one with the rest of a tick), else a new one with ``task_frames``; either
    is its ``dynamics`` attribute. Per tick: ``reduced.dynamics.update(q, v)``, then
    ``reduced.compute(fixed_base)``.
    """
    if dynamics is None:
        dynamics = robot_dynamics(robot, task_frames or [], list(split.contact_frames))
    return core().ReducedDynamics(dynamics, split_spec(split))
