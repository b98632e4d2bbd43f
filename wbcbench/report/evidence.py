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

The ticks cannot see the machine change speed between two runs (on a virtual machine the same
fixed workload may run half as fast a minute later). Each timing row records a speed probe just
before and just after its replay (``conditions.speed_probe_ms``). The interval of a median, and
of a ratio of runs timed apart, is widened by the spread of their probes, ``s = slowest /
fastest − 1``: [lo / (1 + s), hi · (1 + s)]. The rows of a ratio that were timed together,
interleaved in blocks of ticks (``conditions.interleaved``, :mod:`wbcbench.bench.timing`), met the
same changes of speed: their ratio's interval is not widened.
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
    #: the relative spread of the machine's speed the interval was widened by (0: none)
    widened: float = 0.0

    @property
    def finite(self) -> bool:
        return bool(np.isfinite([self.value, self.lo, self.hi]).all())

    def straddles(self, threshold: float) -> bool:
        """Whether the interval contains ``threshold`` (the data cannot tell which side)."""
        return self.finite and self.lo <= threshold <= self.hi

    def widen(self, spread: float) -> Estimate:
        """The interval widened by a relative spread of the machine's speed ``spread``."""
        if not (self.finite and spread > 0):
            return self
        k = 1.0 + spread
        return Estimate(self.value, self.lo / k, self.hi * k, self.source, spread)

    @property
    def note(self) -> str:
        """How much the machine's speed widened the interval, in a clause, or ""."""
        if self.widened < 0.005:
            return ""
        return (
            f"widened by ±{100 * self.widened:.0f} %, the spread of the machine's speed around "
            "the runs"
        )

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
        est = Estimate(float(np.median(x)), lo, hi, "ticks")
    else:
        stored = _stored(res, row, stage, level)
        est = Estimate(stored.value, stored.lo, stored.hi, "stored intervals")
    return est.widen(speed_spread([row]))


def ratio(
    res: Results, a: pd.Series, b: pd.Series, stage: str = "total", level: str = ""
) -> Estimate:
    """median(a) / median(b) of ``stage`` (of ``level``) with its 95 % interval."""
    x, y = tick_us(res, a, stage, level), tick_us(res, b, stage, level)
    if x.size >= 2 and y.size >= 2 and np.median(y) > 0:
        lo, hi = _bootstrap([x, y], lambda p, q: p / np.where(q > 0, q, np.nan))
        est = Estimate(float(np.median(x) / np.median(y)), lo, hi, "ticks")
    else:
        sa, sb = _stored(res, a, stage, level), _stored(res, b, stage, level)
        if not (sa.finite and sb.finite) or min(sb.value, sb.lo) <= 0:
            return NAN
        est = Estimate(sa.value / sb.value, sa.lo / sb.hi, sa.hi / sb.lo, "stored intervals")
    return est if timed_together([a, b]) else est.widen(speed_spread([a, b]))


def timed_together(rows: list[pd.Series]) -> bool:
    """Whether all of ``rows`` were timed in one interleaved group (the same
    ``conditions.interleaved.group``)."""
    groups = {
        str(((_settings(row).get("conditions") or {}).get("interleaved") or {}).get("group", ""))
        for row in rows
    }
    return len(rows) > 1 and len(groups) == 1 and "" not in groups


def speed_spread(rows: pd.DataFrame | list[pd.Series]) -> float:
    """How far the speed probes taken just before and after each of ``rows``
    (``conditions.speed_probe_ms``) spread: slowest / fastest − 1 (0 with fewer than two)."""
    frame = pd.DataFrame(rows) if isinstance(rows, list) else rows
    probes = [
        float(p)
        for _, row in frame.iterrows()
        for p in (_settings(row).get("conditions") or {}).get("speed_probe_ms") or []
        if np.isfinite(float(p)) and float(p) > 0
    ]
    return max(probes) / min(probes) - 1.0 if len(probes) >= 2 else 0.0


def busy(rows: pd.DataFrame | list[pd.Series]) -> str:
    """Why the timings of ``rows`` cannot be compared, in a sentence, else "": a run timed on a
    busy machine (its recorded ``conditions.busy``; the busiest named)."""
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
        return ""
    return (
        f"{count} of {len(frame)} runs behind it were timed on a busy machine (load "
        f"{worst.get('load_1min', float('nan')):g}, {other_work(worst)})"
    )
