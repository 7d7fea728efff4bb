"""APE intervals from resampled frame-to-frame errors (metrics.drift_intervals): the batched
alignment against evo's APE, the re-chaining against the estimate itself, known answers, and
the coverage of the long-run mean on synthetic drives where blocks of per-frame APE errors
fail."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from metrics import ape
from metrics.drift_intervals import (
    Drift,
    _chain_kernel,
    ape_intervals,
    drift_block,
    paired_ape_interval,
    step_errors,
)
from metrics.intervals import unit_intervals
from metrics.relative import inverse_se3
from metrics.units import ape_units


@pytest.mark.parametrize("alignment", ["se3", "sim3", "origin", "none", "se3-first-40",
                                       "sim3-first-40"])
def test_the_batched_rmse_is_evos_ape(alignment):
    gt = ground_truth(300)
    est = noisy_estimate(gt, NoiseModel(0.1, 0.02), seed=3)
    est[:, :3, 3] *= 1.05  # a scale error: Sim(3) differs from SE(3)
    reference = ape(gt, est, alignment)  # evo's Umeyama and APE
    observed = Drift(gt, est, alignment).observed
    assert observed["trans_m"] == pytest.approx(reference.trans_rmse_m, rel=1e-9)
    assert observed["rot_deg"] == pytest.approx(reference.rot_rmse_deg, rel=1e-7)


def test_an_estimate_that_never_moves_is_aligned_by_its_orientations_as_metrics_ape():
    gt = ground_truth(100)
    est = np.repeat(np.eye(4)[None], len(gt), axis=0)
    reference = ape(gt, est, "se3")
    assert reference.alignment == "se3-orientation"
    observed = Drift(gt, est, "se3").observed
    assert observed["trans_m"] == pytest.approx(reference.trans_rmse_m, rel=1e-9)
    assert observed["rot_deg"] == pytest.approx(reference.rot_rmse_deg, rel=1e-7)


def test_chaining_the_step_errors_in_order_rebuilds_the_estimate():
    gt = ground_truth(200)
    est = noisy_estimate(gt, NoiseModel(0.2, 0.05), seed=4)
    n = len(gt)
    idx = np.arange(n - 1)[None]
    pos, rel = np.empty((1, n, 3)), np.empty((1, n, 3, 3))
    _chain_kernel(est[0], inverse_se3(gt[:-1]) @ gt[1:], np.ascontiguousarray(gt[:, :3, :3]),
                  step_errors(gt, est), idx, pos, rel)
    np.testing.assert_allclose(pos[0], est[:, :3, 3], atol=1e-9)
    np.testing.assert_allclose(rel[0], est[:, :3, :3] @ np.swapaxes(gt[:, :3, :3], 1, 2),
                               atol=1e-12)


def test_a_perfect_estimate_has_a_zero_interval_and_equal_estimates_no_difference():
    gt = ground_truth(300)
    exact = Drift(gt, gt.copy())
    iv = ape_intervals(exact, reps=100)
    assert iv["trans_m"].low == 0.0 and iv["trans_m"].high == pytest.approx(0.0, abs=1e-9)
    est = noisy_estimate(gt, NoiseModel(), seed=1)
    same = paired_ape_interval(Drift(gt, est), Drift(gt, est.copy()), reps=100)
    assert not same.excludes_zero and same.high == pytest.approx(0.0, abs=1e-12)


def test_a_three_times_noisier_estimate_of_the_same_drive_is_significantly_worse():
    gt = ground_truth(1000)
    a = Drift(gt, noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=5))
    b = Drift(gt, noisy_estimate(gt, NoiseModel(0.15, 0.03), seed=5))  # the same draws x 3
    diff = paired_ape_interval(b, a, "trans_m", reps=300)
    assert diff.low > 0.0
    reverse = paired_ape_interval(a, b, "trans_m", reps=300)
    assert reverse.high < 0.0
    # scored on other frames: no paired comparison
    other = Drift(gt[:-1], b.est[:-1])
    assert np.isnan(paired_ape_interval(a, other, reps=50).low)


def test_correlated_step_errors_get_longer_blocks():
    gt = ground_truth(1500)
    rng = np.random.default_rng(0)
    white = noisy_estimate(gt, NoiseModel(), seed=2)
    # AR(1) (lag-one correlation 0.95) rotation errors about the vertical axis
    yaw = np.zeros(len(gt) - 1)
    for k in range(1, yaw.size):
        yaw[k] = 0.95 * yaw[k - 1] + rng.normal(0.0, 0.001)
    steps = inverse_se3(gt[:-1]) @ gt[1:]
    c, s = np.cos(yaw), np.sin(yaw)
    noise = np.repeat(np.eye(4)[None], yaw.size, axis=0)
    noise[:, 0, 0], noise[:, 0, 1], noise[:, 1, 0], noise[:, 1, 1] = c, -s, s, c
    correlated = np.empty_like(gt)
    correlated[0] = gt[0]
    for k, step in enumerate(steps @ noise):
        correlated[k + 1] = correlated[k] @ step
    assert drift_block([step_errors(gt, white)]) <= 3
    assert drift_block([step_errors(gt, correlated)]) >= 10


def test_a_sequence_of_two_frames_has_no_interval():
    gt = ground_truth(2)
    iv = ape_intervals(Drift(gt, gt.copy()))
    assert np.isnan(iv["trans_m"].low) and iv["trans_m"].n_independent == 0


def test_ape_intervals_cover_the_long_run_mean_where_blocks_of_frame_errors_do_not():
    """60 synthetic 300 m drives with known noise: the step-error intervals contain the mean
    APE RMSE over 120 more drives about 95 % of the time (measured with 200 / 400 trials of
    750 m: 94-95 %, bench.studies.coverage); blocks of per-frame APE errors (the previous
    rule: 4 blocks, the plain percentile interval) cover it in well under 70 %."""
    gt = ground_truth(600)
    noise = NoiseModel()
    truth = np.mean([ape(gt, noisy_estimate(gt, noise, 5000 + s)).trans_rmse_m
                     for s in range(120)])
    hits, frame_blocks = [], []
    for s in range(60):
        est = noisy_estimate(gt, noise, 6000 + s)
        iv = ape_intervals(Drift(gt, est), reps=300)["trans_m"]
        hits.append(iv.low <= truth <= iv.high)
        units = ape_units(gt, est)
        old = unit_intervals(len(gt), units.anchor, units.end,
                             {"trans_m": units.values["trans_m"]}, rmse=True, reps=300,
                             block=len(gt) // 4, small_sample=False)
        frame_blocks.append(old["trans_m"].low <= truth <= old["trans_m"].high)
    assert np.mean(hits) >= 0.85
    assert np.mean(frame_blocks) < 0.7


def test_a_mirrored_estimate_is_aligned_by_a_rotation_not_a_reflection_as_evo():
    gt = ground_truth(200)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=8)
    est[:, 1, 3] *= -1.0  # positions mirrored: the best orthogonal map would be a reflection
    est[:, 2, 3] += np.linspace(0.0, 1.0, len(est))  # and not planar
    reference = ape(gt, est, "se3")
    observed = Drift(gt, est, "se3").observed
    assert observed["trans_m"] == pytest.approx(reference.trans_rmse_m, rel=1e-9)
    assert observed["rot_deg"] == pytest.approx(reference.rot_rmse_deg, rel=1e-7)


def test_fewer_than_two_whole_blocks_give_no_interval_and_pairs_are_widened_for_them():
    from scipy.stats import norm
    from scipy.stats import t as student_t

    from metrics.drift_intervals import _pivot

    gt = ground_truth(401)
    a = Drift(gt, noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=5))
    b = Drift(gt, noisy_estimate(gt, NoiseModel(0.15, 0.03), seed=5))
    assert np.isnan(ape_intervals(a, reps=100, block=400)["trans_m"].low)  # one block
    two = ape_intervals(a, reps=100, block=200)["trans_m"]
    assert two.n_independent == 2 and np.isfinite(two.low)
    # two blocks: the paired interval is the pivotal one widened by t_1 / z about the difference
    diff = b.observed["trans_m"] - a.observed["trans_m"]
    lo, hi = _pivot(diff, b.draws(200, 100)["trans_m"] - a.draws(200, 100)["trans_m"], 0.95)
    paired = paired_ape_interval(b, a, "trans_m", reps=100, block=200)
    factor = student_t.ppf(0.975, 1) / norm.ppf(0.975)
    assert paired.high - diff == pytest.approx((hi - diff) * factor, rel=1e-9)
    assert diff - paired.low == pytest.approx((diff - lo) * factor, rel=1e-9)


def test_estimates_aligned_differently_are_not_paired():
    gt = ground_truth(300)
    est = noisy_estimate(gt, NoiseModel(), seed=1)
    assert np.isnan(paired_ape_interval(Drift(gt, est, "se3"), Drift(gt, est, "sim3"),
                                        reps=50).low)


@pytest.mark.parametrize("alignment", ["se3", "sim3", "origin", "none", "first-40",
                                       "sim3-first-30"])
def test_the_one_path_kernel_draws_what_the_batched_paths_draw(alignment):
    """Drift.draws (one resample's path at a time, compiled, the fit's sums accumulated while
    chaining) against draws_batched (every resample's path materialised, aligned by
    ape_rmse_batch): the same draws, equal to rounding, for every alignment, on a drive with
    correlated step noise and a block that cuts the last one."""
    from metrics.drift_intervals import draws_batched

    gt = ground_truth(701)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01, correlation=0.6), seed=12)
    drift = Drift(gt, est, alignment)
    new = drift.draws(23, 120, seed=3)
    old = draws_batched(drift, 23, 120, seed=3)
    for q in ("trans_m", "rot_deg"):
        np.testing.assert_allclose(new[q], old[q], rtol=1e-9, atol=1e-11)
        assert np.std(new[q]) > 0  # draws that differ (not one path repeated)


def test_a_degenerate_resample_falls_back_to_the_orientation_alignment():
    """Positions on one line do not fix an SE(3) alignment: the kernel aligns each such
    resample by its orientations, as metrics.ape.align does (the batched reference)."""
    from metrics.drift_intervals import draws_batched

    gt = np.repeat(np.eye(4)[None], 120, axis=0)
    gt[:, 0, 3] = 0.5 * np.arange(120)
    est = gt.copy()
    est[:, 0, 3] *= 1.01  # the same line, stretched: every resample is on one line
    drift = Drift(gt, est, "se3")
    new, old = drift.draws(10, 20, 1), draws_batched(drift, 10, 20, 1)
    for q in ("trans_m", "rot_deg"):
        assert np.all(np.isfinite(new[q]))
        np.testing.assert_allclose(new[q], old[q], rtol=1e-9, atol=1e-11)


def test_the_draws_memory_is_one_path_whatever_the_number_of_resamples():
    """Drift.draws keeps one path (n x 12 floats), a chunk of block starts and the draws
    (reps x 2), never reps x n: the peak of its allocations (numpy reports them to
    tracemalloc) at 2000 poses grows by little more than the draws themselves from 50 to 800
    resamples, and stays well below one materialised chunk of paths."""
    import tracemalloc

    gt = ground_truth(2000)
    drift = Drift(gt, noisy_estimate(gt, NoiseModel(), seed=2))
    assert len(drift.errors) == 1999  # computed once, outside the measurement
    drift.draws(7, 5, seed=9)  # compiled outside the measurement
    peaks = {}
    for reps in (50, 800):
        tracemalloc.start()
        drift.draws(7, reps, seed=reps)
        peaks[reps] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    from metrics.intervals import CHUNK

    path = 2000 * 12 * 8
    starts_chunk = CHUNK * (-(-1999 // 7)) * 8  # one chunk of block starts (int64)
    # the draws (2 x 800 floats), a chunk of starts, 100 kB of slack; reps x n would be 12 MB
    assert peaks[800] - peaks[50] < 800 * 2 * 8 + starts_chunk + 100_000
    assert peaks[800] < 6 * path  # a chunk of 32 paths would be 32 x path


def test_the_block_follows_a_correlated_translation_error_too():
    """Step errors whose translation is correlated from step to step (an AR(1) of 0.95 in x)
    and whose rotation is white: the block is the translation's correlation length, long; a
    block taken from the rotation components only would be a few steps."""
    from metrics.drift_intervals import drift_block

    rng = np.random.default_rng(8)
    n = 2000
    errors = np.repeat(np.eye(4)[None], n, axis=0)
    angles = rng.normal(0.0, 1e-4, (n, 3))
    errors[:, :3, :3] = Rotation.from_rotvec(angles).as_matrix()
    x = np.zeros(n)
    for k in range(1, n):
        x[k] = 0.95 * x[k - 1] + rng.normal(0.0, 0.01)
    errors[:, 0, 3] = x
    white = errors.copy()
    white[:, 0, 3] = rng.normal(0.0, 0.01, n)
    assert drift_block([white]) < 8
    assert drift_block([errors]) > 30


def test_the_ape_interval_reflects_the_draws_about_the_figure():
    """The pivotal interval [X - (q_hi - m*), X - (q_lo - m*)]: with draws skewed to the right
    (a long upper tail) the interval reaches further below X than above it; shifting the
    percentiles to X instead would do the opposite."""
    from metrics.drift_intervals import _pivot

    draws = np.random.default_rng(3).exponential(1.0, 20000) + 1.0
    lo_q, hi_q = np.quantile(draws, [0.025, 0.975])
    mean = draws.mean()
    low, high = _pivot(2.0, draws, 0.95)
    assert low == pytest.approx(2.0 - (hi_q - mean)) and high == pytest.approx(2.0 - (lo_q - mean))
    assert 2.0 - low > high - 2.0  # the long upper tail of the draws goes below X


def test_the_kernels_squared_angle_is_arccos_squared_at_every_angle():
    """The series the draw kernel uses for small angles (metrics.drift_intervals._angle_sq)
    equals arccos(cos)^2 to rounding from 0 to 180 deg, on both sides of where it hands over
    to arccos (20 deg), and clips a cosine rounded beyond +-1."""
    from metrics.drift_intervals import _SERIES_X, _angle_sq

    edge = np.arccos(1.0 - 2.0 * _SERIES_X)
    angles = np.concatenate([np.geomspace(1e-9, np.pi, 400), edge + np.linspace(-1e-6, 1e-6, 9),
                             [0.0, np.pi]])
    got = np.array([_angle_sq(np.cos(a)) for a in angles])
    want = np.arccos(np.cos(angles)) ** 2
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-300)
    assert _angle_sq(1.0 + 1e-12) == 0.0 and _angle_sq(-1.0 - 1e-12) == pytest.approx(np.pi**2)
