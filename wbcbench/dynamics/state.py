"""RobotState: every dynamics quantity a controller needs, computed once per control tick.

Conventions (the whole project uses them):

* Pinocchio configuration ``q`` (nq = 7 + k) and velocity ``v`` (n = 6 + k); the base linear
  velocity ``v[0:3]`` is expressed in the base frame.
* Contact wrenches are the **reaction on the robot**: ``M q̈ + h = Sᵀ Γ + J_cᵀ f``. The papers
  write ``A q̈ + h + J_cᵀ F_c = Sᵀ Γ`` with ``F_c = −f`` (the wrench the robot exerts); convert
  only where paper numbers are compared.
* Task Jacobians of frames are expressed in LOCAL_WORLD_ALIGNED (world axes at the frame
  origin), so ``J q̈ + J̇ q̇`` is the world-frame linear acceleration of the point and the
  world-frame angular acceleration.
* Contact Jacobians are expressed in the contact frame (LOCAL), and their drift ``J̇ q̇`` is the
  frame's spatial acceleration at zero ``q̈``: a contact holds when that 6-vector is zero.

Quantities are computed lazily and cached; the time spent in Pinocchio is accumulated in
``RobotState.compute_time`` so controllers can report a ``dynamics`` stage separately from
formulating and solving their QPs.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import pinocchio as pin

from wbcbench.dynamics.dense import skew, symmetric_from_upper

if TYPE_CHECKING:
    from wbcbench.robots.loader import Robot

LOCAL = pin.ReferenceFrame.LOCAL
LOCAL_WORLD_ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class ContactLike(Protocol):
    """A contact as the state reads it: its frame and, for a point set, its points (N, 3) in
    the frame (None: a flat 6-D contact)."""

    frame: str
    points: tuple[tuple[float, float, float], ...] | None


def point_velocity_map(points: Sequence[Sequence[float]]) -> np.ndarray:
    """Gᵀ (3N, 6): the points' velocities [v_p] of the frame's [v; ω], v_p = v + ω × p =
    [I, −[p]×] [v; ω] (its transpose maps point forces to the frame's wrench)."""
    return np.vstack([np.hstack([np.eye(3), -skew(np.asarray(p, dtype=float))]) for p in points])


@functools.lru_cache(maxsize=64)
def contact_basis(points: tuple[tuple[float, float, float], ...]) -> np.ndarray:
    """T (r, 3N): an orthonormal basis of range(Gᵀ) (r = 3 for one point, 5 for a line, 6 for
    a polygon), from the SVD; the rank counts singular values above 1e-9 of the largest."""
    u, s, _ = np.linalg.svd(point_velocity_map(points), full_matrices=False)
    r = int((s > 1e-9 * s[0]).sum())
    return u[:, :r].T.copy()


def contact_selector(contacts: Sequence[str | ContactLike]) -> np.ndarray | None:
    """The block-diagonal map (r, Σ dim) from the contacts' stacked rows to their independent
    ones (identity blocks for flat contacts, :func:`contact_basis` for point sets); None when
    every contact is flat."""
    point_sets = [None if isinstance(c, str) else c.points for c in contacts]
    if all(p is None for p in point_sets):
        return None
    blocks = [np.eye(6) if p is None else contact_basis(tuple(map(tuple, p))) for p in point_sets]
    T = np.zeros((sum(b.shape[0] for b in blocks), sum(b.shape[1] for b in blocks)))
    r = c = 0
    for b in blocks:
        T[r : r + b.shape[0], c : c + b.shape[1]] = b
        r, c = r + b.shape[0], c + b.shape[1]
    return T


def _contact_key(c: str | ContactLike) -> object:
    return c if isinstance(c, str) else (c.frame, c.points)


def _symmetrize_upper(a: np.ndarray) -> np.ndarray:
    """Pinocchio fills only the upper triangle of M and M⁻¹."""
    return symmetric_from_upper(a)


@dataclass
class RobotState:
    """Dynamics of one robot at one (q, v), computed on demand and cached.

    Build one per control tick with :meth:`from_pin` (or :meth:`from_mujoco`); never reuse it for
    another state. Every array returned is owned by the state (do not modify it in place).
    """

    robot: Robot
    q: np.ndarray
    v: np.ndarray
    data_buffer: pin.Data | None = field(default=None, repr=False)
    compute_time: float = 0.0
    _data: pin.Data = field(init=False, repr=False)
    _cache: dict[object, np.ndarray] = field(init=False, repr=False, default_factory=dict)
    _terms_done: bool = field(init=False, default=False, repr=False)
    _drift_done: bool = field(init=False, default=False, repr=False)
    _subtree_inertias_valid: bool = field(init=False, default=True, repr=False)

    def __post_init__(self) -> None:
        self.q = np.ascontiguousarray(self.q, dtype=float)
        self.v = np.ascontiguousarray(self.v, dtype=float)
        # A runner may lend one Data for the whole run (allocating one costs tens of µs);
        # states that live side by side (tests, oracles) each get their own.
        self._data = self.data_buffer if self.data_buffer is not None else self.model.createData()

    # -- construction -------------------------------------------------------------------------

    @classmethod
    def from_pin(
        cls, robot: Robot, q: np.ndarray, v: np.ndarray, data: pin.Data | None = None
    ) -> RobotState:
        return cls(robot, q, v, data)

    @classmethod
    def from_mujoco(
        cls, robot: Robot, qpos: np.ndarray, qvel: np.ndarray, data: pin.Data | None = None
    ) -> RobotState:
        from wbcbench.robots.convert import mj_to_pin

        q, v = mj_to_pin(robot, qpos, qvel)
        return cls(robot, q, v, data)

    # -- sizes --------------------------------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of generalized velocities (6 + k)."""
        return int(self.robot.nv)

    @property
    def k(self) -> int:
        """Number of actuated joints."""
        return int(self.robot.k)

    @property
    def model(self) -> pin.Model:
        return self.robot.pin_model

    @property
    def data(self) -> pin.Data:
        """Pinocchio data after :meth:`_terms` (and drift passes when they were requested)."""
        self._terms()
        return self._data

    # -- the Pinocchio passes -----------------------------------------------------------------

    def _terms(self) -> None:
        """One pass: kinematics, M, nonlinear effects, gravity, Jacobians, CoM, CMM."""
        if self._terms_done:
            return
        t0 = time.perf_counter()
        pin.computeAllTerms(self.model, self._data, self.q, self.v)
        pin.updateFramePlacements(self.model, self._data)
        self._terms_done = True
        self.compute_time += time.perf_counter() - t0

    def _drifts(self) -> None:
        """Second-order kinematics at zero q̈: the J̇ q̇ of every frame and of the CoM."""
        if self._drift_done:
            return
        self._terms()
        t0 = time.perf_counter()
        a0 = np.zeros(self.n)
        # centerOfMass with an acceleration runs second-order forward kinematics (data.a) and
        # gives the CoM acceleration at zero q̈ in one pass.
        pin.centerOfMass(self.model, self._data, self.q, self.v, a0, False)
        self._drift_done = True
        self.compute_time += time.perf_counter() - t0

    def _cached(self, key: object, compute: object) -> np.ndarray:
        value = self._cache.get(key)
        if value is None:
            t0 = time.perf_counter()
            value = compute()  # type: ignore[operator]
            self.compute_time += time.perf_counter() - t0
            self._cache[key] = value
        return value

    # -- joint-space dynamics -----------------------------------------------------------------

    @property
    def M(self) -> np.ndarray:
        """Joint-space inertia matrix (n, n), armature included."""
        self._terms()
        return self._cached("M", lambda: _symmetrize_upper(self._data.M))

    @property
    def Minv(self) -> np.ndarray:
        """Inverse inertia matrix (n, n), from Pinocchio's ABA-based routine."""
        self._terms()

        def compute() -> np.ndarray:
            pin.computeMinverse(self.model, self._data, self.q)
            # (it reuses data.oYcrb as its own workspace: see subtree_inertias)
            self._subtree_inertias_valid = False
            return _symmetrize_upper(self._data.Minv)

        return self._cached("Minv", compute)

    @property
    def subtree_inertias(self) -> Any:
        """Pinocchio's ``data.oYcrb``: the inertia of each joint's subtree, in world axes.

        Read it here, not from :attr:`data`: computing M⁻¹ overwrites that buffer with each
        body's own inertia, so after :attr:`Minv` it no longer holds the subtrees (the CRBA
        pass then runs again, in the convention computeAllTerms uses).
        """
        self._terms()
        if not self._subtree_inertias_valid:
            t0 = time.perf_counter()
            pin.crba(self.model, self._data, self.q, pin.Convention.WORLD)
            self._subtree_inertias_valid = True
            self.compute_time += time.perf_counter() - t0
        return self._data.oYcrb

    @property
    def h(self) -> np.ndarray:
        """Nonlinear effects C(q, v) v + g(q), (n,) [N, N·m]."""
        self._terms()
        return self._cached("h", lambda: self._data.nle.copy())

    @property
    def g(self) -> np.ndarray:
        """Generalized gravity (n,) [N, N·m]."""
        self._terms()
        return self._cached("g", lambda: self._data.g.copy())

    @property
    def S(self) -> np.ndarray:
        """Actuation selection (k, n): [0 I_k]."""
        return self._cached("S", lambda: np.hstack([np.zeros((self.k, 6)), np.eye(self.k)]))

    # -- centre of mass and centroidal momentum -----------------------------------------------

    @property
    def com(self) -> np.ndarray:
        """CoM position in the world (3,) [m]."""
        self._terms()
        return self._cached("com", lambda: self._data.com[0].copy())

    @property
    def com_velocity(self) -> np.ndarray:
        """CoM velocity in the world (3,) [m/s]."""
        return self._cached("vcom", lambda: self.J_com @ self.v)

    @property
    def J_com(self) -> np.ndarray:
        """CoM Jacobian (3, n)."""
        self._terms()
        return self._cached("Jcom", lambda: self._data.Jcom.copy())

    @property
    def com_drift(self) -> np.ndarray:
        """CoM acceleration at zero q̈, J̇_com q̇ (3,) [m/s²]."""
        self._drifts()
        return self._cached("acom", lambda: self._data.acom[0].copy())

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        self._terms()
        return float(self._data.mass[0])

    @property
    def cmm(self) -> np.ndarray:
        """Centroidal momentum matrix A_G (6, n): [linear; angular] momentum about the CoM."""
        self._terms()
        return self._cached("Ag", lambda: self._data.Ag.copy())

    @property
    def cmm_drift(self) -> np.ndarray:
        """Rate of centroidal momentum at zero q̈, Ȧ_G q̇ (6,)."""
        self._terms()

        def compute() -> np.ndarray:
            pin.computeCentroidalMomentumTimeVariation(
                self.model, self._data, self.q, self.v, np.zeros(self.n)
            )
            return np.asarray(self._data.dhg.np).copy()

        return self._cached("dhg", compute)

    # -- frames ---------------------------------------------------------------------------------

    def frame_id(self, frame: str | int) -> int:
        return frame if isinstance(frame, int) else self.robot.frame_id(frame)

    def placement(self, frame: str | int) -> pin.SE3:
        """World placement of a frame."""
        self._terms()
        return self._data.oMf[self.frame_id(frame)]

    def position(self, frame: str | int) -> np.ndarray:
        """World position of a frame origin (3,) [m]."""
        return self.placement(frame).translation

    def rotation(self, frame: str | int) -> np.ndarray:
        """World rotation of a frame (3, 3)."""
        return self.placement(frame).rotation

    def jacobian(self, frame: str | int, local: bool = False) -> np.ndarray:
        """Frame Jacobian (6, n): [linear; angular], LOCAL_WORLD_ALIGNED unless ``local``."""
        fid = self.frame_id(frame)
        self._terms()
        ref = LOCAL if local else LOCAL_WORLD_ALIGNED
        return self._cached(
            ("J", fid, local),
            lambda: pin.getFrameJacobian(self.model, self._data, fid, ref),
        )

    def velocity(self, frame: str | int, local: bool = False) -> np.ndarray:
        """Frame spatial velocity (6,): [linear; angular], same frames as :meth:`jacobian`."""
        return self.jacobian(frame, local) @ self.v

    def drift(self, frame: str | int, local: bool = False) -> np.ndarray:
        """J̇ q̇ of a frame (6,).

        World-aligned: the classical acceleration at zero q̈ (the second derivative of the
        point's world position, and the angular acceleration). Local: the spatial acceleration
        at zero q̈ in the frame (what must vanish for a rigid contact).
        """
        fid = self.frame_id(frame)
        self._drifts()

        def compute() -> np.ndarray:
            if local:
                acc = pin.getFrameAcceleration(self.model, self._data, fid, LOCAL)
            else:
                acc = pin.getFrameClassicalAcceleration(
                    self.model, self._data, fid, LOCAL_WORLD_ALIGNED
                )
            return np.asarray(acc.vector).copy()

        return self._cached(("dJv", fid, local), compute)

    # -- stacked contact quantities -------------------------------------------------------------

    def contact_jacobian(self, contacts: Sequence[str | ContactLike]) -> np.ndarray:
        """Stacked contact Jacobians (Σ dim, n): a frame's LOCAL Jacobian (6 rows) for a flat
        contact, or each point's linear velocity in the frame's axes (3 rows per point)."""
        key = ("Jc", *map(_contact_key, contacts))
        if key in self._cache:
            return self._cache[key]
        if not contacts:
            value = np.zeros((0, self.n))
        else:
            value = np.vstack([self._contact_rows(c) for c in contacts])
        self._cache[key] = value
        return value

    def contact_drift(self, contacts: Sequence[str | ContactLike]) -> np.ndarray:
        """Stacked J̇_c q̇ (Σ dim,): a flat contact's spatial acceleration at zero q̈ (LOCAL), a
        point's classical acceleration at zero q̈ in the frame's axes."""
        key = ("dJcv", *map(_contact_key, contacts))
        if key in self._cache:
            return self._cache[key]
        if not contacts:
            value = np.zeros(0)
        else:
            value = np.concatenate([self._contact_drift(c) for c in contacts])
        self._cache[key] = value
        return value

    def contact_constraint(
        self, contacts: Sequence[str | ContactLike]
    ) -> tuple[np.ndarray, np.ndarray]:
        """(J_k, d_k): the rows of J_c q̈ + J̇_c q̇ = 0 that are independent by construction.

        A flat contact keeps its 6 rows; a point set's 3N rows are ``Gᵀ J_frame`` and hold only
        the frame motions in the range of Gᵀ (5 for a line, 6 for a polygon), so they are
        replaced by ``T`` times them, ``T`` (r, 3N) an orthonormal basis of that range
        (:func:`contact_basis`): the same constraint, without rows that QP solvers reject as
        dependent equalities.
        """
        key = ("Jk", *map(_contact_key, contacts))
        if key in self._cache:
            return self._cache[key], self._cache[("dk", *key[1:])]
        Jc, dJc = self.contact_jacobian(contacts), self.contact_drift(contacts)
        T = contact_selector(contacts)
        J, d = (Jc, dJc) if T is None else (T @ Jc, T @ dJc)
        self._cache[key], self._cache[("dk", *key[1:])] = J, d
        return J, d

    def _contact_rows(self, c: str | ContactLike) -> np.ndarray:
        frame, points = (c, None) if isinstance(c, str) else (c.frame, c.points)
        J = self.jacobian(frame, local=True)
        if points is None:
            return J
        return point_velocity_map(points) @ J

    def _contact_drift(self, c: str | ContactLike) -> np.ndarray:
        frame, points = (c, None) if isinstance(c, str) else (c.frame, c.points)
        a = self.drift(frame, local=True)
        if points is None:
            return a
        # classical: a_p = a + α × p + ω × (v + ω × p), all in the frame (spatial a, α)
        vel = self.velocity(frame, local=True)
        v, w = vel[:3], vel[3:]
        return np.concatenate(
            [a[:3] + np.cross(a[3:], p) + np.cross(w, v + np.cross(w, p)) for p in points]
        )
