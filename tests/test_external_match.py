"""bench.runs.external.match: an estimate at its own stamps brought to the scan stamps, against
analytic motions (constant speed along x with a constant yaw rate: SE(3) interpolation of two
poses on it is exact in rotation, and exact in translation for the straight part)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.runs.external.match import match_to_scans
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


def test_another_rate_is_interpolated_only_when_asked():
    t_est = np.arange(0, 3.95, 0.037)  # 27 Hz, ends before the last scans
    est = Trajectory(t_est, straight(t_est))
    near = np.min(np.abs(SCANS[:, None] - t_est[None, :]), axis=1) <= 0.01  # evo's rule
    # by default (as evo): only the scans with a pose within 0.01 s, taken as they are
    m = match_to_scans(est, SCANS)
    np.testing.assert_array_equal(m.covered, near)
    np.testing.assert_array_equal(m.matched, near)
    assert m.report["interpolated"] == 0 and m.report["max_gap_s"] is None
    assert 2 < near.sum() < (SCANS <= t_est[-1]).sum() - 2  # both kinds of scans
    # asked (--max-gap): every scan inside the span, interpolated exactly on this motion
    m = match_to_scans(est, SCANS, max_gap_s=3 * 0.037)
    inside = SCANS <= t_est[-1]
    np.testing.assert_array_equal(m.covered, inside)
    np.testing.assert_allclose(m.poses[inside & ~near], straight(SCANS[inside & ~near]),
                               atol=1e-12)
    assert np.isnan(m.poses[~inside]).all()
    assert m.report["matched"] == near.sum()
    assert m.report["interpolated"] == inside.sum() - near.sum()
    assert m.report["max_gap_s"] == pytest.approx(3 * 0.037)


def test_a_gap_longer_than_max_gap_is_never_bridged():
    t_est = np.concatenate([np.arange(0, 1.0, 0.05), np.arange(2.0, 3.0, 0.05)])
    m = match_to_scans(Trajectory(t_est, straight(t_est)), SCANS, max_gap_s=0.15)
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


@pytest.mark.parametrize("option, message", [
    ({"tolerance_s": -1}, "--tolerance -1: expected a finite tolerance >= 0 s"),
    ({"tolerance_s": float("inf")}, "--tolerance inf: expected a finite tolerance"),
    ({"tolerance_s": float("nan")}, "--tolerance nan: expected a finite tolerance"),
    ({"max_gap_s": -1}, "--max-gap -1: expected a finite gap > 0 s"),
    ({"max_gap_s": 0.0}, "--max-gap 0: expected a finite gap > 0 s"),
    ({"max_gap_s": float("nan")}, "--max-gap nan: expected a finite gap"),
    ({"time_offset_s": float("nan")}, "--time-offset nan: expected a finite number of seconds"),
    ({"time_offset_s": float("-inf")}, "--time-offset -inf: expected a finite number"),
])
def test_a_negative_or_non_finite_option_is_an_error(option, message):
    with pytest.raises(DataError) as err:
        match_to_scans(Trajectory(SCANS, straight(SCANS)), SCANS, **option)
    assert str(err.value).startswith(message), str(err.value)


# binary fractions: the distances below are exact, so the boundary is the boundary
GRID = np.arange(16) * 0.25


def test_the_tolerance_is_inclusive_at_its_boundary():
    # every pose exactly 0.125 s after a scan (and before the next: a tie, to the earlier)
    est = Trajectory(GRID + 0.125, straight(GRID))
    m = match_to_scans(est, GRID, tolerance_s=0.125)
    assert m.matched.all() and m.report["matched"] == 16  # |d| <= tolerance
    np.testing.assert_array_equal(m.poses, est.poses)
    with pytest.raises(DataError, match="no scan has a pose within 0.125 s"):
        match_to_scans(est, GRID, tolerance_s=np.nextafter(0.125, 0))


def test_tolerance_zero_matches_equal_stamps_only():
    m = match_to_scans(Trajectory(GRID, straight(GRID)), GRID, tolerance_s=0.0)
    assert m.matched.all() and m.report["matched"] == 16
    off = Trajectory(GRID + 2.0 ** -20, straight(GRID))
    with pytest.raises(DataError, match="no scan has a pose within 0 s"):
        match_to_scans(off, GRID, tolerance_s=0.0)


def test_a_large_tolerance_never_copies_a_pose_beyond_the_estimate():
    """An estimate over the first half of the scans with --tolerance 100: the second half takes
    no pose (the last pose is matched to its own scan only): 50 % covered, not 100 %."""
    est = Trajectory(SCANS[:20], straight(SCANS[:20]))
    m = match_to_scans(est, SCANS, tolerance_s=100.0)
    np.testing.assert_array_equal(m.covered, np.arange(40) < 20)
    assert m.report["covered"] == 20 and np.isnan(m.poses[20:]).all()
    np.testing.assert_array_equal(m.poses[:20], est.poses)


def test_a_pose_is_matched_to_one_scan_at_most():
    """5 Hz poses halfway between the scans of an 8 Hz grid, within the tolerance of two scans
    each: each pose goes to one scan, never copied onto its neighbour."""
    scans = np.arange(32) * 0.125
    t_est = np.arange(8) * 0.5 + 0.0625
    m = match_to_scans(Trajectory(t_est, straight(t_est)), scans, tolerance_s=0.07)
    assert m.report["matched"] == 8
    used = [np.flatnonzero(np.all(m.poses[m.matched] == p, axis=(1, 2))) for p in
            straight(t_est)]
    assert all(len(u) == 1 for u in used)


def test_a_non_finite_offset_gets_a_message_not_a_valueerror():
    """loaders.gt.offset_hint rounded a NaN clock difference (a ValueError traceback); the
    ground truth's association with a NaN offset is one DataError too."""
    from loaders.gt import associate, offset_hint

    assert "not finite" in offset_hint(np.array([np.nan]), SCANS)
    assert "not finite" in offset_hint(SCANS + np.inf, SCANS)
    with pytest.raises(DataError, match="a stamp or the time offset is not finite"):
        associate(Trajectory(SCANS, straight(SCANS)), SCANS, offset_s=float("nan"))


def test_a_scan_keeps_the_index_of_the_pose_it_took():
    """Scan 0's nearest pose (0.06 s) goes to scan 1 (0.04 s from it); scan 0 takes the pose at
    -0.2 s (within 0.3 s): the pose index says which (the reported time follows it)."""
    scans = np.array([0.0, 0.1])
    t_est = np.array([-0.2, 0.06])
    m = match_to_scans(Trajectory(t_est, straight(t_est)), scans, tolerance_s=0.3)
    np.testing.assert_array_equal(m.pose_index, [0, 1])
    np.testing.assert_array_equal(m.poses, straight(t_est))


# --- the report, the ends of an interpolation, and what a refusal says ------------------------

def test_the_report_counts_what_took_a_pose_and_how():
    """Poses at 0, 0.25, 0.5, 1.25, 1.5 s (written 10 s early) on the 4 Hz grid: five scans
    matched, the two in the 0.75 s gap interpolated (--max-gap 0.8), the rest none."""
    e = np.array([0.0, 0.25, 0.5, 1.25, 1.5]) - 10.0
    m = match_to_scans(Trajectory(e, straight(e + 10.0)), GRID, time_offset_s=10.0,
                       tolerance_s=0.01, max_gap_s=0.8)
    assert m.report == {"time_offset_s": 10.0, "tolerance_s": 0.01, "max_gap_s": 0.8,
                        "scans": 16, "poses": 5, "matched": 5, "interpolated": 2, "covered": 7,
                        "widest_bridged_s": 0.75}
    np.testing.assert_array_equal(m.pose_index, [0, 1, 2, -1, -1, 3, 4] + [-1] * 9)
    np.testing.assert_allclose(m.poses[:7], straight(GRID[:7]), atol=1e-12)


def test_two_poses_are_enough_to_interpolate_between():
    t = np.array([0.0, 1.0])
    m = match_to_scans(Trajectory(t, straight(t)), GRID, tolerance_s=0.0, max_gap_s=1.0)
    np.testing.assert_array_equal(m.covered, GRID <= 1.0)
    assert m.report["interpolated"] == 3 and m.report["widest_bridged_s"] == 1.0
    np.testing.assert_allclose(m.poses[GRID <= 1.0], straight(GRID[GRID <= 1.0]), atol=1e-12)


@pytest.mark.parametrize("shift", [5e-10, -5e-10])
def test_a_scan_a_hair_outside_the_estimates_span_takes_the_end_pose(shift):
    """Stamps 0.5 ns after (before) the scans: the first (last) scan lies just outside the
    estimate's span but within the coverage's 1 ns; it is interpolated at the span's end, so it
    takes the end pose (not its neighbour's, 0.5 m away)."""
    est = Trajectory(GRID + shift, straight(GRID))
    m = match_to_scans(est, GRID, tolerance_s=0.0, max_gap_s=0.3)
    assert m.covered.all() and not m.matched.any()
    np.testing.assert_allclose(m.poses, straight(GRID), atol=1e-6)
    assert m.report["widest_bridged_s"] == pytest.approx(0.25, abs=1e-12)


def test_widest_bridged_is_the_gap_around_the_interpolated_scans():
    from bench.runs.external.match import widest_bridged

    s = np.array([0.0, 1.0, 3.0, 3.5])
    q = np.array([0.5, 2.0, 3.25])
    for interpolated, widest in (([True, False, False], 1.0), ([False, True, False], 2.0),
                                 ([False, False, True], 0.5), ([True, True, True], 2.0),
                                 ([False, False, False], 0.0)):
        assert widest_bridged(s, q, np.array(interpolated)) == widest, interpolated
    assert widest_bridged(np.array([0.0, 2.0]), np.array([1.0]), np.array([True])) == 2.0
    # a scan a hair before the first pose or after the last (inside the coverage's 1 ns):
    # the end gap
    assert widest_bridged(s, np.array([-5e-10]), np.array([True])) == 1.0
    assert widest_bridged(s, np.array([3.5 + 5e-10]), np.array([True])) == 0.5
    assert widest_bridged(np.array([0.0]), np.array([0.0]), np.array([True])) == 0.0


OFF = 2.0 ** -11  # 0.000488 s: within a millisecond of a scan, exact in binary


def test_stamps_written_with_few_digits_name_the_tolerance_that_takes_them():
    from bench.runs.external.match import rounding_hint

    hint = rounding_hint(GRID + OFF, GRID, 0.0)
    assert hint.startswith("16 of its stamps lie within 0.000488 s of a scan's")
    assert "16 of them beyond --tolerance 0: " in hint
    assert hint.endswith("--tolerance 0.00049 takes them")  # 1 % above the widest
    assert rounding_hint(GRID + OFF, GRID, OFF) is None  # the tolerance takes them already
    assert rounding_hint(GRID + OFF, GRID, np.nextafter(OFF, 0)) is not None
    half = GRID + np.where(np.arange(16) % 2, OFF, OFF / 4)  # half of them beyond OFF / 2
    assert "8 of them beyond --tolerance 0.000244141: " in rounding_hint(half, GRID, OFF / 2)
    # a stamp exactly at the tolerance is within it (as matching's |d| <= tolerance)
    assert "8 of them beyond --tolerance 0.00012207: " in rounding_hint(half, GRID, OFF / 4)
    # stamps beyond the scans' span are not counted (20 stamps, the 16 inside all rounded)
    longer = np.r_[GRID + OFF, 10.0, 11.0, 12.0, 13.0]
    assert rounding_hint(longer, GRID, 0.0).startswith("16 of its stamps lie within 0.000488 s")
    assert "16 of them beyond" in rounding_hint(longer, GRID, 0.0)
    tiny = rounding_hint(GRID + 2.0 ** -30, GRID, 0.0)
    assert tiny.endswith("--tolerance 1e-06 takes them")  # never below a microsecond
    assert rounding_hint(GRID + 100.0, GRID, 0.0) is None  # none inside the scans' span


def test_the_rounding_hint_needs_nine_in_ten_stamps_on_the_scans():
    from bench.runs.external.match import rounding_hint

    nine = np.r_[GRID[:9] + OFF, GRID[9] + 0.1]  # 9 of the 10 within 1 ms of a scan
    assert rounding_hint(nine, GRID, 0.0).startswith("9 of its stamps")
    eight = np.r_[GRID[:8] + OFF, GRID[8:10] + 0.1]
    assert rounding_hint(eight, GRID, 0.0) is None


def test_the_rounding_hints_millisecond_is_inclusive():
    from bench.runs.external.match import rounding_hint

    scan = np.array([0.0])
    for stamp in (0.001, -0.001):  # exactly a millisecond off (0 +- 0.001 is exact)
        assert rounding_hint(np.array([stamp]), scan, 0.0).startswith(
            "1 of its stamps lie within 0.001 s")
    assert rounding_hint(np.array([0.0011]), scan, 0.0) is None


def test_a_refusal_says_what_would_have_matched_and_what_to_try():
    far = Trajectory(SCANS + 100.0, straight(SCANS))
    with pytest.raises(DataError) as err:
        match_to_scans(far, SCANS, max_gap_s=0.5, hint="try this")
    msg = str(err.value)
    assert ("no scan has a pose within 0.01 s, or two poses at most 0.5 s apart around it; the "
            "estimate spans [100.000, 103.900] s (offset +0.000 s applied), the 40 scans span "
            "[0.000, 3.900] s; different clocks? try this") in msg
    with pytest.raises(DataError) as err:
        match_to_scans(far, SCANS)
    msg = str(err.value)
    assert "no scan has a pose within 0.01 s; the estimate spans" in msg
    assert "different clocks? set the time offset: try --time-offset -100 " in msg
    # stamps rounded off the scans' (a tolerance of 0): the tolerance that takes them first
    with pytest.raises(DataError) as err:
        match_to_scans(Trajectory(GRID + OFF, straight(GRID)), GRID, tolerance_s=0.0)
    msg = str(err.value)
    assert "different clocks? 16 of its stamps lie within 0.000488 s" in msg
    assert "--tolerance 0.00049 takes them; set the time offset: try --time-offset" in msg


def test_a_scan_without_a_pose_is_minus_one():
    """Poses at 0.1 and 0.9 s, scans each 0.25 s: the poses go to scans 0 and 4, the others
    take none (-1, whatever the distance)."""
    from bench.runs.external.match import one_pose_a_scan

    np.testing.assert_array_equal(one_pose_a_scan(np.array([0.1, 0.9]), GRID[:6]),
                                  [0, -1, -1, -1, 1, -1])


@pytest.mark.parametrize("option, cause", [
    ({"time_offset_s": float("nan")}, "(est_stamp + offset = the scans' clock)"),
    ({"max_gap_s": 0.0}, "(or no --max-gap: no interpolation)"),
])
def test_an_option_error_says_what_the_option_means(option, cause):
    with pytest.raises(DataError) as err:
        match_to_scans(Trajectory(SCANS, straight(SCANS)), SCANS, **option)
    assert str(err.value).endswith(cause)
