"""Ego-velocity error: the velocity a trajectory implies, in the sensor frame, against the GT's.

Per scored frame i the velocity over a window is ``v_i = R_i^T (t_j - t_i) / (s_j - s_i)``
(``T_world_sensor`` poses ``(R_i, t_i)`` at stamps ``s_i`` [s]): the relative translation from
frame i to frame j, expressed in the sensor frame at i, over the time between them [m/s], where
j is the first frame with ``s_j - s_i >= window_s`` (``window_s = 0``: the next frame, a
frame-to-frame velocity). The estimate and the GT use the same pairs (i, j).

Why a window: a GT sampled at its own rate and nearest-matched to the scans (NTU4DRadLM: 10 Hz
poses at 12 Hz scans, one GT row in six repeated) gives frame-to-frame GT velocities that are
mostly artefact (a repeated row is a zero velocity, the next step a double one): each GT pose is
the pose of a time up to half a GT period (0.05 s) off its scan's stamp, so a velocity over a
window W is off by up to speed x 0.1 s / W. The default ``DEFAULT_WINDOW_S`` = 1 s (ten GT
rows) bounds that at 10 % of the speed (on the NTU sample, ``doppler``'s mean error is 2.16 m/s
frame to frame, 1.19 over 0.25 s, 0.53 over 0.5 s, 0.38 over 1 s). The window is stated in
every table that shows the error.

Statistics: per axis x, y, z of the sensor frame the mean absolute error and the RMSE [m/s];
for the error vector's norm its mean and RMSE [m/s]; the number of windows ``n``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from metrics.relative import MetricError, check_pose_pair

#: default window [s] of the reference velocity
DEFAULT_WINDOW_S = 1.0
AXES = ("x", "y", "z")


@dataclass(frozen=True)
class VelocitySeries:
    """Per window: start / end frame index, start stamp [s], estimated and GT velocity
    (M, 3) [m/s] in the sensor frame at the start."""

    start_idx: np.ndarray
    end_idx: np.ndarray
    stamps: np.ndarray
    est_mps: np.ndarray
    gt_mps: np.ndarray

    @property
    def error_mps(self) -> np.ndarray:
        return self.est_mps - self.gt_mps


@dataclass(frozen=True)
class VelocityErrorStats:
    """Mean absolute and RMS error per axis (x, y, z) [m/s], mean and RMS of the error norm
    [m/s], windows ``n``, the window [s]; NaN statistics when n = 0 or the estimate is not
    finite."""

    axis_mean_mps: tuple[float, float, float]
    axis_rmse_mps: tuple[float, float, float]
    norm_mean_mps: float
    norm_rmse_mps: float
    n: int
    window_s: float


def window_pairs(stamps: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(i, j): for every frame i the first frame j > i with ``s_j - s_i >= window_s``."""
    s = np.asarray(stamps, dtype=np.float64)
    if not np.all(np.diff(s) > 0):
        raise MetricError("stamps must be strictly increasing for a velocity")
    i = np.arange(len(s))
    j = np.maximum(np.searchsorted(s, s + window_s - 1e-9, side="left"), i + 1)
    ok = j < len(s)
    return i[ok], j[ok]


def body_velocities(poses: np.ndarray, stamps: np.ndarray, i: np.ndarray, j: np.ndarray
                    ) -> np.ndarray:
    """``R_i^T (t_j - t_i) / (s_j - s_i)`` per pair [m/s] (the sensor frame at i)."""
    p = np.asarray(poses, dtype=np.float64)
    s = np.asarray(stamps, dtype=np.float64)
    d = p[j, :3, 3] - p[i, :3, 3]
    with np.errstate(invalid="ignore", over="ignore"):
        return np.einsum("kji,kj->ki", p[i, :3, :3], d) / (s[j] - s[i])[:, None]


def velocity_series(gt_poses: np.ndarray, est_poses: np.ndarray, stamps: np.ndarray,
                    window_s: float = DEFAULT_WINDOW_S) -> VelocitySeries:
    """Estimated and GT velocity over the same windows (see the module docstring)."""
    gt, est = check_pose_pair(gt_poses, est_poses)
    if len(stamps) != len(gt):
        raise MetricError(f"{len(stamps)} stamps for {len(gt)} poses")
    if not (np.isfinite(window_s) and window_s >= 0):
        raise MetricError(f"velocity window must be >= 0 s, got {window_s}")
    i, j = window_pairs(stamps, window_s)
    return VelocitySeries(i, j, np.asarray(stamps, float)[i], body_velocities(est, stamps, i, j),
                          body_velocities(gt, stamps, i, j))


def velocity_stats(series: VelocitySeries, window_s: float) -> VelocityErrorStats:
    """Summary of a ``VelocitySeries`` (NaN when empty or not finite)."""
    err = series.error_mps
    n = len(err)
    if n == 0 or not np.all(np.isfinite(err)):
        nan3 = (float("nan"),) * 3
        return VelocityErrorStats(nan3, nan3, float("nan"), float("nan"), n, float(window_s))
    norm = np.linalg.norm(err, axis=1)
    return VelocityErrorStats(
        tuple(float(x) for x in np.mean(np.abs(err), axis=0)),
        tuple(float(x) for x in np.sqrt(np.mean(err**2, axis=0))),
        float(np.mean(norm)), float(np.sqrt(np.mean(norm**2))), n, float(window_s))


def velocity_errors(gt_poses: np.ndarray, est_poses: np.ndarray, stamps: np.ndarray,
                    window_s: float = DEFAULT_WINDOW_S) -> VelocityErrorStats:
    """Ego-velocity error statistics of a trajectory (see the module docstring)."""
    return velocity_stats(velocity_series(gt_poses, est_poses, stamps, window_s), window_s)


def own_velocity_errors(gt_poses: np.ndarray, stamps: np.ndarray, est_mps: np.ndarray,
                        window_s: float = DEFAULT_WINDOW_S) -> VelocityErrorStats:
    """Error statistics of a method's own velocity estimate (:func:`own_velocity_series`)."""
    return velocity_stats(own_velocity_series(gt_poses, stamps, est_mps, window_s), window_s)


def own_velocity_series(gt_poses: np.ndarray, stamps: np.ndarray, est_mps: np.ndarray,
                        window_s: float = DEFAULT_WINDOW_S) -> VelocitySeries:
    """Error of a method's own per-frame velocity estimate ``est_mps`` (N, 3) [m/s, sensor
    frame at the frame] (a Doppler ego velocity, an instantaneous measurement) against the GT
    velocity over a window centred on the frame: from the last frame at or before
    ``s_i - window_s / 2`` to the first at or after ``s_i + window_s / 2``, in the sensor frame
    at i. Frames whose estimate is NaN (not observable) or whose window leaves the sequence are
    left out."""
    gt, _ = check_pose_pair(gt_poses, gt_poses)
    s = np.asarray(stamps, dtype=np.float64)
    if len(s) != len(gt):
        raise MetricError(f"{len(s)} stamps for {len(gt)} poses")
    k = np.arange(len(s))
    if window_s == 0:  # the step to the next frame
        a, b = k, k + 1
    else:
        a = np.searchsorted(s, s - window_s / 2 + 1e-9, side="right") - 1
        b = np.searchsorted(s, s + window_s / 2 - 1e-9, side="left")
    est = np.asarray(est_mps, dtype=np.float64)
    keep = (a >= 0) & (b < len(s)) & (b > a) & np.all(np.isfinite(est), axis=1)
    k, a, b = k[keep], a[keep], b[keep]
    d = gt[b, :3, 3] - gt[a, :3, 3]
    gt_v = np.einsum("kji,kj->ki", gt[k, :3, :3], d) / (s[b] - s[a])[:, None]
    return VelocitySeries(k, b, s[k], est[k], gt_v)
