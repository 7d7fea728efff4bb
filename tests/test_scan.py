import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from loaders.errors import DataError
from loaders.posefile import read_kitti, read_tum, write_kitti, write_tum
from loaders.scan import FrameRange, MemorySequence, Scan, SensorInfo
from loaders.se3 import exp_se3, inv_T, make_T
from loaders.trajectory import Trajectory


def test_scan_validates_shapes_and_values():
    pts = np.zeros((4, 3)) + 1.0
    with pytest.raises(DataError, match=r"shape \(N, 3\)"):
        Scan(0.0, np.zeros((4, 2)))
    with pytest.raises(DataError, match=r"doppler must have shape \(4,\)"):
        Scan(0.0, pts, np.zeros(3))
    bad = pts.copy()
    bad[2, 1] = np.nan
    with pytest.raises(DataError, match="frame 7: points has 1 non-finite rows \\(first at row 2"):
        Scan(0.0, bad, source="x.bag, frame 7")
    with pytest.raises(DataError, match="doppler has 1 non-finite"):
        Scan(0.0, pts, np.array([0, np.inf, 0, 0]))
    with pytest.raises(DataError, match="field 'power'"):
        Scan(0.0, pts, None, {"power": np.zeros(5)})


def test_select_applies_one_mask_to_every_array():
    pts = np.arange(15, dtype=float).reshape(5, 3)
    s = Scan(1.0, pts, np.arange(5.0), {"power": np.arange(5.0) * 10, "time_offset_s":
                                         np.arange(5.0) / 100})
    sub = s.select(np.array([True, False, True, False, True]))
    assert len(sub) == 3
    np.testing.assert_array_equal(sub.points[:, 0], [0, 6, 12])
    np.testing.assert_array_equal(sub.doppler, [0, 2, 4])
    np.testing.assert_array_equal(sub.fields["power"], [0, 20, 40])
    np.testing.assert_array_equal(sub.fields["time_offset_s"], [0, 0.02, 0.04])
    assert len(s.select(slice(None, None, 2))) == 3


def _traj(n=50):
    stamps = np.linspace(0, 4.9, n)
    poses = np.array([exp_se3(np.array([5.0, 0.2, 0.1, 0.0, 0.01, 0.3]) * t) for t in stamps])
    return Trajectory(stamps, poses)


def test_tum_and_kitti_round_trip(tmp_path):
    traj = _traj()
    write_tum(traj, tmp_path / "a.txt")
    back = read_tum(tmp_path / "a.txt")
    np.testing.assert_allclose(back.stamps, traj.stamps, atol=1e-9)
    np.testing.assert_allclose(back.poses, traj.poses, atol=1e-8)
    write_kitti(traj, tmp_path / "k.txt")
    back = read_kitti(tmp_path / "k.txt", traj.stamps)
    np.testing.assert_allclose(back.poses, traj.poses, atol=1e-8)


def test_tum_header_line_is_skipped_and_bad_rows_named(tmp_path):
    p = tmp_path / "gt_odom.txt"
    p.write_text("timestamp x y z qx qy qz qw\n1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n")
    assert len(read_tum(p)) == 2
    p.write_text("1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0\n")
    with pytest.raises(DataError, match="line 2: expected 8 values"):
        read_tum(p)


def test_plain_pose_files_read_as_the_line_by_line_reader_reads_them(tmp_path, monkeypatch):
    import loaders.posefile as posefile

    rng = np.random.default_rng(3)
    rows = np.column_stack([np.arange(200) * 0.1, rng.normal(0, 1e3, (200, 3)),
                            Rotation.random(200, random_state=4).as_quat()])
    p = tmp_path / "plain.txt"
    np.savetxt(p, rows, fmt="%.17g")  # as the harness writes run folders
    fast, fast_lines = posefile.numeric_rows(p, (8,), "t x y z qx qy qz qw")
    monkeypatch.setattr(posefile, "_plain_rows", lambda *a: None)
    slow, slow_lines = posefile.numeric_rows(p, (8,), "t x y z qx qy qz qw")
    assert np.array_equal(fast, slow) and fast_lines == slow_lines == list(range(1, 201))
    monkeypatch.undo()
    # a blank line: the line numbers of later rows still count it (line 4, not 3)
    p.write_text("0 0 0 0 0 0 0 1\n\n0.1 1 0 0 0 0 0 1\n0.2 2 0 0 0 0 0.5 0.5\n")
    with pytest.raises(DataError, match="line 4: quaternion"):
        read_tum(p)
    p.write_text("0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n0.2 2 0 0 0 0 0.5 0.5")  # no final \n
    with pytest.raises(DataError, match="line 3: quaternion"):
        read_tum(p)
    p.write_text("0 0 0 0 0 0 0 1\n0.1 1_0 0 0 0 0 0 1\n")  # float() reads 1_0 as 10
    assert read_tum(p).poses[1, 0, 3] == 10.0
    p.write_text("")
    with pytest.raises(DataError, match="no TUM pose rows found"):
        read_tum(p)


def test_interpolation_matches_scipy_slerp():
    traj = _traj()
    q = np.array([0.05, 1.234, 3.3333, 4.89])
    got = traj.interpolate(q).poses
    R_ref = Slerp(traj.stamps, Rotation.from_matrix(traj.poses[:, :3, :3]))(q).as_matrix()
    np.testing.assert_allclose(got[:, :3, :3], R_ref, atol=1e-12)
    for k in range(3):
        np.testing.assert_allclose(got[:, k, 3], np.interp(q, traj.stamps, traj.positions[:, k]))


def test_interpolation_errors_on_no_overlap_and_gaps():
    traj = _traj()
    with pytest.raises(DataError, match="do not overlap"):
        traj.interpolate(np.array([10.0, 11.0]), name="gt_odom.txt")
    gappy = Trajectory(np.array([0.0, 0.1, 0.2, 2.0, 2.1]), np.tile(np.eye(4), (5, 1, 1)))
    with pytest.raises(DataError, match="1 of 3 query stamps are not covered"):
        gappy.interpolate(np.array([0.15, 1.0, 2.05]), max_gap_s=0.3)
    assert gappy.coverage_mask(np.array([0.15, 1.0, 2.05]), 0.3).tolist() == [True, False, True]


def test_frame_range_scales_period_and_cuts_gt(twist_sequence):
    fr = FrameRange(twist_sequence, start=2, frames=5, stride=3)
    assert len(fr) == 5
    np.testing.assert_allclose(fr.stamps, twist_sequence.stamps[[2, 5, 8, 11, 14]])
    assert fr.sensor.period_s == pytest.approx(3 * twist_sequence.sensor.period_s)
    assert fr.ground_truth.stamps[0] == pytest.approx(0.2)
    assert fr.ground_truth.stamps[-1] == pytest.approx(1.4)
    assert fr[1].stamp == twist_sequence[5].stamp
    with pytest.raises(DataError, match="past the last frame"):
        FrameRange(twist_sequence, start=100)


def test_sequence_indexing():
    seq = MemorySequence("m", SensorInfo("radar", 0.1),
                         [Scan(i * 0.1, np.ones((3, 3)) * (i + 1)) for i in range(4)])
    assert seq[-1].stamp == pytest.approx(0.3)
    with pytest.raises(IndexError, match="frame 4 out of range"):
        seq[4]
    with pytest.raises(DataError, match="sensor kind"):
        SensorInfo("sonar", 0.1)


def test_inv_T_matches_numpy_inverse():
    T = make_T(Rotation.from_rotvec([0.1, -0.4, 0.7]).as_matrix(), [1.0, -2.0, 3.0])
    np.testing.assert_allclose(inv_T(T), np.linalg.inv(T), atol=1e-12)
