"""metrics.intervals: known answers and an independent implementation for what the mutation
run (``tools/mutate.py``) found untested.

``correlation_length`` is checked against a plain-Python transcription of Politis & White
(2004) with the correction of Patton, Politis & White (2009), written from the papers'
definitions (direct sums, no FFT): the sample autocovariances ``R(k) = 1/n sum (x_t - xbar)
(x_{t+k} - xbar)``, ``m`` the smallest lag after which ``K_N = max(5, ceil(sqrt(log10 n)))``
consecutive autocorrelations lie inside ``+-2 sqrt(log10 n / n)``, ``M = 2 m`` (at least 2, at
most ``n // 2 - 1`` lags), the flat-top window and ``b = (2 G^2 / D)^(1/3) n^(1/3)``."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.stats import norm
from scipy.stats import t as student_t

from metrics.intervals import (
    BLOCK_FACTOR,
    block_counts,
    correlation_length,
    independent_count,
    paired_interval,
    unit_intervals,
)


def _flat_top(t: float) -> float:
    t = abs(t)
    return 1.0 if t <= 0.5 else 2.0 * (1.0 - t) if t <= 1.0 else 0.0


def reference_block(values) -> float:
    """The Politis-White circular block length before rounding (``b``), from the definitions;
    0.0 where the long-run variance estimate ``g(0)`` is not positive, NaN for fewer than 8
    finite values or a constant series."""
    x = [float(v) for v in values if math.isfinite(v)]
    n = len(x)
    if n < 8 or min(x) == max(x):
        return math.nan
    mean = math.fsum(x) / n
    y = [v - mean for v in x]
    r = [math.fsum(y[t] * y[t + k] for t in range(n - k)) / n for k in range(n)]
    k_n = max(5, math.ceil(math.sqrt(math.log10(n))))
    band = 2.0 * math.sqrt(math.log10(n) / n)
    m = n // 2  # no lag qualifies
    for lag in range(n - k_n):  # lags lag + 1 .. lag + K_N must exist (at most n - 1)
        if all(abs(r[lag + j] / r[0]) < band for j in range(1, k_n + 1)):
            m = lag
            break
    big_m = min(max(2 * m, 2), n // 2 - 1)
    g = math.fsum(_flat_top(k / big_m) * abs(k) * r[abs(k)] for k in range(-big_m, big_m + 1))
    g0 = math.fsum(_flat_top(k / big_m) * r[abs(k)] for k in range(-big_m, big_m + 1))
    if g0 <= 0.0:
        return 0.0
    d = 4.0 / 3.0 * g0**2
    return (2.0 * g**2 / d) ** (1.0 / 3.0) * n ** (1.0 / 3.0)


def _series():
    """Seeded series of every kind the rule branches on: white noise (blocks below one frame),
    AR(1) of weak to strong positive and of negative correlation, lengths from the shortest
    accepted (8) up, an offset and a scale far from 0 and 1, a single correlated lag beyond
    the first K_N insignificant ones, and non-finite values to be dropped."""
    out = []
    for seed, n in enumerate((8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 20, 31, 32, 33, 64, 100,
                              257, 600)):
        e = np.random.default_rng(100 + seed).normal(size=n)
        for phi in (0.0, 0.3, 0.7, 0.95, -0.6):
            out.append(lfilter([1.0], [1.0, -phi], e))
    e = np.random.default_rng(7).normal(size=300)
    out.append(50.0 + 0.01 * lfilter([1.0], [1.0, -0.6], e))  # offset 50, scale 1/100
    out.append(1e4 * lfilter([1.0], [1.0, -0.6], e))
    seasonal = e.copy()
    seasonal[12:] += 0.9 * e[:-12]  # correlated at lag 12 only
    out.append(seasonal)
    holes = lfilter([1.0], [1.0, -0.7], e)
    holes[[3, 50, 51, 299]] = [np.nan, np.inf, -np.inf, np.nan]
    out.append(holes)
    lag6 = e.copy()
    lag6[6:] += 0.9 * e[:-6]  # lags 1 .. K_N insignificant, lag 6 not: m = 0, not 6
    out.append(lag6)
    for n in range(8, 21):  # every autocorrelation significant: no m, M = n // 2 - 1
        out.append((-1.0) ** np.arange(n))
    # 8 values whose lag-one autocorrelation alone is significant: m = 1 (the last lag the
    # search can take at n = 8)
    out.append(np.array([-0.4, 0.6, -1.4, 2.1, -1.3, 0.9, -1.1, 1.2]))
    return out


def test_correlation_length_is_the_politis_white_block_of_an_independent_implementation():
    """Whole frames: ``ceil(b)``, at least 1, on every series of :func:`_series`; the cases
    cover b < 1 (white noise), g(0) <= 0 (negative correlation) and M capped at n // 2 - 1."""
    refs = []
    for x in _series():
        b = reference_block(x)
        refs.append(b)
        if b > 0.0 and abs(b - round(b)) < 1e-9:  # an integer b: rounding decides, skip
            continue
        assert correlation_length(x) == max(1, math.ceil(b)), (len(x), b)
    refs = np.array(refs)
    assert np.any(refs == 0.0) and np.any((refs > 0.0) & (refs < 1.0)) and np.any(refs > 10.0)


@pytest.mark.parametrize("value", [0.0, 3.0, 0.1, -2.7, 1e-7, 123.456])
@pytest.mark.parametrize("n", [8, 50, 1000])
def test_a_constant_series_has_blocks_of_one_frame(value, n):
    """A constant series has no correlation to keep (the docstring: 1 for a series too short
    or constant), whatever its value: a mean like 0.1 that is not exact in floating point
    leaves centred values of rounding noise, which must not be read as a correlation."""
    assert correlation_length(np.full(n, value)) == 1


def test_an_alternating_series_of_eight_has_the_block_worked_out_by_hand():
    """``x_t = (-1)^t``, n = 8: mean 0, ``R(k) = (-1)^k (8 - k) / 8``; ``|rho(1)|`` = 0.875 and
    ``|rho(2)|`` = 0.75 exceed the band ``2 sqrt(log10 8 / 8)`` = 0.672, so no window of
    K_N = 5 lags qualifies in the lags searched and M = n // 2 - 1 = 3; the flat-top weights
    at k / 3 = 0, 1/3, 2/3 are 1, 1, 2/3, so ``g(0) = 1 + 2 (-7/8 + 2/3 * 6/8)`` = 1/4 and
    ``G = 2 (7/8 * -1 + 2 * 2/3 * 6/8)`` = 1/4 (in units of R(0)), and
    ``b = (2 G^2 / (4/3 g(0)^2))^(1/3) 8^(1/3) = 2 * 1.5^(1/3)`` = 2.29: 3 frames."""
    assert reference_block((-1.0) ** np.arange(8)) == pytest.approx(2.0 * 1.5 ** (1 / 3))
    assert correlation_length((-1.0) ** np.arange(8)) == 3


def test_a_float32_series_has_the_block_of_its_float64_copy():
    """The autocovariances are computed in float64 whatever the input: a float32 series far
    from 0 (a float32 mean is off by up to about 1e-3, a tenth of the noise) gets the block of
    the same values in float64."""
    for seed in range(20):
        x = 1e4 + 0.01 * lfilter([1.0], [1.0, -0.5], np.random.default_rng(seed).normal(size=300))
        x32 = x.astype(np.float32)
        assert correlation_length(x32) == correlation_length(x32.astype(np.float64)), seed


def test_a_series_too_short_has_blocks_of_one_frame_and_eight_values_are_enough():
    walk = np.cumsum(np.random.default_rng(3).normal(size=8))  # strongly correlated
    assert correlation_length(walk[:7]) == 1
    assert correlation_length(np.append(walk[:7], np.nan)) == 1  # 7 finite values
    assert correlation_length(walk) == max(1, math.ceil(reference_block(walk))) > 1


def test_correlation_length_ignores_the_series_offset_scale_and_non_finite_values():
    """b depends on the autocorrelations only: the same for ``a + c x`` (c != 0), down to values
    whose squares would underflow (1e-170: they were read as a constant, 1e-150: a division
    by zero) and up to values whose squares would overflow; a non-finite value is dropped as
    if it were not there."""
    x = lfilter([1.0], [1.0, -0.8], np.random.default_rng(11).normal(size=400))
    b = correlation_length(x)
    assert b > 5
    for a, c in ((0.0, 1e-3), (0.0, 1e3), (1e3, 1.0), (-5.0, -2.0), (0.0, 1e-170),
                 (0.0, 1e-150), (0.0, 1e150), (0.0, 1e200)):
        assert correlation_length(a + c * x) == b, (a, c)
    assert correlation_length(np.concatenate([[np.nan], x, [np.inf, -np.inf]])) == b


# ---- the rest of metrics/intervals.py ---------------------------------------------------------

def _greedy_chain(start, end) -> int:
    """Plain Python: units in order of their start (ties in their given order, Python's sort
    is stable), the first taken, then the first unit starting at or after the taken one's
    end."""
    order = sorted(range(len(start)), key=lambda i: start[i])
    count, k = 0, 0
    while k < len(order):
        count += 1
        stop = end[order[k]]
        nxt = k + 1
        while nxt < len(order) and start[order[nxt]] < stop:
            nxt += 1
        k = nxt
    return count


def test_independent_count_is_the_greedy_chain_with_ties_in_their_given_order():
    """Many units share a start, with different ends: which of them the chain takes (the first
    given) decides the count. Units of zero span (end = start) follow each other."""
    rng = np.random.default_rng(4)
    for _ in range(5):
        start = rng.integers(0, 60, size=200)
        end = start + rng.integers(1, 15, size=200)
        assert independent_count(start, end) == _greedy_chain(start.tolist(), end.tolist())
    assert independent_count(np.arange(5), np.arange(5)) == 5
    assert independent_count([3, 3, 0], [9, 3, 0]) == 2  # (0, 0), (3, 9) given first: 2
    assert independent_count([3, 3, 0], [3, 9, 0]) == 3  # (0, 0), (3, 3), (3, 9)


def test_units_anchored_at_tied_frames_are_ordered_as_given_for_the_block():
    """The block follows the correlation length of the values ordered by anchor; units that
    share an anchor keep their given order. Two units per frame, given in shuffled order, the
    first given of each frame 5 above the frame's correlated level and the second 5 below:
    ordered as given the values alternate (a strong negative lag-one correlation), ordered
    otherwise within frames they would not."""
    frames = 150
    rng = np.random.default_rng(5)
    level = lfilter([1.0], [1.0, -0.9], rng.normal(size=frames))
    perm = rng.permutation(frames)
    anchor = np.concatenate([perm, perm])  # every frame's +5 unit given before its -5 unit
    values = np.concatenate([level[perm] + 5.0, level[perm] - 5.0])
    end = anchor + 2
    order = sorted(range(len(anchor)), key=lambda i: anchor[i])  # stable
    want = min(math.ceil(BLOCK_FACTOR * max(2, correlation_length(values[order]))), frames // 2)
    iv = unit_intervals(frames, anchor, end, {"v": values}, reps=20)["v"]
    assert iv.block_frames == want
    assert paired_interval(frames, anchor, end, values, np.zeros(len(values)),
                           reps=20).block_frames == want


def test_resamples_that_draw_no_unit_warn_nothing():
    """Units anchored at 3 of 200 frames: with blocks of a frame most resamples draw none of
    them (their statistic is NaN, dropped); no RuntimeWarning of the division reaches the
    user."""
    anchor = np.array([0, 1, 2])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        iv = unit_intervals(200, anchor, anchor + 1, {"v": np.array([1.0, 2.0, 4.0])},
                            reps=50, block=1, small_sample=False)["v"]
        rms = unit_intervals(200, anchor, anchor + 1, {"v": np.array([1.0, 2.0, 4.0])},
                             rmse=True, reps=50, block=1, small_sample=False)["v"]
    assert 1.0 <= iv.low <= iv.high <= 4.0 and 1.0 <= rms.low <= rms.high <= 4.0


def test_whole_number_float_anchors_and_float32_values_give_the_float64_integer_intervals():
    """Anchors and ends as floats (read back from a JSON file) and values in float32 are
    converted: the same intervals as int64 anchors and the float64 values (the figure's mean
    taken in float64, not float32)."""
    n = 240
    anchor = np.arange(0, 230)
    end = anchor + 8
    v = np.abs(lfilter([1.0], [1.0, -0.5], np.random.default_rng(6).normal(size=230))) + 0.1
    v32 = v.astype(np.float32)
    v64 = v32.astype(np.float64)
    want = unit_intervals(n, anchor, end, {"v": v64}, reps=100)["v"]
    got = unit_intervals(n, anchor.astype(float), end.astype(float), {"v": v32}, reps=100)["v"]
    assert (got.low, got.high) == pytest.approx((want.low, want.high), rel=1e-13, abs=0.0)
    assert (got.block_frames, got.n_independent) == (want.block_frames, want.n_independent)
    w = 0.5 * v64[::-1]
    want = paired_interval(n, anchor, end, v64, w, reps=100)
    got = paired_interval(n, anchor.astype(float), end.astype(float), v32,
                          w.astype(np.float32), reps=100)
    assert (got.low, got.high) == pytest.approx((want.low, want.high), rel=1e-13, abs=0.0)


@pytest.mark.parametrize("rmse", [False, True])
def test_paired_interval_is_the_rule_written_out(rmse):
    """``paired_interval`` against its rule with the resamples counted by ``block_counts``
    (frames drawn, not block sums) and SciPy's quantiles: the percentile interval of the
    paired differences, widened about the observed difference by ``t_nu / z sqrt(K / (K - 1))
    / sqrt(1 - s / (3 b))``, ``nu = 1.5 (K - 1)``, K = n // b whole blocks (203 // 25 = 8, not
    8.12), s the units' median span (10), and stretched to hold the difference."""
    n, block, reps = 203, 25, 200
    anchor = np.arange(0, 193)
    end = anchor + 10
    rng = np.random.default_rng(9)
    a = np.abs(rng.normal(1.0, 0.5, 193))
    b = np.abs(a + rng.normal(0.1, 0.3, 193))
    counts = block_counts(n, block, reps, seed=0)[:, anchor]
    if rmse:
        stat = lambda x, w: np.sqrt(w @ x**2 / w.sum(axis=-1))  # noqa: E731
    else:
        stat = lambda x, w: w @ x / w.sum(axis=-1)  # noqa: E731
    ones = np.ones(len(a))
    observed = stat(a, ones) - stat(b, ones)
    lo, hi = np.quantile(stat(a, counts) - stat(b, counts), [0.025, 0.975])
    k = n // block
    f = (student_t.ppf(0.975, 1.5 * (k - 1)) / norm.ppf(0.975) * math.sqrt(k / (k - 1))
         / math.sqrt(1.0 - 10.0 / (3.0 * block)))
    lo, hi = min(observed - (observed - lo) * f, observed), max(observed + (hi - observed) * f,
                                                              observed)
    iv = paired_interval(n, anchor, end, a, b, rmse=rmse, reps=reps, block=block)
    assert (iv.low, iv.high) == pytest.approx((lo, hi), rel=1e-9)
    assert iv.block_frames == block and iv.n_independent == independent_count(anchor, end)
