"""wbcbench: compare humanoid whole-body control formulations and QP solvers on equal terms."""

__version__ = "0.1.0"
