"""Residual mutants of the loaders and of bench/data/inspect_checks.lag_interval."""

from __future__ import annotations

import numpy as np

from bench.data.inspect_checks import MAX_LAG_S, lag_interval


def _speed(t: np.ndarray) -> np.ndarray:
    """A smooth, non-periodic-looking speed (m/s)."""
    return 5 + np.sin(2 * np.pi * t / 7.0) + 0.5 * np.sin(2 * np.pi * t / 3.1)


def test_lag_interval_refines_a_sub_step_lag():
    """GT that is the Doppler speed delayed by 4 ms (less than half the 10 ms lag step): the
    parabolic refinement of the correlation peak finds 4 ms to within 0.5 ms. Kills
    lag_interval 177 (the curvature 2 * r[k] written 2 / r[k]: a third of the shift)."""
    t = np.arange(0, 60, 0.1)
    lag = 0.004
    lo, hi = lag_interval(t, _speed(t), _speed(t - lag))
    assert lo <= hi
    np.testing.assert_allclose([lo, hi], [lag, lag], atol=5e-4)


def _fast(t: np.ndarray) -> np.ndarray:
    return 5 + np.sin(2 * np.pi * t / 1.7) + 0.5 * np.sin(2 * np.pi * t / 0.93)


def test_lag_interval_is_finite_when_the_gt_covers_only_one_end():
    """GT only over the first 3 s of a 30 s record (31 scans): at the lags that push the GT
    window off the scans fewer than 10 scans overlap, so the best lag of a replicate can sit
    next to a lag with no correlation; the interval must still be two finite lags within
    +-MAX_LAG_S (not refined against a missing neighbour). Kills lag_interval 167 (the k - 1
    neighbour not checked) and 170 (the k + 1 neighbour not checked)."""
    t = np.arange(0, 30, 0.1)
    for covered, shift in ((t <= 3.05, -0.3), (t >= 26.95, 0.3)):
        v_g = np.where(covered, _fast(t - shift), np.nan)
        interval = lag_interval(t, _fast(t), v_g)
        assert interval is not None
        lo, hi = interval
        assert np.isfinite(lo) and np.isfinite(hi)
        assert -MAX_LAG_S - 1e-9 <= lo <= hi <= MAX_LAG_S + 1e-9
