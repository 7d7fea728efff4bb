"""Tests for metrics.timing and metrics.divergence."""

import math

import numpy as np

from metrics import RelativeErrorStats, is_diverged, timing_stats


def test_timing_ignores_nan():
    s = timing_stats([np.nan, 1.0, 2.0, 3.0, 10.0])
    assert s["median"] == 2.5 and s["mean"] == 4.0
    assert math.isclose(s["p95"], np.percentile([1.0, 2.0, 3.0, 10.0], 95))


def test_timing_p95_known():
    s = timing_stats(np.arange(1, 102, dtype=float))  # 1..101: p95 at rank 95 -> 96
    assert s == {"median": 51.0, "mean": 51.0, "p95": 96.0}


def test_timing_empty_or_all_nan():
    for times in ([], [np.nan, np.nan]):
        s = timing_stats(times)
        assert set(s) == {"median", "mean", "p95"}
        assert all(math.isnan(v) for v in s.values())


def stats(trans_mean, n=10):
    return RelativeErrorStats(0.1, 0.1, 0.1, 0.0, trans_mean, trans_mean, trans_mean, 0.0, n)


def test_divergence_on_nonfinite_pose():
    est = np.tile(np.eye(4), (5, 1, 1))
    assert not is_diverged(est, {8.0: stats(0.1)})
    est[3, 0, 3] = np.inf
    assert is_diverged(est, {8.0: stats(0.1)})
    est[3, 0, 3] = np.nan
    assert is_diverged(est, {})


def test_divergence_on_error_at_longest_populated_length():
    est = np.tile(np.eye(4), (5, 1, 1))
    # the longest length has no segment: 16 m decides (limit 8 m)
    rel = {8.0: stats(100.0), 16.0: stats(7.9), 48.0: stats(math.nan, n=0)}
    assert not is_diverged(est, rel)
    rel[16.0] = stats(8.1)
    assert is_diverged(est, rel)
    assert not is_diverged(est, {48.0: stats(math.nan, n=0)})
