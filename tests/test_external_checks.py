"""bench.runs.external.checks on a synthetic store (scans 0.125 s apart, a drive whose speed and
turn rate vary): what a correct estimate passes with, which scans are scored (ground truth,
not the calibration frames), the coverage threshold at its bound and what its refusal names,
the clock refusals in their order (the association's hint, then the misfit), and the bridged
gap's warning at three periods."""

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.runs.external.checks import _bridged, check_estimate
from bench.runs.external.score import ExternalSpec
from loaders.errors import DataError
from loaders.estimate import Estimate
from loaders.gt import time_span
from loaders.se3 import make_T
from loaders.trajectory import Trajectory
from test_external_clock import drive

SCANS = np.arange(0, 30, 0.125)  # 240 scans, exact binary stamps


def varied(t):
    return 5 + 3 * np.sin(0.7 * t) + 2 * np.sin(1.9 * t)


POSES = drive(SCANS, varied, yaw_rate=0.05)


class Store:
    """What check_estimate reads of a store sequence: its stamps, ground truth, provenance."""

    def __init__(self, gt_rows=slice(None), calibrated=None):
        self.stamps = SCANS
        self.ground_truth = Trajectory(SCANS[gt_rows], POSES[gt_rows])
        self.provenance = {"calibration": {"frames": calibrated}} if calibrated else {}

    def __len__(self):
        return len(self.stamps)


def check(stamps, poses, store=None, T_frame_sensor=None, fmt="tum", **options):
    spec = ExternalSpec("e.tum", "probe", **options)
    est = Estimate(Trajectory(stamps, poses), fmt=fmt)
    return check_estimate(store or Store(), est, spec,
                          np.eye(4) if T_frame_sensor is None else T_frame_sensor, "e.tum",
                          "store.h5")


def test_a_correct_estimate_passes_every_check():
    found = check(SCANS, POSES)
    assert found.coverage["matched"] == 240 and found.coverage["scans_with_gt"] == 240
    assert found.coverage["scored"] == 240 and found.coverage["share_scored"] == 1.0
    assert found.coverage["scans"] == 240 and found.with_gt.all()
    assert found.clock.startswith("on the store's clock")
    assert found.convention.startswith("wxyz: as read") and found.warnings == []
    np.testing.assert_allclose(found.matched.poses, POSES)
    # the format's own misreading is the one checked
    assert check(SCANS, POSES, fmt="kitti").convention.startswith("inverse: as read")


def test_the_poses_of_another_frame_are_checked_through_the_extrinsic():
    """Poses of a frame 3 m ahead of the sensor: with T_frame_sensor every check is the
    sensor's (the scans' poses, on the store's clock, the convention as read)."""
    T_frame_sensor = make_T(np.eye(3), np.array([3.0, 0.0, 0.0]))
    found = check(SCANS, POSES @ np.linalg.inv(T_frame_sensor), T_frame_sensor=T_frame_sensor)
    np.testing.assert_allclose(found.matched.poses, POSES, atol=1e-9)
    assert found.clock.startswith("on the store's clock")
    assert found.convention.startswith("wxyz: as read")


def test_only_scans_with_ground_truth_outside_the_calibration_frames_are_scored():
    found = check(SCANS, POSES, Store(calibrated=[0, 40]))
    assert not found.with_gt[:40].any() and found.with_gt[40:].all()
    assert found.coverage["scans_with_gt"] == 200 and found.coverage["scored"] == 200
    assert found.coverage["share_scored"] == 1.0
    found = check(SCANS, POSES, Store(gt_rows=slice(0, 160)), trust_clock=True)  # GT 0 .. 20 s
    assert found.coverage["scans_with_gt"] == 160 and found.coverage["scored"] == 160
    assert found.coverage["matched"] == 240


def test_the_coverage_is_refused_below_the_minimum_only():
    found = check(SCANS[:120], POSES[:120], min_coverage=0.5, trust_clock=True)  # 120 of 240
    assert found.coverage["share_scored"] == 0.5
    with pytest.raises(DataError) as e:
        check(SCANS[:119], POSES[:119], min_coverage=0.5, trust_clock=True)
    text = str(e.value)
    assert text.startswith("e.tum covers 119 of the 240 scans of store.h5 with ground truth "
                           "(49.6 %), below --min-coverage 0.5: 119 matched within 0.01 s, 0 "
                           "interpolated; the estimate (119 poses) spans ")
    assert text.endswith("A shorter or sparser estimate? --max-gap S interpolates between poses "
                         "at most S apart; --min-coverage 0 scores what it covers")
    with pytest.raises(DataError) as e:
        check(SCANS[:119], POSES[:119], min_coverage=0.5, max_gap_s=0.2, trust_clock=True)
    assert "--max-gap S" not in str(e.value)
    assert str(e.value).endswith("A shorter or sparser estimate? --min-coverage 0 scores what "
                                 "it covers")


def test_stamps_rounded_beyond_the_tolerance_are_named_with_the_tolerance_that_takes_them():
    """Every other stamp 0.4 ms off its scan, a tolerance of 0.1 ms, with --time-offset 1.05:
    half the scans matched, and the refusal names --tolerance 0.0004 (the offset applied)."""
    stamps = SCANS - 1.05 + 0.0004 * (np.arange(240) % 2)
    with pytest.raises(DataError) as e:
        check(stamps, POSES, time_offset_s=1.05, tolerance_s=1e-4)
    text = str(e.value)
    assert "covers 120 of the 240 scans" in text
    assert text.endswith("beyond --tolerance 0.0001: --tolerance 0.0004 takes them")


def test_nothing_to_score_without_ground_truth_at_the_estimates_scans():
    late = SCANS >= 20
    with pytest.raises(DataError, match=r"^e.tum: none of the 80 scans with an estimate has "
                                        r"ground truth in store.h5; nothing to score$"):
        check(SCANS[late], POSES[late], Store(gt_rows=slice(0, 80)), trust_clock=True)


def test_a_clock_off_the_scans_gets_the_profiles_offsets_in_the_associations_refusal():
    """Stamps 0.33 s early: 0.045 s off every scan, none within 0.01 s; the association's
    refusal says the offset the motion profile fits."""
    with pytest.raises(DataError, match=r"e.tum does not overlap the scans of store.h5.*its "
                                        r"speed and turn-rate profile lines up with the ground "
                                        r"truth's with --time-offset 0.3300"):
        check(SCANS - 0.33, POSES)


def test_a_decisive_misfit_on_the_scans_stamps_is_refused():
    """Stamps 4 periods early: every pose on a scan, yet its profile fits only at +0.5 s."""
    with pytest.raises(DataError, match=r"^e.tum: its clock does not fit the scans of store.h5.*"
                                        r"score it with --time-offset 0.5000 "):
        check(SCANS - 0.5, POSES)
    # with that offset it passes, on the store's clock
    assert check(SCANS - 0.5, POSES, time_offset_s=0.5).clock.startswith("on the store's clock")


def test_the_conventions_are_checked_with_the_estimates_offset_and_tolerance():
    """Stamps 1 s early and 15 ms off: with --time-offset 1 and --tolerance 0.02 the other
    reading is matched as the estimate is (both at every scan), so the convention is told."""
    found = check(SCANS - 1.0 + 0.015, POSES, time_offset_s=1.0, tolerance_s=0.02)
    assert found.coverage["matched"] == 240
    assert found.convention.startswith("wxyz: as read")
    # every other pose, --max-gap 0.3: the other reading is interpolated alike, over the
    # pairs of an estimate at each of the 239 scans it covers (the last is beyond its last pose)
    found = check(SCANS[::2], POSES[::2], max_gap_s=0.3, trust_clock=True)
    assert found.coverage["interpolated"] == 119 and found.coverage["covered"] == 239
    every = check(SCANS[:-1], POSES[:-1], trust_clock=True).convention
    pairs = re.search(r"over \d+ pairs", every).group()
    assert found.convention.startswith("wxyz: as read") and pairs in found.convention


def test_a_gap_bridged_wider_than_three_periods_is_warned():
    found = check(SCANS[::4], POSES[::4], max_gap_s=0.6, trust_clock=True)
    assert found.warnings == ["e.tum: --max-gap 0.6 bridged a gap of 0.5 s (4.0 scan periods) "
                              "between two of its poses: the scans inside are scored on poses "
                              "interpolated across it, not estimated"]
    # 3 periods: not warned
    assert check(SCANS[::3], POSES[::3], max_gap_s=0.6, trust_clock=True).warnings == []
    assert _bridged({"max_gap_s": 1.0, "widest_bridged_s": 0.5}, SCANS[:1], "e") == []
    assert _bridged({"max_gap_s": 1.0}, SCANS, "e") == []


def misread_wxyz(poses):
    """The poses a reader of x y z w gets from a file holding them in w x y z order."""
    out = poses.copy()
    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()  # x y z w
    out[:, :3, :3] = Rotation.from_quat(q[:, [3, 0, 1, 2]]).as_matrix()
    return out


def test_the_other_reading_is_of_the_same_frame_and_named_with_the_file():
    """A file of w x y z quaternions of a frame turned and 3 m ahead of the sensor: the other
    reading, through the extrinsic, is the sensor's motion: refused, naming the file."""
    T_frame_sensor = make_T(Rotation.from_euler("zx", [90, 30], degrees=True).as_matrix(),
                            np.array([3.0, 0.0, 0.0]))
    frame = POSES @ np.linalg.inv(T_frame_sensor)
    with pytest.raises(DataError, match=r"^e.tum: read as tum, its relative motions disagree .*"
                                        r"quaternions in w x y z order"):
        check(SCANS, misread_wxyz(frame), T_frame_sensor=T_frame_sensor, trust_clock=True)
    with pytest.raises(DataError, match=r"^e.tum: read as kitti, .*the inverse poses"):
        check(SCANS, np.linalg.inv(frame), T_frame_sensor=T_frame_sensor, fmt="kitti",
              trust_clock=True)


def test_the_clock_check_gets_the_files_unit_raw_stamps_and_names():
    mm = make_T(POSES[:, :3, :3], POSES[:, :3, 3] * 1e3)
    spec = ExternalSpec("e.tum", "probe")
    est = Estimate(Trajectory(SCANS - 0.33, mm), stamp_unit="ms")
    with pytest.raises(DataError, match=r"^e.tum: read in milliseconds, .* the ground truth of "
                                        r"store.h5 moves"):
        check_estimate(Store(), est, spec, np.eye(4), "e.tum", "store.h5")
    raw = np.arange(240.0)
    est = Estimate(Trajectory(raw * 1e-3, POSES), stamp_unit="ms", raw_stamps=raw)
    with pytest.raises(DataError, match=r"^e.tum: its stamps are frame indices"):
        check_estimate(Store(), est, spec, np.eye(4), "e.tum", "store.h5")


def test_clock_warnings_are_kept_with_the_bridged_gaps():
    """Stamps on the scans, poses 0.5 s late: the clock's warning is among the warnings."""
    late = drive(SCANS + 0.5, varied, yaw_rate=0.05)
    found = check(SCANS, late)
    assert len(found.warnings) == 1 and "its stamps are the scans' own" in found.warnings[0]


def test_one_scan_with_ground_truth_is_the_whole_share():
    found = check(SCANS, POSES, Store(gt_rows=slice(0, 1)), trust_clock=True)
    assert found.coverage["scans_with_gt"] == 1 and found.coverage["share_scored"] == 1.0


def test_ground_truth_out_of_order_is_named_by_the_store():
    store = Store()
    order = np.arange(240)
    order[[10, 11]] = [11, 10]
    store.ground_truth = Trajectory(SCANS[order], POSES[order])
    with pytest.raises(DataError, match=r"^store.h5"):
        check(SCANS, POSES, store, trust_clock=True)


def test_the_coverage_refusal_states_the_span_with_the_offset():
    with pytest.raises(DataError) as e:
        check(SCANS[:119] - 100.0, POSES[:119], time_offset_s=100.0, min_coverage=0.5,
              trust_clock=True)
    assert f"spans {time_span(SCANS[:119])}, the scans with ground truth" in str(e.value)


def test_a_bridged_gap_needs_a_scan_period():
    assert _bridged({"max_gap_s": 1.0, "widest_bridged_s": 0.5}, SCANS[:2], "e")  # 4 periods
    assert _bridged({"max_gap_s": 10.0, "widest_bridged_s": 5.0}, SCANS[:1], "e") == []
