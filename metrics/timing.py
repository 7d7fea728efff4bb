"""Runtime statistics of per-frame registration times (milliseconds in, milliseconds out)."""

from __future__ import annotations

import numpy as np


def timing_stats(times_ms) -> dict[str, float]:
    """Median, mean and 95th percentile (linear interpolation) of ``times_ms`` [ms].

    NaN entries are ignored (e.g. the first frame, which has no registration). With no valid
    entry every value is NaN.
    """
    t = np.asarray(times_ms, dtype=np.float64).ravel()
    t = t[~np.isnan(t)]
    if t.size == 0:
        return {"median": np.nan, "mean": np.nan, "p95": np.nan}
    return {
        "median": float(np.median(t)),
        "mean": float(np.mean(t)),
        "p95": float(np.percentile(t, 95)),
    }
