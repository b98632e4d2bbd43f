"""Reports from a results folder: paper tables, the solver comparison, figures.

``load_results(path)`` is the one way to read a results folder (scripts and notebooks use it).
"""

from wbcbench.report.load import Results, load_results

__all__ = ["Results", "load_results"]
