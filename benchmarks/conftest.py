"""Micro-benchmarks run with one BLAS thread, like the command line."""

from threadpoolctl import threadpool_limits

threadpool_limits(1)
