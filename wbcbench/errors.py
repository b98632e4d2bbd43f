"""The one exception family of wbcbench.

Every error a user can cause (a bad scenario, an unknown name, a solver failure) is a
``WbcBenchError``; the CLI prints its message without a traceback.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any


class WbcBenchError(Exception):
    """Base class of every error wbcbench raises on purpose."""


class ScenarioError(WbcBenchError):
    """A scenario (or sweep) file is invalid; the message names the file and the key path."""

    def __init__(self, file: str, key: str, message: str) -> None:
        self.file = file
        self.key = key
        super().__init__(f"{file}: {key}: {message}" if key else f"{file}: {message}")


class UnknownNameError(WbcBenchError, KeyError):
    """A registry lookup (solver, controller, robot, frame, ...) got a name it does not hold."""

    def __init__(self, kind: str, name: str, valid: Iterable[str], hint: str = "") -> None:
        self.kind = kind
        self.name = name
        self.valid = sorted(valid)
        msg = f"unknown {kind} {name!r}; valid choices: {', '.join(self.valid) or '(none)'}"
        if hint:
            msg += f" ({hint})"
        super().__init__(msg)

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class UnofferedChoiceError(UnknownNameError):
    """A known tier or mode that one registry entry does not run at (e.g. a solver setting that
    fixes its own tolerances); the message names the entry, the choice and the valid ones."""

    def __init__(
        self, owner: str, kind: str, name: str, valid: Iterable[str], hint: str = ""
    ) -> None:
        super().__init__(kind, name, valid, hint)
        self.owner = owner
        msg = f"{owner} does not run at {kind} {name!r}; valid choices: {', '.join(self.valid)}"
        if hint:
            msg += f" ({hint})"
        self.args = (msg,)


class ModelError(WbcBenchError):
    """A robot model cannot be loaded or lacks something a scenario needs."""


class SolverError(WbcBenchError):
    """A QP backend failed; carries the problem so it can be saved and replayed."""

    def __init__(self, message: str, problem: Any = None, solver: str = "") -> None:
        self.problem = problem
        self.solver = solver
        super().__init__(message)


class ControllerError(WbcBenchError):
    """A controller cannot produce a command (e.g. its QP failed and no fallback applies)."""


class NativeModuleError(WbcBenchError):
    """``impl: native`` was asked for where the native module is not built (no C++ compiler at
    install time, or a broken build); raised by :func:`wbcbench._native.core` only."""
