"""A Doppler-free estimate of the rotation between the sensor frame and the ground truth's
frame: hand-eye alignment of a geometric odometry's trajectory (KISS-ICP by default, which
uses no Doppler) against the ground truth over the same frames.

Over segments of about ``segment_s`` seconds, the ground truth moves by ``A = inv(G_k) G_m``
(GT frame) and the odometry by ``B = inv(P_k) P_m`` (sensor frame). With the sensor mounted at
``R_gt_sensor`` (lever arm ``t``), ``A R = R B`` up to the lever arm, so
- the displacement directions agree: ``t_A = R t_B + (I - R_A) t`` ~ ``R t_B`` (the lever-arm
  term is the segment's rotation times a few decimetres, against metres of travel);
- the rotation axes agree: ``axis(R_A) = R axis(R_B)``, for segments that turn by more than
  ``min_turn_deg``.
Displacement directions fix pitch and yaw of a forward-driving car, rotation axes (mostly the
vertical) fix roll and pitch; both sets of unit vectors are fitted together (Wahba on unit
vectors, ``bench.data.calibration.fit_rotation``), an axis whose vectors do not spread around
it is reported as not observable, and bootstrap resampling of the segments gives the spread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from bench.data.calibration import ANGLES, AXES, fit_rotation, rotation_angles
from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.scan import Sequence
from loaders.se3 import inv_T


@dataclass
class HandEyeResult:
    """R_gt_sensor from a geometric odometry: angles and bootstrap std [deg], per-angle
    observability, segments used."""

    R_gt_sensor: np.ndarray
    angles_deg: dict[str, float]
    std_deg: dict[str, float]
    observable: dict[str, bool]
    segments: int
    odometry: str


def segment_vectors(gt_poses: np.ndarray, est_poses: np.ndarray, step: int,
                    min_move_m: float = 1.0, min_turn_deg: float = 2.0
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors of the segments k -> k + step: (odometry vectors (n, 3) in the sensor frame,
    the matching GT vectors in the GT frame, weights): displacement directions of segments that
    move at least ``min_move_m`` and rotation axes of segments that turn at least
    ``min_turn_deg`` (weighted by the turn, so near-straight segments count little)."""
    src, dst, w = [], [], []
    for k in range(0, len(gt_poses) - step):
        A = inv_T(gt_poses[k]) @ gt_poses[k + step]
        B = inv_T(est_poses[k]) @ est_poses[k + step]
        tA, tB = A[:3, 3], B[:3, 3]
        if np.linalg.norm(tA) >= min_move_m and np.linalg.norm(tB) >= min_move_m:
            src.append(tB / np.linalg.norm(tB))
            dst.append(tA / np.linalg.norm(tA))
            w.append(1.0)
        rA = Rotation.from_matrix(A[:3, :3]).as_rotvec()
        rB = Rotation.from_matrix(B[:3, :3]).as_rotvec()
        turn = np.degrees(min(np.linalg.norm(rA), np.linalg.norm(rB)))
        if turn >= min_turn_deg:
            src.append(rB / np.linalg.norm(rB))
            dst.append(rA / np.linalg.norm(rA))
            w.append(min(turn / 10.0, 1.0))
    return np.array(src).reshape(-1, 3), np.array(dst).reshape(-1, 3), np.array(w)


def _weighted_fit(src: np.ndarray, dst: np.ndarray, w: np.ndarray, free: np.ndarray):
    # fit_rotation is unweighted: a weight scales both vectors of a pair (same residual ratio)
    s = np.sqrt(w)[:, None]
    return fit_rotation(src * s, dst * s, free)


def hand_eye_rotation(gt_poses: np.ndarray, est_poses: np.ndarray, period_s: float,
                      odometry: str = "kiss-icp", segment_s: float = 1.0,
                      min_spread: float = 0.05, bootstrap: int = 200,
                      seed: int = 0) -> HandEyeResult:
    """R_gt_sensor from paired GT (GT frame) and odometry (sensor frame) poses of the same
    frames (see the module docstring)."""
    step = max(1, int(round(segment_s / period_s)))
    src, dst, w = segment_vectors(gt_poses, est_poses, step)
    if len(src) < 5:
        raise DataError(f"hand-eye alignment: only {len(src)} usable segments of {segment_s} s "
                        "(the sensor must move at least 1 m per segment); use more frames")
    spread = np.sqrt(np.average(1.0 - (src @ AXES.T) ** 2, axis=0, weights=w))
    free = spread >= min_spread
    R = _weighted_fit(src, dst, w, free)
    rng = np.random.default_rng(seed)
    samples = []
    for _ in range(bootstrap):
        i = rng.integers(0, len(src), len(src))
        samples.append(rotation_angles(_weighted_fit(src[i], dst[i], w[i], free)))
    std = np.std(samples, axis=0) if samples else np.full(3, np.nan)
    angles = rotation_angles(R)
    return HandEyeResult(R, dict(zip(ANGLES, map(float, angles), strict=True)),
                         dict(zip(ANGLES, map(float, std), strict=True)),
                         dict(zip(ANGLES, map(bool, free), strict=True)), len(src), odometry)


def hand_eye_on(sequence: Sequence, odometry: str = "kiss-icp", **kwargs) -> HandEyeResult:
    """Run the (Doppler-free) ``odometry`` method over ``sequence`` and align it to its GT."""
    from methods.base import run_timed
    from methods.registry import make_method

    if sequence.ground_truth is None:
        raise DataError(f"{sequence.name}: hand-eye alignment needs ground truth")
    result = run_timed(make_method(odometry, {}, sequence.sensor), sequence, seed=True)
    gt, scored = gt_for_frames(sequence.ground_truth, result.stamps)
    return hand_eye_rotation(gt[scored], result.poses[scored], sequence.sensor.period_s,
                             odometry, **kwargs)
