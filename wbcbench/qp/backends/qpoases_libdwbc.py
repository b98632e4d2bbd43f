"""``qpoases_libdwbc``: qpOASES used the way the OSF-HQP / TO-OSF papers' library uses it.

Reproduces the solver usage behind the timings of Y. Lee, J. Ahn, J. Lee and J. Park,
"Computationally Efficient HQP-based Whole-body Control Exploiting the Operational-space
Formulation" (OSF-HQP, IROS 2021, §IV: "QPs are solved by qpOASES library"), and of Y. Lee et
al.'s task-oriented OSF (IEEE Access 2021, qpOASES). The papers state no solver settings; they
are those of the authors' C++ library, libdwbc (``CQuadraticProgram::SolveQPoases`` in
``src/qp_wrapper.cpp``, called by ``RobotData::CalcSingleTaskTorqueWithQP`` and
``RobotData::CalcContactRedistribute`` in ``src/dwbc.cpp``):

* one ``SQProblem(n_var, n_constraints)`` per QP, kept between control ticks (re-made only when
  a size changes): the first tick calls ``init``, every later one ``hotstart`` from the working
  set the previous tick ended with;
* ``Options::setToMPC()`` for a task QP (each OSF-HQP level, and every other QP here),
  ``Options::setToReliable()`` for the contact-wrench QP, ``printLevel = PL_NONE``;
* ``nWSR`` = 1000 working-set changes per call for a task QP, 300 for the contact QP;
* no box bounds handed over when the QP has none;
* after a failed ``hotstart``: a fresh ``SQProblem`` with ``setToReliable()``, ten times the
  ``nWSR`` cap, initialised from scratch in the same call.

One departure, in the first ``init`` alone: it starts the box bounds inactive. The QPs have none;
qpOASES stands ±infinity in for them, and ``setToReliable()`` starts each variable at its lower
one, a homotopy that cycles on the contact-wrench QP (thousands of working-set changes, past
libdwbc's caps). ``setToMPC()`` starts them inactive anyway; the options go back to
libdwbc's before the first ``hotstart`` (docs/qpoases.md).

libdwbc sends ``H`` and ``A`` with every ``hotstart`` (the matrix hotstart, which rebuilds
qpOASES' factorisations of the kept working set). Here the matrices go only when they changed
since the last call, else the vector ``hotstart`` keeps the factorisations: on a whole-body
controller's ticks the matrices change every tick, so the two agree; only a bit-identical repeat
of a QP takes the cheaper call here.

What the QP is to its controller picks the options: the handle's :attr:`QPSolver.qp_kind`
(``"wrench"`` for OSF-HQP's contact-wrench QP, ``"task"`` for any other). The solves run in
C++ on both paths (the native module's ``QpOasesSolver``, cmeel-qpoases' qpOASES 3.2.2): this
handle copies the problem into native buffers (counted in ``setup_time``); without the native
module the setting is not available. ``qpoases`` runs qpOASES as CasADi does (default options,
the matrix hotstart with every field, a bounds-only QP re-initialised on every call).

Its options and policy *are* the setting: tier ``default`` and mode ``hot`` only, no option
overrides. Accuracy: ``setToMPC``'s termination tolerance, 1e9 machine epsilons (2.2e-7);
``setToReliable`` keeps qpOASES' default (5e6 epsilons).
"""

from __future__ import annotations

import time
from typing import Any

from wbcbench import _native
from wbcbench.qp.backends._common import fill_buffers, native_solution
from wbcbench.qp.base import Guess, QPSolver
from wbcbench.qp.problem import Problem
from wbcbench.qp.solution import Solution, SolutionStatus

LIBRARY = "cmeel-qpoases"

if _native._core is None:
    raise ImportError(f"qpoases_libdwbc runs in the native module, which is {_native.REASON}")

#: the native profile per QP kind (libdwbc: setToMPC for task QPs, setToReliable for the
#: contact-wrench QP)
PROFILES: dict[str, str] = {"task": "libdwbc_task", "wrench": "libdwbc_wrench"}

#: setToMPC's terminationTolerance: 1e9 machine epsilons
MPC_TOLERANCE = 1e9 * 2.221e-16  # qpOASES EPS


class QpOASESLibdwbcSolver(QPSolver):
    """qpOASES as the OSF papers' libdwbc runs it; see the module docstring."""

    name = "qpoases_libdwbc"
    summary = (
        "qpOASES as the OSF papers' libdwbc runs it: setToMPC (task QPs) / setToReliable "
        "(contact QP), working set kept between ticks"
    )
    warm_start = False
    hot_start = True
    internal_time_covers = "solve"
    default_eps = MPC_TOLERANCE
    tiers = ("default",)
    modes = ("hot",)
    options_allowed = False
    choice_hint = (
        "qpoases_libdwbc is a fixed setting: tier default = libdwbc's qpOASES options "
        "(setToMPC for task QPs, setToReliable for the contact-wrench QP), mode hot = one "
        "SQProblem per QP hot-started from its previous working set; `qpoases` runs qpOASES as "
        "CasADi does at any tier or mode"
    )

    def profile(self) -> str:
        """The native profile of this handle's QP kind."""
        return PROFILES[self.qp_kind]

    def native_solver(self) -> Any | None:
        """The same C++ solver for native ticks (this handle's profile, mode hot)."""
        return _native._core.QpOasesSolver("hot", {}, profile=self.profile())

    def _solve_fresh(self, problem: Problem, guess: Guess | None, keep: bool) -> Solution:
        t0 = time.perf_counter()
        buffers = _native._core.QpBuffers()
        fill_buffers(buffers, problem)
        cpp = _native._core.QpOasesSolver("hot", {}, profile=self.profile())
        t1 = time.perf_counter()
        self._native = (cpp, buffers) if keep else None
        return self._call(cpp, buffers, problem, t1 - t0)

    def _solve_update(
        self, problem: Problem, guess: Guess | None, changed: frozenset[str]
    ) -> Solution:
        cpp, buffers = self._native
        t0 = time.perf_counter()
        fill_buffers(buffers, problem, changed)
        t1 = time.perf_counter()
        # (libdwbc's fallback makes a fresh SQProblem inside the call: reported as rebuilt, not
        # counted in builds, which count the objects a hot handle set up itself)
        return self._call(cpp, buffers, problem, t1 - t0)

    @staticmethod
    def _call(cpp: Any, buffers: Any, problem: Problem, copy_time: float) -> Solution:
        return native_solution(
            cpp,
            buffers,
            problem,
            copy_time,
            internal=True,
            answer=lambda sol: sol.status in (SolutionStatus.SOLVED, SolutionStatus.MAX_ITER),
        )
