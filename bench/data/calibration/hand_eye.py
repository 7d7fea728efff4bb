"""A Doppler-free estimate of the rotation between the sensor frame and the ground truth's
frame: hand-eye alignment of a geometric odometry's trajectory (KISS-ICP by default, which
uses no Doppler) against the ground truth over the same frames.

Over segments of about ``segment_s`` seconds, the ground truth moves by ``A = inv(G_k) G_m``
(GT frame) and the odometry by ``B = inv(P_k) P_m`` (sensor frame). With the sensor mounted at
``R_gt_sensor`` (lever arm ``t``), ``A R = R B`` up to the lever arm, so
- the rotation axes agree: ``axis(R_A) = R axis(R_B)``, for segments that turn by more than
  ``min_turn_deg`` (weighted by the turn). A geometric odometry observes its own turns well
  and a segment's axis does not depend on the odometry's translation drift;
- the displacement directions agree: ``t_A = R t_B + (I - R_A) t`` ~ ``R t_B``. These carry
  the odometry's translation drift: on a near-planar drive a slowly climbing or sinking
  odometry tilts every displacement by its drift angle (the 2.4-2.8 deg pitch disagreement a
  review measured on the real NTU frames, with a bootstrap spread of 0.04 deg).
So the rotation is fitted in two stages, most trusted first (Wahba on unit vectors,
``bench.data.calibration.estimate.fit_rotation``): the turn axes fix the rotations they observe
(roll
and pitch on a drive whose turns are about the vertical), then the displacement directions fix
only what the turns cannot (yaw). An axis that neither set of vectors spreads around is
reported as not observable. The uncertainty is a circular block bootstrap of the frames
(``bench.data.calibration.bootstrap``): a segment enters a resample as often as its start frame is
drawn, and both stages are refitted. The blocks are at least ``block_s`` seconds (default
10 s) and one segment long, and longer when the per-segment residuals are correlated for
longer, so the correlated errors of a drifting odometry widen the interval instead of averaging
out; at most half the frames (over a range shorter than twice ``block_s`` the block is capped,
and the output says so).
"""

from __future__ import annotations

import math
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
from bench.data.calibration.estimate import ANGLES, AXES, fit_rotation, rotation_angles
from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.scan import Sequence
from loaders.se3 import inv_T

TURN_AXES, DISPLACEMENTS = "turn axes", "displacement directions"
#: the shortest bootstrap block [s]: an odometry's drift is correlated for longer than the
#: residuals of a 125-frame range can show
HE_BLOCK_S = 10.0


@dataclass
class HandEyeResult:
    """R_gt_sensor from a geometric odometry: angles, block-bootstrap standard deviation and
    ``level`` t interval [deg], per-angle observability and which vectors fixed it,
    segments used, how the frames were resampled."""

    R_gt_sensor: np.ndarray
    angles_deg: dict[str, float]
    std_deg: dict[str, float]
    observable: dict[str, bool]
    segments: int
    odometry: str
    source: dict[str, str] = field(default_factory=dict)
    interval_deg: dict[str, tuple[float, float]] = field(default_factory=dict)
    level: float = LEVEL
    block: BlockChoice | None = None
    resamples: int = 0
    frames_total: int = 0


@dataclass
class SegmentVectors:
    """Unit vectors of segments k -> k + step: odometry (sensor frame) and GT (GT frame), the
    weight and the segment's start k of each; ``turn`` rows are rotation axes, the others
    displacement directions."""

    odometry: np.ndarray
    gt: np.ndarray
    weight: np.ndarray
    start: np.ndarray
    turn: np.ndarray

    def take(self, rows: np.ndarray) -> SegmentVectors:
        return SegmentVectors(self.odometry[rows], self.gt[rows], self.weight[rows],
                              self.start[rows], self.turn[rows])


def segment_vectors(gt_poses: np.ndarray, est_poses: np.ndarray, step: int,
                    min_move_m: float = 1.0, min_turn_deg: float = 2.0) -> SegmentVectors:
    """Displacement directions of the segments k -> k + step that move at least
    ``min_move_m`` and rotation axes of those that turn at least ``min_turn_deg`` (weighted
    by the turn, so near-straight segments count little)."""
    src, dst, w, start, turn = [], [], [], [], []
    for k in range(0, len(gt_poses) - step):
        A = inv_T(gt_poses[k]) @ gt_poses[k + step]
        B = inv_T(est_poses[k]) @ est_poses[k + step]
        tA, tB = A[:3, 3], B[:3, 3]
        if np.linalg.norm(tA) >= min_move_m and np.linalg.norm(tB) >= min_move_m:
            src.append(tB / np.linalg.norm(tB))
            dst.append(tA / np.linalg.norm(tA))
            w.append(1.0)
            start.append(k)
            turn.append(False)
        rA = Rotation.from_matrix(A[:3, :3]).as_rotvec()
        rB = Rotation.from_matrix(B[:3, :3]).as_rotvec()
        angle = np.degrees(min(np.linalg.norm(rA), np.linalg.norm(rB)))
        if angle >= min_turn_deg:
            src.append(rB / np.linalg.norm(rB))
            dst.append(rA / np.linalg.norm(rA))
            w.append(min(angle / 10.0, 1.0))
            start.append(k)
            turn.append(True)
    return SegmentVectors(np.array(src).reshape(-1, 3), np.array(dst).reshape(-1, 3),
                          np.array(w), np.array(start, dtype=int), np.array(turn, dtype=bool))


def _spread(vectors: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """How far unit vectors spread around each axis of AXES (0: all along it)."""
    if len(vectors) == 0:
        return np.zeros(3)
    return np.sqrt(np.average(1.0 - (vectors @ AXES.T) ** 2, axis=0, weights=weights))


def _weighted_fit(src: np.ndarray, dst: np.ndarray, w: np.ndarray, free: np.ndarray):
    # fit_rotation is unweighted: a weight scales both vectors of a pair (same residual ratio)
    s = np.sqrt(w)[:, None]
    return fit_rotation(src * s, dst * s, free)


def _two_stage(v: SegmentVectors, from_turns: np.ndarray,
               from_displacements: np.ndarray) -> np.ndarray:
    """The turn axes fit ``from_turns``, then the displacements (moved by that fit) fit
    ``from_displacements`` (disjoint axes)."""
    R = np.eye(3)
    t = v.turn
    if from_turns.any() and t.any():
        R = _weighted_fit(v.odometry[t], v.gt[t], v.weight[t], from_turns)
    if from_displacements.any() and (~t).any():
        R = _weighted_fit(v.odometry[~t] @ R.T, v.gt[~t], v.weight[~t], from_displacements) @ R
    return R


def _bootstrap(v: SegmentVectors, n_frames: int, period_s: float, from_turns,
               from_displacements, floor_frames: int, reps: int, seed: int, level: float
               ) -> tuple[BlockChoice, AngleSpread]:
    """Circular block resamples of the frames 0 .. n_frames - 1; a segment enters a resample
    as often as its start frame was drawn and the two-stage fit is redone. The block: at least
    ``floor_frames``, and at least the correlation length of each fitted angle's per-segment
    residuals (turn axes and displacement directions, by start frame)."""
    R = _two_stage(v, from_turns, from_displacements)
    t = v.turn
    series = residual_series(v.odometry[t] @ R.T, v.gt[t], from_turns, v.start[t])
    series += residual_series(v.odometry[~t] @ R.T, v.gt[~t], from_displacements, v.start[~t])
    block = choose_block(n_frames, period_s, series, floor_frames)

    def fit(frames: np.ndarray) -> np.ndarray | None:
        drawn = np.bincount(frames, minlength=n_frames)[v.start]
        rows = np.repeat(np.arange(len(v.start)), drawn)
        sample = v.take(rows)
        if (from_turns.any() and sample.turn.sum() < 3) or \
                (from_displacements.any() and (~sample.turn).sum() < 3):
            return None
        return rotation_angles(_two_stage(sample, from_turns, from_displacements))

    return block, bootstrap_angles(n_frames, block, reps, seed, fit, rotation_angles(R), level)


def hand_eye_rotation(gt_poses: np.ndarray, est_poses: np.ndarray, period_s: float,
                      odometry: str = "kiss-icp", segment_s: float = 1.0,
                      min_spread: float = 0.05, min_turn_spread: float = 0.2,
                      bootstrap: int = 200, block_s: float = HE_BLOCK_S,
                      seed: int = 0, level: float = LEVEL) -> HandEyeResult:
    """R_gt_sensor from paired GT (GT frame) and odometry (sensor frame) poses of the same
    frames (see the module docstring). An axis is fitted from the turn axes when they spread
    around it by at least ``min_turn_spread`` (the axes of small turns are noisy: on a drive
    whose turns are about the vertical, their few-degree tilts would otherwise fix yaw, 0.9
    deg off on the synthetic loop), else from the displacements when they spread by at least
    ``min_spread``. Uncertainty: blocks of at least ``block_s`` seconds and one segment (see
    ``_bootstrap``), at most half the frames."""
    step = max(1, int(round(segment_s / period_s)))
    v = segment_vectors(gt_poses, est_poses, step)
    if len(v.odometry) < 5:
        raise DataError(f"hand-eye alignment: only {len(v.odometry)} usable segments of "
                        f"{segment_s} s (the sensor must move at least 1 m per segment); use "
                        "more frames")
    from_turns = _spread(v.odometry[v.turn], v.weight[v.turn]) >= min_turn_spread
    if v.turn.sum() < 3:  # too few turns to trust their axes
        from_turns[:] = False
    from_displacements = (~from_turns) & (_spread(v.odometry[~v.turn], v.weight[~v.turn])
                                          >= min_spread)
    R = _two_stage(v, from_turns, from_displacements)
    floor = max(step + 1, int(math.ceil(block_s / period_s - 1e-9)))
    block, spread = _bootstrap(v, len(gt_poses), period_s, from_turns, from_displacements,
                               floor, bootstrap, seed, level)
    angles = rotation_angles(R)
    observable = from_turns | from_displacements
    source = {ax: TURN_AXES if from_turns[i] else DISPLACEMENTS if from_displacements[i]
              else "not observable" for i, ax in enumerate(ANGLES)}
    per_angle = lambda x: dict(zip(ANGLES, map(float, x), strict=True))  # noqa: E731
    return HandEyeResult(R, per_angle(angles), per_angle(spread.sd_deg),
                         dict(zip(ANGLES, map(bool, observable), strict=True)),
                         len(v.odometry), odometry, source,
                         {ax: (float(spread.low_deg[i]), float(spread.high_deg[i]))
                          for i, ax in enumerate(ANGLES)}, level, block, spread.resamples,
                         len(gt_poses))


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
