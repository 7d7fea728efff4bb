"""Confidence intervals for statistics of errors measured along one trajectory.

Errors along a trajectory are not independent: relative-error segments that start a few frames
apart share most of their frames, and consecutive velocity windows overlap. Resampling single
segments or frames would treat them as independent and give intervals far too narrow. Here
every error is a *unit* anchored at the frame it starts at (a segment's start pose, a velocity
window's first frame; a single frame for per-frame errors), and
the resampling draws **blocks of consecutive frames** (a circular block bootstrap, Politis &
Romano 1992): ``ceil(n / b)`` blocks of ``b`` frames with uniformly drawn starts, wrapped at the
end, the first ``n`` drawn frames kept. A unit enters a resample as often as its anchor frame
was drawn. The statistic (a mean, or the RMSE) of each resample is the weighted statistic of
the units. With fewer than two independent units there is no interval (NaN).

**A figure's interval** (:func:`unit_intervals`, what a run's ``metrics.json`` stores and the
tables print) is built so that it covers its stated level, by a rule with one declared
constant (:data:`OVERLAP_DOF` is a property of overlapping blocks, not a choice):

1. *Block length*: :data:`BLOCK_FACTOR` (1.5) times the larger of the frames one unit spans and
   the Politis-White length of the unit values (:func:`block_frames`), at most half the frames.
   Why: a block bootstrap's variance of a mean keeps the autocovariance at lag ``k`` with
   weight ``1 - k / b`` and loses everything beyond ``b`` (Kunsch 1989). Overlapping units of
   span ``L`` are correlated out to lag ``L`` (about linearly in their overlap), so a block of
   one span misses about a third of the variance, a block of two spans about a sixth; the
   Politis-White length, chosen for the variance's mean squared error rather than for
   coverage, has the same bias. Longer blocks lose more to step 3's ``b / n``: measured on
   the study's drives (variance of the resampled mean against the variance of the figure over
   drives), blocks of 1, 2 and 3 spans kept 57-64 %, 60-70 % and 56-69 % of the variance at
   48 m with the plain percentile interval, and steps 1-3 together cover at the stated
   level.
2. *A scale's pivot*: a mean of errors that cannot be negative scales with the size of its
   errors, and so does its resampled spread (on the study's drives the resampled sd grows as
   the figure to the power 1.0-1.4): a drive whose errors came out low gets a narrow interval
   exactly where the long-run mean lies above it. Its ratio to the long-run mean is the pivot
   (:func:`scale_pivot`): the percentile interval ``[lo, hi]`` of the figure ``x`` is read as
   ``[x^2 / hi, x^2 / lo]``, the basic bootstrap interval of ``log x``. Without it the misses
   fell 2 : 1 above the interval (4-5 % above, about 2 % below, at every length and on both
   noise processes), with it about evenly.
3. *Overlapping blocks, few of them*: the interval is widened about the figure by
   ``t_nu / z * sqrt(K / (K - 1)) / sqrt(1 - s / (3 b))`` (:func:`overlap_factor`) with
   ``K`` the whole blocks of the resample (``n // b``, at most the independent units), ``s``
   the units' median span and ``nu = 1.5 (K - 1)``. The resampled variance is an
   overlapping-batch-means estimate from ``K`` pieces, its two known biases removed and its
   degrees of freedom counted: about the sample's own mean it is low by ``(K - 1) / K``; a
   block of ``b`` frames keeps lag ``k`` with weight ``1 - k / b``, so of units whose
   covariance falls linearly to 0 over their overlap of ``s`` frames it keeps
   ``1 - s / (3 b)`` (0.78 at 48 m with blocks of 1.5 spans; measured: the resampled sd was
   0.87-0.93 of the figure's sd over drives at 8-48 m);
   and overlapping batches have about 1.5 times the degrees of freedom of ``K`` separate
   ones (Meketon & Schmeiser 1984: the same bias, 2/3 of the variance), so the Student
   quantile is taken at ``1.5 (K - 1)`` (:data:`OVERLAP_DOF`). With blocks of 1.5 spans:
   31 % at ``K`` = 10 (48 m on a 750 m drive; the previous factor 22 %), 78 % at ``K`` = 4
   (88 %), a factor 4.9 at ``K`` = 2 (9.2).
4. *The figure inside*: the interval is stretched to hold the figure itself (:func:`contain`;
   a percentile interval of a skewed statistic from few blocks can miss it), so
   ``low <= value <= high`` always holds; and a statistic of errors that cannot be negative
   (every relative, KITTI and velocity error) has an interval that stops at 0.

Steps 2 and 3 replace the plain batch-means widening ``t_{K-1} / z * sqrt(K / (K - 1))`` of
the previous rule, which on the noise seeds 40000-40399 covered 91.5-92.8 % at 32-48 m
translation and 40 m rotation (6 of 34 cells short of 93 %); on the tuning seeds
30000-30399 its misses fell above the interval twice as often as below and its resampled sd
was 0.87-0.93 of the true one at every length, the short cells only the unluckiest draws of
a rule about 1.5 points short everywhere. They add no free constant (the 1.5
of the degrees of freedom and the 1/3 of the lost lags come from the arguments above); the
rule was chosen among four (the previous one, each step alone, both) on the noise seeds
30000-30399: lowest relative-error coverage 92.8, 92.8, 93.5 and 93.8 %. Before them the
block factor was chosen: the plain batch-means widening was chosen from that bias argument
and measurements on the study's synthetic drives (``bench.studies.coverage``, white and
step-correlated noise; noise seeds 10000-10599, 20000-20599 and 50000-90299, blocks of 2
spans), and the factor 1.5 (not 2) on seeds 30000-30399 between 1, 1.5 and 2: on 750 m
drives all three give about the same widths (the widening makes up for the fewer blocks),
while on a short drive (the 250-frame real sample, 109 m) the intervals at 8 / 16 m grew
1.2-1.5x / 1.9x over the plain percentile rule at 1.5 but 1.5-1.8x / 2.6x at 2: the few
whole blocks of a long block cost a short drive more than the longer block gains. The
manual's table is measured on seeds 40000-40399, used for nothing else. Paired comparisons
(:func:`paired_interval`) follow the same rule (blocks and widening; no pivot).

**Cost.** A resample's statistic needs only the sums of the per-frame unit counts and values
over its blocks (:func:`block_sums`): from a prefix sum over the frames twice round, each
resample costs its number of blocks, not its number of frames, and memory is ``CHUNK`` times
the blocks, whatever the number of resamples.

Block length (:func:`block_frames`): at least the frames one unit spans (a segment's end index
minus its start index, its median over the units) so that units sharing frames mostly fall in
one block, and at least the automatic block length of Politis & White (2004) for the unit
values ordered by anchor (:func:`correlation_length`); never more than half the frames; for
single-frame units at least ``n / APE_MIN_BLOCKS``. Every interval records its block
length. The APE RMSE, a figure of the whole trajectory's drift, is not resampled here: its
per-frame errors form a random walk (blocks of them covered the long-run mean in about 40 % of
trials); ``metrics.drift_intervals`` resamples the estimate's frame-to-frame errors instead,
with the same three steps.

Paired comparison (:func:`paired_interval`): two estimates scored on the same segments (the
same GT, the same scored frames) are resampled with the same blocks and the difference of their
statistics taken per resample; "significantly different" means the difference's interval
excludes zero.

The number of *independent* units behind a figure (:func:`independent_count`) is the longest
chain of non-overlapping units (greedy from the first: the next unit starts at or after the
previous one's end); for single-frame units (APE) it is the number of whole blocks. A figure
with fewer than :data:`MIN_INDEPENDENT` of them is reported as such and never ranked.

The resampling is seeded (``seed``), so a run's ``metrics.json`` is reproducible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

# the quantiles of scipy.stats' norm and t, without importing scipy.stats (35 MB resident, a
# tenth of `bench score`'s memory)
from scipy.special import ndtri, stdtrit

#: the default confidence level of every interval
LEVEL = 0.95
#: the default number of bootstrap resamples
REPS = 1000
#: fewer independent units than this: the figure is not ranked
MIN_INDEPENDENT = 2
#: single-frame units (per-frame errors, e.g. per-frame APE paired where the step errors of
#: ``metrics.drift_intervals`` cannot be): at most this many blocks, i.e. blocks of at least a
#: quarter of the frames
APE_MIN_BLOCKS = 4
#: a figure's block is this many times the span / correlation rule of :func:`block_frames`
#: (the module docstring: a third of the variance the blocks miss, a short drive's few blocks)
BLOCK_FACTOR = 1.5


@dataclass(frozen=True)
class Interval:
    """A ``level`` confidence interval ``[low, high]`` of a statistic, from a circular block
    bootstrap with blocks of ``block_frames`` frames, behind which stand ``n_independent``
    non-overlapping units. ``low`` / ``high`` are NaN when there is nothing to resample."""

    low: float
    high: float
    level: float
    block_frames: int
    n_independent: int

    @property
    def excludes_zero(self) -> bool:
        return bool(np.isfinite(self.low) and np.isfinite(self.high)
                    and (self.low > 0.0 or self.high < 0.0))

    @property
    def rankable(self) -> bool:
        return self.n_independent >= MIN_INDEPENDENT


def independent_count(start_idx: np.ndarray, end_idx: np.ndarray) -> int:
    """The longest greedy chain of non-overlapping units (each starting at or after the
    previous one's end), taken in order of their start."""
    start = np.asarray(start_idx, dtype=np.int64)
    end = np.asarray(end_idx, dtype=np.int64)
    if start.size == 0:
        return 0
    order = np.argsort(start, kind="stable")
    start, end = start[order], end[order]
    count, k = 0, 0
    while k < start.size:
        count += 1
        k = max(k + 1, int(np.searchsorted(start, end[k], side="left")))
    return count


def correlation_length(values: np.ndarray) -> int:
    """The automatic block length of Politis & White (2004, corrected by Patton, Politis &
    White 2009) for the circular block bootstrap of the mean of ``values``: from the sample
    autocovariances up to the lag ``M`` where the autocorrelation stops being significant,
    ``b = (2 G^2 / D)^(1/3) n^(1/3)`` with ``G = sum lambda(k/M) |k| R(k)``,
    ``D = 4/3 g(0)^2``, ``g(0) = sum lambda(k/M) R(k)`` and the flat-top window ``lambda``;
    ``M = 2 m`` and at least 2. 1 for a series too short or constant."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    n = x.size
    if n < 8 or x.min() == x.max():
        # too short, or constant: the centred values of a constant whose mean is not exact in
        # floating point (0.1) are rounding noise, not a correlation
        return 1
    # b depends on the autocorrelations only: the values scaled to at most 1 in magnitude, so
    # that no square of a tiny (1e-150) or huge (1e150) series underflows or overflows
    x = x / np.max(np.abs(x))
    x = x - x.mean()
    size = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfft(x, size)
    acov = np.fft.irfft(f * np.conj(f), size)[:n] / n
    if acov[0] <= 0.0:
        return 1
    rho = acov / acov[0]
    # m: the first lag after which K_N consecutive autocorrelations are insignificant
    k_n = max(5, int(math.ceil(math.sqrt(math.log10(n)))))
    threshold = 2.0 * math.sqrt(math.log10(n) / n)
    small = np.abs(rho[1:]) < threshold  # small[j]: lag j + 1
    m = None
    for lag in range(0, n - 1 - k_n):
        if np.all(small[lag:lag + k_n]):
            m = lag
            break
    if m is None:
        m = n // 2
    # M = 2 m at least 2 (as in Patton's and arch's implementations): M = 1 would give lag 1
    # no weight (lambda(1) = 0), G = 0 and a block of 1 whatever the correlation
    big_m = int(min(max(2 * m, 2), n // 2 - 1)) if n // 2 > 1 else 1
    lags = np.arange(-big_m, big_m + 1)
    t = np.abs(lags) / big_m
    lam = np.where(t <= 0.5, 1.0, np.where(t <= 1.0, 2.0 * (1.0 - t), 0.0))
    r = acov[np.abs(lags)]
    g = float(np.sum(lam * np.abs(lags) * r))
    g0 = float(np.sum(lam * r))
    if g0 <= 0.0:
        return 1
    d = 4.0 / 3.0 * g0**2
    b = (2.0 * g**2 / d) ** (1.0 / 3.0) * n ** (1.0 / 3.0)
    return int(max(1, math.ceil(b)))


def block_frames(n_frames: int, span_frames: float, values: np.ndarray | None = None) -> int:
    """The block length [frames] for units spanning ``span_frames`` (median end - start) whose
    values, ordered by anchor, are ``values``: the larger of the span and the correlation
    length, at least 1, at most half the frames."""
    b = max(1.0, float(span_frames))
    if values is not None:
        b = max(b, float(correlation_length(values)))
    return int(max(1, min(math.ceil(b), max(1, n_frames // 2))))


#: resamples computed together: memory is CHUNK x blocks (CHUNK x frames where the frames'
#: indices themselves are asked for), whatever the number of resamples
CHUNK = 100


@lru_cache(maxsize=8)
def _starts(n: int, b: int, reps: int, seed: int) -> np.ndarray:
    """(reps, ceil(n / b)) the first frame of every block of every resample (read-only)."""
    starts = np.random.default_rng(seed).integers(0, n, size=(reps, -(-n // b)))
    starts.flags.writeable = False
    return starts


def block_starts(n_frames: int, block: int, reps: int = REPS, seed: int = 0) -> np.ndarray:
    """(reps, ceil(n / block)) the first frame of every block of every resample: the draws
    behind :func:`block_counts`, :func:`block_indices` and :func:`block_sums` with the same
    seed (read-only)."""
    return _starts(int(n_frames), max(1, int(block)), int(reps), int(seed))


def block_start_chunks(n_frames: int, block: int, reps: int = REPS, seed: int = 0,
                       chunk: int = CHUNK):
    """:func:`block_starts` ``chunk`` resamples at a time, drawn as they are needed and not
    kept: yields (first resample, (rows, ceil(n / block)) starts). The same draws as
    :func:`block_starts` with the same seed (the generator draws row after row; tested), in
    memory ``chunk`` rows at a time whatever the number of resamples."""
    n, b = int(n_frames), max(1, int(block))
    rng = np.random.default_rng(int(seed))
    k = -(-n // b)
    for c0 in range(0, int(reps), max(1, int(chunk))):
        yield c0, rng.integers(0, n, size=(min(max(1, int(chunk)), int(reps) - c0), k))


def _indices(n: int, b: int, starts: np.ndarray) -> np.ndarray:
    k = starts.shape[1]
    return (starts[:, :, None] + np.arange(b)[None, None, :]).reshape(len(starts), k * b)[:, :n] % n


def _counts(n: int, b: int, starts: np.ndarray) -> np.ndarray:
    idx = _indices(n, b, starts)
    flat = (np.arange(len(starts))[:, None] * n + idx).ravel()
    return np.bincount(flat, minlength=len(starts) * n).reshape(len(starts), n).astype(np.float64)


def block_counts(n_frames: int, block: int, reps: int = REPS, seed: int = 0) -> np.ndarray:
    """(reps, n_frames) how often each frame is drawn in each circular block resample."""
    n, b = int(n_frames), max(1, int(block))
    return _counts(n, b, _starts(n, b, int(reps), int(seed)))


def block_indices(n_frames: int, block: int, reps: int = REPS, seed: int = 0) -> np.ndarray:
    """(reps, n_frames) the frames drawn in each circular block resample, in drawing order:
    ``ceil(n / b)`` blocks of ``b`` consecutive frames (wrapped at the end) from uniformly drawn
    starts, the first ``n`` kept. For statistics that are not weighted means (a fit redone on
    every resample); the same draws as :func:`block_counts` with the same seed."""
    n, b = int(n_frames), max(1, int(block))
    return _indices(n, b, _starts(n, b, int(reps), int(seed)))


def block_index_chunks(n_frames: int, block: int, reps: int = REPS, seed: int = 0,
                       chunk: int = CHUNK):
    """:func:`block_indices` ``chunk`` resamples at a time: yields (first resample, (rows,
    n_frames) indices), so memory stays ``chunk x n_frames`` whatever the number of
    resamples."""
    n, b = int(n_frames), max(1, int(block))
    starts = _starts(n, b, int(reps), int(seed))
    for c0 in range(0, int(reps), max(1, int(chunk))):
        yield c0, _indices(n, b, starts[c0:c0 + max(1, int(chunk))])


def block_sums(n_frames: int, block: int, per_frame: np.ndarray, reps: int = REPS,
               seed: int = 0) -> np.ndarray:
    """(reps, ...) the sum of ``per_frame`` (n_frames, ...) over the frames drawn in each
    circular block resample (the draws of :func:`block_counts` with the same seed, so equal to
    ``block_counts(...) @ per_frame`` up to rounding): from a prefix sum over the frames
    twice round, each resample costs its number of blocks, not its number of frames."""
    n, b = int(n_frames), max(1, int(block))
    x = np.asarray(per_frame, dtype=np.float64)
    k = -(-n // b)
    lengths = np.full(k, b, dtype=np.int64)
    lengths[-1] = n - (k - 1) * b  # the first n drawn frames are kept
    prefix = np.zeros((2 * n + 1,) + x.shape[1:])
    np.cumsum(np.concatenate([x, x]), axis=0, out=prefix[1:])
    out = np.empty((int(reps),) + x.shape[1:])
    for c0, s in block_start_chunks(n, b, reps, seed):
        out[c0:c0 + len(s)] = (prefix[s + lengths] - prefix[s]).sum(axis=1)
    return out


def _resampled(n: int, b: int, reps: int, seed: int, anchor: np.ndarray,
               series: list[np.ndarray], rmse: bool) -> list[np.ndarray]:
    """Per series, the statistic (mean, or RMSE) of each resample: the units weighted by how
    often their anchor frame was drawn, from the block sums (:func:`block_sums`) of the
    per-frame unit counts and value sums."""
    per_frame = np.zeros((n, len(series) + 1))
    np.add.at(per_frame[:, 0], anchor, 1.0)
    for j, v in enumerate(series):
        np.add.at(per_frame[:, j + 1], anchor, v**2 if rmse else v)
    sums = block_sums(n, b, per_frame, reps, seed)
    total = sums[:, 0]
    out = []
    for j in range(len(series)):
        with np.errstate(invalid="ignore", divide="ignore"):
            stat = sums[:, j + 1] / total
        stat[total < 0.5] = np.nan  # no unit drawn (counts are whole numbers)
        if rmse:
            stat = np.sqrt(np.maximum(stat, 0.0))
        out.append(stat)
    return out


def _percentiles(stats: np.ndarray, level: float) -> tuple[float, float]:
    stats = stats[np.isfinite(stats)]
    if stats.size == 0:
        return math.nan, math.nan
    alpha = 0.5 * (1.0 - level)
    lo, hi = np.quantile(stats, [alpha, 1.0 - alpha])
    return float(lo), float(hi)


def _block_rule(n_frames: int, anchor: np.ndarray, end: np.ndarray, series: list[np.ndarray],
                block: int | None, n_independent: int, factor: float = 1.0) -> tuple[int, int]:
    """(block length, independent units): the block is ``factor`` times the largest of
    ``block_frames`` over ``series`` (ordered by anchor), for single-frame units at least
    ``n / APE_MIN_BLOCKS``, at most half the frames, unless given; single-frame units count the
    whole blocks as their independent pieces."""
    span = float(np.median(end - anchor))
    if block is None:
        order = np.argsort(anchor, kind="stable")
        block = max(block_frames(n_frames, span, v[order]) for v in series)
        if span <= 1.0:
            block = max(block, -(-n_frames // APE_MIN_BLOCKS))
        block = max(1, min(math.ceil(factor * block), max(1, n_frames // 2)))
    if span <= 1.0:  # single frames: the independent pieces are the blocks themselves
        n_independent = min(n_independent, max(1, n_frames // int(block)))
    return int(block), n_independent


def contain(observed: float, low: float, high: float) -> tuple[float, float]:
    """``[low, high]`` stretched to hold ``observed`` (a figure always lies in its own
    interval; a percentile interval of a skewed statistic from few blocks can miss it)."""
    if not (math.isfinite(low) and math.isfinite(high) and math.isfinite(observed)):
        return low, high
    return min(low, observed), max(high, observed)


def unit_intervals(n_frames: int, anchor: np.ndarray, end: np.ndarray,
                   values: dict[str, np.ndarray], rmse: bool = False, level: float = LEVEL,
                   reps: int = REPS, seed: int = 0, block: int | None = None,
                   small_sample: bool = True) -> dict[str, Interval]:
    """Intervals of the mean (``rmse``: the RMSE) of each array in ``values`` (one value per
    unit, units anchored at frame ``anchor`` and ending at frame ``end``), all resampled with
    the same blocks. The block length is :data:`BLOCK_FACTOR` times :func:`block_frames` of the
    units' span and of the most correlated of the value series, unless ``block`` is given.
    ``small_sample`` (the default, what a run's figures print): for values that cannot be
    negative the percentile interval read with the ratio to the long-run mean as the pivot
    (:func:`scale_pivot`), widened by :func:`overlap_factor` for the whole blocks behind it
    (at most the independent units) and the units' median span, stretched to hold the figure
    (:func:`contain`) and stopped at 0; else the plain percentile interval. NaN with fewer
    than :data:`MIN_INDEPENDENT` independent units."""
    anchor = np.asarray(anchor, dtype=np.int64)
    end = np.asarray(end, dtype=np.int64)
    n_ind = independent_count(anchor, end)
    nan = Interval(math.nan, math.nan, level, 0, n_ind)
    finite = {k: np.asarray(v, dtype=np.float64) for k, v in values.items()}
    if anchor.size == 0 or n_frames < 2:
        return {k: nan for k in finite}
    block, n_ind = _block_rule(n_frames, anchor, end, list(finite.values()), block, n_ind,
                               BLOCK_FACTOR)
    pieces = min(n_ind, n_frames // int(block))
    span = float(np.median(end - anchor))
    keys = [k for k, v in finite.items() if np.all(np.isfinite(v))]
    stats = dict(zip(keys, _resampled(n_frames, int(block), reps, seed, anchor,
                                      [finite[k] for k in keys], rmse), strict=True))
    out = {}
    for key, v in finite.items():
        if key not in stats or n_ind < MIN_INDEPENDENT:
            out[key] = Interval(math.nan, math.nan, level, int(block), n_ind)
            continue
        lo, hi = _percentiles(stats[key], level)
        if small_sample:
            observed = float(np.sqrt(np.mean(v**2))) if rmse else float(np.mean(v))
            nonnegative = bool(np.all(v >= 0.0))  # a mean (RMSE) of errors
            if nonnegative:
                lo, hi = scale_pivot(observed, lo, hi)
            lo, hi = contain(observed, *widen_overlapping(observed, lo, hi, pieces, level,
                                                          span, int(block)))
            if nonnegative:  # cannot be negative
                lo = max(lo, 0.0)
        out[key] = Interval(lo, hi, level, int(block), n_ind)
    return out


def widen(observed: float, low: float, high: float, n_independent: int, level: float,
          batch_means: bool = False) -> tuple[float, float]:
    """The percentile interval ``[low, high]`` widened about ``observed`` by
    ``t_{K-1} / z`` for ``K = n_independent`` (NaN for K < 2); ``batch_means``: by
    ``t_{K-1} / z * sqrt(K / (K - 1))``, the batch-means interval's factor for ``K`` pieces
    (a bootstrap variance from ``K`` blocks divides by ``K``, an unbiased one by ``K - 1``)."""
    if n_independent < MIN_INDEPENDENT or not (math.isfinite(low) and math.isfinite(high)):
        return math.nan, math.nan
    q = 0.5 * (1.0 + level)
    f = float(stdtrit(n_independent - 1, q) / ndtri(q))
    if batch_means:
        f *= math.sqrt(n_independent / (n_independent - 1))
    return observed - (observed - low) * f, observed + (high - observed) * f


def scale_pivot(observed: float, low: float, high: float) -> tuple[float, float]:
    """The percentile interval ``[low, high]`` of a figure of errors that cannot be negative,
    read with the ratio ``figure / long-run mean`` as the pivot: ``[x^2 / high, x^2 / low]``
    for the figure ``x``. Such a figure scales with the size of its errors, and so does its
    resampled spread: a drive whose errors came out low gets a narrow interval exactly where
    the long-run mean lies above it. The ratio's spread does not depend on the size; its
    resampled quantiles ``low / x`` and ``high / x`` put the long-run mean between ``x / (high
    / x)`` and ``x / (low / x)`` (the basic bootstrap interval of ``log x``). Unchanged where
    the ratio is undefined (``x`` or ``low`` not above 0)."""
    if not (math.isfinite(low) and math.isfinite(high) and observed > 0.0 and low > 0.0):
        return low, high
    return observed * observed / high, observed * observed / low


#: the overlapping batch means behind a circular block bootstrap's variance have about this many
#: times the degrees of freedom of ``K`` non-overlapping batches (Meketon & Schmeiser 1984: the
#: same bias, 2/3 of the variance)
OVERLAP_DOF = 1.5


def overlap_factor(n_pieces: int, level: float, span_frames: float, block: int) -> float:
    """The widening of a circular block bootstrap's percentile interval of a mean of units
    spanning ``span_frames`` frames, from ``n_pieces`` whole blocks of ``block`` frames:
    ``t_nu / z * sqrt(K / (K - 1)) / sqrt(1 - s / (3 b))`` with ``nu = OVERLAP_DOF (K - 1)``
    (NaN for K < 2). ``sqrt(K / (K - 1))``: the variance about the sample's own mean from
    ``K`` pieces; ``1 - s / (3 b)``: the share of the variance a block of ``b`` frames keeps
    of units whose covariance falls linearly to 0 over their overlap of ``s`` frames (lag
    ``k`` kept with weight ``1 - k / b``, Kunsch 1989); ``t_nu``: the Student quantile for the
    variance's degrees of freedom."""
    if n_pieces < MIN_INDEPENDENT:
        return math.nan
    q = 0.5 * (1.0 + level)
    dof = OVERLAP_DOF * (n_pieces - 1)
    lost = min(max(float(span_frames), 0.0), float(block)) / (3.0 * max(1, int(block)))
    return float(stdtrit(dof, q) / ndtri(q) * math.sqrt(n_pieces / (n_pieces - 1))
                 / math.sqrt(1.0 - lost))


def widen_overlapping(observed: float, low: float, high: float, n_pieces: int, level: float,
                      span_frames: float, block: int) -> tuple[float, float]:
    """``[low, high]`` widened about ``observed`` by :func:`overlap_factor`; NaN for fewer
    than two pieces or an interval that is not finite."""
    f = overlap_factor(n_pieces, level, span_frames, block)
    if not (math.isfinite(f) and math.isfinite(low) and math.isfinite(high)):
        return math.nan, math.nan
    return observed - (observed - low) * f, observed + (high - observed) * f


def paired_interval(n_frames: int, anchor: np.ndarray, end: np.ndarray, values_a: np.ndarray,
                    values_b: np.ndarray, rmse: bool = False, level: float = LEVEL,
                    reps: int = REPS, seed: int = 0, block: int | None = None) -> Interval:
    """The interval of ``stat(values_a) - stat(values_b)`` over the same units (paired: both
    resampled with the same blocks; ``stat`` the mean, or the RMSE when ``rmse``), by the
    rule of the tables' own intervals (:func:`unit_intervals`, without the pivot: a difference
    can be negative): blocks of :data:`BLOCK_FACTOR` times the largest of both series' and
    their difference's :func:`block_frames` unless given, the percentile interval widened by
    :func:`overlap_factor` for the whole blocks behind it and stretched to hold the observed
    difference. With blocks of one span and the plain ``t_{K-1} / z`` widening it declared a
    difference between two methods of equal true error on 9-17 % of 120 m drives at 8 and
    24 m (nominal 5 %); with this rule 2.7-7.0 % (``python -m
    bench.studies.paired_coverage``; docs/metrics.md). For a notebook comparing two
    estimates; the tables' marks read each figure's own printed interval instead
    (``bench.report.tables.significance``)."""
    a = np.asarray(values_a, dtype=np.float64)
    b = np.asarray(values_b, dtype=np.float64)
    anchor = np.asarray(anchor, dtype=np.int64)
    end = np.asarray(end, dtype=np.int64)
    n_ind = independent_count(anchor, end)
    if anchor.size == 0 or n_frames < 2 or not (np.all(np.isfinite(a))
                                                 and np.all(np.isfinite(b))):
        return Interval(math.nan, math.nan, level, 0, n_ind)
    block, n_ind = _block_rule(n_frames, anchor, end, [a, b, a - b], block, n_ind,
                               BLOCK_FACTOR)
    pieces = min(n_ind, n_frames // int(block))
    span = float(np.median(end - anchor))
    stat_a, stat_b = _resampled(n_frames, int(block), reps, seed, anchor, [a, b], rmse)
    lo, hi = _percentiles(stat_a - stat_b, level)
    stat = (lambda x: float(np.sqrt(np.mean(x**2)))) if rmse else (lambda x: float(np.mean(x)))
    observed = stat(a) - stat(b)
    lo, hi = contain(observed, *widen_overlapping(observed, lo, hi, pieces, level, span,
                                                  int(block)))
    return Interval(lo, hi, level, int(block), n_ind)
