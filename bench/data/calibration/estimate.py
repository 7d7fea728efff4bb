"""Is the ground truth's frame the sensor's frame? The rotation between them from the Doppler
ego velocity (the estimator behind ``bench calibrate`` and ``bench inspect``'s check).

The Doppler ego velocity (methods/ego_velocity.py) is the sensor's velocity in the sensor frame;
the ground truth gives the same velocity in the GT frame (central differences of the GT
positions, rotated into the GT frame). Over the frames with enough speed, the rotation
``R_gt_sensor`` that maps the one set of directions onto the other is fitted (least squares on
unit vectors, Newton steps on the Euler angles themselves; outlier frames, more than 3 robust
sigmas off a free Kabsch fit, dropped).

Observability: a car moves forward, so velocity directions fix pitch and yaw of the mount but
hardly roll (rotation about the direction of travel). The information of each rotation axis is
the spread of the directions around it; an axis whose RMS spread is below ``min_spread`` is
not observable from velocity. Roll then comes from the road plane: per frame a plane fitted to
the points below the sensor gives the road normal in the sensor frame, paired with the world's
up direction in the GT frame (the road is level on average). Each cue fits only its own
angles, holding the other's (the two sets of equations solved together). Both are reported,
with which angles came from which cue and which remained unobservable.

Angles: ``R_gt_sensor = Rz(yaw) Ry(pitch) Rx(roll)`` [deg]. Uncertainty: a circular block
bootstrap of the frames (``bench.data.calibration.bootstrap``): the velocity pairs and road normals
of the drawn frames, the outlier cut and both fits redone on each resample; the block length
from the autocorrelation of the per-frame residuals of every fitted angle (at least 3 frames,
the span of the GT's central difference); 95 % t intervals (degrees of freedom from the number
of blocks) and standard deviations.
The road-plane check reports the sensor's height above the
road and the road normal's tilt in the sensor frame and in the GT frame.

A corrected store keeps the points exactly as measured and corrects the ground truth:
``T_world_sensor := T_world_gt @ R_gt_sensor`` and ``T_body_sensor := T_body_sensor @
R_gt_sensor`` (methods see the same data; the scores then refer to the sensor's own frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from bench.data.calibration.bootstrap import (
    LEVEL,
    AngleSpread,
    BlockChoice,
    bootstrap_angles,
    choose_block,
    residual_series,
)
from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory
from methods.ego_velocity import estimate_ego_velocity

ANGLES = ("roll", "pitch", "yaw")
AXES = np.eye(3)  # roll about x, pitch about y, yaw about z


@dataclass
class CalibrationResult:
    """R_gt_sensor (3x3) and its angles [deg]; ``std_deg`` the bootstrap standard deviation and
    ``interval_deg`` the ``level`` t interval of each angle [deg] (NaN for an angle not
    observable; ``block``: how the ``frames_total`` frames were resampled, ``resamples`` how
    many were fitted); source per angle
    ("velocity", "road plane" or "not observable") and, for the angles not observable, why
    (``reasons``); velocity frames kept after the outlier cut; road-plane check values."""

    R_gt_sensor: np.ndarray
    angles_deg: dict[str, float]
    std_deg: dict[str, float]
    source: dict[str, str]
    frames_used: int
    road: dict[str, float] = field(default_factory=dict)
    interval_deg: dict[str, tuple[float, float]] = field(default_factory=dict)
    level: float = LEVEL
    block: BlockChoice | None = None
    resamples: int = 0
    frames_total: int = 0
    reasons: dict[str, str] = field(default_factory=dict)

    @property
    def fitted(self) -> list[str]:
        """The angles fitted, in order (``block.correlation`` follows it)."""
        return [a for a in ANGLES if self.source[a] != "not observable"]

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


def _exp_so3(w: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation matrix of rotation vector ``w`` [rad]."""
    theta = float(np.linalg.norm(w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if theta < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(theta) / theta * K + (1 - np.cos(theta)) / theta**2 * K @ K


def fit_rotation_sums(S_aa: np.ndarray, S_ab: np.ndarray, free: np.ndarray) -> np.ndarray:
    """``fit_rotation`` from the pairs' sums ``S_aa = sum a a^T`` and ``S_ab = sum a b^T``
    (3x3): the cost ``sum |b - R a|^2`` and its Gauss-Newton steps depend on the pairs only
    through them. With ``u = R a``: the Jacobian of ``exp(th) u`` is ``axis_k x u``, so
    ``J^T J = tr(U) I - U`` (``U = R S_aa R^T``) and ``J^T (b - u) = sum u x b``, the axial
    vector of ``M = R S_ab``."""
    R = np.eye(3)
    for _ in range(20):
        U = R @ S_aa @ R.T
        M = R @ S_ab
        H = (np.trace(U) * np.eye(3) - U)[np.ix_(free, free)]
        step = np.zeros(3)
        step[free] = np.linalg.solve(H, _axial(M)[free])
        R = _exp_so3(step) @ R
        if np.linalg.norm(step) < 1e-10:
            break
    return R


def _axial(M: np.ndarray) -> np.ndarray:
    """The axial vector of M's antisymmetric part, times 2: ``sum u x b`` for ``M = sum u
    b^T``."""
    return np.array([M[1, 2] - M[2, 1], M[2, 0] - M[0, 2], M[0, 1] - M[1, 0]])


def euler_matrix(angles_rad: np.ndarray) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` of (roll, pitch, yaw) [rad]."""
    cr, cp, cy = np.cos(angles_rad)
    sr, sp, sy = np.sin(angles_rad)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def fit_angles(cues: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """(roll, pitch, yaw) [rad] where each cue ``(S_ab, free)`` is at its best for its own
    ``free`` angles (disjoint masks; angles in no mask stay 0): ``tr(R S_ab)`` stationary in
    them, i.e. ``sum |b - R a|^2`` least for ``S_ab = sum a b^T`` with the other cues' angles
    held. Newton steps on these equations together: a change of the angles turns R (on the
    left) about the columns of ``W = [Rz Ry e_x, Rz e_y, e_z]``; the gradient of ``tr(exp(th)
    M)`` (``M = R S_ab``) is ``axial(M)`` and its Hessian ``sym(M) - tr(M) I``, pulled back
    through W. Newton starts from ``start_angles`` (from zero it finds angles up to some
    45 deg only)."""
    ang = start_angles(cues)
    for _ in range(30):
        R = euler_matrix(ang)
        cy, sy, cp, sp = np.cos(ang[2]), np.sin(ang[2]), np.cos(ang[1]), np.sin(ang[1])
        W = np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
        H, g = np.eye(3), np.zeros(3)
        for S_ab, free in cues:
            M = R @ S_ab
            sym = 0.5 * (M + M.T)
            H[free] = (W.T @ ((sym[0, 0] + sym[1, 1] + sym[2, 2]) * np.eye(3) - sym) @ W)[free]
            g[free] = (W.T @ _axial(M))[free]
        step = np.linalg.solve(H, g)
        ang += step
        if np.abs(step).max() < 1e-12:
            break
    return ang


def start_angles(cues: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Where ``fit_angles`` starts: the (roll, pitch, yaw) [rad] of the rotation with all three
    axes free that best fits every cue's pairs together (``kabsch`` on the summed ``S_ab``),
    the angles in no cue's mask 0."""
    R = kabsch_sums(sum(S_ab for S_ab, _ in cues))
    free = np.any([np.asarray(m, dtype=bool) for _, m in cues], axis=0)
    return np.where(free, np.radians(rotation_angles(R)), 0.0)


def fit_rotation(a: np.ndarray, b: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Rotation R minimising sum |b - R a|^2 over unit-vector pairs, updating only the rotation
    axes (columns of AXES) flagged in ``free`` (Gauss-Newton on a rotation vector, left
    updates ``R := exp(th) R`` from the identity; see ``fit_rotation_sums``)."""
    return fit_rotation_sums(a.T @ a, a.T @ b, np.asarray(free, dtype=bool))


def rotation_angles(R: np.ndarray) -> np.ndarray:
    yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX", degrees=True)
    return np.array([roll, pitch, yaw])


@dataclass
class FrameCues:
    """What each frame of a sequence says about ``R_gt_sensor``: Doppler (sensor frame) and GT
    (GT frame) unit velocity directions of the frames fast enough (``vel_frame``: their frame
    indices), road normals (sensor frame) and world up (GT frame) of the frames with a road
    plane (``road_frame``), the sensor's height above the road [m]; ``n_frames`` frames of
    ``period_s`` [s]."""

    n_frames: int
    period_s: float
    vel_frame: np.ndarray
    a: np.ndarray
    b: np.ndarray
    road_frame: np.ndarray
    normals: np.ndarray
    ups: np.ndarray
    heights: np.ndarray

    def rows(self, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and road rows of the drawn ``frames`` (repeats kept)."""
        vel = np.full(self.n_frames, -1)
        vel[self.vel_frame] = np.arange(len(self.vel_frame))
        road = np.full(self.n_frames, -1)
        road[self.road_frame] = np.arange(len(self.road_frame))
        v, r = vel[frames], road[frames]
        return v[v >= 0], r[r >= 0]

    def piece(self, first: int, stop: int) -> FrameCues:
        """The cues of frames ``first`` .. ``stop - 1`` alone, renumbered from 0."""
        v = (self.vel_frame >= first) & (self.vel_frame < stop)
        r = (self.road_frame >= first) & (self.road_frame < stop)
        return FrameCues(stop - first, self.period_s, self.vel_frame[v] - first, self.a[v],
                         self.b[v], self.road_frame[r] - first, self.normals[r], self.ups[r],
                         self.heights[r])


def collect_cues(sequence: Sequence, min_speed_mps: float = 2.0,
                 name: str | None = None) -> FrameCues:
    """The per-frame cues of ``sequence`` (see FrameCues); DataError without GT or Doppler,
    when no scan (or fewer than 3) has ground truth, or when fewer than 5 frames are faster
    than ``min_speed_mps`` with an observable ego velocity. ``name``: how messages call the
    sequence (default its path or name)."""
    name = name or getattr(sequence, "path", sequence.name)
    if sequence.ground_truth is None:
        raise DataError(f"{name}: calibration needs ground truth; this store has none")
    stamps = sequence.stamps
    gt = sequence.ground_truth
    covered = int(gt.coverage_mask(stamps).sum()) if len(stamps) else 0
    if covered < 3:
        span = (f"its ground truth spans {gt.stamps[0]:.3f}-{gt.stamps[-1]:.3f} s"
                if len(gt.stamps) else "its ground truth has no poses here")
        what = "no scan has" if covered == 0 else f"only {covered} scan(s) have"
        scans = (f"the {len(stamps)} scans {stamps[0]:.3f}-{stamps[-1]:.3f} s" if len(stamps)
                 else "no scans")
        raise DataError(f"{name}: {what} ground truth ({span}, {scans}); calibration needs the GT "
                        "velocity at 3 or more scans: check the GT's clock (`bench inspect` "
                        "shows its coverage)")
    v_gt, up_gt = gt_velocity_directions(gt, stamps)
    thr = 0.2 if sequence.sensor.kind == "radar" else 0.1
    vel_frame, a, b, road_frame, normals, ups, heights = [], [], [], [], [], [], []
    for i, scan in enumerate(sequence):
        if scan.doppler is None:
            raise DataError(f"{scan.source or name}: frame {i}: calibration needs Doppler")
        if not np.isfinite(v_gt[i]).all():
            continue
        ego = estimate_ego_velocity(scan.points, scan.doppler, threshold_mps=thr)
        if ego.observable and ego.speed_mps > min_speed_mps and \
                np.linalg.norm(v_gt[i]) > min_speed_mps:
            vel_frame.append(i)
            a.append(ego.velocity / ego.speed_mps)
            b.append(v_gt[i] / np.linalg.norm(v_gt[i]))
        road = road_normal(scan.select(ego.inliers) if ego.observable else scan, seed=i)
        if road is not None:
            road_frame.append(i)
            normals.append(road[0])
            ups.append(up_gt[i])
            heights.append(road[1])
    if len(a) < 5:
        raise DataError(f"{name}: only {len(a)} frames faster than {min_speed_mps} m/s "
                        "with an observable ego velocity; calibration needs at least 5")
    return FrameCues(len(stamps), float(sequence.sensor.period_s),
                     np.array(vel_frame, dtype=int), np.array(a).reshape(-1, 3),
                     np.array(b).reshape(-1, 3), np.array(road_frame, dtype=int),
                     np.array(normals).reshape(-1, 3), np.array(ups).reshape(-1, 3),
                     np.array(heights))


def kabsch(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation R minimising sum |b - R a|^2 (all three axes free; SVD, no reflection)."""
    return kabsch_sums(a.T @ b)


def kabsch_sums(S_ab: np.ndarray) -> np.ndarray:
    """``kabsch`` from the pairs' sum ``S_ab = sum a b^T`` alone."""
    u, _, vt = np.linalg.svd(S_ab.T)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    return u @ np.diag([1.0, 1.0, d]) @ vt


def outlier_cut(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mask of the direction pairs within 3 robust sigmas (1.4826 x median, at least 0.05 deg
    overall) of a free fit to all of them."""
    R0 = kabsch(a, b)
    err = np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", a @ R0.T, b), -1, 1)))
    return err <= max(3 * 1.4826 * np.median(err), 0.05)


def _estimate(a, b, normals, ups, free_vel, use_road):
    """Outlier cut of the velocity pairs, then the angles: the ``free_vel`` ones from the
    velocity directions, the ``use_road`` ones from the road normals, each fit holding the
    other's angles (solved together; the angles not fitted stay 0). Fitting the
    reported angles themselves matters: a road rotation composed after the velocity fit would
    turn the velocity's own angles by the product of roll and the velocity's tilt (0.25 deg of
    yaw on the real sample's second half)."""
    keep = outlier_cut(a, b)
    cues = [(a[keep].T @ b[keep], free_vel)]
    if use_road.any() and len(normals):
        cues.append((normals.T @ ups, use_road))
    ang = fit_angles(cues)
    return euler_matrix(ang)


def _angle_series(cues: FrameCues, R: np.ndarray, free_vel: np.ndarray,
                  use_road: np.ndarray) -> dict[int, np.ndarray]:
    """Per fitted angle (by index), the per-frame residual series of the cue that fits it
    (velocity pairs kept by the outlier cut, or road normals), in frame order."""
    keep = outlier_cut(cues.a, cues.b)
    out = {}
    for k in range(3):
        only = AXES[k].astype(bool)
        if free_vel[k]:
            (out[k],) = residual_series(cues.a[keep] @ R.T, cues.b[keep], only,
                                        cues.vel_frame[keep])
        elif use_road[k] and len(cues.normals):
            (out[k],) = residual_series(cues.normals @ R.T, cues.ups, only, cues.road_frame)
    return out


def _bootstrap(cues: FrameCues, free_vel, use_road, reps: int, seed: int, level: float,
               block_frames: int | None = None) -> tuple[BlockChoice, AngleSpread]:
    """Block choice and angle spread of the whole estimate (outlier cut included) over circular
    block resamples of the frames. One block for all angles, from the residual series of every
    fitted angle (``block.correlation``: their correlation lengths in angle order; at least 3
    frames, the span of the GT's central difference) unless ``block_frames`` is given. A block
    per angle, each from its own series, was tried: shorter blocks for pitch and yaw (pitch
    +-0.31 instead of +-0.53 deg on the real sample's 250 frames), but `bench
    calibrate-coverage --seeds 12 --bootstrap 100` covered 29 of 36 angles instead of 31."""
    R = _estimate(cues.a, cues.b, cues.normals, cues.ups, free_vel, use_road)
    series = list(_angle_series(cues, R, free_vel, use_road).values())
    block = choose_block(cues.n_frames, cues.period_s, series, floor_frames=3)
    if block_frames is not None:
        block = BlockChoice(int(block_frames), block_frames * cues.period_s, int(block_frames),
                            block.correlation)

    def fit(frames: np.ndarray) -> np.ndarray | None:
        v, r = cues.rows(frames)
        if len(v) < 5:
            return None
        return rotation_angles(_estimate(cues.a[v], cues.b[v], cues.normals[r], cues.ups[r],
                                         free_vel, use_road))

    return block, bootstrap_angles(cues.n_frames, block, reps, seed, fit, rotation_angles(R),
                                   level)


def _reasons(spread: np.ndarray, min_spread: float, road_frames: int, free_vel: np.ndarray,
             use_road: np.ndarray) -> dict[str, str]:
    """Why each angle fitted by neither cue is not observable."""
    out = {}
    for k, ax in enumerate(ANGLES):
        if free_vel[k] or use_road[k]:
            continue
        why = (f"the velocity directions hardly turn about the sensor's {'xyz'[k]} axis (RMS "
               f"spread {spread[k]:.3f}, below {min_spread:g})")
        if k == 0:  # roll's other cue
            why += f", and the road plane was found in only {road_frames} frames (5 needed)"
        out[ax] = why
    return out


def calibrate_cues(cues: FrameCues, min_spread: float = 0.05, max_std_deg: float = 1.0,
                   bootstrap: int = 200, seed: int = 0, level: float = LEVEL,
                   name: str = "sequence", block_frames: int | None = None
                   ) -> CalibrationResult:
    """Fit R_gt_sensor to per-frame cues (see the module docstring). An axis is observable from
    velocity when the directions spread around it by ``min_spread`` RMS [-]; roll is taken from
    the road plane instead when the velocity does not fix it, or fixes it with a bootstrap
    standard deviation above ``max_std_deg`` while a road plane is there. An angle the velocity
    fixes only loosely is kept with its (wide) interval, never dropped: dropping it printed an
    exact 0 with a zero-width interval. ``block_frames`` overrides the bootstrap's block
    length (for studies of the rule)."""
    if len(cues.a) < 5:
        raise DataError(f"{name}: only {len(cues.a)} frames fast enough with an observable "
                        "ego velocity; calibration needs at least 5")
    kept = cues.a[outlier_cut(cues.a, cues.b)]
    # observability of each axis from velocity: RMS spread of the directions around it
    spread = np.sqrt(np.mean(1.0 - (kept @ AXES.T) ** 2, axis=0))
    free_vel = spread >= min_spread
    # road normals are near z: they observe rotations about x and y (roll, pitch); they fit
    # roll here, the angle a forward-driving car's velocity hardly sees
    road_ok = len(cues.normals) >= 5
    use_road = np.array([road_ok, False, False]) & ~free_vel
    block, spread_deg = _bootstrap(cues, free_vel, use_road, bootstrap, seed, level,
                                   block_frames)
    if road_ok and free_vel[0] and not spread_deg.sd_deg[0] <= max_std_deg:
        # the velocity seemed to fix roll, but loosely: the road plane is the better cue
        free_vel[0], use_road[0] = False, True
        block, spread_deg = _bootstrap(cues, free_vel, use_road, bootstrap, seed, level,
                                       block_frames)
    R = _estimate(cues.a, cues.b, cues.normals, cues.ups, free_vel, use_road)
    angles = rotation_angles(R)
    source = {ax: ("velocity" if free_vel[k] else "road plane" if use_road[k]
                   else "not observable") for k, ax in enumerate(ANGLES)}
    road = {}
    normals, ups = cues.normals, cues.ups
    if len(normals):
        n_s = normals.mean(axis=0)
        n_s /= np.linalg.norm(n_s)
        u_g = ups.mean(axis=0)
        u_g /= np.linalg.norm(u_g)
        road = {"frames": float(len(normals)), "height_m": float(np.median(cues.heights)),
                "road_pitch_in_sensor_deg": float(np.degrees(np.arctan2(-n_s[0], n_s[2]))),
                "road_roll_in_sensor_deg": float(np.degrees(np.arctan2(n_s[1], n_s[2]))),
                "up_pitch_in_gt_deg": float(np.degrees(np.arctan2(-u_g[0], u_g[2]))),
                "up_roll_in_gt_deg": float(np.degrees(np.arctan2(u_g[1], u_g[2])))}
    # an angle held at 0 has no spread to report (its resamples all give 0)
    unseen = ~(free_vel | use_road)
    sd, low, high = (np.where(unseen, np.nan, x) for x in
                     (spread_deg.sd_deg, spread_deg.low_deg, spread_deg.high_deg))
    per_angle = lambda x: dict(zip(ANGLES, map(float, x), strict=True))  # noqa: E731
    return CalibrationResult(
        R, per_angle(angles), per_angle(sd), source, int(outlier_cut(cues.a, cues.b).sum()),
        road, {ax: (float(low[k]), float(high[k])) for k, ax in enumerate(ANGLES)}, level,
        block, spread_deg.resamples, cues.n_frames,
        _reasons(spread, min_spread, len(cues.normals), free_vel, use_road))


def calibrate_sequence(sequence: Sequence, min_speed_mps: float = 2.0,
                       min_spread: float = 0.05, max_std_deg: float = 1.0,
                       bootstrap: int = 200, seed: int = 0,
                       level: float = LEVEL) -> CalibrationResult:
    """Fit R_gt_sensor for ``sequence`` (see the module docstring and ``calibrate_cues``)."""
    name = str(getattr(sequence, "path", sequence.name))
    cues = collect_cues(sequence, min_speed_mps, name)
    return calibrate_cues(cues, min_spread, max_std_deg, bootstrap, seed, level, name)


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


def rotation_consistent_text(cal: CalibrationResult, limit_deg: float = 0.5) -> str:
    """What ``bench inspect`` says when no angle is off: consistent within ``limit_deg`` only
    for the angles known that well (3 sd within it); the others are named with their sd, or
    as not observable."""
    loose = [f"{ax} +-{cal.std_deg[ax]:.2f} deg (sd)" for ax in ANGLES
             if cal.source[ax] != "not observable" and 3 * cal.std_deg[ax] > limit_deg]
    unseen = [ax for ax in ANGLES if cal.source[ax] == "not observable"]
    tight = [ax for ax in ANGLES if ax not in unseen
             and not 3 * cal.std_deg[ax] > limit_deg]
    text = "sensor-to-GT rotation (Doppler ego velocity vs GT velocity): "
    text += (f"{', '.join(tight)} consistent within {limit_deg:g} deg" if tight
             else f"no angle fixed to {limit_deg:g} deg")
    if loose:
        text += f"; known only loosely, none found off: {', '.join(loose)}"
    if unseen:
        text += f"; not observable: {', '.join(unseen)}"
    return text + ("; see `bench calibrate`" if loose or unseen else "")


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
