"""One module per QP backend, each using its library's native API.

Each module defines one :class:`wbcbench.qp.base.QPSolver` subclass and a ``tier_settings``
translation; :mod:`wbcbench.qp.registry` lists them. Modules import their library at the top,
so importing a backend whose package is missing raises ``ImportError`` (the registry catches
it and reports the backend as unavailable).
"""
