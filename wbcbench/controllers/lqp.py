"""Conventional lexicographic QP (LQP) on the full model (RC-LQP paper §2 and §4.1, Table 1).

Variables x = (q̈ (n), f (6c)); the torque is eliminated through the actuated rows of the
dynamics (eq. 6–7), Γ = M_a q̈ + h_a − J_c,aᵀ f. Priorities (Table 1):

1. ``dynamics``: the floating-base rows M_u q̈ + h_u − J_c,uᵀ f = 0 (6 eq) and the torque limits
   −Γ_max ≤ Γ ≤ Γ_max (2k ineq). This priority is always feasible (any torque within its limits,
   Γ = 0 say, is realised by some base acceleration with any wrench), so its optimal slacks are
   zero and its optimal set is its feasible set: it is held as hard constraints, which is the
   same solution without a QP of its own;
2. ``contacts``: stationary contacts J_c q̈ + J̇_c q̇ = 0 (6c eq), the contact-wrench inequalities
   (CoP, friction pyramid, yaw, normal force) and the joint-acceleration limits (2k ineq);
3. … the scenario's tasks, one level per distinct ``priority`` (priority 1 = Table 1's level 3:
   CoM position and pelvis orientation; priority 2 = level 4: end-effector poses);

and the acceleration energy ½ q̈ᵀ M q̈ (eq. 27), with a small ‖f‖² term so that double-support
wrenches are unique, in the cost of the last level (eq. 28 puts it in the LQP's cost; it is not a
priority of Table 1), weighted ``final_weight`` against that level's slacks. Every level is a
soft LQP level (eq. 26): minimal slacks, held by the levels below. Two exact shortcuts of
:mod:`wbcbench.qp.hierarchy` save QPs: the contacts level is held hard inside the first task
level's QP when that QP is feasible (its slacks are then zero), and a level with inequalities is
first solved with them hard, with slacks only when that is infeasible or a multiplier of its
inequalities is non-zero. In the usual state the sequential method solves one QP per task
priority. Solved by
the sequential method (``nullspace``), a cascade of full QPs (``cascade``) or one weighted QP
(``weighted``).

f is the reaction on the robot (see :mod:`wbcbench.dynamics.state`): the paper's F_c is −f.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field

from wbcbench import _native
from wbcbench.controllers.base import (
    ControllerConfig,
    ControllerContext,
    ControlOutput,
    NativeConfig,
    StageTimer,
)
from wbcbench.controllers.native import (
    LevelSolve,
    NativeController,
    NativeTimer,
    accept_tol,
    priority_groups,
    set_limits,
)
from wbcbench.dynamics.dense import spd_factor
from wbcbench.dynamics.state import RobotState
from wbcbench.qp.base import QPSolver
from wbcbench.qp.hierarchy import (
    Constraints,
    HierarchyResult,
    Objective,
    PriorityLevel,
    solve_hierarchy,
)
from wbcbench.tasks.contacts import contacts_dim, stack_wrench_constraints
from wbcbench.tasks.tasks import TaskTerm


class LexicographicConfig(ControllerConfig):
    """Settings both LQPs (conventional and reduced-centroidal) share."""

    strategy: Literal["nullspace", "cascade", "weighted"] = Field(
        "nullspace",
        description="sequential null-space method (the paper's), cascade of full QPs, or one "
        "weighted QP",
    )
    qdd_limit: float = Field(
        300.0, gt=0, description="joint-acceleration limit |q̈_j| of actuated joints [rad/s²]"
    )
    wrench_regularization: float = Field(
        1e-4, gt=0, description="weight of ‖f‖² next to the acceleration energy"
    )
    prox: float = Field(
        1e-8,
        ge=0,
        description="proximal weight of the retry of a level the backend failed to solve (a "
        "level's QP is only semidefinite; see wbcbench.qp.hierarchy); 0 = no retry",
    )
    weights: list[float] = Field(
        [1e4, 1e2, 1.0],
        description="weighted strategy only: weight per level (the last one repeats; the "
        "dynamics are hard constraints)",
    )
    final_weight: float = Field(
        1e-4,
        gt=0,
        description="weight of the acceleration energy next to the last level's slacks "
        "(sequential strategies: in the last level's QP; weighted: next to the level weights)",
    )


class LqpConfig(NativeConfig, LexicographicConfig):
    """Settings of the conventional LQP."""


# -- pieces shared with the reduced-centroidal LQP ---------------------------------------------


def task_levels(terms: list[TaskTerm]) -> list[tuple[int, list[TaskTerm]]]:
    """Tasks grouped by priority, highest (1) first."""
    levels: dict[int, list[TaskTerm]] = {}
    for term in terms:
        levels.setdefault(term.task.priority, []).append(term)
    return sorted(levels.items())


def energy_objective(name: str, Lt: np.ndarray, n_extra: int, reg: float) -> Objective:
    """Final objective ‖Lᵀ q̈‖² + reg ‖f‖² = q̈ᵀ M q̈ + reg ‖f‖², from the upper Cholesky
    factor ``Lt`` = Lᵀ of M = L Lᵀ."""
    n = Lt.shape[0]
    F = np.zeros((n + n_extra, n + n_extra))
    F[:n, :n] = Lt
    F[n:, n:] = np.sqrt(reg) * np.eye(n_extra)
    return Objective(name, F, np.zeros(n + n_extra))


def level_weight(weights: list[float], i: int) -> float:
    return weights[min(i, len(weights) - 1)]


def lexicographic_settings(
    cfg: LexicographicConfig, tasks: list[Any], active: list[Any] | None = None
) -> Any:
    """The native settings both LQPs share, from the Python config; ``active``: the tasks of
    the tick (all by default, see :func:`~wbcbench.controllers.native.priority_groups`)."""
    core = _native.core()
    s = core.LexicographicSettings()
    s.strategy = getattr(core.Strategy, cfg.strategy)
    s.qdd_limit = cfg.qdd_limit
    s.wrench_regularization = cfg.wrench_regularization
    s.prox = cfg.prox
    s.final_weight = cfg.final_weight
    s.weights = list(cfg.weights)
    s.priorities, s.groups = priority_groups(tasks, active)
    return s


class SolverPool:
    """Solver handles for the QPs of one hierarchy, created on first use and kept across ticks
    (hot solvers keep one problem structure each)."""

    def __init__(self, ctx: ControllerContext) -> None:
        self.ctx = ctx
        self.handles: list[QPSolver] = []

    def get(self, count: int) -> list[QPSolver]:
        while len(self.handles) < count:
            self.handles.append(self.ctx.new_solver())
        return self.handles[:count]


def slack_diagnostics(result: Any, prefix: str = "") -> dict[str, float]:
    """‖w‖ and ‖v‖ of every level (the optimal slacks: 0 when the level is met)."""
    out: dict[str, float] = {}
    for lv in result.levels:
        out[f"{prefix}w.{lv.name}"] = float(np.linalg.norm(lv.w)) if lv.w.size else 0.0
        out[f"{prefix}v.{lv.name}"] = float(np.linalg.norm(lv.v)) if lv.v.size else 0.0
    return out


def failed_output(
    n: int,
    k: int,
    nc: int,
    terms: list[TaskTerm],
    timings: dict[str, float],
    message: str,
    last: ControlOutput | None = None,
) -> ControlOutput:
    """A failed tick; timing and diagnostic keys of the last good tick are kept (as NaN where
    this tick has none) so per-tick logs stay rectangular."""
    diagnostics: dict[str, float] = {}
    if last is not None:
        timings = {**dict.fromkeys(last.timings, float("nan")), **timings}
        diagnostics = dict.fromkeys(last.diagnostics, float("nan"))
    return ControlOutput(
        tau=np.zeros(k),
        qdd=np.zeros(n),
        wrench=np.zeros(nc),
        terms=terms,
        timings=timings,
        ok=False,
        message=message,
        diagnostics=diagnostics,
    )


# -- the controller ----------------------------------------------------------------------------


class Lqp(NativeController):
    """Conventional full-model LQP of RC-LQP Table 1 (the baseline of ``rc_lqp``)."""

    name = "lqp"
    summary = (
        "conventional lexicographic QP on the full model (RC-LQP Table 1), (q̈, f) with torque "
        "eliminated; sequential null-space, cascade or weighted"
    )
    Config = LqpConfig
    reference_solvers = ("quadprog",)
    config: LqpConfig
    tick_type = "LqpTick"
    native_schedule = True
    # a workspace per contact set in the tick (its levels, constraints and hierarchy sizes)
    contact_workspaces = True

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.frames = ctx.contact_frames
        self.Cw, self.lw, self.uw = stack_wrench_constraints(ctx.contacts)
        self.nc = contacts_dim(self.contacts)
        self.pool = SolverPool(ctx)
        self.last: HierarchyResult | None = None
        self.last_output: ControlOutput | None = None

    def configure_tick(self, tick: Any) -> None:
        s = lexicographic_settings(self.config, self.ctx.tasks, self.active_tasks)
        s.accept_tol = accept_tol(self.ctx)
        set_limits(s, self.ctx.tau_max, self.Cw, self.lw, self.uw, self.nc)
        tick.configure(s)

    def level_solve(self, tick: Any) -> LevelSolve:
        # handles for the most levels any contact set gives (contacts, every priority, energy):
        # a set whose tasks leave a priority empty uses the first ones, as the reference does
        levels = len({task.priority for task in self.ctx.tasks}) + 2
        return LevelSolve(
            lambda pool, i: tick.slot(i),
            [self.pool.get(max(tick.handles, 2 * levels))],
            self.ctx.keep_problems,
            self.config.solver_calls,
            origin=self.config.strategy == "nullspace",
        )

    def native_diagnostics(
        self, state: RobotState, terms: list[TaskTerm], ok: bool
    ) -> dict[str, float]:
        result = self.native_tick.result
        return {**slack_diagnostics(result), "prox_retries": float(result.retries)}

    def native_output(
        self, state: RobotState, timer: NativeTimer, message: str | None
    ) -> ControlOutput:
        """A failed tick keeps the last good tick's keys (see :func:`failed_output`)."""
        if message is not None:
            terms = self.native_terms()
            timings = timer.finish(self.native_tick)
            return failed_output(
                state.n, state.k, self.nc, terms, timings, message, self.last_output
            )
        self.last_output = super().native_output(state, timer, message)
        return self.last_output

    def hierarchy(
        self, state: RobotState, terms: list[TaskTerm]
    ) -> tuple[Constraints, list[PriorityLevel], Objective, np.ndarray, np.ndarray]:
        """Priority 1 (hard), the levels and the energy over x = (q̈, f), and the torque map
        Γ = G x + γ."""
        cfg = self.config
        n, k, nc = state.n, state.k, self.nc
        nx = n + nc
        M, h = state.M, state.h
        Jc = state.contact_jacobian(self.contacts)
        Jk, dk = state.contact_constraint(self.contacts)
        tau_max = self.ctx.tau_max
        G = np.hstack([M[6:], -Jc[:, 6:].T])
        gamma = h[6:]
        dyn = Constraints(
            nx,
            A=np.hstack([M[:6], -Jc[:, :6].T]),
            b=-h[:6],
            C=G,
            l=-tau_max - gamma,
            u=tau_max - gamma,
        )
        nw = self.Cw.shape[0]
        C2 = np.zeros((nw + k, nx))
        C2[:nw, n:] = self.Cw
        C2[nw:, 6:n] = np.eye(k)
        qdd_max = np.full(k, cfg.qdd_limit)
        contacts = PriorityLevel(
            "contacts",
            A=np.hstack([Jk, np.zeros((Jk.shape[0], nc))]),
            b=-dk,
            C=C2,
            l=np.concatenate([self.lw, -qdd_max]),
            u=np.concatenate([self.uw, qdd_max]),
            hard_if_feasible=True,
        )
        levels = [contacts]
        for p, group in task_levels(terms):
            J = np.vstack([t.J for t in group])
            r = np.concatenate([t.acc_ref - t.drift for t in group])
            levels.append(PriorityLevel(f"p{p}", A=np.hstack([J, np.zeros((J.shape[0], nc))]), b=r))
        for i, lv in enumerate(levels):
            lv.weight = level_weight(cfg.weights, i)
        final = energy_objective("energy", spd_factor(M), nc, cfg.wrench_regularization)
        final.weight = cfg.final_weight
        return dyn, levels, final, G, gamma

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        self.select_contacts(t)
        timer = StageTimer(state)
        cfg = self.config
        n, k, nc = state.n, state.k, self.nc
        terms = self.evaluate_tasks(state, t)
        hard, levels, final, G, gamma = self.hierarchy(state, terms)
        result = solve_hierarchy(
            hard,
            levels,
            [final],
            cfg.strategy,
            self.pool.get(2 * (len(levels) + 1)),
            timer,
            prox=cfg.prox,
            merge_finals=True,
            slack_free_first=True,
        )
        self.last = result
        if not result.ok:
            msg = result.message
            return failed_output(n, k, nc, terms, timer.finish(), msg, self.last_output)
        x = result.x
        tau = G @ x + gamma
        self.last_output = ControlOutput(
            tau=tau,
            qdd=x[:n].copy(),
            wrench=x[n:].copy(),
            terms=terms,
            timings=timer.finish(),
            iterations=timer.iterations,
            diagnostics={**slack_diagnostics(result), "prox_retries": float(result.retries)},
        )
        return self.last_output
