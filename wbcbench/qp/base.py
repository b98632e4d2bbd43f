"""The stateful solver handle every backend implements.

A :class:`QPSolver` is created by :func:`wbcbench.qp.registry.make_solver`, typically one per
controller level, and called once per control tick. It keeps the previous solution (for
``warm``) and the native solver object (for ``hot``). Backends implement two hooks:

* :meth:`QPSolver._solve_fresh` — build a native object for ``problem``, solve, return a
  :class:`Solution`; it keeps the object in ``self._native`` when ``keep`` is true so that
* :meth:`QPSolver._solve_update` — update the kept object with what changed and solve —
  can be used on the next call (``hot`` only).

Timing is measured by the backend, around native calls only (see :class:`Solution`).
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from wbcbench.errors import SolverError, UnofferedChoiceError, WbcBenchError
from wbcbench.qp.problem import Problem
from wbcbench.qp.settings import MODES, TIER_EPS, TIERS, check_mode, check_tier, effective_mode
from wbcbench.qp.solution import Solution, SolutionStatus

Array = NDArray[np.float64]

#: What a QP is to its controller (:attr:`QPSolver.qp_kind`): a task QP (a hierarchy level, a
#: whole-body QP) or OSF-HQP's contact-wrench distribution QP. Only a named setting that
#: follows a paper's code per kind of QP (``qpoases_libdwbc``) tells them apart.
QP_KINDS: tuple[str, ...] = ("task", "wrench")

#: Fields of a :class:`Problem` an in-place update may change.
DATA_FIELDS: tuple[str, ...] = ("H", "g", "A", "b", "C", "l", "u", "lb", "ub")


@dataclass
class Guess:
    """An initial guess: primal ``x`` ``(n,)`` and, when known, duals in the shared convention."""

    x: Array
    y: Array | None = None
    z: Array | None = None
    z_box: Array | None = None


class QPSolver(ABC):
    """Base class of every backend handle (one module per backend in ``qp/backends``).

    Class attributes a backend sets:
        name: registry name.
        summary: one line for ``wbcbench list``.
        warm_start: the native API accepts an initial guess on a fresh object.
        hot_start: the native object can be kept and updated in place.
        internal_time_covers: what the solver's own timer covers, ``""`` if it has none.
        tiers, modes: the tiers and modes it runs at: all of them for a backend, fewer for a
            named setting that fixes its own tolerances or update policy
            (:mod:`wbcbench.qp.backends.osqp_libdwbc`); ``choice_hint`` says why.
        options_allowed: native settings may be overridden (``make_solver(..., **options)``);
            ``False`` for a named setting, whose settings are its definition.
        default_eps: the accuracy its own default settings stop at (the ``default`` tier's),
            relative to the problem's scale: what the independent check of a reported solution
            holds it to (:meth:`accuracy`).
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    warm_start: ClassVar[bool] = False
    hot_start: ClassVar[bool] = False
    internal_time_covers: ClassVar[str] = ""
    tiers: ClassVar[tuple[str, ...]] = TIERS
    modes: ClassVar[tuple[str, ...]] = MODES
    choice_hint: ClassVar[str] = ""
    options_allowed: ClassVar[bool] = True
    default_eps: ClassVar[float] = 1e-6

    @classmethod
    def accuracy(cls, tier: str) -> float:
        """The tolerance ``tier`` asks for (:data:`~wbcbench.qp.settings.TIER_EPS`), or the
        backend's own default accuracy at the ``default`` tier."""
        return TIER_EPS.get(tier, cls.default_eps)

    def __init__(self, tier: str = "default", mode: str = "cold", **options: Any) -> None:
        """Create a handle.

        Args:
            tier: accuracy tier (see :mod:`wbcbench.qp.settings`).
            mode: requested mode; ``self.mode`` holds the effective one.
            **options: native settings overriding the tier's (names as in the library).

        Raises:
            UnknownNameError: an unknown tier or mode, or (:class:`UnofferedChoiceError`) one
                this entry does not run at.
            WbcBenchError: native options given to a named setting.
        """
        self.tier = check_tier(tier)
        self.requested_mode = check_mode(mode)
        self.check_choice(tier, mode)
        if options and not self.options_allowed:
            raise WbcBenchError(
                f"{self.name} takes no native options (got {', '.join(sorted(options))}): "
                + (self.choice_hint or "its settings are its definition")
            )
        self.mode = effective_mode(mode, self.warm_start, self.hot_start)
        self.options: dict[str, Any] = {
            **self.tier_caps(tier),
            **self.tier_settings(tier),
            **options,
        }
        #: what the QP is to its controller (:data:`QP_KINDS`); set by the controller
        self.qp_kind = "task"
        self.previous: Solution | None = None
        self.builds = 0  # native objects built by _solve_fresh with keep=True
        self._native: Any = None
        self._native_key: Hashable = None
        self._last: dict[str, bytes | None] = {}

    @classmethod
    def offers(cls, tier: str, mode: str) -> bool:
        """True when this entry runs at ``tier`` and ``mode``."""
        return tier in cls.tiers and mode in cls.modes

    @classmethod
    def check_choice(cls, tier: str, mode: str) -> None:
        """Raise :class:`UnofferedChoiceError` unless this entry runs at ``tier`` and ``mode``."""
        if tier not in cls.tiers:
            raise UnofferedChoiceError(cls.name, "tier", tier, cls.tiers, hint=cls.choice_hint)
        if mode not in cls.modes:
            raise UnofferedChoiceError(cls.name, "mode", mode, cls.modes, hint=cls.choice_hint)

    # ---- backend hooks -------------------------------------------------------------------
    @staticmethod
    def tier_settings(tier: str) -> dict[str, Any]:
        """Native settings realising ``tier`` for this backend (empty for ``default``)."""
        return {}

    @staticmethod
    def tier_caps(tier: str) -> dict[str, Any]:
        """Native time / iteration caps of ``tier`` (:data:`~wbcbench.qp.settings.
        TIER_TIME_LIMIT`), for the backends whose library has them; every tier has caps."""
        return {}

    @abstractmethod
    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        """Build the native object for ``problem`` and solve; keep the object when ``keep``."""

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        """Update the kept native object in place (hot mode); backends that can override it."""
        raise SolverError(f"{self.name} cannot update its solver in place", problem=problem)

    def _native_signature(self, problem: Problem) -> Hashable:
        """What must be equal for an in-place update; backends may add to the structure key."""
        return problem.structure_key()

    def _can_update(self, problem: Problem) -> bool:
        """Extra per-call test for an in-place update (e.g. a sparsity pattern still fits)."""
        return True

    def native_solver(self) -> Any | None:
        """The same solver called from C++ (a ``wbcbench._native`` ``QpSolver`` with this
        handle's mode and settings) for the level solves of native ticks, or None when the
        module does not link this backend's library or cannot take one of its settings; those
        solves then go through :meth:`solve` (``lean=True``)."""
        return None

    # ---- public --------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the previous solution and the native object."""
        self.previous = None
        self._native = None
        self._native_key = None
        self._last = {}

    def solve(
        self,
        problem: Problem,
        x0: Array | None = None,
        raise_on_failure: bool = False,
        lean: bool = False,
        origin: bool = False,
    ) -> Solution:
        """Solve ``problem``.

        Args:
            problem: the QP.
            x0: explicit primal initial guess ``(n,)``; passed to the solver in any mode when
                its API accepts one. Without it, ``warm`` and ``hot`` reuse the previous
                solution.
            origin: the QP's variables are coordinates made afresh for this call (a null-space
                level's y, x = x_p + Z y, x_p the levels above's answer and Z a basis of this
                tick), so the previous solution means nothing in them: ``warm`` and ``hot``
                start at x = 0 (the levels above's answer) with zero duals, a hot backend
                keeping its native object. ``cold`` and an explicit ``x0`` ignore it.
            raise_on_failure: raise :class:`SolverError` (carrying the problem) instead of
                returning a non-``solved`` Solution.
            lean: the timed path of native ticks: no validation of the problem (its builder
                sized the buffers once and checked them finite) and no objective computed when
                the solver reports none. The independent check of the answer runs after the
                tick, as on every path.

        Returns:
            The Solution. A backend exception is returned as status ``failed`` with the
            exception text as message, so a benchmark sweep goes on.
        """
        t_call = time.perf_counter()
        try:
            if not lean:
                problem.validate()
            at_origin = origin and x0 is None and self.mode != "cold"
            if self.mode == "hot":
                sol = self._solve_hot(problem, x0, at_origin)
            else:
                guess = self._origin_guess(problem) if at_origin else self._guess(problem, x0)
                sol = self._solve_fresh(problem, guess, keep=False)
        except Exception as exc:  # a failed row, never a crashed sweep (hot: rebuilt below)
            sol = Solution(status=SolutionStatus.FAILED, message=f"{type(exc).__name__}: {exc}")
        if sol.success and (sol.x is None or not np.isfinite(sol.x).all()):
            sol.status = SolutionStatus.NUMERICAL
            sol.message = f"reported {sol.message or 'solved'} without a finite x"
        sol.solver = self.name
        sol.mode = self.mode
        sol.tier = self.tier
        if not lean and sol.x is not None and sol.objective != sol.objective:  # not reported
            sol.objective = problem.objective(sol.x)
        if sol.internal_time is not None and not sol.internal_time_covers:
            sol.internal_time_covers = self.internal_time_covers
        if sol.success and sol.x is not None:
            self.previous = sol
        elif self.mode == "hot":
            # the native object's iterate is the failed one (possibly diverged): the next call
            # rebuilds it, warm-started from the last solution that succeeded
            self._native = None
        sol.call_time = time.perf_counter() - t_call
        if raise_on_failure and not sol.success:
            raise SolverError(
                f"{self.name} ({self.mode}, tier {self.tier}) returned {sol.status}"
                + (f": {sol.message}" if sol.message else ""),
                problem=problem,
                solver=self.name,
            )
        return sol

    # ---- internals -----------------------------------------------------------------------
    def _guess(self, problem: Problem, x0: Array | None) -> Guess | None:
        if x0 is not None:
            x = np.asarray(x0, dtype=np.float64)
            if x.shape != (problem.n,):
                raise SolverError(
                    f"x0 has shape {x.shape}, expected ({problem.n},)",
                    problem=problem,
                    solver=self.name,
                )
            return Guess(x=x)
        prev = self.previous
        if self.mode == "cold" or prev is None or prev.x is None or prev.x.shape != (problem.n,):
            return None
        return Guess(
            x=prev.x,
            y=prev.y if prev.y is not None and prev.y.shape == (problem.n_eq,) else None,
            z=prev.z if prev.z is not None and prev.z.shape == (problem.n_in,) else None,
            z_box=prev.z_box if prev.z_box is not None and problem.has_box else None,
        )

    def _origin_guess(self, problem: Problem, update: bool = False) -> Guess | None:
        """x = 0 and zero duals (see ``origin`` in :meth:`solve`), or None (the backend's own
        initial guess) for a new native object when no solution came before."""
        if not update and self.previous is None:
            return None
        return Guess(
            x=np.zeros(problem.n),
            y=np.zeros(problem.n_eq),
            z=np.zeros(problem.n_in),
            z_box=np.zeros(problem.n) if problem.has_box else None,
        )

    def _solve_hot(self, problem: Problem, x0: Array | None, at_origin: bool = False) -> Solution:
        key = self._native_signature(problem)
        snapshot = self._snapshot(problem)
        if self._native is not None and key == self._native_key and self._can_update(problem):
            # The native object already holds the previous iterate: pass only an explicit x0
            # or the origin.
            changed = frozenset(k for k in DATA_FIELDS if snapshot[k] != self._last.get(k))
            if at_origin:
                guess: Guess | None = self._origin_guess(problem, update=True)
            else:
                guess = None if x0 is None else self._guess(problem, x0)
            sol = self._solve_update(problem, guess, changed)
        else:
            self._native = None
            guess = self._origin_guess(problem) if at_origin else self._guess(problem, x0)
            sol = self._solve_fresh(problem, guess, keep=True)
            sol.rebuilt = True
            self.builds += 1
            self._native_key = key
        self._last = snapshot
        return sol

    @staticmethod
    def _snapshot(problem: Problem) -> dict[str, bytes | None]:
        """The data as bytes: a copy (a controller may refill its arrays in place) that compares
        by memcmp, the cheapest exact test (a ±0 or NaN mismatch only makes an update send more
        than it must)."""
        out: dict[str, bytes | None] = {}
        for key in DATA_FIELDS:
            v = getattr(problem, key)
            out[key] = None if v is None else v.tobytes()
        return out
