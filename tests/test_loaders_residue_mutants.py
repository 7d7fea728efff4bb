"""Residual mutants of the loaders and of bench/data/inspect_checks.lag_interval."""

from __future__ import annotations

import warnings

import numpy as np

from bench.data.inspect_checks import MAX_LAG_S, lag_interval
from loaders.npy_frames import NpyFramesSequence


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


def _npy_folder(folder, gt_stamps) -> None:
    rng = np.random.default_rng(0)
    for i in range(1, 6):
        np.save(folder / f"frame_{i:03d}.npy", rng.normal(size=(50, 3)) * 10)
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(size=50))
    t = np.asarray(gt_stamps, float)
    np.savetxt(folder / "gt.txt", np.column_stack(
        [t, t * 5.0, np.zeros((len(t), 5)), np.ones(len(t))]))


def test_time_association_of_gt_stamps_that_never_advance(tmp_path):
    """associate="time" with GT rows that all share one stamp (0.3 s, x = 1.5 m): there is
    no GT step to scale a gap limit from, so none is set (max_gap_s None, not a NaN from the
    median of no steps, with its "Mean of empty slice" warning); the one frame at 0.3 s gets
    the pose. Kills NpyFramesSequence._associate 57 (the median taken of no steps)."""
    _npy_folder(tmp_path, [0.3, 0.3, 0.3])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        seq = NpyFramesSequence(tmp_path, period_s=0.1, associate="time")
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert seq.gt_report["max_gap_s"] is None
    np.testing.assert_allclose(seq.ground_truth.stamps, [0.3])
    np.testing.assert_allclose(seq.ground_truth.poses[0, :3, 3], [1.5, 0.0, 0.0])
