"""loaders.gt on small trajectories whose answers are worked out by hand: the time-offset hint
(time zones, slack, non-finite and empty stamps), the clean-up of ground-truth rows (messages,
tolerance), what ``associate`` keeps, scores, reports and warns, the nearest-stamp search and
``gt_for_frames`` on both of its routes."""

import warnings

import numpy as np
import pytest

from loaders.errors import DataError, GroundTruthWarning
from loaders.gt import (
    MAX_GAP_STEPS,
    STAMP_TOLERANCE_S,
    TIME_ZONE_SLACK_S,
    Association,
    associate,
    clean_trajectory,
    gt_for_frames,
    nearest_indices,
    offset_hint,
    remove_origin,
    time_span,
)
from loaders.se3 import make_T
from loaders.trajectory import Trajectory


def along_x(stamps, speed=1.0) -> Trajectory:
    """Poses at x = speed x stamp (identity rotation): interpolation is exact."""
    s = np.asarray(stamps, dtype=np.float64)
    return Trajectory(s, np.stack([make_T(np.eye(3), [speed * t, 0.0, 0.0]) for t in s]))


def hint(gt0: float, scan0: float) -> str:
    return offset_hint(np.array([gt0, gt0 + 1.0]), np.array([scan0, scan0 + 1.0]))


# --- offset_hint -------------------------------------------------------------------------------


def test_a_time_zone_is_suggested_as_whole_hours():
    assert TIME_ZONE_SLACK_S == 600.0
    # GT in UTC+8: its stamps 8 h ahead of the scans' (plus 100 s of misalignment)
    assert hint(1700028800.0, 1700000100.0) == (
        "set the time offset: try --time-offset -28800 (the ground truth's clock is 8 h ahead "
        "of the scans'; gt_stamp + offset = sensor clock)")
    assert hint(1000.0, 1000.0 + 7200.0 - 599.0) == (
        "set the time offset: try --time-offset 7200 (the ground truth's clock is 2 h behind "
        "the scans'; gt_stamp + offset = sensor clock)")
    # exactly the slack still counts; one second more does not
    assert "--time-offset 3600 (the ground truth's clock is 1 h behind" in hint(0.0, 4200.0)
    assert hint(0.0, 4201.0) == (
        "set the time offset: try --time-offset 4201 (this lines up the first stamps; "
        "gt_stamp + offset = sensor clock)")
    assert "--time-offset -3600 (the ground truth's clock is 1 h ahead of" in hint(3000.0, -600.0)
    # hours are diff / 3600 s rounded, however many: 2000 h (a clock 83 days off)
    assert "--time-offset 7200000 (the ground truth's clock is 2000 h behind" in hint(
        0.0, 7200000.0)


def test_less_than_half_an_hour_lines_up_the_first_stamps():
    assert hint(10.0, 10.25) == ("set the time offset: try --time-offset 0.25 (this lines up "
                                 "the first stamps; gt_stamp + offset = sensor clock)")
    assert "--time-offset -500 (this lines up" in hint(600.0, 100.0)
    # ten significant digits
    assert "--time-offset 1234.567891 (" in hint(0.0, 1234.56789123)
    # the first stamps, not the smallest
    assert "--time-offset 5 (" in offset_hint(np.array([0.0, -50.0]), np.array([5.0, -100.0]))


def test_no_stamps_or_non_finite_stamps_get_no_offset():
    assert offset_hint(np.array([]), np.array([1.0])) == "one of them has no stamps"
    assert offset_hint(np.array([1.0]), np.array([])) == "one of them has no stamps"
    assert offset_hint(np.array([np.nan]), np.array([1.0])) == (
        "a stamp or the time offset is not finite (nan); expected finite stamps and offset [s]")
    assert offset_hint(np.array([1.0]), np.array([np.inf])) == (
        "a stamp or the time offset is not finite (inf); expected finite stamps and offset [s]")


def test_time_span():
    assert time_span(np.array([3.0, 1.25, 2.0])) == "[1.250, 3.000] s"
    assert time_span(np.array([])) == "[] s"


# --- clean_trajectory -------------------------------------------------------------------------


def test_clean_errors_name_the_row_and_count():
    t = along_x([0.0, 1.0, 0.5, 2.0, 1.5])
    with pytest.raises(DataError) as err:
        clean_trajectory(t, "gt.txt")
    assert str(err.value) == (
        "gt.txt, pose row 2: stamp 0.500000 s goes backwards from 1.000000 s (2 such rows); "
        "ground-truth rows must be in time order (a garbled or concatenated file?)")
    two = Trajectory(np.array([0.0, 1.0, 1.0, 2.0, 2.0]),
                     np.stack([make_T(np.eye(3), [k, 0, 0]) for k in range(5)]))
    with pytest.raises(DataError) as err:
        clean_trajectory(two, "gt.txt")
    assert str(err.value) == (
        "gt.txt, pose row 2: repeats the stamp 1.000000 s of the previous row with a different "
        "pose (2 such rows); expected one pose per stamp")
    bad = along_x([0.0, 1.0, 2.0])
    bad.stamps[1] = np.inf
    with pytest.raises(DataError) as err:
        clean_trajectory(bad)
    assert str(err.value) == "ground truth, pose row 1: stamp is not finite (inf)"


def test_clean_tolerance_and_duplicate_pose_precision():
    # stamps 0.05 s backwards pass with a tolerance of 0.1 s (and are same-instant rows)
    poses = np.stack([make_T(np.eye(3), [1.0, 0, 0])] * 3)
    t = Trajectory(np.array([0.0, 1.0, 0.95]), poses)
    with pytest.warns(GroundTruthWarning, match="gt: 1 rows repeat the previous row's stamp and "
                                                r"pose \(duplicates dropped\)"):
        out, info = clean_trajectory(t, "gt", tolerance_s=0.1)
    np.testing.assert_array_equal(out.stamps, [0.0, 1.0])
    assert info == {"duplicate_rows": 1}
    # exactly the tolerance apart: the same instant
    with pytest.warns(GroundTruthWarning, match="2 rows repeat"):
        _, info = clean_trajectory(Trajectory(np.array([0.0, 0.5, 1.0]), poses),
                                   tolerance_s=0.5)
    assert info == {"duplicate_rows": 2}
    # poses 1e-10 apart are the same, 1e-8 apart are not
    near = np.stack([np.eye(4), np.eye(4)])
    near[1, 0, 3] = 1e-10
    with pytest.warns(GroundTruthWarning):
        out, _ = clean_trajectory(Trajectory(np.array([1.0, 1.0]), near))
    assert len(out) == 1 and out.poses[0, 0, 3] == 0.0
    near[1, 0, 3] = 1e-8
    with pytest.raises(DataError, match="different pose"):
        clean_trajectory(Trajectory(np.array([1.0, 1.0]), near))


def test_a_clean_trajectory_is_unchanged_and_silent():
    t = along_x([0.0, 0.1, 0.2])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out, info = clean_trajectory(t)
    assert info == {"duplicate_rows": 0}
    np.testing.assert_array_equal(out.stamps, t.stamps)
    np.testing.assert_array_equal(out.poses, t.poses)


# --- associate -------------------------------------------------------------------------------


def test_report_of_a_clean_association():
    gt = along_x(np.arange(0.0, 2.01, 0.1))
    a = associate(gt, np.array([0.25, 0.5, 1.75]), offset_s=0.0, max_gap_s=0.2,
                  gt_file="g.txt")
    assert isinstance(a, Association)
    np.testing.assert_allclose(a.ground_truth.positions[:, 0], [0.25, 0.5, 1.75], atol=1e-12)
    assert a.report == {
        "gt_file": "g.txt", "mode": "interpolate", "offset_s": 0.0, "max_gap_s": 0.2,
        "tolerance_s": 0.0, "uncovered": "keep", "scans": 3, "kept": 3, "with_gt": 3,
        "uncovered_before": 0, "uncovered_after": 0, "uncovered_inside": 0, "trimmed": 0,
        "gt_duplicate_rows": 0}
    assert (a.uncovered, a.trimmed) == (0, 0)


def test_offset_and_default_gap():
    # GT 100 s behind; the default max_gap_s of 0.5 s bridges 0.4 s steps, not 0.6 s
    gt = along_x([0.0, 0.4, 0.8, 1.4, 1.8])
    with pytest.warns(GroundTruthWarning, match="1 inside gaps > 0.5 s"):
        a = associate(gt, np.array([100.2, 100.6, 101.1, 101.6]), offset_s=100.0)
    np.testing.assert_allclose(a.ground_truth.positions[:, 0], [0.2, 0.6, 1.6], atol=1e-12)
    assert list(a.covered) == [True, True, False, True] and a.uncovered_inside == 1
    assert a.uncovered_after == 0 and a.report["offset_s"] == 100.0
    assert a.report["with_gt"] == 3 and a.report["max_gap_s"] == 0.5


def test_warning_counts_and_trim():
    gt = along_x([1.0, 1.1, 1.2, 2.0, 2.1])
    scans = np.array([0.9, 1.05, 1.5, 2.05, 2.2, 2.3])
    with pytest.warns(GroundTruthWarning) as got:
        a = associate(gt, scans, max_gap_s=0.2, scan_file="run.bag", gt_file="gt.txt")
    assert [str(w.message) for w in got] == [
        "run.bag: 4 of the 6 scans kept have no ground truth in gt.txt and are excluded from "
        "scoring (1 before, 2 after its span, 1 inside gaps > 0.2 s)"]
    assert (a.uncovered_before, a.uncovered_after, a.uncovered_inside) == (1, 2, 1)
    assert a.uncovered == 4 and list(a.keep) == [0, 1, 2, 3, 4, 5]
    assert list(a.covered) == [False, True, False, True, False, False]
    with pytest.warns(GroundTruthWarning) as got:
        t = associate(gt, scans, max_gap_s=0.2, uncovered="trim", scan_file="run.bag",
                      gt_file="gt.txt")
    assert [str(w.message) for w in got] == [
        "run.bag: 1 of the 3 scans kept have no ground truth in gt.txt and are excluded from "
        "scoring; 3 scans before/after its span trimmed (1 before, 2 after its span, 1 inside "
        "gaps > 0.2 s)"]
    assert list(t.keep) == [1, 2, 3] and list(t.covered) == [True, False, True]
    assert t.trimmed == 3 and t.report["kept"] == 3 and t.report["trimmed"] == 3
    np.testing.assert_allclose(t.ground_truth.stamps, [1.05, 2.05], atol=0)
    # trimmed but nothing missing: only the trimmed part is said
    with pytest.warns(GroundTruthWarning) as got:
        associate(gt, np.array([0.5, 1.1, 1.2]), uncovered="trim", max_gap_s=0.2,
                  scan_file="s", gt_file="g")
    assert [str(w.message) for w in got] == [
        "s: 1 scans before/after its span trimmed (1 before, 0 after its span, 0 inside gaps "
        "> 0.2 s)"]


def test_uncovered_error_names_the_first_uncovered_scan():
    gt = along_x([1.0, 1.1, 1.2])
    with pytest.raises(DataError) as err:
        associate(gt, np.array([1.0, 1.3, 1.4, 1.5]), uncovered="error", gt_file="g",
                  scan_file="s")
    assert str(err.value) == ("s, frame 1: scan stamp 1.300 s is not covered by g (GT spans "
                              "[1.000, 1.200] s, max gap 0.5 s); 3 of 4 scans uncovered")
    a = associate(gt, np.array([1.0, 1.2]), uncovered="error")  # all covered: fine
    assert a.covered.all()


def test_bad_arguments_and_no_overlap_message():
    gt = along_x([0.0, 1.0])
    with pytest.raises(DataError) as err:
        associate(gt, np.array([0.5]), uncovered="skip")
    assert str(err.value) == "uncovered must be 'keep', 'trim' or 'error', got 'skip'"
    with pytest.raises(DataError) as err:
        associate(gt, np.array([0.5]), mode="linear")
    assert str(err.value) == ("association mode must be 'interpolate' or 'nearest', got "
                              "'linear'")
    with pytest.raises(DataError) as err:
        associate(Trajectory(np.zeros(0), np.zeros((0, 4, 4))), np.array([0.5]), gt_file="g")
    assert str(err.value) == "g: ground truth has no poses"
    with pytest.raises(DataError) as err:
        associate(gt, np.array([7200.5, 7201.0]), offset_s=0.25, gt_file="g", scan_file="s")
    assert str(err.value) == (
        "ground truth g does not overlap the scans of s: GT spans [0.250, 1.250] s (offset "
        "+0.250 s applied), the 2 scans span [7200.500, 7201.000] s; different clocks? set the "
        "time offset: try --time-offset 7200 (the ground truth's clock is 2 h behind the "
        "scans'; gt_stamp + offset = sensor clock)")


def test_old_drop_policy_keeps_with_a_warning():
    gt = along_x([0.0, 0.1])
    with pytest.warns(GroundTruthWarning) as got:
        a = associate(gt, np.array([0.05]), uncovered="drop", scan_file="s")
    assert str(got[0].message) == (
        "s: uncovered='drop' is no longer supported: scans without ground truth are kept in "
        "the sequence and excluded from scoring (uncovered='keep')")
    assert a.report["uncovered"] == "keep"


def test_tolerance_in_interpolate_mode_takes_the_end_poses():
    gt = along_x([1.0, 1.5, 2.0])
    a = associate(gt, np.array([0.95, 1.25, 2.05]), tolerance_s=0.05)
    np.testing.assert_allclose(a.ground_truth.positions[:, 0], [1.0, 1.25, 2.0], atol=1e-12)
    np.testing.assert_allclose(a.ground_truth.stamps, [0.95, 1.25, 2.05], atol=0)
    assert a.report["tolerance_s"] == 0.05
    with pytest.warns(GroundTruthWarning):
        b = associate(gt, np.array([0.94, 1.25, 2.06]), tolerance_s=0.05)
    assert list(b.covered) == [False, True, False]


def test_nearest_mode_and_a_single_pose():
    gt = along_x([1.0, 2.0, 3.0])
    with pytest.warns(GroundTruthWarning):
        a = associate(gt, np.array([1.04, 1.6, 2.96, 3.1]), mode="nearest", tolerance_s=0.05)
    assert list(a.covered) == [True, False, True, False]
    np.testing.assert_allclose(a.ground_truth.positions[:, 0], [1.0, 3.0], atol=0)
    assert a.report["mode"] == "nearest"
    one = Trajectory(np.array([5.0]), make_T(np.eye(3), [7.0, 0, 0])[None])
    b = associate(one, np.array([5.0, 5.0]))
    np.testing.assert_allclose(b.ground_truth.positions, [[7.0, 0, 0]] * 2, atol=0)


def test_extrinsic_and_world_fix_are_applied_on_their_sides():
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg yaw
    gt = Trajectory(np.array([0.0, 1.0]), np.stack([make_T(R, [0, 0, 0]), make_T(R, [2, 0, 0])]))
    T_bs = make_T(np.eye(3), [1.0, 0.0, 0.0])  # sensor 1 m ahead of the body
    fix = make_T(np.eye(3), [0.0, 0.0, -10.0])
    a = associate(gt, np.array([0.5]), T_body_sensor=T_bs, T_world_fix=fix, max_gap_s=1.0)
    # body at (1, 0, 0) facing +y: the sensor at (1, 1, 0), then 10 m down
    np.testing.assert_allclose(a.ground_truth.positions, [[1.0, 1.0, -10.0]], atol=1e-12)
    only_fix = associate(gt, np.array([0.5]), T_world_fix=fix, max_gap_s=None)
    np.testing.assert_allclose(only_fix.ground_truth.positions, [[1.0, 0.0, -10.0]],
                               atol=1e-12)


def test_duplicates_are_reported():
    gt = Trajectory(np.array([0.0, 0.1, 0.1, 0.2]),
                    np.stack([make_T(np.eye(3), [x, 0, 0]) for x in (0.0, 0.1, 0.1, 0.2)]))
    with pytest.warns(GroundTruthWarning, match="duplicates dropped"):
        a = associate(gt, np.array([0.05, 0.15]))
    assert a.report["gt_duplicate_rows"] == 1


# --- nearest_indices, remove_origin, gt_for_frames ---------------------------------------------


def test_nearest_indices_ties_ends_and_one_stamp():
    idx, dist = nearest_indices(np.array([0.0, 1.0, 2.0]), np.array([-5.0, 0.5, 1.4, 1.6, 9.0]))
    assert list(idx) == [0, 0, 1, 2, 2]  # a tie takes the lower
    np.testing.assert_allclose(dist, [5.0, 0.5, 0.4, 0.4, 7.0], atol=1e-12)
    idx, dist = nearest_indices(np.array([3.0]), np.array([1.0, 4.5]))
    assert list(idx) == [0, 0]
    np.testing.assert_allclose(dist, [2.0, 1.5])
    idx, dist = nearest_indices(np.array([0.0, 1.0]), np.array([0.9]))
    assert list(idx) == [1] and dist[0] == pytest.approx(0.1)


def test_remove_origin_returns_the_origin_and_shifts_every_pose():
    gt = along_x([0.0, 1.0, 2.0], speed=3.0).transformed(make_T(np.eye(3), [5.0, 6.0, 7.0]))
    local, origin = remove_origin(gt)
    np.testing.assert_allclose(origin, [5.0, 6.0, 7.0])
    np.testing.assert_allclose(local.positions, [[0, 0, 0], [3, 0, 0], [6, 0, 0]], atol=1e-12)
    origin[0] = 99.0  # a copy, not a view of the poses
    assert gt.poses[0, 0, 3] == 5.0


def test_gt_for_frames_sampled_at_the_scans_takes_exact_rows():
    assert STAMP_TOLERANCE_S == 1e-4 and MAX_GAP_STEPS == 3.0
    gt = along_x([1.0, 1.1, 1.2, 1.3])
    stamps = np.array([1.1, 1.15, 1.2 + 5e-5, 1.3])
    poses, mask = gt_for_frames(gt, stamps)
    assert list(mask) == [True, False, True, True]
    np.testing.assert_allclose(poses[mask][:, 0, 3], [1.1, 1.2, 1.3], atol=1e-12)
    assert np.isnan(poses[1]).all()


def test_gt_for_frames_at_its_own_rate_is_interpolated_within_three_steps():
    gt = along_x([0.0, 0.01, 0.02, 0.03, 0.06, 0.1, 0.11])  # median step 0.01
    stamps = np.array([0.005, 0.045, 0.08, 0.105, 0.2])
    poses, mask = gt_for_frames(gt, stamps)
    # 0.03 -> 0.06 is three steps (bridged), 0.06 -> 0.1 four (not), 0.2 after the span
    assert list(mask) == [True, True, False, True, False]
    np.testing.assert_allclose(poses[mask][:, 0, 3], [0.005, 0.045, 0.105], atol=1e-12)


def test_gt_for_frames_empty_inputs_and_one_row():
    poses, mask = gt_for_frames(Trajectory(np.zeros(0), np.zeros((0, 4, 4))), np.array([1.0]))
    assert poses.shape == (1, 4, 4) and np.isnan(poses).all() and not mask.any()
    poses, mask = gt_for_frames(along_x([1.0]), np.zeros(0))
    assert poses.shape == (0, 4, 4) and mask.shape == (0,)
    poses, mask = gt_for_frames(along_x([1.0]), np.array([0.5, 1.0, 1.00005]))
    assert list(mask) == [False, True, True]
    with pytest.raises(DataError, match="g, pose row 1: stamp"):
        gt_for_frames(along_x([1.0, 0.5]), np.array([1.0]), name="g")
    with pytest.raises(DataError, match="^ground truth, pose row 1: stamp"):
        gt_for_frames(along_x([1.0, 0.5]), np.array([1.0]))


# --- bounds worked out on exactly representable stamps ------------------------------------------


def test_interpolate_mode_tolerance_bounds_are_inclusive():
    gt = along_x([1.0, 1.5, 2.0])
    a = associate(gt, np.array([0.75, 1.25, 1.75, 2.25]), tolerance_s=0.25)
    assert a.covered.all()
    # only the scans outside the span take an end pose; 1.75 s is interpolated
    np.testing.assert_allclose(a.ground_truth.positions[:, 0], [1.0, 1.25, 1.75, 2.0],
                               atol=1e-12)


def test_nearest_mode_tolerance_bound_is_inclusive():
    gt = along_x([1.0, 2.0, 3.0])
    a = associate(gt, np.array([1.25, 2.75]), mode="nearest", tolerance_s=0.25)
    assert a.covered.all()
    np.testing.assert_allclose(a.ground_truth.positions[:, 0], [1.0, 3.0], atol=0)


def test_integer_scan_stamps_are_taken_as_seconds():
    gt = along_x([0.5, 1.0, 1.5, 2.0])
    a = associate(gt, [0, 1, 2], tolerance_s=0.5)
    assert a.covered.all()
    assert a.ground_truth.stamps.dtype == np.float64
    np.testing.assert_allclose(a.ground_truth.positions[:, 0], [0.5, 1.0, 2.0], atol=1e-12)


def test_default_file_names_in_messages():
    gt = along_x([0.0, 1.0])
    with pytest.raises(DataError) as err:
        associate(gt, np.array([5.0]))
    assert str(err.value).startswith("ground truth ground truth does not overlap the scans of "
                                     "scans: GT spans")
    with pytest.warns(GroundTruthWarning) as got:
        associate(gt, np.array([0.5, 3.0]), max_gap_s=None)
    assert str(got[0].message).startswith("scans: 1 of the 2 scans kept have no ground truth in "
                                          "ground truth and are excluded")
    back = along_x([0.0, 1.0, 0.5])
    with pytest.raises(DataError, match=r"^g\.txt, pose row 2: stamp 0\.500000 s goes "):
        associate(back, np.array([0.5]), gt_file="g.txt")
    with pytest.raises(DataError, match=r"^ground truth, pose row 2: stamp"):
        associate(back, np.array([0.5]))


def test_same_stamp_poses_far_from_the_origin_are_compared_absolutely():
    """Two rows at one instant 1 mm apart at x = 1000 km: different poses (a relative
    tolerance would take them for one)."""
    poses = np.stack([make_T(np.eye(3), [1e6, 0, 0]), make_T(np.eye(3), [1e6 + 1e-3, 0, 0])])
    with pytest.raises(DataError, match="different pose"):
        clean_trajectory(Trajectory(np.array([1.0, 1.0]), poses))


def test_gt_for_frames_exact_bound_and_one_scan():
    gt = along_x([1.0, 2.0])
    poses, mask = gt_for_frames(gt, np.array([1.25, 2.0]), tolerance_s=0.25)
    # sampled at the scans (each GT row within 0.25 s of one): the rows, not interpolation
    assert list(mask) == [True, True]
    np.testing.assert_allclose(poses[:, 0, 3], [1.0, 2.0], atol=0)
    poses, mask = gt_for_frames(along_x([1.0, 1.1, 1.2]), np.array([1.1]))
    assert list(mask) == [True] and poses[0, 0, 3] == pytest.approx(1.1)
    poses, mask = gt_for_frames(Trajectory(np.zeros(0), np.zeros((0, 4, 4))), np.array([1.0]))
    assert mask.dtype == bool


def test_gt_for_frames_two_rows_at_their_own_rate_are_interpolated():
    # rows at 0 and 1 s inside the scans' span and off them: interpolated at 0.5 s
    poses, mask = gt_for_frames(along_x([0.0, 1.0]), np.array([-1.0, 0.5, 2.0]))
    assert list(mask) == [False, True, False] and poses[1, 0, 3] == pytest.approx(0.5)


def test_gt_rows_off_the_scans_inside_their_span_mean_its_own_rate():
    # a row at 1.05 s between the first two scans: GT at its own rate, interpolated
    poses, mask = gt_for_frames(along_x([1.0, 1.05, 1.1, 1.2]),
                                np.array([1.0, 1.1, 1.15, 1.2]))
    assert mask.all() and poses[2, 0, 3] == pytest.approx(1.15)
    # a row at 1.15 s between the last two scans: the same
    poses, mask = gt_for_frames(along_x([1.0, 1.1, 1.15, 1.2]),
                                np.array([1.0, 1.05, 1.1, 1.2]))
    assert mask.all() and poses[1, 0, 3] == pytest.approx(1.05)
    # rows far outside the scans' span do not count: sampled at the scans
    poses, mask = gt_for_frames(along_x([0.0, 5.0, 10.0, 10.5, 11.0, 20.0]),
                                np.array([10.0, 10.25, 10.5, 11.0]))
    assert list(mask) == [True, False, True, True]


def test_nearest_indices_are_integers_and_stay_in_range():
    idx, dist = nearest_indices(np.array([0.0, 1.0]), np.array([-1.0, 0.2, 5.0]))
    assert idx.dtype.kind == "i" and list(idx) == [0, 0, 1]
    np.testing.assert_allclose(dist, [1.0, 0.2, 4.0])
    idx, dist = nearest_indices(np.array([2.0]), np.array([1.0]))
    assert idx.dtype.kind == "i" and list(idx) == [0] and dist[0] == 1.0


def test_gt_for_frames_a_scan_just_past_the_gt_end_takes_the_end_pose():
    """GT at its own rate (100 Hz) up to 1.0 s; scans 50 us before its start and after its end
    are within STAMP_TOLERANCE_S (0.1 ms) of the end poses: they have ground truth, the end
    poses (interpolation used to refuse them with a DataError)."""
    s = np.arange(0.0, 1.00001, 0.01)
    poses, mask = gt_for_frames(along_x(s), np.array([-5e-5, 0.505, 1.00005, 1.0002]))
    assert list(mask) == [True, True, True, False]
    np.testing.assert_allclose(poses[:3, 0, 3], [0.0, 0.505, 1.0], atol=1e-12)
    assert np.isnan(poses[3]).all()
