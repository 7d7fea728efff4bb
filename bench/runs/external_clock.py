"""Is an external trajectory on the scans' clock? Its speed profile against the ground truth's.

Stamp matching alone cannot tell: an estimate shifted by a whole number of scan periods matches
every stamp it overlaps (as evo's association would). The speed of the sensor along its path
does not depend on the world frame, the start point or the scale of an estimate made elsewhere
(Pearson's correlation ignores the scale), so two trajectories of one drive on one clock have
speed profiles that line up at zero shift. Two checks (``bench.runs.external`` applies them):

- ``stamp_unit``: the estimate's stamps in another unit (ms, us, ns) move it 10^3, 10^6, 10^9
  times more slowly per stamp unit than the ground truth moves per second (its path over its
  span against the ground truth's);
- ``fit_clock``: the shift ``tau`` [s] that, added to the estimate's stamps, best lines up its
  speed profile with the ground truth's (the normalised cross-correlation of the two profiles,
  both sampled every ``period / GRID_STEPS_PER_PERIOD``, refined between grid steps by a
  parabola through the peak: sub-scan-period precision), with the correlation at zero shift.

A speed profile says nothing when the ground truth's speed hardly varies (a constant-speed
drive: ``MIN_SPEED_STD_MPS``) or when the best correlation is weak (``MIN_CORRELATION``): the
fit is then inconclusive (``offset_s`` None, ``why`` says so) and nothing is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: speed profiles are sampled this many times a scan period (sub-period precision)
GRID_STEPS_PER_PERIOD = 8
#: at most this many samples a profile (long sequences get a coarser grid)
MAX_GRID = 2**15
#: the speed at t is the distance between the positions at t -/+ this many scan periods
HALF_WINDOW_PERIODS = 1.0
#: profiles are compared at shifts where they overlap over at least this share of the shorter
MIN_OVERLAP_SHARE = 0.5
#: the ground truth's speed must vary at least this much [m/s] for a profile to say anything
MIN_SPEED_STD_MPS = 0.2
#: a best correlation below this is no fit
MIN_CORRELATION = 0.5
#: the unit check needs the ground truth to move at least this fast on average [m/s]
MIN_MEAN_SPEED_MPS = 0.1
#: stamp units other than seconds: name -> seconds per unit
UNITS = {"ms": 1e-3, "us": 1e-6, "ns": 1e-9}


@dataclass(frozen=True)
class ClockFit:
    """``offset_s``: the shift to add to the estimate's stamps that best lines up the speed
    profiles (None: inconclusive, ``why``); ``correlation`` there and ``correlation_at_zero``
    (at no shift; NaN when the profiles do not overlap unshifted)."""

    offset_s: float | None
    correlation: float = float("nan")
    correlation_at_zero: float = float("nan")
    why: str = ""


def path_speed(stamps: np.ndarray, positions: np.ndarray) -> float:
    """Path length over time span [m per stamp unit]."""
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    span = float(stamps[-1] - stamps[0])
    return float(steps.sum() / span) if span > 0 else 0.0


def stamp_unit(est_stamps: np.ndarray, est_xyz: np.ndarray, gt_stamps: np.ndarray,
               gt_xyz: np.ndarray) -> tuple[str, float, float] | None:
    """The unit the estimate's stamps look to be in ("ms", "us", "ns") with the two speeds
    (the estimate's per stamp unit, the ground truth's [m/s]), or None when they look like
    seconds or the ground truth hardly moves."""
    gt_speed = path_speed(gt_stamps, gt_xyz)
    est_speed = path_speed(est_stamps, est_xyz)
    if gt_speed < MIN_MEAN_SPEED_MPS or est_speed <= 0:
        return None
    decades = np.log10(est_speed / gt_speed)
    for unit, seconds in UNITS.items():
        if abs(decades - np.log10(seconds)) <= 1.0:  # within 10x of the unit's ratio
            return unit, est_speed, gt_speed
    return None


def speed_profile(stamps: np.ndarray, xyz: np.ndarray, h: float, half_window_s: float,
                  max_gap_s: float) -> np.ndarray:
    """Speed [m/s] every ``h`` from ``stamps[0]`` to ``stamps[-1]``: the distance between the
    (linearly interpolated) positions ``half_window_s`` before and after, over twice that;
    NaN where the window leaves the span or a gap longer than ``max_gap_s`` lies under it."""
    t = stamps[0] + h * np.arange(int(np.floor((stamps[-1] - stamps[0]) / h)) + 1)
    lo, hi = t - half_window_s, t + half_window_s

    def at(q):
        return np.column_stack([np.interp(q, stamps, xyz[:, k]) for k in range(3)])

    speed = np.linalg.norm(at(hi) - at(lo), axis=1) / (2 * half_window_s)
    i_lo = np.clip(np.searchsorted(stamps, lo, side="right") - 1, 0, len(stamps) - 1)
    i_hi = np.clip(np.searchsorted(stamps, hi, side="left"), 0, len(stamps) - 1)
    widest = _range_max(np.diff(stamps), i_lo, i_hi)  # the widest step under the window
    ok = (lo >= stamps[0]) & (hi <= stamps[-1]) & (widest <= max_gap_s)
    return np.where(ok, speed, np.nan)


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


def _correlate(a: np.ndarray, b: np.ndarray, size: int) -> np.ndarray:
    """c[k] = sum_i a[i] b[i - k] for k = 0 .. size-1 (negative k wrap to the end)."""
    return np.fft.irfft(np.fft.rfft(a, size) * np.conj(np.fft.rfft(b, size)), size)


def fit_clock(est_stamps: np.ndarray, est_xyz: np.ndarray, gt_stamps: np.ndarray,
              gt_xyz: np.ndarray, period_s: float) -> ClockFit:
    """The shift [s] to add to ``est_stamps`` that best lines up the speed profiles (see the
    module docstring)."""
    est_stamps = np.asarray(est_stamps, dtype=np.float64)
    gt_stamps = np.asarray(gt_stamps, dtype=np.float64)
    if len(est_stamps) < 3 or len(gt_stamps) < 3 or not period_s > 0:
        return ClockFit(None, why="too few poses for a speed profile")
    span = max(est_stamps[-1] - est_stamps[0], gt_stamps[-1] - gt_stamps[0])
    h = max(period_s / GRID_STEPS_PER_PERIOD, span / MAX_GRID)
    w = HALF_WINDOW_PERIODS * period_s

    def gap(s):
        return max(3.0 * float(np.median(np.diff(s))), 2 * w)

    x = speed_profile(gt_stamps, gt_xyz, h, w, gap(gt_stamps))
    y = speed_profile(est_stamps, est_xyz, h, w, gap(est_stamps))
    mx, my = np.isfinite(x), np.isfinite(y)
    if mx.sum() < 8 or my.sum() < 8:
        return ClockFit(None, why="too short for a speed profile")
    if float(np.std(x[mx])) < MIN_SPEED_STD_MPS:
        return ClockFit(None, why=f"the ground truth's speed hardly varies (standard deviation "
                                  f"{np.std(x[mx]):.2f} m/s)")
    x0, y0 = np.where(mx, x, 0.0), np.where(my, y, 0.0)
    fx, fy = mx.astype(float), my.astype(float)
    size = 1 << int(np.ceil(np.log2(len(x) + len(y))))
    n = _correlate(fx, fy, size)
    sx, sy = _correlate(x0, fy, size), _correlate(fx, y0, size)
    sxx, syy = _correlate(x0 ** 2, fy, size), _correlate(fx, y0 ** 2, size)
    sxy = _correlate(x0, y0, size)
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = sxy - sx * sy / n
        var = (sxx - sx ** 2 / n) * (syy - sy ** 2 / n)
        r = cov / np.sqrt(var)
    k = np.arange(size)
    k = np.where(k < size // 2, k, k - size)  # lag in grid steps
    enough = n >= max(MIN_OVERLAP_SHARE * min(mx.sum(), my.sum()), 8) - 0.5
    r = np.where(enough & np.isfinite(r) & (var > 0), r, -np.inf)
    order = np.argsort(k)
    k, r = k[order], r[order]
    best = int(np.argmax(r))
    if not r[best] >= MIN_CORRELATION:
        return ClockFit(None, float(r[best]),
                        why=f"the speed profiles do not line up at any shift (best correlation "
                            f"{r[best]:.2f})")
    step = 0.0
    if 0 < best < len(r) - 1 and np.isfinite(r[best - 1]) and np.isfinite(r[best + 1]):
        den = r[best - 1] - 2 * r[best] + r[best + 1]
        step = 0.5 * (r[best - 1] - r[best + 1]) / den if den < 0 else 0.0
    base = gt_stamps[0] - est_stamps[0]
    offset = base + (k[best] + step) * h
    zero = -base / h  # the (fractional) lag of no shift
    i0 = int(np.searchsorted(k, np.floor(zero)))
    r0 = float("nan")
    if 0 <= i0 < len(k) - 1 and np.isfinite(r[i0]) and np.isfinite(r[i0 + 1]):
        r0 = float(np.interp(zero, k[i0:i0 + 2], r[i0:i0 + 2]))
    return ClockFit(float(offset), float(r[best]), r0)
