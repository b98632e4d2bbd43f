"""A QP backend from outside wbcbench: DAQP with its proximal-point iterations always on.

wbcbench's ``daqp`` backend leaves ``eps_prox = -1e-6`` (DAQP decides at each solve whether the
Hessian needs proximal iterations); this one fixes ``eps_prox = 1e-6``, so that every solve
takes the same path whatever the Hessian's rounding. The proximal-point iterations converge to
the unregularised optimum.

A plugin backend is a :class:`wbcbench.QPSolver` subclass; this one reuses wbcbench's DAQP
backend and changes its settings only.
"""

from __future__ import annotations

from typing import Any, ClassVar

from wbcbench.qp.backends.daqp import DAQPSolver


class ProximalDAQP(DAQPSolver):
    """DAQP with ``eps_prox = 1e-6`` at every tier."""

    name: ClassVar[str] = "example_daqp"
    summary: ClassVar[str] = "example plugin: DAQP with proximal iterations always on"

    @staticmethod
    def tier_settings(tier: str) -> dict[str, Any]:
        return {**DAQPSolver.tier_settings(tier), "eps_prox": 1e-6}
