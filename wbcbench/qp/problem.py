"""The solver-agnostic quadratic program every controller builds.

A :class:`Problem` is plain dense NumPy data::

    minimise    ½ xᵀ H x + gᵀ x
    subject to  A x = b
                l ≤ C x ≤ u
                lb ≤ x ≤ ub

with ``x`` of shape ``(n,)``. ``A`` has ``n_eq`` rows and ``C`` has ``n_in`` rows (either may be
zero); ``l``, ``u``, ``lb`` and ``ub`` may hold ``±inf`` and the box ``lb``/``ub`` may be absent
(``None``). Units are whatever the controller's decision variables carry (e.g. [rad/s²], [N],
[N·m]); the solver layer never interprets them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Hashable
from dataclasses import dataclass, field
from os import PathLike
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wbcbench.errors import SolverError

Array = NDArray[np.float64]

#: Relative tolerance on ``‖H − Hᵀ‖_max`` accepted by :meth:`Problem.validate`.
SYMMETRY_RTOL = 1e-9


def _as_matrix(M: Any, n: int) -> Array:
    out = np.zeros((0, n)) if M is None else np.asarray(M, dtype=np.float64)
    if out.size == 0 and out.shape != (0, n):
        return np.zeros((0, n))
    return out


def _empty() -> Array:
    return np.zeros(0)


def _as_vector(v: Any) -> Array:
    return np.zeros(0) if v is None else np.asarray(v, dtype=np.float64)


@dataclass
class Problem:
    """A convex QP in dense form (see the module docstring for the formulation).

    Attributes:
        H: Hessian, ``(n, n)``, symmetric positive semidefinite.
        g: linear cost, ``(n,)``.
        A: equality matrix, ``(n_eq, n)``; omitted (or ``None``) means ``(0, n)``.
        b: equality right-hand side, ``(n_eq,)``.
        C: inequality matrix, ``(n_in, n)``; omitted (or ``None``) means ``(0, n)``.
        l: lower inequality bounds, ``(n_in,)``, may hold ``-inf``; omitted means all ``-inf``.
        u: upper inequality bounds, ``(n_in,)``, may hold ``+inf``; omitted means all ``+inf``.
        lb: lower variable bounds, ``(n,)`` or ``None``; may hold ``-inf``.
        ub: upper variable bounds, ``(n,)`` or ``None``; may hold ``+inf``.
        name: a short label (e.g. ``"hqp/level2"``).
        meta: free-form provenance (controller, level, tick, ...); must be JSON-serialisable
            for :meth:`save`.
    """

    H: Array
    g: Array
    A: Array = field(default_factory=_empty)
    b: Array = field(default_factory=_empty)
    C: Array = field(default_factory=_empty)
    l: Array = field(default_factory=_empty)  # noqa: E741 - the QP literature's symbol
    u: Array = field(default_factory=_empty)
    lb: Array | None = None
    ub: Array | None = None
    name: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.H = np.asarray(self.H, dtype=np.float64)
        self.g = np.asarray(self.g, dtype=np.float64)
        n = self.g.shape[0] if self.g.ndim == 1 else 0
        self.A = _as_matrix(self.A, n)
        self.b = _as_vector(self.b)
        self.C = _as_matrix(self.C, n)
        n_in = self.C.shape[0] if self.C.ndim == 2 else 0
        self.l = _as_vector(self.l)
        self.u = _as_vector(self.u)
        if self.l.size == 0 and n_in:
            self.l = np.full(n_in, -np.inf)
        if self.u.size == 0 and n_in:
            self.u = np.full(n_in, np.inf)
        if self.lb is not None:
            self.lb = _as_vector(self.lb)
        if self.ub is not None:
            self.ub = _as_vector(self.ub)

    @property
    def n(self) -> int:
        """Number of decision variables."""
        return int(self.g.shape[0])

    @property
    def n_eq(self) -> int:
        """Number of equality rows (rows of ``A``)."""
        return int(self.A.shape[0])

    @property
    def n_in(self) -> int:
        """Number of two-sided inequality rows (rows of ``C``)."""
        return int(self.C.shape[0])

    @property
    def has_box(self) -> bool:
        """True when ``lb`` or ``ub`` is given."""
        return self.lb is not None or self.ub is not None

    def box(self) -> tuple[Array, Array]:
        """Variable bounds with a missing side filled by ``∓inf``: ``(lb, ub)``, each ``(n,)``."""
        lb = np.full(self.n, -np.inf) if self.lb is None else self.lb
        ub = np.full(self.n, np.inf) if self.ub is None else self.ub
        return lb, ub

    def objective(self, x: Array) -> float:
        """Cost ``½ xᵀ H x + gᵀ x`` at ``x`` of shape ``(n,)``."""
        return float(0.5 * x @ self.H @ x + self.g @ x)

    def structure_key(self) -> Hashable:
        """Signature of everything but the values: a hot solver may update in place iff equal.

        It holds the dimensions and which of ``lb``/``ub`` are present, not the sparsity
        pattern nor where bounds are infinite; a backend whose native form depends on those
        (sparse patterns, rows split per finite side) adds its own check before updating.
        """
        return (self.n, self.n_eq, self.n_in, self.lb is not None, self.ub is not None)

    def validate(self) -> None:
        """Check shapes, finiteness of ``H, g, A, b, C``, symmetry of ``H`` and ``l ≤ u``.

        Called on every solve, so the common case (a valid problem) is a handful of whole-array
        reductions; only a problem that fails one of them is searched for the precise fault.

        Raises:
            SolverError: naming the first inconsistency; it carries this problem.
        """
        n = self.g.shape[0] if self.g.ndim == 1 else -1
        if n < 0:
            raise self._invalid(f"g must be a vector, got shape {self.g.shape}")
        n_eq, n_in = self.A.shape[0], self.C.shape[0]
        for key, arr, shape in (
            ("H", self.H, (n, n)),
            ("A", self.A, (n_eq, n)),
            ("b", self.b, (n_eq,)),
            ("C", self.C, (n_in, n)),
            ("l", self.l, (n_in,)),
            ("u", self.u, (n_in,)),
            ("lb", self.lb, (n,)),
            ("ub", self.ub, (n,)),
        ):
            if arr is not None and arr.shape != shape:
                raise self._invalid(f"{key} has shape {arr.shape}, expected {shape} (n={n})")
        # a sum is finite only if every term is (or, spuriously, on overflow: checked below)
        total = self.H.sum() + self.g.sum()
        if n_eq:
            total += self.A.sum() + self.b.sum()
        if n_in:
            total += self.C.sum()
        if not math.isfinite(total):
            for key in ("H", "g", "A", "b", "C"):
                if not np.all(np.isfinite(getattr(self, key))):
                    raise self._invalid(f"{key} has non-finite entries")
        H = self.H
        if n and H.tobytes() != H.T.tobytes():  # exactly symmetric: the usual case, a memcmp
            if abs(H - H.T).max() > SYMMETRY_RTOL * max(1.0, abs(H).max()):
                raise self._invalid("H is not symmetric")
        # NaN compares false, so this also catches a NaN bound
        if not (self.l <= self.u).all():
            self._bound_fault("l", "u", self.l, self.u)
        lb, ub = self.lb, self.ub
        if lb is not None and ub is not None:
            if not (lb <= ub).all():
                self._bound_fault("lb", "ub", lb, ub)
        else:
            side = lb if lb is not None else ub
            if side is not None and np.isnan(side).any():
                raise self._invalid("lb/ub contain NaN")

    def _invalid(self, msg: str) -> SolverError:
        label = f"problem {self.name!r}: " if self.name else "problem: "
        return SolverError(label + msg, problem=self)

    def _bound_fault(self, lo_key: str, hi_key: str, lo: Array, hi: Array) -> None:
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)):
            raise self._invalid(f"{lo_key}/{hi_key} contain NaN")
        i = int(np.flatnonzero(lo > hi)[0])
        raise self._invalid(f"{lo_key}[{i}] = {lo[i]:g} > {hi_key}[{i}] = {hi[i]:g}")

    def save(self, path: str | PathLike[str]) -> None:
        """Write the problem to an ``.npz`` file (``meta`` stored as JSON) for offline replay."""
        arrays: dict[str, Any] = {
            "H": self.H,
            "g": self.g,
            "A": self.A,
            "b": self.b,
            "C": self.C,
            "l": self.l,
            "u": self.u,
            "name": np.array(self.name),
            "meta": np.array(json.dumps(self.meta, default=_json_default)),
        }
        if self.lb is not None:
            arrays["lb"] = self.lb
        if self.ub is not None:
            arrays["ub"] = self.ub
        np.savez(path, **arrays)

    @classmethod
    def load(cls, path: str | PathLike[str]) -> Problem:
        """Read a problem written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as data:
            return cls(
                H=data["H"],
                g=data["g"],
                A=data["A"],
                b=data["b"],
                C=data["C"],
                l=data["l"],
                u=data["u"],
                lb=data["lb"] if "lb" in data else None,
                ub=data["ub"] if "ub" in data else None,
                name=str(data["name"]),
                meta=json.loads(str(data["meta"])),
            )


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
