"""What the figures shade and say about a run's metrics window, from synthetic logs."""

from __future__ import annotations

import pandas as pd

from wbcbench.report.plots import _window_in_data


def _log(t0: float, t1: float) -> pd.DataFrame:
    return pd.DataFrame({"t": [t0, (t0 + t1) / 2, t1]})


def test_the_window_is_shaded_only_where_a_run_logged() -> None:
    # the whole window logged: shaded as it stands
    assert _window_in_data((1.0, 2.0), [_log(0.0, 3.0)]) == ((1.0, 2.0), "shaded: metrics window")
    # a shortened run ends inside the window: cut to its end, and the title says so
    window, note = _window_in_data((0.5, 4.0), [_log(0.0, 0.98), _log(0.0, 0.5)])
    assert window == (0.5, 0.98)
    assert note == "shaded: the metrics window 0.5–4 s where logged"
    # a run that ends before the window starts: nothing shaded, the title says where it lies
    assert _window_in_data((3.0, 40.0), [_log(0.0, 0.98)]) == (
        None,
        "metrics window 3–40 s: beyond these runs",
    )
    assert _window_in_data(None, [_log(0.0, 1.0)]) == (None, "")
    assert _window_in_data((1.0, 2.0), [pd.DataFrame()]) == (None, "")
