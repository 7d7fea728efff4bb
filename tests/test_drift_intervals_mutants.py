"""metrics.drift_intervals: known answers for what the mutation run (``tools/mutate.py``) found
untested in the Python callers of the compiled kernels.

A drive along a straight line whose estimate turns every unit step by a constant lateral
offset ``delta`` has one and the same step error at every step: every resample re-chains the
estimate itself, so the interval has zero width at the figure, and without an alignment the
figure is known, ``delta * sqrt(mean k^2) = delta * sqrt((n - 1)(2n - 1) / 6)`` over frames
``k = 0 .. n - 1``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import norm
from scipy.stats import t as student_t

from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from metrics import ape, drift_intervals
from metrics.drift_intervals import (
    Drift,
    _pivot,
    _twists,
    ape_intervals,
    draws_batched,
    drift_block,
    paired_ape_interval,
    step_errors,
)
from metrics.intervals import correlation_length


def _straight(n: int, delta: float) -> tuple[np.ndarray, np.ndarray]:
    gt = np.repeat(np.eye(4)[None], n, axis=0)
    gt[:, 0, 3] = np.arange(n)
    est = gt.copy()
    est[:, 1, 3] = delta * np.arange(n)
    return gt, est


def test_a_constant_step_error_has_its_known_figure_and_an_interval_of_zero_width():
    n, delta = 61, 0.01
    gt, est = _straight(n, delta)
    drift = Drift(gt, est, "none")
    want = delta * math.sqrt((n - 1) * (2 * n - 1) / 6.0)
    assert drift.observed["trans_m"] == pytest.approx(want, rel=1e-12)
    assert drift.observed["rot_deg"] == pytest.approx(0.0, abs=1e-12)
    for block in (None, 10, 30):
        iv = ape_intervals(drift, reps=40, block=block)
        t = iv["trans_m"]
        assert t.low == pytest.approx(want, rel=1e-9) and t.high == pytest.approx(want, rel=1e-9)
        if block is not None:
            assert (t.block_frames, t.n_independent) == (block, (n - 1) // block)
        assert iv["rot_deg"].low == 0.0 and iv["rot_deg"].high == pytest.approx(0.0, abs=1e-9)


def test_a_zero_error_estimate_has_an_interval_of_zero_at_zero():
    """Every resample re-chains the GT itself: draws of 0 (to rounding; the rotation angle of
    a rounded identity is about 1e-8 rad), an interval from 0 to about 0."""
    gt = ground_truth(120)
    for alignment in ("se3", "none"):
        iv = ape_intervals(Drift(gt, gt.copy(), alignment), reps=30, block=12)
        for q, tol in (("trans_m", 1e-9), ("rot_deg", 1e-5)):
            assert iv[q].low == 0.0 and iv[q].high == pytest.approx(0.0, abs=tol)
            assert (iv[q].block_frames, iv[q].n_independent) == (12, 119 // 12)


def test_the_figures_interval_is_the_pivotal_one_widened_by_the_batch_means_factor():
    """``ape_intervals`` against the rule written out with SciPy's quantiles from the batched
    reference draws: the pivotal interval of the draws about X, widened about X by
    ``t_{K-1} / z * sqrt(K / (K - 1))`` for K = n_steps // block whole blocks, stretched to hold
    X and stopped at 0."""
    gt = ground_truth(241)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=4)
    drift = Drift(gt, est)
    block, reps = 48, 60
    k = 240 // block
    iv = ape_intervals(drift, reps=reps, seed=2, block=block)
    ref = draws_batched(Drift(gt, est), block, reps, seed=2)
    factor = student_t.ppf(0.95, k - 1) / norm.ppf(0.95) * math.sqrt(k / (k - 1))
    for q in ("trans_m", "rot_deg"):
        x = drift.observed[q]
        q_lo, q_hi = np.quantile(ref[q], [0.05, 0.95])
        centre = ref[q].mean()
        lo, hi = x - (q_hi - centre), x - (q_lo - centre)
        lo, hi = x - (x - lo) * factor, x + (hi - x) * factor
        lo, hi = max(0.0, min(lo, x)), max(hi, x)
        got = ape_intervals(drift, level=0.9, reps=reps, seed=2, block=block)[q]
        assert (got.low, got.high) == pytest.approx((lo, hi), rel=1e-7), q
        assert got.level == 0.9 and got.n_independent == k and got.block_frames == block
        assert iv[q].high - iv[q].low > got.high - got.low  # 95 % is wider than 90 %


#: 20 values of white noise (seed 140, rounded) whose Politis-White length is 22 (the
#: independent transcription of tests/test_intervals_mutants.py: 21.6; g(0) small but not
#: rounding noise: unchanged by perturbations of 1e-6): a block longer than half the series
LONG_20 = np.array([-1.18, 1.8, -1.18, 2.47, -1.67, 0.43, -0.85, -1.39, -0.84, -2.79, 1.19, 0.5,
                    -0.32, -0.52, 1.65, -1.62, 0.78, -0.21, -0.16, -0.06])


def _chained(gt: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """The estimate whose every step is the true step followed by ``errors[k]``."""
    est = np.empty_like(gt)
    est[0] = gt[0]
    for k in range(len(gt) - 1):
        est[k + 1] = est[k] @ np.linalg.inv(gt[k]) @ gt[k + 1] @ errors[k]
    return est


def test_the_automatic_block_is_block_factor_times_drift_block_at_most_half_the_steps():
    gt = ground_truth(301)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01, correlation=0.9), seed=3)
    drift = Drift(gt, est)
    b = drift_block([drift.errors])
    assert 3 <= b < 100
    iv = ape_intervals(drift, reps=20)["trans_m"]
    assert (iv.block_frames, iv.n_independent) == (math.ceil(1.5 * b), 300 // math.ceil(1.5 * b))
    # 20 steps whose lateral error has a correlation length of 22: a block of 10
    errors = np.repeat(np.eye(4)[None], 20, axis=0)
    errors[:, 1, 3] = 0.01 * LONG_20
    short = Drift(gt[:21], _chained(gt[:21], errors))
    np.testing.assert_allclose(short.errors, errors, atol=1e-9)
    assert correlation_length(LONG_20) > 10 and drift_block([short.errors]) == 10
    short_iv = ape_intervals(short, reps=20)["trans_m"]
    assert (short_iv.block_frames, short_iv.n_independent) == (10, 2)
    # the paired block: drift_block of both, not widened by the factor
    assert paired_ape_interval(drift, Drift(gt, gt.copy()), reps=20).block_frames == b


def test_twists_are_the_sine_of_the_angle_about_the_axis_and_the_translation():
    angles = np.array([0.0, 0.01, -0.2, 1.0])
    for axis in range(3):
        rotvec = np.zeros((4, 3))
        rotvec[:, axis] = angles
        errors = np.repeat(np.eye(4)[None], 4, axis=0)
        errors[:, :3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
        errors[:, :3, 3] = [[1.0, 2.0, 3.0], [-1.0, 0.5, 0.0], [0.0, 0.0, 7.0], [4.0, 5.0, 6.0]]
        want = np.zeros((4, 6))
        want[:, axis] = np.sin(angles)
        want[:, 3:] = errors[:, :3, 3]
        np.testing.assert_allclose(_twists(errors), want, atol=1e-15)


def test_drift_block_is_the_longest_component_correlation_length_at_most_half_the_steps():
    """Rotation about z correlated (AR(1) 0.9), translation in y white: the block is the
    largest correlation length of the six components, computed on the sines and translations;
    of 20 steps at most 10; of two estimates the longer."""
    rng = np.random.default_rng(5)
    n = 400
    yaw = np.zeros(n)
    for k in range(1, n):
        yaw[k] = 0.9 * yaw[k - 1] + rng.normal(0.0, 1e-3)
    errors = np.repeat(np.eye(4)[None], n, axis=0)
    errors[:, :3, :3] = Rotation.from_rotvec(np.outer(yaw, [0.0, 0.0, 1.0])).as_matrix()
    errors[:, 1, 3] = rng.normal(0.0, 0.01, n)
    want = max(correlation_length(np.sin(yaw)), correlation_length(errors[:, 1, 3]))
    assert want > 5
    assert drift_block([errors]) == want
    white = errors.copy()
    white[:, :3, :3] = np.eye(3)
    assert drift_block([white]) == correlation_length(errors[:, 1, 3]) < want
    assert drift_block([white, errors]) == drift_block([errors, white]) == want
    assert drift_block([errors[:20]]) == min(10, max(correlation_length(np.sin(yaw[:20])),
                                                     correlation_length(errors[:20, 1, 3])))
    long = errors[:20].copy()
    long[:, 1, 3] = LONG_20
    assert drift_block([long]) == 10  # of a correlation length of 22 over 20 steps
    assert drift_block([errors[:2]]) == 1  # at least one step


def test_step_errors_are_the_gt_step_inverse_times_the_estimate_step():
    gt = ground_truth(30)
    rng = np.random.default_rng(2)
    errors = np.repeat(np.eye(4)[None], 29, axis=0)
    errors[:, :3, :3] = Rotation.from_rotvec(rng.normal(0.0, 0.05, (29, 3))).as_matrix()
    errors[:, :3, 3] = rng.normal(0.0, 0.1, (29, 3))
    est = np.empty_like(gt)
    est[0] = gt[0]
    for k in range(29):  # the true step followed by the error
        est[k + 1] = est[k] @ np.linalg.inv(gt[k]) @ gt[k + 1] @ errors[k]
    np.testing.assert_allclose(step_errors(gt, est), errors, atol=1e-9)


def test_an_estimate_is_usable_from_three_finite_frames():
    gt, est = _straight(3, 0.01)
    assert Drift(gt, est).usable and not Drift(gt[:2], est[:2]).usable
    bad = est.copy()
    bad[1, 0, 3] = np.nan
    nan = ape_intervals(Drift(gt, bad), reps=10)
    assert np.isnan(nan["trans_m"].low) and nan["rot_deg"].n_independent == 0
    assert np.isnan(paired_ape_interval(Drift(gt, est), Drift(gt, bad), reps=10).low)
    assert np.isnan(paired_ape_interval(Drift(gt, bad), Drift(gt, est), reps=10).low)


def test_only_estimates_of_the_same_gt_and_alignment_are_paired():
    gt, est = _straight(40, 0.01)
    a = Drift(gt, est)
    assert a.same_frames(Drift(gt.copy(), est * 1.0))
    assert not a.same_frames(Drift(gt, est, "sim3"))
    assert not a.same_frames(Drift(gt[:39], est[:39]))
    moved = gt.copy()
    moved[5, 2, 3] = 0.1
    assert not a.same_frames(Drift(moved, est))
    assert np.isfinite(paired_ape_interval(a, Drift(gt, gt.copy()), reps=10, block=5).low)
    assert np.isnan(paired_ape_interval(a, Drift(moved, est), reps=10, block=5).low)


def test_draws_are_cached_per_block_resamples_and_seed():
    gt = ground_truth(101)
    drift = Drift(gt, noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=1))
    base = drift.draws(5, 30, seed=1)["trans_m"].copy()
    for other in (drift.draws(6, 30, seed=1), drift.draws(5, 30, seed=2)):
        assert not np.array_equal(other["trans_m"], base)
    # more resamples: the same first 30 (the generator draws row after row) and one more
    more = drift.draws(5, 31, seed=1)["trans_m"]
    assert len(more) == 31 and np.array_equal(more[:30], base)
    np.testing.assert_array_equal(drift.draws(5, 30, seed=1)["trans_m"], base)


def test_the_draws_do_not_depend_on_the_threads_or_a_block_below_one():
    gt = ground_truth(151)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=8)
    try:
        drift_intervals.set_threads(0)  # at least one thread
        assert drift_intervals._threads == 1
        one = Drift(gt, est).draws(4, 230, seed=5)
        drift_intervals.set_threads(2)
        assert drift_intervals._threads == 2
        two = Drift(gt, est).draws(4, 230, seed=5)
    finally:
        drift_intervals.set_threads(1)
    for q in ("trans_m", "rot_deg"):
        np.testing.assert_array_equal(two[q], one[q])
    zero = Drift(gt, est).draws(0, 20, seed=5)["trans_m"]  # a block of at least one step
    np.testing.assert_array_equal(zero, Drift(gt, est).draws(1, 20, seed=5)["trans_m"])
    np.testing.assert_allclose(zero, draws_batched(Drift(gt, est), 1, 20, seed=5)["trans_m"],
                               rtol=1e-9)


def test_the_pivot_of_draws_skips_non_finite_ones_and_needs_a_finite_figure():
    draws = np.array([1.0, 2.0, 3.0, 4.0, np.nan, np.inf])
    lo_q, hi_q = np.quantile([1.0, 2.0, 3.0, 4.0], [0.1, 0.9])
    assert _pivot(10.0, draws, 0.8) == pytest.approx((10.0 - (hi_q - 2.5), 10.0 - (lo_q - 2.5)))
    assert all(math.isnan(v) for v in _pivot(1.0, np.array([np.nan]), 0.95))
    assert all(math.isnan(v) for v in _pivot(math.nan, draws, 0.95))
    assert all(math.isnan(v) for v in _pivot(math.inf, draws, 0.95))


def test_no_interval_is_nan_at_the_asked_level_with_no_block_and_no_pieces():
    gt, est = _straight(30, 0.01)
    bad = est.copy()
    bad[3, 0, 3] = np.inf
    for iv in (*ape_intervals(Drift(gt, bad), level=0.8, reps=10).values(),
               paired_ape_interval(Drift(gt, est), Drift(gt, bad), level=0.8, reps=10),
               paired_ape_interval(Drift(gt, est), Drift(gt, est, "sim3"), level=0.8,
                                   reps=10)):
        assert math.isnan(iv.low) and math.isnan(iv.high)
        assert (iv.level, iv.block_frames, iv.n_independent) == (0.8, 0, 0)


def test_the_paired_interval_is_the_pivot_of_the_seeded_reference_draws_widened_for_k():
    """The paired APE interval written out: the reference draws (``draws_batched``) of both
    estimates at the asked seed, the pivotal interval of their difference about the observed
    difference, widened by ``t_{K-1} / z`` with K = 300 // 7 = 42 whole blocks (an int)."""
    gt = ground_truth(301)
    a = Drift(gt, noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=5))
    b = Drift(gt, noisy_estimate(gt, NoiseModel(0.1, 0.02), seed=6))
    block, reps, seed = 7, 60, 3
    diff = a.observed["trans_m"] - b.observed["trans_m"]
    d = (draws_batched(a, block, reps, seed)["trans_m"]
         - draws_batched(b, block, reps, seed)["trans_m"])
    q_lo, q_hi = np.quantile(d, [0.05, 0.95])
    lo, hi = diff - (q_hi - d.mean()), diff - (q_lo - d.mean())
    k = 300 // block
    f = student_t.ppf(0.95, k - 1) / norm.ppf(0.95)
    iv = paired_ape_interval(a, b, "trans_m", level=0.9, reps=reps, seed=seed, block=block)
    assert (iv.low, iv.high) == pytest.approx((diff - (diff - lo) * f, diff + (hi - diff) * f),
                                              rel=1e-7)
    assert (iv.level, iv.block_frames, iv.n_independent) == (0.9, block, k)
    assert type(iv.n_independent) is int


def test_every_draw_defaults_to_seed_zero():
    gt = ground_truth(81)
    drift = Drift(gt, noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=2))
    zero, one = draws_batched(drift, 4, 20, seed=0), draws_batched(drift, 4, 20, seed=1)
    assert not np.allclose(zero["trans_m"], one["trans_m"])
    np.testing.assert_array_equal(draws_batched(drift, 4, 20)["trans_m"], zero["trans_m"])
    assert ape_intervals(drift, reps=20, block=4) == ape_intervals(drift, reps=20, block=4,
                                                                   seed=0)
    assert ape_intervals(drift, reps=20, block=4) != ape_intervals(drift, reps=20, block=4,
                                                                   seed=1)


def test_uncorrelated_or_constant_step_errors_have_blocks_of_one_step():
    """Exactly constant step errors: every component's correlation length is 1, so the block
    is 1 step (``ape_intervals``: ceil(1.5) = 2); three frames (two steps) have blocks of one
    step and two pieces, an interval."""
    e = np.eye(4)
    e[1, 3] = 0.01
    assert drift_block([np.repeat(e[None], 50, axis=0)]) == 1
    gt, est = _straight(3, 0.01)
    iv = ape_intervals(Drift(gt, est, "none"), reps=10)["trans_m"]
    assert (iv.block_frames, iv.n_independent) == (1, 2) and np.isfinite(iv.low)


def _moved() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A drive, a noisy estimate of it and the same estimate in another frame (rotated and
    shifted: its first pose is not the GT's)."""
    gt = ground_truth(60)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=3)
    t = np.eye(4)
    t[:3, :3] = Rotation.from_rotvec([0.1, -0.2, 0.7]).as_matrix()
    t[:3, 3] = [5.0, -3.0, 1.0]
    return gt, est, t @ est


def test_the_origin_alignment_moves_the_first_pose_onto_the_gts():
    """``origin``: ``G_0 inv(P_0)`` applied to the estimate. The GT itself seen in another frame
    has no error; a moved noisy estimate has metrics.ape's (evo's) origin-aligned APE, and
    its draws are the batched reference's."""
    gt, est, moved = _moved()
    t = moved[0] @ np.linalg.inv(est[0])
    exact = Drift(gt, t @ gt, "origin").observed
    assert exact["trans_m"] == pytest.approx(0.0, abs=1e-9)
    assert exact["rot_deg"] == pytest.approx(0.0, abs=1e-5)
    reference = ape(gt, moved, "origin")
    drift = Drift(gt, moved, "origin")
    assert drift.observed["trans_m"] == pytest.approx(reference.trans_rmse_m, rel=1e-9)
    assert drift.observed["rot_deg"] == pytest.approx(reference.rot_rmse_deg, rel=1e-7)
    assert drift.observed["trans_m"] == pytest.approx(Drift(gt, est, "origin").observed["trans_m"],
                                                      rel=1e-9)
    new, old = drift.draws(5, 20, seed=1), draws_batched(drift, 5, 20, seed=1)
    for q in ("trans_m", "rot_deg"):
        np.testing.assert_allclose(new[q], old[q], rtol=1e-9, atol=1e-11)


def test_three_poses_not_on_a_line_fix_the_fit_as_in_metrics_ape():
    """An alignment fitted on the first 3 poses: three positions not on one line fix it (the
    Umeyama fit, metrics.ape's ``se3-first-3``); fewer than three would not."""
    n = 40
    gt = np.repeat(np.eye(4)[None], n, axis=0)
    angle = 0.3 * np.arange(n)
    gt[:, :3, :3] = Rotation.from_rotvec(np.outer(angle, [0.0, 0.0, 1.0])).as_matrix()
    gt[:, :3, 3] = np.stack([5 * np.cos(angle), 5 * np.sin(angle), 0.1 * np.arange(n)], axis=1)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=4)
    for alignment in ("se3-first-3", "sim3-first-3"):
        reference = ape(gt, est, alignment)
        assert reference.alignment == alignment  # not the orientation fallback
        observed = Drift(gt, est, alignment).observed
        assert observed["trans_m"] == pytest.approx(reference.trans_rmse_m, rel=1e-9)
        assert observed["rot_deg"] == pytest.approx(reference.rot_rmse_deg, rel=1e-7)
