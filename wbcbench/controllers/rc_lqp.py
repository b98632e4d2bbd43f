"""Reduced-centroidal LQP (RC-LQP paper §3–4): two sequential lexicographic QPs.

The unconstrained chains (arms, neck, a swing leg, …) are collapsed into their 6-D centroidal
coordinates (:mod:`wbcbench.dynamics.reduced`), which splits the conventional LQP of
:mod:`wbcbench.controllers.lqp` in two:

**LQP 1** over x₁ = (q̈_r (n_r), f (6c)), the priorities of Table 1 on the reduced model:

1. ``dynamics``: the top six rows of eq. (14) — exactly the floating-base Newton–Euler equations —
   and the torque limits of the constraint chain (its rows of eq. 14); always feasible, so held
   as hard constraints (as in :mod:`wbcbench.controllers.lqp`);
2. ``contacts``: J_c,r q̈_r + J̇_c q̇ = 0 (eq. 15), the wrench inequalities and the constraint
   chain's joint-acceleration limits;
3. … the task rows expressible through q̈_r (J N_r = 0, §3.4.1: CoM, pelvis, constraint-chain
   frames), one level per priority; then the *preview* priority (below); in the last level's
   cost: q̈_rᵀ M_r q̈_r (eq. 28) + a small ‖f‖².

**LQP 2** over x₂ = q̈_uc (every chain joint):

1. ``coupling``: eq. (30), J_G q̈_uc + J̇_G q̇ = q̈*_r,G, with the chains' torque and joint-
   acceleration limits;
2. … the remaining task rows (hands, swing foot, …) with the base and constraint-chain
   accelerations of LQP 1 moved to the right-hand side (the paper's base-relative reference);
   q̈_ucᵀ M_uc q̈_uc (eq. 29) in the last level's cost.

*Preview* (``centroid_preview``): LQP 1 does not see the chains' tasks, so with the paper's
energy alone it picks chain centroidal accelerations the hand motion does not want; eq. (30) then
makes the rest of the chain (the other arm, the neck, the waist) compensate every hand motion,
and with no posture task those light joints drift into their limits in closed loop (measured:
head and neck past their limits within 1.5 s, hand error 3× lqp's). The preview d is the
centroidal acceleration of the chain motion LQP 2's task rows ask for, priority after priority
(damped, dynamically consistent least squares in the null space of the priorities above; no QP).
Those rows see the base and constraint-chain accelerations q̈_p, which LQP 1 is deciding, and
every step is linear, so d = D q̈_p + d0 is affine in them and enters LQP 1 as such: whatever
q̈_p LQP 1 picks, the d it meets is the one that q̈_p calls for. The lower priorities
matter when one chain carries the waist, both arms and the head (COMAN+-like): eq. (30) and the
hand and torso rows then fix every chain joint, so the posture rows reach the chain only through
d (measured on ``comanplus_stand_sway`` with the highest priority alone in d: mean posture error
1.36 rad against lqp's 0.11, a forearm–wrist pair counter-rotating). ``priority`` (default) adds
q̈_r,G = d as an extra priority of LQP 1 — the paper's "additional priority in LQP 1" (§4.2), fed
before LQP 2 rather than after it — right after the chains' highest task priority, so the legs
and the base balance the chains' centroidal motion below the CoM and pelvis tasks but above
lower ones such as a leg posture (with d below the leg posture the same run fell at 0.25 s);
``energy`` only aims LQP 1's energy term at d (no extra level, weaker); ``off`` is the paper's
literal LQP 1. Eq. (30) and every higher priority are untouched either way.

Torque assembly (``assembly``):

* ``exact``: the actuated rows of the full inverse dynamics at the combined (q̈, f). Because
  eq. (30) holds, the floating-base rows hold too (a chain motion that keeps the chain's
  centroidal acceleration leaves the base's Newton–Euler rows unchanged), so the robot realises
  LQP 1's q̈_r and LQP 2's q̈_uc.
* ``paper``: Γ_cc from the constraint-chain rows of eq. (14) (equal to the exact ones) and Γ_uc
  from each chain's fixed-base dynamics, eq. (17), which leaves out the chain's coupling with the
  base's and the constraint chain's acceleration.

With ``coupling_priority`` (the paper's optional extra priority, §4.2), LQP 2 first puts eq. (30)
*below* its task levels; when that leaves a violation, the centroidal acceleration LQP 2 reached
becomes an extra priority of LQP 1 (after its task levels), and both are solved again.

**When eq. (30) cannot be met** (``infeasible_coupling``). LQP 1 plans the chains' centroidal
acceleration q̈_r,G without seeing their torque and joint-acceleration limits; when LQP 2 cannot
realise it within them, its coupling level only minimises the violation, the combined (q̈, f)
then breaks the floating-base rows of the full dynamics, and no torque realises it: the exact
assembly's Γ makes the robot do something else, and the torque may pass its limits. Measured
before this was handled, on perturbed states (joints ±0.1 rad with the soles on the ground,
velocities ±0.3 rad/s with J_c v = 0, t in the metrics window) and against the rigid-contact
oracle (30 states per scenario): predicted and realised q̈ apart by up to 150 rad/s² on
``tocabi_stand_sway`` and 130 on ``ahn_single_support``, wrench off by up to 360 %, torque
limits passed by up to 22 N·m, every such step reported ok; it happens even at the bare
standing keyframe with v = 0 during the sway. The paper leaves this case open
(eq. 30 is LQP 2's highest priority; §4.2's optional extra priority only feeds the violation
back as a soft level). Here every step is checked after the assembly — eq. (30) met, the
floating-base rows met (exact assembly), every torque within its limit, to ``coupling_tol``, and
the contacts' wrench inequalities met to ``wrench_tol`` (a nearly degenerate level QP can come
back from an active-set solver as "solved" with a wrench outside them) — and one that fails the
check is never returned as ok:

* ``replan`` (default): feed the infeasibility back to LQP 1. An LQP 2 of the chains' limits and
  eq. (30) alone gives the centroidal acceleration ā_G the chains *can* reach nearest to the one
  asked for; LQP 1 is solved again with q̈_r,G = ā_G as a hard constraint next to the
  Newton–Euler rows (the preview level dropped: the chains' centroid is no longer free), so its
  priorities (contacts, CoM, pelvis, …) are met as well as the chains' reachable motion allows;
  LQP 2 then meets eq. (30) for ā_G. The chains' torque limits depend on the base acceleration
  LQP 1 has just changed, so this can still miss; then the tick is solved by the full-model LQP
  of :mod:`wbcbench.controllers.lqp` with the same priorities and settings, which holds every
  limit jointly and always realises its plan. Diagnostics ``replan`` and ``fallback`` (0/1) say
  which happened; on 30 perturbed states of ``tocabi_stand_sway`` 11 re-planned and 4 of them
  fell back (``ahn_double_support``: 12 and 0; ``ahn_single_support``: 3 and 1).
* ``fail``: the tick fails (ok = False) with the reason, e.g. "eq. (30) not met (residual …)".

The robot stays controlled by the first and only the re-planned or full-model solution is ever
applied, so every ok step realises what it predicts (oracle: ≤ 1e-10 with quadprog). This holds
for the exact assembly; the ``paper`` assembly departs from its plan by construction (below).

Timings (Table 3): ``reduced`` (the reduced-dynamics calculation), ``lqp1``, ``lqp2`` (each
formulation + solve), ``solve.lqp1`` / ``solve.lqp2`` (solver only) and per level
``solve.lqp1.<level>``, ``fallback`` and ``solve.fallback`` (the full-model LQP's, 0 on other
ticks). Diagnostics: ``replan``, ``fallback``, ``coupling_residual`` (eq. 30), ``base_residual``
(floating-base rows of the full dynamics at the combined solution), ``wrench_residual``
(how far the wrench is outside the contacts' inequalities), ``assembly_diff``
(max |Γ_exact − Γ_paper| [N·m]) and each level's optimal slacks.

``impl: native`` runs the same step in C++ (``wbcbench/_native/src/controllers/rc_lqp.cpp``):
the reduced model, the row split (decided here and handed over), the preview, both LQPs
and every re-solve, the assembly and its checks; each hierarchy's level QPs go to the solver
through the lean path with the handles of the pool the Python step uses for it, so warm and hot
handles see the same problems in both impls. ``reduced``, ``lqp1``, ``lqp2`` and ``fallback``
are then timed natively.

On a changing contact set (a walk) the chains follow the stance: a foot in the air is a chain,
a standing one closes the constraint chain. Each contact set has its own chain split, reduced
model and row split (a *stance*), built once and kept; with a schedule, :meth:`RcLqp.on_start`
builds the stance of every set the schedule uses at the first state, so a change of contacts
switches to one (:meth:`RcLqp.contacts_changed`) and builds nothing. The native tick holds a
reduced model per stance, made with it, and switches with the set it is handed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from pydantic import Field

from wbcbench import _native
from wbcbench.controllers.base import (
    ControllerConfig,
    ControllerContext,
    ControlOutput,
    NativeConfig,
    StageTimer,
    stance_tasks,
)
from wbcbench.controllers.lqp import (
    LexicographicConfig,
    Lqp,
    LqpConfig,
    SolverPool,
    energy_objective,
    failed_output,
    level_weight,
    lexicographic_settings,
    slack_diagnostics,
    task_levels,
)
from wbcbench.controllers.native import (
    LevelSolve,
    NativeController,
    NativeTimer,
    accept_tol,
    set_limits,
)
from wbcbench.dynamics.chains import CENTROID_DIM, ChainSplit, split_chains
from wbcbench.dynamics.dense import spd_factor, tri_solve
from wbcbench.dynamics.reduced import ReducedDynamics, ReducedModel
from wbcbench.dynamics.state import RobotState, contact_selector
from wbcbench.qp.hierarchy import (
    Constraints,
    HierarchyResult,
    Objective,
    PriorityLevel,
    solve_hierarchy,
)
from wbcbench.tasks.contacts import contacts_dim, stack_wrench_constraints
from wbcbench.tasks.tasks import Task, TaskTerm


class RcLqpConfig(NativeConfig, LexicographicConfig):
    """Settings of the reduced-centroidal LQP (``strategy`` etc. apply to each of its LQPs)."""

    assembly: Literal["exact", "paper"] = Field(
        "exact",
        description="torque from the full inverse dynamics at the combined solution, or the "
        "paper's reduced-model + fixed-base chain torques (eq. 14, 17)",
    )
    coupling_priority: bool = Field(
        False,
        description="eq. (30) below LQP 2's tasks, its violation fed back to LQP 1 as an extra "
        "priority (paper §4.2)",
    )
    centroid_preview: Literal["energy", "priority", "off"] = Field(
        "priority",
        description="the chains' centroidal accelerations their tasks need (see the module "
        "docstring) as the target of LQP 1's energy term, as an extra last priority of LQP 1 "
        "(paper §4.2), or not used (the paper's q̈_rᵀ M_r q̈_r)",
    )
    lqp2_energy: Literal["whole", "chain"] = Field(
        "whole",
        description="LQP 2's energy: the whole robot's q̈ᵀ M q̈ (eq. 27) with LQP 1's accelerations "
        "fixed, or the chain's fixed-base q̈_ucᵀ M_uc q̈_uc (eq. 29)",
    )
    diagnostics: bool = Field(
        False,
        description="also report assembly_diff under the exact assembly (one more RNEA per tick)",
    )
    coupling_tol: float = Field(
        1e-6,
        gt=0,
        description="eq. (30) violation that counts as not met (triggers coupling_priority's "
        "re-solve and the infeasible_coupling handling); also the tolerance of the step's check "
        "of the floating-base rows (relative to max(1, ‖h_base‖∞)) and of the torque limits",
    )
    wrench_tol: float = Field(
        1e-3,
        gt=0,
        description="violation of the contacts' wrench inequalities, relative to max(1, ‖f‖∞), "
        "that fails the step's check (level solutions are trusted to the solver's accuracy: "
        "OSQP at eps 1e-3 stays within it)",
    )
    infeasible_coupling: Literal["replan", "fail"] = Field(
        "replan",
        description="when eq. (30) cannot be met within the chains' torque and acceleration "
        "limits: re-plan LQP 1 with the centroidal acceleration the chains can reach, then, if "
        "that is still not met, solve the tick with the full-model LQP (same priorities); or "
        "fail the tick",
    )


#: the largest offset [rad] of the joints and of the base's orientation in :func:`generic_state`
GENERIC_OFFSET = 0.3
#: seed of those offsets (fixed: the row split of a run does not depend on the process)
GENERIC_SEED = 0


def generic_state(state: RobotState) -> RobotState:
    """``state`` with every joint and the base's orientation turned by a fixed pseudo-random
    offset of at most :data:`GENERIC_OFFSET` (velocities kept): a posture with no symmetry
    the initial one may have, where a property that holds only at special postures fails."""
    model = state.model
    dv = np.random.default_rng(GENERIC_SEED).uniform(-GENERIC_OFFSET, GENERIC_OFFSET, model.nv)
    dv[:3] = 0.0
    q = pin.integrate(model, state.q, dv)
    return RobotState(state.robot, q, state.v.copy())


#: Tikhonov damping of the preview's least squares, relative to the largest squared singular
#: value of each priority's rows
PREVIEW_DAMPING = 1e-8
#: singular values below this fraction of the largest count as zero in the preview (their
#: directions are left to the priorities below)
PREVIEW_RANK_TOL = 1e-6


def wrench_violation(Cw: np.ndarray, lw: np.ndarray, uw: np.ndarray, f: np.ndarray) -> float:
    """How far the wrench ``f`` is outside the contacts' inequalities ``lw ≤ Cw f ≤ uw`` (0
    inside), in their units (N and N·m)."""
    if not Cw.shape[0]:
        return 0.0
    cf = Cw @ f
    return float(max(0.0, (lw - cf).max(), (cf - uw).max()))


def _solve(
    hard: Constraints,
    levels: list[PriorityLevel],
    final: Objective,
    cfg: RcLqpConfig,
    pool: SolverPool,
    timer: StageTimer,
) -> HierarchyResult:
    """One of the two LQPs: energy in the last level's cost, slack-free first (see lqp)."""
    handles = pool.get(2 * (len(levels) + 1))
    return solve_hierarchy(
        hard,
        levels,
        [final],
        cfg.strategy,
        handles,
        timer,
        prox=cfg.prox,
        merge_finals=True,
        slack_free_first=True,
    )


@dataclass
class Preview:
    """The chains' centroidal accelerations the chains' tasks ask for, as a function of the
    base and constraint-chain accelerations q̈_p: d = D q̈_p + d0."""

    D: np.ndarray  # (6·n_chains, n_p)
    d0: np.ndarray  # (6·n_chains,)

    def rows(self, n_p: int, centroid: slice, nx: int) -> np.ndarray:
        """P (6·n_chains, nx) with P x₁ = q̈_r,G − D q̈_p for x₁ = (q̈_r, f)."""
        P = np.zeros((self.d0.size, nx))
        P[:, :n_p] = -self.D
        P[:, centroid] += np.eye(self.d0.size)
        return P


@dataclass
class _Stance:
    """What follows one contact set: its chain split, its reduced model and the row split of
    its tasks (None until decided)."""

    split: ChainSplit
    reduced: ReducedDynamics
    rows: _RowSplit | None = None
    #: the native tick's settings for the set (LexicographicSettings, RcLqpSettings, the row
    #: split's lists) and the row split they were made from: made once, handed over at each
    #: change to the set
    native: tuple[Any, ...] | None = None


@dataclass
class _RowSplit:
    """Which rows of each task LQP 1 handles (reducible) and which LQP 2 does."""

    lqp1: dict[str, np.ndarray]
    lqp2: dict[str, np.ndarray]
    #: the highest priority with rows in LQP 2 (where LQP 1's preview level goes), 0 if none
    chain_priority: int


class RcLqp(NativeController):
    """Reduced-centroidal LQP: LQP 1 on the reduced model, LQP 2 on the unconstrained chains."""

    name = "rc_lqp"
    summary = (
        "reduced-centroidal LQP (RC-LQP): arms/neck/swing leg collapsed into centroidal "
        "dynamics, two sequential lexicographic QPs, exact or paper torque assembly"
    )
    Config = RcLqpConfig
    reference_solvers = ("quadprog",)
    config: RcLqpConfig
    tick_type = "RcLqpTick"
    native_schedule = True

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.frames = ctx.contact_frames
        #: each contact set's stance, built once and kept (the first: every contact)
        self._stances: dict[tuple[int, ...], _Stance] = {}
        every = self._stance(tuple(range(len(ctx.contacts))))
        self.split, self.reduced = every.split, every.reduced
        self.Cw, self.lw, self.uw = stack_wrench_constraints(ctx.contacts)
        self.nc = contacts_dim(self.contacts)
        self.pool1 = SolverPool(ctx)
        self.pool2 = SolverPool(ctx)
        self.pool1b = SolverPool(ctx)
        self.pool2b = SolverPool(ctx)
        self.pool1c = SolverPool(ctx)
        self.pool2c = SolverPool(ctx)
        self.pool2r = SolverPool(ctx)
        # the full-model LQP with the same priorities and settings: the last resort of a tick
        # whose eq. (30) cannot be met (infeasible_coupling = "replan"); only its formulation
        # and its solver handles are used, so it is the Python one whatever impl runs
        shared = set(LexicographicConfig.model_fields) - {"impl"}
        self.full = Lqp(ctx, LqpConfig(**self.config.model_dump(include=shared), impl="python"))
        #: every hierarchy's handles, in the order of the native tick's pools (RcLqpPool)
        self.pools = [
            self.pool1,
            self.pool2,
            self.pool1b,
            self.pool2b,
            self.pool1c,
            self.pool2c,
            self.pool2r,
            self.full.pool,
        ]
        self._rows: _RowSplit | None = None
        # the stances the native tick holds, and the state of the native step under way (where
        # a contact set first met at it decides its row split)
        self._tick_stances: set[tuple[int, ...]] = set()
        self._tick_state: RobotState | None = None
        self.last: tuple[HierarchyResult, HierarchyResult | None] | None = None
        self.last_reduced: ReducedModel | None = None
        self.last_output: ControlOutput | None = None
        # actuated indices (into Γ) of the plain coordinates and of the chains
        self._act_plain = self.split.plain[6:] - 6
        self._act_uc = self.split.unconstrained - 6

    # -- a contact set that changes ------------------------------------------------------------

    def select_contacts(self, t: float) -> Any:
        """The active contacts, also for the full-model LQP this controller falls back on (the
        Python one: the native tick's selects with the tick)."""
        if self.impl == "python":
            self.full.select_contacts(t)
        return super().select_contacts(t)

    def _stance(self, active: tuple[int, ...]) -> _Stance:
        """The stance of the contacts ``active`` (indices into the context's), built on first
        use and kept."""
        stance = self._stances.get(active)
        if stance is None:
            contacts = [self.ctx.contacts[i] for i in active]
            split = split_chains(self.ctx.robot.pin_model, [c.frame for c in contacts])
            model = ReducedDynamics(self.ctx.robot.pin_model, split, contacts)
            stance = self._stances[active] = _Stance(split, model)
        return stance

    def contacts_changed(self) -> None:
        """The chains follow the stance: the split, the reduced model and the row split of the
        new contact set (each built once per set and kept; the row split of a set the schedule
        did not foresee is decided at the state of the tick that first meets it)."""
        stance = self._stance(self.active_contacts)
        self.split, self.reduced, self._rows = stance.split, stance.reduced, stance.rows
        self._act_plain = self.split.plain[6:] - 6
        self._act_uc = self.split.unconstrained - 6
        if self.native_tick is not None and self.active_contacts not in self._tick_stances:
            self.native_tick.add_stance(_native.split_spec(stance.split))
            self._tick_stances.add(self.active_contacts)

    def _decide_rows(self, state: RobotState) -> _RowSplit:
        """The row split of the contact set held, at ``state``, kept with its stance."""
        self._rows = self.row_split(state)
        if self.ctx.schedule is not None and -1 not in self.active_contacts:
            self._stance(self.active_contacts).rows = self._rows
        return self._rows

    # -- the native tick ------------------------------------------------------------------------

    def on_start(self, state: RobotState) -> None:
        """The row split, decided at the first state; with a contact schedule, also the stance
        of every contact set it uses and the row split of each set's tasks, at the same state
        (the split is structural: a change of contacts then builds and decides nothing)."""
        self._rows = self.row_split(state)
        schedule = self.ctx.schedule
        if schedule is None:
            return
        for active in schedule.contact_sets():
            contacts, Cw, lw, uw, _, _ = self.contact_set(active)
            tasks = stance_tasks(self.ctx.tasks, {c.frame for c in contacts})
            stance = self._stance(active)
            if stance.rows is None:
                stance.rows = self.row_split(state, stance.reduced, tasks)
            if self.impl == "native" and stance.native is None:
                wrench = (Cw, lw, uw, contacts_dim(contacts))
                stance.native = (stance.rows, *self.tick_settings(stance.rows, tasks, wrench))

    def tick_args(self) -> tuple[Any, ...]:
        """Every stance known, the one of every contact first: the tick builds their reduced
        models once."""
        self._tick_stances = set(self._stances)
        return ([_native.split_spec(stance.split) for stance in self._stances.values()],)

    def native_step(self, state: RobotState, t: float) -> ControlOutput:
        self._tick_state = state
        return super().native_step(state, t)

    def configure_tick(self, tick: Any) -> None:
        rows = self._rows
        if rows is None:
            assert self._tick_state is not None
            rows = self._decide_rows(self._tick_state)
        stance = self._stances.get(self.active_contacts)
        if stance is not None and stance.native is not None and stance.native[0] is rows:
            settings = stance.native
        else:
            wrench = (self.Cw, self.lw, self.uw, self.nc)
            settings = (rows, *self.tick_settings(rows, self.active_tasks, wrench))
            if stance is not None:
                stance.native = settings
        _, s, rc, lqp1_rows = settings
        tick.configure(s, rc)
        tick.set_row_split(lqp1_rows)

    def tick_settings(
        self, rows: _RowSplit, tasks: list[Task], wrench: tuple[Any, ...]
    ) -> tuple[Any, Any, list[list[int]]]:
        """The native tick's settings for a contact set: its tasks, its wrench rows ``(Cw, lw,
        uw, nc)`` (the bounds until ``set_wrench_bounds`` sets a tick's) and its row split."""
        cfg = self.config
        core = _native.core()
        s = lexicographic_settings(cfg, self.ctx.tasks, tasks)
        s.accept_tol = accept_tol(self.ctx)
        set_limits(s, self.ctx.tau_max, *wrench)
        rc = core.RcLqpSettings()
        rc.assembly = getattr(core.Assembly, cfg.assembly)
        rc.coupling_priority = cfg.coupling_priority
        rc.centroid_preview = getattr(core.CentroidPreview, cfg.centroid_preview)
        rc.lqp2_energy = getattr(core.Lqp2Energy, cfg.lqp2_energy)
        rc.diagnostics = cfg.diagnostics
        rc.coupling_tol = cfg.coupling_tol
        rc.wrench_tol = cfg.wrench_tol
        rc.infeasible_coupling = getattr(core.InfeasibleCoupling, cfg.infeasible_coupling)
        lqp1_rows = [
            rows.lqp1[t.name].tolist() if t.name in rows.lqp1 else [] for t in self.ctx.tasks
        ]
        return s, rc, lqp1_rows

    def level_solve(self, tick: Any) -> LevelSolve:
        # handles for the most levels any contact set gives (every priority), as lqp's
        levels = len({task.priority for task in self.ctx.tasks})
        bound = [2 * (levels + 4)] * (len(self.pools) - 1) + [2 * (levels + 2)]
        handles = [
            pool.get(max(tick.handles(i), most))
            for i, (pool, most) in enumerate(zip(self.pools, bound, strict=True))
        ]
        return LevelSolve(
            tick.slot,
            handles,
            self.ctx.keep_problems,
            self.config.solver_calls,
            origin=self.config.strategy == "nullspace",
        )

    def native_region(
        self, q: np.ndarray, v: np.ndarray, t: float, timer: NativeTimer
    ) -> str | None:
        """The timed region of a native step: both LQPs and every re-solve, their QPs through
        the lean path. Returns None, or the message of a failed tick."""
        assert self.native_solve is not None
        self.native_solve.start(timer)
        tick = self.native_tick
        if self.native_solve.run(tick, q, v, t):
            return None
        if tick.level_failed:
            return str(tick.message) + self.native_solve.message(
                tick.failed_level, tick.failed_reason
            )
        return str(tick.message)

    def native_diagnostics(
        self, state: RobotState, terms: list[TaskTerm], ok: bool
    ) -> dict[str, float]:
        """The same diagnostics as :meth:`step`'s, read from the tick."""
        cfg, tick = self.config, self.native_tick
        diag: dict[str, float] = {}
        if cfg.assembly == "paper" or cfg.diagnostics:
            diag["assembly_diff"] = float(tick.assembly_diff)
        diag["base_residual"] = float(tick.base_residual)
        diag["wrench_residual"] = float(tick.wrench_residual)
        if self.split.unconstrained.size or tick.fell_back:
            diag["coupling_residual"] = float(tick.coupling_residual)
        diag.update(slack_diagnostics(tick.lqp1))
        if tick.has_lqp2:
            diag.update(slack_diagnostics(tick.lqp2))
        diag["prox_retries"] = float(tick.retries)
        diag["replan"] = float(tick.replanned)
        diag["fallback"] = float(tick.fell_back)
        if cfg.coupling_priority:
            diag["coupling_violation"] = float(tick.coupling_violation)
            for key in ("w.lqp1.coupling", "v.lqp1.coupling", "w.lqp2.limits", "v.lqp2.limits"):
                diag.setdefault(key, float("nan"))
        return diag

    def native_output(
        self, state: RobotState, timer: NativeTimer, message: str | None
    ) -> ControlOutput:
        """The same output as :meth:`step`'s: a failed tick keeps the last good tick's keys,
        and the LQPs' stages are timed natively."""
        tick = self.native_tick
        self.last = None  # (the LQPs' results are the native tick's)
        if message is not None:
            terms = self.native_terms()
            timings = timer.finish(tick)
            return failed_output(
                state.n, state.k, self.nc, terms, timings, message, self.last_output
            )
        out = super().native_output(state, timer, message)
        timings = out.timings
        timings["reduced"] = tick.reduced_time
        timings["lqp1"] = tick.lqp1_time
        timings["lqp2"] = tick.lqp2_time
        timings["fallback"] = tick.fallback_time
        self.part_stages(timings)
        self.last_output = out
        return out

    def part_stages(self, timings: dict[str, float]) -> None:
        """``solve.lqp1``, ``solve.lqp2`` and ``solve.fallback``: the sums of each part's level
        solves (with ``coupling_priority``, the re-solve's key on every tick)."""
        if self.config.coupling_priority:
            timings.setdefault("solve.lqp1.coupling", 0.0)
        for part in ("lqp1", "lqp2", "fallback"):
            keys = [key for key in timings if key.startswith(f"solve.{part}.")]
            timings[f"solve.{part}"] = sum(timings[key] for key in keys)

    # -- task rows ------------------------------------------------------------------------------

    def row_split(
        self,
        state: RobotState,
        reduced: ReducedDynamics | None = None,
        tasks: list[Task] | None = None,
    ) -> _RowSplit:
        """Rows with J N_r = 0 go to LQP 1, the others to LQP 2 (decided once per contact set:
        structural); of ``tasks`` on ``reduced`` (the contact set held's by default).

        The test runs at ``state`` and at :func:`generic_state` of it, and a row goes to LQP 1
        only when it passes at both: J N_r = 0 can hold at one posture by coincidence (TALOS'
        half-sitting: no chain joint turns the torso about the world x axis while the torso yaw
        is 0, so that row of the torso orientation passes there and fails once the yaw moves).
        A row handed to LQP 1 in error is planned on the reduced model with a Jacobian that is
        wrong as soon as the posture changes, and the chains' preview, which does not see it,
        then asks for centroidal accelerations LQP 1 does not meet.
        """
        reduced = self.reduced if reduced is None else reduced
        tasks = self.active_tasks if tasks is None else tasks
        masks = []
        for s in (state, generic_state(state)):
            red = reduced.compute(s, fixed_base=False)
            masks.append({t.name: red.reducible_rows(t.evaluate(s, 0.0).J) for t in tasks})
        lqp1, lqp2 = {}, {}
        for task in tasks:
            mask = masks[0][task.name] & masks[1][task.name]
            lqp1[task.name] = np.flatnonzero(mask)
            lqp2[task.name] = np.flatnonzero(~mask)
        chain = [t.priority for t in tasks if lqp2[t.name].size]
        return _RowSplit(lqp1, lqp2, min(chain, default=0))

    # -- LQP 1 ----------------------------------------------------------------------------------

    def lqp1_levels(
        self,
        state: RobotState,
        red: ReducedModel,
        terms: list[TaskTerm],
        preview: Preview | None = None,
    ) -> tuple[Constraints, list[PriorityLevel], np.ndarray, np.ndarray]:
        """LQP 1's priority 1 (hard) and levels over x₁ = (q̈_r, f), and the constraint-chain
        torque map Γ_p = G x₁ + γ; ``preview`` (the chains' centroidal accelerations) becomes a
        level right after the levels of the chains' highest task priority."""
        cfg = self.config
        assert self._rows is not None
        nc, n_r, n_p = self.nc, self.split.n_reduced, red.n_plain
        nx = n_r + nc
        nl = red.b_r + red.g_r
        dJc = state.contact_drift(self.contacts)
        Jk_r = red.J_cr
        T = contact_selector(self.contacts)
        if T is not None:  # a point set's independent rows
            Jk_r, dJc = T @ red.J_cr, T @ dJc
        G = np.hstack([red.M_r[6:n_p], -red.J_cr[:, 6:n_p].T])
        gamma = nl[6:n_p]
        tau_max = self.ctx.tau_max[self._act_plain]
        hard = Constraints(
            nx,
            A=np.hstack([red.M_r[:6], -red.J_cr[:, :6].T]),
            b=-nl[:6],
            C=G,
            l=-tau_max - gamma,
            u=tau_max - gamma,
        )
        levels: list[PriorityLevel] = []
        nw = self.Cw.shape[0]
        n_act = n_p - 6
        C2 = np.zeros((nw + n_act, nx))
        C2[:nw, n_r:] = self.Cw
        C2[nw:, 6:n_p] = np.eye(n_act)
        qdd_max = np.full(n_act, cfg.qdd_limit)
        levels.append(
            PriorityLevel(
                "contacts",
                A=np.hstack([Jk_r, np.zeros((Jk_r.shape[0], nc))]),
                b=-dJc,
                C=C2,
                l=np.concatenate([self.lw, -qdd_max]),
                u=np.concatenate([self.uw, qdd_max]),
                hard_if_feasible=True,
            )
        )
        for p, group in task_levels(terms):
            if preview is not None and p > self._rows.chain_priority:
                levels.append(self._preview_level(preview))
                preview = None
            rows = [(t, self._rows.lqp1[t.task.name]) for t in group]
            rows = [(t, r) for t, r in rows if r.size]
            if not rows:
                continue
            J = np.vstack([t.J[r] for t, r in rows])
            drift = np.concatenate([t.drift[r] for t, r in rows])
            ref = np.concatenate([t.acc_ref[r] for t, r in rows])
            Jr, drift_r = red.task(J, drift)
            A = np.hstack([Jr, np.zeros((Jr.shape[0], nc))])
            levels.append(PriorityLevel(f"p{p}", A=A, b=ref - drift_r))
        if preview is not None:
            levels.append(self._preview_level(preview))
        return hard, levels, G, gamma

    def _preview_level(self, preview: Preview) -> PriorityLevel:
        """q̈_r,G = D q̈_p + d0: the chains' centroidal accelerations set to the preview."""
        nx = self.split.n_reduced + self.nc
        A = preview.rows(self.split.plain.size, self.centroid_rows, nx)
        return PriorityLevel("preview", A=A, b=preview.d0)

    def solve_lqp1(
        self,
        red: ReducedModel,
        hard: Constraints,
        levels: list[PriorityLevel],
        preview: Preview | None,
        pool: SolverPool,
        timer: StageTimer,
    ) -> HierarchyResult:
        cfg = self.config
        for i, lv in enumerate(levels):
            lv.weight = level_weight(cfg.weights, i)
            lv.name = lv.name if lv.name.startswith("lqp1.") else f"lqp1.{lv.name}"
        Lt = spd_factor(red.M_r)  # Lᵀ of M_r = L Lᵀ
        final = energy_objective("lqp1.energy", Lt, self.nc, cfg.wrench_regularization)
        if preview is not None:
            # ‖Lᵀ (q̈_r − d)‖² with d zero but for the chains' centroidal rows, where it is
            # D q̈_p + d0: ‖F (x − E x) − F e‖² with E x, e those rows' parts
            nx = final.F.shape[0]
            E = np.zeros((nx, nx))
            E[self.centroid_rows, : self.split.plain.size] = preview.D
            e = np.zeros(nx)
            e[self.centroid_rows] = preview.d0
            final = Objective(final.name, final.F - final.F @ E, final.F @ e)
        final.weight = cfg.final_weight
        return _solve(hard, levels, final, cfg, pool, timer)

    # -- LQP 2 ----------------------------------------------------------------------------------

    def lqp2_levels(
        self,
        state: RobotState,
        red: ReducedModel,
        terms: list[TaskTerm],
        x1: np.ndarray,
        coupling_last: bool,
    ) -> tuple[list[PriorityLevel], np.ndarray, np.ndarray]:
        """LQP 2's levels over q̈_uc and the chains' torque map Γ_uc = M_uc q̈_uc + γ_uc."""
        cfg = self.config
        assert self._rows is not None
        split = self.split
        plain, uc = split.plain, split.unconstrained
        n_p, n_uc = red.n_plain, uc.size
        qdd_plain = x1[:n_p]
        target_G = x1[n_p : split.n_reduced]
        if cfg.assembly == "exact":
            gamma = state.M[np.ix_(uc, plain)] @ qdd_plain + state.h[uc]
        else:
            gamma = red.b_uc + red.g_uc
        M_uc = red.M_uc
        tau_max = self.ctx.tau_max[self._act_uc]
        qdd_max = np.full(n_uc, cfg.qdd_limit)
        coupling = PriorityLevel(
            "coupling",
            A=red.J_G,
            b=target_G - red.dJG_v,
            C=np.vstack([M_uc, np.eye(n_uc)]),
            l=np.concatenate([-tau_max - gamma, -qdd_max]),
            u=np.concatenate([tau_max - gamma, qdd_max]),
            hard_if_feasible=True,
        )
        levels: list[PriorityLevel] = []
        if coupling_last:
            # the limits stay at the top, eq. (30) goes below the tasks
            levels.append(
                PriorityLevel(
                    "limits", C=coupling.C, l=coupling.l, u=coupling.u, hard_if_feasible=True
                ),
            )
        else:
            levels.append(coupling)
        for p, group in task_levels(terms):
            rows = [(t, self._rows.lqp2[t.task.name]) for t in group]
            rows = [(t, r) for t, r in rows if r.size]
            if not rows:
                continue
            J = np.vstack([t.J[r] for t, r in rows])
            ref = np.concatenate([t.acc_ref[r] - t.drift[r] for t, r in rows])
            # base-relative reference: LQP 1's base and constraint-chain accelerations are known
            b = ref - J[:, plain] @ qdd_plain
            levels.append(PriorityLevel(f"p{p}", A=J[:, uc], b=b))
        if coupling_last:
            levels.append(PriorityLevel("coupling", A=coupling.A, b=coupling.b))
        return levels, M_uc, gamma

    def solve_lqp2(
        self,
        state: RobotState,
        red: ReducedModel,
        levels: list[PriorityLevel],
        x1: np.ndarray,
        pool: SolverPool,
        timer: StageTimer,
    ) -> HierarchyResult:
        cfg = self.config
        for i, lv in enumerate(levels):
            lv.weight = level_weight(cfg.weights, i)
            lv.name = lv.name if lv.name.startswith("lqp2.") else f"lqp2.{lv.name}"
        final = energy_objective("lqp2.energy", red.M_uc_factor, 0, cfg.wrench_regularization)
        if cfg.lqp2_energy == "whole":
            # q̈ᵀ M q̈ of the whole robot with LQP 1's q̈ fixed: q̈_ucᵀ M_uc q̈_uc + 2 q̈_ucᵀ M_up q̈_p
            # = ‖Lᵀ q̈_uc − f‖² + const with L f = −M_up q̈_p (M_uc = L Lᵀ)
            plain, uc = self.split.plain, self.split.unconstrained
            cross = state.M[np.ix_(uc, plain)] @ x1[: plain.size]
            f = -tri_solve(final.F, cross, trans=True)  # F = Lᵀ upper triangular
            final = Objective(final.name, final.F, f)
        final.weight = cfg.final_weight
        n_uc = red.M_uc.shape[0]
        return _solve(Constraints(n_uc), levels, final, cfg, pool, timer)

    def preview(self, state: RobotState, red: ReducedModel, terms: list[TaskTerm]) -> Preview:
        """The chains' centroidal accelerations their tasks (LQP 2's rows) ask for, as an affine
        function of the base and constraint-chain accelerations q̈_p (which LQP 1 decides).

        The priorities are resolved in order, each by damped least squares in the null space of
        the ones above, in the coordinates u = Lᵀ q̈_uc (M_uc = L Lᵀ) where ‖u‖² is the chains'
        acceleration energy: the motion left over has the least energy. Every step is linear in
        the right-hand sides, so u = u0 + B q̈_p is carried as the pair (u0, B).
        """
        assert self._rows is not None
        plain, uc = self.split.plain, self.split.unconstrained
        Lt = red.M_uc_factor  # Lᵀ, upper triangular
        u0 = np.zeros(uc.size)
        B = np.zeros((uc.size, plain.size))
        Z: np.ndarray | None = None  # orthonormal basis of what is left free (in u); None: all
        groups = [
            [(t, r) for t in group if (r := self._rows.lqp2[t.task.name]).size]
            for _, group in task_levels(terms)
        ]
        groups = [g for g in groups if g]
        for i, rows in enumerate(groups):
            last = i == len(groups) - 1
            J = np.vstack([t.J[r] for t, r in rows])
            Ju = tri_solve(Lt, J[:, uc].T, trans=True).T  # J_uc L⁻ᵀ
            # residual of the rows at u: [b − J_uc q̈_uc(u0)] − [J_p + J_uc L⁻ᵀ B] q̈_p
            rhs = np.empty((J.shape[0], 1 + plain.size))
            rhs[:, 0] = np.concatenate([t.acc_ref[r] - t.drift[r] for t, r in rows]) - Ju @ u0
            rhs[:, 1:] = -J[:, plain] - Ju @ B
            U, sv, Vt = np.linalg.svd(Ju if Z is None else Ju @ Z, full_matrices=not last)
            rank = int(np.sum(sv > PREVIEW_RANK_TOL * sv[0])) if sv.size and sv[0] > 0 else 0
            if rank:
                s_r = sv[:rank]
                gain = s_r / (s_r**2 + PREVIEW_DAMPING * sv[0] ** 2)
                V_r = Vt[:rank].T if Z is None else Z @ Vt[:rank].T
                step = V_r @ (gain[:, None] * (U[:, :rank].T @ rhs))
                u0 += step[:, 0]
                B += step[:, 1:]
            if last:
                break
            Z = Vt[rank:].T if Z is None else Z @ Vt[rank:].T
            if not Z.shape[1]:
                break
        # q̈_uc = L⁻ᵀ u; d = J_G q̈_uc + J̇_G q̇
        qdd = tri_solve(Lt, np.column_stack([u0, B]))
        return Preview(red.J_G @ qdd[:, 1:], red.J_G @ qdd[:, 0] + red.dJG_v)

    # -- the step -------------------------------------------------------------------------------

    def _plan(
        self,
        state: RobotState,
        red: ReducedModel,
        terms: list[TaskTerm],
        level: Preview | None,
        target: Preview | None,
        timer: StageTimer,
        times: dict[str, float],
        extra: dict[str, float],
    ) -> tuple[HierarchyResult, HierarchyResult | None, str]:
        """LQP 1 then LQP 2 (with ``coupling_priority``'s re-solve); an error message if either
        failed. ``times`` accumulates the time of each LQP."""
        cfg = self.config
        n_p, n_r = self.split.plain.size, self.split.n_reduced
        t1 = time.perf_counter()
        hard1, levels1, _, _ = self.lqp1_levels(state, red, terms, level)
        res1 = self.solve_lqp1(red, hard1, levels1, target, self.pool1, timer)
        times["lqp1"] += time.perf_counter() - t1
        if not res1.ok:
            return res1, None, "LQP 1: " + res1.message
        if not self.split.unconstrained.size:
            return res1, None, ""
        x1 = res1.x
        t2 = time.perf_counter()
        levels2, _, _ = self.lqp2_levels(state, red, terms, x1, cfg.coupling_priority)
        res2 = self.solve_lqp2(state, red, levels2, x1, self.pool2, timer)
        times["lqp2"] += time.perf_counter() - t2
        if res2.ok and cfg.coupling_priority:
            w = res2.levels[len(levels2) - 1].w  # eq. (30)'s violation (the last level)
            extra["coupling_violation"] = float(np.linalg.norm(w))
            if np.linalg.norm(w) > cfg.coupling_tol:
                # LQP 1 again, the centroidal acceleration LQP 2 reached as an extra priority
                t1 = time.perf_counter()
                reached = x1[n_p:n_r] + w
                sel = np.zeros((n_r - n_p, n_r + self.nc))
                sel[:, n_p:n_r] = np.eye(n_r - n_p)
                hard1, levels1b, _, _ = self.lqp1_levels(state, red, terms, level)
                levels1b.append(PriorityLevel("coupling", A=sel, b=reached))
                res1 = self.solve_lqp1(red, hard1, levels1b, target, self.pool1b, timer)
                times["lqp1"] += time.perf_counter() - t1
                if not res1.ok:
                    return res1, None, "LQP 1 (coupling): " + res1.message
                x1 = res1.x
                t2 = time.perf_counter()
                levels2, _, _ = self.lqp2_levels(state, red, terms, x1, False)
                res2 = self.solve_lqp2(state, red, levels2, x1, self.pool2b, timer)
                times["lqp2"] += time.perf_counter() - t2
        if not res2.ok:
            return res1, res2, "LQP 2: " + res2.message
        return res1, res2, ""

    def _replan(
        self,
        state: RobotState,
        red: ReducedModel,
        terms: list[TaskTerm],
        x1: np.ndarray,
        timer: StageTimer,
        times: dict[str, float],
    ) -> tuple[HierarchyResult, HierarchyResult | None, str]:
        """Feed eq. (30)'s infeasibility back to LQP 1. The centroidal acceleration the chains
        can reach within their limits, ā_G = argmin ‖J_G q̈_uc + J̇_G q̇ − q̈_r,G‖ over the q̈_uc
        that respect them (an LQP 2 of the limits and eq. 30 alone), becomes a hard constraint
        q̈_r,G = ā_G of LQP 1 next to the Newton–Euler rows: LQP 1 re-plans the base, the
        constraint chain and the wrench for the chains' motion that can happen, each of its
        priorities met as well as that allows. LQP 2 then solves eq. (30) for ā_G again; the
        chains' torque limits move with the new base acceleration, so the caller checks the
        result."""
        n_p, n_r = self.split.plain.size, self.split.n_reduced
        t2 = time.perf_counter()
        levels, _, _ = self.lqp2_levels(state, red, [], x1, coupling_last=True)
        reach = self.solve_lqp2(state, red, levels, x1, self.pool2r, timer)
        times["lqp2"] += time.perf_counter() - t2
        if not reach.ok:
            return reach, None, "LQP 2 (reachable centroidal acceleration): " + reach.message
        w = next(lv.w for lv in reach.levels if lv.name == "lqp2.coupling")
        reached = x1[n_p:n_r] + w
        t1 = time.perf_counter()
        hard1, levels1, _, _ = self.lqp1_levels(state, red, terms, None)
        sel = np.zeros((n_r - n_p, n_r + self.nc))
        sel[:, n_p:n_r] = np.eye(n_r - n_p)
        assert hard1.A is not None and hard1.b is not None
        hard1 = Constraints(
            hard1.n,
            A=np.vstack([hard1.A, sel]),
            b=np.concatenate([hard1.b, reached]),
            C=hard1.C,
            l=hard1.l,
            u=hard1.u,
        )
        res1 = self.solve_lqp1(red, hard1, levels1, None, self.pool1c, timer)
        times["lqp1"] += time.perf_counter() - t1
        if not res1.ok:
            return res1, None, "LQP 1 (re-planned): " + res1.message
        t2 = time.perf_counter()
        levels2, _, _ = self.lqp2_levels(state, red, terms, res1.x, False)
        res2 = self.solve_lqp2(state, red, levels2, res1.x, self.pool2c, timer)
        times["lqp2"] += time.perf_counter() - t2
        if not res2.ok:
            return res1, res2, "LQP 2 (re-planned): " + res2.message
        return res1, res2, ""

    def _assemble(
        self,
        state: RobotState,
        red: ReducedModel,
        res1: HierarchyResult,
        res2: HierarchyResult | None,
        diag: dict[str, float],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
        """(q̈, f, Γ) of the combined solution, the diagnostics, and why the step must not be
        trusted ("" if it may): eq. (30) not met, the floating-base rows of the full dynamics
        not met (exact assembly: the robot would not realise the plan), a torque limit
        exceeded."""
        cfg = self.config
        split = self.split
        n_r, plain, uc = split.n_reduced, split.plain, split.unconstrained
        n_p = plain.size
        x1 = res1.x
        qdd = np.zeros(state.n)
        qdd[plain] = x1[:n_p]
        f = x1[n_r:]
        if res2 is not None:
            qdd[uc] = res2.x
        Jc = state.contact_jacobian(self.contacts)
        # the full inverse dynamics at (q̈, f): actuated rows for Γ, base rows as a check
        full = state.M @ qdd + state.h - Jc.T @ f
        tau = full[6:]
        if cfg.assembly == "paper" or cfg.diagnostics:
            red_nl = red.b_r + red.g_r
            G1 = np.hstack([red.M_r[6:n_p], -red.J_cr[:, 6:n_p].T])
            tau_paper = np.empty(state.k)
            tau_paper[self._act_plain] = G1 @ x1 + red_nl[6:n_p]
            if uc.size:
                tau_paper[self._act_uc] = red.M_uc @ qdd[uc] + red.b_uc + red.g_uc
            diag["assembly_diff"] = float(np.abs(tau - tau_paper).max())
            if cfg.assembly == "paper":
                tau = tau_paper
        tol = cfg.coupling_tol
        diag["base_residual"] = float(np.abs(full[:6]).max())
        why = ""
        if uc.size:
            realized = red.J_G @ qdd[uc] + red.dJG_v
            diag["coupling_residual"] = float(np.abs(realized - x1[n_p:n_r]).max())
            if diag["coupling_residual"] > tol:
                why = f"eq. (30) not met (residual {diag['coupling_residual']:.3g})"
        if not why and cfg.assembly == "exact":
            scale = max(1.0, float(np.abs(state.h[:6]).max()))
            if diag["base_residual"] > tol * scale:
                why = f"floating-base rows not met ({diag['base_residual']:.3g} N)"
        excess = float((np.abs(tau) - self.ctx.tau_max * (1 + tol)).max(initial=-np.inf))
        if not why and excess > tol:
            why = f"torque limit exceeded by {excess:.3g} N·m"
        diag["wrench_residual"] = wrench_violation(self.Cw, self.lw, self.uw, f)
        if not why and diag["wrench_residual"] > cfg.wrench_tol * max(1.0, np.abs(f).max()):
            why = f"wrench inequalities broken by {diag['wrench_residual']:.3g}"
        return qdd, f, tau, why

    def step(self, state: RobotState, t: float) -> ControlOutput:
        if self.impl == "native":
            return self.native_step(state, t)
        self.select_contacts(t)
        timer = StageTimer(state)
        cfg = self.config
        n, k, nc = state.n, state.k, self.nc
        uc = self.split.unconstrained
        terms = self.evaluate_tasks(state, t)
        red = self.reduced.compute(state, fixed_base=cfg.assembly == "paper" or cfg.diagnostics)
        self.last_reduced = red
        if self._rows is None:
            self._decide_rows(state)

        # the chains' centroidal accelerations: a level of LQP 1 (priority) or its energy's target
        preview = level = target = None
        if cfg.centroid_preview != "off" and uc.size:
            preview = self.preview(state, red, terms)
        if cfg.centroid_preview == "priority":
            level = preview
        else:
            target = preview
        times = {"lqp1": 0.0, "lqp2": 0.0, "fallback": 0.0}
        extra: dict[str, float] = {"replan": 0.0, "fallback": 0.0}
        res1, res2, msg = self._plan(state, red, terms, level, target, timer, times, extra)
        if msg:
            return failed_output(n, k, nc, terms, timer.finish(), msg, self.last_output)
        diag: dict[str, float] = {}
        qdd, f, tau, why = self._assemble(state, red, res1, res2, diag)
        diag.update(slack_diagnostics(res1))
        if res2 is not None:
            diag.update(slack_diagnostics(res2))
        diag["prox_retries"] = float(res1.retries + (res2.retries if res2 is not None else 0))
        if why and cfg.infeasible_coupling == "replan":
            # eq. (30) within the chains' limits is infeasible for what LQP 1 asked: re-plan
            extra["replan"] = 1.0
            r1, r2, msg = self._replan(state, red, terms, res1.x, timer, times)
            if not msg:
                retry: dict[str, float] = {}
                qdd2, f2, tau2, why2 = self._assemble(state, red, r1, r2, retry)
                if not why2:
                    res1, res2, qdd, f, tau, why = r1, r2, qdd2, f2, tau2, ""
                    diag.update(retry)
            if why:
                # still not met: the whole tick by the full-model LQP (same priorities)
                t0 = time.perf_counter()
                hard, levels, final, G, gamma = self.full.hierarchy(state, terms)
                for lv in levels:
                    lv.name = f"fallback.{lv.name}"
                handles = self.full.pool.get(2 * (len(levels) + 1))
                fb = solve_hierarchy(
                    hard,
                    levels,
                    [final],
                    cfg.strategy,
                    handles,
                    timer,
                    prox=cfg.prox,
                    merge_finals=True,
                    slack_free_first=True,
                )
                times["fallback"] = time.perf_counter() - t0
                if not fb.ok:
                    msg = f"{why}; re-planning did not meet it and the full-model LQP failed: "
                    return failed_output(
                        n, k, nc, terms, timer.finish(), msg + fb.message, self.last_output
                    )
                extra["fallback"] = 1.0
                qdd, f, tau, why = fb.x[:n].copy(), fb.x[n:].copy(), G @ fb.x + gamma, ""
                # the residuals of the solution applied (the full model has no eq. 30)
                Jc = state.contact_jacobian(self.contacts)
                base = state.M[:6] @ qdd + state.h[:6] - Jc[:, :6].T @ f
                diag["base_residual"] = float(np.abs(base).max())
                diag["coupling_residual"] = float("nan")
                diag["wrench_residual"] = wrench_violation(self.Cw, self.lw, self.uw, f)
        if why:
            msg = f"{why}: eq. (30) cannot be met within the chains' torque and q̈ limits"
            return failed_output(n, k, nc, terms, timer.finish(), msg, self.last_output)
        diag.update(extra)
        if cfg.coupling_priority:
            # keys of the re-solve exist on every tick, so per-tick logs stay rectangular
            for key in ("w.lqp1.coupling", "v.lqp1.coupling", "w.lqp2.limits", "v.lqp2.limits"):
                diag.setdefault(key, float("nan"))
            diag.setdefault("coupling_violation", float("nan"))
        # the two LQPs' results when they produced this step (None when the full model did)
        self.last = None if extra["fallback"] else (res1, res2)

        timings = timer.finish()
        timings["reduced"] = red.time
        timings.update(times)
        self.part_stages(timings)
        self.last_output = ControlOutput(
            tau=tau,
            qdd=qdd,
            wrench=f.copy(),
            terms=terms,
            timings=timings,
            iterations=timer.iterations,
            diagnostics=diag,
        )
        return self.last_output

    @property
    def centroid_rows(self) -> slice:
        """Rows of q̈_r holding the chains' centroidal accelerations."""
        n_p = self.split.plain.size
        return slice(n_p, n_p + CENTROID_DIM * len(self.split.chains))
