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

Timings (Table 3): ``reduced`` (the reduced-dynamics calculation), ``lqp1``, ``lqp2`` (each
formulation + solve), ``solve.lqp1`` / ``solve.lqp2`` (solver only) and per level
``solve.lqp1.<level>``. Diagnostics: ``coupling_residual`` (eq. 30), ``base_residual``
(floating-base rows of the full dynamics at the combined solution), ``assembly_diff``
(max |Γ_exact − Γ_paper| [N·m]) and each level's optimal slacks.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from wbcbench.controllers.base import (
    Controller,
    ControllerConfig,
    ControllerContext,
    ControlOutput,
    StageTimer,
)
from wbcbench.controllers.lqp import (
    LexicographicConfig,
    SolverPool,
    energy_objective,
    failed_output,
    level_weight,
    slack_diagnostics,
    task_levels,
)
from wbcbench.dynamics.chains import CENTROID_DIM, split_chains
from wbcbench.dynamics.dense import spd_factor, tri_solve
from wbcbench.dynamics.reduced import ReducedDynamics, ReducedModel
from wbcbench.dynamics.state import RobotState
from wbcbench.qp.hierarchy import (
    Constraints,
    HierarchyResult,
    Objective,
    PriorityLevel,
    solve_hierarchy,
)
from wbcbench.tasks.contacts import stack_wrench_constraints
from wbcbench.tasks.tasks import TaskTerm


class RcLqpConfig(LexicographicConfig):
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
        1e-6, gt=0, description="coupling_priority: eq. (30) violation that triggers re-solving"
    )


#: Tikhonov damping of the preview's least squares, relative to the largest squared singular
#: value of each priority's rows
PREVIEW_DAMPING = 1e-8
#: singular values below this fraction of the largest count as zero in the preview (their
#: directions are left to the priorities below)
PREVIEW_RANK_TOL = 1e-6


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
class _RowSplit:
    """Which rows of each task LQP 1 handles (reducible) and which LQP 2 does."""

    lqp1: dict[str, np.ndarray]
    lqp2: dict[str, np.ndarray]
    #: the highest priority with rows in LQP 2 (where LQP 1's preview level goes), 0 if none
    chain_priority: int


class RcLqp(Controller):
    """Reduced-centroidal LQP: LQP 1 on the reduced model, LQP 2 on the unconstrained chains."""

    name = "rc_lqp"
    summary = (
        "reduced-centroidal LQP (RC-LQP): arms/neck/swing leg collapsed into centroidal "
        "dynamics, two sequential lexicographic QPs, exact or paper torque assembly"
    )
    Config = RcLqpConfig
    reference_solvers = ("quadprog",)
    config: RcLqpConfig

    def __init__(self, ctx: ControllerContext, config: ControllerConfig | None = None) -> None:
        super().__init__(ctx, config)
        self.frames = ctx.contact_frames
        self.split = split_chains(ctx.robot.pin_model, self.frames)
        self.reduced = ReducedDynamics(ctx.robot.pin_model, self.split)
        self.Cw, self.lw, self.uw = stack_wrench_constraints(ctx.contacts)
        self.nc = 6 * len(self.frames)
        self.pool1 = SolverPool(ctx)
        self.pool2 = SolverPool(ctx)
        self.pool1b = SolverPool(ctx)
        self.pool2b = SolverPool(ctx)
        self._rows: _RowSplit | None = None
        self.last: tuple[HierarchyResult, HierarchyResult | None] | None = None
        self.last_reduced: ReducedModel | None = None
        self.last_output: ControlOutput | None = None
        # actuated indices (into Γ) of the plain coordinates and of the chains
        self._act_plain = self.split.plain[6:] - 6
        self._act_uc = self.split.unconstrained - 6

    # -- task rows ------------------------------------------------------------------------------

    def _classify(self, red: ReducedModel, terms: list[TaskTerm]) -> _RowSplit:
        """Rows with J N_r = 0 go to LQP 1, the others to LQP 2 (decided once: structural)."""
        lqp1, lqp2 = {}, {}
        for term in terms:
            mask = red.reducible_rows(term.J)
            lqp1[term.task.name] = np.flatnonzero(mask)
            lqp2[term.task.name] = np.flatnonzero(~mask)
        chain = [t.task.priority for t in terms if lqp2[t.task.name].size]
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
        dJc = state.contact_drift(self.frames)
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
                A=np.hstack([red.J_cr, np.zeros((nc, nc))]),
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

    def step(self, state: RobotState, t: float) -> ControlOutput:
        timer = StageTimer(state)
        cfg = self.config
        split = self.split
        n, k, nc = state.n, state.k, self.nc
        n_r, plain, uc = split.n_reduced, split.plain, split.unconstrained
        n_p = plain.size
        terms = self.evaluate_tasks(state, t)
        red = self.reduced.compute(state, fixed_base=cfg.assembly == "paper" or cfg.diagnostics)
        self.last_reduced = red
        if self._rows is None:
            self._rows = self._classify(red, terms)

        t1 = time.perf_counter()
        # the chains' centroidal accelerations: a level of LQP 1 (priority) or its energy's target
        preview = level = target = None
        if cfg.centroid_preview != "off" and uc.size:
            preview = self.preview(state, red, terms)
        if cfg.centroid_preview == "priority":
            level = preview
        else:
            target = preview
        hard1, levels1, G1, gamma1 = self.lqp1_levels(state, red, terms, level)
        res1 = self.solve_lqp1(red, hard1, levels1, target, self.pool1, timer)
        t_lqp1 = time.perf_counter() - t1
        if not res1.ok:
            return failed_output(
                n, k, nc, terms, timer.finish(), "LQP 1: " + res1.message, self.last_output
            )
        x1 = res1.x

        res2: HierarchyResult | None = None
        t_lqp2 = 0.0
        extra: dict[str, float] = {}
        if uc.size:
            t2 = time.perf_counter()
            levels2, _, _ = self.lqp2_levels(state, red, terms, x1, cfg.coupling_priority)
            res2 = self.solve_lqp2(state, red, levels2, x1, self.pool2, timer)
            t_lqp2 += time.perf_counter() - t2
            if res2.ok and cfg.coupling_priority:
                w = res2.levels[len(levels2) - 1].w  # eq. (30)'s violation (the last level)
                extra["coupling_violation"] = float(np.linalg.norm(w))
                if np.linalg.norm(w) > cfg.coupling_tol:
                    # LQP 1 again, the centroidal acceleration LQP 2 reached as an extra priority
                    t1 = time.perf_counter()
                    reached = x1[n_p:n_r] + w
                    sel = np.zeros((n_r - n_p, n_r + nc))
                    sel[:, n_p:n_r] = np.eye(n_r - n_p)
                    hard1, levels1b, G1, gamma1 = self.lqp1_levels(state, red, terms, level)
                    levels1b.append(PriorityLevel("coupling", A=sel, b=reached))
                    res1 = self.solve_lqp1(red, hard1, levels1b, target, self.pool1b, timer)
                    t_lqp1 += time.perf_counter() - t1
                    if not res1.ok:
                        msg = "LQP 1 (coupling): " + res1.message
                        return failed_output(n, k, nc, terms, timer.finish(), msg, self.last_output)
                    x1 = res1.x
                    t2 = time.perf_counter()
                    levels2, _, _ = self.lqp2_levels(state, red, terms, x1, False)
                    res2 = self.solve_lqp2(state, red, levels2, x1, self.pool2b, timer)
                    t_lqp2 += time.perf_counter() - t2
            if not res2.ok:
                return failed_output(
                    n, k, nc, terms, timer.finish(), "LQP 2: " + res2.message, self.last_output
                )

        # combined solution
        qdd = np.zeros(n)
        qdd[plain] = x1[:n_p]
        f = x1[n_r:]
        if res2 is not None:
            qdd[uc] = res2.x
        Jc = state.contact_jacobian(self.frames)
        # the full inverse dynamics at (q̈, f): actuated rows for Γ, base rows as a check
        full = state.M @ qdd + state.h - Jc.T @ f
        tau = full[6:]
        diag: dict[str, float] = {}
        if cfg.assembly == "paper" or cfg.diagnostics:
            tau_paper = np.empty(k)
            tau_paper[self._act_plain] = G1 @ x1 + gamma1
            if uc.size:
                tau_paper[self._act_uc] = red.M_uc @ qdd[uc] + red.b_uc + red.g_uc
            diag["assembly_diff"] = float(np.abs(tau - tau_paper).max())
            if cfg.assembly == "paper":
                tau = tau_paper
        diag["base_residual"] = float(np.abs(full[:6]).max())
        if uc.size:
            realized = red.J_G @ qdd[uc] + red.dJG_v
            diag["coupling_residual"] = float(np.abs(realized - x1[n_p:n_r]).max())
        diag.update(slack_diagnostics(res1))
        if res2 is not None:
            diag.update(slack_diagnostics(res2))
        diag.update(extra)
        diag["prox_retries"] = float(res1.retries + (res2.retries if res2 is not None else 0))
        if cfg.coupling_priority:
            # keys of the re-solve exist on every tick, so per-tick logs stay rectangular
            for key in ("w.lqp1.coupling", "v.lqp1.coupling", "w.lqp2.limits", "v.lqp2.limits"):
                diag.setdefault(key, float("nan"))
            diag.setdefault("coupling_violation", float("nan"))
        self.last = (res1, res2)

        timings = timer.finish()
        timings["reduced"] = red.time
        timings["lqp1"] = t_lqp1
        timings["lqp2"] = t_lqp2
        if cfg.coupling_priority:
            timings.setdefault("solve.lqp1.coupling", 0.0)
        for part in ("lqp1", "lqp2"):
            keys = [key for key in timings if key.startswith(f"solve.{part}.")]
            timings[f"solve.{part}"] = sum(timings[key] for key in keys)
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
