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
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
    """

    frame: str
    x_range: tuple[float, float] = (-0.05, 0.05)
    y_range: tuple[float, float] = (-0.05, 0.05)
    mu: float = 0.5
    fmin: float = 30.0
    facets: int = 4
    mu_yaw: float | None = None
    fmax: float = np.inf
    _rows: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def wrench_constraints(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(C, l, u) with ``l ≤ C f ≤ u`` for this contact's 6-D wrench; C is (r, 6)."""
        if self._rows is not None:
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

    @property
    def n_constraints(self) -> int:
        return self.wrench_constraints()[0].shape[0]

    def violation(self, wrench: np.ndarray) -> dict[str, float]:
        """Largest violation of each family of inequalities by a wrench (≥ 0; 0 = satisfied).

        Normalised where it makes sense: friction and CoP are reported as ratios that the
        constraint bounds (‖f_t‖/f_z − μ and CoP distance outside the box [m]).
        """
        fx, fy, fz, mx, my, mz = np.asarray(wrench, dtype=float)
        out = {"normal": max(0.0, self.fmin - fz)}
        if fz <= 1e-9:
            out.update(friction=np.inf, cop=np.inf, yaw=np.inf)
            return out
        out["friction"] = max(0.0, float(np.hypot(fx, fy)) / fz - self.mu)
        mu_yaw = self.mu if self.mu_yaw is None else self.mu_yaw
        out["yaw"] = max(0.0, abs(mz) / fz - mu_yaw)
        cop_x, cop_y = -my / fz, mx / fz
        out["cop"] = max(
            0.0,
            self.x_range[0] - cop_x,
            cop_x - self.x_range[1],
            self.y_range[0] - cop_y,
            cop_y - self.y_range[1],
        )
        return out


def stack_wrench_constraints(
    contacts: list[PlaneContact],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Block-diagonal (C, l, u) for the stacked wrench of several contacts, C is (r, 6c)."""
    if not contacts:
        return np.zeros((0, 0)), np.zeros(0), np.zeros(0)
    blocks = [c.wrench_constraints() for c in contacts]
    r = sum(b[0].shape[0] for b in blocks)
    C = np.zeros((r, 6 * len(contacts)))
    row = 0
    for i, (Ci, _, _) in enumerate(blocks):
        C[row : row + Ci.shape[0], 6 * i : 6 * i + 6] = Ci
        row += Ci.shape[0]
    lower = np.concatenate([b[1] for b in blocks])
    upper = np.concatenate([b[2] for b in blocks])
    return C, lower, upper
