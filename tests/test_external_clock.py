"""bench.runs.external.clock on analytic motions: the profiles' values (speed [m/s], turn rate
[rad/s]), the fit's shift and sign, and when a fit is inconclusive."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.runs.external.clock import aligned_offset, fit_clock, motion_profiles
from bench.runs.external.clock_check import _power_of_1000
from loaders.se3 import make_T

T = np.arange(0, 30, 0.1)


def drive(t, speed=lambda t: 2.0 + 0 * t, yaw_rate=0.3):
    """Planar motion along the heading, speed ``speed(t)`` [m/s], constant yaw rate."""
    t = np.asarray(t, dtype=np.float64)
    fine = np.arange(t[0] - 1, t[-1] + 1, 1e-3)
    yaw = yaw_rate * fine
    v = speed(fine)
    xy = np.cumsum(np.column_stack([v * np.cos(yaw), v * np.sin(yaw)]), axis=0) * 1e-3
    x, y = np.interp(t, fine, xy[:, 0]), np.interp(t, fine, xy[:, 1])
    R = Rotation.from_euler("z", yaw_rate * t[:, None]).as_matrix()
    return make_T(R, np.column_stack([x, y, np.zeros_like(t)]))


def test_the_profiles_are_speed_and_turn_rate():
    poses = drive(T, yaw_rate=0.1)
    speed, rate = motion_profiles(T, poses, 0.05, 1.0, 0.3)
    ok = np.isfinite(speed)
    assert ok.sum() > 400 and np.isnan(speed[:10]).all()  # the window leaves the span
    # the chord of a circle of radius 20 m (2 m/s at 0.1 rad/s) over 2 s, per 2 s:
    # 2 * 20 sin(0.1) / 2 = 1.99667 m/s (positions interpolated between the 0.1 s poses)
    np.testing.assert_allclose(speed[ok], 20 * np.sin(0.1), rtol=1e-4)
    np.testing.assert_allclose(rate[ok], 0.1, rtol=1e-9)


def test_the_fit_finds_the_shift_and_its_sign():
    def speed(t):
        return 5 + 3 * np.sin(0.7 * t) + 2 * np.sin(1.9 * t)

    poses = drive(T, speed, yaw_rate=0.05)
    fit = fit_clock(T - 0.37, poses, T, poses, 0.1)  # est_stamp + 0.37 = the scans' clock
    assert fit.offset_s == pytest.approx(0.37, abs=1e-3)
    assert fit.correlation == pytest.approx(1.0, abs=1e-6) and fit.correlation_at_zero < 0.99
    assert fit_clock(T + 2.0, poses, T, poses, 0.1).offset_s == pytest.approx(-2.0, abs=1e-3)


def test_a_constant_speed_straight_drive_is_inconclusive():
    poses = drive(T, yaw_rate=0.0)
    fit = fit_clock(T - 0.37, poses, T, poses, 0.1)
    assert fit.offset_s is None and "speed and turn rate hardly vary" in fit.why


def test_a_power_of_1000_within_10x():
    assert _power_of_1000(1000.0) == 1 and _power_of_1000(3000.0) == 1
    assert _power_of_1000(1e-9) == -3 and _power_of_1000(1e6 * 0.2) == 2
    assert _power_of_1000(30.0) is None and _power_of_1000(1.0) is None
    assert _power_of_1000(1e12) is None and _power_of_1000(0.0) is None


def test_the_bootstrap_interval_holds_the_shift_and_is_reproducible():
    def speed(t):
        return 5 + 3 * np.sin(0.7 * t) + 2 * np.sin(1.9 * t)

    poses = drive(T, speed, yaw_rate=0.05)
    noisy = poses.copy()
    noisy[:, :3, 3] += np.random.default_rng(0).normal(0, 0.05, (len(T), 3))
    fit = fit_clock(T - 0.37, noisy, T, poses, 0.1)
    lo, hi = fit.interval_s
    assert lo <= 0.37 <= hi and hi - lo < 0.2 and fit.decisive
    assert fit_clock(T - 0.37, noisy, T, poses, 0.1) == fit  # seeded: the same verdict


def test_the_aligned_offset_lines_the_stamps_up():
    scans = np.arange(100) * 0.1
    est = scans - 0.37
    assert aligned_offset(est, scans, 0.36, 0.1) == pytest.approx(0.37, abs=1e-12)
    assert aligned_offset(est, scans, 0.30, 0.1) == pytest.approx(0.27, abs=1e-12)


def test_a_part_of_the_drive_at_a_standstill_is_no_unit_problem():
    """The speed is compared with the ground truth's over the estimate's own span: a part
    covering a stop (1 mm/s where the whole drive averages 3.3 m/s) is not a unit; the whole in
    mm or in ms is, each named by the path length."""
    from bench.runs.external.clock_check import unit_misfit
    from loaders.trajectory import Trajectory

    t = np.arange(0, 60, 0.1)
    x = np.where(t < 20, 5 * t, np.where(t < 40, 100 + 0.001 * (t - 20), 100.02 + 5 * (t - 40)))
    poses = make_T(np.repeat(np.eye(3)[None], len(t), 0), np.column_stack([x, 0 * t, 0 * t]))
    gt = Trajectory(t, poses)
    stop = (t > 22) & (t < 38)
    assert unit_misfit(t[stop], poses[stop, :3, 3], gt, "s", "e", "s") is None
    assert "positions in millimetres" in unit_misfit(t, poses[:, :3, 3] * 1e3, gt, "s", "e", "s")
    assert "--stamp-unit ms" in unit_misfit(t * 1e3, poses[:, :3, 3], gt, "s", "e", "s")


def test_stamps_in_picoseconds_are_no_unit_of_stamp_unit():
    """Stamps 1000 times too long read in ns (picoseconds) or 10^6 times read in us: no
    --stamp-unit fits (a picosecond is not within np.isclose's default 1e-8 of a nanosecond
    for the unit advice); 1000 times too long read in us are nanoseconds."""
    from bench.runs.external.clock_check import unit_misfit
    from loaders.trajectory import Trajectory

    t = np.arange(0, 60, 0.1)
    poses = drive(t, lambda t: 3 + np.sin(t), yaw_rate=0.05)
    gt = Trajectory(t, poses)
    for unit, scale in (("ns", 1e3), ("us", 1e6), ("ms", 1e9)):
        text = unit_misfit(t * scale, poses[:, :3, 3], gt, unit, "e", "s")
        assert "stamps in another unit" in text and "--stamp-unit" not in text, unit
        assert f"its seconds look {scale:g} times too long" in text
    assert "--stamp-unit ns" in unit_misfit(t * 1e3, poses[:, :3, 3], gt, "us", "e", "s")


def test_the_aligned_offset_moves_at_most_half_a_period():
    scans = np.arange(100) * 0.125
    est = scans - 0.3125
    # shifted by 0.25 every stamp is exactly half a period (0.0625 s) from two scans: moved
    # to either
    assert aligned_offset(est, scans, 0.25, 0.125) in (0.1875, 0.3125)
    assert aligned_offset(est, scans, 0.25, 0.12) == 0.25  # beyond half a period: kept
    # no scan inside the shifted span, or a single scan: kept
    assert aligned_offset(est + 100, scans, 0.25, 0.125) == 0.25
    assert aligned_offset(est, scans[:1], 0.3, 0.125) == 0.3
    # the median: 10 % of the stamps elsewhere do not move it
    odd = est.copy()
    odd[::10] += 0.05
    assert aligned_offset(odd, scans, 0.3, 0.125) == pytest.approx(0.3125, abs=1e-12)
