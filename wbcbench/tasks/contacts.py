"""Plane contacts and their wrench inequalities (TO-OSF paper, eq. 15).

The wrench ``f = [f_x, f_y, f_z, m_x, m_y, m_z]`` is the **reaction on the robot**, expressed in the
contact frame (LOCAL, z = contact normal pointing from the environment into the robot, moments
about the frame origin). The paper's ``F_c`` is the wrench on the environment, ``F_c = −f``, so its
``f_z < ε`` with ε = −30 N reads ``f_z ≥ 30 N`` here; the CoP ratios are unchanged by the sign.

Inequalities, all linear in f:

* minimum normal force: ``f_z ≥ f_min``;
* friction: the cone ``√(f_x² + f_y²) ≤ μ f_z`` replaced by an inscribed pyramid of ``facets``
  faces, ``cos θ_i f_x + sin θ_i f_y ≤ μ cos(π/facets) f_z`` (inscribed, so feasible wrenches of the
  pyramid are feasible for the cone);
* yaw moment: ``|m_z| ≤ μ_yaw f_z`` (the paper's ``μ_s |f_z| > m_z`` with μ_yaw = μ by default);
* centre of pressure inside the box: ``x_min ≤ −m_y / f_z ≤ x_max`` and
  ``y_min ≤ m_x / f_z ≤ y_max``, written as ``x_min f_z ≤ −m_y ≤ x_max f_z`` (valid because
  f_z > 0).

A contact may instead be a set of **points** on its frame (``points``, (N, 3) in the frame): a
point, a line (two points) or a polygon. Each point i carries a 3-D force ``f_i`` (reaction on
the robot, contact-frame axes) and no moment; its inequalities are the unilateral normal force
``f_min ≤ f_i,z (≤ f_max)`` and the same inscribed friction pyramid. The stacked point forces
(3N,) map to the frame's 6-D wrench by ``w = G f``, ``G = [I … I; [p_1]× … [p_N]×]``, and the
contact's Jacobian rows are the points' linear velocities ``Gᵀ J_frame`` (3 per point). The
wrench a controller reports for such a contact is ``G f``, so logs and metrics read 6 numbers
per contact whatever its type.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wbcbench.dynamics.state import point_velocity_map


@dataclass
class PlaneContact:
    """A rectangular (or point-like) plane contact held by one frame of the robot.

    Attributes:
        frame: name of the contact frame (z = normal into the robot, origin on the contact plane).
        x_range: CoP limits along the frame's x axis [m], (min, max).
        y_range: CoP limits along the frame's y axis [m], (min, max).
        mu: static friction coefficient [-].
        fmin: minimum normal force [N] (reaction on the robot).
        facets: number of faces of the linearized friction cone.
        mu_yaw: yaw-moment coefficient [m]·[-] multiplying f_z; defaults to ``mu``.
        fmax: optional maximum normal force [N] (inf: none).
        points: None for a flat contact (6-D wrench); else the contact points (N, 3) in the
            frame, each carrying a 3-D force (fmin and fmax then bound each point's normal
            force; x_range and y_range are the points' bounding box).
    """

    frame: str
    x_range: tuple[float, float] = (-0.05, 0.05)
    y_range: tuple[float, float] = (-0.05, 0.05)
    mu: float = 0.5
    fmin: float = 30.0
    facets: int = 4
    mu_yaw: float | None = None
    fmax: float = np.inf
    points: tuple[tuple[float, float, float], ...] | None = None
    _rows: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def wrench_constraints(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(C, l, u) with ``l ≤ C f ≤ u`` for this contact's 6-D wrench; C is (r, 6)."""
        if self._rows is not None:
            return self._rows
        if self.points is not None:
            self._rows = self._point_constraints()
            return self._rows
        rows: list[np.ndarray] = []
        lower: list[float] = []
        upper: list[float] = []

        def add(row: list[float], lo: float, hi: float) -> None:
            rows.append(np.asarray(row, dtype=float))
            lower.append(lo)
            upper.append(hi)

        # f_min ≤ f_z ≤ f_max
        add([0, 0, 1, 0, 0, 0], self.fmin, self.fmax)
        # inscribed friction pyramid: cosθ f_x + sinθ f_y − μ' f_z ≤ 0
        mu_in = self.mu * np.cos(np.pi / self.facets)
        for i in range(self.facets):
            theta = 2.0 * np.pi * i / self.facets
            add([np.cos(theta), np.sin(theta), -mu_in, 0, 0, 0], -np.inf, 0.0)
        # |m_z| ≤ μ_yaw f_z
        mu_yaw = self.mu if self.mu_yaw is None else self.mu_yaw
        add([0, 0, -mu_yaw, 0, 0, 1], -np.inf, 0.0)
        add([0, 0, -mu_yaw, 0, 0, -1], -np.inf, 0.0)
        # CoP box: x_min f_z ≤ −m_y ≤ x_max f_z ; y_min f_z ≤ m_x ≤ y_max f_z
        x_lo, x_hi = self.x_range
        y_lo, y_hi = self.y_range
        add([0, 0, x_lo, 0, 1, 0], -np.inf, 0.0)  # x_lo f_z + m_y ≤ 0
        add([0, 0, -x_hi, 0, -1, 0], -np.inf, 0.0)  # −m_y − x_hi f_z ≤ 0
        add([0, 0, y_lo, -1, 0, 0], -np.inf, 0.0)  # y_lo f_z − m_x ≤ 0
        add([0, 0, -y_hi, 1, 0, 0], -np.inf, 0.0)  # m_x − y_hi f_z ≤ 0
        self._rows = (np.vstack(rows), np.asarray(lower), np.asarray(upper))
        return self._rows

    def _point_constraints(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per point: f_min ≤ f_z ≤ f_max and the inscribed friction pyramid, (r, 3N)."""
        mu_in = self.mu * np.cos(np.pi / self.facets)
        theta = 2.0 * np.pi * np.arange(self.facets) / self.facets
        pyramid = np.column_stack([np.cos(theta), np.sin(theta), np.full(self.facets, -mu_in)])
        block = np.vstack([[0.0, 0.0, 1.0], pyramid])
        lo = np.concatenate([[self.fmin], -np.inf * np.ones(self.facets)])
        hi = np.concatenate([[self.fmax], np.zeros(self.facets)])
        npts = len(self.points or ())
        return np.kron(np.eye(npts), block), np.tile(lo, npts), np.tile(hi, npts)

    def normal_rows(self) -> list[int]:
        """The rows of :meth:`wrench_constraints` that bound a normal force (one per point)."""
        if self.points is None:
            return [0]
        return [i * (1 + self.facets) for i in range(len(self.points))]

    @property
    def dim(self) -> int:
        """Size of the contact's force variable: 6 (flat) or 3 per point."""
        return 6 if self.points is None else 3 * len(self.points)

    def wrench_map(self) -> np.ndarray:
        """G (6, dim): the frame's wrench [f; m] of the contact's force variable."""
        if self.points is None:
            return np.eye(6)
        return point_wrench_map(self.points)

    @property
    def n_constraints(self) -> int:
        return self.wrench_constraints()[0].shape[0]

    def violation(self, wrench: np.ndarray) -> dict[str, float]:
        """Largest violation of each family of inequalities by a wrench (≥ 0; 0 = satisfied).

        Normalised where it makes sense: friction and CoP are reported as ratios that the
        constraint bounds (‖f_t‖/f_z − μ and CoP distance outside the box [m]).
        """
        fx, fy, fz, mx, my, mz = np.asarray(wrench, dtype=float)
        # a point set bounds each point's normal force: the total is at least N f_min
        fmin = self.fmin if self.points is None else self.fmin * len(self.points)
        out = {"normal": max(0.0, fmin - fz)}
        if fz <= 1e-9:
            out.update(friction=np.inf, cop=np.inf, yaw=np.inf)
            return out
        out["friction"] = max(0.0, float(np.hypot(fx, fy)) / fz - self.mu)
        mu_yaw = self.mu if self.mu_yaw is None else self.mu_yaw
        # a point set has no yaw-moment bound of its own (its points' friction bounds it)
        out["yaw"] = max(0.0, abs(mz) / fz - mu_yaw) if self.points is None else 0.0
        cop_x, cop_y = -my / fz, mx / fz
        out["cop"] = max(
            0.0,
            self.x_range[0] - cop_x,
            cop_x - self.x_range[1],
            self.y_range[0] - cop_y,
            cop_y - self.y_range[1],
        )
        return out


def point_wrench_map(points: Any) -> np.ndarray:
    """G (6, 3N) = [I … I; [p_1]× … [p_N]×]: the wrench about the frame origin of point forces."""
    return point_velocity_map(points).T


def contacts_dim(contacts: list[PlaneContact]) -> int:
    """Size of the stacked force variable of several contacts (6 per flat one, 3 per point)."""
    return sum(c.dim for c in contacts)


def frame_wrenches(contacts: list[PlaneContact], f: np.ndarray) -> np.ndarray:
    """The stacked 6-D frame wrenches (6c,) of the contacts' stacked force variable ``f``
    (``f`` itself when every contact is flat)."""
    if all(c.points is None for c in contacts):
        return f
    out = np.zeros(6 * len(contacts))
    row = 0
    for i, c in enumerate(contacts):
        out[6 * i : 6 * i + 6] = c.wrench_map() @ f[row : row + c.dim]
        row += c.dim
    return out


def stack_wrench_constraints(
    contacts: list[PlaneContact],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Block-diagonal (C, l, u) for the stacked force variable of several contacts, C is
    (r, Σ dim) (6 per flat contact, 3 per point)."""
    if not contacts:
        return np.zeros((0, 0)), np.zeros(0), np.zeros(0)
    blocks = [c.wrench_constraints() for c in contacts]
    r = sum(b[0].shape[0] for b in blocks)
    C = np.zeros((r, contacts_dim(contacts)))
    row = col = 0
    for c, (Ci, _, _) in zip(contacts, blocks, strict=True):
        C[row : row + Ci.shape[0], col : col + c.dim] = Ci
        row += Ci.shape[0]
        col += c.dim
    lower = np.concatenate([b[1] for b in blocks])
    upper = np.concatenate([b[2] for b in blocks])
    return C, lower, upper


def tile_wrench_weights(weights: np.ndarray, contacts: list[PlaneContact]) -> np.ndarray:
    """Per-row weights of the stacked force variable from 6 per-component ones: a flat
    contact's 6, the first 3 (the force's) for each point of a point set."""
    w = np.asarray(weights, dtype=float)
    return np.concatenate(
        [w if c.points is None else np.tile(w[:3], len(c.points)) for c in contacts]
        or [np.zeros(0)]
    )
