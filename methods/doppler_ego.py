"""``doppler-ego``: translation from the Doppler ego velocity, rotation from the geometry.

Each Doppler value is a direct measurement of the sensor's linear velocity (``doppler = -d . v``
for static points), and a scan holds thousands of them; what Doppler cannot see is the rotation
(``d . (w x p) = 0``). So each part of the motion comes from the measurement that observes it:

    scan k (points, Doppler)
      -> ego velocity v_k [sensor frame] by RANSAC + least squares  (methods/ego_velocity.py)
         and the static points (its inliers: movers, ghosts and clutter are dropped)
      -> static points voxel-downsampled, each with a covariance: its neighbourhood's spread
         plus the sensor noise (range noise in every direction, range x angular noise across
         the ray)
      -> translation as a function of the rotation (trapezoid over the scan interval, both
         velocities in the previous frame):  t_prev_curr(R) = dT/2 (v_{k-1} + R_prev_curr v_k)
      -> rotation: generalized ICP of the static points against a local map (the static points
         of the last ``map_seconds`` of scans, in the world frame), solving only the 3 rotation
         unknowns with the translation tied to t_prev_curr(R); pairs within 1 m (exact nearest
         neighbour through a spatial hash); initial rotation from the previous step's rotation
         rate                                                             (methods/local_map.py)
      -> T_world_curr = T_world_prev (R_prev_curr, t_prev_curr); the scan joins the map.

When a scan's ego velocity is not observable the other scan's velocity alone is used, and when
neither is, the step falls back to a free 6-DoF registration from a constant-velocity guess.

Ablation switches: ``ego_translation`` (off: free 6-DoF registration with a constant-velocity
guess, i.e. a plain GICP scan-to-map odometry), ``static_filter`` (off: all points go to the
registration and the map), ``use_map`` (off: scan-to-scan against the previous scan only).

Seed / no seed: the method carries its own motion prior (the Doppler ego velocity and the
rotation rate it estimated itself), so the harness' initial guess does not apply
(``uses_initial_guess = False``; it runs once). Timing: everything per frame after loading
(ego velocity, filtering, downsampling, covariances, map update, registration).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import small_gicp
from pydantic import Field

from loaders.errors import DataError
from loaders.scan import SensorInfo, Sequence
from loaders.se3 import inv_T
from methods.base import FrameRecord, MethodParams, Odometry, OdometryResult, scale_motion
from methods.ego_velocity import estimate_ego_velocity
from methods.local_map import LocalMap, register_to_map, scan_covariances
from methods.timing import stopwatch, timed_section

# sensor-dependent defaults: (radar, lidar), each with its physical reason
DEFAULTS = {
    # ~3 sigma of radar Doppler noise (~0.06-0.1 m/s); FMCW LiDAR ~0.03 m/s
    "threshold_mps": (0.25, 0.1),
    # radar: about the cross-range noise at 30 m (1 deg); dense LiDAR: ~1 m cells
    "voxel_m": (0.5, 1.0),
    "covariance_floor_m": (0.15, 0.03),
    # angular noise across the ray (azimuth, elevation) [deg]: the real Eagle sample's Doppler
    # residual grows with the azimuth sensitivity as 0.45 deg of azimuth noise (top 1 % of
    # residuals trimmed; 0.9 untrimmed, `bench synth --realism`), so 0.5; 4D radar elevation is
    # resolved about half as finely (synthetic sensors: 1 / 2 deg cells); FMCW LiDAR ~0.02 deg
    "angle_noise_deg": ((0.5, 1.0), (0.02, 0.02)),
    # ~1 s of radar scans for enough structure; LiDAR scans are dense on their own
    "map_seconds": (1.0, 0.5),
}


class DopplerEgoParams(MethodParams):
    ego_translation: bool = Field(True, description="translation from the Doppler ego velocity")
    static_filter: bool = Field(True, description="register only the ego-velocity inliers")
    use_map: bool = Field(True, description="scan-to-map (else scan-to-scan)")
    threshold_mps: float | None = Field(None, gt=0, description="RANSAC Doppler inlier gate "
                                        "[m/s] (radar 0.25, LiDAR 0.1)")
    voxel_m: float | None = Field(None, gt=0, description="source voxel size [m]")
    # The translation is fixed by Doppler (to mm) and the rotation predicted from the last
    # step, so a correctly associated point lies within about a voxel diagonal (0.87 m for the
    # radar's 0.5 m) of its nearest map point; farther pairs are wrong associations. (2 m, the
    # radar's angular noise at 100 m, let wrong pairs in: 48 m rotation error 2.3x in a U-turn.)
    max_correspondence_m: float = Field(1.0, gt=0, description="pair gate [m]")
    covariance_floor_m: float | None = Field(None, gt=0, description="covariance floor [m]")
    angle_noise_deg: tuple[float, float] | None = Field(
        None, description="angular noise across the ray (azimuth, elevation) [deg]: point "
        "covariances grow as range x angle across the ray (radar 0.5, 1.0; LiDAR 0.02, 0.02)")
    map_seconds: float | None = Field(None, gt=0, description="local map span [s]")
    neighbours: int = Field(10, ge=3, description="points per covariance")
    kernel_scale: float = Field(3.0, gt=0, description="Cauchy scale, Mahalanobis [-]")
    max_iterations: int = Field(15, ge=1)
    max_source_points: int = Field(1500, ge=10, description="registration uses at most this "
                                   "many (strided) source points; the map gets all of them")


class DopplerEgo(Odometry):
    name = "doppler-ego"
    description = ("Doppler ego velocity for translation + rotation-only GICP of the static "
                   "points against a local map (this project's method)")
    uses_initial_guess = False
    Params = DopplerEgoParams

    def __init__(self, params: DopplerEgoParams | None = None, **overrides) -> None:
        base = params if params is not None else DopplerEgoParams()
        self.params = DopplerEgoParams.model_validate({**base.model_dump(), **overrides})

    def configured_for(self, sensor: SensorInfo) -> DopplerEgo:
        col = 0 if sensor.kind == "radar" else 1
        filled = {k: v[col] for k, v in DEFAULTS.items() if getattr(self.params, k) is None}
        return DopplerEgo(self.params.model_copy(update=filled))

    def _resolved(self, sensor: SensorInfo) -> DopplerEgoParams:
        return self.configured_for(sensor).params

    def run(self, sequence: Sequence, seed: bool,
            on_frame: Callable[[int], None] | None = None) -> OdometryResult:
        p = self._resolved(sequence.sensor)
        frames_kept = 1 if not p.use_map else max(1, math.ceil(p.map_seconds
                                                               / sequence.sensor.period_s))
        local_map = LocalMap(frames_kept, p.max_correspondence_m)
        n = len(sequence)
        poses = np.repeat(np.eye(4)[None], n, axis=0)
        stamps = np.empty(n)
        records: list[FrameRecord] = []
        v_prev = None
        last_motion, last_dt = np.eye(4), None  # T_prev_curr of the previous step
        for i, scan in enumerate(sequence):
            if scan.doppler is None:
                raise DataError(f"{scan.source or sequence.name}: doppler-ego needs Doppler")
            stamps[i] = scan.stamp
            reg = None
            with timed_section(self.clock == "wall") as watch:
                ego = estimate_ego_velocity(scan.points, scan.doppler,
                                            threshold_mps=p.threshold_mps)
                static_only = p.static_filter and ego.observable
                pts = scan.points[ego.inliers] if static_only else scan.points
                src = _voxel(pts, p.voxel_m)
                covs = scan_covariances(src, p.neighbours, p.covariance_floor_m,
                                        p.angle_noise_deg)
                v_curr = ego.velocity if ego.observable else None
                pairs, iterations, converged = 0, 0, True
                if i > 0:
                    dt = scan.stamp - stamps[i - 1]
                    T_wp = poses[i - 1]
                    guess = scale_motion(last_motion, dt / last_dt) if last_dt else np.eye(4)
                    init = T_wp @ guess
                    translation_of = None
                    if p.ego_translation and (v_curr is not None or v_prev is not None):
                        translation_of = _ego_translation(T_wp, v_prev, v_curr, dt)
                    step = max(1, -(-len(src) // p.max_source_points))  # ceil division
                    with stopwatch() as reg:
                        fit = register_to_map(local_map, src[::step], covs[::step], init,
                                              translation_of, p.max_correspondence_m,
                                              p.kernel_scale, p.max_iterations)
                    if fit.correspondences >= 10 and np.all(np.isfinite(fit.T_world_sensor)):
                        poses[i] = fit.T_world_sensor
                    else:  # nothing to register to: keep the motion prior
                        poses[i] = (init if translation_of is None
                                    else _with_t(init, translation_of))
                    pairs, iterations = fit.correspondences, fit.iterations
                    converged = fit.converged
                    last_motion, last_dt = inv_T(T_wp) @ poses[i], dt
                local_map.add(src, covs, poses[i])
            records.append(self.frame_record(i, scan.stamp, watch if i else None, reg,
                                             len(scan), pairs, iterations, converged))
            v_prev = v_curr
            if on_frame:
                on_frame(i)
        return OdometryResult(stamps, poses, records)


def _ego_translation(T_world_prev: np.ndarray, v_prev, v_curr, dt: float):
    """t_world_curr as a function of R_world_curr: the prev-frame displacement is the trapezoid
    dT/2 (v_prev + R_prev_curr v_curr) (one velocity alone when the other is missing)."""
    R_wp, t_wp = T_world_prev[:3, :3], T_world_prev[:3, 3]

    def translation_of(R_world_curr: np.ndarray) -> np.ndarray:
        R_pc = R_wp.T @ R_world_curr
        if v_prev is None:
            d = dt * (R_pc @ v_curr)
        elif v_curr is None:
            d = dt * v_prev
        else:
            d = 0.5 * dt * (v_prev + R_pc @ v_curr)
        return t_wp + R_wp @ d

    return translation_of


def _with_t(T: np.ndarray, translation_of) -> np.ndarray:
    out = T.copy()
    out[:3, 3] = translation_of(T[:3, :3])
    return out


def _voxel(points: np.ndarray, voxel_m: float) -> np.ndarray:
    """Voxel-grid centroids (small_gicp) as an (M, 3) array."""
    if len(points) == 0:
        return np.empty((0, 3))
    pc = small_gicp.voxelgrid_sampling(points, voxel_m)
    return np.asarray(pc.points())[:, :3].copy()

