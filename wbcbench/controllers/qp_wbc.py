"""Weighted QP whole-body control (TO-OSF paper §V-A, eq. 22–25).

One QP per tick. Soft hierarchy: every task is a weighted least-squares term, with the weight set
by its priority (the paper uses 1e9, 1e6, 1e3, 1).

Variables ``full``: x = (q̈ (n), Γ (k), f (6c)); ``eliminated``: x = (q̈, f) with Γ removed through
the actuated rows of the dynamics (as RC-LQP §2 eq. 6–7 do). Both give the same optimum.

    minimise   Σ_j w_j ‖J_j q̈ + J̇_j q̇ − ẍ*_j‖² + w_f ‖f‖² + w_Γ ‖Γ‖² + w_q̈ ‖q̈‖²
    subject to M q̈ + h = Sᵀ Γ + J_cᵀ f            (dynamics; only its 6 base rows when eliminated)
               J_c q̈ + J̇_c q̇ = 0                    (stationary contacts)
               l_w ≤ C_w f ≤ u_w                      (wrench inequalities, TO-OSF eq. 15)
               −Γ_max ≤ Γ ≤ Γ_max                      (torque limits)

f is the reaction on the robot (see :mod:`wbcbench.dynamics.state`).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

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
from wbcbench.controllers.native import NativeController, QpCall, set_limits
from wbcbench.dynamics.state import RobotState
from wbcbench.qp import Problem
from wbcbench.tasks.contacts import contacts_dim, stack_wrench_constraints
from wbcbench.tasks.tasks import Task, TaskTerm


class QpWbcConfig(NativeConfig):
    """Settings of the weighted QP-WBC."""

    variables: Literal["full", "eliminated"] = Field(
        "full", description="(q̈, Γ, f) or torque-eliminated (q̈, f)"
    )
    weights: list[Annotated[float, Field(gt=0)]] = Field(
        [1e3, 1.0, 1e-3, 1e-6],
        min_length=1,
        description="task weight per priority (1 first); the last one repeats for lower ones",
    )
    wrench_weight: float = Field(1e-5, ge=0, description="weight of ‖f‖²")
    torque_weight: float = Field(1e-7, ge=0, description="weight of ‖Γ‖²")
    acceleration_weight: float = Field(1e-7, ge=0, description="weight of ‖q̈‖² (regularization)")


def task_weight(term: TaskTerm, weights: list[float]) -> float:
    """A task's explicit weight, else the weight of its priority (last weight repeats)."""
    return task_weight_of(term.task, weights)


def task_weight_of(task: Task, weights: list[float]) -> float:
    """:func:`task_weight` of a task."""
    if task.weight is not None:
        return task.weight
    idx = min(max(task.priority, 1), len(weights)) - 1
    return weights[idx]


def accumulate_tasks(
    terms: list[TaskTerm], weights: list[float], n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Σ w Jᵀ J (n, n) and −Σ w Jᵀ (ẍ* − J̇ q̇) (n,): the task part of a weighted QP over q̈."""
    if not terms:
        return np.zeros((n, n)), np.zeros(n)
    J = np.vstack([t.J for t in terms])
    r = np.concatenate([t.acc_ref - t.drift for t in terms])
    w = np.concatenate([np.full(t.dim, task_weight(t, weights)) for t in terms])
    Jw = J * w[:, None]
    return J.T @ Jw, -(Jw.T @ r)


class QpWbc(NativeController):
    """Weighted QP-WBC: one QP, soft priorities through weights."""

    name = "qp_wbc"
    summary = "weighted QP-WBC (soft hierarchy), variables (q̈, Γ, f) or (q̈, f)"
    Config = QpWbcConfig
    config: QpWbcConfig
    tick_type = "QpWbcTick"
    native_schedule = True
    contact_workspaces = True

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.solver = ctx.new_solver()
        frames = ctx.contact_frames
        self.frames = frames
        self.Cw, self.lw, self.uw = stack_wrench_constraints(ctx.contacts)
        self.nc = contacts_dim(self.contacts)

    def configure_tick(self, tick: Any) -> None:
        cfg = self.config
        s = _native.core().QpWbcSettings()
        s.eliminated = cfg.variables == "eliminated"
        # the tick holds every task's rows; a task that has left the QP (a swing task while its
        # foot stands) weighs nothing
        active = {id(task) for task in self.active_tasks}
        s.row_weights = np.concatenate(
            [
                np.full(task.dim, task_weight_of(task, cfg.weights) if id(task) in active else 0.0)
                for task in self.ctx.tasks
            ]
            or [np.zeros(0)]
        )
        s.acceleration_weight = cfg.acceleration_weight
        s.torque_weight = cfg.torque_weight
        s.wrench_weight = cfg.wrench_weight
        set_limits(s, self.ctx.tau_max, self.Cw, self.lw, self.uw, self.nc)
        tick.configure(s)

    def qp_calls(self, tick: Any) -> list[QpCall]:
        return [QpCall(tick.qp, "qp_wbc", self.solver, self.config.solver_calls)]

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        self.select_contacts(t)
        timer = StageTimer(state)
        cfg = self.config
        n, k, nc = state.n, state.k, self.nc
        terms = self.evaluate_tasks(state, t)
        M, h = state.M, state.h
        Jc = state.contact_jacobian(self.contacts)
        # J_c q̈ + J̇_c q̇ = 0 on the rows independent by construction (all of a flat contact's)
        Jk, dJc = state.contact_constraint(self.contacts)
        nk = Jk.shape[0]
        Hq, gq = accumulate_tasks(terms, cfg.weights, n)
        Hq[np.diag_indices(n)] += cfg.acceleration_weight
        tau_max = self.ctx.tau_max

        if cfg.variables == "full":
            nx = n + k + nc
            iq, it, iF = slice(0, n), slice(n, n + k), slice(n + k, nx)
            H = np.zeros((nx, nx))
            g = np.zeros(nx)
            H[iq, iq] = Hq
            g[iq] = gq
            H[it, it] = cfg.torque_weight * np.eye(k)
            H[iF, iF] = cfg.wrench_weight * np.eye(nc)
            A = np.zeros((n + nk, nx))
            b = np.zeros(n + nk)
            A[:n, iq] = M
            A[6:n, it] = -np.eye(k)
            A[:n, iF] = -Jc.T
            b[:n] = -h
            A[n:, iq] = Jk
            b[n:] = -dJc
            C = np.zeros((self.Cw.shape[0], nx))
            C[:, iF] = self.Cw
            lb = np.full(nx, -np.inf)
            ub = np.full(nx, np.inf)
            lb[it], ub[it] = -tau_max, tau_max
            problem = Problem(H, g, A, b, C, self.lw.copy(), self.uw.copy(), lb, ub, name="qp_wbc")
        else:
            nx = n + nc
            iq, iF = slice(0, n), slice(n, nx)
            # Γ = G x + γ from the actuated rows of the dynamics
            G = np.hstack([M[6:], -Jc[:, 6:].T])
            gamma = h[6:]
            H = np.zeros((nx, nx))
            g = np.zeros(nx)
            H[iq, iq] = Hq
            g[iq] = gq
            H[iF, iF] = cfg.wrench_weight * np.eye(nc)
            H += cfg.torque_weight * (G.T @ G)
            g += cfg.torque_weight * (G.T @ gamma)
            A = np.zeros((6 + nk, nx))
            b = np.zeros(6 + nk)
            A[:6, iq] = M[:6]
            A[:6, iF] = -Jc[:, :6].T
            b[:6] = -h[:6]
            A[6:, iq] = Jk
            b[6:] = -dJc
            nw = self.Cw.shape[0]
            C = np.zeros((nw + k, nx))
            C[:nw, iF] = self.Cw
            C[nw:] = G
            lower = np.concatenate([self.lw, -tau_max - gamma])
            upper = np.concatenate([self.uw, tau_max - gamma])
            problem = Problem(H, g, A, b, C, lower, upper, name="qp_wbc")

        sol = self.solver.solve(problem)
        timer.add_solution(sol)
        if not sol.success or sol.x is None:
            return ControlOutput(
                tau=np.zeros(k),
                qdd=np.zeros(n),
                wrench=np.zeros(nc),
                terms=terms,
                timings=timer.finish(),
                ok=False,
                message=f"{sol.solver}: {sol.status.value}: {sol.message}",
                iterations=timer.iterations,
                problems=[problem] if self.ctx.keep_problems else [],
            )
        x = sol.x
        qdd = x[:n]
        wrench = x[nx - nc :]
        if cfg.variables == "full":
            tau = x[n : n + k]
        else:
            tau = G @ x + gamma
        return ControlOutput(
            tau=tau,
            qdd=qdd,
            wrench=wrench,
            terms=terms,
            timings=timer.finish(),
            iterations=timer.iterations,
            problems=[problem] if self.ctx.keep_problems else [],
        )
