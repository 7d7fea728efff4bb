"""bench.runs.external_match: an estimate at its own stamps brought to the scan stamps, against
analytic motions (constant speed along x with a constant yaw rate: SE(3) interpolation of two
poses on it is exact in rotation, and exact in translation for the straight part)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.runs.external_match import match_to_scans
from loaders.errors import DataError
from loaders.posefile import parse_extrinsic
from loaders.se3 import make_T
from loaders.trajectory import Trajectory


def straight(stamps: np.ndarray, v=2.0, yaw_rate=0.3) -> np.ndarray:
    """Position x = v t (a straight line), yaw = yaw_rate t: linear in t, so slerp + linear
    interpolation reproduces it exactly."""
    t = np.asarray(stamps, dtype=np.float64)
    R = Rotation.from_euler("z", yaw_rate * t[:, None]).as_matrix()
    return make_T(R, np.column_stack([v * t, np.zeros_like(t), np.zeros_like(t)]))


SCANS = np.arange(40) * 0.1  # 10 Hz


def test_matched_stamps_take_the_pose_as_it_is():
    est = Trajectory(SCANS + 1e-6, straight(SCANS))  # a microsecond off: within tolerance
    m = match_to_scans(est, SCANS)
    assert m.covered.all() and m.matched.all()
    np.testing.assert_array_equal(m.poses, est.poses)
    assert m.report["matched"] == 40 and m.report["interpolated"] == 0


def test_another_rate_is_interpolated_to_the_scan_stamps():
    t_est = np.arange(0, 3.95, 0.037)  # 27 Hz, ends before the last scans
    m = match_to_scans(Trajectory(t_est, straight(t_est)), SCANS)
    inside = SCANS <= t_est[-1]
    np.testing.assert_array_equal(m.covered, inside)
    np.testing.assert_allclose(m.poses[inside], straight(SCANS[inside]), atol=1e-12)
    assert np.isnan(m.poses[~inside]).all()
    # only 0.0 (and 3.7) lie on the 27 Hz grid: matched; the others interpolated
    assert m.report["matched"] == 2 and m.report["interpolated"] == inside.sum() - 2
    assert m.report["max_gap_s"] == pytest.approx(3 * 0.037)


def test_a_gap_longer_than_max_gap_is_never_bridged():
    t_est = np.concatenate([np.arange(0, 1.0, 0.05), np.arange(2.0, 3.0, 0.05)])
    m = match_to_scans(Trajectory(t_est, straight(t_est)), SCANS)
    in_gap = (SCANS > t_est[19] + 1e-9) & (SCANS < 2.0 - 1e-9)
    assert not m.covered[in_gap].any() and m.covered[SCANS <= 0.95].all()
    wide = match_to_scans(Trajectory(t_est, straight(t_est)), SCANS, max_gap_s=1.1)
    assert wide.covered[in_gap].all()


def test_time_offset_moves_the_estimate_onto_the_scan_clock():
    est = Trajectory(SCANS - 1000.0, straight(SCANS))  # est_stamp + 1000 = sensor clock
    m = match_to_scans(est, SCANS, time_offset_s=1000.0)
    assert m.matched.all()
    np.testing.assert_array_equal(m.poses, est.poses)


def test_no_overlap_is_refused_with_the_offset_to_try():
    est = Trajectory(SCANS + 3600.0 * 8, straight(SCANS))  # a time zone apart
    with pytest.raises(DataError) as err:
        match_to_scans(est, SCANS, est_name="odom.tum", scan_name="run.h5")
    text = str(err.value)
    assert text.startswith("odom.tum does not overlap the scans of run.h5")
    assert "try --time-offset -28800 (the estimate's clock is 8 h ahead" in text
    assert "est_stamp + offset = sensor clock" in text


def test_poses_of_another_frame_are_moved_to_the_sensor():
    T_frame_sensor = parse_extrinsic("1.2 0.1 1.5 0.0087265 -0.0130896 0.0043633 0.9998719")
    body = straight(SCANS)
    m = match_to_scans(Trajectory(SCANS, body), SCANS, T_frame_sensor=T_frame_sensor)
    np.testing.assert_allclose(m.poses, body @ T_frame_sensor, atol=1e-15)


def test_negative_tolerance_is_an_error():
    with pytest.raises(DataError, match="--tolerance -1"):
        match_to_scans(Trajectory(SCANS, straight(SCANS)), SCANS, tolerance_s=-1)
