"""Small generated QPs for tests and benchmarks (deterministic for a given seed).

Every generator builds the problem around a known feasible point, so feasibility holds by
construction; the optimum itself is computed by the solvers.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from wbcbench.qp.problem import Problem


def random_qp(
    seed: int,
    n: int = 10,
    n_eq: int = 3,
    n_in: int = 6,
    box: bool = True,
    inf_fraction: float = 0.25,
) -> Problem:
    """A random strictly convex feasible QP with equalities, two-sided rows and bounds.

    Args:
        seed: random seed.
        n, n_eq, n_in: sizes.
        box: add variable bounds (a fraction of them infinite).
        inf_fraction: fraction of the bound sides set to ``±inf``.
    """
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    H = M @ M.T / n + 0.1 * np.eye(n)
    g = rng.standard_normal(n)
    x_f = rng.standard_normal(n)
    A = rng.standard_normal((n_eq, n))
    b = A @ x_f
    C = rng.standard_normal((n_in, n))
    Cx = C @ x_f
    # Tight slacks so that some rows are active at the optimum.
    l = Cx - rng.uniform(0.0, 0.5, n_in)  # noqa: E741
    u = Cx + rng.uniform(0.0, 0.5, n_in)
    l[rng.random(n_in) < inf_fraction] = -np.inf
    u[rng.random(n_in) < inf_fraction] = np.inf
    lb = ub = None
    if box:
        lb = x_f - rng.uniform(0.0, 0.5, n)
        ub = x_f + rng.uniform(0.0, 0.5, n)
        lb[rng.random(n) < inf_fraction] = -np.inf
        ub[rng.random(n) < inf_fraction] = np.inf
    return Problem(
        H=H,
        g=g,
        A=A,
        b=b,
        C=C,
        l=l,
        u=u,
        lb=lb,
        ub=ub,
        name=f"random_qp/{seed}",
        meta={"generator": "random_qp", "seed": seed},
    )


def infeasible_qp(n: int = 4) -> Problem:
    """A QP whose equality ``Σx = 1`` contradicts its bounds ``x ≤ 0``."""
    return Problem(
        H=np.eye(n),
        g=np.zeros(n),
        A=np.ones((1, n)),
        b=np.array([1.0]),
        C=np.eye(n)[:2],
        l=np.full(2, -1.0),
        u=np.full(2, 1.0),
        lb=np.full(n, -1.0),
        ub=np.zeros(n),
        name="infeasible_qp",
    )


class _DriftingRng:
    """Random draws ``base + t · perturbation`` from two seeded streams (masks do not drift)."""

    def __init__(self, seed: int, t: float) -> None:
        self._base = np.random.default_rng(seed)
        self._pert = np.random.default_rng(seed + 7919)
        self._t = t

    def standard_normal(self, size: Any) -> np.ndarray:
        return self._base.standard_normal(size) + self._t * self._pert.standard_normal(size)

    def uniform(self, low: float, high: float, size: Any) -> np.ndarray:
        # Both terms lie in [low, high]; t ≥ 0 keeps the sum ≥ low.
        return self._base.uniform(low, high, size) + self._t * self._pert.uniform(low, high, size)

    def random(self, size: Any) -> np.ndarray:
        self._pert.random(size)  # keep the streams aligned
        return self._base.random(size)


def wbc_like_qp(seed: int = 0, t: float = 0.0) -> Problem:
    """A dense whole-body-control-like QP: 70 variables, 45 equalities, 60 inequalities.

    ``t ≥ 0`` drifts every matrix and vector smoothly from the ``t = 0`` problem while keeping
    the structure (sizes and which bounds are infinite) and feasibility: consecutive values such
    as ``t = k · 1e-3`` mimic consecutive control ticks (see :func:`wbc_like_sequence`).

    Variables ``x = (q̈, f, τ)`` with ``q̈`` ``(32,)`` [rad/s²], contact wrenches ``f``
    ``(12,)`` [N, N·m] for two feet and joint torques ``τ`` ``(26,)`` [N·m]. Equalities: the
    floating-base dynamics ``M q̈ − J_cᵀ f − Sᵀ τ = −h`` (32 rows), stationary contacts
    ``J_c q̈ = −J̇_c q̇`` (12 rows) and one extra task held exactly (1 row). Cost: 24 rows of
    weighted task accelerations on ``q̈`` and a small wrench regularisation, none on ``τ``, so
    ``H`` is PSD with rank 36 < 70 (not PD); the optimum is still unique because ``H`` is
    definite on the null space of the equalities (reduced condition number ~3e7).
    Inequalities: per foot a linearised friction pyramid (4 rows), a minimum normal force (1)
    and a centre-of-pressure box (4), one-sided; 42 two-sided joint-acceleration limits, some
    infinite. Bounds: torque limits on ``τ``, none on ``f``, some on ``q̈``.
    """
    rng = _DriftingRng(seed, t)
    nv, nf, nt = 32, 12, 26
    n = nv + nf + nt
    L = rng.standard_normal((nv, nv)) * 0.3
    M = L @ L.T + np.diag(rng.uniform(0.05, 2.0, nv))  # inertia-like, SPD [kg·m²]
    Jc = rng.standard_normal((nf, nv))
    S = np.zeros((nt, nv))
    S[:, nv - nt :] = np.eye(nt)

    # A feasible point first: torques within limits, a positive normal force on each foot.
    qdd_f = rng.standard_normal(nv) * 0.5
    f_f = rng.standard_normal(nf) * 10.0
    f_f[[2, 8]] = 350.0  # normal forces [N]
    tau_f = rng.standard_normal(nt) * 20.0
    h = -(M @ qdd_f - Jc.T @ f_f - S.T @ tau_f)

    A = np.zeros((45, n))
    A[:nv, :nv] = M
    A[:nv, nv : nv + nf] = -Jc.T
    A[:nv, nv + nf :] = -S.T
    A[nv : nv + nf, :nv] = Jc
    A[-1, :nv] = rng.standard_normal(nv)
    x_f = np.concatenate([qdd_f, f_f, tau_f])
    b = A @ x_f
    b[:nv] = -h

    J = rng.standard_normal((24, nv))
    w = np.repeat([1e3, 1e2, 1e1, 1.0], 6)  # soft priorities
    Hq = J.T @ (w[:, None] * J)
    a_ref = J @ qdd_f + rng.standard_normal(24)
    H = np.zeros((n, n))
    H[:nv, :nv] = Hq
    H[nv : nv + nf, nv : nv + nf] = 1e-2 * np.eye(nf)
    g = np.zeros(n)
    g[:nv] = -J.T @ (w * a_ref)

    mu, hx, hy, f_min = 0.7, 0.1, 0.05, 10.0
    rows, lo, hi = [], [], []
    for k in range(2):
        o = nv + 6 * k  # (fx, fy, fz, mx, my, mz)
        for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            r = np.zeros(n)
            r[o] = sx
            r[o + 1] = sy
            r[o + 2] = -mu
            rows.append(r)
            lo.append(-np.inf)
            hi.append(0.0)
        r = np.zeros(n)
        r[o + 2] = -1.0
        rows.append(r)
        lo.append(-np.inf)
        hi.append(-f_min)
        for axis, half in ((3, hy), (4, hx)):
            for sign in (1.0, -1.0):
                r = np.zeros(n)
                r[o + axis] = sign
                r[o + 2] = -half
                rows.append(r)
                lo.append(-np.inf)
                hi.append(0.0)
    C_contact = np.array(rows)
    # Wrench regularisation may push a component to the friction limit: move the feasible
    # point's contact rows inside by construction (slack added to the upper side).
    hi_c = np.maximum(np.array(hi), C_contact @ x_f + 1.0)
    C_acc = np.zeros((42, n))
    C_acc[:, :nv] = rng.standard_normal((42, nv))
    acc = C_acc @ x_f
    lo_acc = acc - rng.uniform(0.05, 2.0, 42)
    hi_acc = acc + rng.uniform(0.05, 2.0, 42)
    lo_acc[rng.random(42) < 0.2] = -np.inf
    hi_acc[rng.random(42) < 0.2] = np.inf
    C = np.vstack([C_contact, C_acc])
    l = np.concatenate([np.array(lo), lo_acc])  # noqa: E741
    u = np.concatenate([hi_c, hi_acc])

    lb = np.full(n, -np.inf)
    ub = np.full(n, np.inf)
    lb[:nv:3] = qdd_f[::3] - 3.0
    ub[:nv:3] = qdd_f[::3] + 3.0
    tau_max = np.abs(tau_f) + rng.uniform(1.0, 15.0, nt)
    lb[nv + nf :] = -tau_max
    ub[nv + nf :] = tau_max
    return Problem(
        H=H,
        g=g,
        A=A,
        b=b,
        C=C,
        l=l,
        u=u,
        lb=lb,
        ub=ub,
        name=f"wbc_like/{seed}" + (f"/t={t:g}" if t else ""),
        meta={"generator": "wbc_like_qp", "seed": seed, "t": t},
    )


def wbc_like_sequence(length: int, seed: int = 0, step: float = 1e-3) -> list[Problem]:
    """``length`` consecutive "ticks" ``wbc_like_qp(seed, t=k·step)``: same structure, drifting
    data, as a controller level sees them in a timing run."""
    return [wbc_like_qp(seed, t=k * step) for k in range(length)]
