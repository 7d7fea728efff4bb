"""bench.runs.external.clock on analytic motions: the profiles' values (speed [m/s], turn rate
[rad/s]), the fit's shift and sign, and when a fit is inconclusive."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.runs.external.clock import aligned_offset, fit_clock, motion_profiles, path_speed
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
    assert fit.why.endswith("a constant motion shows no clock")


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


# --- the pieces of the fit, each against its definition -----------------------------------------

def straight(t, speed):
    """Straight motion along x at ``speed(t)`` [m/s] (no turn: the speed channel alone)."""
    t = np.asarray(t, dtype=np.float64)
    fine = np.arange(t[0] - 1, t[-1] + 1, 1e-4)
    x = np.interp(t, fine, np.cumsum(speed(fine)) * 1e-4)
    return make_T(np.repeat(np.eye(3)[None], len(t), 0),
                  np.column_stack([x, np.zeros_like(t), np.zeros_like(t)]))


def curve(t, yaw):
    """2 m/s along a heading ``yaw(t)`` [rad] (a turn rate that varies, a speed that hardly
    does: the turn channel alone)."""
    t = np.asarray(t, dtype=np.float64)
    fine = np.arange(t[0] - 1, t[-1] + 1, 1e-4)
    xy = np.cumsum(2.0 * np.column_stack([np.cos(yaw(fine)), np.sin(yaw(fine))]), axis=0) * 1e-4
    x, y = np.interp(t, fine, xy[:, 0]), np.interp(t, fine, xy[:, 1])
    R = Rotation.from_euler("z", yaw(t)[:, None]).as_matrix()
    return make_T(R, np.column_stack([x, y, np.zeros_like(t)]))


def test_the_path_speed_is_the_path_length_over_the_time_span():
    xyz = np.array([[0.0, 0, 0], [3, 4, 0], [3, 4, 2]])
    assert path_speed(np.array([0.0, 1.0, 3.0]), xyz) == pytest.approx(7 / 3)
    assert path_speed(np.array([1.0, 1.0, 1.0]), xyz) == 0.0  # no span


def test_the_profiles_window_stays_inside_the_span_and_off_gaps():
    """Exact binary stamps 0.125 s apart, a grid of 0.0625 s, windows of +/- 1 s: defined from
    1 s after the first pose to 1 s before the last, and not where a 2 s gap (10 .. 12 s) lies
    under the window (t in (9, 13)); a gap of exactly the largest allowed is no gap."""
    t = np.arange(0, 30, 0.125)
    poses = straight(t, lambda s: 2.0 + 0 * s)
    speed, _ = motion_profiles(t, poses, 0.0625, 1.0, 0.3)
    assert len(speed) == 479
    np.testing.assert_array_equal(np.flatnonzero(np.isfinite(speed)), np.arange(16, 463))
    holed = (t <= 10) | (t >= 12)
    grid = 0.0625 * np.arange(479)
    speed, rate = motion_profiles(t[holed], poses[holed], 0.0625, 1.0, 0.3)
    nan = ~np.isfinite(speed)
    np.testing.assert_array_equal(nan, (grid < 1) | (grid > 28.875) | ((grid > 9) & (grid < 13)))
    np.testing.assert_array_equal(nan, ~np.isfinite(rate))
    np.testing.assert_allclose(speed[~nan], 2.0, rtol=1e-3)
    speed, _ = motion_profiles(t[holed], poses[holed], 0.0625, 1.0, 2.0)  # the gap: 2 s
    np.testing.assert_array_equal(np.flatnonzero(np.isfinite(speed)), np.arange(16, 463))
    speed, _ = motion_profiles(t[holed], poses[holed], 0.0625, 1.0, 1.99)
    assert np.isnan(speed[grid == 11]).all()


def test_the_range_maximum_is_the_maximum_of_each_range():
    from bench.runs.external.clock import _range_max

    rng = np.random.default_rng(3)
    values = rng.normal(size=37)
    lo = rng.integers(0, 38, 500)
    hi = np.minimum(lo + rng.integers(0, 40, 500), 37)
    want = [values[a:b].max() if b > a else 0.0 for a, b in zip(lo, hi, strict=True)]
    np.testing.assert_array_equal(_range_max(values, lo, hi), want)
    np.testing.assert_array_equal(_range_max(values[:1], np.array([0, 0, 1]),
                                             np.array([1, 0, 1])), [values[0], 0.0, 0.0])
    np.testing.assert_array_equal(_range_max(np.array([]), np.array([0]), np.array([0])), [0.0])


def test_the_lags_run_from_minus_half_the_size():
    from bench.runs.external.clock import _lags

    k, order = _lags(8)
    np.testing.assert_array_equal(k, [-4, -3, -2, -1, 0, 1, 2, 3])
    np.testing.assert_array_equal(order, [4, 5, 6, 7, 0, 1, 2, 3])


def pearson(x, y, k, w=None):
    """Pearson's r of x[i] with y[i - k] over the i both have, weighted by w[i]; (r, n)."""
    i = np.arange(len(x))
    j = i - k
    ok = (j >= 0) & (j < len(y))
    i, j = i[ok], j[ok]
    both = np.isfinite(x[i]) & np.isfinite(y[j])
    a, b = x[i][both], y[j][both]
    wt = np.ones(len(a)) if w is None else w[i][both]
    if len(a) == 0 or wt.sum() == 0:
        return float("nan"), 0
    ma, mb = np.average(a, weights=wt), np.average(b, weights=wt)
    cov = np.sum(wt * (a - ma) * (b - mb))
    var = np.sum(wt * (a - ma) ** 2) * np.sum(wt * (b - mb) ** 2)
    return (cov / np.sqrt(var) if var > 0 else float("nan")), len(a)


def test_the_correlation_per_lag_is_pearsons_over_the_overlap():
    """x: 40 samples (36 finite), y: 30 (26 finite): r at every lag where they overlap over at
    least half the shorter (13 samples), -inf elsewhere; with weights, a weighted Pearson."""
    from bench.runs.external.clock import _Channel, _ncc

    rng = np.random.default_rng(4)
    x, y = rng.normal(size=40), rng.normal(size=30)
    x[[3, 10, 11, 30]] = np.nan
    y[[0, 5, 6, 29]] = np.nan
    k, r = _ncc(x, y)
    assert len(k) == 128  # the FFT size: the next power of 2 above 70 samples
    for lag, got in zip(k, r, strict=True):
        want, n = pearson(x, y, lag)
        if n >= 13:
            assert got == pytest.approx(want, abs=1e-9), lag
        else:
            assert got == -np.inf, lag
    w = np.zeros(40)
    w[:12] = [2, 1, 2, 1, 2, 1, 1, 2, 1, 2, 1, 1]  # 6 of them finite on both sides at lag 0:
    # below half the overlap, yet weighed (the overlap rule is the unweighted profiles')
    c = _Channel(x, y)
    rw = c.correlation(w)
    zero = int(np.flatnonzero(c.k == 0)[0])
    assert rw[zero] == pytest.approx(pearson(x, y, 0, w)[0], abs=1e-9)
    # a constant side has no correlation at any lag
    assert np.all(_Channel(np.full(40, 2.0), y).correlation() == -np.inf)


def test_at_least_eight_samples_overlap():
    from bench.runs.external.clock import _ncc

    rng = np.random.default_rng(5)
    x, y = rng.normal(size=10), rng.normal(size=10)
    k, r = _ncc(x, y)
    # equal lengths: 10 - |k| overlap; at least 8 (half of 10 is less)
    np.testing.assert_array_equal(np.isfinite(r), np.abs(k) <= 2)


def test_the_peak_is_the_vertex_of_the_parabola_through_its_neighbours():
    from bench.runs.external.clock import _peak

    # through (-1, 0), (0, 1), (1, 0.5): vertex at (0 - 0.5) / (2 (0 - 2 + 0.5)) = 1/6
    assert _peak(np.array([0.0, 1.0, 0.5]), 1) == pytest.approx(1 / 6)
    assert _peak(np.array([0.5, 1.0, 0.0]), 1) == pytest.approx(-1 / 6)
    assert _peak(np.array([0.0, 1.0, 0.5]), 0) == 0.0  # no neighbour on one side
    assert _peak(np.array([0.0, 0.5, 1.0]), 2) == 0.0
    assert _peak(np.array([-np.inf, 1.0, 0.5]), 1) == 0.0
    assert _peak(np.array([0.0, 1.0, np.nan]), 1) == 0.0
    assert _peak(np.array([1.0, 1.0, 1.0]), 1) == 0.0  # flat: no vertex


def test_the_correlation_at_a_fractional_lag_is_interpolated():
    from bench.runs.external.clock import _at

    k = np.array([-2, -1, 0, 1, 2])
    r = np.array([0.1, 0.3, 0.9, 0.5, -np.inf])
    assert _at(k, r, 0.25) == pytest.approx(0.8)
    assert _at(k, r, -1.5) == pytest.approx(0.2)
    assert _at(k, r, -2.0) == pytest.approx(0.1)
    assert _at(k, r, 0.0) == pytest.approx(0.9)
    assert np.isnan(_at(k, r, 1.5))  # a neighbour without a correlation
    assert np.isnan(_at(k, r, 2.0)) and np.isnan(_at(k, r, 7.0))  # at or beyond the last lag


def test_the_block_bootstrap_draws_whole_circular_blocks():
    from bench.runs.external.clock import block_weights

    rng = np.random.default_rng(6)
    np.testing.assert_array_equal(block_weights(10, 10, rng), np.ones(10))  # one whole turn
    np.testing.assert_array_equal(block_weights(10, 25, rng), np.ones(10))  # at most n
    for n, block in ((10, 3), (97, 8), (50, 0)):
        w = block_weights(n, block, rng)
        assert len(w) == n and w.sum() == n
    # blocks of 1 are single draws: some samples twice or more, some not at all
    w = block_weights(1000, 1, rng)
    assert (w == 0).any() and (w >= 2).any()
    # blocks of 5 over 20: 4 starts, each 5 consecutive samples (mod 20)
    w = block_weights(20, 5, np.random.default_rng(7))
    starts = np.random.default_rng(7).integers(0, 20, 4)
    want = np.zeros(20)
    for s in starts:
        want[(s + np.arange(5)) % 20] += 1
    np.testing.assert_array_equal(w, want)


def test_a_shift_decides_only_outside_the_widened_interval_and_with_a_gain_above_0():
    from bench.runs.external.clock import ClockFit

    def f(lo, hi, gain=0.01, at_zero=0.8):
        return ClockFit(0.3, 0.9, at_zero, interval_s=(lo, hi), gain_low=gain, grid_s=0.0125)

    assert f(0.0126, 0.6).decisive and not f(0.0125, 0.6).decisive
    assert f(-0.6, -0.0126).decisive and not f(-0.6, -0.0125).decisive
    assert not f(0.1, 0.5, gain=0.0).decisive
    assert not f(0.1, 0.5, gain=float("nan")).decisive  # no gain worked out: not decisive...
    assert f(0.1, 0.5, gain=float("nan"), at_zero=float("nan")).decisive  # ...unless no overlap
    assert not ClockFit(0.3, 0.9, 0.8, gain_low=0.5).decisive  # no interval


# --- the fit on known motions -------------------------------------------------------------------

def test_the_correlation_unshifted_is_pearsons_of_the_profiles_at_equal_times():
    """A straight drive stamped 0.5 s early (40 grid steps of 0.0125 s): the best shift 0.5 s,
    decisively; the correlation at no shift is Pearson's of the two speed profiles sampled at
    the same times (est sample j + 40 at gt sample j)."""
    t = np.arange(0, 30, 0.1)
    poses = straight(t, lambda s: 5 + 3 * np.sin(0.7 * s) + 2 * np.sin(1.9 * s))
    fit = fit_clock(t - 0.5, poses, t, poses, 0.1, replicates=40)
    assert fit.offset_s == pytest.approx(0.5, abs=1e-3)
    assert fit.correlation == pytest.approx(1.0, abs=1e-6)
    assert fit.grid_s == pytest.approx(0.1 / 8)
    h = 0.1 / 8
    gt_speed, _ = motion_profiles(t, poses, h, 1.0, 2.0)
    est_speed, _ = motion_profiles(t - 0.5, poses, h, 1.0, 2.0)
    want, _ = pearson(gt_speed, est_speed, -40)
    assert want < 0.95 and fit.correlation_at_zero == pytest.approx(want, abs=1e-6)
    lo, hi = fit.interval_s
    assert lo <= 0.5 <= hi and fit.gain_low > 0 and fit.decisive
    assert fit.gain_low <= fit.correlation - fit.correlation_at_zero + 1e-9


def test_no_shift_is_never_decisive():
    t = np.arange(0, 30, 0.1)
    poses = drive(t, lambda s: 5 + 3 * np.sin(0.7 * s) + 2 * np.sin(1.9 * s), yaw_rate=0.05)
    noisy = poses.copy()
    noisy[:, :3, 3] += np.random.default_rng(8).normal(0, 0.05, (len(t), 3))
    fit = fit_clock(t, noisy, t, poses, 0.1, replicates=40)
    assert abs(fit.offset_s) < 0.02 and fit.correlation_at_zero == pytest.approx(
        fit.correlation, abs=0.01)
    assert not fit.decisive


def test_a_turn_rate_that_varies_tells_the_shift_where_the_speed_cannot():
    t = np.arange(0, 30, 0.1)
    poses = curve(t, lambda s: 0.4 * np.sin(0.8 * s) + 0.2 * np.sin(2.3 * s))
    fit = fit_clock(t - 0.37, poses, t, poses, 0.1, replicates=40)
    assert fit.offset_s == pytest.approx(0.37, abs=2e-3) and fit.decisive
    assert fit.correlation == pytest.approx(1.0, abs=1e-6)


def test_profiles_that_do_not_overlap_unshifted_have_no_gain_the_interval_decides():
    """The first half of the drive stamped 100 s late: no overlap at no shift."""
    t = np.arange(0, 30, 0.1)
    poses = drive(t, lambda s: 5 + 3 * np.sin(0.7 * s) + 2 * np.sin(1.9 * s), yaw_rate=0.05)
    half = t < 15
    fit = fit_clock(t[half] + 100, poses[half], t, poses, 0.1, replicates=40)
    assert fit.offset_s == pytest.approx(-100, abs=2e-3)
    assert np.isnan(fit.correlation_at_zero) and np.isnan(fit.gain_low) and fit.decisive


def test_unrelated_profiles_are_no_fit():
    """A speed of another drive (other frequencies): no shift lines it up."""
    t = np.arange(0, 30, 0.1)
    gt = straight(t, lambda s: 5 + 3 * np.sin(0.7 * s) + 2 * np.sin(1.9 * s))
    other = straight(t, lambda s: 5 + 3 * np.sin(3.1 * s + 1) * np.sin(0.23 * s))
    fit = fit_clock(t, other, t, gt, 0.1, replicates=5)
    assert fit.offset_s is None and fit.correlation < 0.5
    assert fit.why == (f"the speed profiles do not line up at any shift (best correlation "
                       f"{fit.correlation:.2f})")


def test_too_few_or_too_short_is_no_fit():
    t = np.arange(0, 30, 0.125)
    poses = straight(t, lambda s: 5 + 3 * np.sin(0.7 * s))
    assert fit_clock(t[:2], poses[:2], t, poses, 0.125).why == "too few poses for a speed profile"
    assert fit_clock(t, poses, t[:2], poses[:2], 0.125).why == "too few poses for a speed profile"
    assert fit_clock(t[:3], poses[:3], t, poses, 0.125).why != "too few poses for a speed profile"
    assert fit_clock(t, poses, t, poses, 0.0).why == "too few poses for a speed profile"
    # a grid of 0.125 / 8 s, windows of +/- 1 s: a span of 2 s + 7 steps has 8 samples, of
    # 2 s + 6 steps 7 (too short)
    for steps, short in ((7, False), (6, True)):
        s = np.r_[np.arange(0, 2.0, 0.125), 2.0 + steps * 0.015625]
        p = straight(s, lambda u: 5 + 3 * np.sin(0.7 * u))
        fit = fit_clock(s, p, t, poses, 0.125, replicates=5)
        assert (fit.why == "too short for a speed profile") == short, steps
        fit = fit_clock(t, poses, s, p, 0.125, replicates=5)
        assert (fit.why == "too short for a speed profile") == short, steps


def test_a_long_recording_gets_a_coarser_grid():
    """At most 2^15 samples a profile: 0.5 s scans over 2500 s are sampled every
    2500 / 2^15 s (0.076 s), not every 0.5 / 8 s."""
    t = np.arange(0, 2500.5, 0.5)
    x = 5 * t - 3 / 0.2 * np.cos(0.2 * t) - 2 / 0.53 * np.cos(0.53 * t)  # 5 + 3 sin + 2 sin
    poses = make_T(np.repeat(np.eye(3)[None], len(t), 0), np.column_stack([x, 0 * t, 0 * t]))
    fit = fit_clock(t - 3.0, poses, t, poses, 0.5, replicates=2)
    assert fit.grid_s == pytest.approx(2500 / 2**15)
    assert fit.offset_s == pytest.approx(3.0, abs=0.01)


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


# --- survivors of mutation: bounds, windows, spans and the refinement --------------------------

def test_the_edges_of_the_pieces():
    from bench.runs.external.clock import _at, _peak, _range_max

    k = np.array([-2, -1, 0, 1, 2])
    r = np.array([0.1, 0.3, 0.9, 0.5, 0.7])
    assert _at(k, r, 1.5) == pytest.approx(0.6)  # between the last two lags
    assert np.isnan(_at(k, r, 2.0))  # the last lag has no right neighbour to interpolate with
    # (0.2, 0.5, 0.4): vertex at (0.2 - 0.4) / (2 (0.2 - 1.0 + 0.4)) = 0.25
    assert _peak(np.array([0.2, 0.5, 0.4]), 1) == pytest.approx(0.25)
    assert _peak(np.array([0.0, 1.0, -np.inf]), 1) == 0.0
    assert _peak(np.array([1.0, 0.5, 0.2]), 0) == 0.0  # the first has no left neighbour
    # a range from 0 of a power-of-2 length: the next value is not in it
    values = np.array([0.0, 0.0, 0.0, 0.0, 9.0])
    np.testing.assert_array_equal(_range_max(values, np.array([0, 1]), np.array([4, 5])),
                                  [0.0, 9.0])


def test_the_profiles_of_any_window_and_start():
    """Stamps from 10 s, windows of +/- 0.5 s: the grid runs from the first stamp to the last,
    the speed (2 m/s) and turn rate (0.1 rad/s) are per second whatever the window."""
    t = 10 + np.arange(0, 20, 0.125)
    poses = drive(t, yaw_rate=0.1)
    speed, rate = motion_profiles(t, poses, 0.0625, 0.5, 0.3)
    assert len(speed) == int((t[-1] - t[0]) / 0.0625) + 1
    ok = np.isfinite(speed)
    # the chord of a circle of 20 m over 1 s, per second: 40 sin(0.05) = 1.99917 m/s
    np.testing.assert_allclose(speed[ok], 40 * np.sin(0.05), rtol=1e-4)
    np.testing.assert_allclose(rate[ok], 0.1, rtol=1e-9)


def test_a_gap_in_the_first_or_last_step_is_under_the_windows_that_reach_it():
    t = np.r_[0.0, np.arange(2.5, 10, 0.125)]
    speed, _ = motion_profiles(t, straight(t, lambda s: 2.0 + 0 * s), 0.0625, 1.0, 0.3)
    assert np.isnan(speed[16])  # t = 1 s: its window [0, 2] s lies over the 2.5 s step
    t = np.r_[np.arange(0, 10, 0.125), 12.5]
    speed, _ = motion_profiles(t, straight(t, lambda s: 2.0 + 0 * s), 0.0625, 1.0, 0.3)
    assert np.isnan(speed[int(11.5 / 0.0625)])  # t = 11.5 s: its window ends at the last pose


def test_the_path_speed_of_a_span_under_a_second():
    xyz = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    assert path_speed(np.array([0.0, 0.5]), xyz) == pytest.approx(2.0)


def test_the_aligned_offset_at_the_scans_bounds():
    q = np.array([0.0, 0.125, 0.25, 0.375])
    # two scans are enough: 0.01 s is 0.01 s past the first, 0.11 s 0.015 s before the second
    assert aligned_offset(np.array([0.01, 0.11]), q[:2], 0.0, 0.125) == pytest.approx(0.0025)
    assert aligned_offset(np.array([0.36]), q, 0.0, 0.125) == pytest.approx(0.015)  # last scan
    # stamps exactly on the first or last scan are inside
    assert aligned_offset(np.array([0.0, 0.135]), q, 0.0, 0.125) == pytest.approx(-0.005)
    assert aligned_offset(np.array([0.365, 0.375]), q, 0.0, 0.125) == pytest.approx(0.005)
    # stamps beyond the scans' span do not move it
    est = np.r_[q[:3] + 0.01, 5 + np.arange(10) * 0.125 + 0.05]
    assert aligned_offset(est, q, 0.0, 0.125) == pytest.approx(-0.01)


def test_single_draws_are_a_multinomial_of_the_samples():
    from bench.runs.external.clock import block_weights

    w = block_weights(20, 1, np.random.default_rng(9))
    want = np.bincount(np.random.default_rng(9).integers(0, 20, 20), minlength=20)
    np.testing.assert_array_equal(w, want)
    np.testing.assert_array_equal(block_weights(20, 0, np.random.default_rng(9)), want)


def test_a_nearly_constant_profile_has_no_correlation():
    """A side varying by less than 1e-6 of the other's spread (relative variance below 1e-12)
    is constant; one varying by 3e-6 is not."""
    from bench.runs.external.clock import _ncc

    rng = np.random.default_rng(10)
    y = rng.normal(size=200)
    k, r = _ncc(1 + 0.5e-6 * rng.normal(size=200), y)
    assert np.all(r == -np.inf)
    k, r = _ncc(1 + 3e-6 * rng.normal(size=200), y)
    assert np.isfinite(r[k == 0]).all()


def test_the_shift_is_refined_between_grid_steps_the_right_way():
    """Poses at 0.033 s past the ground truth's stamps, stamped 0.37 s early: the shift is 2.64
    grid steps from the grids' start; the parabola refines it to 0.37 s, and the bootstrap's
    interval (noise-free: all but a point) lies there too."""
    def speed(t):
        return 5 + 3 * np.sin(0.7 * t) + 2 * np.sin(1.9 * t)

    gt = drive(T, speed, yaw_rate=0.05)
    est = drive(T + 0.033, speed, yaw_rate=0.05)
    fit = fit_clock(T + 0.033 - 0.37, est, T, gt, 0.1, replicates=10)
    assert fit.offset_s == pytest.approx(0.37, abs=1e-3)
    lo, hi = fit.interval_s
    assert lo - 1e-3 <= 0.37 <= hi + 1e-3


def test_the_correlation_at_no_shift_of_a_part_of_the_drive():
    """The estimate covers 5 .. 25 s of the drive, stamped 0.5 s early: its grid starts at
    4.5 s, the ground truth's at 0, so equal times are 360 grid steps apart (4.5 / 0.0125)."""
    t = np.arange(0, 30, 0.1)
    poses = straight(t, lambda s: 5 + 3 * np.sin(0.7 * s) + 2 * np.sin(1.9 * s))
    part = (t >= 5) & (t < 25)
    fit = fit_clock(t[part] - 0.5, poses[part], t, poses, 0.1, replicates=5)
    h = 0.1 / 8
    gt_speed, _ = motion_profiles(t, poses, h, 1.0, 2.0)
    est_speed, _ = motion_profiles(t[part] - 0.5, poses[part], h, 1.0, 2.0)
    want, _ = pearson(gt_speed, est_speed, 360)
    assert fit.correlation_at_zero == pytest.approx(want, abs=1e-6)


def test_the_ground_truth_needs_three_poses_and_the_blocks_are_four_seconds(monkeypatch):
    from bench.runs.external import clock

    t = np.arange(0, 30, 0.125)
    poses = straight(t, lambda s: 5 + 3 * np.sin(0.7 * s))
    assert fit_clock(t, poses, t[:3], poses[:3], 0.125).why != "too few poses for a speed profile"
    seen = []
    real = clock.block_weights

    def spy(n, block, rng):
        seen.append((n, block))
        return real(n, block, rng)

    monkeypatch.setattr(clock, "block_weights", spy)
    fit_clock(t - 0.5, poses, t, poses, 0.125, replicates=3)
    h = 0.125 / 8
    assert seen == [(int((t[-1] - t[0]) / h) + 1, int(np.ceil(4.0 / h)))] * 3


def test_the_grid_follows_the_longer_span():
    """0.5 s scans; the ground truth over 100 .. 2600 s, the estimate over part of it (and the
    reverse): the grid is 2500 s / 2^15 either way."""
    t = 100 + np.arange(0, 2500.5, 0.5)
    x = 5 * t - 3 / 0.2 * np.cos(0.2 * t) - 2 / 0.53 * np.cos(0.53 * t)
    poses = make_T(np.repeat(np.eye(3)[None], len(t), 0), np.column_stack([x, 0 * t, 0 * t]))
    part = slice(0, 4001)  # 100 .. 2100 s
    fit = fit_clock(t[part] - 3.0, poses[part], t, poses, 0.5, replicates=2)
    assert fit.grid_s == pytest.approx(2500 / 2**15, rel=1e-12)
    fit = fit_clock(t - 3.0, poses, t[part], poses[part], 0.5, replicates=2)
    assert fit.grid_s == pytest.approx(2500 / 2**15, rel=1e-12)


def test_a_hole_wider_than_the_window_is_left_out_of_the_profile():
    """The estimate lacks 2.5 s of poses (wider than the 2 s window): no speed is made up
    across the hole, so the profile fits the ground truth's exactly at its shift."""
    def speed(t):
        return 5 + 3 * np.sin(0.7 * t) + 2 * np.sin(1.9 * t)

    poses = drive(T, speed, yaw_rate=0.05)
    keep = (T < 12) | (T > 14.45)
    fit = fit_clock(T[keep] - 0.37, poses[keep], T, poses, 0.1, replicates=5)
    assert fit.correlation == pytest.approx(1.0, abs=1e-9)
    assert fit.why == "" and fit.offset_s == pytest.approx(0.37, abs=1e-3)


def test_a_hole_is_bridged_up_to_twice_the_window_or_three_pose_steps():
    """Poses every 0.625 s (3 steps: 1.875 s, less than the 2 s of two windows): a 2.5 s hole
    is left out (the profile fits exactly at its 5-grid-step shift); with 1.25 s scans (windows
    of +/- 1.25 s) a 2.1875 s hole in poses every 0.3125 s is bridged (its chord is in the
    profile: no exact fit)."""
    def speed(t):
        return 5 + 3 * np.sin(0.7 * t) + 2 * np.sin(1.9 * t)

    t = np.arange(0, 40, 0.625)
    poses = drive(t, speed, yaw_rate=0.05)
    keep = (t <= 12.5) | (t >= 15.0)  # 12.5 -> 15.0: 2.5 s
    shift = 5 * 0.625 / 8
    fit = fit_clock(t[keep] - shift, poses[keep], t, poses, 0.625, replicates=5)
    assert fit.correlation == pytest.approx(1.0, abs=1e-9)
    t = np.arange(0, 60, 0.3125)
    poses = drive(t, speed, yaw_rate=0.05)
    keep = (t <= 20) | (t >= 22.1875)  # 7 steps: 2.1875 s, within 2 x 1.25 s
    shift = 4 * 1.25 / 8
    fit = fit_clock(t[keep] - shift, poses[keep], t, poses, 1.25, replicates=5)
    assert fit.correlation < 1 - 1e-6


def test_the_intervals_are_the_bootstraps_central_95_percent(monkeypatch):
    """With the replicates' refinements and gains replaced by known values, the shift's
    interval is their 2.5th and 97.5th percentiles (in grid steps from the fit's lag) and the
    gain's lower end their 2.5th."""
    from bench.runs.external import clock

    t = np.arange(0, 30, 0.1)
    poses = straight(t, lambda s: 5 + 3 * np.sin(0.7 * s) + 2 * np.sin(1.9 * s))
    steps = np.linspace(-0.9, 0.9, 40) ** 3  # the replicates' refinements [grid steps]
    gains = np.linspace(-0.2, 0.6, 40) ** 2
    peaks = iter([0.0, *steps])
    monkeypatch.setattr(clock, "_peak", lambda r, best: next(peaks))
    ats = iter([0.5] + [v for g in gains for v in (0.7 + g, 0.7)])
    monkeypatch.setattr(clock, "_at", lambda k, r, lag: next(ats))
    fit = fit_clock(t - 0.5, poses, t, poses, 0.1, replicates=40)
    h = 0.1 / 8
    lo, hi = fit.interval_s
    assert lo == pytest.approx(fit.offset_s + np.percentile(steps, 2.5) * h, abs=1e-12)
    assert hi == pytest.approx(fit.offset_s + np.percentile(steps, 97.5) * h, abs=1e-12)
    assert fit.gain_low == pytest.approx(np.percentile(gains, 2.5), abs=1e-12)
