"""Sanity checks of a sequence's conventions: the Doppler sign, the Doppler kind (raw radial or
ego-compensated) and (radar) the elevation sign.

Doppler sign check: fit the ego velocity from Doppler and compare it with ground truth.

For a static scene, doppler_i = -d_i . v_sensor (receding positive, d_i the unit direction of
point i, v_sensor the sensor's velocity in its own frame). A per-frame least-squares fit of
v_sensor (with a robust second pass that drops moving points) is compared with the velocity of
the ground-truth sensor poses: a cosine near +1 confirms the convention, near -1 means it is
flipped; the speed ratio |v_doppler| / |v_gt| near 1 also confirms the time base (period).

Doppler kind check (``doppler_kind_check``): with GT motion, static points of raw radial Doppler
read ``-d . v_gt``; ego-compensated Doppler (the dataset removed the sensor's motion, e.g.
HeLiPR's Aeva velocities) reads about 0 m/s for them while the sensor moves. The share of points
fitting each says which the data are, whatever the loader declared.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loaders.errors import DataError
from loaders.scan import Scan, Sequence


def ego_velocity_from_doppler(points: np.ndarray, doppler: np.ndarray) -> np.ndarray | None:
    """Least-squares v_sensor [m/s, sensor frame] from doppler = -d . v; None if ill-posed."""
    r = np.linalg.norm(points, axis=1)
    ok = r > 0.5
    if ok.sum() < 10:
        return None
    A = -points[ok] / r[ok, None]
    b = doppler[ok]
    v = np.linalg.lstsq(A, b, rcond=None)[0]
    resid = np.abs(A @ v - b)
    inliers = resid <= max(3.0 * np.median(resid), 0.2)  # drop moving points and clutter
    if inliers.sum() >= 10:
        v = np.linalg.lstsq(A[inliers], b[inliers], rcond=None)[0]
    return v


GT_SPEED_HALF_WINDOW_S = 0.5


def half_window_frames(stamps: np.ndarray, half_window_s: float = GT_SPEED_HALF_WINDOW_S) -> int:
    """Frames in +-``half_window_s`` at the median period (at least 2). Ground truth at a lower
    rate resampled to the scans (NTU4DRadLM: 10 Hz onto 12 Hz, one pose in six repeated) makes
    differences over a few frames jump by a whole GT step; over a second the jump is ~5 %."""
    dt = np.diff(stamps)
    period = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    return max(2, int(np.ceil(half_window_s / period)))


def gt_velocities(stamps: np.ndarray, poses: np.ndarray, half_window: int | None = None
                  ) -> np.ndarray:
    """Sensor-frame linear velocity from GT poses T_world_sensor by central differences over
    +-half_window frames (default: +-0.5 s, robust to repeated GT poses)."""
    if half_window is None:
        half_window = half_window_frames(stamps)
    n = len(stamps)
    lo = np.clip(np.arange(n) - half_window, 0, n - 1)
    hi = np.clip(np.arange(n) + half_window, 0, n - 1)
    dt = stamps[hi] - stamps[lo]
    dt[dt == 0] = np.nan
    v_world = (poses[hi, :3, 3] - poses[lo, :3, 3]) / dt[:, None]
    return np.einsum("nji,nj->ni", poses[:, :3, :3], v_world)  # R^T v


#: a Doppler / GT speed ratio further from 1 than this questions the stamps (the period)
SPEED_RATIO_TOLERANCE = 0.10


@dataclass
class SignCheck:
    frames_used: int
    median_cosine: float
    median_speed_ratio: float
    verdict: str  # "confirmed", "flipped", "inconclusive", "no ground truth", "no Doppler"

    def describe(self) -> str:
        if self.frames_used == 0:
            return f"Doppler sign check: {self.verdict}"
        return (f"Doppler sign check over {self.frames_used} moving frames: median cosine "
                f"{self.median_cosine:+.3f}, median speed ratio {self.median_speed_ratio:.3f} "
                f"-> receding-positive convention {self.verdict}")


def doppler_sign_check(seq: Sequence, gt_poses: np.ndarray | None, max_frames: int = 200,
                       min_speed_mps: float = 0.5) -> SignCheck:
    """Compare Doppler ego velocity with GT velocity on up to ``max_frames`` frames.

    ``gt_poses``: T_world_sensor at the scan stamps (None: no ground truth)."""
    if gt_poses is None:
        return SignCheck(0, np.nan, np.nan, "not checked (no ground truth)")
    stamps = seq.stamps
    v_gt = gt_velocities(stamps, gt_poses)
    idx = np.unique(np.linspace(0, len(seq) - 1, min(max_frames, len(seq))).astype(int))
    cosines, ratios = [], []
    for i in idx:
        speed = np.linalg.norm(v_gt[i])
        if not np.isfinite(speed) or speed < min_speed_mps:
            continue
        scan: Scan = seq[int(i)]
        if scan.doppler is None:
            return SignCheck(0, np.nan, np.nan, "not checked (no Doppler)")
        v = ego_velocity_from_doppler(scan.points, scan.doppler)
        if v is None or np.linalg.norm(v) == 0:
            continue
        cosines.append(float(v @ v_gt[i] / (np.linalg.norm(v) * speed)))
        ratios.append(float(np.linalg.norm(v) / speed))
    if not cosines:
        return SignCheck(0, np.nan, np.nan, "inconclusive (no moving frames)")
    cos, ratio = float(np.median(cosines)), float(np.median(ratios))
    verdict = "confirmed" if cos > 0.5 else "appears FLIPPED" if cos < -0.5 else "inconclusive"
    if verdict == "confirmed" and abs(ratio - 1.0) > SPEED_RATIO_TOLERANCE:
        # the direction agrees but the speed does not: a wrong scan period or GT clock (e.g.
        # 0.1 s GT rows taken as the stamps of a 12 Hz radar) scales every speed
        verdict = (f"confirmed in direction, but the Doppler speed is {ratio:.2f} x the GT "
                   "speed: check the scan stamps (their period) and the GT clock, which "
                   "scale every speed")
    return SignCheck(len(cosines), cos, ratio, verdict)


#: the height check looks at the points within this horizontal range of the sensor [m]: near
#: the sensor the densest layer is the road; farther out, walls, trees and vehicles' roofs can
#: outnumber it (stores whose densest layer over all ranges sat at z = +2.1 m had the road at
#: -0.5 m within 30 m)
NEAR_FIELD_M = 30.0
#: fewer near-field points than this: the check uses every point and says so
MIN_NEAR_POINTS = 200
LAYER_M = 0.25


def _densest_layer(z: np.ndarray) -> float:
    """The median z of the densest ``LAYER_M`` height layer."""
    edges = np.arange(np.floor(z.min()), np.ceil(z.max()) + 2 * LAYER_M, LAYER_M)
    if len(edges) < 2:
        edges = np.array([z.min() - LAYER_M / 2, z.max() + LAYER_M / 2])
    hist, edges = np.histogram(z, bins=edges)
    k = int(np.argmax(hist))
    return float(np.median(z[(z >= edges[k]) & (z <= edges[k + 1])]))


#: the height check samples this many frames evenly across the whole sequence: a stretch of
#: frames can have its densest near layer above the sensor (the real NTU4DRadLM sample's frames
#: 200-229: +1.4 m, a wall or vehicle beside the road), so no check reads only the first frames
HEIGHT_FRAMES = 60
#: a sampled frame with fewer near-field points than this gives no layer of its own
MIN_FRAME_POINTS = 20


def low_points_median_z(sequence: Sequence, frames: int = HEIGHT_FRAMES, quantile: float = 0.1,
                        near_field_m: float = NEAR_FIELD_M) -> dict:
    """Elevation-sign check on up to ``frames`` scans sampled evenly across the whole sequence,
    on the near field: the points within ``near_field_m`` (horizontal range) of the sensor
    (with fewer than ``MIN_NEAR_POINTS`` there over the sampled frames, every point, said in
    ``basis``). Each sampled frame gives the z of its densest 0.25 m layer (the road surface,
    mostly); the ground estimate (``dominant_layer_z_m``) is the height most frames agree on:
    the densest layer of those per-frame heights, so a stretch of frames where a wall or a
    vehicle outnumbers the road does not decide it. With the right ``elevation_sign`` the road
    comes out BELOW the sensor (about minus the mounting height, e.g. -0.5 m for a bumper
    radar); mirrored, it comes out above. Also reported: the share of frames whose own layer is
    below the sensor, the median z of the lowest ``quantile`` of the points, the share of
    points above the sensor and the densest layer of every point over all ranges
    (``all_ranges_layer_z_m``: far away, buildings and trees can outnumber the road)."""
    n = len(sequence)
    if n == 0:
        raise DataError(f"{sequence.name}: no frames to check")
    idx = np.unique(np.linspace(0, n - 1, min(frames, n)).round().astype(int))
    pts = [np.asarray(sequence.scan(int(i)).points, dtype=np.float64) for i in idx]
    near = [np.hypot(p[:, 0], p[:, 1]) <= near_field_m for p in pts]
    if sum(int(k.sum()) for k in near) >= MIN_NEAR_POINTS:
        zs, basis = [p[k, 2] for p, k in zip(pts, near, strict=True)], \
            f"points within {near_field_m:g} m"
    else:
        zs = [p[:, 2] for p in pts]
        basis = (f"all points (only {sum(int(k.sum()) for k in near)} within "
                 f"{near_field_m:g} m, fewer than {MIN_NEAR_POINTS})")
    zn = np.concatenate(zs)
    per_frame = np.array([_densest_layer(z) for z in zs if len(z) >= MIN_FRAME_POINTS])
    layer = _densest_layer(per_frame) if len(per_frame) else _densest_layer(zn)
    z = np.concatenate([p[:, 2] for p in pts])
    low = zn[zn <= np.quantile(zn, quantile)]
    return {
        "frames": int(len(idx)),
        "frames_with_layer": int(len(per_frame)),
        "points": int(len(zn)),
        "basis": basis,
        "low_points_median_z_m": float(np.median(low)),
        "dominant_layer_z_m": layer,
        "frames_below_sensor": float((per_frame < 0).mean()) if len(per_frame) else float("nan"),
        "all_ranges_layer_z_m": _densest_layer(z),
        "median_z_m": float(np.median(zn)),
        "share_above_sensor": float((zn > 0).mean()),
        "verdict": ("road below the sensor (sign looks right)" if layer < 0 else
                    "densest layer above the sensor (the elevation looks mirrored)"),
    }


#: a point fits a hypothesis when its Doppler is within this of the predicted value: the larger
#: of an absolute floor and a share of the sensor speed [m/s]
KIND_TOLERANCE_MPS = 0.15
KIND_TOLERANCE_SHARE = 0.1


@dataclass
class KindCheck:
    """What a sequence's Doppler values are, measured against the GT motion.

    Over moving frames, each point whose predicted static-world radial velocity ``-d . v_gt``
    is clearly non-zero is tested against two hypotheses: raw radial velocity of a static point
    (``doppler = -d . v_gt``, either sign: the sign check is separate) and ego-compensated
    (``doppler`` about 0). Most of a scene is static, so the larger share says which it is."""

    declared: str
    frames_used: int
    share_radial: float
    share_compensated: float
    measured: str  # "radial", "ego-compensated", "inconclusive", "not checked (...)"

    @property
    def disagrees(self) -> bool:
        """The measurement contradicts the declared kind (a gt-reconstructed store is radial)."""
        if self.measured not in ("radial", "ego-compensated"):
            return False
        declared = "radial" if self.declared == "gt-reconstructed" else self.declared
        return declared != self.measured

    def describe(self) -> str:
        head = f"Doppler kind: declared {self.declared}"
        if self.frames_used == 0:
            return f"{head}; measured: {self.measured}"
        text = (f"{head}; measured over {self.frames_used} moving frames: "
                f"{100 * self.share_radial:.0f} % of the points fit the raw radial velocity of "
                f"a static world, {100 * self.share_compensated:.0f} % read about 0 m/s -> "
                f"{self.measured}")
        if self.measured == "ego-compensated":
            text += (": the sensor's own motion is already removed (static points near 0 m/s "
                     "while the sensor moves); a Doppler method cannot use it as radial "
                     "velocity")
        if self.disagrees:
            text += f" - this DISAGREES with the declared kind ({self.declared})"
        if self.declared == "gt-reconstructed":
            text += (" (rebuilt from the GT's ego motion: every result from this store is "
                     "GT-assisted)")
        return text


def doppler_kind_check(seq: Sequence, gt_poses: np.ndarray | None, max_frames: int = 100,
                       min_speed_mps: float = 1.0) -> KindCheck:
    """Measure whether the Doppler is raw radial or ego-compensated (``KindCheck``) on up to
    ``max_frames`` frames moving faster than ``min_speed_mps``. ``gt_poses``: T_world_sensor at
    the scan stamps (NaN where a frame has none; None: no ground truth)."""
    declared = seq.sensor.doppler_kind
    if gt_poses is None:
        return KindCheck(declared, 0, np.nan, np.nan, "not checked (no ground truth)")
    v_gt = gt_velocities(seq.stamps, gt_poses)
    idx = np.unique(np.linspace(0, len(seq) - 1, min(max_frames, len(seq))).astype(int))
    fits_radial = fits_zero = total = frames = 0
    for i in idx:
        v = v_gt[i]
        speed = float(np.linalg.norm(v))
        if not np.isfinite(speed) or speed < min_speed_mps:
            continue
        scan: Scan = seq[int(i)]
        if scan.doppler is None:
            return KindCheck(declared, 0, np.nan, np.nan, "not checked (no Doppler)")
        r = np.linalg.norm(scan.points, axis=1)
        ok = r > 0.5
        predicted = -(scan.points[ok] / r[ok, None]) @ v
        tol = max(KIND_TOLERANCE_MPS, KIND_TOLERANCE_SHARE * speed)
        telling = np.abs(predicted) > 3 * tol  # the two hypotheses differ clearly here
        if telling.sum() < 10:
            continue
        d = scan.doppler[ok][telling]
        p = predicted[telling]
        fits_radial += int(((np.abs(d - p) <= tol) | (np.abs(d + p) <= tol)).sum())
        fits_zero += int((np.abs(d) <= tol).sum())
        total += len(d)
        frames += 1
    if total == 0:
        return KindCheck(declared, 0, np.nan, np.nan, "inconclusive (no moving frames)")
    radial, zero = fits_radial / total, fits_zero / total
    measured = ("ego-compensated" if zero >= 0.5 and zero > 2 * radial else
                "radial" if radial >= 0.5 and radial > 2 * zero else "inconclusive")
    return KindCheck(declared, frames, radial, zero, measured)
