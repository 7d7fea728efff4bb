"""metrics/relative.py, what tests/test_metrics_relative.py leaves open (make mutate's
survivors): the pairing's defaults and tolerance (passed on, not replaced by the default), the
last start pose and the shortest path (two poses), a tolerance of zero and lengths under a
metre, the statistics of a single segment and every statistic's value, the messages a user
reads, a diverged estimate summarised without RuntimeWarnings, and an estimate whose
translation overflows keeping its rotation error.

Known answers: straight GT paths with chosen steps, whose travelled distances (and so the
accepted segments) are counted by hand from the definition in the module docstring."""

import re
import warnings

import numpy as np
import pytest

from metrics.relative import (
    MetricError,
    SegmentErrors,
    check_pose_pair,
    relative_errors,
    relative_segments,
    rotation_angle_deg,
    segment_errors,
    segment_pairs,
    stats_from_segments,
)


def line_poses(distances, yaw=None):
    """Poses along x at the given travelled distances, with an optional yaw per pose [rad]."""
    d = np.asarray(distances, float)
    poses = np.tile(np.eye(4), (len(d), 1, 1))
    poses[:, 0, 3] = d
    if yaw is not None:
        c, s = np.cos(yaw), np.sin(yaw)
        poses[:, 0, 0], poses[:, 0, 1], poses[:, 1, 0], poses[:, 1, 1] = c, -s, s, c
    return poses


def scaled(gt, factor):
    est = gt.copy()
    est[:, :3, 3] *= factor
    return est


def test_the_default_tolerance_is_a_fifth_of_the_length():
    # 5 m steps: the closest pose to 8 m is 2 m off (more than 0.2 x 8 = 1.6 m, less than 1.2 x 8)
    dist = np.arange(0.0, 60.0, 5.0)
    start, end = segment_pairs(dist, 8.0)
    assert start.size == 0 and end.size == 0
    start, end = segment_pairs(dist, 10.0)
    np.testing.assert_array_equal(end - start, 2)
    gt = line_poses(dist)
    segs = relative_segments(gt, scaled(gt, 1.01), [8.0, 10.0])
    assert segs[8.0].trans_m.size == 0 and segs[10.0].trans_m.size == 10
    stats = relative_errors(gt, scaled(gt, 1.01), [8.0, 10.0])
    assert stats[8.0].n == 0 and stats[10.0].n == 10


def test_the_tolerance_given_is_the_one_used():
    gt = line_poses(np.arange(0.0, 60.0, 5.0))
    est = scaled(gt, 1.01)
    # a quarter of 8 m is 2 m: the 10 m segments are accepted as 8 m ones
    for got in (segment_errors(gt, est, 8.0, tolerance=0.25),
                relative_segments(gt, est, [8.0], tolerance=0.25)[8.0]):
        np.testing.assert_array_equal(got.start_idx, np.arange(10))
        np.testing.assert_array_equal(got.end_idx, np.arange(2, 12))
        np.testing.assert_allclose(got.trans_m, 0.1, rtol=1e-9)  # 1 % of the 10 m travelled
    assert relative_errors(gt, est, [8.0], tolerance=0.25)[8.0].n == 10
    # and a tolerance smaller than the default refuses what the default would accept
    gt = line_poses(np.arange(0.0, 40.0, 1.5))  # 7.5 m is 0.5 m from 8 m
    assert relative_errors(gt, gt.copy(), [8.0, 9.0])[8.0].n > 0
    stats = relative_errors(gt, gt.copy(), [8.0, 9.0], tolerance=0.05)
    assert stats[8.0].n == 0 and stats[9.0].n == len(gt) - 6


def test_the_last_step_is_a_segment_and_two_poses_are_a_path():
    start, end = segment_pairs(np.array([0.0, 1.0, 9.0]), 8.0)
    np.testing.assert_array_equal(start, [0, 1])  # 0 -> 2 is 9 m (1 m off), 1 -> 2 is 8 m
    np.testing.assert_array_equal(end, [2, 2])
    start, end = segment_pairs(np.array([0.0, 8.0]), 8.0)
    np.testing.assert_array_equal(start, [0])
    np.testing.assert_array_equal(end, [1])
    start, end = segment_pairs(np.array([0.0]), 8.0)
    assert start.size == 0 and end.size == 0


def test_a_tolerance_of_zero_accepts_exact_lengths_only():
    gt = line_poses(np.arange(0.0, 20.0, 1.0))
    seg = segment_errors(gt, gt.copy(), 4.0, tolerance=0.0)
    np.testing.assert_array_equal(seg.end_idx - seg.start_idx, 4)
    assert seg.trans_m.size == 16
    assert segment_errors(gt, gt.copy(), 4.5, tolerance=0.0).trans_m.size == 0


def test_a_segment_shorter_than_a_metre_is_allowed():
    gt = line_poses(np.arange(0.0, 5.0, 0.25))
    seg = segment_errors(gt, scaled(gt, 1.1), 0.5)
    np.testing.assert_array_equal(seg.end_idx - seg.start_idx, 2)
    np.testing.assert_allclose(seg.trans_m, 0.05, rtol=1e-9)  # 10 % of 0.5 m


def test_one_segment_has_its_own_value_as_every_statistic():
    gt = line_poses([0.0, 8.0], yaw=[0.0, 0.0])
    est = line_poses([0.0, 8.4], yaw=[0.0, np.radians(3.0)])
    stats = relative_errors(gt, est, [8.0])[8.0]
    assert stats.n == 1
    assert stats.trans_m_mean == stats.trans_m_median == stats.trans_m_rmse == \
        pytest.approx(0.4, rel=1e-12)
    assert stats.rot_deg_mean == stats.rot_deg_median == stats.rot_deg_rmse == \
        pytest.approx(3.0, rel=1e-12)
    assert stats.trans_m_std == 0.0 and stats.rot_deg_std == 0.0


def test_every_statistic_is_its_definition():
    # segments of 4 m on a 1 m grid; the estimate's yaw grows by a chosen angle per step, so
    # each segment's rotation error is the sum of 4 steps' angles
    n = 12
    steps = np.radians(np.array([0.1, 0.5, 0.2, 0.9, 0.3, 0.3, 0.0, 0.7, 0.4, 0.8, 0.6]))
    gt = line_poses(np.arange(n, dtype=float), yaw=np.zeros(n))
    est = line_poses(np.arange(n, dtype=float), yaw=np.concatenate([[0.0], np.cumsum(steps)]))
    seg = segment_errors(gt, est, 4.0)
    expected_rot = np.degrees([steps[i:i + 4].sum() for i in range(n - 4)])
    np.testing.assert_allclose(seg.rot_deg, expected_rot, rtol=1e-9)
    stats = stats_from_segments(seg)
    assert stats.n == n - 4
    assert stats.rot_deg_mean == pytest.approx(np.mean(expected_rot), rel=1e-9)
    assert stats.rot_deg_median == pytest.approx(np.median(expected_rot), rel=1e-9)
    assert stats.rot_deg_rmse == pytest.approx(np.sqrt(np.mean(expected_rot**2)), rel=1e-9)
    assert stats.rot_deg_std == pytest.approx(np.std(expected_rot), rel=1e-9)
    assert stats.trans_m_median == pytest.approx(np.median(seg.trans_m), rel=1e-9)
    assert stats.trans_m_std == pytest.approx(np.std(seg.trans_m), rel=1e-9)


def test_the_messages_name_what_was_wrong():
    gt = line_poses(np.arange(0.0, 20.0))
    with pytest.raises(MetricError, match="^no segment length requested$"):
        relative_errors(gt, gt.copy(), [])
    for length in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(MetricError, match="^" + re.escape(
                f"segment length must be a positive number of metres, got {length}") + "$"):
            segment_errors(gt, gt.copy(), length)
    for tolerance in (-0.1, np.nan, np.inf):
        with pytest.raises(MetricError, match="^" + re.escape(
                f"tolerance must be a non-negative fraction of L, got {tolerance}") + "$"):
            segment_errors(gt, gt.copy(), 4.0, tolerance)
    with pytest.raises(MetricError, match="^" + re.escape(
            "no relative-error segment found: GT path length is 19.000 m, shortest requested "
            "segment length is 30 m (tolerance 0.2 x L)") + "$"):
        relative_errors(gt, gt.copy(), [40.0, 30.0])


def test_a_diverged_estimate_is_summarised_without_runtime_warnings():
    gt = line_poses(np.arange(0.0, 60.0, 0.5))
    est = gt.copy()
    est[40:, :3, 3] = np.inf
    est[80:] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stats = relative_errors(gt, est, [8.0, 16.0])
        seg = segment_errors(gt, est, 8.0)
    assert stats[8.0].n == seg.trans_m.size > 0
    assert np.isnan(stats[8.0].trans_m_std) and np.isnan(stats[8.0].rot_deg_mean)
    # errors whose squares overflow: the mean and std stay exact, and no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        huge = stats_from_segments(SegmentErrors(np.arange(2), np.arange(2) + 1,
                                                 np.array([1e200, 1e200]),
                                                 np.array([1e200, 1e200])))
    assert huge.trans_m_mean == 1e200 and huge.trans_m_std == 0.0


def test_an_estimate_whose_translation_overflows_keeps_its_rotation_error():
    # positions of +-1e308 m are finite, but each step between them overflows; the relative
    # rotations are still exact (identity on both sides), so the rotation error is 0
    gt = line_poses(np.arange(6.0))
    est = np.tile(np.eye(4), (6, 1, 1))
    est[:, 0, 3] = 1e308 * (-1.0) ** np.arange(6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        seg = segment_errors(gt, est, 1.0)
    assert seg.trans_m.size == 5 and not np.isfinite(seg.trans_m).any()
    np.testing.assert_array_equal(seg.rot_deg, 0.0)


def test_rotation_angles_of_non_finite_or_huge_matrices_warn_nothing():
    inf = np.tile(np.eye(3), (3, 1, 1))
    inf[0] = np.inf  # inf - inf in the axis vector
    inf[1, 0, 0] = np.inf
    huge = np.tile(np.eye(3), (2, 1, 1)) * 1e308  # the trace overflows
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        angles = rotation_angle_deg(inf)
        assert np.isnan(angles[:2]).all() and angles[2] == 0.0
        np.testing.assert_array_equal(rotation_angle_deg(huge), 0.0)  # atan2(0, inf)


def test_integer_poses_are_read_as_float():
    gt = line_poses(np.arange(0.0, 12.0)).astype(int)
    est = gt.copy()
    est[:, 0, 3] *= 2
    checked_gt, checked_est = check_pose_pair(gt, est)
    assert checked_gt.dtype == np.float64 and checked_est.dtype == np.float64
    np.testing.assert_allclose(segment_errors(gt, est, 4.0).trans_m, 4.0)


def test_pose_arrays_are_named_in_their_messages():
    gt = line_poses(np.arange(5.0))
    for bad, name in (((gt[:, :3], gt), "gt_poses"), ((gt, gt[:, :, :3]), "est_poses")):
        shape = bad[0].shape if name == "gt_poses" else bad[1].shape
        with pytest.raises(MetricError, match="^" + re.escape(
                f"{name} must have shape (N, 4, 4), got {shape}") + "$"):
            check_pose_pair(*bad)
    with pytest.raises(MetricError, match="^" + re.escape(
            "gt_poses and est_poses must be associated 1:1, got 5 GT poses and 3 estimated "
            "poses") + "$"):
        check_pose_pair(gt, gt[:3])
    nonfinite = gt.copy()
    nonfinite[3, 1, 3] = np.nan
    nonfinite[4, 0, 0] = np.inf
    with pytest.raises(MetricError, match="^" + re.escape(
            "gt_poses contain non-finite values at 2 poses (first: index 3)") + "$"):
        check_pose_pair(nonfinite, gt)


def test_an_empty_trajectory_is_refused_and_one_pose_is_a_trajectory():
    empty = np.zeros((0, 4, 4))
    with pytest.raises(MetricError, match="^empty trajectory: no poses given$"):
        check_pose_pair(empty, empty)
    one = line_poses([3.0])
    gt, est = check_pose_pair(one, one)
    assert gt.shape == est.shape == (1, 4, 4)
    assert segment_errors(one, one, 1.0).trans_m.size == 0


def test_a_pause_at_the_start_pairs_as_evo_does_with_a_wide_tolerance():
    """GT pauses for three poses, then jumps 30 m: with tolerance 1 (a segment may be 0..2 L
    long) the closest pose to 8 m from a pose in the pause is the next one in the pause (0 m,
    8 m off; the jump is 22 m off); evo's first minimum of |d - L| over the later poses."""
    from evo.core.filters import filter_pairs_by_path

    dist = np.array([0.0, 0.0, 0.0, 30.0, 31.0])
    start, end = segment_pairs(dist, 8.0, tolerance=1.0)
    expected = filter_pairs_by_path(list(line_poses(dist)), 8.0, 8.0, all_pairs=True)
    assert list(zip(start.tolist(), end.tolist(), strict=True)) == expected
    assert expected[:2] == [(0, 1), (1, 2)]


def test_an_infinite_segment_error_is_summarised_without_warnings():
    seg = SegmentErrors(np.arange(3), np.arange(3) + 1, np.array([1.0, 2.0, np.inf]),
                        np.array([0.5, np.inf, 0.5]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stats = stats_from_segments(seg)
    assert stats.trans_m_mean == np.inf and stats.trans_m_median == 0.5
    assert np.isnan(stats.trans_m_std)  # inf - inf about the mean: undefined
    assert stats.rot_deg_median == 2.0 and stats.rot_deg_rmse == np.inf
