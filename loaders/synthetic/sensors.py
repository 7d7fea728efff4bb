"""Sensor models: ray pattern, detection, measurement noise, clutter and ghosts.

Sensor frame: x forward, y left, z up. Azimuth = atan2(y, x), elevation = asin(z / r) [rad];
range r [m]; Doppler [m/s, positive = receding]. Noise is added in (range, azimuth, elevation,
Doppler) to the exact values, then points are converted back to Cartesian; points whose noisy
measurement falls outside the field of view or the range limits are not reported.

Radar: detections come mostly from the scene's persistent scattering centres (see
scatterers.py: world-fixed, or fixed in a mover's body frame) that are in the field of view
(widened by ``detection_margin_deg``, the generator option ``edge_band``: one just outside
is detected inside through its neighbouring cells and angle errors), face the sensor and are
not occluded; each is detected when its SNR (point-target radar equation: RCS, aspect, r^-4
range loss, antenna taper and per-frame Swerling 1/3 fading) exceeds a threshold, so
detections flicker but most persist.
A semi-dense sensor also reports a strong scatterer in its neighbouring resolution cells
(``resolution``, ``spread_loss_db``). A smaller share of diffuse surface returns comes from
random rays (uniform in the FoV, per-frame RNG; patch reflectivity by material, incidence,
r^-2 range loss, Swerling 1). Then random dropouts, multipath ghosts and clutter are applied
and the strongest ``max_points`` detections are kept. Radar noise follows the SNR
(~1/sqrt(SNR), ``sigma_*`` at ``snr_ref_db``, floored at ``noise_floor``) and each scatterer
has a persistent angle bias (``sigma_bias_deg``), plus an SNR-independent angular accuracy
(``angle_accuracy_deg``). LiDAR: a fixed scan pattern (patterns.py: a uniform grid, or Aeva's
64-line CARLA pattern; density falls with range), a weak-return cut-off and random dropouts.

Per-point fields: radar ``power`` [dB], ``rcs`` [dBsm], ``snr`` [dB]; LiDAR ``intensity``
[0..1]; both ``gt_label`` (0 static, 1 moving object, 2 clutter/ghost: ground truth, not a
measurement); radar ``gt_scatterer`` (ground truth: id of the scattering centre, -1 for diffuse
returns, clutter and ghosts).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from loaders.se3 import make_T
from loaders.synthetic import patterns

# patch reflectivity by material id (see scenes.MATERIAL_NAMES)
RADAR_REFLECTIVITY_DB = np.array([-22.0, 8.0, 8.0, 5.0, 10.0, 12.0, 15.0, -2.0, 6.0, 0.0, -6.0])
LIDAR_REFLECTIVITY = np.array([0.15, 0.4, 0.5, 0.35, 0.45, 0.5, 0.5, 0.3, 0.4, 0.2, 0.15])

LABEL_STATIC, LABEL_DYNAMIC, LABEL_CLUTTER = 0, 1, 2


@dataclass(frozen=True)
class SensorSpec:
    name: str
    kind: str  # "radar" | "lidar"
    description: str
    period_s: float
    lever_arm: tuple[float, float, float]  # sensor origin in the body frame [m]
    az_half_deg: float
    el_half_deg: float
    min_range: float
    max_range: float
    sigma_range: float  # [m]
    sigma_az_deg: float
    sigma_el_deg: float
    sigma_doppler: float  # [m/s]
    rays: int = 0  # radar: random rays per frame (diffuse returns); lidar: grid rays (~ points)
    max_points: int = 0  # radar output limit (strongest kept)
    snr_gain_db: float = 30.0  # SNR of a 0 dB patch at 10 m (diffuse returns)
    point_gain_db: float = 45.0  # SNR of a 0 dBsm point scatterer at 10 m
    edge_loss_db: float = 3.0  # antenna loss at the edges of the field of view
    snr_ref_db: float = 20.0  # radar: SNR at which the noise has the sigma_* values
    noise_floor: float = 0.7  # radar: smallest noise scale (strong targets)
    sigma_bias_deg: float = 0.0  # radar: persistent angle bias of each scatterer
    # radar: angular accuracy [deg]: per-detection azimuth and elevation noise that does not
    # shrink with SNR (array calibration and resolution limits), added in quadrature to the
    # SNR-scaled noise; the one fitted value per radar class (README.md, "Calibration")
    angle_accuracy_deg: float = 0.0
    # radar: resolution cells (range [m], azimuth [deg], elevation [deg]) and the loss [dB] from
    # a scatterer's cell to its neighbouring cell along each; a strong scatterer is also
    # detected in the neighbouring cells (point-spread mainlobe). () = peak detections only.
    resolution: tuple[float, float, float] = ()
    spread_loss_db: tuple[float, float, float] = ()
    snr_threshold_db: float = 12.0
    pattern: str = "grid"  # LiDAR scan pattern (patterns.py): "grid" or "aeva-64"
    dropout: float = 0.0  # random per-point loss
    ghost_frac: float = 0.0  # multipath ghosts per detection
    clutter_frac: float = 0.0  # random clutter per detection

    def as_dict(self) -> dict:
        return asdict(self)

    @property
    def T_body_sensor(self) -> np.ndarray:
        return make_T(np.eye(3), np.array(self.lever_arm))


SENSORS: dict[str, SensorSpec] = {
    "radar-sparse": SensorSpec(
        "radar-sparse", "radar",
        "ZF FRGen21-like sparse 4D radar: 60 ms, 400-1,400 detections, +-75 x +-15 deg, 100 m",
        0.06, (3.5, 0.0, 0.6), 75.0, 15.0, 0.5, 100.0, 0.12, 1.0, 1.3, 0.1,
        rays=250, max_points=1400, point_gain_db=48.0, noise_floor=0.2, snr_ref_db=12.0,
        sigma_bias_deg=0.5, dropout=0.05, ghost_frac=0.03, clutter_frac=0.02),
    # Oculii Eagle, calibrated on the real NTU4DRadLM loop-1 sample (realism.py): ranges to
    # 191 m (p99 170 m) -> max_range 200 m; at most 4,620 points a frame -> max_points;
    # ego-velocity residual 0.044 m/s RMS -> sigma_doppler 0.03 m/s (+ angle noise; the
    # residual's Doppler part: real 0.036, synthetic 0.038 m/s); frame-to-frame feature
    # residual |f - g| of the kept pairs (real 0.021 / 0.078 / 0.21 / 0.36 m^2 at 0-20 / 20-50 /
    # 50-100 / 100-250 m) -> sigma_range 0.02 m (was 0.08: 2-3x the real residual);
    # median 4,318 points a frame -> point_gain_db 56 (was 52, before the loop scene's lower
    # buildings); azimuth within +-60 deg (manual: 120 x 40 deg field of view); 12 Hz (the
    # dataset paper)
    "radar-semidense": SensorSpec(
        "radar-semidense", "radar",
        "Oculii Eagle-like semi-dense 4D radar: 1/12 s, 1,000-4,600 points, +-60 x +-15 deg, "
        "200 m",
        1.0 / 12.0, (3.6, 0.0, 0.7), 60.0, 15.0, 0.5, 200.0, 0.02, 0.6, 1.0, 0.03,
        rays=1200, max_points=4620, point_gain_db=56.0, noise_floor=0.08, snr_ref_db=0.0,
        sigma_bias_deg=0.3, resolution=(0.25, 1.0, 2.0), spread_loss_db=(6.0, 6.0, 9.0),
        dropout=0.03, ghost_frac=0.02, clutter_frac=0.015),
    "lidar-dense": SensorSpec(
        "lidar-dense", "lidar",
        "Aeva Aeries-like FMCW LiDAR: 0.1 s, 40k-120k points on a 120 x 30 deg grid, 150 m",
        0.1, (1.5, 0.0, 1.8), 60.0, 15.0, 1.0, 150.0, 0.02, 0.02, 0.02, 0.03,
        rays=60000, dropout=0.01),
    # Aeva's own CARLA FMCW-LiDAR (Aeva's CARLA fork, 2024; shared/REFERENCE.md): scan pattern
    # 64-19.2-Uniform (patterns.py; every 6th of the 3,051 points of a line kept: 509 a line,
    # 32,576 rays), range noise 0.05 m (std) and 30 % random dropout (its example script's
    # noise), no angle noise (a ray cast), mounted 1.04 m ahead and 1.69 m up (the same
    # script); 10 Hz (the DICP sequences: frames 0.1 s apart); max range 150 m (not published
    # for the example; 40-300 m changes `doppler` by < 10 %, README.md)
    "lidar-aeva": SensorSpec(
        "lidar-aeva", "lidar",
        "Aeva FMCW LiDAR, CARLA scan pattern 64-19.2-Uniform: 0.1 s, 64 lines x 509 points, "
        "144 x 19.2 deg, 150 m, range noise 0.05 m, 30 % dropout",
        0.1, (1.04, 0.0, 1.69), 72.0, 9.6, 1.0, 150.0, 0.05, 0.0, 0.0, 0.03,
        rays=64 * 509, dropout=0.3, pattern="aeva-64"),
}

#: The only fitted values of the synthetic suite, one per sensor class (never per sequence):
#: class -> (sensor, SensorSpec field, value, how it was fitted). Each is a physical parameter
#: no source publishes, fitted to the paper's Table III rows of `doppler` ("Ours") only: each
#: paper row against the mean of `doppler` on the 4 synthetic tuning seeds (1000-1003) of its
#: scene, least RMS of log(synthetic / paper) over every cell (8-48 m, rotation and
#: translation) on a grid (loaders/synthetic/README.md, "Calibration"). Every other method's
#: numbers on the suite are predictions. The dense LiDAR has none (no single unpublished
#: parameter brings its rows near the paper's; README.md).
CALIBRATION: dict[str, tuple[str, str, float, str]] = {
    "Sparse 4D Radar": ("radar-frgen21", "angle_accuracy_deg", 0.75,
                        "FRGen21 angular accuracy, not published; grid 0.25-1.5 deg in 0.25 deg "
                        "steps against the doppler rows of Campus1-2 (RMS log ratio 0.343; "
                        "0.5 deg: 0.392, 1.0 deg: 0.354)"),
    "Semi-Dense 4D Radar": ("radar-eagle", "angle_accuracy_deg", 0.0,
                            "Eagle angular accuracy, not published; grid 0-0.3 deg in 0.1 deg "
                            "steps against the doppler rows of Loop1_0/2/3/4: the best value "
                            "is 0, no change (RMS log ratio 0.402; 0.1 deg: 0.407)"),
}
# the dataset-imitating radars of synthetic-paper: the generic models with their class's fitted
# value (the generic ones stay as they are for development and CI)
SENSORS["radar-frgen21"] = replace(
    SENSORS["radar-sparse"], name="radar-frgen21",
    description="ZF FRGen21 (Campus) sparse 4D radar: radar-sparse with the fitted angular "
                "accuracy", angle_accuracy_deg=CALIBRATION["Sparse 4D Radar"][2])
SENSORS["radar-eagle"] = replace(
    SENSORS["radar-semidense"], name="radar-eagle",
    description="Oculii Eagle (NTU4DRadLM) semi-dense 4D radar: radar-semidense with the "
                "fitted angular accuracy", angle_accuracy_deg=CALIBRATION["Semi-Dense 4D Radar"][2])


def get_sensor(name: str) -> SensorSpec:
    """The spec for sensor ``name``."""
    if name not in SENSORS:
        raise ValueError(f"unknown sensor {name!r}; known: {', '.join(SENSORS)}")
    return SENSORS[name]


def with_rays(spec: SensorSpec, rays: int) -> SensorSpec:
    return replace(spec, rays=int(rays))


def grid_shape(spec: SensorSpec) -> tuple[int, int]:
    """(n_az, n_el) of a ``grid`` LiDAR: equal angular spacing, about ``rays`` rays."""
    return patterns.grid_shape(spec.rays, spec.az_half_deg, spec.el_half_deg)


#: LiDAR grid sweep: column groups fired one after the other over one period (patterns.py)
SWEEP_STEPS = patterns.GRID_SWEEP_STEPS


def sweep_offsets(spec: SensorSpec, n_rays: int) -> np.ndarray:
    """Time offset [s] after the stamp of each ray of ``ray_directions`` (LiDAR, the spec's
    scan pattern; see ``patterns.firing_offsets``)."""
    offsets = patterns.firing_offsets(spec.pattern, spec.rays, spec.az_half_deg,
                                      spec.el_half_deg, spec.period_s)
    if n_rays != len(offsets):
        raise ValueError(f"sweep_offsets: {n_rays} rays, expected the pattern's {len(offsets)}")
    return offsets


def _unit(az: np.ndarray, el: np.ndarray) -> np.ndarray:
    return patterns.unit_vectors(az, el)


def ray_directions(spec: SensorSpec, rng: np.random.Generator) -> np.ndarray:
    """Unit ray directions (N, 3) in the sensor frame for one frame: LiDAR, the spec's scan
    pattern; radar, ``rays`` random rays uniform in the field of view."""
    if spec.kind == "lidar":
        return patterns.directions(spec.pattern, spec.rays, spec.az_half_deg, spec.el_half_deg)
    a, e = np.radians(spec.az_half_deg), np.radians(spec.el_half_deg)
    return _unit(rng.uniform(-a, a, spec.rays), rng.uniform(-e, e, spec.rays))


def _spherical(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r = np.linalg.norm(p, axis=1)
    return r, np.arctan2(p[:, 1], p[:, 0]), np.arcsin(np.clip(p[:, 2] / r, -1.0, 1.0))


def fading_db(rng: np.random.Generator, swerling: np.ndarray) -> np.ndarray:
    """Per-frame RCS fluctuation [dB], mean power 1: Swerling 1 (exponential power, many
    comparable reflectors) or Swerling 3 (chi-square with 4 degrees of freedom, one dominant
    reflector)."""
    p = np.where(swerling == 3, rng.gamma(2.0, 0.5, len(swerling)),
                 rng.exponential(1.0, len(swerling)))
    return 10 * np.log10(np.maximum(p, 1e-12))


def point_snr_db(spec: SensorSpec, rcs_db, r, az, el) -> np.ndarray:
    """Mean SNR [dB] of point scatterers (before fading): radar equation, SNR ~ RCS / r^4."""
    return (rcs_db - 40 * np.log10(np.maximum(r, 0.5) / 10.0) + spec.point_gain_db
            + antenna_db(spec, az, el))


def detection_margin_deg(spec: SensorSpec) -> np.ndarray:
    """How far beyond the field of view (azimuth, elevation) [deg] a radar scatterer can lie and
    still be reported inside it: one resolution cell (its neighbouring-cell detections,
    ``_spread``) plus 3 sigma of the angle error of a strong detection (persistent bias, noise
    at the floor of the SNR scale, angular accuracy). LiDAR: 0 (fixed ray pattern).

    The field of view is a cut on measured angles, so the detections near its edge come from
    scatterers on both sides of it. Sampling only the scatterers inside it left the edge bands
    with detections displaced towards the edge and none coming in from beyond it: at the dense
    upper edge of the loop scene (buildings) the detections a cell above their scatterer, with
    its Doppler, tilted the Doppler ego velocity up by about 0.05 deg (the pitch bias of
    ``bench calibrate-coverage``, docs/doppler-ego.md). Applied unless the generator option
    ``edge_band`` is False (loaders/synthetic/generate.py; on by default, so in every suite and
    the CI baseline, since issue 40)."""
    if spec.kind != "radar":
        return np.zeros(2)
    cell = np.array(spec.resolution[1:] if spec.resolution else (0.0, 0.0), float)
    noise = np.array([spec.sigma_az_deg, spec.sigma_el_deg]) * spec.noise_floor
    return cell + 3.0 * np.sqrt(spec.sigma_bias_deg**2 + noise**2 + spec.angle_accuracy_deg**2)


def antenna_db(spec: SensorSpec, az: np.ndarray, el: np.ndarray) -> np.ndarray:
    """Two-way antenna gain relative to boresight [dB]: ``-spec.edge_loss_db`` at the edges of
    the field of view (quadratic taper in azimuth and elevation)."""
    return -spec.edge_loss_db * ((az / np.radians(spec.az_half_deg)) ** 2
                                 + (el / np.radians(spec.el_half_deg)) ** 2) / 2.0


def measure(spec: SensorSpec, rng: np.random.Generator, points: np.ndarray,
            doppler: np.ndarray, cos_inc: np.ndarray, material: np.ndarray,
            dynamic: np.ndarray, v_sensor: np.ndarray, noise: bool, *,
            scatterer: np.ndarray | None = None, rcs_db: np.ndarray | None = None,
            swerling: np.ndarray | None = None, angle_bias: np.ndarray | None = None,
            fading: np.ndarray | None = None, time_offset_s: np.ndarray | None = None):
    """Turn exact hits (sensor frame) into measurements: returns points (M, 3), Doppler (M,)
    and the per-point fields. With ``noise=False`` the kept points and Doppler are exact and
    there is no clutter or ghost (detection sampling and dropouts still apply).

    Radar: rows with ``scatterer >= 0`` are discrete scattering centres with RCS ``rcs_db``
    [dBsm] (point-target radar equation, SNR ~ RCS / r^4, Swerling ``swerling`` fading); the
    other rows are diffuse surface returns (patch reflectivity by material and incidence,
    SNR ~ 1 / r^2, Swerling 1). ``fading`` [dB], optional: the scatterers' fading of this frame
    when the caller has drawn it (the values of the other rows are ignored). ``time_offset_s``
    (LiDAR sweep), optional: each hit's time after the stamp [s], kept as a per-point field."""
    r, az, el = _spherical(points)
    label = np.where(dynamic, LABEL_DYNAMIC, LABEL_STATIC)
    if spec.kind == "lidar":
        intensity = LIDAR_REFLECTIVITY[material] * cos_inc
        keep = intensity / np.maximum(r / 100.0, 0.1) ** 2 > 0.01
        keep &= rng.uniform(size=len(r)) >= spec.dropout
        fields = {"intensity": intensity}
        if time_offset_s is not None:
            fields["time_offset_s"] = np.asarray(time_offset_s, dtype=np.float64)
        sig_scale = np.ones(len(r))
    else:
        if scatterer is None:
            scatterer = np.full(len(r), -1, dtype=np.int64)
        point = scatterer >= 0
        # diffuse patches: material reflectivity, rough surfaces 10 log10(cos), the road is
        # near-specular 30 log10(cos), SNR ~ 1 / r^2
        inc_db = np.where(material == 0, 30.0, 10.0) * np.log10(np.maximum(cos_inc, 1e-3))
        snr = (RADAR_REFLECTIVITY_DB[material] + inc_db
               - 20 * np.log10(np.maximum(r, 0.5) / 10.0) + spec.snr_gain_db
               + antenna_db(spec, az, el))
        if point.any():
            snr[point] = point_snr_db(spec, np.asarray(rcs_db)[point], r[point], az[point],
                                      el[point])
        if fading is None:
            fading = fading_db(rng, np.where(point, 3 if swerling is None else swerling, 1))
        else:  # drawn by the caller for the scatterers; diffuse returns: Swerling 1
            fading = np.array(fading, dtype=float)
            fading[~point] = fading_db(rng, np.ones(int((~point).sum()), np.int64))
        snr = snr + fading
        if noise and spec.spread_loss_db and point.any():
            r, az, el, doppler, label, snr, scatterer, angle_bias = _spread(
                spec, rng, r, az, el, doppler, label, snr, scatterer, angle_bias)
        keep = (snr > spec.snr_threshold_db) & (rng.uniform(size=len(r)) >= spec.dropout)
        fields = {"snr": snr, "gt_scatterer": scatterer.astype(np.float64)}
        # thermal noise ~ 1 / sqrt(SNR) (Cramer-Rao), floored by the sensor's resolution limits
        sig_scale = np.clip(10 ** ((spec.snr_ref_db - snr) / 20.0), spec.noise_floor, 1.5)
        if angle_bias is not None and noise:
            b = np.radians(spec.sigma_bias_deg) * angle_bias
            az, el = az + b[:, 0], el + b[:, 1]
    r, az, el, doppler, label = r[keep], az[keep], el[keep], doppler[keep], label[keep]
    sig_scale = sig_scale[keep]
    fields = {k: v[keep] for k, v in fields.items()}
    if spec.kind == "radar" and noise:
        r, az, el, doppler, label, fields, sig_scale = _ghosts_and_clutter(
            spec, rng, r, az, el, doppler, label, fields, sig_scale, v_sensor)
    if noise:
        n = len(r)
        r_scale = sig_scale if spec.kind == "radar" else 1.0
        r = r + rng.normal(0.0, spec.sigma_range, n) * r_scale
        az = az + rng.normal(0.0, np.radians(spec.sigma_az_deg), n) * sig_scale
        el = el + rng.normal(0.0, np.radians(spec.sigma_el_deg), n) * sig_scale
        if spec.angle_accuracy_deg > 0:
            acc = np.radians(spec.angle_accuracy_deg)
            az = az + rng.normal(0.0, acc, n)
            el = el + rng.normal(0.0, acc, n)
        doppler = doppler + rng.normal(0.0, spec.sigma_doppler, n)
    ok = ((r >= spec.min_range) & (r <= spec.max_range)
          & (np.abs(az) <= np.radians(spec.az_half_deg))
          & (np.abs(el) <= np.radians(spec.el_half_deg)))
    if spec.kind == "radar" and spec.max_points and ok.sum() > spec.max_points:
        strongest = np.argsort(-np.where(ok, fields["snr"], -np.inf), kind="stable")
        ok = np.zeros(len(r), bool)
        ok[strongest[:spec.max_points]] = True
    pts = r[ok, None] * _unit(az[ok], el[ok]) if noise else None
    if not noise:  # exact: keep the caller's points (no round trip through angles)
        pts = points[keep][ok]
    fields = {k: v[ok] for k, v in fields.items()}
    if spec.kind == "radar":
        log_r = 10 * np.log10(np.maximum(r[ok], 0.5) / 10.0)
        point = fields["gt_scatterer"] >= 0
        fields["rcs"] = np.where(point, fields["snr"] - spec.point_gain_db + 4 * log_r,
                                 fields["snr"] - spec.snr_gain_db + 2 * log_r)
        fields["power"] = fields["snr"] + 40.0  # receiver noise floor at 40 dB (arbitrary)
    fields["gt_label"] = label[ok].astype(np.float64)
    return pts, doppler[ok], fields


def _spread(spec, rng, r, az, el, doppler, label, snr, scatterer, angle_bias):
    """Detections of strong scatterers in the neighbouring resolution cells: one cell away
    in range, azimuth or elevation, with the scatterer's Doppler and SNR minus the cell loss
    (plus a small random variation with the scatterer's position inside its cell)."""
    res = np.array(spec.resolution, float)
    res[1:] = np.radians(res[1:])
    loss = np.array(spec.spread_loss_db, float)
    src = np.flatnonzero((scatterer >= 0) & (snr - loss.min() + 3.0 > spec.snr_threshold_db))
    rows, d_r, d_az, d_el, d_snr = [], [], [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            s_snr = snr[src] - loss[axis] + rng.normal(0.0, 1.5, len(src))
            ok = s_snr > spec.snr_threshold_db
            rows.append(src[ok])
            d_snr.append(s_snr[ok])
            off = np.zeros((3, ok.sum()))
            off[axis] = sign * res[axis]
            d_r.append(off[0])
            d_az.append(off[1])
            d_el.append(off[2])
    rows = np.concatenate(rows)
    cat = np.concatenate
    bias = None if angle_bias is None else cat([angle_bias, angle_bias[rows]])
    return (cat([r, r[rows] + cat(d_r)]), cat([az, az[rows] + cat(d_az)]),
            cat([el, el[rows] + cat(d_el)]), cat([doppler, doppler[rows]]),
            cat([label, label[rows]]), cat([snr, cat(d_snr)]), cat([scatterer, scatterer[rows]]),
            bias)


def _ghosts_and_clutter(spec, rng, r, az, el, doppler, label, fields, sig_scale, v_sensor):
    """Multipath ghosts (a real detection seen further away, often mirrored in elevation, with
    its Doppler) and uniform clutter with Doppler unrelated to the scene."""
    n = len(r)
    snr = fields["snr"]
    n_ghost = int(rng.poisson(spec.ghost_frac * n)) if n else 0
    src = rng.integers(0, max(n, 1), n_ghost)
    g_r = r[src] * rng.uniform(1.1, 1.7, n_ghost)
    g_az = az[src] + rng.normal(0.0, np.radians(3.0), n_ghost)
    g_el = np.where(rng.uniform(size=n_ghost) < 0.5, -el[src], el[src])
    g_dop = doppler[src].copy()
    g_snr = snr[src] - rng.uniform(3.0, 10.0, n_ghost)
    n_clut = int(rng.poisson(spec.clutter_frac * n)) if n else 0
    a, e = np.radians(spec.az_half_deg), np.radians(spec.el_half_deg)
    c_r = rng.uniform(spec.min_range, 0.8 * spec.max_range, n_clut)
    c_az, c_el = rng.uniform(-a, a, n_clut), rng.uniform(-e, e, n_clut)
    c_dop = -(_unit(c_az, c_el) @ v_sensor) + rng.normal(0.0, 3.0, n_clut)
    c_snr = spec.snr_threshold_db + rng.exponential(3.0, n_clut)
    extra = n_ghost + n_clut
    return (np.concatenate([r, g_r, c_r]), np.concatenate([az, g_az, c_az]),
            np.concatenate([el, g_el, c_el]), np.concatenate([doppler, g_dop, c_dop]),
            np.concatenate([label, np.full(extra, LABEL_CLUTTER)]),
            {"snr": np.concatenate([snr, g_snr, c_snr]),
             **{k: np.concatenate([v, np.full(extra, -1.0)]) for k, v in fields.items()
                if k != "snr"}},
            np.concatenate([sig_scale, np.full(extra, 1.5)]))
