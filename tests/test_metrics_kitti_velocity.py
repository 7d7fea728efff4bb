"""metrics.kitti (KITTI devkit drift) and metrics.velocity (ego-velocity error): known answers
and an independent loop implementation of the devkit's definition."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from metrics import kitti_drift, velocity_errors
from metrics.velocity import own_velocity_errors


def curvy(n=1500, step_m=0.8, seed=0):
    """A 3-D path with turns (T_world_body), heading along the path."""
    rng = np.random.default_rng(seed)
    yaw = np.cumsum(rng.normal(0, 0.02, n))
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.from_rotvec(np.column_stack(
        [0.02 * np.sin(np.arange(n) / 50), np.zeros(n), yaw])).as_matrix()
    poses[:, :3, 3] = np.cumsum(poses[:, :3, 0] * step_m, axis=0)
    return poses


def devkit_loop(gt, est, lengths, step=10):
    """The devkit's calcSequenceErrors written as its loops (evaluate_odometry.cpp)."""
    dist = [0.0]
    for i in range(1, len(gt)):
        dist.append(dist[-1] + float(np.linalg.norm(gt[i, :3, 3] - gt[i - 1, :3, 3])))
    t_err, r_err = [], []
    for first in range(0, len(gt), step):
        for length in lengths:
            last = next((i for i in range(first, len(gt)) if dist[i] > dist[first] + length), -1)
            if last == -1:
                continue
            d_gt = np.linalg.inv(gt[first]) @ gt[last]
            d_est = np.linalg.inv(est[first]) @ est[last]
            e = np.linalg.inv(d_est) @ d_gt
            d = 0.5 * (e[0, 0] + e[1, 1] + e[2, 2] - 1.0)
            r_err.append(math.acos(max(min(d, 1.0), -1.0)) / length)
            t_err.append(float(np.linalg.norm(e[:3, 3])) / length)
    return 100 * np.mean(t_err), 100 * np.degrees(np.mean(r_err)), len(t_err)


def test_kitti_drift_matches_the_devkit_loop():
    gt = curvy()
    noise = np.tile(np.eye(4), (len(gt), 1, 1))
    rng = np.random.default_rng(1)
    noise[:, :3, :3] = Rotation.from_rotvec(np.cumsum(rng.normal(0, 2e-4, (len(gt), 3)),
                                                      axis=0)).as_matrix()
    est = gt @ noise
    est[:, :3, 3] *= 1.02
    lengths = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)
    k = kitti_drift(gt, est, lengths)
    t, r, n = devkit_loop(gt, est, lengths)
    assert k.n == n > 0
    assert k.trans_pct == pytest.approx(t, rel=1e-9)
    assert k.rot_deg_per_100m == pytest.approx(r, rel=1e-9)
    assert k.too_long == ()


def test_kitti_drift_known_answers_and_too_short_lengths():
    n = 300
    gt = np.tile(np.eye(4), (n, 1, 1))
    gt[:, 0, 3] = np.arange(n) * 1.0  # 299 m straight
    est = gt.copy()
    est[:, 0, 3] *= 1.01  # 1 % too long
    k = kitti_drift(gt, est, (100.0, 200.0, 400.0))
    # the end is the first pose strictly beyond L: 101 m travelled, 1.01 m error per 100 m
    assert k.per_length[100.0][0] == pytest.approx(1.01, rel=1e-9)
    assert k.per_length[200.0][0] == pytest.approx(1.005, rel=1e-9)
    n100, n200 = k.per_length[100.0][2], k.per_length[200.0][2]
    assert k.trans_pct == pytest.approx((1.01 * n100 + 1.005 * n200) / (n100 + n200), rel=1e-9)
    assert k.rot_deg_per_100m == pytest.approx(0.0, abs=1e-9)
    assert k.too_long == (400.0,) and k.per_length[400.0][2] == 0
    assert n100 == len(range(0, n - 101, 10))  # starts whose start + 101 m is a pose
    # a yaw error of 0.5 deg per 100 m: 0.505 deg over each 101 m segment of "100 m"
    yawed = gt.copy()
    yaw_deg = (np.arange(n) * 0.005)[:, None]
    yawed[:, :3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    yawed[:, :3, 3] = gt[:, :3, 3]
    assert kitti_drift(gt, yawed, (100.0,)).rot_deg_per_100m == pytest.approx(0.505, rel=1e-9)
    assert math.isnan(kitti_drift(gt, est, (1000.0,)).trans_pct)


def straight(speed_mps=10.0, rate_hz=12.0, seconds=20.0):
    stamps = np.arange(0, seconds, 1 / rate_hz)
    poses = np.tile(np.eye(4), (len(stamps), 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("z", 90, degrees=True).as_matrix()  # heading +y
    poses[:, 1, 3] = speed_mps * stamps
    return stamps, poses


def test_velocity_error_known_answer_in_the_sensor_frame():
    stamps, gt = straight()
    est = gt.copy()
    est[:, 1, 3] *= 1.1  # 1 m/s too fast, along the sensor's x (forward) axis
    v = velocity_errors(gt, est, stamps, window_s=0.0)
    assert v.axis_mean_mps == pytest.approx((1.0, 0.0, 0.0), abs=1e-9)
    assert v.norm_rmse_mps == pytest.approx(1.0, rel=1e-9) and v.n == len(stamps) - 1


def test_window_removes_the_nearest_matched_gt_artefact():
    """GT at 10 Hz nearest-matched to 12 Hz scans (a row in six repeated): a perfect estimate
    scores ~2 m/s frame to frame at 10 m/s, under 1 m/s over 0.5 s windows."""
    stamps, truth = straight()
    gt_stamps = np.arange(0, 20.0, 0.1)
    nearest = np.abs(stamps[:, None] - gt_stamps[None, :]).argmin(axis=1)
    gt = truth.copy()
    gt[:, 1, 3] = 10.0 * gt_stamps[nearest]
    frame = velocity_errors(gt, truth, stamps, window_s=0.0)
    window = velocity_errors(gt, truth, stamps, window_s=0.5)
    assert frame.norm_mean_mps > 1.5
    assert window.norm_mean_mps < 0.5 * frame.norm_mean_mps and window.norm_rmse_mps < 1.0


def test_own_velocity_skips_unobservable_frames():
    stamps, gt = straight()
    own = np.tile([10.5, 0.0, 0.0], (len(stamps), 1))
    own[::7] = np.nan
    v = own_velocity_errors(gt, stamps, own, window_s=0.5)
    assert v.axis_mean_mps[0] == pytest.approx(0.5, abs=1e-9)
    assert 0 < v.n < len(stamps)


def _yawed_poses(stamps, positions, yaw_deg):
    poses = np.tile(np.eye(4), (len(stamps), 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    poses[:, :3, 3] = positions
    return poses


def test_velocity_is_rotated_into_the_sensor_frame_with_R_transpose():
    """Known answer, signed: a sensor yawed 30 deg (not 90: a quarter turn's R and R^T differ
    only by a sign that absolute errors hide) moving along world +x at 10 m/s moves at
    R^T (10, 0, 0) = (8.660, -5.0, 0) in its own frame; independently, the translation of
    inv(T_i) @ T_j over the time."""
    s = 0.1 * np.arange(12)
    gt = _yawed_poses(s, np.column_stack([10 * s, 0 * s, 0 * s]), 30.0)
    from metrics.velocity import velocity_series

    series = velocity_series(gt, gt, s, window_s=0.5)
    np.testing.assert_allclose(series.gt_mps, np.tile([10 * math.cos(math.pi / 6),
                                                       -10 * math.sin(math.pi / 6), 0.0],
                                                      (len(series.gt_mps), 1)), atol=1e-9)
    rel = np.linalg.inv(gt[series.start_idx]) @ gt[series.end_idx]
    dt = s[series.end_idx] - s[series.start_idx]
    np.testing.assert_allclose(series.gt_mps, rel[:, :3, 3] / dt[:, None], atol=1e-9)
    # an estimate that gets the speed right along a wrongly signed lateral axis is scored so
    est = gt.copy()
    est[:, :3, :3] = Rotation.from_euler("z", -30.0, degrees=True).as_matrix()
    stats = velocity_errors(gt, est, s, window_s=0.5)
    assert stats.axis_mean_mps[1] == pytest.approx(10.0, abs=1e-9)


def test_own_velocity_window_is_centred_on_the_frame_under_acceleration():
    """Known answer under constant acceleration (2 m/s^2 along world x, sensor yawed 30 deg):
    a window centred on s_i gives exactly v(s_i) = 2 s_i (the central difference of a
    parabola is exact); a window a whole window early would give 2 (s_i - W), 1 m/s off at
    W = 0.5 s. A constant speed could not tell them apart."""
    s = 0.05 * np.arange(80)
    gt = _yawed_poses(s, np.column_stack([s**2, 0 * s, 0 * s]), 30.0)
    R = Rotation.from_euler("z", 30.0, degrees=True).as_matrix()
    est = (R.T @ np.column_stack([2 * s, 0 * s, 0 * s]).T).T  # the exact velocity at s_i
    stats = own_velocity_errors(gt, s, est, window_s=0.5)
    assert stats.n == len(s) - 10  # 5 frames each end lack a full window
    assert stats.norm_mean_mps < 1e-9
    late = own_velocity_errors(gt, s, est - (R.T @ [1.0, 0.0, 0.0]), window_s=0.5)
    assert late.norm_mean_mps == pytest.approx(1.0, abs=1e-9)
