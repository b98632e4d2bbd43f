"""QP layer: the solver-agnostic :class:`Problem`, one module per backend, one registry.

Controllers build :class:`Problem` objects and either keep a handle per hierarchy level::

    solver = make_solver("proxqp", tier="mid", mode="hot")
    sol = solver.solve(problem)

or call the one-shot :func:`solve`. Every backend returns a :class:`Solution` with the same
fields and sign conventions; :func:`check_solution` verifies one independently.
"""

from __future__ import annotations

# first: chooses proxsuite's build before any backend imports proxsuite
from wbcbench.qp import proxsuite_build  # noqa: F401
from wbcbench.qp.base import QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.registry import (
    all_solvers,
    available_backends,
    available_solvers,
    default_solver,
    make_solver,
    solver_class,
)
from wbcbench.qp.settings import MODES, TIERS
from wbcbench.qp.solution import Solution, SolutionStatus
from wbcbench.qp.validity import Validity, check_solution, validated

__all__ = [
    "MODES",
    "TIERS",
    "Problem",
    "QPSolver",
    "Solution",
    "SolutionStatus",
    "Validity",
    "all_solvers",
    "available_backends",
    "available_solvers",
    "check_solution",
    "default_solver",
    "make_solver",
    "solve",
    "solver_class",
    "validated",
]


def solve(
    problem: Problem, solver: str = "default", tier: str = "default", mode: str = "cold"
) -> Solution:
    """Solve ``problem`` once with a fresh handle (see :func:`make_solver` for the arguments).

    A one-shot handle has no previous solution, so ``warm`` and ``hot`` behave as ``cold``
    here; keep a handle from :func:`make_solver` to benefit from them.
    """
    name = default_solver() if solver == "default" else solver
    return make_solver(name, tier=tier, mode=mode).solve(problem)
