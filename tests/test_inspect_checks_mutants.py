"""The pieces of ``bench inspect``'s GT clock check (bench.data.inspect_checks) against answers
worked out by hand: the windows, the GT speed of known motions, the Pearson correlation (numpy's
corrcoef), the lag of speed curves shifted on purpose, the bootstrap interval's refusal of short
pieces, and each line the check prints (a lag within one period is no alarm, one beyond it with
an interval beyond it is a warning, anything between is inconclusive)."""

import numpy as np
import pytest

import bench.data.inspect_checks as ic
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import make_T
from loaders.trajectory import Trajectory

PERIOD = 0.1


def _track(stamps: np.ndarray, positions: np.ndarray) -> Trajectory:
    return Trajectory(stamps, np.array([make_T(np.eye(3), p) for p in positions]))


def _speed(t):  # a speed that varies (std 2.1 m/s), not periodic within the search
    return 8 + 3 * np.sin(2 * np.pi * t / 7.0) * np.exp(-((t - 11) / 9) ** 2)


def _position(t):  # its integral, numerically (fine grid, trapezoid)
    fine = np.linspace(-5, 40, 45001)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (_speed(fine[1:]) + _speed(fine[:-1]))
                                         * np.diff(fine))])
    return np.interp(t, fine, x)


def _curves(late: float, n: int = 220):
    """Scan stamps, the exact sensor speed at them, and a GT stamped ``late`` s late (each GT
    pose shows the car ``late`` earlier)."""
    t = np.arange(n) * PERIOD
    x = _position(t - late)
    gt = _track(t, np.column_stack([x, np.zeros(n), np.zeros(n)]))
    return t, _speed(t), gt


# -- windows and the GT speed ------------------------------------------------------------------

def test_a_window_is_full_only_when_it_lies_inside_the_stamps():
    t = np.linspace(0.0, 10.0, 101)
    assert ic._full_window(t, 0.5) and ic._full_window(t, 9.5) and ic._full_window(t, 5.0)
    assert not ic._full_window(t, 0.49) and not ic._full_window(t, 9.51)


def test_the_window_mean_averages_the_usable_values_within_half_a_second():
    t = np.arange(100) * 0.125  # exact in binary: windows of 9 scans, +-4
    values = 2.0 * t + 1.0
    ok = np.ones(100, bool)
    out = ic._window_mean(t, values, ok)
    inside = (t >= 0.5) & (t <= t[-1] - 0.5)
    assert inside.sum() == 92 and np.isnan(out[~inside]).all()
    np.testing.assert_allclose(out[inside], values[inside], atol=1e-9)  # symmetric windows
    # an unusable value is left out: a spike at scan 50 marked not ok changes nothing
    spiked = np.full(100, 3.0)
    spiked[50] = 1e6
    ok[50] = False
    np.testing.assert_allclose(ic._window_mean(t, spiked, ok)[inside], 3.0, atol=1e-9)
    # nothing usable: no mean
    assert np.isnan(ic._window_mean(t, values, np.zeros(100, bool))).all()
    # the mean is over +-0.5 s, ends included: at 2.0 s the 9 values of 1.5 .. 2.5 s
    step = np.where(t >= 2.5, 9.0, 0.0)
    assert ic._window_mean(t, step, np.ones(100, bool))[16] == pytest.approx(1.0)


def test_the_gt_speed_is_the_slope_of_the_positions_within_the_window():
    t = np.arange(96) * 0.0625  # 0 .. 5.9375 s, exact in binary
    # 3-4-12 m/s: speed 13 m/s, along every axis
    gt = _track(t, np.column_stack([3 * t, -4 * t + 2, 12 * t]))
    q = np.array([0.2, 0.5, 2.0, 3.33, 5.4, 5.6])
    v = ic.gt_speed(gt, q)
    assert np.isnan(v[[0, 5]]).all()  # the window is cut by the GT's ends
    np.testing.assert_allclose(v[1:5], 13.0, rtol=1e-9)
    # x = t^2: the line through a symmetric window has slope 2 q (the curvature averages out)
    gt2 = _track(t, np.column_stack([t ** 2, np.zeros_like(t), np.zeros_like(t)]))
    np.testing.assert_allclose(ic.gt_speed(gt2, np.array([1.0, 2.5, 4.0])), [2.0, 5.0, 8.0],
                               rtol=1e-9)
    # fewer than 3 poses in the window: none; 3 (two of them on its ends): the slope
    zeros = np.zeros(4)
    sparse = _track(np.array([0.0, 0.75, 1.25, 2.0]), np.column_stack([[0, 7.5, 12.5, 20.0],
                                                                       zeros, zeros]))
    assert np.isnan(ic.gt_speed(sparse, np.array([1.0]))).all()
    zeros = np.zeros(5)
    three = _track(np.array([0.0, 0.5, 1.0, 1.5, 2.0]), np.column_stack([[0, 5, 10, 15, 20.0],
                                                                         zeros, zeros]))
    assert ic.gt_speed(three, np.array([1.0]))[0] == pytest.approx(10.0)


# -- correlation and the best lag --------------------------------------------------------------

def test_the_correlation_is_pearsons_over_the_shifted_scans_inside_the_gt():
    rng = np.random.default_rng(3)
    t = np.arange(40) * 0.1
    v_d = rng.normal(size=40)
    t_gt = np.arange(0.5, 3.0, 0.1)
    v_gt = rng.normal(size=len(t_gt))
    lag = 0.25  # no shifted stamp on the GT's ends
    q = t + lag
    inside = (q >= t_gt[0]) & (q <= t_gt[-1])
    assert 10 < inside.sum() < 40
    expected = np.corrcoef(v_d[inside], np.interp(q[inside], t_gt, v_gt))[0, 1]
    assert ic._correlation(t, v_d, t_gt, v_gt, lag) == pytest.approx(expected, abs=1e-9)
    # a negative correlation stays negative
    assert ic._correlation(t, -v_d, t_gt, v_gt, lag) == pytest.approx(-expected, abs=1e-9)
    # a constant curve correlates with nothing
    assert np.isnan(ic._correlation(t, np.ones(40), t_gt, v_gt, lag))
    assert np.isnan(ic._correlation(t, v_d, t_gt, np.ones(len(t_gt)), lag))


def test_the_correlation_needs_ten_scans_inside_the_gt():
    t = np.arange(30) * 1.0
    v = np.sin(t)
    t_gt = np.arange(0.0, 9.5, 1.0)  # 0 .. 9: ten stamps
    assert np.isfinite(ic._correlation(t, v, t_gt, np.sin(t_gt), 0.0))
    assert np.isnan(ic._correlation(t, v, t_gt[:-1], np.sin(t_gt[:-1]), 0.0))
    # shifting by +1 s leaves 0 .. 8 inside: nine
    assert np.isnan(ic._correlation(t, v, t_gt, np.sin(t_gt), 1.0))
    assert np.isfinite(ic._correlation(t, v, t_gt, np.sin(t_gt), -1.0))


@pytest.mark.parametrize("late", [0.535, -0.285, 0.0, 1.988, -1.988])
def test_the_best_lag_finds_a_shift_between_grid_steps(late):
    """Exact speeds: the parabola through the peak's neighbours finds the lag to a twentieth
    of the 0.01 s search step, up to next to the search's +-2 s edges."""
    t = np.arange(300) * PERIOD
    v_g = _speed(t - late)
    lag, corr, why = ic._best_lag(t, _speed(t), v_g)
    assert why == "" and corr > 0.99
    assert lag == pytest.approx(late, abs=0.0005)


def test_a_lag_closest_to_the_search_edge_is_not_estimated():
    """A GT 1.996 s late peaks on the last lag searched (2.00 s): refused as at the edge."""
    t = np.arange(300) * PERIOD
    for late in (1.996, -1.996):
        lag, _, why = ic._best_lag(t, _speed(t), _speed(t - late))
        assert lag is None and why == "the best lag is at the edge of the search (+-2 s)"


def test_the_best_lag_says_why_there_is_none():
    t = np.arange(300) * PERIOD
    v = _speed(t)
    few = np.full(300, np.nan)
    few[:9] = v[:9]
    assert ic._best_lag(t, few, v)[2].startswith("too few scans")
    assert ic._best_lag(t, v, few)[2].startswith("too few scans")
    assert ic._best_lag(t, few, v)[2] == "too few scans with both a Doppler speed and ground " \
                                         "truth"
    few[9] = v[9]  # ten are enough to go on
    assert not ic._best_lag(t, few, v)[2].startswith("too few scans")
    assert not ic._best_lag(t, v, few)[2].startswith("too few scans")
    flat = 5 + 0.25 * np.sin(t)  # std 0.18 m/s
    lag, corr, why = ic._best_lag(t, v, flat)
    assert lag is None and np.isnan(corr)
    assert why == f"the speed hardly changes (GT speed std {np.std(flat):.2f} m/s): nothing to " \
                  "line up"
    noise = np.random.default_rng(0).normal(8, 2, 300)
    lag, corr, why = ic._best_lag(t, noise, v)
    assert lag is None and corr < 0.5 and why == f"the speeds agree poorly (correlation " \
                                                 f"{corr:.2f})"
    # a GT 3 s late (a single bump, so no echo within the search): the peak at the edge
    bump = lambda x: 8 + 3 * np.exp(-((x - 15) / 1.5) ** 2)  # noqa: E731
    lag, corr, why = ic._best_lag(t, bump(t), bump(t - 3.0))
    assert lag is None and corr > 0.5 and why == "the best lag is at the edge of the search " \
                                                 "(+-2 s)"
    lag, corr, why = ic._best_lag(t, bump(t), bump(t + 3.0))
    assert lag is None and why.startswith("the best lag is at the edge")
    # the speeds never overlap in time: the GT speed is there only before the scans' speed
    late_d = np.where(t > 20, v, np.nan)
    early_g = np.where(t < 5, v, np.nan)
    assert ic._best_lag(t, late_d, early_g)[2] == "the speeds do not overlap"


def test_a_speed_varying_just_enough_is_timed():
    t = np.arange(300) * PERIOD
    v = 8 + 1.0 * np.sin(2 * np.pi * t / 6.0) * np.exp(-((t - 15) / 10) ** 2)
    assert 0.4 < np.std(v) < 0.5  # above the 0.3 m/s needed
    lag, _, why = ic._best_lag(t, v, v)
    assert why == "" and lag == pytest.approx(0.0, abs=0.002)


# -- the whole estimate and its interval -------------------------------------------------------

def test_a_late_gt_is_timed_with_an_interval_and_the_offset_that_removes_it():
    t, v, gt = _curves(0.5)
    observable = np.ones(len(t), bool)
    speed = v.copy()
    observable[40] = False
    speed[41] = np.nan
    speed[40] = 1e3  # not observable: never used
    est = ic.gt_clock_offset(t, speed, observable, gt, converted_offset_s=0.2)
    assert est.lag_s == pytest.approx(0.5, abs=0.01)
    assert est.time_offset_s == pytest.approx(0.2 - 0.5, abs=0.01)
    assert est.scans == len(t) - 2 and est.reason == ""
    lo, hi = est.interval_s
    assert lo <= est.lag_s <= hi and hi - lo < 0.05
    assert est.spread_s == pytest.approx((hi - lo) / 2)
    assert est.correlation > 0.99
    # the observable flags as 0/1 numbers (as a store may keep them) mean the same
    flags = ic.gt_clock_offset(t, speed, observable.astype(np.uint8), gt, converted_offset_s=0.2)
    assert flags == est


def test_no_ground_truth_or_too_little_gives_no_estimate():
    t, v, gt = _curves(0.0)
    ok = np.ones(len(t), bool)
    for missing in (None, Trajectory(gt.stamps[:2], gt.poses[:2])):
        est = ic.gt_clock_offset(t, v, ok, missing)
        assert est.lag_s is None and est.time_offset_s is None and est.interval_s is None
        assert est.reason.startswith("too few scans") and np.isnan(est.spread_s)
        assert est.scans == len(t)


def test_the_interval_needs_five_bootstrap_blocks():
    """Blocks of 4 s at 0.1 s: 40 scans each; 200 scans are 5 blocks, 199 fewer."""
    t = np.arange(200) * PERIOD
    v_d = _speed(t)
    v_g = _speed(t - 0.3)
    lo, hi = ic.lag_interval(t, v_d, v_g)
    assert lo <= 0.3 + 0.01 and hi >= 0.3 - 0.01 and hi - lo < 0.05
    assert ic.lag_interval(t[:199], v_d[:199], v_g[:199]) is None
    # the block follows the period: at 0.2 s a block is 20 scans, so 100 scans suffice
    t2 = np.arange(100) * 0.2
    assert ic.lag_interval(t2, _speed(t2), _speed(t2 - 0.3)) is not None
    assert ic.lag_interval(t2[:99], _speed(t2[:99]), _speed(t2[:99] - 0.3)) is None
    few = np.full(200, np.nan)
    few[:9] = 1.0
    assert ic.lag_interval(t, few, v_g) is None and ic.lag_interval(t, v_d, few) is None


def test_the_interval_covers_the_lag_of_noisy_speeds_and_is_reproducible():
    rng = np.random.default_rng(5)
    t = np.arange(260) * PERIOD
    v_d = _speed(t) + rng.normal(0, 0.3, len(t))
    v_g = _speed(t + 0.25)
    lo, hi = ic.lag_interval(t, v_d, v_g)
    assert lo < -0.25 < hi and 0.005 < hi - lo < 0.5
    assert ic.lag_interval(t, v_d, v_g) == (lo, hi)
    # the point estimate lies inside its own interval
    lag, _, _ = ic._best_lag(t, v_d, v_g)
    assert lo <= lag <= hi


def test_the_converted_offset_is_read_from_the_provenance():
    assert ic.converted_offset({"gt_association": {"offset_s": 0.25}}) == 0.25
    assert ic.converted_offset({"gt_association": {"offset_s": "-1.5"}}) == -1.5
    assert ic.converted_offset({"time_offset_s": 0.125}) == 0.125
    # the association's record wins over the older key, even without an offset in it
    assert ic.converted_offset({"gt_association": {"mode": "time"}, "time_offset_s": 3}) == 0.0
    assert ic.converted_offset({"gt_association": "time", "time_offset_s": 3}) == 3.0
    for bad in ({}, {"time_offset_s": None}, {"time_offset_s": "x"},
                {"gt_association": {"offset_s": [1]}}):
        assert ic.converted_offset(bad) == 0.0


# -- the lines bench inspect prints ------------------------------------------------------------

def _seq(n: int = 30, period: float = 0.125, loader: str = "ntu4dradlm",
         provenance: dict | None = None) -> MemorySequence:
    scans = [Scan(k * period, np.zeros((1, 3)), np.zeros(1)) for k in range(n)]
    return MemorySequence("s", SensorInfo("radar", 0.25), scans, None,
                          {"loader": loader, **(provenance or {})})


_SPEEDS = {"stamps": np.zeros(3), "speed_doppler": np.zeros(3), "observable": np.ones(3, bool)}


def _lines(monkeypatch, seq, lag, interval=None, reason="", corr=0.97, scans=180):
    seen = {}

    def fake(stamps, speed, observable, gt, converted):
        seen["converted"] = converted
        spread = np.nan if interval is None else (interval[1] - interval[0]) / 2
        return ic.ClockOffset(lag, spread, corr, scans,
                              None if lag is None else converted - lag, reason, interval)

    monkeypatch.setattr(ic, "gt_clock_offset", fake)
    out = ic.clock_offset_lines(seq, _SPEEDS)
    assert len(out) == 1
    return out[0], seen["converted"]


def test_no_estimate_is_said_dimly_with_the_reason(monkeypatch):
    (style, line), _ = _lines(monkeypatch, _seq(), None, reason="the speeds do not overlap")
    assert style == "dim"
    assert line == "GT clock vs Doppler speed: not estimated (the speeds do not overlap)"


def test_a_lag_within_one_period_with_a_tight_interval_is_no_alarm(monkeypatch):
    (style, line), _ = _lines(monkeypatch, _seq(), 0.04, (-0.02, 0.1))
    assert style == "green" and line.endswith(": within one scan period")
    assert "the ground truth lags the sensor by +0.040 s" in line
    assert "(95 % block-bootstrap interval [-0.020, +0.100] s)" in line
    assert "cross-correlation of the speeds 0.97 over 180 scans, one scan period 0.125 s" in line
    # the edges (scans 0.125 s apart, exact): a lag of exactly one period, an interval reaching
    # exactly one period either way
    (style, _), _ = _lines(monkeypatch, _seq(), -0.125, (-0.125, 0.0))
    assert style == "green"
    (style, _), _ = _lines(monkeypatch, _seq(), 0.125, (0.0, 0.125))
    assert style == "green"


def test_a_lag_within_one_period_with_a_wide_interval_cannot_time_the_gt(monkeypatch):
    for interval in ((-0.15, 0.05), (-0.05, 0.15), (-0.13, 0.13), None):
        (style, line), _ = _lines(monkeypatch, _seq(), 0.02, interval)
        assert style == "dim" and line.endswith(
            ": within one scan period, but the interval reaches beyond: this sequence cannot "
            "time the ground truth")
    assert "(too few scans for an interval: under 5 blocks of 4 s)" in line


def test_a_lag_beyond_a_period_with_its_interval_beyond_is_a_warning(monkeypatch):
    (style, line), conv = _lines(monkeypatch, _seq(provenance={
        "gt_association": {"offset_s": 0.3}}), 0.5, (0.45, 0.55))
    assert conv == 0.3
    assert style == "yellow" and line.startswith("warning: GT clock vs Doppler speed: ")
    assert line.endswith(": more than one scan period, so every scored pose is compared with "
                         "the wrong moment; convert again with --time-offset -0.200")
    (style, line), _ = _lines(monkeypatch, _seq(), -0.5, (-0.56, -0.44))
    assert style == "yellow" and line.startswith("warning:")
    assert line.endswith("--time-offset 0.500")
    # a loader without the option: the shift to make, and no option named
    (_, line), _ = _lines(monkeypatch, _seq(loader="npy-frames"), 0.5, (0.45, 0.55))
    assert line.endswith("shift the GT stamps by -0.500 s (gt_stamp + offset = sensor clock; "
                         "npy-frames takes no time-offset option)")
    (_, line), _ = _lines(monkeypatch, _seq(loader=""), 0.5, (0.45, 0.55))
    assert "its loader takes no time-offset option" in line


def test_a_lag_beyond_a_period_with_an_interval_reaching_within_is_inconclusive(monkeypatch):
    # intervals reaching back to exactly one period (0.125 s) either way, or further
    for lag, interval in ((0.5, (0.125, 0.9)), (0.5, (0.05, 0.9)), (-0.5, (-0.9, -0.125)),
                          (0.5, None), (-0.5, (-0.9, 0.2))):
        (style, line), _ = _lines(monkeypatch, _seq(), lag, interval)
        assert style == "yellow" and not line.startswith("warning")
        assert ": more than a period, but the interval reaches within one period: " \
               "inconclusive on this sequence (if confirmed: convert again with " \
               f"--time-offset {-lag:.3f})" in line


def test_the_period_is_the_scans_median_step_or_the_nominal_one(monkeypatch):
    # scans 0.2 s apart: a 0.15 s lag is within one period
    (style, line), _ = _lines(monkeypatch, _seq(period=0.2), 0.15, (0.1, 0.2))
    assert style == "green" and "one scan period 0.200 s" in line
    (style, line), _ = _lines(monkeypatch, _seq(period=0.05), 0.15, (0.1, 0.2))
    assert style == "yellow" and "one scan period 0.050 s" in line
    # two scans are enough to measure it
    (style, line), _ = _lines(monkeypatch, _seq(n=2, period=0.2), 0.15, (0.1, 0.2))
    assert style == "green" and "one scan period 0.200 s" in line
    # a single scan: the sensor's nominal period (0.25 s)
    (style, line), _ = _lines(monkeypatch, _seq(n=1), 0.15, (0.1, 0.2))
    assert style == "green" and "one scan period 0.250 s" in line


# -- the height advice -------------------------------------------------------------------------

def test_the_height_line_says_what_the_layer_rests_on():
    seq = MemorySequence("n", SensorInfo("radar", 0.1), [], None, {"loader": "ntu4dradlm"})
    z = {"dominant_layer_z_m": -0.62, "verdict": "road below", "frames": 60,
         "frames_below_sensor": 0.9, "basis": "points within 30 m"}
    assert ic.height_advice(seq, z) == (
        "densest layer at z = -0.62 m (the height most of 60 frames across the sequence agree "
        "on, 90 % of them with their own layer below; points within 30 m): road below")
    no_share = {**z, "frames_below_sensor": float("nan"), "basis": ""}
    assert ic.height_advice(seq, no_share) == (
        "densest layer at z = -0.62 m (the height most of 60 frames across the sequence agree "
        "on): road below")
    assert ic.height_advice(seq, {**no_share, "frames_below_sensor": None}) == \
        ic.height_advice(seq, no_share)
    no_frames = {"dominant_layer_z_m": -0.5, "verdict": "road below", "basis": "all points"}
    assert ic.height_advice(seq, no_frames) == "densest layer at z = -0.50 m (all points): " \
                                               "road below"
    assert ic.height_advice(seq, {"dominant_layer_z_m": -0.5, "verdict": "v"}) == \
        "densest layer at z = -0.50 m: v"


def test_a_layer_at_or_above_the_sensor_gets_advice():
    campus = MemorySequence("c", SensorInfo("radar", 0.1), [], None, {"loader": "campus"})
    z = {"dominant_layer_z_m": 0.0, "verdict": "above"}
    assert ic.height_advice(campus, z) == ("densest layer at z = +0.00 m: above; if the road is "
                                           "below the sensor, convert again with "
                                           "--elevation-sign -1 (bench convert campus)")
    ntu = MemorySequence("n", SensorInfo("radar", 0.1), [], None, {"loader": "ntu4dradlm"})
    assert ic.height_advice(ntu, {**z, "dominant_layer_z_m": 0.7}) == (
        "densest layer at z = +0.70 m: above; ntu4dradlm takes no elevation-sign option (its "
        "points' z is as the sensor recorded it): check the sensor's mounting and the extrinsic")


# -- the interval's edges ----------------------------------------------------------------------

def test_the_interval_needs_ten_scans_with_each_speed():
    """Scans 2 s apart: a bootstrap block is 2 scans, so 10 scans are 5 blocks; only lag 0
    keeps all 10 inside the GT, so every resample's best lag is 0."""
    import warnings

    t = np.arange(10) * 2.0
    v = np.random.default_rng(0).normal(size=10)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # lags without scans inside divide 0 by 0: silently
        lo, hi = ic.lag_interval(t, v, v.copy())
    assert lo == pytest.approx(0.0, abs=1e-9) and hi == pytest.approx(0.0, abs=1e-9)
    gap = v.copy()
    gap[5] = np.nan  # 9 GT speeds (still spanning every scan): no interval
    assert ic.lag_interval(t, v, gap) is None
    assert ic.lag_interval(t, gap, v) is None


def test_the_interval_searches_the_same_lags_as_the_estimate():
    """A GT 2.3 s late lies beyond the +-2 s search: every resample ends on its edge."""
    t = np.arange(300) * PERIOD
    bump = lambda x: 8 + 3 * np.exp(-((x - 15) / 1.5) ** 2)  # noqa: E731
    lo, hi = ic.lag_interval(t, bump(t), bump(t - 2.3))
    assert lo == pytest.approx(2.0, abs=1e-6) and hi == pytest.approx(2.0, abs=1e-6)


def test_scans_shifted_outside_the_gt_are_left_out_of_the_interval():
    """The GT speed only over 8-18 s of a 26 s drive, 0.3 s late: the scans whose shifted time
    falls outside it say nothing, and the interval stays tight around 0.3 s."""
    t = np.arange(260) * PERIOD
    v_g = np.where((t >= 8) & (t <= 18), _speed(t - 0.3), np.nan)
    lo, hi = ic.lag_interval(t, _speed(t), v_g)
    assert 0.29 < lo <= hi < 0.31


def test_a_constant_or_faint_curve_warns_nothing_and_correlates_exactly():
    import warnings

    rng = np.random.default_rng(8)
    t = np.arange(40) * 0.1
    faint = 1e-3 * rng.normal(size=40)  # a sum of squares far below 1
    other = 1e-3 * rng.normal(size=40)
    expected = np.corrcoef(faint, other)[0, 1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "invalid value" from numpy on a flat curve
        assert np.isnan(ic._correlation(t, np.ones(40), t, other, 0.0))
        assert ic._correlation(t, faint, t, other, 0.0) == pytest.approx(expected, abs=1e-9)


def test_a_poor_match_still_reports_its_correlation():
    t, v, gt = _curves(0.0)
    noise = np.random.default_rng(0).normal(8, 2, len(t))
    est = ic.gt_clock_offset(t, noise, np.ones(len(t), bool), gt)
    assert est.lag_s is None and est.reason.startswith("the speeds agree poorly (correlation ")
    assert isinstance(est.correlation, float) and -1 <= est.correlation < 0.5
    assert f"(correlation {est.correlation:.2f})" in est.reason


@pytest.mark.parametrize("late", [0.535, -1.987, 1.987])
def test_every_resample_refines_its_lag_between_grid_steps(late):
    """Exact speeds shifted by a lag between the 0.01 s steps (next to the search's edges too):
    every resample's peak, refined by the parabola through its neighbours, is the lag."""
    t = np.arange(300) * PERIOD
    lo, hi = ic.lag_interval(t, _speed(t), _speed(t - late))
    assert lo == pytest.approx(late, abs=0.002) and hi == pytest.approx(late, abs=0.002)


def test_a_gt_early_beyond_the_search_ends_on_its_lower_edge():
    t = np.arange(300) * PERIOD
    bump = lambda x: 8 + 3 * np.exp(-((x - 15) / 1.5) ** 2)  # noqa: E731
    lo, hi = ic.lag_interval(t, bump(t), bump(t + 2.3))
    assert lo == pytest.approx(-2.0, abs=1e-6) and hi == pytest.approx(-2.0, abs=1e-6)


def test_the_interval_is_the_central_95_percent_of_the_resampled_lags(monkeypatch):
    """The interval's ends are the 2.5 and 97.5 percentiles of the resamples' lags."""
    asked = []
    percentile = np.percentile

    def spy(values, q, *args, **kwargs):
        asked.append((len(values), list(np.atleast_1d(q))))
        return percentile(values, q, *args, **kwargs)

    monkeypatch.setattr(np, "percentile", spy)
    t = np.arange(200) * PERIOD
    ic.lag_interval(t, _speed(t), _speed(t - 0.3))
    ((count, q),) = asked
    assert count == 200  # every resample found a lag
    np.testing.assert_allclose(q, [2.5, 97.5])
