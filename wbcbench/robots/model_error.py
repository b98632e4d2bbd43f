"""A robot whose Pinocchio model is wrong in stated ways: what a controller believes when its
model was identified with an error.

Only the Pinocchio model changes; the MuJoCo model (what is simulated), the names and the limits
stay the file's, so a controller built on the result drives the true robot with a wrong model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from wbcbench.robots.loader import Robot


def with_model_error(
    robot: Robot,
    mass_scale: float = 1.0,
    inertia_scale: float | None = None,
    com_offset: Sequence[float] = (0.0, 0.0, 0.0),
) -> Robot:
    """``robot`` with every link's inertia changed in its Pinocchio model.

    Args:
        mass_scale: factor on every link's mass (> 0).
        inertia_scale: factor on every link's rotational inertia about its centre of mass
            (> 0); ``mass_scale`` when None (a uniform density error).
        com_offset: added to every link's centre of mass, in its joint's frame (3,) [m].

    Returns the robot itself when nothing changes.
    """
    scale_i = mass_scale if inertia_scale is None else inertia_scale
    offset = np.asarray(com_offset, dtype=float)
    if mass_scale == 1.0 and scale_i == 1.0 and not offset.any():
        return robot
    model = pin.Model(robot.pin_model)  # a copy
    for j in range(1, model.njoints):  # 0 is the universe
        inertia = model.inertias[j]
        model.inertias[j] = pin.Inertia(
            inertia.mass * mass_scale, inertia.lever + offset, inertia.inertia * scale_i
        )
    return dataclasses.replace(robot, pin_model=model)
