"""eiquadprog called from C++, as TSID calls it: Goldfarb–Idnani dual active set, dense.

The eiquadprog wheel ships the C++ library and its headers, no Python binding: every solve of
this backend, on the Python path too, goes through the native module's ``EiquadprogSolver``
(``wbcbench/_native/src/qp/eiquadprog_solver.hpp``, which describes the native form, the row
split, the status map, the duals and the Hessian shift). This handle copies the problem into a
native ``QpBuffers`` (counted in ``setup_time``) and hands it to that object;
:meth:`EiquadprogSolver.native_solver` gives native ticks an object of their own in the same
mode, so a tick's QPs never leave C++. Without the native module the backend is not available.

Modes: the library takes no initial guess, so ``warm`` runs ``cold``; ``hot`` keeps the
``EiquadprogFast`` object as TSID does (its workspace sized once; rebuilt when a size or the set
of finite sides changes), and every solve still starts from the unconstrained minimum. Times:
``wall_time`` is the ``solve_quadprog`` call, ``setup_time`` the copies and the check that ``H``
is positive definite; the library has no timer. Tiers do not apply (the active-set method is
exact up to round-off); the only setting is ``max_iter`` (the library's default: 1000
active-set iterations).
"""

from __future__ import annotations

import time
from typing import Any

from wbcbench import _native
from wbcbench.qp.backends._common import fill_buffers as fill
from wbcbench.qp.backends._common import native_solution
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.solution import Solution

LIBRARY = "eiquadprog"

if _native._core is None:
    raise ImportError(f"eiquadprog is called from the native module, which is {_native.REASON}")
if not hasattr(_native._core, "EiquadprogSolver"):
    raise ImportError(
        "the native module was built without eiquadprog: rebuild it (make native) with the "
        "eiquadprog wheel installed"
    )


class EiquadprogSolver(QPSolver):
    """eiquadprog through the native module; see the module docstring."""

    name = "eiquadprog"
    default_eps = 1e-9  # a dual active-set method: exact to round-off
    summary = "eiquadprog (C++, as TSID calls it): Goldfarb-Idnani dual active set, dense"
    warm_start = False
    hot_start = True
    internal_time_covers = ""

    def _cpp_options(self) -> dict[str, float]:
        return {k: float(v) for k, v in self.options.items()}

    def native_solver(self) -> Any | None:
        """The same C++ solver for native ticks, in this handle's mode; None when a setting is
        not one it takes (those solves then fail on the Python path with the reason)."""
        try:
            return _native._core.EiquadprogSolver(self.mode, self._cpp_options())
        except (ValueError, TypeError):
            return None

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        buffers = _native._core.QpBuffers()
        fill(buffers, problem)
        cpp = _native._core.EiquadprogSolver("hot" if keep else "cold", self._cpp_options())
        t1 = time.perf_counter()
        self._native = (cpp, buffers) if keep else None
        return self._call(cpp, buffers, problem, t1 - t0)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        cpp, buffers = self._native
        t0 = time.perf_counter()
        fill(buffers, problem, changed)
        t1 = time.perf_counter()
        sol = self._call(cpp, buffers, problem, t1 - t0)
        if sol.rebuilt:  # the finite sides changed: the C++ object rebuilt its solver
            self.builds += 1
        return sol

    @staticmethod
    def _call(cpp: Any, buffers: Any, problem: Problem, copy_time: float) -> Solution:
        return native_solution(cpp, buffers, problem, copy_time)
