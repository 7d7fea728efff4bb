"""The block bootstrap of the calibration estimates (bench.data.calibration.bootstrap): the
block length rule (floor, twice the Politis-White length, cap at half the frames), its degrees
of freedom and description, the t interval ``estimate +- t(k - 1) * sd * sqrt(n / (n - b))``
recomputed here from its definition, and the residual series."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import t as student_t

from bench.data.calibration.bootstrap import (
    BLOCKS_PER_CORRELATION,
    LEVEL,
    BlockChoice,
    bootstrap_angles,
    choose_block,
    residual_series,
)
from metrics.intervals import block_indices, correlation_length


def test_degrees_of_freedom_are_blocks_minus_one_at_least_one():
    b = BlockChoice(40, 3.2, 40, (20,))
    assert b.dof(120) == 2.0
    assert b.dof(100) == pytest.approx(1.5)
    assert b.dof(60) == 1.0  # 1.5 blocks: floored at 1
    assert b.dof(80) == 1.0  # exactly 2 blocks: 1
    assert not b.capped and BlockChoice(40, 3.2, 41, ()).capped


def test_the_description_names_block_resamples_refit_and_dof():
    b = BlockChoice(40, 3.2, 40, (20,))
    assert b.describe(50, 120, "each refitted with its cut") == (
        "circular block bootstrap, block 40 frames (3.2 s), 50 resamples, each refitted with "
        "its cut; intervals estimate +- t * sd with 2.0 degrees of freedom")
    assert b.describe(50, 120).split(", ")[3].startswith("each refitted;")
    capped = BlockChoice(40, 3.2, 90, (45,))
    assert capped.describe(50, 80).endswith(
        "with 1.0 degrees of freedom; the rule asked for 90 frames, more than half of them: "
        "too few blocks, even this interval may be too narrow")


def _ar1(n, phi, seed):
    rng = np.random.default_rng(seed)
    x = np.zeros(n)
    e = rng.normal(size=n)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + e[k]
    return x


def test_the_block_is_twice_the_longest_correlation_length_capped_at_half():
    """Three residual series (white, AR(1) 0.5 and 0.9): the block is BLOCKS_PER_CORRELATION
    (2) times the longest Politis-White length (metrics.intervals, computed here); empty
    series are ignored; a larger floor wins; at most n // 2 frames; seconds = frames x
    period."""
    assert BLOCKS_PER_CORRELATION == 2
    series = [np.random.default_rng(0).normal(size=400), _ar1(400, 0.5, 1), _ar1(400, 0.9, 2)]
    lengths = tuple(int(correlation_length(s)) for s in series)
    assert lengths[2] > lengths[1] >= lengths[0] >= 1 and 2 * lengths[2] < 200
    b = choose_block(400, 0.08, [*series, np.array([])])
    assert b.correlation == lengths
    assert b.frames == b.wanted == 2 * lengths[2]
    assert b.seconds == pytest.approx(0.08 * b.frames)
    assert isinstance(b.frames, int) and not b.capped
    # a declared floor above it wins
    b = choose_block(400, 0.1, series, floor_frames=2 * lengths[2] + 5)
    assert b.frames == b.wanted == 2 * lengths[2] + 5
    # capped at half the frames, and says so
    b = choose_block(20, 0.1, [], floor_frames=15)
    assert (b.frames, b.wanted, b.capped) == (10, 15, True)
    assert b.seconds == pytest.approx(1.0)
    # no series: a block of one frame
    b = choose_block(50, 0.1, [])
    assert (b.frames, b.wanted, b.correlation) == (1, 1, ())
    b = choose_block(50, 0.1, [], floor_frames=3)
    assert (b.frames, b.wanted) == (3, 3)
    # one frame: still a block of one
    assert choose_block(1, 0.1, [], floor_frames=4).frames == 1


def test_the_interval_is_the_t_interval_of_the_block_resamples():
    """A fit = the mean of three per-frame series over the drawn frames: sd over the resamples
    (ddof 1), t quantile with blocks - 1 degrees of freedom at the level, inflated by
    sqrt(n / (n - b)), around the given estimate (not the resamples' mean)."""
    n, reps, seed = 60, 40, 3
    data = np.c_[_ar1(n, 0.5, 4), _ar1(n, 0.7, 5), np.random.default_rng(6).normal(size=n)]
    block = BlockChoice(12, 1.2, 12, ())
    seen = []

    def fit(idx):
        seen.append(np.array(idx))
        return data[idx].mean(axis=0)

    est = np.array([1.0, -2.0, 0.5])
    got = bootstrap_angles(n, block, reps, seed, fit, est, level=0.9)
    draws = block_indices(n, 12, reps, seed)
    np.testing.assert_array_equal(np.array(seen), draws)
    samples = np.array([data[i].mean(axis=0) for i in draws])
    sd = samples.std(axis=0, ddof=1)
    half = student_t.ppf(0.95, 60 / 12 - 1) * sd * np.sqrt(60 / 48)
    np.testing.assert_allclose(got.sd_deg, sd, rtol=1e-12)
    np.testing.assert_allclose(got.low_deg, est - half, rtol=1e-12)
    np.testing.assert_allclose(got.high_deg, est + half, rtol=1e-12)
    assert got.level == 0.9 and got.resamples == reps
    # the default level: 95 %
    assert LEVEL == 0.95
    dflt = bootstrap_angles(n, block, reps, seed, lambda i: data[i].mean(axis=0), est)
    half95 = student_t.ppf(0.975, 4) * sd * np.sqrt(60 / 48)
    np.testing.assert_allclose(dflt.high_deg, est + half95, rtol=1e-12)
    assert dflt.level == 0.95


def test_resamples_that_cannot_be_fitted_are_left_out():
    n, block = 30, BlockChoice(5, 0.5, 5, ())
    calls = []

    def fit(idx):
        calls.append(1)
        return None if len(calls) % 2 else np.array([len(calls), 0.0, 0.0])

    got = bootstrap_angles(n, block, 10, 0, fit, np.zeros(3))
    assert got.resamples == 5
    assert got.sd_deg[0] == pytest.approx(np.std([2, 4, 6, 8, 10], ddof=1))
    # fewer than two fitted: no interval, the count kept
    one = bootstrap_angles(n, block, 10, 0,
                           lambda idx: np.ones(3) if idx[0] == -1 else None, np.zeros(3))
    assert one.resamples == 0 and np.isnan(one.low_deg).all() and np.isnan(one.sd_deg).all()
    calls.clear()
    only = bootstrap_angles(n, block, 3, 0, lambda idx: (calls.append(1) or
                                                         (np.ones(3) if len(calls) == 1
                                                          else None)), np.zeros(3))
    assert only.resamples == 1 and np.isnan(only.high_deg).all() and only.level == 0.95
    # fewer than two resamples or frames asked: nothing fitted
    for args in ((n, 1), (1, 10)):
        none = bootstrap_angles(args[0], block, args[1], 0, lambda idx: 1 / 0, np.zeros(3),
                                level=0.8)
        assert none.resamples == 0 and none.level == 0.8
        for values in (none.sd_deg, none.low_deg, none.high_deg):
            assert values.shape == (3,) and np.isnan(values).all()
    two = bootstrap_angles(2, BlockChoice(1, 0.1, 1, ()), 2, 0,
                           lambda idx: np.array(idx, float)[[0, 0, 1]], np.zeros(3))
    assert two.resamples == 2
    # exactly two fitted resamples are enough for an interval
    calls.clear()
    pair = bootstrap_angles(n, block, 4, 0, lambda idx: (calls.append(1) or
                                                         (np.full(3, len(calls))
                                                          if len(calls) <= 2 else None)),
                            np.zeros(3))
    assert pair.resamples == 2
    np.testing.assert_allclose(pair.sd_deg, np.std([1, 2], ddof=1))
    assert np.isfinite(pair.low_deg).all() and np.isfinite(pair.high_deg).all()


def test_a_block_as_long_as_the_range_does_not_divide_by_zero():
    """n - b = 0: the deficit's denominator is held at 1 (n / 1)."""
    n = 10
    data = np.random.default_rng(1).normal(size=(n, 3))
    got = bootstrap_angles(n, BlockChoice(n, 1.0, n, ()), 20, 0,
                           lambda i: data[np.sort(i)[:3]].mean(axis=0), np.zeros(3))
    samples = np.array([data[np.sort(i)[:3]].mean(axis=0) for i in block_indices(n, n, 20, 0)])
    half = student_t.ppf(0.975, 1.0) * samples.std(axis=0, ddof=1) * np.sqrt(n / 1)
    np.testing.assert_allclose(got.high_deg, half, rtol=1e-12)
    got = bootstrap_angles(n, BlockChoice(n - 1, 0.9, n - 1, ()), 20, 0,
                           lambda i: data[np.sort(i)[:3]].mean(axis=0), np.zeros(3))
    samples = np.array([data[np.sort(i)[:3]].mean(axis=0)
                        for i in block_indices(n, n - 1, 20, 0)])
    half = student_t.ppf(0.975, 1.0) * samples.std(axis=0, ddof=1) * np.sqrt(n / 1)
    np.testing.assert_allclose(got.high_deg, half, rtol=1e-12)


def test_residual_series_are_the_cross_product_components_in_frame_order():
    """Unit x turned by a small angle about z (rows of frames 2, 0, 1): the z component of
    fitted x target is sin(angle), in frame order; only the flagged axes are returned."""
    angles = np.radians([0.3, 0.1, 0.2])  # rows for frames 2, 0, 1
    fitted = np.tile([1.0, 0.0, 0.0], (3, 1))
    target = np.c_[np.cos(angles), np.sin(angles), np.zeros(3)]
    out = residual_series(fitted, target, np.array([False, False, True]), np.array([2, 0, 1]))
    assert len(out) == 1
    np.testing.assert_allclose(out[0], np.sin(np.radians([0.1, 0.2, 0.3])), rtol=1e-12)
    out = residual_series(fitted, target, np.array([True, True, True]), np.array([2, 0, 1]))
    assert len(out) == 3
    np.testing.assert_allclose(out[0], 0.0, atol=0)
    np.testing.assert_allclose(out[1], 0.0, atol=0)
    # ties keep the rows' order (stable)
    out = residual_series(fitted, target, np.array([False, False, True]), np.array([1, 0, 1]))
    np.testing.assert_allclose(out[0], np.sin(np.radians([0.1, 0.3, 0.2])), rtol=1e-12)
    # many ties (500 rows, 5 frames): still the rows' order within a frame
    rng = np.random.default_rng(0)
    order = rng.integers(0, 5, 500)
    angles = np.radians(np.arange(500) * 1e-3)
    fitted = np.tile([1.0, 0.0, 0.0], (500, 1))
    target = np.c_[np.cos(angles), np.sin(angles), np.zeros(500)]
    (z,) = residual_series(fitted, target, np.array([False, False, True]), order)
    expected = np.concatenate([np.sin(angles[order == f]) for f in range(5)])
    np.testing.assert_allclose(z, expected, rtol=1e-12)
    assert residual_series(np.empty((0, 3)), np.empty((0, 3)), np.ones(3, bool),
                           np.empty(0)) == []
