"""Triangle helpers for the small dense matrices of a control tick.

``np.triu`` rebuilds its index mask on every call, which costs more than the copy itself on the
30–120-sized matrices a controller handles; these cache the mask per shape.
"""

from __future__ import annotations

import functools

import numpy as np


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
