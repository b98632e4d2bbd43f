"""The field's differential-IK libraries as velocity-level peers of ``kin_hqp``.

Two controllers, ``pink`` (`pin-pink <https://github.com/stephane-caron/pink>`_, on the robot's
Pinocchio model) and ``mink`` (`mink <https://github.com/kevinzakka/mink>`_, on its MuJoCo
model), run the kinematic scenarios through each library's own tasks, limits, QP builder
(``build_ik``) and QP solvers (qpsolvers). They enter through the plugin interface like any
user's controller: entry points of wbcbench's own distribution in the ``wbcbench.controllers``
group. The libraries are the optional extra ``peers`` (``pip install 'wbcbench[peers]'``) and
are imported when a controller is built, so the entry points load without them.

What each library can express of wbcbench's tasks and limits, and what it cannot, is in the
docstrings of :mod:`wbcbench.peers.common`, :mod:`wbcbench.peers.pink_ik` and
:mod:`wbcbench.peers.mink_ik`.
"""

from __future__ import annotations
