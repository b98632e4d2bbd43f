"""Entries from outside the package: entry points, and ``register_*`` calls of a script.

Three registries take them, each under an entry-point group:

- controllers, ``wbcbench.controllers``: a :class:`~wbcbench.controllers.base.Controller`
  subclass whose ``name`` is the entry point's name;
- QP solver backends, ``wbcbench.solvers``: a :class:`~wbcbench.qp.base.QPSolver` subclass;
- robots, ``wbcbench.robots``: a :class:`~wbcbench.robots.spec.RobotFile` (a model file and
  the facts the file does not carry: contact frames, sole sizes).

A distribution declares them in its ``pyproject.toml``::

    [project.entry-points."wbcbench.controllers"]
    damped_qp_wbc = "my_plugin.controllers:DampedQpWbc"

A registry reads its group when a name is looked up that is not built in, so a plugin works in
every process where its distribution is installed (a guarded run's child, a Dask worker) and
needs no import by the user. An entry point that cannot be loaded is an error naming the
distribution and the entry point when its name is asked for, and is listed as broken by
``wbcbench list``; it never hides the built-in entries or the other plugins.

A script can add an entry for its own process (``wbcbench.register_controller``,
``register_solver``, ``register_robot``). The runs take such registrations along to the
processes they run in (:func:`pickled_call`, :func:`run_pickled`), so a registered
class must be importable by its module and name (not defined in ``__main__``), and a registered
value (a robot's :class:`~wbcbench.robots.spec.RobotFile`) must pickle.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import pickle
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from wbcbench.errors import WbcBenchError

GROUPS: tuple[str, ...] = ("wbcbench.controllers", "wbcbench.solvers", "wbcbench.robots")


class PluginError(WbcBenchError):
    """A plugin entry that cannot be loaded or is not what its group takes."""


@dataclass(frozen=True)
class Origin:
    """Where a registry entry comes from.

    Attributes:
        kind: ``built-in``, ``registered`` (by a call in this process) or ``plugin``.
        target: ``module:attribute`` of the entry (empty for built-in ones).
        distribution: the distribution and version declaring a plugin's entry point.
    """

    kind: str
    target: str = ""
    distribution: str = ""

    def __str__(self) -> str:
        if self.kind == "plugin":
            return f"plugin {self.distribution} ({self.target})"
        if self.kind == "registered":
            return f"registered ({self.target})"
        return self.kind


BUILT_IN = Origin("built-in")


@dataclass(frozen=True)
class Entry:
    """An entry point of one of :data:`GROUPS`, not loaded yet."""

    group: str
    name: str
    target: str  # module:attribute
    distribution: str  # "<name> <version>"

    def describe(self) -> str:
        return (
            f"entry point {self.name} = {self.target!r} of distribution {self.distribution} "
            f"(group {self.group})"
        )


#: group → name → what was registered in this process (a class, or a value such as a RobotFile)
_REGISTERED: dict[str, dict[str, Any]] = {group: {} for group in GROUPS}
#: loaded objects, by target
_LOADED: dict[str, Any] = {}


def _check_group(group: str) -> None:
    if group not in GROUPS:
        raise PluginError(f"unknown plugin group {group!r}; valid choices: {', '.join(GROUPS)}")


def entry_points(group: str) -> dict[str, Entry]:
    """The group's entry points of the installed distributions (read now), by name; where two
    distributions declare one name, the first found on ``sys.path`` wins."""
    _check_group(group)
    out: dict[str, Entry] = {}
    for ep in importlib.metadata.entry_points(group=group):
        dist = ep.dist
        label = f"{dist.name} {dist.version}" if dist is not None else "(unknown distribution)"
        out.setdefault(ep.name, Entry(group, ep.name, ep.value, label))
    return out


def _import(target: str) -> Any:
    """The object at ``module:qualname``."""
    if target in _LOADED:
        return _LOADED[target]
    module_name, _, qualname = target.partition(":")
    obj: Any = importlib.import_module(module_name)
    for part in qualname.split(".") if qualname else []:
        obj = getattr(obj, part)
    _LOADED[target] = obj
    return obj


def load(entry: Entry, check: Callable[[str, Any], str] | None = None) -> Any:
    """The object an entry point names; ``check(name, obj)`` returns why it does not fit the
    group ("" when it does).

    Raises:
        PluginError: naming the distribution, the entry point and what went wrong.
    """
    try:
        obj = _import(entry.target)
    except Exception as exc:  # any error of a broken plugin's import is the plugin's
        raise PluginError(f"cannot load {entry.describe()}: {type(exc).__name__}: {exc}") from None
    problem = check(entry.name, obj) if check is not None else ""
    if problem:
        raise PluginError(f"{entry.describe()}: {problem}")
    return obj


def target_of(obj: Any) -> str:
    """``module:qualname`` of an importable object.

    Raises:
        PluginError: the object cannot be imported by that name (defined in ``__main__`` or
            inside a function): runs in other processes could not find it.
    """
    module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
    if not module or not qualname or module == "__main__" or "<locals>" in qualname:
        raise PluginError(
            f"{obj!r} is not importable by module and name (defined in __main__ or in a "
            "function): define it in a module, so that runs in a child process or a Dask "
            "worker can import it"
        )
    target = f"{module}:{qualname}"
    try:
        found = _import(target)
    except Exception as exc:
        raise PluginError(f"{obj!r}: cannot import {target}: {exc}") from None
    if found is not obj:
        raise PluginError(f"{obj!r}: {target} names another object")
    return target


def describe(obj: Any) -> str:
    """``module:qualname`` of a class or function, else the value's repr."""
    if isinstance(obj, type) or callable(obj):
        return f"{getattr(obj, '__module__', '?')}:{getattr(obj, '__qualname__', '?')}"
    return repr(obj)


def register(group: str, name: str, obj: Any, replace: bool = False) -> None:
    """Add ``obj`` under ``name`` to ``group`` for this process (and its runs' processes).

    Raises:
        PluginError: the name is registered already (and not ``replace``), a class not
            importable by its module and name, or a value that does not pickle.
    """
    _check_group(group)
    if isinstance(obj, type):
        target_of(obj)
    else:
        try:
            pickle.dumps(obj)
        except Exception as exc:
            raise PluginError(f"{obj!r} does not pickle ({exc}): runs elsewhere need it") from None
    current = _REGISTERED[group].get(name)
    if current is not None and current is not obj and not replace:
        raise PluginError(
            f"{name!r} is registered already in {group} ({describe(current)}); pass replace=True"
        )
    _REGISTERED[group][name] = obj


def unregister(group: str, name: str) -> None:
    """Remove a registration of this process (nothing when there is none)."""
    _check_group(group)
    _REGISTERED[group].pop(name, None)


def registered(group: str) -> dict[str, Any]:
    """The group's registrations in this process: name → what was registered."""
    _check_group(group)
    return dict(_REGISTERED[group])


def find(
    group: str, name: str, check: Callable[[str, Any], str] | None = None
) -> tuple[Any, Origin] | None:
    """The registered entry ``name``, else the plugin's, with its origin; None when neither
    has it. A broken plugin entry of that name raises :class:`PluginError`."""
    obj = _REGISTERED.get(group, {}).get(name)
    if obj is not None:
        problem = check(name, obj) if check is not None else ""
        if problem:
            raise PluginError(f"{name!r} registered in {group} ({describe(obj)}): {problem}")
        return obj, Origin("registered", describe(obj))
    entry = entry_points(group).get(name)
    if entry is None:
        return None
    return load(entry, check), Origin("plugin", entry.target, entry.distribution)


def external(
    group: str, check: Callable[[str, Any], str] | None = None
) -> tuple[dict[str, tuple[Any, Origin]], dict[str, str]]:
    """Every registered and plugin entry of the group that loads (name → object, origin), and
    the broken ones (name → why)."""
    good: dict[str, tuple[Any, Origin]] = {}
    broken: dict[str, str] = {}
    for name in sorted({*registered(group), *entry_points(group)}):
        try:
            found = find(group, name, check)
        except PluginError as exc:
            broken[name] = str(exc)
            continue
        if found is not None:
            good[name] = found
    return good, broken


def registrations() -> dict[str, dict[str, Any]]:
    """Every registration of this process, to take to another (:func:`restore`; it pickles)."""
    return {group: dict(names) for group, names in _REGISTERED.items() if names}


def restore(saved: dict[str, dict[str, Any]]) -> None:
    """Make the registrations of another process (:func:`registrations`) in this one."""
    for group, names in saved.items():
        _check_group(group)
        _REGISTERED[group].update(names)


def pickled_call(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[bytes, bytes]:
    """This process's registrations and the call ``fn(*args, **kwargs)``, pickled apart, for
    :func:`run_pickled` in another process: the registrations are made there before the call's
    arguments are unpickled (a run's robot may be a registered one)."""
    protocol = pickle.HIGHEST_PROTOCOL
    return pickle.dumps(registrations(), protocol), pickle.dumps((fn, args, kwargs), protocol)


def run_pickled(saved: bytes, call: bytes) -> Any:
    """In another process: make the registrations, then unpickle and run the call
    (:func:`pickled_call`)."""
    restore(pickle.loads(saved))
    fn, args, kwargs = pickle.loads(call)
    return fn(*args, **kwargs)
