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
         of the last ``map_seconds`` of scans, in the world frame) with the translation tied to
         t_prev_curr(R) (exact derivative: the tied translation turns with R); on a sensor
         that re-publishes its earlier detections the vertical translation (sensor z) is left
         free in this solve (see below); pairs within the gate (exact nearest neighbour
         through a spatial hash); on such a sensor the solve is tied to
         t_prev_curr(R) + (R - I) r, r an online lever arm (``lever_memory_s``), and its last
         step is taken again with the re-published copies weighted down by their publications
         (``repeat_weight_power``; both issue 49); with ``tie_sigma_mps`` > 0 the horizontal
         translation is only held to it by a prior (issue 49's ablation); started
         from the harness's constant-velocity guess (with seed) or from the previous pose (no
         seed)                                                          (methods/local_map.py)
      -> T_world_curr = T_world_prev (R_prev_curr, t_prev_curr(R_prev_curr)): the translation
         is always the Doppler one; the scan joins the map.

Why the vertical may be left free. With the translation tied, any disagreement between the
Doppler translation and the geometry can only be absorbed by the rotation, and a steady one
becomes a steady rotation drift. The real Oculii Eagle's point cloud is an accumulation: 96-97 %
of a scan's points are the previous scan's, carried over by the sensor's own motion
compensation (they coincide to millimetres once aligned), and that compensation moves them
about 1.8 deg flatter than the Doppler velocity says (1.4 cm per 0.46 m step on the tuning
frames, store 0-124), so tied, the rotation tilted and rolled (48 m rotation error 3.05 deg on
the tuning frames; 2.06 deg with the vertical free). Whether a sensor re-publishes its
detections is tested once, on the first pair of scans (``repeats_detections``); on a sensor
with independent detections (every synthetic one) the translation stays fully tied, which is
better there (the Doppler vertical is then the more accurate one).

The horizontal tie and yaw (issue 49). The same disagreement exists sideways, smaller: on the
tuning frames the geometry's step points +0.05 deg - 21.4 deg per rad/s of yaw rate off the
Doppler translation (correlation -0.95 over 1 s; 0.37 s of yaw rate, i.e. the lateral velocity
of a sensor ~2 m ahead of the car's centre of rotation, which re-published points carried by a
model without that term would lack, or a lag). Tied, it becomes a yaw error that grows with the
heading change: over 100-frame windows yaw +0.31 / -0.43 deg (half A / B of the tuning split),
+0.22 / -0.01 deg with the horizontal untied. ``tie_sigma_mps`` > 0 loosens the tie on such a
sensor into a prior of that sigma (``register_to_map(tie_sigma_m=)``: 6 DoF, the prior with its
exact Jacobian); the pose keeps the Doppler translation either way. Criterion C of the tuning
rule at 3 m/s (the free solve's rotation): half A 0.924 [0.889, 0.950], half B 0.978 [0.818,
1.054]: better on both, significant on A only, so the rule keeps the exact tie (default 0;
configs/tuning/doppler-ego-tie.yaml) and ``-p tie_sigma_mps=3`` is the decoupled ablation
(1.06x the time per frame). docs/doppler-ego.md, "The tie and the rotation drift".

The lever arm (issue 49, ``lever_memory_s``). That disagreement is what a rigid body gives when
the velocity applies at one point and the geometry registers another: the points' frame moves
by ``t + (R - I) r`` a step (lateral velocity ``w x r``). With ``lever_memory_s`` > 0, on a
re-publishing sensor, the rotation solve is tied to that (``EgoTranslation(offset=r)``, the
Jacobian still exact), with r (sensor x, y) estimated online (``LeverArm``: least squares of
the geometry's disagreement, from one free Gauss-Newton step after each solve,
``register_to_map(geometry_step=True)``, against ``R - I``; past steps forgotten with this
time constant; a 2 m zero-mean prior until the rotation excites it); the pose keeps the Doppler
translation. On the tuning halves it finds the same arm (r_x -2.3 / -1.9 m after 25 steps) and
removes the yaw bias (100-frame windows +0.31 -> +0.24 deg on A, -0.43 -> 0.00 on B), but B's
roll error grows (+0.24 -> +1.04 deg: the geometry's own roll drift, which the exact tie's yaw
error had cancelled there): alone, criterion C is A 0.960 [0.898, 1.002], B 1.015 [0.856,
1.083] at 30 s. Forced on a sensor without an arm (synthetic, vertical freed) it estimates
0.2-0.3 m of its own and costs up to 14 %, hence only on re-publishing sensors.

The re-published copies (issue 49, ``repeat_weight_power``). That roll drift comes from the
re-published detections: a copy lands within millimetres of its previous copy in the map, so
its pair measures the sensor's own motion compensation again, not the world (83 % of the
registered points). At the solve's last iteration the points whose pair lies within
``replace_within_m`` (the map's copy test) are flagged, each weighted by its detection's
publications (``LocalMap.counts``) to the power ``-repeat_weight_power``, new detections by 1,
and that iteration's step is solved again over the same pairs (the lever's geometry step uses
them too: no extra pair search). With the lever it moves the roll drift toward zero on both
halves (radar frame, 100-frame windows: +0.39 -> -0.03 deg on A, +0.52 -> -0.83 on B: past
zero at power 2) and keeps the yaw bias under 0.3 deg (+0.04 / -0.29). The tuning rule chose
the two together (configs/tuning/doppler-ego-repeat.yaml: memory 30 s, power 2; C 0.849, half
A 0.818 [0.807, 0.894], half B 0.880 [0.844, 0.969]; power 1 qualifies at every memory, 0.857;
neither setting qualifies alone); 1.12x the time per frame. Where its premise fails (every
point re-published, nothing new: exact test data) it costs up to 0.09 deg a step.

When a scan's ego velocity is not observable the other scan's velocity alone is used, and when
neither is, the step falls back to a free 6-DoF registration from the motion guess.

Ablation switches: ``ego_translation`` (off: free 6-DoF registration and its translation, i.e.
a plain GICP scan-to-map odometry), ``static_filter`` (off: all points go to the registration
and the map), ``use_map`` (off: scan-to-scan against the previous scan only),
``free_vertical`` (false: the translation stays fully tied even on an accumulating sensor),
``tie_sigma_mps`` (3: on an accumulating sensor the rotation from a solve untied from the Doppler
translation, held only by a 3 m/s prior), ``lever_memory_s`` (0: the exact tie without the
lever arm), ``repeat_weight_power`` (0: the re-published copies weighted like new detections;
both 0: the method before issue 49's last change).

Seed / no seed: with seed, each frame's registration starts from the harness's constant-velocity
guess, the previous step's motion scaled to this step's interval (``scale_motion``; the same
prior every seeded method gets, ``motion_prior = CONSTANT_VELOCITY``, computed in this loop as
doppler-ego runs the sequence itself), so its table rows read "(With Seed)"; no seed, it starts
from the previous pose (no motion) and nothing is carried from one step to the next except the
map and the previous scan's Doppler velocity (a measurement, not a prior: the translation comes
from it in both). As the translation is the Doppler one either way, the seed only decides where
the rotation solve starts: the two rows of a table differ by less than 2 %.

What its tables show (``bench table``, README "doppler-ego: beyond the paper"): per run, the
mean relative rotation [deg] / translation [m] error per segment length against the store's
ground truth as given; the time is ``time_ms``, everything per frame after loading (ego
velocity, filtering, downsampling, covariances, registration, map update; the CPU time of the
one thread), and ``register_ms`` the ``register_to_map`` call alone. Its defaults were chosen
on the tuning split only (configs/methods/doppler-ego.yaml; replayable sweeps:
configs/tuning/doppler-ego-*.yaml).
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
from methods.angular_noise import AngularNoise
from methods.base import (
    FrameRecord,
    MethodParams,
    Odometry,
    OdometryResult,
    Presentation,
    scale_motion,
)
from methods.ego_velocity import estimate_ego_velocity
from methods.local_map import LocalMap, register_to_map, scan_covariances
from methods.timing import stopwatch, timed_section

_SENSOR_Z = np.array([[0.0, 0.0, 1.0]])

# sensor-dependent defaults (radar, lidar); each value's source is in
# configs/methods/doppler-ego.yaml ("tuning: real" = real store frames 0-124 only)
DEFAULTS = {
    # RANSAC hypothesis gate and upper bound of the inlier gate [m/s]. Radar: 99.4 % of the
    # Doppler residuals of the tuning frames lie within 0.25 m/s (robust sigma 0.031 m/s);
    # LiDAR: the Doppler scale of DICP's Tukey kernel on Aeva data (0.2 m/s, REFERENCE.md)
    "threshold_mps": (0.25, 0.2),
    # about the cross-range noise at the median range: radar 0.4 deg at 70 m (tuning: real)
    # = 0.49 m; LiDAR: kiss-icp's voxel rule max_range / 100 for a 100 m sensor
    "voxel_m": (0.5, 1.0),
    # pair gate [m]: radar the paper's tau_spatial = 3 m (kept by the tuning rule of
    # configs/splits.yaml, configs/tuning/doppler-ego-gate.yaml: wider gates gain under 1 % on
    # the real halves and lose 10 % on the synthetic radar); LiDAR: about its 1 m voxel
    "max_correspondence_m": (3.0, 1.0),
    # noise in every direction [m]: radar tuning: real (configs/tuning/doppler-ego-covariance-
    # floor.yaml: flat within 0.7 % over 0.02-0.1 m, 0.15 m 2 % worse, 0.3 m 8 %);
    # LiDAR: a few cm of FMCW range precision (Aeva's CARLA script adds 0.05 m, REFERENCE.md;
    # the synthetic LiDAR prefers ever smaller floors, which would only fit its own noise)
    "covariance_floor_m": (0.02, 0.03),
    # points per covariance: small_gicp's default 10 (radar: kept by the tuning rule of
    # configs/splits.yaml, configs/tuning/doppler-ego-neighbours.yaml: 20 was not
    # significantly better on half B and 8 % worse on the synthetic radar)
    "neighbours": (10, 10),
    # radar: 1 s (tuning: real; 0.5 s worse, 2 s no better); LiDAR: dense scans carry their
    # own structure, 5 scans
    "map_seconds": (1.0, 0.5),
}


class DopplerEgoParams(MethodParams):
    ego_translation: bool = Field(True, description="translation from the Doppler ego velocity")
    static_filter: bool = Field(True, description="register only the ego-velocity inliers")
    use_map: bool = Field(True, description="scan-to-map (else scan-to-scan)")
    free_vertical: bool | None = Field(
        None, description="leave the vertical translation (sensor z) to the geometry in the "
        "rotation solve (None: when the sensor re-publishes its earlier detections)")
    tie_sigma_mps: float = Field(
        0.0, ge=0, description="on a sensor that re-publishes its detections (free_vertical), "
        "the rotation solve holds the horizontal translation to the Doppler one by a prior of "
        "this sigma [m/s, times the scan interval: metres] instead of tying it exactly; the pose "
        "keeps the Doppler translation either way (0: tied exactly)")
    lever_memory_s: float = Field(
        30.0, ge=0, description="on a sensor that re-publishes its detections, tie the rotation "
        "solve to the Doppler translation of a point a lever arm r away, t + (R - I) r, with r "
        "(sensor x, y) estimated online from the geometry's disagreement with the Doppler "
        "translation, by least squares over the past steps forgotten with this time constant "
        "[s] (0: off, r = 0); the pose keeps the Doppler translation")
    repeat_weight_power: float = Field(
        2.0, ge=0, description="on a sensor that re-publishes its detections, after the "
        "rotation solve one more Gauss-Newton step in which each re-published copy (a point "
        "within replace_within_m of its map copy) weighs its detection's publications to the "
        "power -repeat_weight_power, new detections 1 (0: off)")
    threshold_mps: float | None = Field(None, gt=0, description="RANSAC Doppler gate [m/s] "
                                        "(radar 0.25, LiDAR 0.2)")
    gate_sigmas: float = Field(3.0, gt=0, description="static points: within this many robust "
                               "sigmas of the scan's own Doppler residual (at most "
                               "threshold_mps)")
    cauchy_sigmas: float = Field(2.385, gt=0, description="ego velocity: Cauchy-weighted least "
                                 "squares with this scale in robust sigmas (the conventional "
                                 "95 %-efficiency constant)")
    voxel_m: float | None = Field(None, gt=0, description="source voxel size [m]")
    max_correspondence_m: float | None = Field(None, gt=0, description="pair gate [m] "
                                               "(radar 3.0, LiDAR 1.0)")
    covariance_floor_m: float | None = Field(None, gt=0, description="covariance floor [m]")
    angle_noise_deg: tuple[float, float] | None = Field(
        None, description="angular noise across the ray (azimuth, elevation) [deg]: point "
        "covariances grow as range x angle across the ray; None: estimated from the sensor's "
        "own Doppler residuals (methods/angular_noise.py)")
    map_seconds: float | None = Field(None, gt=0, description="local map span [s]")
    replace_within_m: float = Field(
        0.05, ge=0, description="on a sensor that re-publishes its detections, a scan's point "
        "replaces older map points within this distance [m] (each detection kept once)")
    neighbours: int | None = Field(None, ge=3, description="points per covariance (10, "
                                   "small_gicp's)")
    kernel_scale: float = Field(3.0, gt=0, description="Cauchy scale, Mahalanobis [-]")
    max_iterations: int = Field(15, ge=1, description="Gauss-Newton iterations at most")
    max_source_points: int = Field(1500, ge=10, description="registration uses at most this "
                                   "many (strided) source points; the map gets all of them")
    num_threads: int = Field(1, ge=1, description="threads of the voxel grid and the "
                             "covariances' neighbour search (small_gicp); the rest is serial")


class DopplerEgo(Odometry):
    name = "doppler-ego"
    needs_doppler = True
    reads_fields = frozenset({"doppler"})
    presentation = Presentation("Doppler-Ego (this harness)", "#e377c2", 8)
    description = ("Doppler ego velocity for translation + rotation-only GICP of the static "
                   "points against a local map (this project's method)")
    uses_initial_guess = True
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
        velocities = np.full((n, 3), np.nan)  # the Doppler ego velocity per frame [m/s]
        records: list[FrameRecord] = []
        v_prev, first_static = None, None
        noise = AngularNoise()
        free_vertical = p.free_vertical  # None: decided on the first pair of scans
        last_motion, last_dt = np.eye(4), None  # T_prev_curr of the previous step (seed only)
        lever = LeverArm(p.lever_memory_s) if p.lever_memory_s > 0 else None
        for i, scan in enumerate(sequence):
            if scan.doppler is None:
                raise DataError(f"{scan.source or sequence.name}: doppler-ego needs Doppler")
            stamps[i] = scan.stamp
            reg = None
            with timed_section(self.clock == "wall") as watch:
                ego = estimate_ego_velocity(scan.points, scan.doppler,
                                            threshold_mps=p.threshold_mps,
                                            gate_sigmas=p.gate_sigmas,
                                            cauchy_sigmas=p.cauchy_sigmas)
                static_only = p.static_filter and ego.observable
                pts = scan.points[ego.inliers] if static_only else scan.points
                angles = p.angle_noise_deg
                if angles is None:  # the sensor's own, from its Doppler residuals so far
                    if ego.observable:
                        noise.add(scan.points[ego.inliers], scan.doppler[ego.inliers],
                                  ego.velocity)
                    est = noise.estimate()
                    angles = (0.0, 0.0) if est is None else est[1:]
                src = _voxel(pts, p.voxel_m, p.num_threads)
                covs = scan_covariances(src, p.neighbours, p.covariance_floor_m, angles,
                                        p.num_threads)
                v_curr = ego.velocity if ego.observable else None
                if v_curr is not None:
                    velocities[i] = v_curr
                pairs, iterations, converged, replaced = 0, 0, True, False
                if i == 0 and free_vertical is None:
                    first_static = pts
                if i > 0:
                    dt = scan.stamp - stamps[i - 1]
                    T_wp = poses[i - 1]
                    # with seed: the previous step's motion, scaled to this step; no seed: the
                    # identity (the Doppler translation below is a measurement, not a prior)
                    guess = (scale_motion(last_motion, dt / last_dt) if seed and last_dt
                             else np.eye(4))
                    init = T_wp @ guess
                    if free_vertical is None:
                        free_vertical = repeats_detections(first_static, pts, guess, p)
                    ego_t = None
                    use_lever = lever is not None and bool(free_vertical)
                    if p.ego_translation and (v_curr is not None or v_prev is not None):
                        ego_t = EgoTranslation(T_wp, v_prev, v_curr, dt,
                                               lever.value() if use_lever else None)
                    step = max(1, -(-len(src) // p.max_source_points))  # ceil division
                    with stopwatch() as reg:
                        fit = register_to_map(local_map, src[::step], covs[::step], init, ego_t,
                                              p.max_correspondence_m, p.kernel_scale,
                                              p.max_iterations, free_axes_sensor=_SENSOR_Z
                                              if free_vertical else None,
                                              tie_sigma_m=p.tie_sigma_mps * dt
                                              if free_vertical else 0.0,
                                              geometry_step=use_lever and ego_t is not None,
                                              repeat_power=p.repeat_weight_power
                                              if free_vertical else 0.0,
                                              repeat_within_m=p.replace_within_m)
                    if use_lever and ego_t is not None and fit.T_geometry is not None:
                        lever.update(T_wp, fit.T_geometry, ego_t.without_offset(), dt)
                    T = fit.T_world_sensor
                    replaced = fit.correspondences < 10 or not np.all(np.isfinite(T))
                    if replaced:  # nothing to register to: keep the motion prior (counted)
                        T = init
                    if ego_t is not None:  # the translation is the Doppler one, always
                        T = _with_t(T, ego_t if POSE_WITH_OFFSET else ego_t.without_offset())
                    poses[i] = T
                    pairs, iterations = fit.correspondences, fit.iterations
                    converged = fit.converged
                    last_motion, last_dt = inv_T(T_wp) @ poses[i], dt
                local_map.add(src, covs, poses[i],
                              replace_within_m=p.replace_within_m if free_vertical else 0.0)
            records.append(self.frame_record(i, scan.stamp, watch if i else None, reg,
                                             len(scan), pairs, iterations, converged,
                                             replaced))
            v_prev = v_curr
            if on_frame:
                on_frame(i)
        return OdometryResult(stamps, poses, records, velocities)


def repeats_detections(prev_points: np.ndarray, points: np.ndarray,
                       guess_T_prev_curr: np.ndarray, p: DopplerEgoParams,
                       coincide_m: float = 0.01) -> bool:
    """Does the sensor re-publish its earlier detections? True when at least half of
    ``points`` (N, 3) [m, current sensor frame] lie within ``coincide_m`` of a point of
    ``prev_points`` (M, 3) [m, previous sensor frame] once the two scans are aligned (a free
    6-DoF GICP of the raw points from ``guess_T_prev_curr``).

    Independent detections of one scatterer land a range x angular noise apart (decimetres at
    tens of metres); copies of one detection carried from scan to scan by the sensor's own
    motion compensation coincide to millimetres. The real Oculii Eagle's enhanced cloud is
    such an accumulation (96-97 % of a scan's points within 1 cm of the previous scan's on
    the tuning frames; 0-1 % on the synthetic sensors)."""
    if len(prev_points) < 10 or len(points) < 10:
        return False
    ref = LocalMap(1, 2 * p.max_correspondence_m)
    ref.add(prev_points, scan_covariances(prev_points, p.neighbours, p.covariance_floor_m),
            np.eye(4))
    # an evenly strided sample of the scan decides as well as all of it (the two answers are
    # 96 % and 0-1 %), at the main registration's source size: 0.2 s instead of 0.7 s on a
    # 21k-point LiDAR scan
    step = max(1, -(-len(points) // p.max_source_points))  # ceil division
    covs = scan_covariances(points, p.neighbours, p.covariance_floor_m)[::step]
    points = points[::step]
    fit = register_to_map(ref, points, covs, guess_T_prev_curr, None,
                          2 * p.max_correspondence_m, p.kernel_scale, p.max_iterations)
    T = fit.T_world_sensor
    _, sq = ref.nearest(points @ T[:3, :3].T + T[:3, 3])
    return bool(np.mean(sq < coincide_m**2) >= 0.5)


POSE_WITH_OFFSET = False  # experiment switch: the pose takes t + (R - I) r too


class EgoTranslation:
    """t_world_curr as a function of R_world_curr (``__call__``): the prev-frame displacement
    is the trapezoid dT/2 (v_prev + R_prev_curr v_curr) (one velocity alone, over dT, when the
    other is missing), plus ``(R_prev_curr - I) offset`` with ``offset`` [m, sensor frame]: the
    displacement of a point ``offset`` away from where the velocity applies (rigid body; None:
    zero). ``lever`` [m, sensor frame]: how it turns with R (``register_to_map``): the v_curr
    term's coefficient times v_curr (zero without v_curr) plus the offset."""

    def __init__(self, T_world_prev: np.ndarray, v_prev, v_curr, dt: float,
                 offset: np.ndarray | None = None) -> None:
        self.R_wp, self.t_wp = T_world_prev[:3, :3], T_world_prev[:3, 3]
        self.v_prev, self.v_curr, self.dt = v_prev, v_curr, dt
        self.offset = None if offset is None else np.asarray(offset, dtype=float)
        if v_curr is None:
            self.lever = np.zeros(3)
        else:
            self.lever = (dt if v_prev is None else 0.5 * dt) * np.asarray(v_curr, dtype=float)
        if self.offset is not None:
            self.lever = self.lever + self.offset

    def without_offset(self) -> EgoTranslation:
        if self.offset is None:
            return self
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.R_wp, self.t_wp
        return EgoTranslation(T, self.v_prev, self.v_curr, self.dt)

    def __call__(self, R_world_curr: np.ndarray) -> np.ndarray:
        if self.v_curr is None:
            d_world = self.R_wp @ (self.dt * self.v_prev)
        else:
            d_world = R_world_curr @ (self.lever if self.offset is None
                                      else self.lever - self.offset)
            if self.v_prev is not None:
                d_world = d_world + self.R_wp @ (0.5 * self.dt * self.v_prev)
        if self.offset is not None:  # R_wp (R_prev_curr - I) offset
            d_world = d_world + (R_world_curr - self.R_wp) @ self.offset
        return self.t_wp + d_world


DIAG = None  # experiment: a list collects (R_prev_curr, d_prev, t_doppler_prev) per step


class LeverArm:
    """Online estimate of the lever arm r = (r_x, r_y, 0) [m, sensor frame] between where the
    Doppler velocity applies and the frame the geometry registers, from the model
    ``d = (R_prev_curr - I) r``: d the geometry's step translation minus the Doppler one (in the
    previous sensor frame, horizontal rows), R_prev_curr the geometry's step rotation. Least
    squares over the past steps, each forgotten with the time constant ``memory_s``; a zero-mean
    prior of ``prior_m`` keeps r near zero until the rotation has excited it (r's information
    is the sum of squared step rotations, rad^2), weighed against the residual variance measured
    on the same steps."""

    def __init__(self, memory_s: float, prior_m: float = 2.0, noise_m: float = 0.01) -> None:
        self.memory_s, self.prior_m = memory_s, prior_m
        self.S, self.b = np.zeros((2, 2)), np.zeros(2)
        self.ss, self.n = noise_m**2, 1.0  # residual sum of squares [m^2] and its count
        self.r = np.zeros(3)

    def update(self, T_world_prev: np.ndarray, T_geometry: np.ndarray,
               doppler: EgoTranslation, dt: float) -> None:
        R_wp = T_world_prev[:3, :3]
        R_g = T_geometry[:3, :3]
        d = R_wp.T @ (T_geometry[:3, 3] - doppler(R_g))
        A = (R_wp.T @ R_g - np.eye(3))[:2, :2]
        if DIAG is not None:
            DIAG.append((R_wp.T @ R_g, d, R_wp.T @ (doppler(R_g) - T_world_prev[:3, 3])))
        lam = math.exp(-dt / self.memory_s)
        e = d[:2] - A @ self.r[:2]
        self.ss, self.n = lam * self.ss + e @ e, lam * self.n + 2.0
        self.S = lam * self.S + A.T @ A
        self.b = lam * self.b + A.T @ d[:2]
        ridge = (self.ss / self.n) / self.prior_m**2
        self.r[:2] = np.linalg.solve(self.S + ridge * np.eye(2), self.b)

    def value(self) -> np.ndarray:
        return self.r.copy()


def _with_t(T: np.ndarray, translation_of: EgoTranslation) -> np.ndarray:
    out = T.copy()
    out[:3, 3] = translation_of(T[:3, :3])
    return out


def _voxel(points: np.ndarray, voxel_m: float, num_threads: int = 1) -> np.ndarray:
    """Voxel-grid centroids (small_gicp) as an (M, 3) array."""
    if len(points) == 0:
        return np.empty((0, 3))
    pc = small_gicp.voxelgrid_sampling(points, voxel_m, num_threads=num_threads)
    return np.asarray(pc.points())[:, :3].copy()

