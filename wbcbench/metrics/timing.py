"""Timing statistics of the measurement protocol: median, IQR, p99, max, deadline misses."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

DEADLINE_1KHZ = 1e-3  # [s]


def timing_stats(samples: np.ndarray, deadline: float = DEADLINE_1KHZ) -> dict[str, float]:
    """Statistics of per-tick times given in seconds, reported in microseconds.

    Returns ``median_us`` with its 95 % confidence interval ``median_ci_lo_us`` /
    ``median_ci_hi_us`` (:func:`median_ci`), ``iqr_us`` (p75 − p25), ``p99_us``, ``max_us``,
    ``mean_us`` and ``miss_rate`` (fraction of ticks over ``deadline``). NaN samples (a stage the
    solver does not report) are ignored; all NaN gives NaN statistics.
    """
    x = np.asarray(samples, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        nan = float("nan")
        return dict(
            median_us=nan,
            median_ci_lo_us=nan,
            median_ci_hi_us=nan,
            iqr_us=nan,
            p99_us=nan,
            max_us=nan,
            mean_us=nan,
            miss_rate=nan,
        )
    p25, p50, p75, p99 = np.percentile(x, [25, 50, 75, 99])
    lo, hi = median_ci(x)
    return dict(
        median_us=1e6 * float(p50),
        median_ci_lo_us=1e6 * lo,
        median_ci_hi_us=1e6 * hi,
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


def median_ci(
    x: np.ndarray, level: float = 0.95, block: int = 10, resamples: int = 300, seed: int = 0
) -> tuple[float, float]:
    """A confidence interval of the median of a time series by the moving-block bootstrap.

    Consecutive ticks are not independent (a hot-started solver's work follows the state), so
    whole blocks of ``block`` ticks are resampled; ``resamples`` medians of such series give the
    interval's percentiles. Seeded: the same samples give the same interval.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    if n < 2:
        v = float(x[0]) if n else float("nan")
        return v, v
    b = max(1, min(block, n))
    starts = np.arange(n - b + 1)
    k = -(-n // b)  # blocks per resampled series
    rng = np.random.default_rng(seed)
    picks = rng.choice(starts, size=(resamples, k))
    series = x[(picks[:, :, None] + np.arange(b)).reshape(resamples, -1)[:, :n]]
    medians = np.median(series, axis=1)
    tail = 50.0 * (1.0 - level)
    lo, hi = np.percentile(medians, [tail, 100.0 - tail])
    return float(lo), float(hi)
