"""metrics/drift.py: per-axis drift from the first frame, against known answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loaders.se3 import inv_T, make_T
from metrics.drift import drift_from_first_frame


def straight(n=21, step=1.0):
    """GT along world x, level, identity attitude (body x = world x)."""
    return make_T(np.repeat(np.eye(3)[None], n, 0), np.column_stack(
        [np.arange(n) * step, np.zeros(n), np.zeros(n)]))


def turned_at(poses, m, R):
    """The same trajectory, but with the rotation R (body frame of pose m) added at pose m:
    every later pose turns with it about pose m (a heading / attitude error made there)."""
    out = poses.copy()
    kick = poses[m] @ make_T(R, np.zeros(3)) @ inv_T(poses[m])
    out[m:] = kick @ poses[m:]
    return out


def test_a_perfect_estimate_has_no_drift_and_the_distance_is_the_gt_path():
    gt = straight()
    offset = make_T(Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), [5.0, -2.0, 1.0])
    d = drift_from_first_frame(gt, offset @ gt)  # another world frame: no error
    np.testing.assert_allclose(d.distance_m, np.arange(21.0))
    np.testing.assert_allclose(d.rot_err_deg, 0.0, atol=1e-12)
    np.testing.assert_allclose(d.trans_err_m, 0.0, atol=1e-12)


def test_a_heading_error_shows_as_yaw_and_an_across_track_offset():
    gt = straight()
    psi = np.radians(2.0)
    est = turned_at(gt, 5, Rotation.from_rotvec([0, 0, psi]).as_matrix())
    d = drift_from_first_frame(gt, est)
    L = np.arange(21.0) - 5
    L[:5] = 0
    np.testing.assert_allclose(d.rot_err_deg[:, 2], np.where(np.arange(21) >= 5, 2.0, 0.0),
                               atol=1e-9)
    np.testing.assert_allclose(d.rot_err_deg[:, :2], 0.0, atol=1e-9)
    np.testing.assert_allclose(d.trans_err_m[:, 0], (np.cos(psi) - 1) * L, atol=1e-9)
    np.testing.assert_allclose(d.trans_err_m[:, 1], np.sin(psi) * L, atol=1e-9)
    np.testing.assert_allclose(d.trans_err_m[:, 2], 0.0, atol=1e-9)


def test_a_roll_error_about_the_direction_of_travel_moves_no_position():
    gt = straight()
    est = turned_at(gt, 3, Rotation.from_rotvec([np.radians(4.0), 0, 0]).as_matrix())
    d = drift_from_first_frame(gt, est)
    np.testing.assert_allclose(d.rot_err_deg[3:], [[4.0, 0.0, 0.0]] * 18, atol=1e-9)
    np.testing.assert_allclose(d.trans_err_m, 0.0, atol=1e-9)


def test_the_axes_are_the_gt_body_axes_after_a_turn():
    """GT 10 m along x, a 90 deg left turn, 10 m along y; the estimate's positions scaled by
    1.1 (attitudes right). At the end the body x axis is world y and body y is world -x: the
    estimate is 1 m ahead along the road and 1 m to the right of it."""
    R_turn = Rotation.from_rotvec([0, 0, np.pi / 2]).as_matrix()
    poses = [make_T(np.eye(3), [x, 0.0, 0.0]) for x in range(11)]
    poses += [make_T(R_turn, [10.0, y, 0.0]) for y in range(1, 11)]
    gt = np.array(poses)
    est = gt.copy()
    est[:, :3, 3] *= 1.1
    d = drift_from_first_frame(gt, est)
    np.testing.assert_allclose(d.trans_err_m[-1], [1.0, -1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(d.rot_err_deg, 0.0, atol=1e-9)
    assert d.distance_m[-1] == pytest.approx(20.0)


def test_a_pitch_error_bends_the_path_down():
    """A pitch error (nose down: +y rotation) made at frame 1 bends the estimate's path below
    the GT's: vertical error -sin(theta) x distance since, along (cos(theta) - 1) x it. (One
    made at frame 0 would vanish: both trajectories are re-based on their first frame.)"""
    gt = straight()
    theta = np.radians(1.5)
    est = turned_at(gt, 1, Rotation.from_rotvec([0, theta, 0]).as_matrix())
    d = drift_from_first_frame(gt, est)
    L = np.clip(np.arange(21.0) - 1, 0, None)
    np.testing.assert_allclose(d.rot_err_deg[1:, 1], 1.5, atol=1e-9)
    np.testing.assert_allclose(d.trans_err_m[:, 2], -np.sin(theta) * L, atol=1e-9)
    np.testing.assert_allclose(d.trans_err_m[:, 0], (np.cos(theta) - 1) * L, atol=1e-9)


def test_non_finite_estimates_give_nan_rows():
    gt = straight(5)
    est = gt.copy()
    est[3] = np.nan
    d = drift_from_first_frame(gt, est)
    assert np.all(np.isnan(d.rot_err_deg[3])) and np.all(np.isnan(d.trans_err_m[3]))
    assert np.all(np.isfinite(d.rot_err_deg[[0, 1, 2, 4]]))
