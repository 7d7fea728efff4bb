"""``SyntheticSequence``: a ``Sequence`` whose scans are ray cast on demand.

Deterministic from (scene, sensor, frames, seed, noise, options): the plan, the motion and the
scene each use their own RNG stream derived from the seed, and frame i uses an RNG seeded from
(seed, i), so ``scan(i)`` gives the same scan in any order. Ground truth: option ``gt``
(groundtruth.py) - the exact ``T_world_sensor`` at the scan stamps (default), or the pipeline
of an imitated dataset (``ntu4dradlm``, ``campus``); the scans do not depend on it. By default
every point of a scan is taken at the scan stamp (no motion distortion). LiDAR option
``sweep=True`` (an FMCW LiDAR that scans its field of view during the frame, like the Aeva
Aeries I): the rays fire at the scan pattern's times after the stamp (patterns.py: the grid's
columns in ``GRID_SWEEP_STEPS`` groups; the Aeva pattern line by line), the sweep starting at
the stamp and spanning one period; each group of rays is cast from the sensor pose at its own
time, so a point is reported in the sensor frame of its own time (motion distortion), its
Doppler is the radial velocity at that time, and the per-point field ``time_offset_s`` [s]
holds the offset.

Doppler (sensor frame, positive = receding) is the exact radial velocity of each point relative
to the sensor: doppler = d . (R_world_sensor^T u - v_s), with d the unit direction of the
noise-free point, u the point's world velocity (0 for static points) and v_s the sensor
origin's velocity in the sensor frame. The rotation term vanishes because d . (w x p) = 0.

Radar scans come mostly from the scene's persistent scattering centres (scatterers.py; their
own RNG stream from the seed, so the same physical points are seen frame after frame), plus
diffuse returns of random rays; each radar point carries ``gt_scatterer`` (the centre's id,
-1 for diffuse returns, clutter and ghosts).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np

from loaders.scan import Scan, SensorInfo, Sequence
from loaders.synthetic.codehash import current_code_hash
from loaders.synthetic.groundtruth import ground_truth, pipeline_params
from loaders.synthetic.motion import Motion, make_profile
from loaders.synthetic.raycast import GROUND_ID, cast
from loaders.synthetic.scatterers import OCCLUSION_TOL, build_scatterers, candidates, finish
from loaders.synthetic.scenes import GROUND, SCENES, TUNNEL_WALL, build_scene, motion_spec
from loaders.synthetic.sensors import (
    SENSORS,
    fading_db,
    get_sensor,
    measure,
    point_snr_db,
    ray_directions,
    sweep_offsets,
    with_rays,
)

OPTIONS = {
    "points": "target points per frame (LiDAR: the ray count; radar: the diffuse rays and the "
              "scatterer SNR gain; calibrated on probe frames)",
    "uturn": "loop: insert a ~0.55 rad/s U-turn",
    "speed": "(low, high) speed range [m/s]",
    "road_radius": "curved-wall: road radius [m]",
    "rib_spacing": "tunnel: rib spacing [m] (default 3-5 m; 0 = a smooth lining without ribs)",
    "one_lane": "tunnel-vehicles: traffic only ahead in the ego's lane, none oncoming "
                "(a one-lane tunnel with alternating signals, like Baker-Barry); default False",
    "attitude_deg": "pitch/roll oscillation amplitude [deg] (0 = flat, default 0.6)",
    "jitter_s": "deterministic stamp jitter, standard deviation [s] (default 0)",
    "t0": "first stamp [s] (default 0)",
    "sweep": "LiDAR: scan the field of view during the period (per-point time_offset_s, "
             "motion distortion, Doppler at each point's own time); default False",
    "gt": "ground-truth pipeline (groundtruth.py): exact (default), ntu4dradlm or campus",
    "edge_band": "radar: scatterers up to one resolution cell plus 3 sigma of angle error "
                 "beyond the field of view are detected too (its edge cuts measured angles; "
                 "sensors.detection_margin_deg); default True. False: the previous cut (the "
                 "edge bands hold detections from inside only, which tilts the loop's Doppler "
                 "ego velocity up by about 0.05 deg), kept to reproduce older stores",
}


def list_scenes() -> dict[str, str]:
    """Scene name -> one-line description."""
    return dict(SCENES)


def list_sensors() -> dict[str, str]:
    """Sensor name -> one-line description."""
    return {name: spec.description for name, spec in SENSORS.items()}


def doppler_of(points_s: np.ndarray, v_sensor: np.ndarray,
               point_velocity_s: np.ndarray | None = None) -> np.ndarray:
    """Radial velocity [m/s, + receding] of points ``points_s`` (N, 3, sensor frame) seen by a
    sensor moving with ``v_sensor`` (3,, sensor frame); ``point_velocity_s`` (N, 3) is each
    point's own velocity rotated into the sensor frame (R_world_sensor^T u), None if static."""
    d = points_s / np.linalg.norm(points_s, axis=1, keepdims=True)
    rel = -np.broadcast_to(np.asarray(v_sensor, dtype=float), points_s.shape)
    if point_velocity_s is not None:
        rel = rel + point_velocity_s
    return np.einsum("ij,ij->i", d, rel)


def params_hash(params: dict) -> str:
    """Hash of a sequence's parameters and of the generator's code."""
    text = json.dumps({**params, "generator_code": current_code_hash()}, sort_keys=True,
                      default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


class SyntheticSequence(Sequence):
    """A synthetic sequence of ``frames`` scans of ``scene`` seen by ``sensor``.

    ``name`` and ``meta`` (merged into the provenance) do not change the data.
    Attributes besides the Sequence API: ``motion`` (the vehicle model), ``scene_model``,
    ``spec`` (the sensor spec), ``scatterers`` (radar: the scene's scattering centres, else
    None), ``sensor_twist(i)``.
    """

    def __init__(self, scene: str, sensor: str, frames: int, seed: int = 0, noise: bool = True,
                 *, name: str | None = None, meta: dict | None = None, **options) -> None:
        unknown = sorted(set(options) - set(OPTIONS))
        if unknown:
            raise ValueError(f"unknown synthetic option(s) {unknown}; known: {sorted(OPTIONS)}")
        if scene not in SCENES:
            raise ValueError(f"unknown scene {scene!r}; known: {', '.join(SCENES)}")
        if frames < 1:
            raise ValueError(f"frames must be >= 1, got {frames}")
        self.spec = spec = get_sensor(sensor)
        self.seed, self.noise, self.options = int(seed), bool(noise), dict(options)
        self.scene_name = scene
        period = spec.period_s
        k = np.arange(frames)
        jitter = float(options.get("jitter_s", 0.0))
        offsets = np.zeros(frames)
        if jitter > 0:
            j = np.random.default_rng([self.seed, 4]).normal(0.0, jitter, frames)
            offsets = np.clip(j, -period / 4, period / 4)
        self._rel = k * period + offsets  # motion time of each scan [s]
        self._stamps = float(options.get("t0", 0.0)) + self._rel
        plan = motion_spec(scene, spec.kind, np.random.default_rng([self.seed, 1]), options)
        duration = float(max(self._rel[-1], period))
        profile = make_profile(plan["kind"], np.random.default_rng([self.seed, 2]), duration,
                               plan["speed"], float(options.get("attitude_deg", 0.6)),
                               plan["curvature"])
        margin = (spec.max_range + 250.0) / max(plan["speed"][0], 1.0)
        self.motion = Motion(profile, spec.T_body_sensor, -margin, duration + margin)
        sigma_end = float(self.motion.planar_state(np.array([duration]))["sigma"][0])
        self.scene_model = build_scene(scene, self.motion, plan,
                                       np.random.default_rng([self.seed, 3]), options,
                                       sigma_end, spec.max_range)
        # radar: persistent scattering centres of the scene (own RNG stream)
        self.scatterers = (build_scatterers(self.scene_model, np.random.default_rng([self.seed, 5]))
                           if spec.kind == "radar" else None)
        self._poses = self.motion.sensor_pose(self._rel)
        self._twist = self.motion.sensor_twist(self._rel)
        self.name = name or f"{scene}_{sensor}_s{self.seed}"
        if "points" in options:
            self.spec = spec = self._calibrated(spec, int(options["points"]))
        self.sensor = SensorInfo(kind=spec.kind, period_s=period,
                                 T_body_sensor=spec.T_body_sensor, model=sensor)
        self.gt_pipeline = str(options.get("gt", "exact"))
        self.ground_truth = ground_truth(self.gt_pipeline, self.motion.sensor_pose, self._rel,
                                         self._stamps, np.random.default_rng([self.seed, 6]))
        params = {"scene": scene, "sensor": sensor, "frames": int(frames), "seed": self.seed,
                  "noise": self.noise, "options": self.options}
        self.provenance = {
            "source": "synthetic", "generator_code_hash": current_code_hash(), **params,
            "params_hash": params_hash(params), "motion_profile": profile.as_dict(),
            "scene_summary": self.scene_model.summary(), "sensor_spec": spec.as_dict(),
            "gt_pipeline": {"name": self.gt_pipeline, **pipeline_params(self.gt_pipeline)},
            **(meta or {}),
        }

    def _calibrated(self, spec, target: int):
        """Spec giving about ``target`` points on the middle frame. LiDAR: the ray count.
        Radar: the diffuse ray count and the scatterer SNR gain (a few probe frames)."""
        if spec.kind == "radar":
            for k in range(6):
                self.spec = spec
                ratio = target / max(len(self.scan(len(self) // 2)), 1)
                if abs(ratio - 1.0) < 0.05:
                    break
                rays = spec.rays if k else int(round(min(max(spec.rays * ratio, 50), 50000)))
                spec = replace(spec, rays=rays,
                               point_gain_db=spec.point_gain_db + 15.0 * np.log10(ratio))
            return spec
        probe_rays = min(spec.rays, 8000)
        self.spec = with_rays(spec, probe_rays)
        n = len(self.scan(len(self) // 2))
        rays = probe_rays * target / max(n, 1)
        return with_rays(spec, int(round(min(max(rays, target), 4 * target))))

    def __len__(self) -> int:
        return len(self._stamps)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def sensor_twist(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """Exact (v_s, w_s) of the sensor at scan ``index``, sensor frame [m/s, rad/s]."""
        return self._twist[0][index].copy(), self._twist[1][index].copy()

    def raw_hits(self, index: int) -> dict[str, np.ndarray]:
        """Exact hits of frame ``index`` before the sensor model: points (sensor frame), Doppler,
        cosine of incidence, material id, dynamic flag, primitive id (see raycast.cast).
        Radar: first the visible scattering centres whose SNR with this frame's fading
        (``fading_db``) exceeds the detection threshold (``scatterer`` = their id, ``rcs_db``
        their RCS towards the sensor, ``swerling`` their fluctuation model, ``angle_bias``
        their persistent angle error in units of the sensor's sigma_bias_deg), then the
        diffuse returns of the random rays (``scatterer`` = -1). LiDAR with ``sweep``: also
        ``time_offset_s`` (each point's time after the stamp; points and Doppler at that time)."""
        spec = self.spec
        rng = np.random.default_rng([self.seed, int(index), 7])
        D_s = ray_directions(spec, rng)
        t_rel = float(self._rel[index])
        if spec.kind == "lidar" and self.options.get("sweep"):
            offsets = sweep_offsets(spec, len(D_s))
            parts = []
            for tau in np.unique(offsets):
                rows = offsets == tau
                part = self._cast(D_s[rows], t_rel + tau, None)
                part["time_offset_s"] = np.full(len(part["points"]), tau)
                parts.append(part)
            out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        else:
            out = self._cast(D_s, t_rel, rng)
        out["rng"] = rng
        return out

    def _cast(self, D_s: np.ndarray, t_rel: float, rng) -> dict[str, np.ndarray]:
        """Hits of the rays ``D_s`` (sensor frame) from the sensor pose at motion time ``t_rel``
        [s]; radar (``self.scatterers``): plus the visible scattering centres (``rng`` draws
        their fading)."""
        spec = self.spec
        T = self.motion.sensor_pose(np.array([t_rel]))[0]
        v_s = self.motion.sensor_twist(np.array([t_rel]))[0][0]
        R, o = T[:3, :3], T[:3, 3]
        D_w = D_s @ R.T
        geom = self.scene_model.geometry(t_rel)
        n_rays = len(D_s)
        cand = None
        if self.scatterers is not None:  # one cast for the random rays and the scatterers
            cand = candidates(self.scatterers, geom, o, R, spec,
                              bool(self.options.get("edge_band", True)))
            # this frame's fading first: only the scatterers above the detection threshold
            # need the occlusion test (the same SNR as in sensors.measure)
            D_c = cand["points_s"] / cand["range"][:, None]
            cand["fading_db"] = fading_db(rng, self.scatterers.swerling[cand["ids"]])
            snr = cand["fading_db"] + point_snr_db(
                spec, cand["rcs_db"], cand["range"], np.arctan2(D_c[:, 1], D_c[:, 0]),
                np.arcsin(np.clip(D_c[:, 2], -1.0, 1.0)))
            strong = snr > spec.snr_threshold_db - 1e-6
            cand = {k: v[strong] for k, v in cand.items()}
            D_c = D_c[strong]
            D_s, D_w = np.concatenate([D_s, D_c]), np.concatenate([D_w, D_c @ R.T])
        t_limit = None
        if cand is not None:  # scatterer rays: an occlusion test up to the scatterer
            t_limit = np.concatenate([np.full(n_rays, np.inf), cand["range"] - OCCLUSION_TOL])
        t, prim, normal = cast(geom, o, D_w, D_s, R, spec.max_range, t_limit)
        if cand is not None:
            vis = finish(self.scatterers, geom, o, cand, t[n_rays:])
            t, prim, normal = t[:n_rays], prim[:n_rays], normal[:n_rays]
            D_s, D_w = D_s[:n_rays], D_w[:n_rays]
        hit = np.isfinite(t) & (t >= spec.min_range) & (t <= spec.max_range)
        t, prim, normal, D_s, D_w = t[hit], prim[hit], normal[hit], D_s[hit], D_w[hit]
        pts_s = t[:, None] * D_s
        obj = prim >= 0
        material = np.where(prim == GROUND_ID, GROUND, TUNNEL_WALL)
        material[obj] = geom.material[prim[obj]]
        dynamic = np.zeros(len(t), bool)
        dynamic[obj] = geom.dynamic[prim[obj]]
        u_s = np.zeros_like(pts_s)
        if dynamic.any():
            pts_w = o + t[dynamic, None] * D_w[dynamic]
            u_s[dynamic] = geom.point_velocity(prim[dynamic], pts_w) @ R
        out = {"points": pts_s, "doppler": doppler_of(pts_s, v_s, u_s),
               "cos_inc": np.abs(np.einsum("ij,ij->i", D_w, normal)), "material": material,
               "dynamic": dynamic, "prim": prim}
        if cand is not None:
            sc = {"points": vis["points_s"],
                  "doppler": doppler_of(vis["points_s"], v_s, vis["velocity_w"] @ R),
                  "cos_inc": vis["cos_inc"], "material": vis["material"],
                  "dynamic": vis["dynamic"], "prim": vis["prim"]}
            n_dif = len(t)
            out = {k: np.concatenate([sc[k], out[k]]) for k in out}
            out["scatterer"] = np.concatenate([vis["ids"], np.full(n_dif, -1, np.int64)])
            out["rcs_db"] = np.concatenate([vis["rcs_db"], np.full(n_dif, np.nan)])
            out["swerling"] = np.concatenate([vis["swerling"], np.ones(n_dif, np.int64)])
            out["angle_bias"] = np.concatenate([vis["bias"], np.zeros((n_dif, 2))])
            out["fading_db"] = np.concatenate([vis["fading_db"], np.zeros(n_dif)])
        return out

    def scan(self, index: int) -> Scan:
        raw = self.raw_hits(index)
        extra = {k: raw[k] for k in ("scatterer", "rcs_db", "swerling", "angle_bias",
                                     "time_offset_s") if k in raw}
        if "fading_db" in raw:
            extra["fading"] = raw["fading_db"]
        pts, dop, fields = measure(self.spec, raw["rng"], raw["points"], raw["doppler"],
                                   raw["cos_inc"], raw["material"], raw["dynamic"],
                                   self._twist[0][index], self.noise, **extra)
        return Scan(stamp=self._stamps[index], points=pts, doppler=dop, fields=fields,
                    source=f"{self.name}, frame {index}")
