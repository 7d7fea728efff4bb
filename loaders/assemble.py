"""The last step of every loader: a Scan from raw arrays, and the nominal period of a stream.

``finish_scan`` drops points with a non-finite coordinate or Doppler (``warnings.warn`` with the
count) and refuses empty scans with a ``DataError`` naming the file and frame. It also refuses
implausible coordinates: no sensor here sees beyond ``MAX_POINT_RANGE_M`` (10 km; the longest
ranges are a few hundred metres), so a point farther away is a decoding error (a file read with
the wrong record layout gives values up to 3e38 m): a few such points are dropped like NaN
ones, more than ``MAX_FAR_SHARE`` (1 %) of a scan is a ``DataError`` naming the file and frame;
``median_period`` is the median positive step of a stream of stamps.
"""

from __future__ import annotations

import warnings

import numpy as np

from loaders.errors import DataError
from loaders.scan import Scan

#: the farthest a point may lie from its sensor [m] (any coordinate): beyond is a decoding error
MAX_POINT_RANGE_M = 10_000.0
#: more than this share of a scan's points beyond MAX_POINT_RANGE_M refuses the scan
MAX_FAR_SHARE = 0.01


def finish_scan(
    stamp: float,
    points: np.ndarray,
    doppler: np.ndarray | None,
    fields: dict[str, np.ndarray],
    source: str,
    counters: dict | None = None,
) -> Scan:
    """Drop points with a non-finite coordinate or Doppler (``warnings.warn`` with the count,
    added to ``counters["nan_points_dropped"]``) and build the Scan; an empty scan (0 points
    before or after dropping) raises ``DataError`` naming the file and frame."""
    points = np.asarray(points)
    n = len(points)
    if n == 0:
        raise DataError(f"{source}: empty scan (0 points); expected at least one point")
    good = np.isfinite(points).all(axis=1)
    with np.errstate(invalid="ignore"):
        far = good & (np.abs(points) > MAX_POINT_RANGE_M).any(axis=1)
    n_far = int(far.sum())
    if n_far > MAX_FAR_SHARE * n:
        a = np.abs(points[far])
        raise DataError(
            f"{source}: {n_far} of {n} points lie beyond {MAX_POINT_RANGE_M:,.0f} m of the "
            f"sensor (up to {a.max():.3g} m); expected coordinates within that bound: the file "
            "is decoded with the wrong record layout or byte order, or is corrupt")
    good &= ~far
    if doppler is not None:
        good &= np.isfinite(doppler)
    bad = int(n - good.sum())
    if bad:
        warnings.warn(f"{source}: dropped {bad} of {n} points with NaN/inf coordinates or "
                      f"Doppler{f' ({n_far} beyond {MAX_POINT_RANGE_M:,.0f} m)' if n_far else ''}",
                      stacklevel=3)
        if counters is not None:
            counters["nan_points_dropped"] = counters.get("nan_points_dropped", 0) + bad
            counters["frames_with_nan"] = counters.get("frames_with_nan", 0) + 1
        if bad == n:
            raise DataError(f"{source}: empty scan (all {n} points are NaN/inf)")
        points = points[good]
        doppler = None if doppler is None else doppler[good]
        fields = {k: v[good] for k, v in fields.items()}
    return Scan(stamp=stamp, points=points, doppler=doppler, fields=fields, source=source)


def median_period(stamps: np.ndarray, default: float) -> float:
    d = np.diff(np.asarray(stamps, dtype=np.float64))
    d = d[d > 0]
    return float(np.median(d)) if len(d) else default
