"""Is an external trajectory on the scans' clock? Its speed profile against the ground truth's.

Stamp matching alone cannot tell: an estimate shifted by a whole number of scan periods matches
every stamp it overlaps (as evo's association would). The speed of the sensor along its path
does not depend on the world frame, the start point or the scale of an estimate made elsewhere
(Pearson's correlation ignores the scale), nor does its turn rate (the rotation angle per
second, the same for any frame on the body), so two trajectories of one drive on one clock have
motion profiles that line up at zero shift.

``fit_clock`` finds the shift ``tau`` [s] that, added to the estimate's stamps, best lines up
its speed profile with the ground truth's (the normalised cross-correlation of the two
profiles, both sampled every ``period / GRID_STEPS_PER_PERIOD`` over windows of +/-
``HALF_WINDOW_S``, refined between grid steps by a parabola through the peak: sub-scan-period
precision), with the correlation at zero shift. When the ground truth turns
(``MIN_TURN_STD_RADPS``) the turn-rate profiles' correlation is averaged in (on the vendored
NTU4DRadLM sample the speed profile of the harness's own runs alone lines up 0.25 s early,
speed and turn rate together within 0.07 s). The fit's uncertainty: a circular block bootstrap
of the ground truth's profile samples (blocks of ``BLOCK_S``, ``BOOTSTRAP_REPLICATES``
replicates; the estimate's side fixed, so every replicate is one FFT correlation) gives the
``LEVEL`` interval of the best shift and of the correlation's gain at that shift over none;
``ClockFit.decisive`` says whether the data exclude no shift. ``aligned_offset`` moves a
suggested shift to the nearest one that also lines the stamps up.

A profile says nothing when the ground truth's speed hardly varies and it does not turn (a
constant-speed drive: ``MIN_SPEED_STD_MPS``) or when the best correlation is weak
(``MIN_CORRELATION``): the fit is then inconclusive (``offset_s`` None, ``why`` says so) and
nothing is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

#: speed profiles are sampled this many times a scan period (sub-period precision)
GRID_STEPS_PER_PERIOD = 8
#: at most this many samples a profile (long sequences get a coarser grid)
MAX_GRID = 2**15
#: the speed at t is the distance between the positions at t -/+ this [s] (at least a period)
HALF_WINDOW_S = 1.0
#: the turn rate (the same over the same window) joins the speed when the ground truth turns
USE_TURN_RATE = True
#: ... by at least this much [rad/s] (standard deviation of its turn rate)
MIN_TURN_STD_RADPS = 0.005
#: profiles are compared at shifts where they overlap over at least this share of the shorter
MIN_OVERLAP_SHARE = 0.5
#: the ground truth's speed must vary at least this much [m/s] for a profile to say anything
MIN_SPEED_STD_MPS = 0.2
#: a best correlation below this is no fit
MIN_CORRELATION = 0.5
#: the block bootstrap: blocks of this long [s] (twice the profiles' 2 s window: a block spans
#: the profiles' correlation), this many replicates, intervals at this level
BLOCK_S = 4.0
BOOTSTRAP_REPLICATES = 200
LEVEL = 0.95


@dataclass(frozen=True)
class ClockFit:
    """``offset_s``: the shift to add to the estimate's stamps that best lines up the speed
    profiles (None: inconclusive, ``why``); ``correlation`` there and ``correlation_at_zero``
    (at no shift; NaN when the profiles do not overlap unshifted); ``suggested_s``: the
    ``--time-offset`` to suggest (set by the caller: ``aligned_offset``)."""

    offset_s: float | None
    correlation: float = float("nan")
    correlation_at_zero: float = float("nan")
    why: str = ""
    suggested_s: float | None = None
    #: the block bootstrap's interval (``LEVEL``) of the best shift [s]
    interval_s: tuple[float, float] | None = None
    #: the lower end of the interval of the correlation's gain at the best shift over none
    gain_low: float = float("nan")
    #: the profiles' grid step [s] (the fit's resolution before its parabola)
    grid_s: float = float("nan")
    #: the ``--time-offset`` values that fit alike (the caller's: ``alike_offsets``)
    alike_s: tuple[float, ...] = ()

    @property
    def decisive(self) -> bool:
        """The data exclude no shift: the gain's interval lies above 0 and the best shift's
        interval (widened by a grid step) leaves out 0."""
        if self.offset_s is None or self.interval_s is None:
            return False
        lo, hi = self.interval_s
        if lo - self.grid_s <= 0 <= hi + self.grid_s:
            return False
        # profiles that do not overlap unshifted have no gain to weigh: the interval decides
        return bool(self.gain_low > 0 or not np.isfinite(self.correlation_at_zero))


def path_speed(stamps: np.ndarray, positions: np.ndarray) -> float:
    """Path length over time span [m per stamp unit]."""
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    span = float(stamps[-1] - stamps[0])
    return float(steps.sum() / span) if span > 0 else 0.0


def motion_profiles(stamps: np.ndarray, poses: np.ndarray, h: float, half_window_s: float,
                    max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Speed [m/s] and turn rate [rad/s] every ``h`` from ``stamps[0]`` to ``stamps[-1]``: the
    distance and the rotation angle between the (interpolated: linear, slerp) poses
    ``half_window_s`` before and after, over twice that; NaN where the window leaves the span
    or a gap longer than ``max_gap_s`` lies under it. Both are independent of the world frame
    and of a constant frame change (the turn rate of any frame on the body)."""
    t = stamps[0] + h * np.arange(int(np.floor((stamps[-1] - stamps[0]) / h)) + 1)
    lo, hi = t - half_window_s, t + half_window_s
    i_lo = np.clip(np.searchsorted(stamps, lo, side="right") - 1, 0, len(stamps) - 1)
    i_hi = np.clip(np.searchsorted(stamps, hi, side="left"), 0, len(stamps) - 1)
    widest = _range_max(np.diff(stamps), i_lo, i_hi)  # the widest step under the window
    ok = (lo >= stamps[0]) & (hi <= stamps[-1]) & (widest <= max_gap_s)
    speed = np.full(len(t), np.nan)
    rate = np.full(len(t), np.nan)
    if ok.any():
        xyz = poses[:, :3, 3]

        def at(q):
            return np.column_stack([np.interp(q, stamps, xyz[:, k]) for k in range(3)])

        speed[ok] = np.linalg.norm(at(hi[ok]) - at(lo[ok]), axis=1) / (2 * half_window_s)
        slerp = Slerp(stamps, Rotation.from_matrix(poses[:, :3, :3]))
        turn = slerp(lo[ok]).inv() * slerp(hi[ok])
        rate[ok] = turn.magnitude() / (2 * half_window_s)
    return speed, rate


def _range_max(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """max(values[lo:hi]) per pair (0 for an empty range), by a sparse table."""
    if len(values) == 0:
        return np.zeros(len(lo))
    table = [values]
    while 2 ** len(table) <= len(values):
        prev, k = table[-1], 2 ** (len(table) - 1)
        table.append(np.maximum(prev[:-k], prev[k:]))
    n = np.maximum(hi - lo, 1)
    level = np.floor(np.log2(n)).astype(int)
    out = np.empty(len(lo))
    for k in np.unique(level):
        sel = level == k
        a, b = lo[sel], hi[sel] - 2 ** k
        out[sel] = np.maximum(table[k][np.clip(a, 0, len(table[k]) - 1)],
                              table[k][np.clip(b, 0, len(table[k]) - 1)])
    return np.where(hi > lo, out, 0.0)


def _spectra(a: np.ndarray, size: int) -> np.ndarray:
    return np.fft.rfft(a, size)


def _lags(size: int) -> tuple[np.ndarray, np.ndarray]:
    k = np.arange(size)
    k = np.where(k < size // 2, k, k - size)  # lag in grid steps
    order = np.argsort(k)
    return k[order], order


class _Channel:
    """One profile pair (ground truth ``x``, estimate ``y``) ready for Pearson's correlation of
    ``x[i]`` with ``y[i - k]`` at every lag k, with per-sample weights on ``x`` (a block
    bootstrap's counts) and the estimate's spectra computed once."""

    def __init__(self, x: np.ndarray, y: np.ndarray):
        self.mx, my = np.isfinite(x), np.isfinite(y)
        self.x0 = np.where(self.mx, x, 0.0)
        y0 = np.where(my, y, 0.0)
        self.size = 1 << int(np.ceil(np.log2(len(x) + len(y))))
        self.fy = [np.conj(_spectra(a, self.size)) for a in (my.astype(float), y0, y0 ** 2)]
        self.k, self.order = _lags(self.size)
        self.min_n = max(MIN_OVERLAP_SHARE * min(self.mx.sum(), my.sum()), 8) - 0.5

    def correlation(self, w: np.ndarray | None = None) -> np.ndarray:
        """Pearson's r per lag (sorted like ``self.k``), -inf where the (unweighted) overlap
        is short or either side is constant there."""
        fx = self.mx.astype(float) if w is None else self.mx * w
        x0 = self.x0 if w is None else self.x0 * w
        x2 = self.x0 ** 2 if w is None else self.x0 ** 2 * w
        sz = self.size
        fX, xX, x2X = (_spectra(a, sz) for a in (fx, x0, x2))
        fY, yY, y2Y = self.fy
        n, sx, sy = (np.fft.irfft(a * b, sz) for a, b in ((fX, fY), (xX, fY), (fX, yY)))
        sxx, syy, sxy = (np.fft.irfft(a * b, sz) for a, b in ((x2X, fY), (fX, y2Y), (xX, yY)))
        # irfft(X conj(Y)) is c[k] = sum_i x[i] y[i - k] (negative k wrap to the end)
        with np.errstate(invalid="ignore", divide="ignore"):
            cov = sxy - sx * sy / n
            var = (sxx - sx ** 2 / n) * (syy - sy ** 2 / n)
            r = cov / np.sqrt(var)
        ok = np.isfinite(r) & (var > 1e-12 * np.maximum(n, 1) ** 2)
        if w is None:
            ok &= n >= self.min_n
        return np.where(ok, r, -np.inf)[self.order]


def _ncc(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pearson's correlation of ``x[i]`` with ``y[i - k]`` over the samples both have (NaN:
    none), per lag k (sorted); -inf where they overlap over less than ``MIN_OVERLAP_SHARE`` of
    the shorter or either is constant there."""
    c = _Channel(x, y)
    return c.k, c.correlation()


def _peak(r: np.ndarray, best: int) -> float:
    """The parabola's vertex through the peak and its neighbours [grid steps from ``best``]."""
    if 0 < best < len(r) - 1 and np.isfinite(r[best - 1]) and np.isfinite(r[best + 1]):
        den = r[best - 1] - 2 * r[best] + r[best + 1]
        if den < 0:
            return float(0.5 * (r[best - 1] - r[best + 1]) / den)
    return 0.0


def _at(k: np.ndarray, r: np.ndarray, lag: float) -> float:
    """r interpolated at a fractional lag (NaN outside the lags with a correlation)."""
    i0 = int(np.searchsorted(k, np.floor(lag)))
    if 0 <= i0 < len(k) - 1 and np.isfinite(r[i0]) and np.isfinite(r[i0 + 1]):
        return float(np.interp(lag, k[i0:i0 + 2], r[i0:i0 + 2]))
    return float("nan")


def block_weights(n: int, block: int, rng: np.random.Generator) -> np.ndarray:
    """Counts of a circular block bootstrap of ``n`` samples in blocks of ``block``."""
    block = max(1, min(block, n))
    starts = rng.integers(0, n, int(np.ceil(n / block)))
    idx = (starts[:, None] + np.arange(block)[None, :]).ravel()[:n] % n
    return np.bincount(idx, minlength=n).astype(float)


def fit_clock(est_stamps: np.ndarray, est_poses: np.ndarray, gt_stamps: np.ndarray,
              gt_poses: np.ndarray, period_s: float, replicates: int = BOOTSTRAP_REPLICATES,
              seed: int = 0) -> ClockFit:
    """The shift [s] to add to ``est_stamps`` that best lines up the estimate's speed profile
    (and turn-rate profile) with the ground truth's, with its block-bootstrap interval and
    the interval of the correlation's gain over no shift (see the module docstring)."""
    est_stamps = np.asarray(est_stamps, dtype=np.float64)
    gt_stamps = np.asarray(gt_stamps, dtype=np.float64)
    if len(est_stamps) < 3 or len(gt_stamps) < 3 or not period_s > 0:
        return ClockFit(None, why="too few poses for a speed profile")
    span = max(est_stamps[-1] - est_stamps[0], gt_stamps[-1] - gt_stamps[0])
    h = max(period_s / GRID_STEPS_PER_PERIOD, span / MAX_GRID)
    w = max(HALF_WINDOW_S, period_s)

    def gap(s):
        return max(3.0 * float(np.median(np.diff(s))), 2 * w)

    gt_speed, gt_rate = motion_profiles(gt_stamps, np.asarray(gt_poses), h, w, gap(gt_stamps))
    est_speed, est_rate = motion_profiles(est_stamps, np.asarray(est_poses), h, w,
                                          gap(est_stamps))
    if np.isfinite(gt_speed).sum() < 8 or np.isfinite(est_speed).sum() < 8:
        return ClockFit(None, why="too short for a speed profile")
    channels = []
    spread, turns = float(np.nanstd(gt_speed)), float(np.nanstd(gt_rate))
    if spread >= MIN_SPEED_STD_MPS:
        channels.append(_Channel(gt_speed, est_speed))
    if USE_TURN_RATE and turns >= MIN_TURN_STD_RADPS:
        channels.append(_Channel(gt_rate, est_rate))
    if not channels:
        return ClockFit(None, why=f"the ground truth's speed and turn rate hardly vary "
                                  f"(standard deviations {spread:.2f} m/s, {turns:.3f} rad/s): "
                                  "a constant motion shows no clock")
    k = channels[0].k
    r = np.mean([c.correlation() for c in channels], axis=0)
    best = int(np.argmax(r))
    if not r[best] >= MIN_CORRELATION:
        return ClockFit(None, float(r[best]),
                        why=f"the speed profiles do not line up at any shift (best correlation "
                            f"{r[best]:.2f})")
    base = gt_stamps[0] - est_stamps[0]
    lag = k[best] + _peak(r, best)
    zero = -base / h  # the (fractional) lag of no shift
    r0 = _at(k, r, zero)
    valid = np.isfinite(r)
    rng = np.random.default_rng(seed)
    block = int(np.ceil(BLOCK_S / h))
    lags, gains = np.empty(replicates), np.empty(replicates)
    for b in range(replicates):
        wts = block_weights(len(gt_speed), block, rng)
        rb = np.mean([c.correlation(wts) for c in channels], axis=0)
        rb = np.where(valid, rb, -np.inf)
        i = int(np.argmax(rb))
        lags[b] = k[i] + _peak(rb, i)
        gains[b] = _at(k, rb, lag) - _at(k, rb, zero)
    lo, hi = np.percentile(lags, [50 * (1 - LEVEL), 50 * (1 + LEVEL)])
    gain_lo = (float(np.percentile(gains[np.isfinite(gains)], 50 * (1 - LEVEL)))
               if np.isfinite(gains).any() else float("nan"))
    return ClockFit(float(base + lag * h), float(r[best]), r0,
                    interval_s=(float(base + lo * h), float(base + hi * h)),
                    gain_low=gain_lo, grid_s=float(h))


def aligned_offset(est_stamps: np.ndarray, scan_stamps: np.ndarray, offset_s: float,
                   period_s: float) -> float:
    """``offset_s`` moved by the median distance from the shifted estimate's stamps to their
    nearest scans when that is within half a scan period (the offset that also lines the stamps
    up, for an estimate stamped at the scans), else ``offset_s``."""
    s = np.asarray(est_stamps, dtype=np.float64) + offset_s
    q = np.asarray(scan_stamps, dtype=np.float64)
    if len(q) < 2:
        return offset_s
    hi = np.clip(np.searchsorted(q, s), 1, len(q) - 1)
    lo = hi - 1
    near = np.where(np.abs(q[hi] - s) < np.abs(s - q[lo]), q[hi], q[lo])
    inside = (s >= q[0]) & (s <= q[-1])
    if not inside.any():
        return offset_s
    delta = float(np.median((near - s)[inside]))
    return offset_s + delta if abs(delta) <= 0.5 * period_s else offset_s
