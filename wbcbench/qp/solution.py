"""The uniform result every backend returns."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


class SolutionStatus(StrEnum):
    """What the solver reported, translated to one vocabulary.

    ``solved``: converged to the requested tolerances. ``infeasible``: primal or dual
    infeasibility detected. ``max_iter``: an iteration or time limit stopped it.
    ``numerical``: the solver gave up or only reached reduced accuracy for numerical reasons.
    ``failed``: anything else, including an exception raised inside the backend.
    """

    SOLVED = "solved"
    INFEASIBLE = "infeasible"
    MAX_ITER = "max_iter"
    NUMERICAL = "numerical"
    FAILED = "failed"


@dataclass
class Solution:
    """Result of one solve.

    Dual sign convention (shared by every backend, see :mod:`wbcbench.qp.validity`): the
    Lagrangian is ``½xᵀHx + gᵀx + yᵀ(Ax − b) + zᵀCx + z_boxᵀx`` and at the optimum
    ``Hx + g + Aᵀy + Cᵀz + z_box = 0`` with ``z_i ≥ 0`` when the upper bound ``u_i`` is active,
    ``z_i ≤ 0`` when the lower bound ``l_i`` is active, ``0`` when neither is.

    Attributes:
        status: the solver's own verdict (see :func:`wbcbench.qp.validity.validated` for the
            verdict after an independent check).
        x: primal solution ``(n,)``, or ``None`` if the backend produced none.
        y: equality duals ``(n_eq,)`` or ``None``.
        z: inequality duals ``(n_in,)`` or ``None``.
        z_box: bound duals ``(n,)`` when the problem has a box and the backend reports them.
        iterations: the solver's iteration count (its own definition), or ``None``.
        wall_time: [s] ``time.perf_counter`` around the native solve call(s) only.
        setup_time: [s] building (or, in hot mode, updating) the native object and matrices.
        call_time: [s] the whole ``QPSolver.solve`` call: validation, change detection, set-up,
            the native call and reading the result back (what a controller pays).
        internal_time: [s] the solver's own timer, or ``None`` when unavailable.
        internal_time_covers: what ``internal_time`` measures (``"solve"``,
            ``"setup+solve"``) or ``""`` when unavailable.
        objective: ``½ xᵀHx + gᵀx`` at ``x`` (``nan`` when ``x`` is ``None``).
        solver: registry name of the backend (e.g. ``"proxqp"``, ``"qpsolvers:osqp"``).
        mode: the effective mode (``cold``, ``warm``, ``hot``) after any fallback.
        message: the solver's status text, notes on fallbacks or regularisation, or the
            exception text of a failure.
        tier: the accuracy tier the solver was configured with.
        rebuilt: in hot mode, True when the native object was (re)built on this call.
    """

    status: SolutionStatus
    x: Array | None = None
    y: Array | None = None
    z: Array | None = None
    z_box: Array | None = None
    iterations: int | None = None
    wall_time: float = 0.0
    setup_time: float = 0.0
    call_time: float = 0.0
    internal_time: float | None = None
    internal_time_covers: str = ""
    objective: float = float("nan")
    solver: str = ""
    mode: str = ""
    message: str = ""
    tier: str = ""
    rebuilt: bool = False

    @property
    def success(self) -> bool:
        """True iff the solver reported ``solved``."""
        return self.status is SolutionStatus.SOLVED


class SolveTimes:
    """The solve stages of one step, summed over its QPs: ``solve`` (the calls into the QP
    layer), ``solve_setup``, ``solve_native``, ``solve_internal``, ``solve.<level>``, and the
    iterations."""

    def __init__(self) -> None:
        self.solve = 0.0
        self.solve_setup = 0.0
        self.solve_native = 0.0
        self.solve_internal = 0.0
        self.internal_known = True
        self.levels: dict[str, float] = {}
        self.iterations = 0.0

    def add_solution(self, sol: Solution, level: str | None = None) -> None:
        # the whole call into the QP layer: validation, set-up / update of the solver's object,
        # the native solve and reading the result back (``solve_native`` is the native call)
        call = sol.call_time or (sol.setup_time + sol.wall_time)
        self.solve += call
        self.solve_setup += sol.setup_time
        self.solve_native += sol.wall_time
        if sol.internal_time is None:
            self.internal_known = False
        else:
            self.solve_internal += sol.internal_time
        if sol.iterations is not None:
            self.iterations += sol.iterations
        if level is not None:
            key = f"solve.{level}"
            self.levels[key] = self.levels.get(key, 0.0) + call

    def solve_stages(self) -> dict[str, float]:
        return {
            "solve": self.solve,
            "solve_setup": self.solve_setup,
            "solve_native": self.solve_native,
            "solve_internal": self.solve_internal if self.internal_known else float("nan"),
            **self.levels,
        }
