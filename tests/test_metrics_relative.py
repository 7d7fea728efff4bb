"""Tests for metrics.relative: known answers, pairing across a GT pause, and evo cross-check."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from metrics import DEFAULT_LENGTHS_M, MetricError, relative_errors, segment_errors
from metrics.relative import path_distances, rotation_angle_deg


def poses_from(positions, rotvecs=None):
    """(N,4,4) T_world_body from (N,3) positions and optional (N,3) rotation vectors [rad]."""
    positions = np.asarray(positions, dtype=float)
    n = positions.shape[0]
    poses = np.tile(np.eye(4), (n, 1, 1))
    if rotvecs is not None:
        poses[:, :3, :3] = Rotation.from_rotvec(rotvecs).as_matrix()
    poses[:, :3, 3] = positions
    return poses


def straight_line(n=1000, step=0.1):
    return np.column_stack([step * np.arange(n), np.zeros(n), np.zeros(n)])


def yaw_rotvecs(yaw):
    return np.column_stack([np.zeros_like(yaw), np.zeros_like(yaw), yaw])


def smooth_trajectory(rng, n, with_pause=False):
    """Random planar-ish drive: varying speed (with near-stops) and yaw rate, some z/roll/pitch."""
    dt = 0.1
    phase = rng.uniform(0, 2 * np.pi)
    speed = 1.0 + np.sin(2 * np.pi * np.arange(n) / 300 + phase) + rng.normal(0, 0.2, n)
    speed = np.clip(speed, 0.0, 3.0)  # includes stretches of (near) standstill
    if with_pause:
        speed[n // 3 : n // 3 + 40] = 0.0
    yaw = np.cumsum(rng.normal(0, 0.03, n))
    step = (
        np.column_stack([np.cos(yaw), np.sin(yaw), 0.02 * rng.normal(size=n)])
        * (speed * dt)[:, None]
    )
    pos = np.cumsum(step, axis=0)
    rv = np.column_stack([0.01 * rng.normal(size=n), 0.01 * rng.normal(size=n), yaw])
    return poses_from(pos, rv)


def noisy_estimate(rng, gt):
    """Estimate with a slowly growing drift plus white noise on every pose."""
    n = gt.shape[0]
    drift = np.cumsum(rng.normal(0, 0.002, (n, 3)), axis=0)
    drift_rot = np.cumsum(rng.normal(0, 0.0005, (n, 3)), axis=0)
    noise = poses_from(
        drift + rng.normal(0, 0.02, (n, 3)), drift_rot + rng.normal(0, 0.002, (n, 3))
    )
    return gt @ noise


# ---------------------------------------------------------------- known answers


def test_scale_error_on_straight_line_gives_one_percent_of_segment_length():
    gt = poses_from(straight_line())
    est = poses_from(1.01 * straight_line())
    dist = path_distances(gt[:, :3, 3])
    for length in DEFAULT_LENGTHS_M:
        seg = segment_errors(gt, est, length)
        travelled = dist[seg.end_idx] - dist[seg.start_idx]
        np.testing.assert_allclose(seg.trans_m, 0.01 * travelled, rtol=0, atol=1e-10)
        np.testing.assert_allclose(seg.rot_deg, 0.0, atol=1e-9)
        # interior segments are exactly L long (L / 0.1 poses apart) -> error 0.01 L
        steps = round(length / 0.1)
        interior = seg.start_idx + steps <= 999
        assert np.all(seg.end_idx[interior] == seg.start_idx[interior] + steps)
        np.testing.assert_allclose(seg.trans_m[interior], 0.01 * length, atol=1e-10)
        # near the end, shorter segments are accepted down to 0.8 L
        assert np.all(travelled >= 0.8 * length - 1e-9)
        # every start with at least 0.8 L of path left has a segment (exact 0.8 L: rounding)
        expected = np.flatnonzero(dist[-1] - dist >= 0.8 * length + 1e-6)
        assert np.all(np.isin(expected, seg.start_idx))
        assert seg.start_idx.size <= expected.size + 1


def test_constant_yaw_rate_bias_gives_bias_times_elapsed_frames():
    n = 800
    gt = poses_from(straight_line(n))
    bias = 1e-3  # rad per frame
    est = poses_from(straight_line(n), yaw_rotvecs(bias * np.arange(n)))
    seg = segment_errors(gt, est, 16.0)
    assert seg.start_idx.size > 0
    np.testing.assert_allclose(
        seg.rot_deg, np.degrees(bias * (seg.end_idx - seg.start_idx)), rtol=0, atol=1e-9
    )
    stats = relative_errors(gt, est, [16.0])[16.0]
    interior = seg.end_idx - seg.start_idx == 160
    assert interior.sum() > 500
    assert math.isclose(np.median(seg.rot_deg[interior]), math.degrees(0.16), abs_tol=1e-9)
    assert stats.n == seg.start_idx.size


def test_gt_pause_pairs_the_right_poses():
    # 0.1 m/pose for poses 0..99, standing still for poses 100..149, moving again after.
    n = 400
    x = np.concatenate([0.1 * np.arange(100), np.full(50, 9.9), 9.9 + 0.1 * np.arange(1, 251)])
    gt = poses_from(np.column_stack([x, np.zeros(n), np.zeros(n)]))
    rng = np.random.default_rng(3)
    est = poses_from(gt[:, :3, 3] + rng.normal(0, 0.05, (n, 3)), rng.normal(0, 0.01, (n, 3)))
    seg = segment_errors(gt, est, 8.0)
    ends = dict(zip(seg.start_idx.tolist(), seg.end_idx.tolist(), strict=True))
    assert ends[0] == 80
    # the end (9.9 m) lies on the pause: the earliest pose there is taken
    assert ends[19] == 99
    # a segment crossing the pause ends 8 m further along the path, 50 poses later
    assert ends[30] == 30 + 80 + 50
    # every start during the pause shares one end, 8 m after the pause position
    for i in range(99, 150):
        assert ends[i] == 149 + 80
    # errors are computed on exactly those poses
    for i, j, t, r in zip(seg.start_idx, seg.end_idx, seg.trans_m, seg.rot_deg, strict=True):
        e = np.linalg.inv(np.linalg.inv(gt[i]) @ gt[j]) @ (np.linalg.inv(est[i]) @ est[j])
        assert math.isclose(t, np.linalg.norm(e[:3, 3]), abs_tol=1e-12)
        assert math.isclose(
            r, np.degrees(Rotation.from_matrix(e[:3, :3]).magnitude()), abs_tol=1e-9
        )


def test_stats_match_segment_arrays_and_empty_length_is_nan():
    rng = np.random.default_rng(0)
    gt = smooth_trajectory(rng, 600)
    est = noisy_estimate(rng, gt)
    total = path_distances(gt[:, :3, 3])[-1]
    too_long = float(np.ceil(total * 2))
    rel = relative_errors(gt, est, [8.0, too_long])
    seg = segment_errors(gt, est, 8.0)
    s = rel[8.0]
    assert s.n == seg.trans_m.size > 0
    assert math.isclose(s.trans_m_mean, np.mean(seg.trans_m))
    assert math.isclose(s.trans_m_median, np.median(seg.trans_m))
    assert math.isclose(s.trans_m_rmse, np.sqrt(np.mean(seg.trans_m**2)))
    assert math.isclose(s.trans_m_std, np.std(seg.trans_m))
    assert math.isclose(s.rot_deg_mean, np.mean(seg.rot_deg))
    assert math.isclose(s.rot_deg_rmse, np.sqrt(np.mean(seg.rot_deg**2)))
    empty = rel[too_long]
    assert empty.n == 0
    assert math.isnan(empty.trans_m_mean) and math.isnan(empty.rot_deg_rmse)


# ---------------------------------------------------------------- errors / edge cases


def test_no_segment_at_any_length_raises_with_path_length():
    gt = poses_from(straight_line(50))  # 4.9 m
    with pytest.raises(MetricError, match=r"4\.900 m.*8 m"):
        relative_errors(gt, gt.copy())


def test_shape_mismatch_and_nonfinite_gt_raise():
    gt = poses_from(straight_line(100))
    with pytest.raises(MetricError, match="1:1"):
        relative_errors(gt, gt[:-1])
    with pytest.raises(MetricError, match=r"\(N, 4, 4\)"):
        relative_errors(gt[:, :3, :], gt)
    bad = gt.copy()
    bad[10, 0, 3] = np.nan
    with pytest.raises(MetricError, match="non-finite"):
        relative_errors(bad, gt)
    with pytest.raises(MetricError):
        segment_errors(gt, gt, 0.0)


def test_nonfinite_estimate_does_not_crash():
    gt = poses_from(straight_line(300))
    est = gt.copy()
    est[150:, :3, 3] = np.inf
    est[200:] = np.nan
    rel = relative_errors(gt, est, [8.0])
    seg = segment_errors(gt, est, 8.0)
    finite = seg.end_idx < 150
    np.testing.assert_allclose(seg.trans_m[finite], 0.0, atol=1e-12)
    assert not np.any(np.isfinite(seg.trans_m[~finite]))
    assert np.all(np.isnan(seg.rot_deg[seg.end_idx >= 200]))
    assert rel[8.0].n == seg.trans_m.size
    assert not math.isfinite(rel[8.0].trans_m_mean)


# ---------------------------------------------------------------- cross-check against evo


def evo_rpe(gt, est, length, relation, tol=0.2):
    from evo.core import metrics
    from evo.core.trajectory import PosePath3D

    rpe = metrics.RPE(
        relation,
        delta=length,
        delta_unit=metrics.Unit.meters,
        all_pairs=True,
        pairs_from_reference=True,
        rel_delta_tol=tol,
    )
    rpe.process_data((PosePath3D(poses_se3=list(gt)), PosePath3D(poses_se3=list(est))))
    return np.asarray(rpe.error)


@pytest.mark.parametrize(
    "case",
    ["smooth0", "smooth1", "smooth2", "pause", "regular_grid"],
)
def test_matches_evo_rpe_all_pairs(case):
    from evo.core import filters
    from evo.core.metrics import PoseRelation

    rng = np.random.default_rng(sum(map(ord, case)))
    if case.startswith("smooth"):
        gt = smooth_trajectory(rng, 1500)
    elif case == "pause":
        gt = smooth_trajectory(rng, 1500, with_pause=True)
    else:  # regular 0.1 m spacing: segment ends fall on poses up to rounding (near-ties)
        t = np.arange(1200)
        gt = poses_from(straight_line(t.size), yaw_rotvecs(0.002 * t))
    est = noisy_estimate(rng, gt)
    for length in DEFAULT_LENGTHS_M:
        ours = segment_errors(gt, est, length)
        pairs = filters.filter_pairs_by_path(list(gt), length, 0.2 * length, all_pairs=True)
        evo_start = np.array([p[0] for p in pairs])
        evo_end = np.array([p[1] for p in pairs])
        np.testing.assert_array_equal(ours.start_idx, evo_start)
        np.testing.assert_array_equal(ours.end_idx, evo_end)
        np.testing.assert_allclose(
            ours.trans_m, evo_rpe(gt, est, length, PoseRelation.translation_part), atol=1e-9
        )
        np.testing.assert_allclose(
            ours.rot_deg, evo_rpe(gt, est, length, PoseRelation.rotation_angle_deg), atol=1e-9
        )


def test_pairs_match_evo_on_exact_ties_and_pauses():
    """Half-step lengths on a regular grid (two equally close ends) and quantised pauses."""
    from evo.core import filters

    from metrics.relative import segment_pairs

    rng = np.random.default_rng(7)
    for trial in range(60):
        n = int(rng.integers(50, 300))
        if trial % 2 == 0:
            step = float(rng.choice([0.1, 0.2, 0.25]))
            pos = straight_line(n, step)
            length = step * (int(rng.integers(5, 40)) + 0.5)
        else:
            steps = rng.choice([0.0, 0.0, 0.1, 0.2], size=n)
            pos = np.column_stack([np.cumsum(steps), np.zeros(n), np.zeros(n)])
            length = float(rng.choice([0.5, 1.0, 1.05, 2.0, 3.3]))
        tol = float(rng.choice([0.0, 0.1, 0.2, 0.5]))
        ref = filters.filter_pairs_by_path(list(poses_from(pos)), length, length * tol, True)
        start, end = segment_pairs(path_distances(pos), length, tol)
        assert list(zip(start.tolist(), end.tolist(), strict=True)) == [tuple(p) for p in ref]


def test_rotation_angle_equals_scipys_quaternion_magnitude_at_every_angle():
    """metrics.relative.rotation_angle_deg (atan2 of the axis vector and the trace) against
    scipy's Rotation.magnitude from 1e-9 rad to pi: equal to rounding, also near 0 where
    arccos of the trace would be off by about 1e-6 deg; NaN for a non-finite matrix."""
    rng = np.random.default_rng(7)
    axes = rng.normal(size=(3000, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    angles = np.concatenate([np.geomspace(1e-9, 1.0, 1500), rng.uniform(1.0, np.pi, 1500)])
    mats = Rotation.from_rotvec(axes * angles[:, None]).as_matrix()
    ours = rotation_angle_deg(mats)
    np.testing.assert_allclose(ours, np.degrees(Rotation.from_matrix(mats).magnitude()),
                               rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(ours, np.degrees(angles), rtol=1e-9)
    mats[5, 0, 0] = np.nan
    assert np.isnan(rotation_angle_deg(mats)[5]) and np.isfinite(rotation_angle_deg(mats)[6])
