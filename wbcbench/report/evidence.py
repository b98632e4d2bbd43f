"""The numbers a speed verdict rests on: medians of replayed tick times and ratios of medians,
each with a 95 % bootstrap confidence interval, and the machine's load while they were timed.

Where a timing run kept its per-tick times (``logs/<run_id>.parquet``, the default), the
interval of a median, or of a ratio of two runs' medians, is a percentile bootstrap over the
ticks after the warm-up (:data:`RESAMPLES` resamples, seed :data:`SEED`). The ticks are sorted
before they are resampled, so the interval depends on the distribution of the tick times and
not on their order: the same results give the same verdicts whatever order their ticks were
stored in. The two runs of a ratio are resampled independently (they replay the same states, so
this interval is, if anything, wider than a paired one).

A run that kept no per-tick times falls back on the interval its row stores
(``t_<stage>_median_ci_lo_us`` / ``_hi_us``, a moving-block bootstrap over its ticks): a ratio's
interval is then the quotient of the two intervals' ends, [lo_a / hi_b, hi_a / lo_b], wider than
the bootstrap's.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from wbcbench.bench.provenance import other_work, other_work_per_core
from wbcbench.report.load import Results

#: bootstrap resamples and seed (fixed: the same ticks give the same interval)
RESAMPLES = 2000
SEED = 0
#: the confidence level of every interval
LEVEL = 0.95


@dataclass(frozen=True)
class Estimate:
    """A median (or a ratio of medians) with its confidence interval and where it comes from."""

    value: float
    lo: float
    hi: float
    source: str  # "ticks" (bootstrap over the stored ticks) or "stored intervals"

    @property
    def finite(self) -> bool:
        return bool(np.isfinite([self.value, self.lo, self.hi]).all())

    def straddles(self, threshold: float) -> bool:
        """Whether the interval contains ``threshold`` (the data cannot tell which side)."""
        return self.finite and self.lo <= threshold <= self.hi

    def text(self, unit: str = "×", digits: int = 3) -> str:
        f = f"{{:.{digits}g}}"
        return (
            f"{f.format(self.value)}{unit} [{f.format(self.lo)}, {f.format(self.hi)}]"
            if self.finite
            else "—"
        )


NAN = Estimate(float("nan"), float("nan"), float("nan"), "none")


def _settings(row: pd.Series) -> dict[str, Any]:
    try:
        info = json.loads(str(row.get("settings") or "{}"))
    except ValueError:
        return {}
    return info if isinstance(info, dict) else {}


def tick_us(res: Results, row: pd.Series, stage: str = "total", level: str = "") -> np.ndarray:
    """The run's per-tick times of ``stage`` (of hierarchy ``level`` when given) after its
    warm-up, in µs; empty when the run kept no per-tick times."""
    log = res.log(str(row["run_id"]))
    column = f"time.{stage}" + (f".{level}" if level else "")
    if log.empty or column not in log:
        return np.empty(0)
    x = log[column].to_numpy(dtype=float)
    warmup = min(int(_settings(row).get("warmup", 0)), max(0, len(x) - 1))
    x = x[warmup:]
    return 1e6 * x[np.isfinite(x)]


def _stored(res: Results, row: pd.Series, stage: str, level: str) -> Estimate:
    m = res.metrics
    if m.empty:
        return NAN
    sel = m[(m["run_id"] == row["run_id"]) & (m["task"].astype(str) == (level or "*"))]
    values = sel.drop_duplicates("metric").set_index("metric")["value"]

    def get(name: str) -> float:
        return float(values.get(f"t_{stage}_{name}", np.nan))

    return Estimate(get("median_us"), get("median_ci_lo_us"), get("median_ci_hi_us"), "stored")


def _bootstrap(
    samples: list[np.ndarray], statistic: Callable[..., np.ndarray]
) -> tuple[float, float]:
    rng = np.random.default_rng(SEED)
    draws = []
    for x in samples:
        x = np.sort(x)  # order-free: the interval depends on the values only
        draws.append(x[rng.integers(0, x.size, size=(RESAMPLES, x.size))])
    values = statistic(*(np.median(d, axis=1) for d in draws))
    tail = 50.0 * (1.0 - LEVEL)
    lo, hi = np.percentile(values, [tail, 100.0 - tail])
    return float(lo), float(hi)


def median(res: Results, row: pd.Series, stage: str = "total", level: str = "") -> Estimate:
    """The median tick time of one run's ``stage`` [µs] with its 95 % interval."""
    x = tick_us(res, row, stage, level)
    if x.size >= 2:
        lo, hi = _bootstrap([x], lambda m: m)
        return Estimate(float(np.median(x)), lo, hi, "ticks")
    stored = _stored(res, row, stage, level)
    return Estimate(stored.value, stored.lo, stored.hi, "stored intervals")


def ratio(
    res: Results, a: pd.Series, b: pd.Series, stage: str = "total", level: str = ""
) -> Estimate:
    """median(a) / median(b) of ``stage`` (of ``level``) with its 95 % interval."""
    x, y = tick_us(res, a, stage, level), tick_us(res, b, stage, level)
    if x.size >= 2 and y.size >= 2 and np.median(y) > 0:
        lo, hi = _bootstrap([x, y], lambda p, q: p / np.where(q > 0, q, np.nan))
        return Estimate(float(np.median(x) / np.median(y)), lo, hi, "ticks")
    sa, sb = _stored(res, a, stage, level), _stored(res, b, stage, level)
    if not (sa.finite and sb.finite) or min(sb.value, sb.lo) <= 0:
        return NAN
    return Estimate(sa.value / sb.value, sa.lo / sb.hi, sa.hi / sb.lo, "stored intervals")


def busy(rows: pd.DataFrame | list[pd.Series]) -> str:
    """Why the timings of ``rows`` cannot be compared, in a sentence, else "": a run timed on a
    busy machine (its recorded ``conditions.busy``; the busiest named), or the machine's speed
    moving between the runs (:func:`speed_shift`)."""
    frame = pd.DataFrame(rows) if isinstance(rows, list) else rows
    worst: dict[str, Any] | None = None
    count = 0
    for _, row in frame.iterrows():
        conditions = _settings(row).get("conditions") or {}
        if conditions.get("busy"):
            count += 1
            if worst is None or other_work_per_core(conditions) > other_work_per_core(worst):
                worst = conditions
    if worst is None:
        return speed_shift(frame)
    return (
        f"{count} of {len(frame)} runs behind it were timed on a busy machine (load "
        f"{worst.get('load_1min', float('nan')):g}, {other_work(worst)})"
    )


#: the largest spread of the speed probes around the runs behind a verdict (slowest / fastest
#: − 1) at which their times still compare
SPEED_SHIFT = 0.15


def speed_shift(rows: pd.DataFrame | list[pd.Series]) -> str:
    """A sentence when the speed probes taken just before and after each of ``rows``
    (``conditions.speed_probe_ms``) spread by more than :data:`SPEED_SHIFT`: the machine ran
    the same fixed workload that much slower at one time than at another, so the runs' times
    are not comparable; else ""."""
    frame = pd.DataFrame(rows) if isinstance(rows, list) else rows
    probes = [
        float(p)
        for _, row in frame.iterrows()
        for p in (_settings(row).get("conditions") or {}).get("speed_probe_ms") or []
        if np.isfinite(float(p)) and float(p) > 0
    ]
    if len(probes) < 2 or max(probes) / min(probes) - 1.0 <= SPEED_SHIFT:
        return ""
    return (
        f"the machine's speed moved while the {len(frame)} runs behind it were timed: a fixed "
        f"workload took {min(probes):.3g}–{max(probes):.3g} ms around them "
        f"(+{100 * (max(probes) / min(probes) - 1):.0f} %, above {100 * SPEED_SHIFT:.0f} %)"
    )
