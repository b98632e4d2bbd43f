"""The tables of QP solvers: name → module, import-guarded.

:data:`BACKENDS` holds one entry per library, each runnable at every accuracy tier and mode.
:data:`NAMED_SETTINGS` holds backends run the way a paper's code runs them (fixed tolerances,
mode and update policy, e.g. ``osqp_libdwbc``): chosen by name like a backend, at the one tier
and mode they define (:meth:`QPSolver.check_choice` names them). ``qpsolvers:<name>`` runs a
library through qpsolvers.

From outside the package, a backend is an entry point of the group ``wbcbench.solvers`` (a
:class:`QPSolver` subclass), or :func:`register_solver` in a script (:mod:`wbcbench.plugins`).

Adding a built-in backend: write ``wbcbench/qp/backends/<name>.py`` with a
:class:`QPSolver` subclass, add one line to :data:`BACKENDS`, and the registry sweep in
``tests/test_qp_backends.py`` picks it up (a named setting: a subclass of its backend with
``tiers`` / ``modes`` narrowed, one line in :data:`NAMED_SETTINGS`). Names are looked up here
before any backend is imported, so an error inside a backend is never mistaken for "no such
solver".
"""

from __future__ import annotations

import importlib
import importlib.metadata
from dataclasses import dataclass
from functools import cache
from typing import Any, TypedDict

from wbcbench import plugins
from wbcbench.errors import UnknownNameError
from wbcbench.qp.base import QPSolver
from wbcbench.qp.settings import check_mode, check_tier


@dataclass(frozen=True)
class BackendEntry:
    """One registry row: where the class lives and which distribution provides the library."""

    module: str
    cls: str
    distribution: str


#: name → backend. Every entry uses the library's native API (eiquadprog's is C++: its backend
#: solves through the native module, and is available only where that is built).
BACKENDS: dict[str, BackendEntry] = {
    "clarabel": BackendEntry("wbcbench.qp.backends.clarabel", "ClarabelSolver", "clarabel"),
    "daqp": BackendEntry("wbcbench.qp.backends.daqp", "DAQPSolver", "daqp"),
    "eiquadprog": BackendEntry("wbcbench.qp.backends.eiquadprog", "EiquadprogSolver", "eiquadprog"),
    "highs": BackendEntry("wbcbench.qp.backends.highs", "HiGHSSolver", "highspy"),
    "osqp": BackendEntry("wbcbench.qp.backends.osqp", "OSQPSolver", "osqp"),
    "piqp": BackendEntry("wbcbench.qp.backends.piqp", "PIQPSolver", "piqp"),
    "proxqp": BackendEntry("wbcbench.qp.backends.proxqp", "ProxQPSolver", "proxsuite"),
    "qpmad": BackendEntry("wbcbench.qp.backends.qpmad", "QpmadSolver", "pyqpmad"),
    "qpoases": BackendEntry("wbcbench.qp.backends.qpoases", "QpOASESSolver", "casadi"),
    "quadprog": BackendEntry("wbcbench.qp.backends.quadprog", "QuadprogSolver", "quadprog"),
}

#: name → a backend at a paper's fixed settings. Listed by ``all`` and by name, not by
#: ``native`` (which means "every library once").
NAMED_SETTINGS: dict[str, BackendEntry] = {
    "osqp_libdwbc": BackendEntry("wbcbench.qp.backends.osqp_libdwbc", "OSQPLibdwbcSolver", "osqp"),
    "qpoases_libdwbc": BackendEntry(
        "wbcbench.qp.backends.qpoases_libdwbc", "QpOASESLibdwbcSolver", "cmeel-qpoases"
    ),
}

QPSOLVERS_PREFIX = "qpsolvers:"

#: Backends also offered through qpsolvers as ``qpsolvers:<name>`` (qpsolvers' own names; its
#: ``qpoases`` is the standalone qpOASES package, not CasADi's).
QPSOLVERS_NAMES: tuple[str, ...] = (
    "clarabel",
    "daqp",
    "highs",
    "osqp",
    "piqp",
    "proxqp",
    "qpoases",
    "quadprog",
)

#: wrapped backends whose time / iteration caps are the library's own settings, which qpsolvers
#: passes through (the others' caps are wbcbench's own code and do not reach the library)
CAPS_PASS_THROUGH: tuple[str, ...] = ("clarabel", "highs", "osqp")

UNKNOWN_HINT = "wbcbench.qp.all_solvers() lists every backend with its availability and version"


GROUP = "wbcbench.solvers"


def _builtin_names() -> list[str]:
    return sorted([*BACKENDS, *NAMED_SETTINGS, *(QPSOLVERS_PREFIX + n for n in QPSOLVERS_NAMES)])


def _all_names() -> list[str]:
    """Built-in names, then the registered and plugin backends that load."""
    return sorted([*_builtin_names(), *plugins.external(GROUP, _check)[0]])


def _entry(name: str) -> BackendEntry:
    return BACKENDS[name] if name in BACKENDS else NAMED_SETTINGS[name]


def _builtin(name: str) -> bool:
    if name.startswith(QPSOLVERS_PREFIX):
        return name[len(QPSOLVERS_PREFIX) :] in QPSOLVERS_NAMES
    return name in BACKENDS or name in NAMED_SETTINGS


def _check(name: str, obj: object) -> str:
    """Why ``obj`` cannot be the backend ``name`` ("" when it can)."""
    if not (isinstance(obj, type) and issubclass(obj, QPSolver)):
        return f"{obj!r} is not a subclass of wbcbench.QPSolver"
    if _builtin(name):
        return f"{name!r} is a built-in solver name; choose another"
    return ""


def _known(name: str) -> bool:
    return _builtin(name) or plugins.find(GROUP, name, _check) is not None


def _load(name: str) -> type[QPSolver] | None:
    """The backend class, or ``None`` when its library is not installed (built in) or no
    registration or plugin has the name."""
    if _builtin(name):
        return _load_builtin(name)
    found = plugins.find(GROUP, name, _check)
    return None if found is None else found[0]


def register_solver(cls: type[QPSolver], name: str = "", replace: bool = False) -> None:
    """Add a QP backend class under ``name`` (default: its ``name``) for this process and its
    runs (a guarded child, a Dask worker of a sweep). The class must be importable by its
    module and name.

    Raises:
        PluginError: not a QPSolver subclass, a built-in name, a name registered already
            (without ``replace``), or a class that cannot be imported by name.
    """
    name = name or cls.name
    problem = _check(name, cls)
    if problem:
        raise plugins.PluginError(f"register_solver({cls!r}): {problem}")
    plugins.register(GROUP, name, cls, replace)


#: name → why its module did not import, for the entries whose library is installed (e.g.
#: eiquadprog without the native module)
_LOAD_ERRORS: dict[str, str] = {}


@cache
def _load_builtin(name: str) -> type[QPSolver] | None:
    """A built-in backend's class, or ``None`` when its library is not installed or its module
    does not import (then :data:`_LOAD_ERRORS` says why)."""
    if name.startswith(QPSOLVERS_PREFIX):
        inner = name[len(QPSOLVERS_PREFIX) :]
        try:
            import qpsolvers

            from wbcbench.qp.backends.qpsolvers_wrapper import make_wrapper
        except ImportError:
            return None
        if inner not in qpsolvers.available_solvers:
            return None
        native = _load(inner) if inner in BACKENDS else None
        caps = native.tier_caps if native and inner in CAPS_PASS_THROUGH else None
        return make_wrapper(
            inner,
            native.tier_settings if native else lambda tier: {},
            caps or (lambda tier: {}),
            native.default_eps if native else QPSolver.default_eps,
        )
    entry = _entry(name)
    try:
        module = importlib.import_module(entry.module)
    except ImportError as exc:
        if _version(entry.distribution):
            _LOAD_ERRORS[name] = str(exc)
        return None
    cls: type[QPSolver] = getattr(module, entry.cls)
    return cls


def _unavailable(name: str) -> str:
    """Why the backend ``name`` (not a qpsolvers wrapper) is not available."""
    dist = _entry(name).distribution
    if name in _LOAD_ERRORS:
        return f"package {dist!r} is installed, but the backend does not load: {_LOAD_ERRORS[name]}"
    return f"package {dist!r} not installed"


def _version(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return ""


class SolverInfo(TypedDict):
    """What :func:`all_solvers` reports for one registry name (a plain dict)."""

    name: str
    available: bool
    version: str
    reason: str
    warm_start: bool
    hot_start: bool
    internal_time: str
    summary: str
    named_setting: bool
    tiers: tuple[str, ...]
    modes: tuple[str, ...]
    origin: str


def available_solvers() -> list[str]:
    """Registry names whose library is installed, sorted."""
    return [name for name in _all_names() if _load(name) is not None]


def available_backends() -> list[str]:
    """Installed :data:`BACKENDS` (every library once, through its own API) and the
    registered and plugin backends that load, sorted."""
    external = plugins.external(GROUP, _check)[0]
    return sorted([*(n for n in BACKENDS if _load(n) is not None), *external])


#: the backend a run solves with when none is named: the sweeps', the API's, the recordings'
DEFAULT_SOLVER = "proxqp"


def default_solver() -> str:
    """:data:`DEFAULT_SOLVER` where it is installed, else the first installed backend."""
    installed = available_backends()
    return DEFAULT_SOLVER if DEFAULT_SOLVER in installed else installed[0]


def all_solvers() -> list[SolverInfo]:
    """Every registry name with availability, library version and native capabilities.

    Each entry is a :class:`SolverInfo` dict; ``reason`` says why a name is unavailable.
    ``version`` is the library's distribution version (for ``qpsolvers:<name>``:
    ``"qpsolvers <v>, <library> <v>"``); capabilities, ``summary`` and the ``tiers`` and
    ``modes`` it runs at are those of an available backend and empty otherwise;
    ``named_setting`` marks the entries of :data:`NAMED_SETTINGS`.
    """
    out: list[SolverInfo] = []
    external, broken = plugins.external(GROUP, _check)
    for name in _all_names():
        cls = _load(name)
        origin = "built-in"
        if name in external:
            origin = str(external[name][1])
            version = external[name][1].distribution.rpartition(" ")[2]
            reason = ""
        elif name.startswith(QPSOLVERS_PREFIX):
            inner = name[len(QPSOLVERS_PREFIX) :]
            dist = BACKENDS[inner].distribution if inner in BACKENDS else inner
            version = f"qpsolvers {_version('qpsolvers')}, {dist} {_version(dist)}"
            reason = f"qpsolvers does not offer {inner!r} here"
        else:
            version = _version(_entry(name).distribution)
            reason = _unavailable(name)
        out.append(
            SolverInfo(
                name=name,
                available=cls is not None,
                version=version if cls is not None else "",
                reason="" if cls is not None else reason,
                warm_start=bool(cls and cls.warm_start),
                hot_start=bool(cls and cls.hot_start),
                internal_time=cls.internal_time_covers if cls else "",
                summary=cls.summary if cls else "",
                named_setting=name in NAMED_SETTINGS,
                tiers=cls.tiers if cls else (),
                modes=cls.modes if cls else (),
                origin=origin,
            )
        )
    for name, why in broken.items():
        out.append(
            SolverInfo(
                name=name,
                available=False,
                version="",
                reason=why,
                warm_start=False,
                hot_start=False,
                internal_time="",
                summary="",
                named_setting=False,
                tiers=(),
                modes=(),
                origin="plugin",
            )
        )
    return out


def solver_class(name: str) -> type[QPSolver]:
    """The class behind a registry name, nothing built: what it runs at (``tiers``, ``modes``,
    :meth:`~wbcbench.qp.base.QPSolver.offers`), its ``summary`` and capabilities.

    Raises:
        UnknownNameError: the name is not in the registry, or its library is not installed
            (listing the installed names).
    """
    if not _known(name):
        raise UnknownNameError("solver", name, available_solvers(), hint=UNKNOWN_HINT)
    cls = _load(name)
    if cls is None:
        if name in _LOAD_ERRORS:
            hint = f"{name!r} is a known backend but {_unavailable(name)}"
        else:
            missing = (
                "qpsolvers (with this solver)"
                if name.startswith(QPSOLVERS_PREFIX)
                else _entry(name).distribution
            )
            hint = (
                f"{name!r} is a known backend but its package is not installed: "
                f"pip install {missing}"
            )
        raise UnknownNameError("solver", name, available_solvers(), hint=hint)
    return cls


def make_solver(name: str, tier: str = "default", mode: str = "cold", **options: Any) -> QPSolver:
    """A solver handle (one per controller level), e.g. ``make_solver("proxqp", "mid", "hot")``.

    Args:
        name: registry name (see :func:`available_solvers`).
        tier: accuracy tier, one of :data:`~wbcbench.qp.settings.TIERS`.
        mode: ``cold``, ``warm`` or ``hot`` (see :mod:`wbcbench.qp.settings`).
        **options: native settings overriding the tier's.

    Raises:
        UnknownNameError: the name is not in the registry or its library is not installed
            (listing the installed names), or the tier or mode is unknown, or
            (:class:`~wbcbench.errors.UnofferedChoiceError`) a named setting does not run at
            it (listing those it runs at).
        WbcBenchError: options given to a named setting.
    """
    if not _known(name):
        raise UnknownNameError("solver", name, available_solvers(), hint=UNKNOWN_HINT)
    check_tier(tier)
    check_mode(mode)
    return solver_class(name)(tier=tier, mode=mode, **options)
