"""Time of the three hierarchy algorithms against the problem size N (RQR-HQP paper, Fig. 1).

Run with ``pytest benchmarks/bench_hls.py --benchmark-enable`` (pytest-benchmark), or as a script
for the plain median tables: ``python benchmarks/bench_hls.py``.

Every algorithm solves the same fixed-shape stack (``fig1_stack``: 4 equality levels that
together constrain 80 % of the N variables), in both impls: the Python reference (timed around
the call) and the C++ mirror (timed inside the module; the call from Python is shown apart).
BLAS runs single-threaded: at these sizes OpenBLAS threads cost more than they save (measured up
to 50x slower per level with two threads) and make the timings depend on what else the machine
does. The LAPACK table times the factorisations each algorithm's first level rests on, called
from Python through SciPy's LAPACK wrappers (medians of the bare calls, µs).
"""

from __future__ import annotations

import os
import time
from typing import Any

# Must precede the first NumPy import of the process to take effect.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest
from scipy.linalg import lapack

from wbcbench.qp.hls_baselines import (
    ALGORITHMS,
    default_impls,
    fig1_stack,
    get_algorithm,
    scaling_series,
)

SIZES = (10, 20, 40, 60, 80, 100)


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
@pytest.mark.parametrize("impl", default_impls())
def test_hierarchy_time_vs_size(benchmark: Any, impl: str, algorithm: str, n: int) -> None:
    levels = fig1_stack(n)
    solve = get_algorithm(algorithm, impl)
    benchmark.group = f"hls N={n}"
    benchmark.extra_info.update({"N": n, "algorithm": algorithm, "impl": impl})
    result = benchmark(solve, levels)
    assert result.x.shape == (n,)


def _median_us(fn: Any, *args: Any, repeats: int = 300, **kwargs: Any) -> float:
    fn(*args, **kwargs)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(*args, **kwargs)
        times.append(time.perf_counter() - t0)
    return 1e6 * float(np.median(times))


def lapack_table() -> None:
    """LAPACK's and BLAS's own times for one level of the N stack (m = N / 5 rows): the pivoted
    QR of (A Z)ᵀ (dgeqp3, what the reduced and the full QR factorise), the SVD of A P (dgesdd,
    the SVD baseline's), and the full QR's projector P = Z Zᵀ (dgemm, n × n × n), which the
    reduced QR never forms."""
    print("LAPACK / BLAS alone (SciPy's wrappers, NumPy's matmul), one level, median us:")
    print(f"{'N':>4} {'m':>3} {'dgeqp3 (AZ)^T':>14} {'dgesdd AP':>10} {'dgemm Z Z^T':>12}")
    for n in SIZES:
        A = fig1_stack(n)[1].A
        assert A is not None
        Z = np.linalg.svd(fig1_stack(n)[0].A)[2][A.shape[0] :].T  # null space of level 1
        AZt = np.asfortranarray((A @ Z).T)
        P = Z @ Z.T
        AP = np.asfortranarray(A @ P)
        qr = _median_us(lapack.dgeqp3, AZt)
        svd = _median_us(lapack.dgesdd, AP, full_matrices=0)
        proj = _median_us(np.matmul, Z, Z.T)
        print(f"{n:>4} {A.shape[0]:>3} {qr:>14.1f} {svd:>10.1f} {proj:>12.1f}")


def main() -> None:
    """Print the median-time tables of both impls and the ratios to the reduced QR."""
    rows = scaling_series(SIZES, repeats=200)
    med = {(r["N"], r["algorithm"], r["impl"]): r for r in rows}
    for impl in default_impls():
        what = "timed inside the module" if impl == "native" else "timed around the call"
        print(f"{impl} ({what}), median us:")
        print(
            f"{'N':>4} {'reduced_qr':>11} {'full_qr':>11} {'svd':>11} {'full/red':>9} "
            f"{'svd/red':>8}  {'ordering':<26} call (reduced, full, svd)"
        )
        for n in SIZES:
            red, full, svd = (1e6 * med[(n, a, impl)]["median_s"] for a in ALGORITHMS_ORDER)
            calls = " ".join(
                f"{1e6 * med[(n, a, impl)]['call_median_s']:.1f}" for a in ALGORITHMS_ORDER
            )
            order = " < ".join(
                a
                for _, a in sorted(
                    (1e6 * med[(n, a, impl)]["median_s"], a.removesuffix("_qr"))
                    for a in ALGORITHMS_ORDER
                )
            )
            times = f"{red:>11.1f} {full:>11.1f} {svd:>11.1f}"
            print(f"{n:>4} {times} {full / red:>9.2f} {svd / red:>8.2f}  {order:<26} {calls}")
        print()
    lapack_table()


#: the paper's Fig. 1 ordering, fastest first
ALGORITHMS_ORDER = ("reduced_qr", "full_qr", "svd")


if __name__ == "__main__":
    main()
