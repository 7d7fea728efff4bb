"""The sensor's linear velocity from one scan's Doppler (the ego velocity), robustly.

For a static point at unit direction d (sensor frame) the measured radial velocity is
``doppler = -d . v`` (v: the sensor's linear velocity in the sensor frame [m/s]; Doppler is
positive when the point recedes). A scan of N points is N linear equations in the 3 unknowns of
v; points on moving objects, ghosts and clutter do not obey them. So:

1. RANSAC: hypotheses from 3-point samples (solve 3x3), each scored by how many points agree
   within ``threshold_mps`` (scored on a fixed random subset for dense scans);
2. least squares on the best hypothesis' inliers, inliers re-selected, repeated a few times;
3. optionally (``gate_sigmas``), on the scan's own noise: sigma = the robust (MAD) sigma of all
   residuals; the velocity by Cauchy-weighted least squares (scale ``cauchy_sigmas`` sigma) of
   the points within ``threshold_mps``, and the inliers (static points) those within
   ``gate_sigmas`` sigma of it. On the real Eagle the residual tail beyond 3 sigma (a few %)
   tilted the plain least-squares velocity down by about 0.4 deg and its points, off in
   position as well, hurt the registration;
4. covariance ``sigma^2 (D^T D)^-1`` with sigma^2 from the inlier residuals.

"Not observable" is a result, not an exception: when too few points agree, or when the inlier
directions do not span enough of the sphere (the smallest singular value of D / sqrt(n), the
RMS extent of the directions along their thinnest axis, is below ``min_spread``: e.g. a
planar sensor, or every point straight ahead), ``observable`` is False and ``velocity`` is NaN.
An angular velocity is never observable from one sensor's Doppler: d . (w x p) = 0.

The RNG is seeded (``seed``), so the same scan always gives the same answer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from loaders.doppler_check import gt_velocities


@dataclass(frozen=True)
class EgoVelocity:
    """One scan's ego velocity.

    velocity: (3,) sensor linear velocity [m/s, sensor frame] (NaN when not observable).
    inliers: (N,) bool, the points that agree (static points). covariance: (3, 3) [m^2/s^2].
    sigma_mps: RMS Doppler residual of the inliers [m/s]. spread: smallest singular value of the
    inlier direction matrix over sqrt(n) [-]. reason: why not observable ("" when observable).
    """

    velocity: np.ndarray
    inliers: np.ndarray
    covariance: np.ndarray
    sigma_mps: float
    spread: float
    observable: bool
    reason: str = ""

    @property
    def speed_mps(self) -> float:
        return float(np.linalg.norm(self.velocity))


def _not_observable(n: int, reason: str, inliers=None, spread: float = 0.0) -> EgoVelocity:
    nan3 = np.full(3, np.nan)
    mask = np.zeros(n, dtype=bool) if inliers is None else inliers
    return EgoVelocity(nan3, mask, np.full((3, 3), np.nan), float("nan"), spread, False, reason)


def estimate_ego_velocity(
    points: np.ndarray,
    doppler: np.ndarray,
    threshold_mps: float = 0.2,
    hypotheses: int = 100,
    min_inliers: int = 10,
    min_inlier_ratio: float = 0.2,
    min_spread: float = 0.03,
    min_range_m: float = 0.5,
    refinements: int = 3,
    max_score_points: int = 1500,
    seed: int = 0,
    gate_sigmas: float | None = None,
    cauchy_sigmas: float = 1.5,
    irls_iterations: int = 5,
) -> EgoVelocity:
    """Ego velocity of the sensor from one scan: points (N, 3) [m, sensor frame], doppler (N,)
    [m/s, receding positive]. See the module docstring for the method and its outputs."""
    points = np.asarray(points, dtype=np.float64)
    doppler = np.asarray(doppler, dtype=np.float64)
    n = len(points)
    rng_m = np.linalg.norm(points, axis=1)
    usable = rng_m > min_range_m
    if usable.sum() < max(min_inliers, 3):
        return _not_observable(n, f"only {int(usable.sum())} points beyond {min_range_m} m")
    idx_all = np.flatnonzero(usable)
    D = points[idx_all] / rng_m[idx_all, None]
    r = doppler[idx_all]
    m = len(idx_all)

    rng = np.random.default_rng(seed)
    score_idx = (np.arange(m) if m <= max_score_points
                 else rng.choice(m, max_score_points, replace=False))
    samples = rng.integers(0, m, size=(hypotheses, 3))
    A = D[samples]  # (K, 3, 3): rows are directions; -A v = r
    det = np.linalg.det(A)
    good = np.abs(det) > 1e-3  # near-coplanar samples give wild hypotheses: skip them
    if not good.any():
        return _not_observable(n, "directions too flat: every 3-point sample is (nearly) planar")
    V = np.linalg.solve(A[good], -r[samples[good]][..., None])[..., 0]  # (K', 3)
    counts = _count_agreeing(V, np.ascontiguousarray(D[score_idx]), r[score_idx],
                             threshold_mps)
    best = V[int(np.argmax(counts))]

    v, inl = _refine(D, r, best, threshold_mps, refinements)
    if gate_sigmas is not None and inl.sum() >= 3:
        # the scan's own Doppler noise: robust sigma (MAD) of every point's residual (movers
        # and clutter are a minority, which the median ignores), never below 1 mm/s (far under
        # any sensor's Doppler resolution: exact data has no noise to scale with)
        sigma = max(1.4826 * float(np.median(np.abs(r + D @ v))), 1e-3)
        # the velocity: Cauchy-weighted least squares of the points within threshold_mps, so
        # the tail neither tilts it (as plain least squares does) nor is cut off from it
        v = _cauchy_irls(np.ascontiguousarray(D[inl]), r[inl], v, cauchy_sigmas * sigma,
                         irls_iterations)
        # the static points: within gate_sigmas robust sigmas of it
        inl = np.abs(r + D @ v) < min(threshold_mps, gate_sigmas * sigma)

    mask = np.zeros(n, dtype=bool)
    mask[idx_all[inl]] = True
    k = int(inl.sum())
    if k < max(min_inliers, 4) or k < min_inlier_ratio * m:
        return _not_observable(n, f"only {k} of {m} points agree on one velocity", mask)
    Di = D[inl]
    gram = Di.T @ Di
    # smallest singular value of Di, from the 3x3 Gram matrix
    s_min = float(np.sqrt(max(np.linalg.eigvalsh(gram)[0], 0.0) / k))
    if s_min < min_spread:
        return _not_observable(
            n, f"inlier directions too flat, nearly planar (spread {s_min:.3f} < "
            f"{min_spread})", mask, s_min)
    res = r[inl] + Di @ v
    sigma2 = float(res @ res) / max(k - 3, 1)
    cov = sigma2 * np.linalg.inv(gram)
    return EgoVelocity(v, mask, cov, float(np.sqrt(sigma2)), s_min, True)


@numba.njit(cache=True)
def _cauchy_irls(D, r, v, scale, iterations):
    """v minimising sum log(1 + ((r + D v) / scale)^2) by iteratively reweighted least
    squares from ``v`` (weights 1 / (1 + (e / scale)^2)), until it moves less than 1 um/s."""
    v = v.copy()
    for _ in range(iterations):
        G = np.zeros((3, 3))
        b = np.zeros(3)
        for i in range(len(r)):
            e = (r[i] + D[i, 0] * v[0] + D[i, 1] * v[1] + D[i, 2] * v[2]) / scale
            w = 1.0 / (1.0 + e * e)
            for a in range(3):
                b[a] -= w * D[i, a] * r[i]
                for c in range(3):
                    G[a, c] += w * D[i, a] * D[i, c]
        if abs(np.linalg.det(G)) < 1e-12:
            break
        v_new = np.linalg.solve(G, b)
        step = np.sqrt(((v_new - v) ** 2).sum())
        v = v_new
        if step < 1e-6:
            break
    return v


@numba.njit(cache=True)
def _count_agreeing(V, D, r, gate):
    """Per hypothesis velocity V[h], how many points have |r + D v| < gate."""
    counts = np.zeros(len(V), dtype=np.int64)
    for h in range(len(V)):
        vx, vy, vz = V[h, 0], V[h, 1], V[h, 2]
        c = 0
        for i in range(len(r)):
            if abs(r[i] + D[i, 0] * vx + D[i, 1] * vy + D[i, 2] * vz) < gate:
                c += 1
        counts[h] = c
    return counts


@numba.njit(cache=True)
def _refine(D, r, v, gate, refinements):
    """Least squares on the points within ``gate`` of ``v`` (normal equations), inliers
    re-selected, repeated up to ``refinements`` times or until they stop changing."""
    m = len(r)
    inl = np.empty(m, dtype=np.bool_)
    for i in range(m):
        inl[i] = abs(r[i] + D[i, 0] * v[0] + D[i, 1] * v[1] + D[i, 2] * v[2]) < gate
    v = v.copy()
    for _ in range(refinements):
        G = np.zeros((3, 3))
        b = np.zeros(3)
        k = 0
        for i in range(m):
            if inl[i]:
                k += 1
                for a in range(3):
                    b[a] -= D[i, a] * r[i]
                    for c in range(3):
                        G[a, c] += D[i, a] * D[i, c]
        if k < 3 or abs(np.linalg.det(G)) < 1e-12:
            break
        v = np.linalg.solve(G, b)
        changed = False
        for i in range(m):
            new = abs(r[i] + D[i, 0] * v[0] + D[i, 1] * v[1] + D[i, 2] * v[2]) < gate
            if new != inl[i]:
                changed = True
                inl[i] = new
        if not changed:
            break
    return v, inl


def speed_from_doppler(sequence, threshold_mps: float | None = None
                       ) -> dict[str, np.ndarray]:
    """Per-frame ego speed from Doppler and, where ground truth exists, the GT speed.

    Returns arrays of length len(sequence): ``stamps`` [s], ``velocity`` (N, 3) [m/s, sensor
    frame, NaN where not observable], ``speed_doppler`` [m/s], ``speed_gt`` [m/s] (central
    differences of the GT positions at the scan stamps over +-0.5 s, so that GT resampled from
    a lower rate does not jump; NaN without GT) and ``observable``.
    For ``bench inspect`` (speed over time) and for the calibration check."""
    kind = sequence.sensor.kind
    thr = threshold_mps if threshold_mps is not None else (0.2 if kind == "radar" else 0.1)
    stamps = sequence.stamps
    vel = np.full((len(sequence), 3), np.nan)
    obs = np.zeros(len(sequence), dtype=bool)
    for i, scan in enumerate(sequence):
        if scan.doppler is None:
            continue
        ego = estimate_ego_velocity(scan.points, scan.doppler, threshold_mps=thr)
        vel[i], obs[i] = ego.velocity, ego.observable
    speed_gt = np.full(len(sequence), np.nan)
    gt = sequence.ground_truth
    if gt is not None and len(gt) >= 2:
        covered = gt.coverage_mask(stamps)
        if covered.sum() >= 3:
            st = stamps[covered]
            speed_gt[covered] = np.linalg.norm(gt_velocities(st, gt.interpolate(st).poses), axis=1)
    return {"stamps": stamps, "velocity": vel, "speed_doppler": np.linalg.norm(vel, axis=1),
            "speed_gt": speed_gt, "observable": obs}
