"""Small dense kernels for the matrices of a control tick (sizes 3–120).

At these sizes the fixed cost of a call dominates: ``np.triu`` rebuilds its index mask on every
call, and scipy.linalg's wrappers (argument checks, workspace queries) cost as much as the
factorisation. These cache the masks and call LAPACK directly.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.linalg import lapack


@functools.cache
def _upper_mask(rows: int, cols: int) -> np.ndarray:
    mask = np.triu(np.ones((rows, cols), dtype=bool))
    mask.setflags(write=False)
    return mask


def upper(a: np.ndarray) -> np.ndarray:
    """The upper triangle of ``a`` (diagonal included), zeros below: ``np.triu(a)``."""
    return np.where(_upper_mask(*a.shape), a, 0.0)


def symmetric_from_upper(a: np.ndarray) -> np.ndarray:
    """The symmetric matrix whose upper triangle is that of the square ``a`` (the lower one is
    ignored: LAPACK and Pinocchio fill only the upper one)."""
    return np.where(_upper_mask(*a.shape), a, a.T)


def skew(v: np.ndarray) -> np.ndarray:
    """The cross-product matrix [v]ₓ of a 3-vector: [v]ₓ w = v × w."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def tri_solve(T: np.ndarray, B: np.ndarray, trans: bool = False) -> np.ndarray:
    """Solve T X = B (or Tᵀ X = B) with T upper triangular and non-singular."""
    x, info = lapack.dtrtrs(T, B, lower=0, trans=1 if trans else 0)
    if info != 0:
        raise np.linalg.LinAlgError(f"triangular solve failed (info {info})")
    return np.asarray(x)


def spd_factor(A: np.ndarray) -> np.ndarray:
    """Upper Cholesky factor U of a symmetric positive definite A = Uᵀ U."""
    u, info = lapack.dpotrf(A, lower=0, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"matrix not positive definite (info {info})")
    return np.asarray(u)


def spd_solve_factored(U: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A⁻¹ B from the upper Cholesky factor U of A."""
    x, info = lapack.dpotrs(U, B, lower=0)
    if info != 0:
        raise np.linalg.LinAlgError(f"Cholesky solve failed (info {info})")
    return np.asarray(x)


def spd_solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A⁻¹ B for a symmetric positive definite A (Cholesky)."""
    return spd_solve_factored(spd_factor(A), B)


def spd_inverse(A: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive definite matrix (Cholesky), exactly symmetric."""
    inv, info = lapack.dpotri(spd_factor(A), lower=0)
    if info != 0:
        raise np.linalg.LinAlgError(f"Cholesky inverse failed (info {info})")
    return symmetric_from_upper(inv)
