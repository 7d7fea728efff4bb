"""Checks of ``bench inspect`` that take nothing on trust: the ground truth's clock against the
sensor's (from the Doppler speed), and advice that names only options the store's loader has.

**GT clock offset.** The Doppler ego speed of every scan is a measurement on the sensor's clock;
the ground truth's speed (central differences of its positions) is on the GT's clock as the
store associated it. Speeding up and slowing down show in both, so the lag that best lines up
the two speed curves (the peak of their normalised cross-correlation, refined by a parabola
through its neighbours) is the GT's clock error: a positive lag means the GT shows each motion
that much later than the sensor. Its uncertainty is a circular block bootstrap over the scans
(blocks of ``BLOCK_S``, ``REPLICATES`` replicates, a ``LEVEL`` interval of the best lag). A lag
is warned about, with the ``--time-offset`` value that removes it (``gt_stamp + offset = sensor
clock``, on top of the offset the store was converted with), only when the whole interval lies
beyond one scan period; a lag beyond a period whose interval reaches back within it is
"inconclusive". A sequence whose speed hardly changes has no such information: the estimate
then says so. (The earlier rule, the spread of the two halves' estimates, warned on 5 of 10
correct 100-frame pieces of the vendored sample: ``bench.studies.inspect_clock_study``.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.data.advice import loader_name, option_flag
from loaders.scan import Sequence

#: the GT speed must vary by at least this much [m/s, standard deviation] to time the GT
MIN_SPEED_STD_MPS = 0.3
#: lags searched [s] (either way) and the step of the search
MAX_LAG_S, LAG_STEP_S = 2.0, 0.01
#: a peak correlation below this is no estimate
MIN_CORRELATION = 0.5
#: the lag's uncertainty: a circular block bootstrap over the scans in blocks of this [s], this
#: many replicates, an interval at this level
BLOCK_S, REPLICATES, LEVEL = 4.0, 200, 0.95
#: fewer blocks than this give no interval (a bootstrap of 2-3 blocks cannot see its spread)
MIN_BLOCKS = 5


@dataclass(frozen=True)
class ClockOffset:
    """The GT's lag behind the sensor clock [s] (positive: GT late), its spread (half the width
    of the bootstrap interval ``interval_s``; NaN when none), the peak correlation, the scans
    used and the ``--time-offset`` that removes the lag (None: inconclusive, ``reason`` says
    why)."""

    lag_s: float | None
    spread_s: float
    correlation: float
    scans: int
    time_offset_s: float | None
    reason: str = ""
    interval_s: tuple[float, float] | None = None


#: both speeds are averaged over +-this window [s] (the same filter on both: no lag between
#: them from the filtering, and less noise than a frame-to-frame difference)
WINDOW_S = 0.5


def _full_window(t: np.ndarray, q: float) -> bool:
    """The window around ``q`` lies inside ``t``'s span (a cut window would shift its centre)."""
    return t[0] <= q - WINDOW_S + 1e-9 and q + WINDOW_S - 1e-9 <= t[-1]


def _window_mean(t: np.ndarray, values: np.ndarray, ok: np.ndarray) -> np.ndarray:
    out = np.full(len(t), np.nan)
    for i in range(len(t)):
        if not _full_window(t, t[i]):
            continue
        k = ok & (np.abs(t - t[i]) <= WINDOW_S)
        if k.any():
            out[i] = values[k].mean()
    return out


def gt_speed(gt, stamps: np.ndarray) -> np.ndarray:
    """GT speed [m/s] at ``stamps``: the slope of a line fitted to the GT positions within
    +-``WINDOW_S`` (NaN where fewer than 3 poses, or where the window is cut by the GT's
    ends)."""
    t, p = gt.stamps, gt.poses[:, :3, 3]
    out = np.full(len(stamps), np.nan)
    for i, q in enumerate(stamps):
        k = np.abs(t - q) <= WINDOW_S
        if k.sum() >= 3 and _full_window(t, q):
            dt = t[k] - t[k].mean()
            slope = (dt[:, None] * (p[k] - p[k].mean(axis=0))).sum(axis=0) / (dt * dt).sum()
            out[i] = float(np.linalg.norm(slope))
    return out


def _correlation(t: np.ndarray, v_doppler: np.ndarray, t_gt: np.ndarray, v_gt: np.ndarray,
                 lag: float) -> float:
    """Pearson correlation of the Doppler speed at ``t`` with the GT speed at ``t + lag``, over
    the scans whose shifted time lies inside the GT's span."""
    q = t + lag
    inside = (q >= t_gt[0]) & (q <= t_gt[-1])
    if inside.sum() < 10:
        return np.nan
    a = v_doppler[inside] - v_doppler[inside].mean()
    b = np.interp(q[inside], t_gt, v_gt)
    b = b - b.mean()
    den = np.sqrt((a * a).sum() * (b * b).sum())
    return float((a * b).sum() / den) if den > 0 else np.nan


def _best_lag(t, v_d, v_g) -> tuple[float | None, float, str]:
    """(lag, peak correlation, why not) of the Doppler speed against the GT speed."""
    use, has_gt = np.isfinite(v_d), np.isfinite(v_g)
    if use.sum() < 10 or has_gt.sum() < 10:
        return None, np.nan, "too few scans with both a Doppler speed and ground truth"
    if np.std(v_g[has_gt]) < MIN_SPEED_STD_MPS:
        return None, np.nan, (f"the speed hardly changes (GT speed std "
                              f"{np.std(v_g[has_gt]):.2f} m/s): nothing to line up")
    lags = np.arange(-MAX_LAG_S, MAX_LAG_S + LAG_STEP_S / 2, LAG_STEP_S)
    corr = np.array([_correlation(t[use], v_d[use], t[has_gt], v_g[has_gt], lag)
                     for lag in lags])
    if not np.isfinite(corr).any():
        return None, np.nan, "the speeds do not overlap"
    k = int(np.nanargmax(corr))
    if corr[k] < MIN_CORRELATION:
        return None, float(corr[k]), f"the speeds agree poorly (correlation {corr[k]:.2f})"
    if k in (0, len(lags) - 1):
        return None, float(corr[k]), (f"the best lag is at the edge of the search "
                                      f"(+-{MAX_LAG_S:g} s)")
    lag = float(lags[k])
    den = corr[k - 1] - 2 * corr[k] + corr[k + 1]
    if np.isfinite(den) and den < 0:  # the parabola's vertex through the peak's neighbours
        lag += float(0.5 * (corr[k - 1] - corr[k + 1]) / den) * LAG_STEP_S
    return lag, float(corr[k]), ""


def gt_clock_offset(stamps: np.ndarray, speed_doppler: np.ndarray, observable: np.ndarray,
                    gt, converted_offset_s: float = 0.0) -> ClockOffset:
    """The GT's clock lag: Doppler speeds at the scan ``stamps`` (``observable`` marks the
    frames where the ego velocity was observable) against the speed of the ground truth
    ``gt`` (a ``Trajectory`` of T_world_sensor), with its block-bootstrap interval;
    ``converted_offset_s``: the time offset the store was converted with (the suggested
    ``--time-offset`` adds to it)."""
    t = np.asarray(stamps, float)
    ok = np.isfinite(speed_doppler) & np.asarray(observable, bool)
    v_d = _window_mean(t, np.nan_to_num(np.asarray(speed_doppler, float)), ok)
    v_g = gt_speed(gt, t) if gt is not None and len(gt) >= 3 else np.full(len(t), np.nan)
    lag, corr, why = _best_lag(t, v_d, v_g)
    scans = int(ok.sum())
    if lag is None:
        return ClockOffset(None, np.nan, corr, scans, None, why)
    interval = lag_interval(t, v_d, v_g)
    spread = np.nan if interval is None else (interval[1] - interval[0]) / 2
    return ClockOffset(lag, spread, corr, scans, converted_offset_s - lag, interval_s=interval)


def lag_interval(t: np.ndarray, v_d: np.ndarray, v_g: np.ndarray, seed: int = 0
                 ) -> tuple[float, float] | None:
    """The ``LEVEL`` interval of the best lag under a circular block bootstrap of the scans
    (the same lags and correlation as ``_best_lag``, with weights); None when too few scans."""
    use, has_gt = np.isfinite(v_d), np.isfinite(v_g)
    if use.sum() < 10 or has_gt.sum() < 10:
        return None
    lags = np.arange(-MAX_LAG_S, MAX_LAG_S + LAG_STEP_S / 2, LAG_STEP_S)
    td, vd, tg, vg = t[use], v_d[use], t[has_gt], v_g[has_gt]
    q = td[None, :] + lags[:, None]
    inside = (q >= tg[0]) & (q <= tg[-1])
    b = np.where(inside, np.interp(q, tg, vg), 0.0)
    period = float(np.median(np.diff(td))) if len(td) > 1 else 1.0
    block = max(1, int(round(BLOCK_S / max(period, 1e-9))))
    if len(td) < MIN_BLOCKS * block:
        return None
    rng = np.random.default_rng(seed)
    found = []
    for _ in range(REPLICATES):
        starts = rng.integers(0, len(td), int(np.ceil(len(td) / block)))
        idx = (starts[:, None] + np.arange(block)[None, :]).ravel()[:len(td)] % len(td)
        w = np.bincount(idx, minlength=len(td)).astype(float) * inside
        n = w.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            ma, mb = (w * vd).sum(axis=1) / n, (w * b).sum(axis=1) / n
            da, db = vd[None, :] - ma[:, None], b - mb[:, None]
            r = (w * da * db).sum(axis=1) / np.sqrt((w * da ** 2).sum(axis=1)
                                                    * (w * db ** 2).sum(axis=1))
        r = np.where((inside.sum(axis=1) >= 10) & np.isfinite(r), r, -np.inf)
        k = int(np.argmax(r))
        if not np.isfinite(r[k]):
            continue
        lag = float(lags[k])
        if 0 < k < len(lags) - 1 and np.isfinite(r[k - 1]) and np.isfinite(r[k + 1]):
            den = r[k - 1] - 2 * r[k] + r[k + 1]
            if den < 0:
                lag += float(0.5 * (r[k - 1] - r[k + 1]) / den) * LAG_STEP_S
        found.append(lag)
    if len(found) < REPLICATES // 2:
        return None
    lo, hi = np.percentile(found, [50 * (1 - LEVEL), 50 * (1 + LEVEL)])
    return float(lo), float(hi)


def converted_offset(provenance: dict) -> float:
    """The GT time offset a store was converted with (0 when not recorded)."""
    gt = provenance.get("gt_association")
    value = gt.get("offset_s") if isinstance(gt, dict) else provenance.get("time_offset_s")
    try:
        return float(value or 0.0)
    except (TypeError, ValueError):
        return 0.0


def clock_offset_lines(seq: Sequence, speeds: dict) -> list[tuple[str, str]]:
    """(style, line) to print: the estimated GT clock lag (``speeds``: the output of
    ``methods.ego_velocity.speed_from_doppler``), and a warning with the ``--time-offset`` to
    use when the whole bootstrap interval lies beyond one scan period (a lag beyond a period
    whose interval reaches within it: inconclusive)."""
    est = gt_clock_offset(speeds["stamps"], speeds["speed_doppler"], speeds["observable"],
                          seq.ground_truth, converted_offset(seq.provenance))
    if est.lag_s is None:
        return [("dim", f"GT clock vs Doppler speed: not estimated ({est.reason})")]
    period = float(np.median(np.diff(seq.stamps))) if len(seq) > 1 else seq.sensor.period_s
    iv = est.interval_s
    spread = (f" (95 % block-bootstrap interval [{iv[0]:+.3f}, {iv[1]:+.3f}] s)"
              if iv is not None else f" (too few scans for an interval: under {MIN_BLOCKS} "
              f"blocks of {BLOCK_S:g} s)")
    text = (f"GT clock vs Doppler speed: the ground truth lags the sensor by {est.lag_s:+.3f} s"
            f"{spread}; cross-correlation of the speeds {est.correlation:.2f} over {est.scans} "
            f"scans, one scan period {period:.3f} s")
    if abs(est.lag_s) <= period:
        if iv is not None and -period <= iv[0] and iv[1] <= period:
            return [("green", text + ": within one scan period")]
        return [("dim", text + ": within one scan period, but the interval reaches beyond: "
                               "this sequence cannot time the ground truth")]
    flag = option_flag(seq.provenance, "time_offset_s")
    how = (f"convert again with --time-offset {est.time_offset_s:.3f}" if flag else
           f"shift the GT stamps by {-est.lag_s:+.3f} s (gt_stamp + offset = sensor clock; "
           f"{loader_name(seq.provenance)} takes no time-offset option)")
    if iv is None or not (iv[0] > period or iv[1] < -period):
        return [("yellow", f"{text}: more than a period, but the interval reaches within one "
                           f"period: inconclusive on this sequence (if confirmed: {how})")]
    return [("yellow", f"warning: {text}: more than one scan period, so every scored pose is "
                       f"compared with the wrong moment; {how}")]


def height_advice(seq: Sequence, z: dict) -> str:
    """The height check's line (``loaders.doppler_check.low_points_median_z``), its advice
    naming only an option the store's loader has."""
    basis = f"; {z['basis']}" if z.get("basis") else ""
    share = z.get("frames_below_sensor")
    below = (f", {100 * share:.0f} % of them with their own layer below" if share is not None
             and np.isfinite(share) else "")
    frames = (f"the height most of {z['frames']} frames across the sequence agree on{below}"
              f"{basis}" if z.get("frames") else z.get("basis", ""))
    line = (f"densest layer at z = {z['dominant_layer_z_m']:+.2f} m"
            + (f" ({frames})" if frames else "") + f": {z['verdict']}")
    if z["dominant_layer_z_m"] < 0:
        return line
    flag = option_flag(seq.provenance, "elevation_sign")
    if flag:
        return (f"{line}; if the road is below the sensor, convert again with {flag} -1 "
                f"(bench convert {loader_name(seq.provenance)})")
    return (f"{line}; {loader_name(seq.provenance)} takes no elevation-sign option (its points' "
            "z is as the sensor recorded it): check the sensor's mounting and the extrinsic")
