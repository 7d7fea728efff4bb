"""bench calibrate's Doppler estimate: the fit solves for the reported angles, and its stated
95 % intervals (circular block bootstrap, outlier cut redone per resample) are honest."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from bench.data.calibration.estimate import (
    ANGLES,
    FrameCues,
    calibrate_cues,
    euler_matrix,
    fit_angles,
    kabsch,
)

PERIOD_S = 1 / 12


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _ar1(rng, n: int, phi: float, sd: float) -> np.ndarray:
    """(n, 3) AR(1) series with lag-one correlation ``phi`` and stationary sd ``sd``."""
    e = np.empty((n, 3))
    e[0] = rng.normal(0, sd, 3)
    for k in range(1, n):
        e[k] = phi * e[k - 1] + rng.normal(0, sd * np.sqrt(1 - phi**2), 3)
    return e


def simulated_cues(rng, truth_deg: dict[str, float], n: int = 120, phi: float = 0.8,
                   sd_deg: float = 0.3, road_sd_deg: float = 0.5, outliers: float = 0.05
                   ) -> FrameCues:
    """A drive of ``n`` frames with a known R_gt_sensor: GT velocity directions (GT frame) near
    forward with a slowly varying slip and climb, the vehicle's up (GT frame) rolling and
    pitching slowly; the sensor sees them rotated by R^T and perturbed by AR(1) rotation errors
    (``sd_deg``, lag-one correlation ``phi``; roads ``road_sd_deg``) and ``outliers`` of the
    velocity frames 4-8 deg off. Frame 7 has no velocity (slow), frame 11 no road."""
    R = euler_matrix(np.radians([truth_deg[a] for a in ANGLES]))
    t = np.arange(n) * PERIOD_S
    slip = 0.02 * np.sin(2 * np.pi * t / 4 + rng.uniform(0, 6))
    climb = 0.02 * np.sin(2 * np.pi * t / 6 + rng.uniform(0, 6))
    b = _unit(np.column_stack([np.cos(slip), np.sin(slip), np.sin(climb)]))
    err = np.radians(_ar1(rng, n, phi, sd_deg))
    bad = rng.random(n) < outliers
    off = np.radians(rng.uniform(4, 8, (bad.sum(), 1)))
    err[bad] += _unit(rng.normal(size=(bad.sum(), 3))) * off
    a = np.einsum("nij,nj->ni", Rotation.from_rotvec(err).as_matrix(), b @ R)
    tilt = np.radians(0.8) * np.column_stack([np.sin(2 * np.pi * t / 9),
                                              np.sin(2 * np.pi * t / 5), np.zeros(n)])
    ups = Rotation.from_rotvec(tilt).apply([0.0, 0.0, 1.0])
    road_err = np.radians(_ar1(rng, n, phi, road_sd_deg))
    normals = np.einsum("nij,nj->ni", Rotation.from_rotvec(road_err).as_matrix(), ups @ R)
    vel, road = np.setdiff1d(np.arange(n), [7]), np.setdiff1d(np.arange(n), [11])
    return FrameCues(n, PERIOD_S, vel, a[vel], b[vel], road, normals[road], ups[road],
                     np.full(len(road), 0.8))


TRUTH = {"roll": 1.5, "pitch": 1.0, "yaw": -0.5}


def test_fit_angles_agrees_with_an_independent_minimiser():
    """Each cue at its best for its own angles, the other's held: checked against scipy's
    minimiser of each cue's own cost at the solution, and against Kabsch with all angles
    free."""
    rng = np.random.default_rng(5)
    R = euler_matrix(np.radians([4.0, -7.0, 12.0]))
    a = _unit(rng.normal(size=(40, 3)) + [3.0, 0.0, 0.0])
    b = _unit(a @ R.T + rng.normal(0, 0.01, (40, 3)))
    n = _unit(rng.normal(size=(30, 3)) * [0.1, 0.1, 1.0] + [0, 0, 1.0])
    up = _unit(n @ R.T + rng.normal(0, 0.01, (30, 3)))
    np.testing.assert_allclose(euler_matrix(fit_angles([(a.T @ b, np.ones(3, bool))])),
                               kabsch(a, b), atol=1e-9)
    vel, road = np.array([False, True, True]), np.array([True, False, False])
    ang = fit_angles([(a.T @ b, vel), (n.T @ up, road)])

    def cost(x, src, dst, free):
        th = ang.copy()
        th[free] = x
        return np.sum((dst - src @ euler_matrix(th).T) ** 2)

    for src, dst, free in ((a, b, vel), (n, up, road)):
        best = minimize(cost, ang[free] + 0.01, args=(src, dst, free), method="Nelder-Mead",
                        options={"xatol": 1e-10, "fatol": 1e-14, "maxiter": 4000}).x
        np.testing.assert_allclose(ang[free], best, atol=1e-7)
    # the angles differ from a plain composition: each cue's fit holds the other's angles
    assert np.degrees(np.abs(ang - np.radians([4.0, -7.0, 12.0]))).max() < 1.0


def test_noise_free_cues_give_the_mounting_rotation_exactly():
    """Roll from the road, pitch and yaw from the velocity, with a large roll: exact to 1e-6
    deg (a road rotation composed after the velocity fit was off by the product of roll and the
    velocity's tilt: 0.07 deg here)."""
    truth = {"roll": -4.0, "pitch": 1.0, "yaw": -0.7}
    cues = simulated_cues(np.random.default_rng(1), truth, sd_deg=0.0, road_sd_deg=0.0,
                          outliers=0.0)
    cal = calibrate_cues(cues, bootstrap=20)
    assert cal.source == {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}
    for ax in ANGLES:
        assert cal.angles_deg[ax] == pytest.approx(truth[ax], abs=1e-6), ax


def _coverage(reps: int, block_frames: int | None) -> tuple[np.ndarray, list[int]]:
    hits, blocks = [], []
    for rep in range(reps):
        cues = simulated_cues(np.random.default_rng(rep), TRUTH)
        cal = calibrate_cues(cues, bootstrap=100, seed=rep, block_frames=block_frames)
        assert cal.source == {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}
        blocks.append(cal.block.frames)
        hits.append([cal.interval_deg[a][0] <= TRUTH[a] <= cal.interval_deg[a][1]
                     for a in ANGLES])
    return np.array(hits), blocks


def test_stated_95_percent_intervals_cover_the_truth_on_correlated_frames():
    """60 simulated drives of 120 frames (10 s) with AR(1) per-frame errors (lag-one
    correlation 0.8, about 9 frames of integrated correlation) and 5 % outlier frames: the
    stated 95 % intervals cover the known rotation in 93-99 % of the 180 angle checks
    (binomial sd 1.6 %); the same resampling with single frames (the old bootstrap) covers
    about half."""
    hits, blocks = _coverage(60, None)
    assert 16 <= np.median(blocks) <= 40  # twice the Politis-White length of the residuals
    assert 0.9 <= hits.mean() <= 0.995, hits.mean(axis=0)
    assert hits.mean(axis=0).min() >= 0.85, hits.mean(axis=0)
    iid, _ = _coverage(30, 1)
    assert iid.mean() < 0.75, iid.mean(axis=0)


SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "ntu4dradlm-loop1.h5"


def _plain_pitch_deg(a: np.ndarray, b: np.ndarray) -> float:
    """An independent pitch estimate: the mean difference of the elevation angles of the
    Doppler and GT velocity directions (for b = Ry(p) a and a near forward, b_z = -sin p)."""
    return float(np.degrees(np.mean(np.arcsin(a[:, 2]) - np.arcsin(b[:, 2]))))


def test_the_real_sample_prints_pitch_with_an_interval_holding_a_plain_fit():
    """The vendored real sample, all 250 frames and each half: pitch and yaw come from the
    Doppler velocity with intervals of positive width, and the pitch interval holds the plain
    elevation-difference estimate of the same frames (about -2.27 / -2.57 / -1.97 deg)."""
    from bench.data.calibration.estimate import collect_cues
    from loaders.scan import FrameRange
    from loaders.store import StoreSequence

    assert SAMPLE.exists(), f"{SAMPLE} is missing (the vendored real sample)"
    seq = StoreSequence(SAMPLE)
    try:
        cues = [collect_cues(FrameRange(seq, first, n)) for first, n in
                ((0, 250), (0, 125), (125, 125))]
    finally:
        seq.close()
    for c in cues:
        cal = calibrate_cues(c, bootstrap=100)
        assert cal.source == {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}
        plain = _plain_pitch_deg(c.a, c.b)
        lo, hi = cal.interval_deg["pitch"]
        assert lo < plain < hi, (plain, lo, hi)
        assert -3.0 < cal.angles_deg["pitch"] < -1.5
        for ax in ANGLES:
            lo, hi = cal.interval_deg[ax]
            assert lo < cal.angles_deg[ax] < hi and hi - lo > 0.05, ax
            assert hi - cal.angles_deg[ax] >= 1.96 * cal.std_deg[ax]


def test_an_angle_known_loosely_keeps_its_estimate_and_wide_interval():
    """An angle the velocity directions fix geometrically is never dropped for a large
    bootstrap sd (that printed "+0.000 95 % [+0.000, +0.000] sd 0.000 (not observable)"): with
    the sd bound below every sd, pitch and yaw keep their estimates and intervals; on a drive
    whose errors wander (lag-one correlation 0.99) the blocks leave about one degree of
    freedom, the intervals are wide, and the output says why."""
    from bench.data.calibration.calibrate import format_result

    cues = simulated_cues(np.random.default_rng(3), TRUTH)
    cal = calibrate_cues(cues, bootstrap=50, max_std_deg=1e-6)
    assert cal.source == {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}
    for ax in ("pitch", "yaw"):
        assert cal.angles_deg[ax] == pytest.approx(TRUTH[ax], abs=0.3)
    wander = simulated_cues(np.random.default_rng(2), TRUTH, phi=0.99, sd_deg=3.0,
                            outliers=0.0)
    loose = calibrate_cues(wander, bootstrap=50)
    assert loose.source["pitch"] == "velocity"
    lo, hi = loose.interval_deg["pitch"]
    assert hi - lo > 2.0 and lo < loose.angles_deg["pitch"] < hi
    assert loose.block.dof(loose.frames_total) < 2
    text = "\n".join(format_result(loose))
    assert "few blocks: the " in text and "it does not mean an angle is unobservable" in text
    assert "[+0.000, +0.000]" not in text and "not observable" not in text


def test_printed_lines_never_show_a_zero_width_interval_or_a_number_for_an_unseen_angle():
    """The angle lines: an angle not observable prints its reason and no estimate; an interval
    below the printed resolution says so instead of "[x, x]"; a missing interval says so."""
    import re

    from bench.data.calibration.calibrate import _angle_line

    unseen = _angle_line("roll", 0.0, (0.0, 0.0), 0.0, 0.95, "not observable", "no road")
    assert unseen == "  roll  not observable: no road"
    exact = _angle_line("pitch", 2.0, (2.0 - 1e-9, 2.0 + 1e-9), 1e-10, 0.95, "velocity")
    assert "narrower than 0.001 deg" in exact and "[" not in exact
    none = _angle_line("yaw", -1.5, (np.nan, np.nan), np.nan, 0.95, "velocity", resamples=1)
    assert "no interval" in none and "nan" not in none
    wide = _angle_line("pitch", -1.65, (-4.2, 0.9), 1.1, 0.95, "velocity")
    lo, hi = map(float, re.search(r"\[([-+.\d]+), ([-+.\d]+)\]", wide).groups())
    assert (lo, hi) == (-4.2, 0.9) and "-1.650 deg" in wide


def test_block_choice_floor_cap_and_description():
    from bench.data.calibration.bootstrap import choose_block

    white = np.random.default_rng(0).normal(size=100)
    free = choose_block(100, 0.1, [white], floor_frames=3)
    assert free.frames == free.wanted >= 3 and not free.capped
    smooth = _ar1(np.random.default_rng(1), 100, 0.9, 1.0)[:, 0]  # correlated over ~19 frames
    assert choose_block(100, 0.1, [white, smooth]).frames > 2 * free.frames
    capped = choose_block(100, 0.1, [white], floor_frames=70)
    assert (capped.frames, capped.wanted, capped.capped) == (50, 70, True)
    assert capped.seconds == pytest.approx(5.0) and capped.dof(100) == pytest.approx(1.0)
    text = capped.describe(200, 100)
    assert "block 50 frames (5.0 s)" in text and "asked for 70 frames" in text
    assert "1.0 degrees of freedom" in text


def test_t_interval_of_a_block_bootstrapped_mean():
    """bootstrap_angles on a plain mean, against the same draws counted by
    metrics.intervals.block_counts: sd of the weighted means, and the half-width t(k - 1) * sd *
    sqrt(n / (n - b)) with k = n / b blocks."""
    from scipy.stats import t as student_t

    from bench.data.calibration.bootstrap import BlockChoice, bootstrap_angles
    from metrics.intervals import block_counts

    x = np.cumsum(np.random.default_rng(2).normal(size=90)) * 0.1
    block = BlockChoice(15, 1.5, 15, ())
    spread = bootstrap_angles(90, block, 300, 7, lambda idx: np.array([x[idx].mean(), 0, 0]),
                              np.array([x.mean(), 0.0, 0.0]))
    means = block_counts(90, 15, 300, 7) @ x / 90
    assert spread.sd_deg[0] == pytest.approx(means.std(ddof=1), rel=1e-9)
    half = student_t.ppf(0.975, 90 / 15 - 1) * means.std(ddof=1) * np.sqrt(90 / 75)
    assert spread.low_deg[0] == pytest.approx(x.mean() - half, rel=1e-9)
    assert spread.high_deg[0] == pytest.approx(x.mean() + half, rel=1e-9)
    assert spread.resamples == 300 and spread.sd_deg[1] == 0.0


def test_residual_series_are_ordered_by_frame_whatever_the_row_order():
    """Rows given out of frame order: each residual series is in frame order (the correlation
    length is of the series along the drive). fitted = x, target = x turned by a_i about z:
    the residual on z is sin(a_i)."""
    from bench.data.calibration.bootstrap import residual_series

    frames = np.array([3, 0, 4, 1, 2])
    angles = 0.01 * (frames + 1.0)
    fitted = np.tile([1.0, 0.0, 0.0], (5, 1))
    target = np.stack([np.cos(angles), np.sin(angles), np.zeros(5)], axis=1)
    (z,) = residual_series(fitted, target, np.array([False, False, True]), frames)
    np.testing.assert_allclose(z, np.sin(0.01 * np.arange(1, 6)), rtol=1e-12)


def test_resamples_that_cannot_be_fitted_give_no_interval_quietly():
    import warnings

    from bench.data.calibration.bootstrap import BlockChoice, bootstrap_angles

    calls = []

    def fit(idx):  # only the first resample can be fitted
        calls.append(1)
        return np.zeros(3) if len(calls) == 1 else None

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        spread = bootstrap_angles(40, BlockChoice(5, 0.5, 5, ()), 20, 0, fit, np.zeros(3))
    assert spread.resamples == 1
    assert np.isnan(spread.sd_deg).all() and np.isnan(spread.low_deg).all()
