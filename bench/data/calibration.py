"""Is the ground truth's frame the sensor's frame? The rotation between them from the Doppler
ego velocity (the estimator behind ``bench calibrate`` and ``bench inspect``'s check).

The Doppler ego velocity (methods/ego_velocity.py) is the sensor's velocity in the sensor frame;
the ground truth gives the same velocity in the GT frame (central differences of the GT
positions, rotated into the GT frame). Over the frames with enough speed, the rotation
``R_gt_sensor`` that maps the one set of directions onto the other is fitted (Wahba/Kabsch on
unit vectors, Gauss-Newton on a rotation vector, outlier frames dropped at 3 robust sigmas).

Observability: a car moves forward, so velocity directions fix pitch and yaw of the mount but
hardly roll (rotation about the direction of travel). The information of each rotation axis is
the spread of the directions around it; an axis whose RMS spread is below ``min_spread`` is
not observable from velocity. Roll then comes from the road plane: per frame a plane fitted to
the points below the sensor gives the road normal in the sensor frame, paired with the world's
up direction in the GT frame (the road is level on average). Both are reported, with which
angles came from which cue and which remained unobservable.

Angles: ``R_gt_sensor = Rz(yaw) Ry(pitch) Rx(roll)`` [deg]; uncertainties are bootstrap
standard deviations over frames. The road-plane check reports the sensor's height above the
road and the road normal's tilt in the sensor frame and in the GT frame.

A corrected store keeps the points exactly as measured and corrects the ground truth:
``T_world_sensor := T_world_gt @ R_gt_sensor`` and ``T_body_sensor := T_body_sensor @
R_gt_sensor`` (methods see the same data; the scores then refer to the sensor's own frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory
from methods.ego_velocity import estimate_ego_velocity

ANGLES = ("roll", "pitch", "yaw")
AXES = np.eye(3)  # roll about x, pitch about y, yaw about z


@dataclass
class CalibrationResult:
    """R_gt_sensor (3x3) and its angles [deg]; std_deg from the bootstrap; source per angle
    ("velocity", "road plane" or "not observable"); frames used; road-plane check values."""

    R_gt_sensor: np.ndarray
    angles_deg: dict[str, float]
    std_deg: dict[str, float]
    source: dict[str, str]
    frames_used: int
    road: dict[str, float] = field(default_factory=dict)

    @property
    def total_deg(self) -> float:
        return float(np.degrees(Rotation.from_matrix(self.R_gt_sensor).magnitude()))

    @property
    def not_observable(self) -> list[str]:
        return [a for a in ANGLES if self.source[a] == "not observable"]


def gt_velocity_directions(gt: Trajectory, stamps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GT velocity in the GT frame at the scan stamps [m/s] (central differences) and the
    world up direction in the GT frame; NaN where the GT does not cover a frame."""
    n = len(stamps)
    vel, up = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    covered = gt.coverage_mask(stamps)
    if covered.sum() < 3:
        return vel, up
    poses = gt.interpolate(stamps[covered]).poses
    v_world = np.gradient(poses[:, :3, 3], stamps[covered], axis=0)
    R = poses[:, :3, :3]
    vel[covered] = np.einsum("nji,nj->ni", R, v_world)
    up[covered] = R[:, 2, :]  # R^T e_z
    return vel, up


def road_normal(scan: Scan, seed: int = 0, threshold_m: float = 0.15
                ) -> tuple[np.ndarray, float] | None:
    """Road plane under the sensor: (unit normal pointing up [sensor frame], height [m]) by
    RANSAC over the points 0.3 m or more below the sensor within 40 m; None without a plane
    (fewer than 30 supporting points, or a normal more than 20 deg from the sensor's z)."""
    p = scan.points
    sel = p[(p[:, 2] < -0.3) & (np.linalg.norm(p[:, :2], axis=1) < 40.0)]
    if len(sel) < 30:
        return None
    rng = np.random.default_rng(seed)
    s = sel[rng.integers(0, len(sel), size=(200, 3))]
    nrm = np.cross(s[:, 1] - s[:, 0], s[:, 2] - s[:, 0])
    length = np.linalg.norm(nrm, axis=1)
    ok = length > 1e-6
    nrm = nrm[ok] / length[ok, None]
    nrm *= np.sign(nrm[:, 2:3] + 1e-12)
    d = -np.einsum("ni,ni->n", nrm, s[ok, 0])
    upright = nrm[:, 2] > np.cos(np.radians(20))
    if not upright.any():
        return None
    nrm, d = nrm[upright], d[upright]
    count = (np.abs(sel @ nrm.T + d) < threshold_m).sum(axis=0)
    best = int(np.argmax(count))
    inl = sel[np.abs(sel @ nrm[best] + d[best]) < threshold_m]
    if len(inl) < 30:
        return None
    c = inl.mean(axis=0)
    normal = np.linalg.svd(inl - c)[2][-1]
    normal *= np.sign(normal[2])
    return normal, float(-(normal @ c))


def fit_rotation(a: np.ndarray, b: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Rotation R minimising sum |b - R a|^2 over unit-vector pairs, updating only the rotation
    axes (columns of AXES) flagged in ``free`` (Gauss-Newton on a rotation vector)."""
    R = np.eye(3)
    for _ in range(20):
        Ra = a @ R.T
        e = b - Ra
        # d(exp(th) R a)/d th_k = axis_k x (R a)
        J = np.stack([np.cross(AXES[k], Ra) for k in range(3)], axis=2)  # (n, 3, 3)
        J = J[:, :, free]
        H = np.einsum("nia,nib->ab", J, J)
        g = np.einsum("nia,ni->a", J, e)
        step = np.zeros(3)
        step[free] = np.linalg.solve(H, g)
        R = Rotation.from_rotvec(step).as_matrix() @ R
        if np.linalg.norm(step) < 1e-10:
            break
    return R


def rotation_angles(R: np.ndarray) -> np.ndarray:
    yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX", degrees=True)
    return np.array([roll, pitch, yaw])


def _estimate(a, b, normals, ups, free_vel, use_road):
    R = fit_rotation(a, b, free_vel)
    if use_road.any() and len(normals):
        # the road fixes what velocity cannot: a rotation about the remaining axes, applied
        # after the velocity fit (velocity axes untouched)
        R_road = fit_rotation(normals @ R.T, ups, use_road)
        R = R_road @ R
    return R


def _bootstrap(a, b, normals, ups, free_vel, use_road, n: int, seed: int) -> np.ndarray:
    """Standard deviation [deg] of (roll, pitch, yaw) over ``n`` resamples of the frames."""
    if n < 2:
        return np.full(3, np.nan)
    rng = np.random.default_rng(seed)
    samples = []
    for _ in range(n):
        i = rng.integers(0, len(a), len(a))
        j = rng.integers(0, len(normals), len(normals)) if len(normals) else np.arange(0)
        R = _estimate(a[i], b[i], normals[j], ups[j], free_vel, use_road)
        samples.append(rotation_angles(R))
    return np.std(samples, axis=0)


def calibrate_sequence(sequence: Sequence, min_speed_mps: float = 2.0,
                       min_spread: float = 0.05, max_std_deg: float = 1.0,
                       bootstrap: int = 200, seed: int = 0) -> CalibrationResult:
    """Fit R_gt_sensor for ``sequence`` (see the module docstring). An axis is observable from
    velocity when the directions spread around it by ``min_spread`` RMS [-] and its bootstrap
    standard deviation stays below ``max_std_deg``."""
    name = getattr(sequence, "path", sequence.name)
    if sequence.ground_truth is None:
        raise DataError(f"{name}: calibration needs ground truth; this store has none")
    stamps = sequence.stamps
    v_gt, up_gt = gt_velocity_directions(sequence.ground_truth, stamps)
    thr = 0.2 if sequence.sensor.kind == "radar" else 0.1
    a, b, normals, ups, heights = [], [], [], [], []
    for i, scan in enumerate(sequence):
        if scan.doppler is None:
            raise DataError(f"{scan.source or name}: calibration needs Doppler")
        if not np.isfinite(v_gt[i]).all():
            continue
        ego = estimate_ego_velocity(scan.points, scan.doppler, threshold_mps=thr)
        if ego.observable and ego.speed_mps > min_speed_mps and \
                np.linalg.norm(v_gt[i]) > min_speed_mps:
            a.append(ego.velocity / ego.speed_mps)
            b.append(v_gt[i] / np.linalg.norm(v_gt[i]))
        road = road_normal(scan.select(ego.inliers) if ego.observable else scan, seed=i)
        if road is not None:
            normals.append(road[0])
            ups.append(up_gt[i])
            heights.append(road[1])
    if len(a) < 5:
        raise DataError(f"{name}: only {len(a)} frames faster than {min_speed_mps} m/s with "
                        "an observable ego velocity; calibration needs at least 5")
    a, b = np.array(a), np.array(b)
    normals, ups = np.array(normals).reshape(-1, 3), np.array(ups).reshape(-1, 3)
    # outlier frames: refit without directions more than 3 robust sigmas off
    R0 = fit_rotation(a, b, np.ones(3, bool))
    err = np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", a @ R0.T, b), -1, 1)))
    keep = err <= max(3 * 1.4826 * np.median(err), 0.05)
    a, b = a[keep], b[keep]
    # observability of each axis from velocity: RMS spread of the directions around it
    spread = np.sqrt(np.mean(1.0 - (a @ AXES.T) ** 2, axis=0))
    free_vel = spread >= min_spread
    # road normals are near z: they observe rotations about x and y (roll, pitch)
    road_ok = len(normals) >= 5
    use_road = np.array([road_ok, False, False]) & ~free_vel
    R = _estimate(a, b, normals, ups, free_vel, use_road)

    std = _bootstrap(a, b, normals, ups, free_vel, use_road, bootstrap, seed)
    # an axis the velocity spread seemed to fix but the bootstrap says it did not: give it up
    weak = free_vel & (std > max_std_deg)
    if weak.any():
        free_vel &= ~weak
        use_road = np.array([road_ok, False, False]) & ~free_vel
        R = _estimate(a, b, normals, ups, free_vel, use_road)
        std = _bootstrap(a, b, normals, ups, free_vel, use_road, bootstrap, seed)
    angles = rotation_angles(R)
    source = {ax: ("velocity" if free_vel[k] else "road plane" if use_road[k]
                   else "not observable") for k, ax in enumerate(ANGLES)}
    road = {}
    if len(normals):
        n_s = normals.mean(axis=0)
        n_s /= np.linalg.norm(n_s)
        u_g = ups.mean(axis=0)
        u_g /= np.linalg.norm(u_g)
        road = {"frames": float(len(normals)), "height_m": float(np.median(heights)),
                "road_pitch_in_sensor_deg": float(np.degrees(np.arctan2(-n_s[0], n_s[2]))),
                "road_roll_in_sensor_deg": float(np.degrees(np.arctan2(n_s[1], n_s[2]))),
                "up_pitch_in_gt_deg": float(np.degrees(np.arctan2(-u_g[0], u_g[2]))),
                "up_roll_in_gt_deg": float(np.degrees(np.arctan2(u_g[1], u_g[2])))}
    return CalibrationResult(R, dict(zip(ANGLES, map(float, angles), strict=True)),
                             dict(zip(ANGLES, map(float, std), strict=True)), source,
                             int(len(a)), road)


class CorrectedSequence(Sequence):
    """``base`` with its ground truth moved to the sensor frame by ``R_gt_sensor``: points,
    Doppler and stamps unchanged; GT ``T_world_gt @ R_gt_sensor``; extrinsic likewise. The
    provenance records the rotation, the frames it was estimated on (``frames``: [first,
    stop), which runs on the corrected store do not score) and ``details`` (both estimates)."""

    def __init__(self, base: Sequence, R_gt_sensor: np.ndarray,
                 frames: tuple[int, int] | None = None, details: dict | None = None) -> None:
        self.base = base
        T_fix = np.eye(4)
        T_fix[:3, :3] = R_gt_sensor
        self.name = base.name
        s = base.sensor
        self.sensor = SensorInfo(s.kind, s.period_s, s.T_body_sensor @ T_fix, s.model,
                                 s.doppler_kind)
        gt = base.ground_truth
        self.ground_truth = None if gt is None else gt.transformed(T_right=T_fix)
        angles = rotation_angles(R_gt_sensor)
        self.provenance = {**base.provenance, "calibration": {
            "R_gt_sensor": R_gt_sensor.tolist(),
            "roll_pitch_yaw_deg": [float(x) for x in angles],
            "applied_to": "ground truth and T_body_sensor (points unchanged)",
            "frames": None if frames is None else [int(frames[0]), int(frames[1])],
            **(details or {})}}

    def __len__(self) -> int:
        return len(self.base)

    def scan(self, index: int) -> Scan:
        return self.base.scan(index)

    @property
    def stamps(self) -> np.ndarray:
        return self.base.stamps


def rotation_check(sequence: Sequence, limit_deg: float = 0.5) -> tuple[CalibrationResult | None,
                                                                        str | None]:
    """For ``bench inspect``: the calibration (None when it cannot be made: no GT, no Doppler,
    too slow) and a one-line warning when the sensor-to-GT rotation looks off by more than
    ``limit_deg`` (an observable angle beyond the limit and beyond 3 of its sigmas)."""
    try:
        cal = calibrate_sequence(sequence, bootstrap=50)
    except DataError:
        return None, None
    off = [f"{ax} {cal.angles_deg[ax]:+.2f} deg (+-{cal.std_deg[ax]:.2f}, {cal.source[ax]})"
           for ax in ANGLES if cal.source[ax] != "not observable"
           and abs(cal.angles_deg[ax]) > max(limit_deg, 3 * cal.std_deg[ax])]
    if not off:
        return cal, None
    return cal, ("the ground truth's frame looks rotated against the sensor frame (Doppler "
                 f"ego velocity vs GT velocity): {', '.join(off)}; see `bench calibrate`")
