"""Conventional hierarchical QP (HQP) whole-body control (OSF-HQP paper §II, eq. 2–15).

Decision variable x = (q̈ (n), Γ (k), f (6c)), f the contact wrench on the robot. Hard at every
level: the dynamics M q̈ + h = Sᵀ Γ + J_cᵀ f, stationary contacts J_c q̈ + J̇_c q̇ = 0, the contact
wrench inequalities and the torque limits. Tasks of equal ``priority`` form one level; level l
minimises the norm of its slack w_l = J_l q̈ + J̇_l q̇ − ẍ*_l with the optimal slacks of the levels
above held. Final regularisation levels resolve the remaining redundancy:

* ``torque`` — ‖Γ‖² (the papers' usual choice);
* ``wrench`` — ‖W_c f‖², W_c = diag(``wrench_weights``) per contact (OSF-HQP T5 sets the normal
  force's weight to zero: minimise tangential forces and moments);
* ``acceleration_energy`` — ‖q̈‖²_A = q̈ᵀ A q̈;
* ``zero_torque_energy`` — ‖q̈ − q̈₀‖²_A with q̈₀ the zero-torque constrained motion: the
  objective under which the conventional HQP gives the OSF solution (same q̈, torques equal up to
  the contact-wrench distribution).

A task with ``level: force`` is a torque-level request (OSF-HQP T4: joint damping Γ = −k q̇); it
is supported for joint tasks, whose torque rows are S_j Γ = −k_v q̇_j + S_j h: the damping acts on
top of the joints' bias compensation, as the OSF's force-level tasks act on top of Γ_gc. It is
not the OSF's force-level task: ``osf_hqp`` applies F* through the projected OSF Jacobian,
J*_{l|<l}ᵀ F* (OSF-HQP eq. 30–31), so ``zero_torque_energy`` makes the two controllers agree
for acceleration-level tasks only (see the README's known limitations).

Strategies (see :mod:`wbcbench.qp.hierarchy`): ``cascade`` (the papers' conventional method),
``nullspace``, ``weighted`` and ``rqr``.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
import scipy.linalg
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
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.qp.hierarchy import Constraints, Objective, PriorityLevel, solve_hierarchy
from wbcbench.tasks.contacts import (
    contacts_dim,
    stack_wrench_constraints,
    tile_wrench_weights,
)
from wbcbench.tasks.tasks import JointPostureTask, TaskTerm

Final = Literal["torque", "wrench", "acceleration_energy", "zero_torque_energy"]


class HqpConfig(NativeConfig):
    """Settings of the conventional HQP."""

    strategy: Literal["cascade", "nullspace", "weighted", "rqr"] = Field(
        "cascade", description="how the levels are solved (see wbcbench.qp.hierarchy)"
    )
    finals: list[Final] = Field(
        ["torque"], min_length=1, description="final regularisation levels, in order"
    )
    wrench_weights: list[float] = Field(
        [1.0, 1.0, 0.0, 1.0, 1.0, 1.0],
        min_length=6,
        max_length=6,
        description="W_c diagonal per contact for the 'wrench' final (fx fy fz mx my mz)",
    )
    prox: float = Field(
        1e-8,
        ge=0,
        description="proximal weight of the retry of a level the backend failed to solve (see "
        "wbcbench.qp.hierarchy); 0 = no retry",
    )
    level_weights: list[float] = Field(
        [1e6, 1e3, 1.0, 1e-3, 1e-6],
        description="weights per priority for the 'weighted' strategy (last one repeats)",
    )


class Hqp(NativeController):
    """Conventional cascade HQP over (q̈, Γ, f)."""

    name = "hqp"
    summary = "conventional HQP: one QP per priority over (q̈, Γ, f); cascade/nullspace/rqr"
    Config = HqpConfig
    config: HqpConfig
    tick_type = "HqpTick"
    native_schedule = True
    # a workspace per contact set in the tick (its levels, constraints and hierarchy sizes)
    contact_workspaces = True

    @classmethod
    def impl_for(cls, config: ControllerConfig) -> str:
        """``rqr`` solves no QPs and has no native tick: it runs the Python reference unless
        native is asked for explicitly, which is an error."""
        if getattr(config, "strategy", None) == "rqr":
            if config.impl == "native":
                raise ControllerError(
                    "hqp: strategy rqr has no native tick; valid choices with impl: native: "
                    "cascade, nullspace, weighted (or impl: python)"
                )
            return "python"
        return super().impl_for(config)

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        for task in ctx.tasks:
            if task.level == "force" and not isinstance(task, JointPostureTask):
                raise ControllerError(
                    f"hqp: task {task.name!r} is force-level; hqp supports force-level tasks "
                    "for joint tasks only (joint_posture, joint_damping)"
                )
        self.priorities = sorted({t.priority for t in ctx.tasks})
        self.frames = ctx.contact_frames
        self.nc = contacts_dim(self.contacts)
        self.Cw, self.lw, self.uw = stack_wrench_constraints(ctx.contacts)
        n_qp = (
            1
            if self.config.strategy == "weighted"
            else len(self.priorities) + len(self.config.finals)
        )
        self.solvers = (
            [] if self.config.strategy == "rqr" else [ctx.new_solver() for _ in range(n_qp)]
        )

    def configure_tick(self, tick: Any) -> None:
        cfg = self.config
        core = _native.core()
        s = core.HqpSettings()
        s.strategy = getattr(core.Strategy, cfg.strategy)
        s.finals = [getattr(core.HqpFinal, name) for name in cfg.finals]
        weights = np.asarray(cfg.wrench_weights, dtype=float)
        if any(c.points is not None for c in self.contacts):  # one per row: points take 3
            weights = tile_wrench_weights(weights, self.contacts)
        s.wrench_weights = weights
        s.prox = cfg.prox
        s.accept_tol = accept_tol(self.ctx)
        s.priorities, s.groups = priority_groups(self.ctx.tasks, self.active_tasks)
        # the weighted strategy's weight of a level is its priority's among all priorities
        per_level = cfg.level_weights
        s.level_weights = [
            per_level[min(self.priorities.index(p), len(per_level) - 1)] for p in s.priorities
        ] or list(per_level)
        s.force_level = [task.level == "force" for task in self.ctx.tasks]
        set_limits(s, self.ctx.tau_max, self.Cw, self.lw, self.uw, self.nc)
        tick.configure(s)

    def level_solve(self, tick: Any) -> LevelSolve:
        return LevelSolve(
            lambda pool, i: tick.slot(i),
            [self.solvers],
            self.ctx.keep_problems,
            self.config.solver_calls,
            origin=self.config.strategy == "nullspace",
        )

    def native_region(
        self, q: np.ndarray, v: np.ndarray, t: float, timer: NativeTimer
    ) -> str | None:
        message = super().native_region(q, v, t, timer)
        return None if message is None else f"hqp: {message}"

    def native_diagnostics(
        self, state: RobotState, terms: list[TaskTerm], ok: bool
    ) -> dict[str, float]:
        result = self.native_tick.result
        levels = len({task.priority for task in self.active_tasks})
        return self._diagnostics(result.levels[:levels], result.retries)

    @staticmethod
    def _diagnostics(levels: list[Any], retries: int) -> dict[str, float]:
        """‖(w, v)‖ of each priority level and the proximal retries."""
        out = {
            f"slack.{lv.name}": float(np.linalg.norm(np.concatenate([lv.w, lv.v]))) for lv in levels
        }
        out["prox_retries"] = float(retries)
        return out

    # -- formulation ----------------------------------------------------------------------

    def _hard(self, state: RobotState) -> Constraints:
        n, k, nc = state.n, state.k, self.nc
        nx = n + k + nc
        Jc = state.contact_jacobian(self.contacts)
        Jk, dk = state.contact_constraint(self.contacts)
        nk = Jk.shape[0]
        A = np.zeros((n + nk, nx))
        b = np.zeros(n + nk)
        A[:n, :n] = state.M
        A[6:n, n : n + k] = -np.eye(k)
        A[:n, n + k :] = -Jc.T
        b[:n] = -state.h
        A[n:, :n] = Jk
        b[n:] = -dk
        C = np.zeros((self.Cw.shape[0], nx))
        C[:, n + k :] = self.Cw
        lb = np.full(nx, -np.inf)
        ub = np.full(nx, np.inf)
        lb[n : n + k] = -self.ctx.tau_max
        ub[n : n + k] = self.ctx.tau_max
        return Constraints(nx, A, b, C, self.lw, self.uw, lb, ub)

    def _task_rows(self, term: TaskTerm, state: RobotState) -> tuple[np.ndarray, np.ndarray]:
        n, k = state.n, state.k
        rows = np.zeros((term.dim, n + k + self.nc))
        if term.task.level == "force":
            # torque-level joint task on top of the bias compensation of its joints:
            # S_j (Γ − h_a) = reference (Γ_j = −k_v q̇_j + h_j for damping). Without the
            # compensation, the joints this task is the only one to command sag under gravity.
            sel = term.J[:, 6:]
            rows[:, n : n + k] = sel
            return rows, term.acc_ref + sel @ state.h[6:]
        rows[:, :n] = term.J
        return rows, term.acc_ref - term.drift

    def _levels(self, terms: list[TaskTerm], state: RobotState) -> list[PriorityLevel]:
        weights = self.config.level_weights
        levels = []
        for i, p in enumerate(self.priorities):
            group = [self._task_rows(t, state) for t in terms if t.task.priority == p]
            if not group:  # its only tasks drive feet that stand (a contact schedule)
                continue
            rows, rhs = zip(*group, strict=True)
            w = weights[min(i, len(weights) - 1)]
            levels.append(PriorityLevel(f"L{p}", np.vstack(rows), np.concatenate(rhs), weight=w))
        return levels

    def _finals(self, state: RobotState) -> list[Objective]:
        n, k, nc = state.n, state.k, self.nc
        nx = n + k + nc
        out = []
        for name in self.config.finals:
            if name == "torque":
                F = np.zeros((k, nx))
                F[:, n : n + k] = np.eye(k)
                out.append(Objective(name, F, np.zeros(k), weight=1e-6))
            elif name == "wrench":
                W = tile_wrench_weights(np.asarray(self.config.wrench_weights), self.contacts)
                F = np.zeros((nc, nx))
                F[:, n + k :] = np.diag(W)
                out.append(Objective(name, F, np.zeros(nc), weight=1e-6))
            else:
                # ‖q̈ − q̈₀‖²_A = ‖Lᵀ (q̈ − q̈₀)‖², A = L Lᵀ
                L = scipy.linalg.cholesky(state.M, lower=True, check_finite=False)
                F = np.zeros((n, nx))
                F[:, :n] = L.T
                target = np.zeros(n)
                if name == "zero_torque_energy":
                    qdd0 = forward_dynamics(state, np.zeros(k), self.contacts).qdd
                    target = L.T @ qdd0
                out.append(Objective(name, F, target, weight=1e-6))
        return out

    # -- the step -----------------------------------------------------------------------------

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        self.select_contacts(t)
        timer = StageTimer(state)
        n, k = state.n, state.k
        terms = self.evaluate_tasks(state, t)
        hard = self._hard(state)
        levels = self._levels(terms, state)
        finals = self._finals(state)
        result = solve_hierarchy(
            hard,
            levels,
            finals,
            self.config.strategy,
            self.solvers,
            timer=timer,
            prox=self.config.prox,
        )
        diagnostics = self._diagnostics(result.levels[: len(levels)], result.retries)
        if not result.ok:
            return ControlOutput(
                tau=np.zeros(k),
                qdd=np.zeros(n),
                wrench=np.zeros(self.nc),
                terms=terms,
                timings=timer.finish(),
                ok=False,
                message=f"hqp: {result.message}",
                iterations=timer.iterations,
                diagnostics=diagnostics,
            )
        x = result.x
        return ControlOutput(
            tau=x[n : n + k],
            qdd=x[:n],
            wrench=x[n + k :],
            terms=terms,
            timings=timer.finish(),
            iterations=timer.iterations,
            diagnostics=diagnostics,
        )
