"""HQP on the contact-consistent OSF (OSF-HQP, Lee, Ahn, Lee, Park, IROS 2021, §III eq. 16–31).

One small QP per priority level over the level's task-space slack and the contact-wrench
distribution, x_l = (w_l, F_r):

    minimise   ½ ‖w_l‖² (+ ½ ε ‖F_r‖²)                                          (26)
    subject to Γ = Γ_{<l}* + E_l (ẍ*_l + w_l) − B_l (Ĵ_l Γ_{<l}* + b_l) + Y_c F_r     (25)
               −Γ_max ≤ Γ ≤ Γ_max                                                (27)
               |ẍ*_l + w_l| ≤ ẍ_max                                              (28)
               l_w ≤ C_w (F Γ + f₀) ≤ u_w                                        (29)

with the slacks of the levels above fixed (Γ_{<l}* is their torque), E_l = J*_{l|<l}ᵀ Λ_{l|<l} for
an acceleration-level task and J*_{l|<l}ᵀ for a force-level one (eq. 30–31; the reference is then
an operational force, see :mod:`wbcbench.tasks.osf`). The exact level coupling B_l Ĵ_l Γ_{<l}
(``coupling: exact``) makes every level realise its reference when feasible; ``literal`` drops it
as the paper's eq. (25) does. A final QP optimises the contact wrench over F_r only,
min ½ ‖W_c f‖² subject to (27)–(29) (§III-B1, W_c zero on the normal forces by default, as in the
paper's experiment); with a single plane contact there is no F_r and no final QP.

Timings: ``solve.T<i>`` per task level, ``solve.wrench`` for the final QP, ``params`` for the
operational-space parameters (see :mod:`wbcbench.controllers.params`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from wbcbench.controllers.base import ControllerConfig, ControllerContext, ControlOutput, StageTimer
from wbcbench.controllers.native import NAN_MESSAGE, NativeTimer, QpCall
from wbcbench.controllers.to_osf import OsfBaseConfig, OsfControllerBase, wrench_selection
from wbcbench.dynamics.state import RobotState
from wbcbench.qp import Problem
from wbcbench.tasks.tasks import TaskTerm


class OsfHqpConfig(OsfBaseConfig):
    """Settings of the OSF-based HQP."""

    regularization: float = Field(
        1e-6, ge=0, description="weight of ‖F_r‖² [1/N²] in every QP (keeps the Hessians > 0)"
    )
    carry_tolerance: float = Field(
        1e-6,
        ge=0,
        description="inequality bounds of the i-th QP (0 first) widened by i times this much "
        "[N·m, N]: a level inherits the solution above only to the solver's accuracy, and a "
        "bound active there would otherwise make the next level infeasible",
    )


class OsfHqp(OsfControllerBase):
    """Cascade of small task-space QPs on the contact-consistent OSF, then a wrench QP."""

    name = "osf_hqp"
    summary = "HQP on the contact-consistent OSF (OSF-HQP): one small QP per level over (w, F_r)"
    Config = OsfHqpConfig
    config: OsfHqpConfig
    tick_type = "OsfHqpTick"
    settings_type = "OsfHqpSettings"

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.solvers = [ctx.new_solver() for _ in self.levels]
        self.final_solver = ctx.new_solver("wrench")
        self.wrench_weighting()
        #: how many of the native tick's QPs the last tick reached
        self.reached = 0

    set_attrs = (*OsfControllerBase.set_attrs, "WtW")

    def wrench_weighting(self) -> None:
        # a level per solver handle, also when a contact set's tasks form more levels
        solvers = getattr(self, "solvers", None)
        while solvers is not None and len(solvers) < len(self.levels):
            solvers.append(self.ctx.new_solver())
        Wc = wrench_selection(self.config.wrench_weights, self.contacts, self.name)
        self.WtW = Wc.T @ Wc

    def on_start(self, state: RobotState) -> None:
        """The wrench-distribution space's dimension at the first state, for the native tick:
        ``c − 6`` for independent plane contacts; point sets (dependent rows) give it from the
        rank of their rows."""
        super().on_start(state)
        self.distribution = -1
        if any(c.points is not None and len(c.points) > 1 for c in self.contacts):
            self.distribution = int(self.model.params(state).Yc.shape[1])

    def native_settings(self, s: Any) -> None:
        s.distribution = getattr(self, "distribution", -1)
        s.regularization = self.config.regularization
        s.carry_tolerance = self.config.carry_tolerance
        s.WtW = np.asarray(self.WtW, dtype=float).reshape(self.nc, self.nc)

    def qp_calls(self, tick: Any) -> list[QpCall]:
        """One QP per level, then the wrench QP where there is a distribution space: new calls
        (a new tick, or the workspace of a contact set), each with its own C++ solver."""
        self._calls: dict[str, QpCall] = {}
        return self.qp_calls_of(tick)

    def rebind_calls(self, tick: Any) -> None:
        """A new contact set's QPs (the tick makes them anew: a level may have left, and a
        single contact has no wrench QP)."""
        self.native_calls = self.qp_calls_of(tick)

    def qp_calls_of(self, tick: Any) -> list[QpCall]:
        """The tick's QPs, each with its handle: a QP keeps the call of its name (kept also
        while the QP is absent, e.g. the wrench QP in single support), and with it its C++
        solver, as long as the same handle solves it."""
        L = len(self.held_levels())
        names = [f"T{i + 1}" for i in range(L)] + ["wrench"]
        solvers = [*self.solvers, self.final_solver]
        calls: list[QpCall] = []
        for i in range(tick.n_qps):
            name, handle = names[min(i, L)], solvers[min(i, L)]
            call = self._calls.get(name)
            if call is not None and call.handle is handle:
                call.buffers = tick.qp(i)
                call.rebind()
            else:
                call = self._calls[name] = QpCall(
                    tick.qp(i), name, handle, self.config.solver_calls
                )
            calls.append(call)
        return calls

    def native_region(
        self, q: np.ndarray, v: np.ndarray, t: float, timer: NativeTimer
    ) -> str | None:
        """The timed region of a native step: the level QPs, then the wrench QP. Returns None
        or the message of a failed tick."""
        tick = self.native_tick
        L = len(self.levels)
        self.reached = 0
        if not tick.build(q, v, t):
            return tick.message or NAN_MESSAGE
        for i, call in enumerate(self.native_calls):
            level = f"T{i + 1}" if i < L else "wrench"
            self.reached = i + 1
            x, sol = call.solve(timer, level)
            if x is None:
                where = f"level {level}" if i < L else "wrench level"
                return f"{where}: {sol.solver}: {sol.status.value}: {sol.message}"
            if i < L:
                if not tick.level(i, x):
                    return NAN_MESSAGE
            else:
                tick.finish(x)
        if len(self.native_calls) == L:
            tick.finish(np.zeros(0))
        return None

    def native_problems(self) -> list[Problem]:
        """The QPs the last tick reached (a failed level ends the cascade)."""
        return [call.problem for call in self.native_calls[: self.reached]]

    def native_diagnostics(
        self, state: RobotState, terms: list[TaskTerm], ok: bool
    ) -> dict[str, float]:
        """Each level's slack norm ``slack.T<i>`` = ‖w_i‖."""
        tick = self.native_tick
        own = {f"slack.T{i + 1}": float(w) for i, w in enumerate(tick.slack_norms)} if ok else {}
        return self.osf_diagnostics(state, terms, ok, own)

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        self.select_contacts(t)
        timer = StageTimer(state)
        cfg = self.config
        terms, per_level, refs, read = self.prepare(state, t)
        p = read.params
        k = state.k
        np_ = p.Yc.shape[1]
        tau_max = self.ctx.tau_max
        cw_f0 = self.Cw @ p.f0 if self.nc else np.zeros(0)
        CwF = self.Cw @ p.F if self.nc else np.zeros((0, k))
        CwQ = self.Cw @ p.Qf if self.nc else np.zeros((0, np_))
        tau = np.zeros(k)
        partial: list[np.ndarray] = []
        problems: list[Problem] = []
        diagnostics = self.base_diagnostics(read)
        nw = self.Cw.shape[0]
        for i, lv in enumerate(p.levels):
            m = lv.dim
            base = p.level_step(i, tau, refs[i])  # Γ_{≤l} with w_l = 0
            E = lv.E
            nx = m + np_
            C = np.empty((k + nw, nx))  # [E Y_c; C_w F E  C_w Q_f]
            C[:k, :m] = E
            C[:k, m:] = p.Yc
            np.matmul(CwF, E, out=C[k:, :m])
            C[k:, m:] = CwQ
            bounds = np.empty((2, k + nw))
            bounds[0, :k] = -tau_max - base
            bounds[1, :k] = tau_max - base
            if nw:
                cwb = cw_f0 + CwF @ base
                bounds[0, k:] = self.lw - cwb
                bounds[1, k:] = self.uw - cwb
            tol = cfg.carry_tolerance * i
            bounds[0] -= tol
            bounds[1] += tol
            lb = ub = None
            bound = self.acc_bound[i]
            if np.isfinite(bound).any():  # |ẍ* + w| ≤ ẍ_max on the slacks, F_r free
                lb = np.concatenate([-bound - refs[i], np.full(np_, -np.inf)])
                ub = np.concatenate([bound - refs[i], np.full(np_, np.inf)])
            name = f"T{i + 1}"
            problem = Problem(
                np.diag(np.concatenate([np.ones(m), np.full(np_, cfg.regularization)])),
                np.zeros(nx),
                C=C,
                l=bounds[0],
                u=bounds[1],
                lb=lb,
                ub=ub,
                name=name,
            )
            problems.append(problem)
            sol = self.solvers[i].solve(problem)
            timer.add_solution(sol, f"T{i + 1}")
            if not sol.success or sol.x is None:
                return self.failed(
                    timer,
                    read,
                    terms,
                    f"level T{i + 1}: {sol.solver}: {sol.status.value}: {sol.message}",
                    problems,
                )
            w = sol.x[:m]
            tau = base + E @ w
            partial.append(tau)
            diagnostics[f"slack.T{i + 1}"] = float(np.linalg.norm(w))
        f_r = np.zeros(np_)
        if np_:
            f_tasks = p.f0 + p.F @ tau
            QW = p.Qf.T @ self.WtW  # Q_fᵀ W_cᵀ W_c
            H = QW @ p.Qf
            H[np.diag_indices(np_)] += cfg.regularization
            g = QW @ f_tasks
            C = np.vstack([p.Yc, CwQ])
            cwt = self.Cw @ f_tasks
            tol = cfg.carry_tolerance * len(p.levels)
            lower = np.concatenate([-tau_max - tau, self.lw - cwt]) - tol
            upper = np.concatenate([tau_max - tau, self.uw - cwt]) + tol
            problem = Problem(H, g, C=C, l=lower, u=upper, name="wrench")
            problems.append(problem)
            sol = self.final_solver.solve(problem)
            timer.add_solution(sol, "wrench")
            if not sol.success or sol.x is None:
                return self.failed(
                    timer,
                    read,
                    terms,
                    f"wrench level: {sol.solver}: {sol.status.value}: {sol.message}",
                    problems,
                )
            f_r = sol.x
        return self.output(
            state, read, timer, terms, per_level, partial, p.Yc @ f_r, diagnostics, problems
        )
