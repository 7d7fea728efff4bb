"""The local map and the registration step of ``doppler-ego``.

``LocalMap`` keeps the static points of the last ``max_frames`` scans in the world frame, each
point with the covariance of its neighbourhood in its own scan (computed once, when the scan is
added, and rotated into the world frame), and an exact radius-limited nearest-neighbour index
over their union (``methods/spatial_hash.py``), rebuilt once per frame in O(N).

``register_to_map`` is a Gauss-Newton generalized-ICP (each pair weighted by the inverse of
the summed covariances, a Cauchy kernel on the Mahalanobis distance) over the pose
``T_world_sensor = (R, t)``, perturbed as ``R <- exp(dtheta) R``, ``t <- t + dt`` (rotation about
the sensor's own position). With ``translation_of(R)`` given, the translation is not a free
unknown: it is recomputed from the rotation after every step (the Doppler ego-velocity
translation) and only the 3 rotation unknowns are solved - the geometry is asked only for what
Doppler cannot observe.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np
import small_gicp
from scipy.spatial.transform import Rotation

from loaders.se3 import skew
from methods.spatial_hash import SpatialHash


def scan_covariances(points: np.ndarray, neighbours: int, floor_m: float,
                     angle_noise_deg: tuple[float, float] = (0.0, 0.0),
                     num_threads: int = 1) -> np.ndarray:
    """(N, 3, 3) covariance of each point [m^2, sensor frame]: the spread of its
    ``neighbours`` nearest points in the same scan (the local surface), plus the measurement
    noise: ``floor_m``^2 in every direction (range noise; radar neighbourhoods are sparse) and
    the angular noise across the ray, (r sigma_az)^2 along the azimuth direction and
    (r sigma_el)^2 along the elevation direction (``angle_noise_deg`` = (sigma_az, sigma_el)):
    a radar's far points are metres uncertain across the ray but centimetres along it."""
    n = len(points)
    pts = np.ascontiguousarray(points, dtype=np.float64)
    k = min(neighbours, n)
    if k < 3:
        idx = np.zeros((n, 0), dtype=np.int64)
    else:
        tree = small_gicp.KdTree(pts, num_threads=num_threads)
        idx = np.asarray(tree.batch_knn_search(pts, k, num_threads=num_threads)[0],
                         dtype=np.int64)
    az, el = np.radians(angle_noise_deg)
    return _point_covariances(pts, idx, float(floor_m) ** 2, float(az) ** 2, float(el) ** 2)


@numba.njit(cache=True)
def _point_covariances(points, idx, floor2, az2, el2):
    """Sample covariance (divisor m - 1) of the m points idx[n, :] that are not -1 (none
    when m < 3), plus floor2 on the diagonal and the ray-transverse angular noise (variances
    az2, el2 [rad^2])."""
    n, k = idx.shape
    cov = np.zeros((n, 3, 3))
    for i in range(n):
        m = 0
        m0 = m1 = m2 = 0.0
        for j in range(k):
            p = idx[i, j]
            if p >= 0:
                m += 1
                m0 += points[p, 0]
                m1 += points[p, 1]
                m2 += points[p, 2]
        if m >= 3:
            m0, m1, m2 = m0 / m, m1 / m, m2 / m
            s00 = s01 = s02 = s11 = s12 = s22 = 0.0
            for j in range(k):
                p = idx[i, j]
                if p < 0:
                    continue
                a, b, c = points[p, 0] - m0, points[p, 1] - m1, points[p, 2] - m2
                s00 += a * a
                s01 += a * b
                s02 += a * c
                s11 += b * b
                s12 += b * c
                s22 += c * c
            f = 1.0 / (m - 1)
            cov[i, 0, 0], cov[i, 1, 1], cov[i, 2, 2] = s00 * f, s11 * f, s22 * f
            cov[i, 0, 1] = cov[i, 1, 0] = s01 * f
            cov[i, 0, 2] = cov[i, 2, 0] = s02 * f
            cov[i, 1, 2] = cov[i, 2, 1] = s12 * f
        for a in range(3):
            cov[i, a, a] += floor2
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        rh2 = x * x + y * y
        r2 = rh2 + z * z
        if (az2 > 0.0 or el2 > 0.0) and rh2 > 0.0:
            rh = np.sqrt(rh2)
            # unit vectors of increasing azimuth (ua) and elevation (ue); a step d_az moves the
            # point by r cos(el) d_az = rh d_az along ua, a step d_el by r d_el along ue
            ua = (-y / rh, x / rh, 0.0)
            ue = (-z * x / (rh * np.sqrt(r2)), -z * y / (rh * np.sqrt(r2)), rh / np.sqrt(r2))
            va, ve = az2 * rh2, el2 * r2
            for a in range(3):
                for b in range(3):
                    cov[i, a, b] += va * ua[a] * ua[b] + ve * ue[a] * ue[b]
    return cov


class LocalMap:
    """World-frame points (with covariances) of the last ``max_frames`` scans, searchable for
    the nearest point within ``search_radius_m``.

    Storage is a ring of ``max_frames`` slots of equal capacity (grown when a scan is larger):
    a new scan overwrites the oldest slot, so nothing is concatenated per frame, and
    ``points`` / ``covs`` hold every slot with ``alive`` marking the map's points (the index
    searches only those; ``nearest`` returns indices into these arrays).

    ``add(..., replace_within_m=r)`` lets a scan's point replace every older map point within
    ``r`` of it: for a sensor that re-publishes its earlier detections, a detection then stays
    in the map once (its newest copy) instead of once per scan of the window, and ``counts``
    holds how many times it has been published (1: a new detection; a copy: its replaced
    copy's count + 1)."""

    def __init__(self, max_frames: int, search_radius_m: float) -> None:
        self.max_frames = int(max_frames)
        self.search_radius_m = float(search_radius_m)
        self.capacity = 0  # points per slot
        self.points = np.empty((0, 3))
        self.covs = np.empty((0, 3, 3))
        self.alive = np.zeros(0, dtype=bool)
        self.counts = np.zeros(0)  # publications of each point's detection so far (1: new)
        self.next_slot = 0
        self.index: SpatialHash | None = None

    def _grow(self, capacity: int) -> None:
        old_cap, new = self.capacity, max(capacity, 2 * self.capacity)
        points = np.zeros((self.max_frames * new, 3))
        covs = np.zeros((self.max_frames * new, 3, 3))
        alive = np.zeros(self.max_frames * new, dtype=bool)
        counts = np.zeros(self.max_frames * new)
        for slot in range(self.max_frames if old_cap else 0):
            src, dst = slot * old_cap, slot * new
            points[dst:dst + old_cap] = self.points[src:src + old_cap]
            covs[dst:dst + old_cap] = self.covs[src:src + old_cap]
            alive[dst:dst + old_cap] = self.alive[src:src + old_cap]
            counts[dst:dst + old_cap] = self.counts[src:src + old_cap]
        self.points, self.covs, self.alive, self.capacity = points, covs, alive, new
        self.counts = counts

    def add(self, points_sensor: np.ndarray, covs_sensor: np.ndarray,
            T_world_sensor: np.ndarray, replace_within_m: float = 0.0) -> None:
        R, t = T_world_sensor[:3, :3], T_world_sensor[:3, 3]
        n = len(points_sensor)
        world = points_sensor @ R.T + t
        count = np.ones(n)
        if replace_within_m > 0 and self.index is not None and n:
            idx, sq = self.index.nearest(world, min(replace_within_m, self.search_radius_m))
            copy = sq < replace_within_m**2
            count[copy] = self.counts[idx[copy]] + 1  # a copy: one publication more
            self.alive[idx[copy]] = False
        if n > self.capacity:
            self._grow(n)
        base = self.next_slot * self.capacity
        self.alive[base:base + self.capacity] = False
        self.points[base:base + n] = world
        self.covs[base:base + n] = R @ covs_sensor @ R.T
        self.alive[base:base + n] = True
        self.counts[base:base + n] = count
        self.next_slot = (self.next_slot + 1) % self.max_frames
        self.index = (SpatialHash(self.points, self.search_radius_m, self.alive)
                      if self.alive.any() else None)

    def nearest(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest map point of each point within the search radius: index into ``points``
        (-1: none) and squared distance [m^2] (inf: none)."""
        return self.index.nearest(points_world, self.search_radius_m)

    def __len__(self) -> int:
        return int(np.count_nonzero(self.alive))


@dataclass
class MapFit:
    """T_world_sensor: the solved pose; correspondences: pairs of the last iteration;
    T_geometry: with ``geometry_step``, the pose one free 6-DoF Gauss-Newton step of the
    geometric cost alone takes from the solved one (None otherwise or when it fails)."""

    T_world_sensor: np.ndarray
    correspondences: int
    iterations: int
    converged: bool
    T_geometry: np.ndarray | None = None


class TiedTranslation(Protocol):
    """A translation measured apart from the geometry (the Doppler ego translation) as a
    function of the rotation: ``__call__(R_world_sensor) -> t_world_sensor`` [m], and
    ``lever`` (3,) [m, sensor frame], how it turns with the rotation:
    ``t(exp(d) R) = t(R) + d x (R lever)`` to first order."""

    lever: np.ndarray

    def __call__(self, R_world_sensor: np.ndarray) -> np.ndarray: ...


@numba.njit(cache=True)
def _normal_equations(Rl, moved, covs, R, map_points, map_covs, idx, keep, c2, Tcols, pw):
    """H (dof x dof) and g (dof) of the weighted GICP cost over the kept pairs: residual
    e = R p + t - q, weight W = (C_q + R C_p R^T)^-1 scaled by the Cauchy IRLS factor,
    Jacobian [-(Rl)^, Tcols]: rotation columns from ``Rl`` (R p, or R (p + lever) when the
    translation turns with R), then the translation's free directions ``Tcols`` (3 x k;
    dof = 3 + k); ``pw`` (N,) scales each pair's weight. Scalar code: small matrix products in
    numba would allocate per pair."""
    dof = 3 + Tcols.shape[1]
    H = np.zeros((dof, dof))
    g = np.zeros(dof)
    J = np.zeros((3, dof))
    RC = np.zeros((3, 3))
    C = np.zeros((3, 3))
    W = np.zeros((3, 3))
    for a in range(3):
        for b in range(dof - 3):
            J[a, 3 + b] = Tcols[a, b]
    for n in range(len(Rl)):
        if not keep[n]:
            continue
        j = idx[n]
        for a in range(3):  # C = C_q + R C_p R^T
            for b in range(3):
                RC[a, b] = (R[a, 0] * covs[n, 0, b] + R[a, 1] * covs[n, 1, b]
                            + R[a, 2] * covs[n, 2, b])
        for a in range(3):
            for b in range(3):
                C[a, b] = map_covs[j, a, b] + (RC[a, 0] * R[b, 0] + RC[a, 1] * R[b, 1]
                                               + RC[a, 2] * R[b, 2])
        # inverse of a 3x3 by cofactors
        c00 = C[1, 1] * C[2, 2] - C[1, 2] * C[2, 1]
        c01 = C[1, 2] * C[2, 0] - C[1, 0] * C[2, 2]
        c02 = C[1, 0] * C[2, 1] - C[1, 1] * C[2, 0]
        det = C[0, 0] * c00 + C[0, 1] * c01 + C[0, 2] * c02
        if not det > 1e-18:
            continue
        inv_det = 1.0 / det
        W[0, 0], W[1, 0], W[2, 0] = c00 * inv_det, c01 * inv_det, c02 * inv_det
        W[0, 1] = (C[0, 2] * C[2, 1] - C[0, 1] * C[2, 2]) * inv_det
        W[1, 1] = (C[0, 0] * C[2, 2] - C[0, 2] * C[2, 0]) * inv_det
        W[2, 1] = (C[0, 1] * C[2, 0] - C[0, 0] * C[2, 1]) * inv_det
        W[0, 2] = (C[0, 1] * C[1, 2] - C[0, 2] * C[1, 1]) * inv_det
        W[1, 2] = (C[0, 2] * C[1, 0] - C[0, 0] * C[1, 2]) * inv_det
        W[2, 2] = (C[0, 0] * C[1, 1] - C[0, 1] * C[1, 0]) * inv_det
        e0 = moved[n, 0] - map_points[j, 0]
        e1 = moved[n, 1] - map_points[j, 1]
        e2 = moved[n, 2] - map_points[j, 2]
        We0 = W[0, 0] * e0 + W[0, 1] * e1 + W[0, 2] * e2
        We1 = W[1, 0] * e0 + W[1, 1] * e1 + W[1, 2] * e2
        We2 = W[2, 0] * e0 + W[2, 1] * e1 + W[2, 2] * e2
        w = pw[n] / (1.0 + (e0 * We0 + e1 * We1 + e2 * We2) / c2)
        x, y, z = Rl[n, 0], Rl[n, 1], Rl[n, 2]
        J[0, 1], J[0, 2] = z, -y  # J[:, :3] = -skew(Rl)
        J[1, 0], J[1, 2] = -z, x
        J[2, 0], J[2, 1] = y, -x
        for a in range(dof):
            # (J^T W)[a, :] then its products with J and e
            t0 = J[0, a] * W[0, 0] + J[1, a] * W[1, 0] + J[2, a] * W[2, 0]
            t1 = J[0, a] * W[0, 1] + J[1, a] * W[1, 1] + J[2, a] * W[2, 1]
            t2 = J[0, a] * W[0, 2] + J[1, a] * W[1, 2] + J[2, a] * W[2, 2]
            g[a] += w * (t0 * e0 + t1 * e1 + t2 * e2)
            for b in range(a, dof):
                H[a, b] += w * (t0 * J[0, b] + t1 * J[1, b] + t2 * J[2, b])
    for a in range(dof):
        for b in range(a):
            H[a, b] = H[b, a]
    return H, g


def register_to_map(
    local_map: LocalMap,
    points: np.ndarray,
    covs: np.ndarray,
    init_T_world_sensor: np.ndarray,
    tied: TiedTranslation | None,
    max_correspondence_m: float,
    kernel_scale: float = 3.0,
    max_iterations: int = 15,
    min_correspondences: int = 10,
    tolerance_rad: float = 1e-4,
    free_axes_sensor: np.ndarray | None = None,
    tie_sigma_m: float = 0.0,
    geometry_step: bool = False,
    repeat_power: float = 0.0,
    repeat_within_m: float = 0.0,
) -> MapFit:
    """Align ``points`` (N, 3) [m, sensor frame] with covariances ``covs`` (N, 3, 3) to the map.

    Unknowns. ``tied`` None: all 6 degrees of freedom, from ``init_T_world_sensor``. Otherwise
    the translation is ``tied(R) + U s``: the measured translation plus a free offset ``s``
    along the unit vectors ``free_axes_sensor`` (k, 3) [sensor frame, turned into the world by
    the initial rotation: the columns of U]; k = 0 (None) solves the 3 rotation unknowns alone,
    k = 1 with the sensor's z axis leaves the vertical to the geometry. The perturbation is
    ``R <- exp(dtheta) R``, ``s <- s + ds``; as ``tied(R)`` turns with R about the sensor, the
    translation moves by ``-(R lever)^ dtheta + U ds``, and the Gauss-Newton step uses exactly
    that (the full derivative of the constrained cost, so the iteration converges to its own
    optimum). ``kernel_scale`` is the Cauchy scale on the Mahalanobis distance [-]. Returns the
    pose T_world_sensor and the last pair count.

    ``tie_sigma_m`` > 0 (with ``tied``) loosens the tie into a prior: all 6 degrees of freedom
    are unknown, from ``(R_init, tied(R_init))``, and the cost gains ``|P (t - tied(R))|^2 /
    tie_sigma_m^2`` with P the projection off the free axes (they stay free). Its Jacobian is
    ``[(R lever)^, I]``: the measured translation turns with R. The geometry then decides the
    translation it is sure of, the measured one holds the directions it cannot see, and a
    disagreement between the two is no longer absorbed by the rotation alone.

    ``geometry_step``: after the solve, one more Gauss-Newton step of the geometric cost alone
    over all 6 degrees of freedom (no tie, no prior) from the solved pose, returned as
    ``MapFit.T_geometry``: where the geometry would put the pose (to first order) when the
    translation were free; the cost of one iteration. ``doppler-ego`` reads the measured
    translation's disagreement with the geometry from it (its lever arm, issue 49).

    ``repeat_power`` > 0 (with ``repeat_within_m`` > 0): at the solve's last iteration, the
    points whose pair lies within ``repeat_within_m`` (a sensor's re-published copy of a map
    point: they land within millimetres of it) are weighted by their detection's publications
    to the power ``-repeat_power`` (publications = the map copy's ``counts`` + 1), every other
    pair by 1, and that iteration's Gauss-Newton step of the same cost (same pairs, unknowns,
    tie and prior) is taken again with those weights (``geometry_step`` then uses the same
    pairs; issue 49: a detection carried from scan to scan by the sensor's motion compensation
    measures that compensation again, not the world)."""
    # contiguous, whatever the caller passes (a strided subsample ``covs[::step]`` would make
    # numba compile a second version of ``_normal_equations`` inside a timed frame: the first
    # frame with more than ``max_source_points`` points after a warm-up pair with fewer)
    points = np.ascontiguousarray(points, dtype=np.float64)
    covs = np.ascontiguousarray(covs, dtype=np.float64)
    R = init_T_world_sensor[:3, :3].copy()
    prior_info = None  # (3, 3) information of the prior on t - tied(R) [1/m^2, world frame]
    s = None  # the free translation offsets along U (exact tie only)
    if tied is None:
        U = np.eye(3)  # the translation is free
        t = init_T_world_sensor[:3, 3].copy()
    else:
        axes = np.zeros((0, 3)) if free_axes_sensor is None else np.atleast_2d(free_axes_sensor)
        U = R @ np.asarray(axes, dtype=np.float64).T  # (3, k) world frame
        s = np.zeros(U.shape[1])
        t = tied(R)
        if tie_sigma_m > 0:
            prior_info = (np.eye(3) - U @ U.T) / tie_sigma_m**2
            U = np.eye(3)  # the translation is free, held by the prior
    n_pairs, converged, it = 0, False, 0
    if local_map.index is None:
        return MapFit(_pose(R, t), 0, 0, False)
    if max_correspondence_m > local_map.search_radius_m:
        raise ValueError(f"pair gate {max_correspondence_m} m exceeds the map's search radius "
                         f"{local_map.search_radius_m} m")
    c2 = kernel_scale**2
    ones = np.ones(len(points))
    reweight = repeat_power > 0 and repeat_within_m > 0
    T_geometry = None

    def solve_step(R, t, s, Rl, moved, idx, keep, pw):
        """One Gauss-Newton step over the given pairs: the new (R, t, s) and the rotation
        and translation-unknown updates (None when singular)."""
        H, g = _normal_equations(Rl, moved, covs, R, local_map.points, local_map.covs,
                                 idx, keep, c2, U, pw)
        if prior_info is not None:  # residual t - tied(R), Jacobian [(R lever)^, I]
            J = np.hstack([skew(R @ tied.lever), np.eye(3)])
            H = H + J.T @ prior_info @ J
            g = g + J.T @ prior_info @ (t - tied(R))
        try:
            delta = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            return None
        R = Rotation.from_rotvec(delta[:3]).as_matrix() @ R
        if tied is None or prior_info is not None:
            t = t + delta[3:]
        else:
            s = s + delta[3:]
            t = tied(R) + U @ s
        return R, t, s, delta

    if prior_info is not None:
        s = None
    for step in range(1, max_iterations + 1):
        it = step
        Rp = points @ R.T
        moved = Rp + t
        idx, sq = local_map.nearest(moved)
        keep = sq < max_correspondence_m**2
        n_pairs = int(keep.sum())
        if n_pairs < min_correspondences:
            break
        # the point moves by -(R p)^ dtheta + dt; tied: dt = -(R lever)^ dtheta + U ds
        exact_tie = tied is not None and prior_info is None
        Rl = Rp + R @ tied.lever if exact_tie else Rp
        out = solve_step(R, t, s, Rl, moved, idx, keep, ones)
        if out is None:
            break
        small = (np.linalg.norm(out[3][:3]) < tolerance_rad
                 and np.linalg.norm(out[3][3:]) < 1e-4)
        if (small or step == max_iterations) and reweight:
            # the re-weighted step over this iteration's pairs, from the pose they were found
            # at (the update just solved is below the tolerance: the same pairs): each
            # re-published copy weighted by its detection's publications ** -repeat_power
            copy = sq < repeat_within_m**2
            pw = np.where(copy, (local_map.counts[np.maximum(idx, 0)] + 1.0) ** -repeat_power,
                          1.0)
            if geometry_step:  # and the geometry step from the same pairs
                T_geometry = _free_step(Rp, moved, covs, R, t, local_map, idx, keep, c2, ones)
            out = solve_step(R, t, s, Rl, moved, idx, keep, pw) or out
        R, t, s = out[:3]
        if small:
            converged = True
            break
    if geometry_step and T_geometry is None and n_pairs >= min_correspondences:
        Rp = points @ R.T
        idx, sq = local_map.nearest(Rp + t)
        keep = sq < max_correspondence_m**2
        if int(keep.sum()) >= min_correspondences:
            T_geometry = _free_step(Rp, Rp + t, covs, R, t, local_map, idx, keep, c2, ones)
    return MapFit(_pose(R, t), n_pairs, it, converged, T_geometry)


def _free_step(Rp, moved, covs, R, t, local_map, idx, keep, c2, pw) -> np.ndarray | None:
    """The pose one free 6-DoF Gauss-Newton step of the geometric cost takes from (R, t),
    over the given pairs (None when singular)."""
    H, g = _normal_equations(Rp, moved, covs, R, local_map.points, local_map.covs, idx, keep,
                             c2, np.eye(3), pw)
    try:
        delta = -np.linalg.solve(H, g)
    except np.linalg.LinAlgError:
        return None
    return _pose(Rotation.from_rotvec(delta[:3]).as_matrix() @ R, t + delta[3:])


def _pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(R)  # back onto SO(3): round-off would compound over a sequence
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = U @ Vt, t
    return T
