"""Time of the three hierarchy algorithms against the problem size N (RQR-HQP paper, Fig. 1).

Run with ``pytest benchmarks/bench_hls.py --benchmark-enable`` (pytest-benchmark), or as a script
for the plain median table: ``python benchmarks/bench_hls.py``.

Every algorithm solves the same fixed-shape stack (``fig1_stack``: 4 equality levels that
together constrain 80 % of the N variables). BLAS runs single-threaded: at these sizes OpenBLAS
threads cost more than they save (measured up to 50x slower per level with two threads) and
make the timings depend on what else the machine does.
"""

from __future__ import annotations

import os
from typing import Any

# Must precede the first NumPy import of the process to take effect.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest

from wbcbench.qp.hls_baselines import ALGORITHMS, fig1_stack, scaling_series

SIZES = (10, 20, 40, 60, 80, 100)


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_hierarchy_time_vs_size(benchmark: Any, algorithm: str, n: int) -> None:
    levels = fig1_stack(n)
    solve = ALGORITHMS[algorithm]
    benchmark.group = f"hls N={n}"
    benchmark.extra_info.update({"N": n, "algorithm": algorithm})
    result = benchmark(solve, levels)
    assert result.x.shape == (n,)


def main() -> None:
    """Print the median-time table and the speed-up of the reduced QR method."""
    rows = scaling_series(SIZES, repeats=200)
    med = {(r["N"], r["algorithm"]): r["median_s"] for r in rows}
    print(f"{'N':>4} {'reduced_qr':>11} {'full_qr':>11} {'svd':>11} {'full/red':>9} {'svd/red':>8}")
    for n in SIZES:
        red, full, svd = (med[(n, a)] * 1e6 for a in ("reduced_qr", "full_qr", "svd"))
        times = f"{red:>9.1f}us {full:>9.1f}us {svd:>9.1f}us"
        print(f"{n:>4} {times} {full / red:>9.2f} {svd / red:>8.2f}")


if __name__ == "__main__":
    main()
