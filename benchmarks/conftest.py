"""Micro-benchmarks run with one BLAS thread, like the command line."""

import scipy.linalg  # noqa: F401 - SciPy ships its own BLAS: load it before limiting threads
from threadpoolctl import threadpool_limits

threadpool_limits(1)
