"""RQR-HQP: Fig. 1."""

from __future__ import annotations

import numpy as np
import pandas as pd

from wbcbench.report import papers as P
from wbcbench.report.load import Results
from wbcbench.report.tables.common import (
    PaperTable,
    _machines,
    _runs,
)

#: the paper's Fig. 1 ordering, fastest first
FIG1_ORDER = ("reduced_qr", "full_qr", "svd")


def _fig1_order(times: dict[str, float]) -> str:
    """``reduced < full < svd`` style ordering of one N's medians, and whether it is the
    paper's."""
    present = {a: t for a, t in times.items() if np.isfinite(t)}
    if len(present) < len(FIG1_ORDER):
        return ""
    order = sorted(present, key=present.__getitem__)
    text = " < ".join(a.removesuffix("_qr") for a in order)
    return f"{text} ({'as' if tuple(order) == FIG1_ORDER else 'not as'} Fig. 1)"


def rqr_fig1(res: Results) -> PaperTable:
    from wbcbench.bench.timing import HLS_SCENARIO

    t = PaperTable("rqr_fig1", "RQR-HQP Fig. 1: hierarchy time vs problem size N", "rqr_hqp", None)
    runs = _runs(res, "timing", HLS_SCENARIO)
    if runs.empty:
        t.missing = "Run a sweep with an `hls_scaling` section (`sweeps/default.yaml` has one)."
        return t
    # rows of results made before the native series have no impl: the Python reference's
    impls_of_runs = runs["impl"] if "impl" in runs else pd.Series([""] * len(runs))
    impl_of = {
        rid: (impl if isinstance(impl, str) and impl else "python")
        for rid, impl in zip(runs["run_id"], impls_of_runs, strict=True)
    }
    m = res.metrics[
        res.metrics["run_id"].isin(runs["run_id"]) & (res.metrics["metric"] == "t_solve_median_us")
    ].copy()
    m["impl"] = m["run_id"].map(impl_of)
    wide = m.pivot_table(
        index="task", columns=["impl", "controller"], values="value", aggfunc="first"
    )
    wide.index = [int(str(i).split("=")[1]) for i in wide.index]
    wide = wide.sort_index()
    frame = pd.DataFrame({"N": wide.index})
    impls = [i for i in ("native", "python") if i in wide.columns.get_level_values(0)]
    algos = [a for a in FIG1_ORDER if a in wide.columns.get_level_values(1)]
    for impl in impls:
        for algo in algos:
            if (impl, algo) in wide.columns:
                frame[f"{algo} {impl} median [µs]"] = wide[(impl, algo)].to_numpy()
    for impl in impls:
        if (impl, "reduced_qr") not in wide.columns:
            continue
        for algo in algos[1:]:
            if (impl, algo) in wide.columns:
                ratio = wide[(impl, algo)] / wide[(impl, "reduced_qr")]
                frame[f"{algo} / reduced_qr ({impl})"] = ratio.to_numpy()
        frame[f"ordering ({impl})"] = [
            _fig1_order({a: float(row.get((impl, a), np.nan)) for a in FIG1_ORDER})
            for _, row in wide.iterrows()
        ]
    t.frame = frame
    t.notes += [
        P.RQR_FIG1_NOTE,
        "native: the C++ mirror of the three algorithms, timed inside the module (no "
        "interpreter); python: the reference, timed around the call. `ordering` gives each "
        "N's medians fastest first and whether that is the paper's (reduced QR < full-size QR "
        "< SVD).",
        _machines(res, "rqr_hqp"),
    ]
    return t
