"""Timing statistics of the measurement protocol: median, IQR, p99, max, deadline misses."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

DEADLINE_1KHZ = 1e-3  # [s]


def timing_stats(samples: np.ndarray, deadline: float = DEADLINE_1KHZ) -> dict[str, float]:
    """Statistics of per-tick times given in seconds, reported in microseconds.

    Returns ``median_us``, ``iqr_us`` (p75 − p25), ``p99_us``, ``max_us``, ``mean_us`` and
    ``miss_rate`` (fraction of ticks over ``deadline``). NaN samples (a stage the solver does not
    report) are ignored; all NaN gives NaN statistics.
    """
    x = np.asarray(samples, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        nan = float("nan")
        return dict(median_us=nan, iqr_us=nan, p99_us=nan, max_us=nan, mean_us=nan, miss_rate=nan)
    p25, p50, p75, p99 = np.percentile(x, [25, 50, 75, 99])
    return dict(
        median_us=1e6 * float(p50),
        iqr_us=1e6 * float(p75 - p25),
        p99_us=1e6 * float(p99),
        max_us=1e6 * float(x.max()),
        mean_us=1e6 * float(x.mean()),
        miss_rate=float(np.mean(x > deadline)),
    )


def shifted_geometric_mean(values: Iterable[float], shift: float = 10.0) -> float:
    """exp(mean(log(x + s))) − s: the aggregate qpbenchmark uses across problems.

    The shift (in the unit of the values, e.g. 10 µs) keeps tiny values from dominating.
    """
    x = np.asarray(list(values), dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return float("nan")
    return float(np.exp(np.mean(np.log(x + shift))) - shift)
