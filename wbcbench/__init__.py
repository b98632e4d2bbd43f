"""wbcbench: compare humanoid whole-body control formulations and QP solvers on equal terms.

The Python API (``wbcbench.make_controller``, ``wbcbench.load_results``) is in
:mod:`wbcbench.api`; it is imported on first use, so that ``import wbcbench`` stays light.
"""

from typing import Any

__version__ = "0.1.0"

__all__ = ["load_results", "make_controller"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from wbcbench import api

        return getattr(api, name)
    raise AttributeError(f"module 'wbcbench' has no attribute {name!r}")
