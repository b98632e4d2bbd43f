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
