"""Accuracy tiers and solve modes, shared by every backend.

Tiers follow qpbenchmark: ``default`` keeps each solver's own defaults (so results are *not*
iso-accuracy); ``low``, ``mid`` and ``high`` ask for absolute primal residual, dual residual and
duality gap below 1e-3, 1e-6 and 1e-9, with relative tolerances 0 and duality-gap checks on
where the solver has them. Each backend module translates a tier into its native settings in its
``tier_settings`` function; active-set solvers that have no such tolerance say so there.

Modes:

``cold``
    a fresh native solver object on every call, no initial guess.
``warm``
    a fresh native object, given the previous solution as initial guess where supported.
``hot``
    one persistent native object updated in place (only the data that changed) while
    :meth:`Problem.structure_key` is unchanged, rebuilt otherwise.

A backend that cannot warm start runs ``warm`` as ``cold``; one that cannot keep a native object
runs ``hot`` as ``warm`` (or ``cold``). The effective mode is reported in ``Solution.mode``.
"""

from __future__ import annotations

from wbcbench.errors import UnknownNameError

TIERS: tuple[str, ...] = ("default", "low", "mid", "high")
MODES: tuple[str, ...] = ("cold", "warm", "hot")

#: Absolute primal / dual / duality-gap tolerance of each non-default tier.
TIER_EPS: dict[str, float] = {"low": 1e-3, "mid": 1e-6, "high": 1e-9}

#: Wall-time cap of one solve at each tier [s], for every backend whose library has one (and
#: an iteration cap where its default is unbounded): a whole-body QP still running after this
#: has stalled, and the solve ends as a failure (``max_iter``) instead of holding the run. A
#: cap, not an accuracy setting: the default tier keeps each solver's tolerances.
TIER_TIME_LIMIT: dict[str, float] = {"default": 5.0, "low": 5.0, "mid": 10.0, "high": 30.0}

TIER_HINT = (
    "Tiers set absolute primal, dual and duality-gap tolerances: low 1e-3, mid 1e-6, "
    "high 1e-9; default keeps each solver's own settings"
)
MODE_HINT = (
    "Modes: cold builds a fresh solver on every call, warm passes the previous solution as "
    "initial guess, hot keeps one solver and updates it in place"
)


def check_tier(tier: str) -> str:
    """Return ``tier`` if valid.

    Raises:
        UnknownNameError: listing the valid tiers.
    """
    if tier not in TIERS:
        raise UnknownNameError("tier", tier, TIERS, hint=TIER_HINT)
    return tier


def check_mode(mode: str) -> str:
    """Return ``mode`` if valid.

    Raises:
        UnknownNameError: listing the valid modes.
    """
    if mode not in MODES:
        raise UnknownNameError("mode", mode, MODES, hint=MODE_HINT)
    return mode


def effective_mode(mode: str, warm: bool, hot: bool) -> str:
    """The mode a backend actually runs given what it supports natively."""
    if mode == "hot" and not hot:
        mode = "warm"
    if mode == "warm" and not warm:
        mode = "cold"
    return mode
