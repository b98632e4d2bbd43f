"""Capsule and box distances with their Jacobians, for collision-avoidance inequalities.

The RQR-HQP paper (§IV-B, eq. 51–53) wraps the robot link by link in capsules ("sphere-capped
cylinders") and keeps every checked pair apart with a velocity-level inequality

    ḋ ≥ −ξ (d − d_safe),    ḋ = nᵀ (J_2 − J_1) q̇,

where d is the distance between the two surfaces (distance between the capsules' axes minus
their radii), P_1, P_2 the closest points, n = (P_2 − P_1)/‖P_2 − P_1‖ and J_i the world Jacobian
of the point P_i moving with its body. The same form keeps capsules away from fixed boxes (the
stress scenario's obstacles), with J_2 = 0.

Everything is vectorised over the pairs: one call per tick evaluates all of them. Capsules come
from the model's ``<body>_capsule`` geoms (MuJoCo's compiled pos / quat / size, so ``fromto``
capsules work too) and move with the Pinocchio frame of their body.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from wbcbench.dynamics.state import RobotState
from wbcbench.errors import UnknownNameError, WbcBenchError

Array = NDArray[np.float64]

CAPSULE_SUFFIX = "_capsule"
#: below this axis-to-axis distance [m] a pair counts as penetrating: its normal is undefined
_TOUCH = 1e-9


# --------------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Capsule:
    """A capsule fixed to a body: the segment ``p0``–``p1`` (body frame, [m]) swept by a ball.

    Attributes:
        body: body name (also the Pinocchio frame it moves with).
        frame_id: Pinocchio frame id of the body.
        p0, p1: axis end points in the body frame (3,) [m].
        radius: [m].
    """

    body: str
    frame_id: int
    p0: Array
    p1: Array
    radius: float


@dataclass(frozen=True)
class Box:
    """A fixed box obstacle.

    Attributes:
        name: label used in logs.
        center: world position (3,) [m].
        R: world rotation (3, 3) (columns: the box axes).
        half: half sizes along its axes (3,) [m].
    """

    name: str
    center: Array
    R: Array
    half: Array

    @classmethod
    def from_rpy(
        cls, name: str, pos: Sequence[float], size: Sequence[float], rpy: Sequence[float]
    ) -> Box:
        """A box from its centre, half sizes and roll-pitch-yaw angles [rad]."""
        R = pin.rpy.rpyToMatrix(*(float(a) for a in rpy))
        return cls(name, np.asarray(pos, dtype=float), np.asarray(R), np.asarray(size, float))


def robot_capsules(robot: object) -> dict[str, Capsule]:
    """Every ``<body>_capsule`` geom of the robot's MuJoCo model, keyed by body name."""
    m = robot.mj_model  # type: ignore[attr-defined]
    out: dict[str, Capsule] = {}
    for g in range(m.ngeom):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_CAPSULE or not name.endswith(CAPSULE_SUFFIX):
            continue
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
        # The body's own frame: a site of the same name (e.g. "head") would shadow it.
        fid = robot.pin_model.getFrameId(body, pin.FrameType.BODY)  # type: ignore[attr-defined]
        if fid >= robot.pin_model.nframes:  # type: ignore[attr-defined]
            continue
        R = np.empty(9)
        mujoco.mju_quat2Mat(R, m.geom_quat[g])
        axis = R.reshape(3, 3)[:, 2] * float(m.geom_size[g][1])
        center = np.asarray(m.geom_pos[g], dtype=float)
        out[body] = Capsule(
            body,
            int(fid),
            center - axis,
            center + axis,
            float(m.geom_size[g][0]),
        )
    return out


def closest_segment_segment(a0: Array, a1: Array, b0: Array, b1: Array) -> tuple[Array, Array]:
    """Closest points between segments ``a0a1`` and ``b0b1``, vectorised over P pairs.

    Args:
        a0, a1, b0, b1: end points (P, 3) [m].

    Returns:
        The point on each segment (P, 3), (P, 3). Parallel segments get one of the closest pairs.
    """
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    tiny = 1e-15
    a_s, e_s = np.maximum(a, tiny), np.maximum(e, tiny)
    denom = a * e - b * b
    # s on segment A for the infinite lines (0 when parallel), then t, then re-clamp s
    # (Ericson, Real-Time Collision Detection, §5.1.9).
    general = denom > 1e-12 * a_s * e_s
    s = np.where(general, np.clip((b * f - c * e) / np.where(general, denom, 1.0), 0, 1), 0.0)
    t = (b * s + f) / e_s
    s = np.where(t < 0, np.clip(-c / a_s, 0, 1), np.where(t > 1, np.clip((b - c) / a_s, 0, 1), s))
    t = np.clip(t, 0, 1)
    # Degenerate segments (points) have parameter 0.
    point_b = e <= tiny
    s = np.where(point_b, np.clip(-c / a_s, 0, 1), s)
    t = np.where(point_b, 0.0, t)
    point_a = a <= tiny
    s = np.where(point_a, 0.0, s)
    t = np.where(point_a & ~point_b, np.clip(f / e_s, 0, 1), t)
    return a0 + s[:, None] * d1, b0 + t[:, None] * d2


def closest_segment_box(
    a0: Array, a1: Array, center: Array, R: Array, half: Array
) -> tuple[Array, Array]:
    """Closest points between segments and oriented boxes, vectorised over P pairs.

    The squared distance from ``x(t) = a0 + t (a1 − a0)`` to a box is convex and piecewise
    quadratic in t, with breaks where x(t) crosses a face plane; minimising each piece in closed
    form and keeping the best gives the exact closest points.

    Args:
        a0, a1: segment end points (P, 3) [m].
        center: box centres (P, 3); R: box rotations (P, 3, 3); half: half sizes (P, 3).

    Returns:
        The point on the segment and the point of the box (P, 3), (P, 3), world frame. A segment
        that passes through a box gets a point inside it for both.
    """
    a = np.einsum("pji,pj->pi", R, a0 - center)  # box-frame coordinates
    D = np.einsum("pji,pj->pi", R, a1 - a0)
    P = a.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        breaks = np.concatenate([(half - a) / D, (-half - a) / D], axis=1)
    breaks = np.where(np.isfinite(breaks), np.clip(breaks, 0.0, 1.0), 0.0)
    ts = np.sort(np.concatenate([np.zeros((P, 1)), breaks, np.ones((P, 1))], axis=1), axis=1)
    lo, hi = ts[:, :-1], ts[:, 1:]  # (P, 7) pieces
    mid = 0.5 * (lo + hi)
    xm = a[:, None, :] + mid[..., None] * D[:, None, :]  # (P, 7, 3)
    h = half[:, None, :]
    # On a piece each coordinate stays above, below or inside its slab: clamp target c_i.
    above, below = xm > h, xm < -h
    active = above | below
    c = np.where(above, h, -h)
    Dp = np.broadcast_to(D[:, None, :], xm.shape)
    off = a[:, None, :] - c
    num = np.sum(np.where(active, Dp * off, 0.0), axis=2)
    den = np.sum(np.where(active, Dp * Dp, 0.0), axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        tstar = np.where(den > 1e-300, -num / den, mid)
    tstar = np.clip(tstar, lo, hi)
    x = a[:, None, :] + tstar[..., None] * D[:, None, :]
    gap = x - np.clip(x, -h, h)
    best = np.argmin(np.einsum("pki,pki->pk", gap, gap), axis=1)
    t = tstar[np.arange(P), best]
    xs = a + t[:, None] * D
    xb = np.clip(xs, -half, half)
    pa = a0 + t[:, None] * (a1 - a0)
    pb = center + np.einsum("pij,pj->pi", R, xb)
    return pa, pb


# --------------------------------------------------------------------------------------------
# Pairs on a robot
# --------------------------------------------------------------------------------------------


def joint_path_length(model: pin.Model, frame_a: int, frame_b: int) -> int:
    """Number of joints on the kinematic-tree path between the bodies of two frames."""
    ja, jb = model.frames[frame_a].parentJoint, model.frames[frame_b].parentJoint

    def chain(j: int) -> list[int]:
        out = [j]
        while j > 0:
            j = model.parents[j]
            out.append(j)
        return out

    ca, cb = chain(ja), chain(jb)
    common = set(ca) & set(cb)
    return next(i for i, j in enumerate(ca) if j in common) + next(
        i for i, j in enumerate(cb) if j in common
    )


@dataclass
class CollisionTerms:
    """Distances of every checked pair at one state and their gradients.

    Attributes:
        names: ``"a|b"`` per pair (P,).
        d: surface distances (P,) [m] (negative: penetration).
        grad: ∂d/∂q in velocity coordinates, so ḋ = grad q̇ (P, n).
        points: closest points (P, 2, 3) [m], world frame.
    """

    names: list[str]
    d: Array
    grad: Array
    points: Array

    @property
    def min_distance(self) -> float:
        return float(self.d.min()) if self.d.size else float("inf")


class CollisionModel:
    """Capsule–capsule (self) and capsule–box (obstacle) pairs evaluated together.

    Args:
        robot: the loaded robot (its ``<body>_capsule`` geoms are the capsules).
        self_pairs: body-name pairs checked against each other.
        obstacle_bodies: bodies whose capsules are checked against every obstacle.
        obstacles: fixed boxes.
        min_joints: pairs whose bodies are this many joints apart or fewer are rejected (they
            touch by construction or cannot move apart).

    Raises:
        UnknownNameError: a body has no capsule.
        WbcBenchError: a pair of bodies too close in the tree.
    """

    def __init__(
        self,
        robot: object,
        self_pairs: Sequence[tuple[str, str]] = (),
        obstacle_bodies: Sequence[str] = (),
        obstacles: Sequence[Box] = (),
        min_joints: int = 2,
    ) -> None:
        caps = robot_capsules(robot)
        model: pin.Model = robot.pin_model  # type: ignore[attr-defined]

        def capsule(body: str) -> Capsule:
            if body not in caps:
                raise UnknownNameError("capsule body", body, sorted(caps))
            return caps[body]

        for a, b in self_pairs:
            dist = joint_path_length(model, capsule(a).frame_id, capsule(b).frame_id)
            if dist <= min_joints:
                raise WbcBenchError(
                    f"collision pair ({a}, {b}): the bodies are {dist} joint(s) apart; pairs "
                    f"within {min_joints} joints of each other are not checked"
                )
        self.bodies: list[Capsule] = []
        index: dict[str, int] = {}
        for body in [x for pair in self_pairs for x in pair] + list(obstacle_bodies):
            if body not in index:
                index[body] = len(self.bodies)
                self.bodies.append(capsule(body))
        pairs = [(index[a], index[b]) for a, b in self_pairs]
        self.n_self = len(pairs)
        self._ia = np.array([p[0] for p in pairs], dtype=int)
        self._ib = np.array([p[1] for p in pairs], dtype=int)
        ob = [(index[body], k) for body in obstacle_bodies for k in range(len(obstacles))]
        self._oc = np.array([p[0] for p in ob], dtype=int)
        self._ok = np.array([p[1] for p in ob], dtype=int)
        self.obstacles = list(obstacles)
        self.names = [f"{a}|{b}" for a, b in self_pairs] + [
            f"{self.bodies[c].body}|{obstacles[k].name}" for c, k in ob
        ]
        self._p0 = np.array([c.p0 for c in self.bodies]).reshape(-1, 3)
        self._p1 = np.array([c.p1 for c in self.bodies]).reshape(-1, 3)
        self._r = np.array([c.radius for c in self.bodies])
        self._box_c = np.array([o.center for o in obstacles]).reshape(-1, 3)
        self._box_R = np.array([o.R for o in obstacles]).reshape(-1, 3, 3)
        self._box_h = np.array([o.half for o in obstacles]).reshape(-1, 3)

    @property
    def n_pairs(self) -> int:
        return len(self.names)

    @property
    def index_pairs(self) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
        """The pairs by index, in the order :meth:`evaluate` lists them: self pairs as
        (capsule, capsule) and obstacle pairs as (capsule, box), indices into :attr:`bodies`
        and :attr:`obstacles`."""
        self_pairs = [(int(a), int(b)) for a, b in zip(self._ia, self._ib, strict=True)]
        obstacle_pairs = [(int(c), int(k)) for c, k in zip(self._oc, self._ok, strict=True)]
        return self_pairs, obstacle_pairs

    def evaluate(self, state: RobotState) -> CollisionTerms:
        """Distances and gradients of all pairs at ``state`` (P = self + obstacle pairs)."""
        n = state.n
        P = self.n_pairs
        if P == 0:
            return CollisionTerms([], np.zeros(0), np.zeros((0, n)), np.zeros((0, 2, 3)))
        nb = len(self.bodies)
        org = np.empty((nb, 3))
        rot = np.empty((nb, 3, 3))
        J = np.empty((nb, 6, n))
        for i, cap in enumerate(self.bodies):  # one cached Pinocchio lookup per body
            M = state.placement(cap.frame_id)
            org[i], rot[i] = M.translation, M.rotation
            J[i] = state.jacobian(cap.frame_id)
        w0 = org + np.einsum("bij,bj->bi", rot, self._p0)
        w1 = org + np.einsum("bij,bj->bi", rot, self._p1)

        ia, ib, oc, ok = self._ia, self._ib, self._oc, self._ok
        pa_s, pb_s = closest_segment_segment(w0[ia], w1[ia], w0[ib], w1[ib])
        pa_o, pb_o = closest_segment_box(
            w0[oc], w1[oc], self._box_c[ok], self._box_R[ok], self._box_h[ok]
        )
        pa = np.vstack([pa_s, pa_o])
        pb = np.vstack([pb_s, pb_o])
        radii = np.concatenate([self._r[ia] + self._r[ib], self._r[oc]])
        diff = pb - pa
        axis_dist = np.linalg.norm(diff, axis=1)
        touching = axis_dist < _TOUCH
        normal = diff / np.where(touching, 1.0, axis_dist)[:, None]
        normal[touching] = 0.0  # penetrating pairs: no direction to move apart along

        def point_rows(body: NDArray[np.intp], p: Array, nrm: Array) -> Array:
            # nᵀ J_p with J_p = J_v − [p − o]× J_ω:  nᵀ J_v + ((p − o) × n)ᵀ J_ω
            lever = np.cross(p - org[body], nrm)
            return np.einsum("pi,pij->pj", nrm, J[body, :3]) + np.einsum(
                "pi,pij->pj", lever, J[body, 3:]
            )

        first = np.concatenate([ia, oc])
        grad = -point_rows(first, pa, normal)
        ns = self.n_self
        grad[:ns] += point_rows(ib, pb[:ns], normal[:ns])
        return CollisionTerms(list(self.names), axis_dist - radii, grad, np.stack([pa, pb], axis=1))
