"""Tests for loaders.gt: association, interpolation, extrinsic, trimming, sanity report."""

import warnings

import numpy as np
import pytest

from helpers_bags import Motion
from loaders.errors import DataError, GroundTruthWarning
from loaders.gt import (
    associate,
    clean_trajectory,
    gt_for_frames,
    nearest_indices,
    remove_origin,
)
from loaders.gt_report import gt_sanity_report
from loaders.posefile import parse_extrinsic, read_gt_file
from loaders.se3 import interpolate_poses, make_T
from loaders.trajectory import Trajectory

T_BS = make_T(np.eye(3), [0.296, -0.130, -0.005])


def gt_traj(motion: Motion, t0: float, t1: float, step: float) -> Trajectory:
    t = np.arange(t0, t1 + step / 2, step)
    return Trajectory(t, motion.body_pose(t))


def test_interpolated_gt_with_extrinsic_matches_motion():
    m = Motion(T_body_sensor=T_BS, t0=0.0)
    gt = gt_traj(m, 0.0, 2.0, 0.02)
    scans = 0.5 + 0.08 * np.arange(10)  # on GT rows
    a = associate(gt, scans, T_body_sensor=T_BS, max_gap_s=0.1)
    assert a.uncovered == 0 and len(a.keep) == 10 and a.covered.all()
    np.testing.assert_allclose(a.ground_truth.poses, m.sensor_pose(scans), atol=1e-9)
    np.testing.assert_allclose(a.ground_truth.stamps, scans)


def test_interpolation_between_rows_is_se3_interpolation():
    m = Motion(t0=0.0)
    gt = gt_traj(m, 0.0, 2.0, 0.1)
    scans = np.array([0.55, 1.234])
    a = associate(gt, scans, max_gap_s=0.2)
    np.testing.assert_allclose(a.ground_truth.poses,
                               interpolate_poses(gt.stamps, gt.poses, scans), atol=1e-12)
    # and close to the analytic motion (arc vs chord)
    np.testing.assert_allclose(a.ground_truth.poses, m.body_pose(scans), atol=1e-2)


def test_time_offset_moves_gt_onto_sensor_clock():
    m = Motion(t0=0.0)
    gt = gt_traj(m, 0.0, 2.0, 0.02)
    shifted = Trajectory(gt.stamps - 100.0, gt.poses)  # GT clock 100 s behind
    scans = 0.5 + 0.08 * np.arange(5)
    with pytest.raises(DataError, match="does not overlap"):
        associate(shifted, scans, gt_file="gt.txt", scan_file="run.bag")
    a = associate(shifted, scans, offset_s=100.0)
    np.testing.assert_allclose(a.ground_truth.poses, m.body_pose(scans), atol=1e-9)


def test_no_overlap_names_both_files_and_spans():
    gt = Trajectory(np.array([0.0, 1.0]), np.stack([np.eye(4)] * 2))
    with pytest.raises(DataError) as err:
        associate(gt, np.array([50.0, 51.0]), gt_file="gt_odom.txt", scan_file="loop1_0.bag")
    msg = str(err.value)
    assert "gt_odom.txt" in msg and "loop1_0.bag" in msg
    assert "[0.000, 1.000]" in msg and "[50.000, 51.000]" in msg


def test_uncovered_scans_are_kept_and_counted():
    m = Motion(t0=0.0)
    gt = gt_traj(m, 1.0, 2.0, 0.02)
    scans = np.arange(0.0, 3.0, 0.1)  # 10 before, 9 after
    with pytest.warns(GroundTruthWarning, match="excluded from scoring"):
        a = associate(gt, scans, max_gap_s=0.1)
    assert a.uncovered_before == 10 and a.uncovered_after == 9 and a.uncovered_inside == 0
    assert list(a.keep) == list(range(30))  # ground truth limits the scoring, not the sequence
    assert a.report["with_gt"] == a.covered.sum() == 11
    np.testing.assert_allclose(a.ground_truth.stamps, scans[a.keep][a.covered])
    with pytest.warns(GroundTruthWarning, match="trimmed"):
        t = associate(gt, scans, max_gap_s=0.1, uncovered="trim")
    assert list(t.keep) == list(range(10, 21)) and t.covered.all()


def test_gap_policies():
    m = Motion(t0=0.0)
    t = np.concatenate([np.arange(0.0, 1.0, 0.02), np.arange(2.0, 3.0, 0.02)])
    gt = Trajectory(t, m.body_pose(t))
    scans = np.arange(0.1, 2.9, 0.1)
    with pytest.warns(GroundTruthWarning):
        a = associate(gt, scans, max_gap_s=0.1)
    assert a.uncovered_inside > 0 and a.uncovered_before == a.uncovered_after == 0
    assert len(a.keep) == len(scans)
    inside_gap = (scans[a.keep] > t[49]) & (scans[a.keep] < 2.0)
    np.testing.assert_array_equal(a.covered, ~inside_gap)
    with pytest.warns(GroundTruthWarning):  # trim cuts the ends only: the gap stays, unscored
        tr = associate(gt, scans, max_gap_s=0.1, uncovered="trim")
    assert len(tr.keep) == len(scans) and tr.uncovered_inside == a.uncovered_inside
    with pytest.raises(DataError, match="not covered"):
        associate(gt, np.arange(0.1, 3.5, 0.1), max_gap_s=2.0, uncovered="error")
    with pytest.warns(GroundTruthWarning, match="no longer supported"):  # old configs
        old = associate(gt, scans, max_gap_s=0.1, uncovered="drop")
    assert len(old.keep) == len(scans)
    with pytest.raises(DataError, match="uncovered"):
        associate(gt, scans, uncovered="skip")


def test_a_long_gap_is_never_bridged_even_near_its_edge():
    """A 5 s GT outage on an arc: a scan 0.2 s after the last pose before the outage used to be
    "near" a pose and was interpolated across the whole outage (metres off the arc)."""
    m = Motion(t0=0.0, v=10.0, w=0.3)
    t = np.concatenate([np.arange(0.0, 5.0 + 1e-9, 0.02), np.arange(10.0, 15.0, 0.02)])
    gt = Trajectory(t, m.body_pose(t))
    scans = np.arange(0.0, 15.0, 1 / 12)
    with pytest.warns(GroundTruthWarning):
        a = associate(gt, scans, max_gap_s=0.5)
    in_outage = (scans > 5.0 + 1e-9) & (scans < 10.0 - 1e-9)
    np.testing.assert_array_equal(a.covered, ~in_outage)
    err = np.linalg.norm(a.ground_truth.positions - m.body_pose(a.ground_truth.stamps)[:, :3, 3],
                         axis=1)
    assert err.max() < 0.01  # only interpolation between 20 ms-apart poses remains
    # an edge scan exactly on the last pose before the outage is covered (it takes that pose)
    b = associate(gt, np.array([4.0, 5.0]), max_gap_s=0.5)
    assert b.covered.all()


@pytest.mark.parametrize("gap_steps, bridged", [(2, True), (3, True), (4, False), (6, False)])
def test_gt_at_its_own_rate_is_bridged_across_at_most_three_steps(gap_steps, bridged):
    """The scoring path (``gt_for_frames``, used by every run's evaluation): GT sampled at its
    own rate (0.25 s, not at the scans) is interpolated across a gap of up to 3 of its median
    steps and never across a longer one. Stamps are multiples of 1/4 s (exact in binary), so
    the gap of exactly 3 steps sits on the boundary: 2 and 3 steps bridged, 4 (one step over)
    and 6 not."""
    m = Motion(t0=0.0, v=10.0, w=0.3)
    before = np.arange(0, 21) * 0.25  # 0 .. 5 s
    after = 5.0 + gap_steps * 0.25 + np.arange(0, 21) * 0.25
    t = np.concatenate([before, after])
    gt = Trajectory(t, m.body_pose(t))
    scans = np.arange(0.01, after[-1], 0.1)  # never on a GT stamp
    poses, mask = gt_for_frames(gt, scans)
    in_gap = (scans > 5.0) & (scans < after[0])
    assert in_gap.sum() >= 4
    assert mask[~in_gap].all()
    assert mask[in_gap].all() == bridged and mask[in_gap].any() == bridged, mask[in_gap]
    assert np.isnan(poses[~mask]).all()
    # what is scored off the gap is the truth up to the interpolation between 0.25 s poses
    err = np.linalg.norm(poses[mask, :3, 3] - m.body_pose(scans[mask])[:, :3, 3], axis=1)
    assert err[~in_gap[mask]].max() < 0.05


def test_tolerance_and_nearest_mode():
    m = Motion(t0=0.0)
    gt = gt_traj(m, 0.0, 1.0, 0.1)
    a = associate(gt, np.array([-0.01, 0.5, 1.005]), tolerance_s=0.02)
    assert a.uncovered == 0
    np.testing.assert_allclose(a.ground_truth.poses[0], gt.poses[0])
    np.testing.assert_allclose(a.ground_truth.poses[-1], gt.poses[-1])
    with pytest.warns(UserWarning):
        n = associate(gt, np.array([0.101, 0.35, 0.9]), mode="nearest", tolerance_s=0.01)
    assert list(n.keep) == [0, 1, 2] and list(n.covered) == [True, False, True]
    np.testing.assert_allclose(n.ground_truth.poses, gt.poses[[1, 9]])
    idx, dist = nearest_indices(gt.stamps, np.array([0.04, 0.06]))
    assert list(idx) == [0, 1] and np.allclose(dist, 0.04)


def test_duplicate_rows_dropped_with_named_warning():
    t = np.array([0.0, 0.1, 0.2, 0.2, 0.3])
    gt = Trajectory(t, np.stack([make_T(np.eye(3), [s, 0, 0]) for s in t]))
    with pytest.warns(GroundTruthWarning, match="1 rows repeat the previous row's stamp and pose"):
        clean, info = clean_trajectory(gt, "gt.txt")
    assert info == {"duplicate_rows": 1}
    np.testing.assert_allclose(clean.stamps, [0.0, 0.1, 0.2, 0.3])


def test_repeated_stamp_with_another_pose_or_backwards_stamp_is_an_error():
    t = np.array([0.0, 0.1, 0.2, 0.2, 0.3])
    poses = np.stack([make_T(np.eye(3), [k, 0, 0]) for k in range(5)])
    with pytest.raises(DataError, match=r"gt.txt, pose row 3: repeats the stamp"):
        clean_trajectory(Trajectory(t, poses), "gt.txt")
    back = np.array([0.0, 0.2, 0.1, 0.3, 0.4])
    with pytest.raises(DataError, match=r"gt.txt, pose row 2: stamp 0.100000 s goes backwards"):
        clean_trajectory(Trajectory(back, poses), "gt.txt")
    with pytest.raises(DataError, match="backwards"):
        associate(Trajectory(back, poses), np.array([0.15]), gt_file="gt.txt")


def test_remove_origin_and_world_fix():
    m = Motion(t0=0.0)
    gt = gt_traj(m, 0.0, 1.0, 0.1).transformed(make_T(np.eye(3), [350000.0, 3.4e6, 10.0]))
    local, origin = remove_origin(gt)
    np.testing.assert_allclose(origin, [350000.0, 3.4e6, 10.0])
    np.testing.assert_allclose(local.poses[0, :3, 3], 0.0, atol=1e-9)
    np.testing.assert_allclose(local.poses[:, :3, :3], gt.poses[:, :3, :3])


def test_repeated_poses_are_told_apart_from_a_stall():
    """10 Hz GT nearest-matched onto 12 Hz scans repeats one step in six, scattered; a stalled
    GT repeats in a row: the report says which."""
    t = np.arange(0, 6.0, 1 / 12)
    x = np.round(t * 10) / 10 * 5.0  # positions sampled at 10 Hz, given to 12 Hz stamps
    resampled = gt_sanity_report(Trajectory(t, np.stack([make_T(np.eye(3), [v, 0, 0])
                                                         for v in x])))
    (finding,) = [f for f in resampled["findings"] if "repeat" in f]
    assert "scattered (1 step in 6)" in finding and "lower rate" in finding
    x[20:30] = x[20]
    stalled = gt_sanity_report(Trajectory(t, np.stack([make_T(np.eye(3), [v, 0, 0])
                                                       for v in x])))
    (finding,) = [f for f in stalled["findings"] if "repeat" in f]
    assert "in a row" in finding and "stalled" in finding


def test_sanity_report_findings():
    t = np.concatenate([np.arange(0, 1.0, 0.1), [2.0, 2.1, 2.1, 2.05, 2.3]])
    poses = np.stack([make_T(np.eye(3), [s, 0, 0]) for s in t])
    poses[3] = poses[2]  # a repeated pose
    rep = gt_sanity_report(Trajectory(t, poses), scan_stamps=np.arange(-1.0, 2.0, 0.1))
    assert rep["poses"] == len(t)
    assert rep["repeated_poses"] >= 1
    assert rep["repeated_stamps"] == 1 and rep["non_monotonic"] == 1
    assert rep["gaps"] and rep["gaps"][0]["gap_s"] == pytest.approx(1.1)
    assert 0 < rep["scan_coverage_pct"] < 100
    assert any("gap" in f for f in rep["findings"])
    assert any("covers" in f for f in rep["findings"])
    clean = gt_sanity_report(Trajectory(np.arange(0, 1, 0.1),
                                        np.stack([make_T(np.eye(3), [s, 0, 0])
                                                  for s in np.arange(0, 1, 0.1)])),
                             scan_stamps=np.array([0.2, 0.5]))
    assert clean["findings"] == [] and clean["scan_coverage_pct"] == 100.0


def test_parse_extrinsic_forms():
    T = parse_extrinsic("0.296 -0.130 -0.005 0 0 0 1")
    np.testing.assert_allclose(T, T_BS)
    np.testing.assert_allclose(parse_extrinsic(T.ravel()), T)
    np.testing.assert_allclose(parse_extrinsic([1, 2, 3])[:3, 3], [1, 2, 3])
    Rz = parse_extrinsic("0 0 0 0 0 0.7071067811865476 0.7071067811865476")
    np.testing.assert_allclose(Rz[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    with pytest.raises(DataError, match="7 numbers"):
        parse_extrinsic("1 2 3 4")
    with pytest.raises(DataError, match="unit"):
        parse_extrinsic("0 0 0 0 0 0 2")


def test_read_gt_file_tum_header_and_kitti(tmp_path):
    p = tmp_path / "gt_odom.txt"
    p.write_text("timestamp x y z qx qy qz qw\n1.0 1 2 3 0 0 0 1\n2.0 2 2 3 0 0 0 1\n")
    tr = read_gt_file(p)
    assert len(tr) == 2 and tr.stamps[0] == 1.0
    k = tmp_path / "poses.txt"
    np.savetxt(k, np.tile(np.eye(4)[:3].ravel(), (3, 1)))
    assert len(read_gt_file(k, stamps=np.array([0.0, 0.1, 0.2]))) == 3
    with pytest.raises(DataError, match="not found"):
        read_gt_file(tmp_path / "missing.txt")


def test_no_warning_when_clean():
    m = Motion(t0=0.0)
    gt = gt_traj(m, 0.0, 1.0, 0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        associate(gt, np.array([0.2, 0.3]))
