"""bench.runs.external.clock_check on known answers: which stamps are the scans' own or frame
indices (at and across the thresholds), which offsets fit alike (one scan period apart within
the interval), what is refused (decisive and beyond half a period or the tolerance) and what is
only said, and what the refusals and warnings name (the file, the store, the offsets, the
cause)."""

import numpy as np
import pytest

import bench.runs.external.clock_check as cc
from bench.runs.external.clock import ClockFit
from bench.runs.external.clock_check import (
    ClockVerdict,
    alike_offsets,
    check_clock,
    clock_misfit,
    fit_hint,
    index_stamps,
    offsets_text,
    refuse_misfit,
    stamps_are_scans,
    unit_misfit,
)
from loaders.errors import DataError
from loaders.se3 import make_T
from loaders.trajectory import Trajectory
from test_external_clock import T, drive

SCANS = T  # 300 scans 0.1 s apart, 0 .. 29.9 s


def varied(t):
    """A speed [m/s] that varies (a profile that can tell shifts apart)."""
    return 5 + 3 * np.sin(0.7 * t) + 2 * np.sin(1.9 * t)


GT = Trajectory(T, drive(T, varied, yaw_rate=0.05))


def fit(offset, interval, gain_low=0.05, at_zero=0.8, grid=0.0125, alike=()):
    return ClockFit(offset, 0.95, at_zero, interval_s=interval, gain_low=gain_low, grid_s=grid,
                    alike_s=alike)


# --- which stamps are the scans' own, which are frame indices -------------------------------

def test_stamps_within_the_tolerance_of_each_scan_are_the_scans_own():
    q = np.array([0.0, 0.5, 1.0, 1.5])
    assert stamps_are_scans(q, q, 0.01)
    assert stamps_are_scans(q + 0.25, q, 0.25)  # exactly the tolerance off: still on its scan
    assert not stamps_are_scans(q + 0.25, q, 0.125)
    assert not stamps_are_scans(q[:3], q, 0.01)  # one scan without its stamp
    assert not stamps_are_scans(np.r_[q, 2.0], q, 0.01)


def test_frame_indices_are_whole_numbers_one_apart_where_scans_are_not_a_second_apart():
    idx = np.arange(20.0)
    assert index_stamps(idx, 0.1) and index_stamps(idx[:3], 0.1)
    assert not index_stamps(idx[:2], 0.1)  # too few to tell
    assert not index_stamps(idx + 0.5, 0.1)  # not whole numbers
    assert not index_stamps(idx * 2, 0.1)  # whole numbers 2 apart
    # a period of about 1 s (within a factor 1.5) makes indices look like seconds
    assert not index_stamps(idx, 1.0) and not index_stamps(idx, 1.5)
    assert not index_stamps(idx, 1 / 1.5 + 1e-9)
    assert index_stamps(idx, 1.51) and index_stamps(idx, 0.66) and index_stamps(idx, 0.0)
    # 9 of 10 steps exactly 1: indices; 8 of 10: not
    nine = np.r_[np.arange(10.0), 12.0]
    eight = np.r_[np.arange(9.0), 11.0, 13.0]
    assert index_stamps(nine, 0.1) and not index_stamps(eight, 0.1)


# --- units --------------------------------------------------------------------------------------

def test_a_unit_is_named_by_what_the_path_length_settles():
    t, xyz = GT.stamps, GT.poses[:, :3, 3]
    um = unit_misfit(t, xyz * 1e6, GT, "s", "est.tum", "store.h5")
    assert "est.tum: read in seconds" in um and "store.h5" in um
    assert "positions in micrometres" in um and "1e+06 times too long" in um
    assert "1e+06 times faster" in um
    nm = unit_misfit(t, xyz * 1e9, GT, "s", "e", "s")
    assert "positions in nanometres" in nm
    # stamps read in ns that are in ps: no unit of --stamp-unit fits
    ps = unit_misfit(t * 1e3, xyz, GT, "ns", "e", "s")
    assert "read in nanoseconds" in ps and "1000 times slower" in ps
    assert "stamps in another unit (the path fits" in ps
    assert "its seconds look 1000 times too long" in ps and "--stamp-unit" not in ps
    assert "--trust-clock" in ps
    us = unit_misfit(t * 1e6, xyz, GT, "s", "e", "s")
    assert "stamps in microseconds" in us and "--stamp-unit us" in us
    # both scaled, the speed off 1000 times: the path length cannot settle which
    both = unit_misfit(t * 1e3, xyz * 1e6, GT, "s", "e", "s")
    assert "cannot settle which" in both and "--trust-clock" in both
    assert unit_misfit(t, xyz, GT, "s", "e", "s") is None  # the speed fits
    assert unit_misfit(t, xyz * 30, GT, "s", "e", "s") is None  # not a power of 1000


def test_no_unit_is_named_for_a_standing_ground_truth_or_estimate():
    t = GT.stamps
    still = Trajectory(t, make_T(np.repeat(np.eye(3)[None], len(t), 0), np.zeros((len(t), 3))))
    slow = Trajectory(t, make_T(np.repeat(np.eye(3)[None], len(t), 0),
                                np.column_stack([0.099 * t, 0 * t, 0 * t])))
    fast = Trajectory(t, make_T(np.repeat(np.eye(3)[None], len(t), 0),
                                np.column_stack([0.101 * t, 0 * t, 0 * t])))
    xyz = GT.poses[:, :3, 3]
    assert unit_misfit(t, xyz * 1e3, still, "s", "e", "s") is None
    # the ground truth's speed must be at least 0.1 m/s
    assert unit_misfit(t, slow.poses[:, :3, 3] * 1e3, slow, "s", "e", "s") is None
    assert "millimetres" in unit_misfit(t, fast.poses[:, :3, 3] * 1e3, fast, "s", "e", "s")
    assert unit_misfit(t, np.zeros((len(t), 3)), GT, "s", "e", "s") is None


# --- offsets that fit alike -------------------------------------------------------------------

def test_an_estimate_stamped_at_the_scans_fits_alike_one_period_apart_within_the_interval():
    est = SCANS - 0.3  # every stamp on a scan once shifted by 0.3 s
    # interval [0.12, 0.47] widened by a grid step 0.0125: 0.2, 0.3, 0.4 (0.1 and 0.5 outside)
    got = alike_offsets(est, SCANS, fit(0.31, (0.12, 0.47)), 0.1, 0.01)
    assert got[0] == pytest.approx(0.3, abs=1e-9)
    assert sorted(got) == pytest.approx([0.2, 0.3, 0.4], abs=1e-9)
    assert got[1] == pytest.approx(0.4, abs=1e-9)  # the most likely first: 0.4 is nearer 0.31
    # the widening by the grid step: 0.5 is 0.02 beyond 0.48, inside with a grid of 0.025
    wide = alike_offsets(est, SCANS, fit(0.31, (0.12, 0.48), grid=0.025), 0.1, 0.01)
    assert sorted(wide) == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5], abs=1e-9)
    # no interval: the aligned offset alone
    assert alike_offsets(est, SCANS, fit(0.31, None), 0.1, 0.01) == pytest.approx((0.3,))
    # an interval that leaves out the aligned offset: still that one
    assert alike_offsets(est, SCANS, fit(0.31, (0.33, 0.37)), 0.1, 0.01) == pytest.approx((0.3,))
    # at most 50 periods either way
    assert len(alike_offsets(est, SCANS, fit(0.31, (-20.0, 20.0)), 0.1, 0.01)) == 101


def test_an_estimate_off_the_scans_fits_only_its_own_shift():
    est = np.arange(0, 29, 0.13)  # 0.13 s apart: most stamps off the scans however shifted
    assert alike_offsets(est, SCANS, fit(0.26, (0.1, 0.5)), 0.1, 0.01) == (0.26,)
    # within a tolerance of half a period every stamp is on a scan
    assert len(alike_offsets(est, SCANS, fit(0.26, (0.1, 0.5)), 0.1, 0.05)) > 1
    # no scan period, or no stamp inside the scans' span once shifted: the fit's own shift
    assert alike_offsets(est, SCANS, fit(0.26, (0.1, 0.5)), 0.0, 0.01) == (0.26,)
    assert alike_offsets(est + 100, SCANS, fit(0.26, (0.1, 0.5)), 0.1, 0.01) == (0.26,)


def test_ninety_percent_of_the_stamps_on_the_scans_make_an_estimate_stamped_at_them():
    q = np.arange(11) * 0.1
    on = q[:10].copy()
    nine = on.copy()
    nine[4] += 0.04  # 9 of 10 on their scans
    eight = nine.copy()
    eight[6] += 0.04  # 8 of 10
    f = fit(0.0, (-0.25, 0.25), grid=0.0)
    assert len(alike_offsets(nine, q, f, 0.1, 0.01)) == 5  # -0.2 .. 0.2
    assert alike_offsets(eight, q, f, 0.1, 0.01) == (0.0,)
    # a tolerance of 0 still counts stamps on their scans up to 1 ns
    assert len(alike_offsets(on + 5e-10 * (-1.0) ** np.arange(10), q, f, 0.1, 0.0)) == 5


# --- what is decisive and what is refused -------------------------------------------------------

def test_a_misfit_is_decisive_and_beyond_half_a_period_and_the_tolerance():
    assert clock_misfit(fit(0.0501, (0.03, 0.07)), 0.01, 0.1)
    assert not clock_misfit(fit(0.05, (0.03, 0.07)), 0.01, 0.1)  # half a period: no misfit
    assert clock_misfit(fit(-0.3, (-0.4, -0.2)), 0.01, 0.1)  # either way
    assert not clock_misfit(fit(0.15, (0.1, 0.2)), 0.2, 0.1)  # within the tolerance
    assert clock_misfit(fit(0.25, (0.2, 0.3)), 0.2, 0.1)
    assert clock_misfit(fit(0.03, (0.02, 0.04)), 0.01)  # no period given: the tolerance alone
    assert not clock_misfit(fit(0.3, (-0.1, 0.5)), 0.01, 0.1)  # not decisive
    assert not clock_misfit(None, 0.01, 0.1) and not clock_misfit(ClockFit(None), 0.01, 0.1)


def test_the_refusal_names_the_file_the_store_and_every_offset_that_fits_alike():
    f = fit(0.31, (0.12, 0.47), at_zero=0.8, alike=(1.3, 1.4, 1.2))
    verdict = ClockVerdict(f, "found", period_s=0.1)
    with pytest.raises(DataError) as e:
        refuse_misfit(verdict, 1.0, 0.01, "est.tum", "store.h5")
    text = str(e.value)
    assert text.startswith("est.tum: its clock does not fit the scans of store.h5")
    assert "shifted by +0.3100 s" in text and "[+0.1200, +0.4700]" in text
    assert "against 0.800 as it is, with --time-offset 1)" in text
    assert ("--time-offset 1.3000 (the profile cannot tell it from --time-offset 1.4000, "
            "--time-offset 1.2000: they fit alike") in text
    assert "--trust-clock" in text
    # profiles that do not overlap unshifted: said so
    f = fit(5.0, (4.9, 5.1), at_zero=float("nan"), alike=(5.0,))
    with pytest.raises(DataError, match=r"against no overlap as it is.*--time-offset 5\.0000 "):
        refuse_misfit(ClockVerdict(f, "", period_s=0.1), 0.0, 0.01, "e", "s")


def test_no_refusal_on_the_scans_or_without_a_misfit():
    f = fit(0.31, (0.12, 0.47), alike=(0.3,))
    assert refuse_misfit(ClockVerdict(f, "", on_scans=True, period_s=0.1), 0, 0.01, "e",
                         "s") is None
    assert refuse_misfit(ClockVerdict(f, "", period_s=1.0), 0, 0.01, "e", "s") is None
    # the verdict's period defaults to none: the tolerance alone decides
    with pytest.raises(DataError):
        refuse_misfit(ClockVerdict(f, ""), 0, 0.01, "e", "s")
    assert refuse_misfit(ClockVerdict(None, ""), 0, 0.01, "e", "s") is None


def test_the_hint_and_the_offsets_text():
    assert offsets_text(fit(0.3, (0.2, 0.4), alike=(0.3,))) == "--time-offset 0.3000"
    hint = fit_hint(fit(0.3, (0.2, 0.4), alike=(0.3, 0.2)))
    assert "--time-offset 0.3000 (the profile cannot tell it from --time-offset 0.2000" in hint
    assert "correlation 0.950" in hint and "est_stamp + offset = sensor clock" in hint
    assert fit_hint(None) is None and fit_hint(ClockFit(None)) is None
    assert fit_hint(fit(0.3, (0.2, 0.4))) is None  # no offsets worked out


def test_a_negative_zero_is_printed_as_zero():
    text = cc._fit_text(fit(-0.0, (-0.0, 0.1)))
    assert "-0.0000" not in text and "shifted by +0.0000 s" in text
    assert "[+0.0000, +0.1000]" in text


# --- check_clock: the motion profile on a known drive ------------------------------------------

def test_a_shifted_estimate_is_found_and_refused_with_its_offset():
    """The ground truth's poses stamped 0.37 s early (0.03 s off every scan): the fit finds
    +0.37 s, decisively; beyond half a period (0.05 s), so refused, naming it."""
    est = Trajectory(T - 0.37 - 1.0, GT.poses)  # and read with --time-offset 1
    v = check_clock(est, np.eye(4), GT, SCANS, 1.0, False, "est.tum", "store.h5")
    assert not v.on_scans and not v.warnings and v.period_s == pytest.approx(0.1)
    assert v.fit.offset_s == pytest.approx(0.37, abs=2e-3) and v.fit.decisive
    assert v.fit.suggested_s == pytest.approx(1.37, abs=2e-3)
    assert v.fit.alike_s == pytest.approx((1.37,), abs=2e-3)
    assert v.line.startswith("the speed and turn-rate profile fits best shifted by +0.37")
    with pytest.raises(DataError, match=r"est.tum: its clock does not fit the scans of store.h5"
                                        r".*with --time-offset 1\).*--time-offset 1\.37"):
        refuse_misfit(v, 1.0, 0.01, "est.tum", "store.h5")
    # with the offset it fits: the shift found is within a grid step of none, not refused
    fixed = check_clock(est, np.eye(4), GT, SCANS, 1.37, False, "est.tum", "store.h5")
    assert abs(fixed.fit.offset_s) < 0.0125
    refuse_misfit(fixed, 1.37, 0.01, "est.tum", "store.h5")


def test_the_sensor_frame_is_applied_before_the_fit():
    """An estimate of a frame 3 m ahead of the sensor, turning: its speed is not the sensor's;
    with the extrinsic it is (the fit's correlation is 1 at the shift)."""
    T_frame_sensor = make_T(np.eye(3), np.array([3.0, 0.0, 0.0]))
    T_sensor_frame = np.linalg.inv(T_frame_sensor)
    turning = Trajectory(T, drive(T, varied, yaw_rate=0.4))
    est = Trajectory(T - 0.37, turning.poses @ T_sensor_frame)
    v = check_clock(est, T_frame_sensor, turning, SCANS, 0.0, False, "e", "s")
    assert v.fit.correlation == pytest.approx(1.0, abs=1e-6)
    assert v.fit.offset_s == pytest.approx(0.37, abs=2e-3)


def test_stamps_on_the_scans_with_a_profile_fitting_elsewhere_are_warned_not_refused():
    est = Trajectory(SCANS, drive(T + 0.5, varied, yaw_rate=0.05))  # poses 0.5 s late
    v = check_clock(est, np.eye(4), GT, SCANS, 0.0, False, "est.tum", "store.h5")
    assert v.on_scans and v.fit.offset_s == pytest.approx(0.5, abs=2e-3)
    # the fit's shift (microseconds off 0.5 s) is suggested lined up with the scans
    assert v.fit.suggested_s == pytest.approx(0.5, abs=1e-9)
    assert v.line.startswith("on the store's clock (one stamp per scan, each its scan's); the "
                             "speed and turn-rate profile fits best shifted by +0.50")
    assert len(v.warnings) == 1
    assert v.warnings[0].startswith("est.tum: its stamps are the scans' own, yet")
    assert "poses written against the wrong scans' stamps" in v.warnings[0]
    refuse_misfit(v, 0.0, 0.01, "est.tum", "store.h5")  # on the scans: never refused
    # the same estimate on its right poses: no warning
    right = check_clock(Trajectory(SCANS, GT.poses), np.eye(4), GT, SCANS, 0.0, False, "e", "s")
    assert right.on_scans and not right.warnings


def test_a_flat_drive_could_not_be_checked_and_poses_beyond_the_scans_are_warned():
    flat = Trajectory(T, drive(T, yaw_rate=0.0))  # 2 m/s straight on
    v = check_clock(Trajectory(SCANS, flat.poses), np.eye(4), flat, SCANS, 0.0, False, "e", "s")
    assert v.on_scans and v.fit.offset_s is None and not v.warnings
    assert v.line.startswith("on the store's clock (one stamp per scan, each its scan's); the "
                             "clock could not be checked: the ground truth's speed and turn "
                             "rate hardly vary")
    assert v.line.endswith("; scored as given")
    late = Trajectory(T + 2.05, flat.poses)
    v = check_clock(late, np.eye(4), flat, SCANS, 0.0, False, "est.tum", "s")
    assert not v.on_scans and v.line.startswith("the clock could not be checked")
    # stamps 2.05 .. 31.95 s, the last scan at 29.9 s: 20 poses beyond it by more than 0.1 s
    # (30.05 .. 31.95 s)
    assert len(v.warnings) == 1 and v.warnings[0].startswith(
        "est.tum: 20 of its poses lie beyond the scans' span (up to 2.05 s after the last scan)")
    assert "try --time-offset" in v.warnings[0]


def test_poses_beyond_the_scans_span_by_more_than_a_period_and_the_tolerance():
    q = np.arange(0, 10, 0.1)
    w = cc._outside(q - 2.05, q, 0.01, 0.1, "e")
    assert w[0].startswith("e: 20 of its poses lie beyond the scans' span (up to 2.05 s before "
                           "the first scan)")
    assert cc._outside(q - 0.1, q, 0.01, 0.1, "e") == []  # within a period
    assert cc._outside(q + 0.25, q, 0.3, 0.1, "e") == []  # within the tolerance
    assert "1 of its poses" in cc._outside(np.r_[q, 10.25], q, 0.3, 0.1, "e")[0]
    assert cc._outside(q - 0.5, q[:0], 0.01, 0.1, "e") == []  # no scans


def test_an_undecided_fit_is_scored_saying_why(monkeypatch):
    """The fit's outcomes, each as check_clock reads it (the fit replaced by a known one)."""
    est = Trajectory(T - 0.03, GT.poses)  # not on the scans
    cases = {"holds": fit(0.3, (-0.01, 0.6)),
             "gain": fit(0.3, (0.2, 0.4), gain_low=-0.01),
             "small": fit(0.03, (0.02, 0.04)),
             "misfit": fit(0.3, (0.2, 0.4))}
    got = {}
    for name, f in cases.items():
        monkeypatch.setattr(cc, "fit_clock", lambda *a, f=f, **k: f)
        got[name] = check_clock(est, np.eye(4), GT, SCANS, 0.0, False, "e", "s")
    assert got["holds"].line.startswith("the clock could not be checked: the speed and ")
    assert got["holds"].line.endswith("the data cannot tell that shift from none (its interval "
                                      "holds no shift); scored as given")
    assert got["gain"].line.endswith("(the correlation's gain over no shift may be 0); scored "
                                     "as given")
    assert got["small"].line.endswith("within half a scan period (0.05 s) of no shift; scored "
                                      "as given")
    for name in ("holds", "gain"):
        assert not got[name].on_scans and got[name].period_s == pytest.approx(0.1)
        assert not clock_misfit(got[name].fit, 0.01, 0.1)
    assert got["small"].period_s == pytest.approx(0.1) and not got["small"].warnings
    assert got["misfit"].period_s == pytest.approx(0.1)
    assert clock_misfit(got["misfit"].fit, 0.01, got["misfit"].period_s)
    # the interval (widened by its grid step) holds no shift: 0 is 0.0125 below 0.0125
    monkeypatch.setattr(cc, "fit_clock", lambda *a, **k: fit(0.3, (0.0125, 0.6)))
    edge = check_clock(est, np.eye(4), GT, SCANS, 0.0, False, "e", "s")
    assert "its interval holds no shift" in edge.line


def test_the_fit_is_given_the_offset_stamps_and_the_scans_period(monkeypatch):
    seen = {}

    def spy(est_stamps, est_poses, gt_stamps, gt_poses, period_s, *a, **k):
        seen.update(est=est_stamps, poses=est_poses, gt=gt_stamps, period=period_s)
        return ClockFit(None, why="spied")

    monkeypatch.setattr(cc, "fit_clock", spy)
    T_fs = make_T(np.eye(3), np.array([0.5, 0.0, 0.0]))
    v = check_clock(Trajectory(T, GT.poses), T_fs, GT, SCANS, 0.25, False, "e", "s")
    np.testing.assert_allclose(seen["est"], T + 0.25)
    np.testing.assert_allclose(seen["poses"], GT.poses @ T_fs)
    np.testing.assert_array_equal(seen["gt"], GT.stamps)
    assert seen["period"] == pytest.approx(0.1)
    assert v.line == "the clock could not be checked: spied; scored as given"
    assert check_clock(Trajectory(T, GT.poses), np.eye(4), GT, SCANS[:1], 0.0, False, "e",
                       "s").fit is not None and seen["period"] == 0.0  # one scan: no period


# --- check_clock: what is refused before the fit -----------------------------------------------

def test_an_offset_too_large_for_the_stamps_precision_is_refused():
    est = Trajectory(1.0 + np.arange(5) * 1e-7, np.repeat(np.eye(4)[None], 5, 0))
    with pytest.raises(DataError, match=r"--time-offset 1e\+10: the stamps of est.tum no longer "
                                        r"increase once offset"):
        check_clock(est, np.eye(4), GT, SCANS, 1e10, False, "est.tum", "s")
    # refused even with --trust-clock (nothing could be scored)
    with pytest.raises(DataError, match="no longer increase"):
        check_clock(est, np.eye(4), GT, SCANS, 1e10, True, "est.tum", "s")


def test_trust_clock_checks_nothing_more():
    est = Trajectory(np.arange(300.0), GT.poses)  # frame indices: refused unless trusted
    v = check_clock(est, np.eye(4), GT, SCANS, 0.0, True, "e", "s")
    assert v.fit is None and v.line == "not checked (--trust-clock)"
    assert not v.on_scans and v.warnings == [] and v.period_s == 0.0


def test_frame_indices_are_refused_naming_them_and_the_scans_period():
    est = Trajectory(np.arange(300.0), GT.poses)
    with pytest.raises(DataError) as e:
        check_clock(est, np.eye(4), GT, SCANS, 0.0, False, "est.tum", "store.h5")
    text = str(e.value)
    assert text.startswith("est.tum: its stamps are frame indices (0, 1, 2, ...")
    assert "the scans of store.h5 are 0.1 s apart" in text and "--trust-clock" in text
    # the raw stamps decide: indices read in ms (0.001 s apart) were indices in the file
    ms = Trajectory(np.arange(300.0) * 1e-3, GT.poses)
    with pytest.raises(DataError, match=r"frame indices \(0, 1, 2,"):
        check_clock(ms, np.eye(4), GT, SCANS, 0.0, False, "e", "s",
                    raw_stamps=np.arange(300.0))
    # whole numbers 1 apart within the tolerance of each scan are the scans' stamps, never
    # indices (scans 0.4 and 1.6 s apart in turn: a median period of 0.4 s)
    scans = np.arange(30.0) + 0.3 * (-1.0) ** np.arange(30)
    v = check_clock(Trajectory(np.arange(30.0), GT.poses[::10]), np.eye(4),
                    GT, scans, 0.0, False, "e", "s", tolerance_s=0.31)
    assert v.on_scans and v.period_s == pytest.approx(0.4)


def test_a_unit_misfit_is_refused_before_the_fit():
    est = Trajectory(T - 0.37, make_T(GT.poses[:, :3, :3], GT.poses[:, :3, 3] * 1e3))
    with pytest.raises(DataError, match="est.tum: read in milliseconds.*positions in millimetres"):
        check_clock(est, np.eye(4), GT, SCANS, 0.0, False, "est.tum", "store.h5", unit="ms")
    # stamps on the scans: still refused (positions in mm keep the scans' stamps)
    with pytest.raises(DataError, match="positions in millimetres"):
        check_clock(Trajectory(SCANS, est.poses), np.eye(4), GT, SCANS, 0.0, False, "e", "s",
                    unit="ms")


# --- survivors of mutation: bounds and what the messages say -----------------------------------

def straight_at(stamps, speed=5.0):
    """Poses moving straight along x at a constant ``speed`` [m/s] (chords are the path)."""
    stamps = np.asarray(stamps, dtype=float)
    return make_T(np.repeat(np.eye(3)[None], len(stamps), 0),
                  np.column_stack([speed * stamps, 0 * stamps, 0 * stamps]))


def test_a_factor_of_exactly_ten_from_a_power_of_1000_is_that_unit():
    assert cc._power_of_1000(100.0) == 1 and cc._power_of_1000(1e4) == 1


def test_the_ground_truth_is_taken_over_the_estimates_span_when_it_covers_half_of_it():
    """Positions in mm (5 m/s straight): the ground truth rows inside the estimate's span
    (10 .. 20 s) are its own when at least 3 of them span at least half of it; the refusal's
    ground-truth span says which were taken."""
    est_t = np.arange(80, 161) * 0.125  # 10 .. 20 s exactly
    est_xyz = straight_at(est_t)[:, :3, 3] * 1e3

    def gt_span(gt_stamps):
        gt = Trajectory(np.asarray(gt_stamps, float), straight_at(gt_stamps))
        text = unit_misfit(est_t, est_xyz, gt, "s", "e", "s")
        assert "positions in millimetres" in text
        return text.split(" m over ")[1].split(" s")[0]

    assert gt_span([0, 10, 15, 20, 40]) == "10"  # 3 rows inside, at both ends
    assert gt_span([0, 10, 12.5, 15, 40]) == "5"  # 3 rows over exactly half the span
    assert gt_span([0, 10, 12.4, 14.9, 40]) == "40"  # less than half: the whole
    assert gt_span([0, 10, 15, 40]) == "40"  # 2 rows inside: the whole
    # 3 rows spanning more than half, the last 1 s before the estimate's end
    est_t = np.arange(80, 169) * 0.125  # 10 .. 21 s
    est_xyz = straight_at(est_t)[:, :3, 3] * 1e3
    assert gt_span([0, 10, 15, 20, 40]) == "10"


def test_the_refusal_states_the_paths_and_spans():
    """Ground truth rows at 50 .. 60 s and 150 .. 180 s (10 rows a second, 5 m/s straight), an
    estimate of 50 .. 80 s in mm: inside its span the ground truth covers a third, so the
    whole is compared: 650 m over 130 s against 1.5e+05 (mm) over 30 (s)."""
    gt_t = np.r_[np.arange(500, 601), np.arange(1500, 1801)] * 0.1
    gt = Trajectory(gt_t, straight_at(gt_t))
    est_t = np.arange(500, 801) * 0.1
    text = unit_misfit(est_t, straight_at(est_t)[:, :3, 3] * 1e3, gt, "s", "e", "store")
    assert "Its path is 1.5e+05 (position units) over 30 (stamp units), the ground truth's 650 " \
           "m over 130 s" in text
    assert "where the ground truth of store moves at 5 m/s" in text
    assert "(a stamp unit would not help)" in text and "write them in metres" in text


def test_a_ground_truth_of_exactly_a_tenth_of_a_metre_a_second_is_compared():
    gt = Trajectory(np.array([0.0, 5.0, 10.0]), straight_at([0.0, 5.0, 10.0], 0.1))
    est_xyz = gt.poses[:, :3, 3] * 1e3
    assert "millimetres" in unit_misfit(gt.stamps, est_xyz, gt, "s", "e", "s")  # 1.0 m / 10 s


def test_a_short_ground_truth_is_compared_by_its_own_length_and_span():
    """Ground truth 0.05 m over 0.05 s: stamps in ms read as seconds (a span 1000 times too
    long), and positions in mm (a path 1000 times too long), each settled."""
    gt = Trajectory(np.array([100.0, 100.05]), straight_at([0.0, 0.05], 1.0))
    ms = unit_misfit(np.array([1e5, 1e5 + 50]), gt.poses[:, :3, 3], gt, "s", "e", "s")
    assert "stamps in milliseconds (the path fits, the span is 1000 times too long); score it " \
           "with --stamp-unit ms (or --trust-clock to score it as it is)" in ms
    mm = unit_misfit(gt.stamps, gt.poses[:, :3, 3] * 1e3, gt, "s", "e", "s")
    assert "positions in millimetres" in mm
    gt3 = Trajectory(np.array([0.0, 0.25, 0.5]), straight_at([0.0, 0.25, 0.5], 0.1))
    assert "positions in millimetres" in unit_misfit(gt3.stamps, gt3.poses[:, :3, 3] * 1e3,
                                                     gt3, "s", "e", "s")


def test_positions_in_kilometres_are_another_unit_and_a_speed_split_between_both_is_unsettled():
    t, xyz = GT.stamps, GT.poses[:, :3, 3]
    km = unit_misfit(t, xyz * 1e-3, GT, "s", "e", "s")
    assert "positions in another unit (the span fits, the path is 0.001 times too long)" in km
    # path sqrt(1000) times too short over a span sqrt(1000) times too long: the speed is 1000
    # times off, yet neither settles it
    r = np.sqrt(1000.0)
    split = unit_misfit(t * r, xyz / r, GT, "s", "e", "s")
    assert "(position units) over" in split
    assert "the path length cannot settle which" in split
    assert "check the units the file was written in (or --trust-clock to score it as it is)" \
        in split
    us = unit_misfit(t * 1e6, xyz, GT, "s", "e", "s")
    assert "the span is 1e+06 times too long" in us


def test_offsets_alike_at_the_bounds():
    q = np.arange(0, 30, 0.125)
    # the interval's ends are in: 0.125 .. 0.375 around 0.25
    assert sorted(alike_offsets(q - 0.25, q, fit(0.25, (0.125, 0.375), grid=0.0), 0.125,
                                0.01)) == [0.125, 0.25, 0.375]
    # a stamp exactly at the last scan is inside the scans' span
    est = np.array([2.875, 3.0, 3.125, 3.25]) - 0.25
    assert len(alike_offsets(est, q[:24], fit(0.25, (0.0, 0.5), grid=0.0), 0.125, 0.01)) == 5
    # 2 of 10 stamps exactly the tolerance off their scans: on the scans
    near = np.arange(10) * 0.125
    near[[3, 7]] += 0.0625
    f = fit(0.0, (-0.3, 0.3), grid=0.0)
    assert len(alike_offsets(near, q, f, 0.125, 0.0625)) == 5
    # no period: the fit's own offset
    assert alike_offsets(SCANS - 0.3, SCANS, fit(0.3, (0.12, 0.47)), 0.0, 0.01) == (0.3,)
    # on the scans once shifted by 0.03 s (not by -0.03 s)
    got = alike_offsets(SCANS - 0.03, SCANS, fit(0.03, (-0.2, 0.25)), 0.1, 0.01)
    assert sorted(got) == pytest.approx([-0.17, -0.07, 0.03, 0.13, 0.23], abs=1e-9)
    # stamps beyond the scans' span do not count against those inside
    wide = np.arange(-150, 300) * 0.1 - 0.3
    assert len(alike_offsets(wide, SCANS, fit(0.31, (0.12, 0.47)), 0.1, 0.01)) == 3


def test_negative_zero_interval_ends_print_as_zero():
    text = cc._fit_text(fit(-0.0, (-0.1, -0.0)))
    assert "[-0.1000, +0.0000]" in text


def test_poses_beyond_the_span_are_counted_beyond_a_period():
    q = np.arange(0, 10, 0.125)
    # stamps at -0.5 .. : those before -0.125 (a period before the first scan): 3
    assert "3 of its poses" in cc._outside(q - 0.5, q, 0.01, 0.125, "e")[0]
    assert "3 of its poses" in cc._outside(q + 0.5, q, 0.01, 0.125, "e")[0]


def test_misfits_and_small_shifts_as_check_clock_reads_them(monkeypatch):
    """On the scans: a shift of 0.07 s (beyond half of the 0.1 s period) is warned, one of
    0.03 s (beyond the 0.01 s tolerance only) is not; off the scans the same 0.07 s is a
    misfit (refused), 0.03 s is within half a period."""
    on = Trajectory(SCANS, GT.poses)
    off = Trajectory(SCANS - 0.03, GT.poses)
    got = {}
    for name, est in (("on", on), ("off", off)):
        for size in (0.07, 0.03):
            f = fit(size, (size - 0.01, size + 0.01))
            monkeypatch.setattr(cc, "fit_clock", lambda *a, f=f, **k: f)
            got[name, size] = check_clock(est, np.eye(4), GT, SCANS, 0.0, False, "e", "s")
    assert len(got["on", 0.07].warnings) == 1 and got["on", 0.03].warnings == []
    assert "within half a scan period" not in got["off", 0.07].line
    with pytest.raises(DataError, match=r"or --trust-clock to score it as it is$"):
        refuse_misfit(got["off", 0.07], 0.0, 0.01, "e", "s")
    small = got["off", 0.03]
    assert "within half a scan period" in small.line and small.fit is not None
    refuse_misfit(small, 0.0, 0.01, "e", "s")
    # an interval whose upper end, widened, is exactly 0: it holds no shift
    monkeypatch.setattr(cc, "fit_clock", lambda *a, **k: fit(-0.3, (-0.6, -0.0125)))
    edge = check_clock(off, np.eye(4), GT, SCANS, 0.0, False, "e", "s")
    assert "its interval holds no shift" in edge.line
    assert edge.fit is not None and edge.on_scans is False and edge.warnings == []
    # an undecided fit of poses beyond the scans' span: warned, naming the estimate
    late = Trajectory(T + 2.05, GT.poses)
    v = check_clock(late, np.eye(4), GT, SCANS, 0.0, False, "est.tum", "s")
    assert v.warnings[0].startswith("est.tum: 20 of its poses")


def test_two_scans_have_a_period(monkeypatch):
    seen = {}

    def spy(est_stamps, est_poses, gt_stamps, gt_poses, period_s, *a, **k):
        seen["period"] = period_s
        return ClockFit(None, why="spied")

    monkeypatch.setattr(cc, "fit_clock", spy)
    check_clock(Trajectory(T, GT.poses), np.eye(4), GT, SCANS[:2], 0.0, False, "e", "s")
    assert seen["period"] == pytest.approx(0.1)


def test_the_messages_name_the_cause_and_what_to_do():
    est = Trajectory(1.0 + np.arange(5) * 1e-7, np.repeat(np.eye(4)[None], 5, 0))
    with pytest.raises(DataError, match="expected an offset of the size of the clocks' "
                                        "difference$"):
        check_clock(est, np.eye(4), GT, SCANS, 1e10, False, "e", "s")
    with pytest.raises(DataError) as e:
        check_clock(Trajectory(np.arange(300.0), GT.poses), np.eye(4), GT, SCANS, 0.0, False,
                    "e", "s")
    assert "expected stamps in seconds on the sensor's clock; write each pose's scan stamp " \
           "(the scans' stamps are those of the bag `bench export` writes), or --trust-clock " \
           "to score it as it is" in str(e.value)
    # the unit refusal: read in seconds unless told, naming the store
    mm = Trajectory(T - 0.37, make_T(GT.poses[:, :3, :3], GT.poses[:, :3, 3] * 1e3))
    with pytest.raises(DataError, match=r"^e: read in seconds, .* where the ground truth of "
                                        r"store.h5 moves at"):
        check_clock(mm, np.eye(4), GT, SCANS, 0.0, False, "e", "store.h5")
