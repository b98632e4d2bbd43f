"""Task-oriented OSF whole-body control (TO-OSF, Lee et al. 2021, §III-A eq. 9–15).

One QP per tick over the optimised task references of every level and an internal contact wrench,
ρ = (ẍ_opt,1 … ẍ_opt,m, F_opt):

    minimise   ½ Σ_i H_i ‖ẍ_opt,i − ẍ*_i‖² + ½ H_w ‖S_f f‖²                 (9)–(11)
    subject to Γ = K ẍ_opt + γ₀ + Y_w F_opt          (12, the OS-WBC torque of eq. 7 as one
                                                       affine map; γ₀ is Γ_gc)
               f = F (K ẍ_opt + γ₀) + f₀ + F_opt      (13, the contact wrench)
               G F_opt = 0                            (14, F_opt is internal: G is the grasp map)
               l_w ≤ C_w f ≤ u_w                      (15, normal force, friction, CoP, yaw)
               −Γ_max ≤ Γ ≤ Γ_max,  |ẍ_opt,i| ≤ ẍ_max,i
    then Γ from eq. (7) with the optimised references.

Γ and f are substituted rather than kept as variables, and F_opt = N w ranges over a basis N of
G's null space (:func:`internal_basis`), which meets eq. (14) by construction: the QP has
Σ m_i + c − 6 variables and no equality rows. ``internal: constraint`` keeps F_opt's c variables
and eq. (14) as six equality rows instead: the same optimum, but an active-set solver that
factorises its equality rows (qpOASES projects its Hessian onto their null space on every
matrix update) pays several times more for it (docs/qpoases.md). The
wrench term penalises the tangential forces and the moments of the *total* wrench (S_f drops the
normal forces), which is what the paper says it is for ("the most stable CoP position and the
least slipping"); ``wrench_cost: internal`` penalises only F_opt, the literal eq. (11). The task
weights default to H = 1e7 for every task and H_w = 1 (TO-OSF §IV, "H_{m+1} = I").

f is the reaction on the robot (the papers' F_c = −f). The operational-space parameters come from
:mod:`wbcbench.tasks.osf` through the parameter server (``params: inline | periodic:N |
async``). This module also holds what both OSF controllers share (:class:`OsfControllerBase`).
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field, field_validator

from wbcbench import _native
from wbcbench.controllers.base import (
    ControllerConfig,
    ControllerContext,
    ControlOutput,
    NativeConfig,
    StageTimer,
)
from wbcbench.controllers.native import NativeController, QpCall, set_limits
from wbcbench.controllers.params import ParameterServer, ParamsRead, parse_params_mode
from wbcbench.controllers.qp_wbc import task_weight, task_weight_of
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.metrics.consistency import dc_error, hierarchy_leak
from wbcbench.qp import Problem
from wbcbench.tasks.contacts import (
    PlaneContact,
    contacts_dim,
    stack_wrench_constraints,
    tile_wrench_weights,
)
from wbcbench.tasks.osf import OsfModel, OsfParams, group_levels, level_kinds
from wbcbench.tasks.schedule import ContactSchedule
from wbcbench.tasks.tasks import Task, TaskTerm


class OsfBaseConfig(NativeConfig):
    """Settings both OSF controllers share."""

    wrench_weights: list[float] = Field(
        [1.0, 1.0, 0.0, 1.0, 1.0, 1.0],
        description="diagonal of the wrench weighting (TO-OSF's S_f, OSF-HQP's W_c) per contact "
        "(fx fy fz mx my mz), or one value per wrench row; 0 on the normal forces is the papers'",
    )

    @field_validator("wrench_weights")
    @classmethod
    def _nonnegative(cls, v: list[float]) -> list[float]:
        if not v or min(v) < 0:
            raise ValueError(f"wrench_weights must be non-negative numbers, got {v}")
        return v

    inverse: Literal["cod", "svd", "pinv"] = Field(
        "cod", description="dynamically consistent inverse by COD or SVD; pinv = ablation"
    )
    params: str = Field(
        "inline", description="operational-space parameters: inline | periodic:N | async"
    )
    coupling: Literal["exact", "literal"] = Field(
        "exact", description="exact level coupling, or the papers' literal Λ ẍ* + Γ_gc form"
    )
    rcond: float = Field(1e-9, gt=0, lt=1, description="relative rank threshold of the inverses")
    acc_limits: dict[str, float] = Field(
        default_factory=dict,
        description="task name → bound on |ẍ_opt| per axis [m/s², rad/s²; N, N·m for force tasks]",
    )
    consistency: bool = Field(
        False, description="oracle hierarchy-leak metrics in the diagnostics (costs time)"
    )

    @field_validator("params")
    @classmethod
    def _mode(cls, v: str) -> str:
        parse_params_mode(v)
        return v


class OsfControllerBase(NativeController):
    """Shared plumbing: levels, the parameter server, references, limits, diagnostics, and the
    native tick's set-up (``impl: native``)."""

    config: OsfBaseConfig
    affine: bool = False
    native_schedule = True
    contact_workspaces = True
    #: what a contact set fixes (:meth:`contacts_changed`), kept per set after its first tick
    set_attrs: ClassVar[tuple[str, ...]] = ("levels", "kinds", "acc_bound", "level_tasks", "model")
    #: the native settings' type name in the module
    settings_type: ClassVar[str] = ""

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        cfg = self.config
        self.frames = ctx.contact_frames
        self.group_tasks(ctx.tasks)
        #: every task in level order: the native tick's tasks, of which the levels of a contact
        #: set pick the active ones (a subsequence: the same order)
        self.tick_order = list(self.level_tasks)
        self._per_set: dict[tuple[int, ...], dict[str, Any]] = {}
        self._tick_settings: dict[tuple[int, ...], Any] = {}
        self.model = self.osf_model()
        if ctx.schedule is not None and parse_params_mode(cfg.params).kind == "async":
            raise ControllerError(
                f"{self.name}: params async does not follow a contact schedule (its worker "
                "computes the parameters of one contact set); use params inline or periodic:N"
            )
        self.server = ParameterServer(self.model, cfg.params, ctx.robot)
        self.Cw, self.lw, self.uw = stack_wrench_constraints(ctx.contacts)
        self.nc = contacts_dim(self.contacts)
        names = {t.name for t in ctx.tasks}
        unknown = sorted(set(cfg.acc_limits) - names)
        if unknown:
            raise ControllerError(
                f"{self.name}: acc_limits names unknown task(s) {', '.join(unknown)}; "
                f"valid choices: {', '.join(sorted(names))}"
            )
        self.tick = 0
        #: the state the native tick sizes each contact set's parameters at (the first), and
        #: while make_native configures the sets, that state (None otherwise)
        self._start_state: RobotState | None = None
        self._sizing: RobotState | None = None

    def osf_model(self) -> OsfModel:
        """The OSF model of the present levels and contact set."""
        cfg = self.config
        return OsfModel(
            self.levels,
            self.contacts,
            self.kinds,
            inverse=cfg.inverse,
            coupling=cfg.coupling,
            rcond=cfg.rcond,
            affine=self.affine,
        )

    def group_tasks(self, tasks: list[Task]) -> None:
        """The levels of ``tasks``, their kinds, acceleration bounds and level order."""
        self.levels = group_levels(tasks)
        self.kinds = level_kinds(self.levels)
        limits = self.config.acc_limits
        self.acc_bound = [
            np.concatenate([np.full(t.dim, limits.get(t.name, np.inf)) for t in level])
            for level in self.levels
        ]
        #: the tasks in level order (the native tick stacks them so)
        self.level_tasks = [task for tasks in self.levels for task in tasks]

    def contacts_changed(self) -> None:
        """The levels, OSF model and wrench weighting of the new contact set (made on its first
        tick and kept: they depend on the set alone) and a fresh parameter server: the
        parameters of the old set are never used (a periodic server computes its first set at
        once)."""
        self.server.close()
        kept = self._per_set.get(self.active_contacts)
        if kept is None:
            self.group_tasks(self.active_tasks)
            self.model = self.osf_model()
            self.wrench_weighting()
            self._per_set[self.active_contacts] = {a: getattr(self, a) for a in self.set_attrs}
        else:
            self.__dict__.update(kept)
        self.server = ParameterServer(self.model, self.config.params, self.ctx.robot)

    def held_levels(self) -> list[list[Task]]:
        """The levels of the contact set held (:meth:`~Controller.hold_contacts`): those
        :meth:`contacts_changed` made for it, also while :meth:`configure_workspaces` holds one
        set after another without a change."""
        kept = self._per_set.get(self.active_contacts)
        return self.levels if kept is None else kept["levels"]

    def wrench_weighting(self) -> None:
        """The controller's wrench weighting for the current contact set (none here)."""

    def on_start(self, state: RobotState) -> None:
        super().on_start(state)
        self._start_state = state

    def make_native(self) -> None:
        """The native tick (:meth:`NativeController.make_native`), with a workspace per contact
        set of the schedule (``contact_workspaces``): each set's settings are made first
        (:meth:`prepare_contact_sets`), and each set's parameters are sized at the start state
        (``tick.prepare``), so that no change of contacts allocates in the tick."""
        if self.ctx.schedule is not None and -1 in self.active_contacts:
            self.prepare_contact_sets(self.ctx.schedule)
        self._sizing = self._start_state
        try:
            super().make_native()
        finally:
            self._sizing = None

    def prepare_contact_sets(self, schedule: ContactSchedule) -> None:
        """Before the first tick of a native run: what each contact set of the schedule fixes
        (its wrench rows, levels, model, wrench weighting and native settings), so that the
        tick a set first becomes active re-makes none of it, as a change back to a known set
        does not. The controller is left as it was (every contact, none selected yet): its
        first tick selects its set as before."""
        held = ("frames", "contacts", "Cw", "lw", "uw", "nc", "active_tasks", "active_contacts")
        before = {a: getattr(self, a) for a in (*held, *self.set_attrs)}
        for t, _ in schedule.set_instants():
            self.select_contacts(t)
            if self.active_contacts not in self._tick_settings:
                self._tick_settings[self.active_contacts] = self.tick_settings()
        self.__dict__.update(before)
        self.server.close()
        self.server = ParameterServer(self.model, self.config.params, self.ctx.robot)

    # -- the native tick ----------------------------------------------------------------------

    def native_settings(self, s: Any) -> None:
        """Set the subclass's own fields of its native settings ``s`` (the shared ones are set
        by :meth:`configure_tick`)."""

    def tick_tasks(self) -> list[Task]:
        return self.tick_order

    def configure_tick(self, tick: Any) -> None:
        """The settings of the contact set (made on its first tick and kept; the ramped wrench
        bounds follow every tick, ``set_wrench_bounds``) to the tick."""
        s = self._tick_settings.get(self.active_contacts)
        if s is None:
            s = self._tick_settings[self.active_contacts] = self.tick_settings()
        tick.configure(s)
        if self._sizing is not None:  # set-up (make_native): the set's parameters sized
            tick.prepare(self._sizing.q, self._sizing.v, 0.0)

    def tick_settings(self) -> Any:
        """The native settings of the present contact set."""
        cfg = self.config
        s = getattr(_native.core(), self.settings_type)()
        self.native_settings(s)
        index = {id(task): i for i, task in enumerate(self.tick_order)}
        s.tasks = [index[id(task)] for task in self.level_tasks]
        s.level_dims = [sum(t.dim for t in tasks) for tasks in self.levels]
        s.force_level = [kind == "force" for kind in self.kinds]
        s.inverse = cfg.inverse
        s.exact = cfg.coupling == "exact"
        s.rcond = cfg.rcond
        s.period = self.server.mode.period
        s.asynchronous = self.server.mode.kind == "async"
        set_limits(s, self.ctx.tau_max, self.Cw, self.lw, self.uw, self.nc)
        s.acc_bound = np.concatenate(self.acc_bound or [np.zeros(0)])
        return s

    def osf_diagnostics(
        self, state: RobotState, terms: list[TaskTerm], ok: bool, own: dict[str, float]
    ) -> dict[str, float]:
        """A native tick's diagnostics: the parameters' staleness and time, the subclass's
        ``own``, and (``consistency``, on a tick that succeeded) the hierarchy-leak metrics."""
        tick = self.native_tick
        diagnostics = {
            "params_staleness": float(tick.staleness),
            "params_compute_time": tick.params_compute_time,
            **own,
        }
        if ok and self.config.consistency:
            by_task = {id(term.task): term for term in terms}
            per_level = [[by_task[id(task)] for task in tasks] for tasks in self.levels]
            jac = [
                (np.vstack([t.J for t in lv]), np.concatenate([t.drift for t in lv]))
                for lv in per_level
            ]
            partial = [row.copy() for row in tick.partial]
            tau = tick.tau.copy()
            extra = tau - partial[-1] if partial else tau
            params = self.model.params(state, jac)
            diagnostics.update(
                self.consistency_diagnostics(
                    state, params, per_level, partial, extra, tick.wrench.copy()
                )
            )
        return diagnostics

    def close(self) -> None:
        """Stop the parameter worker (``params: async``): the process, or the native thread."""
        self.server.close()
        if self.native_tick is not None:
            self.native_tick.close()

    # -- per tick ---------------------------------------------------------------------------

    def prepare(
        self, state: RobotState, t: float
    ) -> tuple[list[TaskTerm], list[list[TaskTerm]], list[np.ndarray], ParamsRead]:
        """Task terms (flat and per level), stacked references per level and the parameters."""
        terms = self.evaluate_tasks(state, t)
        by_task = {id(term.task): term for term in terms}
        per_level = [[by_task[id(task)] for task in tasks] for tasks in self.levels]
        refs = [np.concatenate([term.acc_ref for term in lv]) for lv in per_level]
        jac = [
            (np.vstack([term.J for term in lv]), np.concatenate([term.drift for term in lv]))
            for lv in per_level
        ]
        read = self.server.get(state, self.tick, jac)
        self.tick += 1
        return terms, per_level, refs, read

    def finish_timings(self, timer: StageTimer, read: ParamsRead) -> dict[str, float]:
        """Stage timings with the parameter time as its own stage (taken out of ``build``)."""
        out = timer.finish()
        out["params"] = read.loop_time
        out["build"] = max(0.0, out["build"] - read.loop_time)
        return out

    def base_diagnostics(self, read: ParamsRead) -> dict[str, float]:
        return {
            "params_staleness": float(read.staleness),
            "params_compute_time": read.compute_time,
        }

    def consistency_diagnostics(
        self,
        state: RobotState,
        params: OsfParams,
        per_level: list[list[TaskTerm]],
        partial: list[np.ndarray],
        extra: np.ndarray,
        wrench: np.ndarray,
    ) -> dict[str, float]:
        if not self.config.consistency:
            return {}
        level_tasks = [[(term.task.name, term.J, term.drift) for term in lv] for lv in per_level]
        out = hierarchy_leak(state, self.contacts, partial, extra, level_tasks, wrench)
        out["dc_error"] = dc_error(params)
        return out

    def output(
        self,
        state: RobotState,
        read: ParamsRead,
        timer: StageTimer,
        terms: list[TaskTerm],
        per_level: list[list[TaskTerm]],
        partial: list[np.ndarray],
        dist: np.ndarray,
        diagnostics: dict[str, float],
        problems: list[Problem],
        internal: np.ndarray | None = None,
    ) -> ControlOutput:
        """The tick's output for the torque Γ = Γ_{≤L} + ``dist`` (the levels' cumulative
        torques ``partial`` plus the wrench-distribution torque), with what it realises;
        ``internal``: forces no torque produces (G f = 0: along a line contact) the wrench
        holds besides."""
        tau = partial[-1] + dist if partial else dist
        wrench = read.params.wrench(tau)
        if internal is not None:
            wrench = wrench + internal
        diagnostics.update(
            self.consistency_diagnostics(state, read.params, per_level, partial, dist, wrench)
        )
        return ControlOutput(
            tau=tau,
            qdd=read.params.qdd(tau),
            wrench=wrench,
            terms=terms,
            timings=self.finish_timings(timer, read),
            iterations=timer.iterations,
            diagnostics=diagnostics,
            problems=problems if self.ctx.keep_problems else [],
        )

    def failed(
        self,
        timer: StageTimer,
        read: ParamsRead,
        terms: list[TaskTerm],
        message: str,
        problems: list[Problem],
    ) -> ControlOutput:
        k, n = self.ctx.robot.k, self.ctx.robot.nv
        return ControlOutput(
            tau=np.zeros(k),
            qdd=np.zeros(n),
            wrench=np.zeros(self.nc),
            terms=terms,
            timings=self.finish_timings(timer, read),
            ok=False,
            message=message,
            iterations=timer.iterations,
            diagnostics=self.base_diagnostics(read),
            problems=problems if self.ctx.keep_problems else [],
        )


#: why a tick with ``internal: basis`` failed when G's first contact block is singular
SINGULAR_BASIS = "to_osf: the grasp map's first contact block is singular; use internal: constraint"


def internal_basis(G: np.ndarray) -> np.ndarray | None:
    """A basis N of the null space of the grasp map G (6, c): the internal wrenches are
    F = N w. With B, G's first six columns (the first 6-D contact's block, invertible),
    G F = 0 ⇔ F_B = −B⁻¹ G_R F_R, so N = [−B⁻¹ G_R; I] and w = F_R, the other contacts' part of
    F. This basis is the same in every implementation (no factorisation whose signs or
    rotation may differ). None when there are fewer than six columns or B is singular."""
    c = G.shape[1]
    B = G[:, :6]
    if c < 6 or not np.linalg.cond(B, 1) < 1e12:
        return None
    return np.vstack([-np.linalg.solve(B, G[:, 6:]), np.eye(c - 6)])


def wrench_selection(
    weights: list[float], contacts: list[PlaneContact], controller: str
) -> np.ndarray:
    """Diagonal weighting of the force variable (nc, nc) from 6 values per contact (repeated;
    a point's force takes the first 3) or one per row; rows weighted 0 are dropped."""
    w = np.asarray(weights, dtype=float)
    nc = contacts_dim(contacts)
    if w.size == 6:
        w = tile_wrench_weights(w, contacts)
    if w.size != nc:
        raise ControllerError(
            f"{controller}: wrench_weights has {w.size} values; give 6 (repeated per contact) "
            f"or {nc} (one per wrench row)"
        )
    keep = np.flatnonzero(w > 0)
    return np.eye(nc)[keep] * w[keep, None]


class ToOsfConfig(OsfBaseConfig):
    """Settings of the task-oriented OSF."""

    weights: list[float] = Field(
        [1e7],
        description="H per task priority (1 first; the last repeats for lower priorities)",
    )
    weighting: Literal["priority", "identical"] = Field(
        "priority",
        description="priority: H from `weights` by task priority; identical: every task weighted "
        "by the first of `weights` (TO-OSF §IV-B3)",
    )
    wrench_weight: float = Field(1.0, ge=0, description="H_w of ‖S_f f‖² (tangential + moments)")
    wrench_cost: Literal["total", "internal"] = Field(
        "total", description="S_f applied to the total wrench, or to F_opt only (literal eq. 11)"
    )
    regularization: float = Field(
        1e-3,
        ge=0,
        description="weight of ‖F_opt‖² relative to H_w (keeps the Hessian positive definite)",
    )
    internal: Literal["basis", "constraint"] = Field(
        "basis",
        description="F_opt as N w over a basis N of the grasp map's null space (a QP with no "
        "equality rows and 6 variables fewer; when the first contact is flat), or as its own "
        "variables with G F_opt = 0 as equality rows (the literal eq. 14); the same optimum",
    )

    @field_validator("weights")
    @classmethod
    def _positive(cls, v: list[float]) -> list[float]:
        if not v or min(v) <= 0:
            raise ValueError(f"weights must be a non-empty list of positive numbers, got {v}")
        return v


class ToOsf(OsfControllerBase):
    """Task-oriented OSF: one QP amends every task reference and the contact wrench."""

    name = "to_osf"
    summary = "task-oriented OSF (TO-OSF): one QP over task accelerations and contact wrench"
    Config = ToOsfConfig
    config: ToOsfConfig
    affine = True
    tick_type = "ToOsfTick"
    settings_type = "ToOsfSettings"

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.solver = ctx.new_solver()
        self.wrench_weighting()

    set_attrs = (*OsfControllerBase.set_attrs, "Sf")

    def wrench_weighting(self) -> None:
        self.Sf = wrench_selection(self.config.wrench_weights, self.contacts, self.name)

    def uses_basis(self) -> bool:
        """F_opt over a basis of G's null space: with ``internal: basis`` when the first
        contact is flat (its block of G is then invertible); a first contact made of points
        keeps eq. (14) as equality rows."""
        return (
            self.config.internal == "basis"
            and bool(self.contacts)
            and self.contacts[0].points is None
        )

    def native_settings(self, s: Any) -> None:
        cfg = self.config
        weights = cfg.weights[:1] if cfg.weighting == "identical" else cfg.weights
        s.row_weights = np.concatenate(
            [np.full(t.dim, task_weight_of(t, weights)) for t in self.level_tasks] or [np.zeros(0)]
        )
        s.wrench_weight = cfg.wrench_weight
        s.wrench_total = cfg.wrench_cost == "total"
        s.regularization = cfg.regularization
        s.Sf = np.asarray(self.Sf, dtype=float).reshape(-1, self.nc)
        s.internal_basis = self.uses_basis()

    def qp_calls(self, tick: Any) -> list[QpCall]:
        return [QpCall(tick.qp, "to_osf", self.solver, self.config.solver_calls)]

    def native_diagnostics(
        self, state: RobotState, terms: list[TaskTerm], ok: bool
    ) -> dict[str, float]:
        """How far the QP moved each task's reference: ``amend.<task>`` = ‖ρ_i − ẍ*_i‖."""
        own: dict[str, float] = {}
        tick = self.native_tick
        if ok:
            amend = tick.rho - tick.level_ref
            pos = 0
            for task in self.level_tasks:
                own[f"amend.{task.name}"] = float(np.linalg.norm(amend[pos : pos + task.dim]))
                pos += task.dim
        return self.osf_diagnostics(state, terms, ok, own)

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        self.select_contacts(t)
        timer = StageTimer(state)
        cfg = self.config
        terms, per_level, refs, read = self.prepare(state, t)
        p = read.params
        k, nc = state.k, self.nc
        rho_ref = np.concatenate(refs)
        nr = rho_ref.size
        # F_opt = N w: N a basis of G's null space (internal_basis), or F_opt itself (N = I)
        basis = self.uses_basis()
        N = internal_basis(p.G) if basis else None
        if N is None and basis:
            return self.failed(timer, read, terms, SINGULAR_BASIS, [])
        nw = nc if N is None else N.shape[1]
        nx = nr + nw
        weights = cfg.weights[:1] if cfg.weighting == "identical" else cfg.weights
        h_task = np.concatenate(
            [np.full(term.dim, task_weight(term, weights)) for lv in per_level for term in lv]
        )
        scale = 1.0 / float(h_task.max())  # the same minimiser, better-scaled numbers
        # F_opt's block weighs ~H_w/H_task; it is solved for in units of σ [N] so that both
        # blocks of the Hessian are O(1) (ill-conditioned otherwise: daqp cycles)
        w_f = scale * cfg.wrench_weight if nc and cfg.wrench_weight > 0 else scale
        sigma = 1.0 / np.sqrt(w_f)
        D = np.concatenate([np.ones(nr), np.full(nw, sigma)])
        # wrench f = A_f x + f_c  (eq. 13)
        A_f = np.hstack([p.F @ p.K, np.eye(nc) if N is None else N])
        f_c = p.F @ p.gamma0 + p.f0
        H = np.zeros((nx, nx))
        g = np.zeros(nx)
        H[np.arange(nr), np.arange(nr)] = scale * h_task
        g[:nr] = -scale * h_task * rho_ref
        if nc and cfg.wrench_weight > 0:
            hw = scale * cfg.wrench_weight
            if cfg.wrench_cost == "total":
                SA = self.Sf @ A_f
                H += hw * (SA.T @ SA)
                g += hw * (SA.T @ (self.Sf @ f_c))
            else:
                SN = self.Sf if N is None else self.Sf @ N
                H[nr:, nr:] += hw * (SN.T @ SN)
        if N is None:
            H[np.arange(nr, nx), np.arange(nr, nx)] += cfg.regularization * w_f
        else:  # ‖F_opt‖² = wᵀ NᵀN w
            H[nr:, nr:] += cfg.regularization * w_f * (N.T @ N)
        A_eq = np.hstack([np.zeros((6, nr)), p.G]) if nc and N is None else np.zeros((0, nx))
        b_eq = np.zeros(A_eq.shape[0])
        A_tau = np.hstack([p.K, p.Yw if N is None else p.Yw @ N])
        tau_max = self.ctx.tau_max
        C = np.vstack([A_tau, self.Cw @ A_f]) if nc else A_tau
        lower = -tau_max - p.gamma0
        upper = tau_max - p.gamma0
        if nc:
            cwf = self.Cw @ f_c
            lower = np.concatenate([lower, self.lw - cwf])
            upper = np.concatenate([upper, self.uw - cwf])
        bound = np.concatenate(self.acc_bound)
        lb = ub = None
        if np.isfinite(bound).any():
            lb = np.concatenate([-bound, np.full(nw, -np.inf)])
            ub = np.concatenate([bound, np.full(nw, np.inf)])
        # x = D x̃
        H = H * D[:, None] * D[None, :]
        problem = Problem(H, g * D, A_eq * D, b_eq, C * D, lower, upper, lb, ub, name="to_osf")
        sol = self.solver.solve(problem)
        timer.add_solution(sol)
        if not sol.success or sol.x is None:
            return self.failed(
                timer, read, terms, f"{sol.solver}: {sol.status.value}: {sol.message}", [problem]
            )
        x = sol.x * D
        rho, f_opt = x[:nr], (x[nr:] if N is None else N @ x[nr:])
        opt_refs = np.split(rho, np.cumsum([r.size for r in refs])[:-1])
        partial = p.partial_torques(opt_refs)
        dist = p.Yw @ f_opt if nc else np.zeros(k)
        diagnostics = self.base_diagnostics(read)
        pos = 0
        for lv in per_level:
            for term in lv:
                amend = rho[pos : pos + term.dim] - term.acc_ref
                diagnostics[f"amend.{term.task.name}"] = float(np.linalg.norm(amend))
                pos += term.dim
        internal = None
        if nc and any(c.points is not None and len(c.points) > 1 for c in self.contacts):
            # the QP's distribution: F_opt's part no torque produces (forces along a line
            # contact, which change no wrench at the frame) holds each point in its cone
            internal = f_opt - p.Qf @ (p.Qf.T @ f_opt)
        return self.output(
            state, read, timer, terms, per_level, partial, dist, diagnostics, [problem], internal
        )
