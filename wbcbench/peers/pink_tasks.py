"""A pink task whose rows are given each tick: the RQR-HQP paper's gaze enters pink through it.

Imported only when a ``pink`` controller with a gaze is built (it imports pink).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from pink.tasks import Task

Array = NDArray[np.float64]


class RowsTask(Task):
    """J Δq = −e at (weighted) best, with J (m, n) and e (m,) set by :meth:`set_rows`.

    pink's extension point for a task it does not ship: its QP objective is pink's own,
    ½ ‖W (J Δq + α e)‖² (gain α = 1).
    """

    def __init__(self, cost: Array) -> None:
        super().__init__(cost=np.asarray(cost, dtype=float), gain=1.0)
        self.jacobian = np.zeros((len(cost), 0))
        self.error = np.zeros(len(cost))

    def set_rows(self, jacobian: Array, error: Array) -> None:
        """This tick's Jacobian (m, n) and error (m,) [the error in units of Δq's image]."""
        self.jacobian = np.asarray(jacobian, dtype=float)
        self.error = np.asarray(error, dtype=float)

    def compute_error(self, configuration: object) -> Array:
        return self.error

    def compute_jacobian(self, configuration: object) -> Array:
        return self.jacobian

    def __repr__(self) -> str:
        return f"RowsTask(rows={self.error.shape[0]}, cost={self.cost})"
