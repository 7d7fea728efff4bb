"""KITTI-style drift: translation error in % and rotation error in deg/100 m, averaged over
segments of 100, 200, ..., 800 m (the KITTI odometry benchmark's definition).

Definition (the KITTI odometry devkit, ``devkit/cpp/evaluate_odometry.cpp``: ``calcSequenceErrors``,
``trajectoryDistances``, ``lastFrameFromSegmentLength``, ``rotationError``,
``translationError``), on GT and estimate associated 1:1 (``T_world_body``, (N, 4, 4)):

- ``dist[k]``: distance travelled along the GT path up to pose k (``dist[0] = 0``).
- Segment starts: every ``step_frames``-th pose (10 in the devkit: once a second at 10 Hz).
- For a start i and a length L, the end is the first pose j with ``dist[j] > dist[i] + L``
  (strictly greater); no such pose: no segment.
- ``E = inv(inv(P_i) P_j) @ (inv(G_i) G_j)`` (estimated motion inverted times GT motion);
  translation error ``|t(E)| / L``, rotation error ``acos(clip((trace R(E) - 1) / 2)) / L``.
- The drift is the mean over all segments of all lengths (not a mean of per-length means);
  reported as ``100 * t`` [%] and ``100 * degrees(r)`` [deg/100 m], as kiss-icp and the radar
  odometry papers do. Per-length means are kept too (the devkit's per-length plots).

evo has no such metric (its RPE pairs by nearest distance with a tolerance, every pose a
start), so it is computed here; the devkit runs in single precision, this in double.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from metrics.relative import check_pose_pair, inverse_se3, path_distances

#: the KITTI benchmark's segment lengths [m]
KITTI_LENGTHS_M: tuple[float, ...] = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)
#: segment starts every this many poses (the devkit's ``step_size``)
STEP_FRAMES = 10


@dataclass(frozen=True)
class KittiSegments:
    """One entry per segment: start / end pose index, nominal length [m], translation error
    [fraction of the length] and rotation error [rad/m]."""

    start_idx: np.ndarray
    end_idx: np.ndarray
    length_m: np.ndarray
    trans_per_m: np.ndarray
    rot_rad_per_m: np.ndarray


@dataclass(frozen=True)
class KittiDrift:
    """``trans_pct`` [%] and ``rot_deg_per_100m`` over every segment (NaN with none), ``n``
    segments; ``per_length``: length -> (trans_pct, rot_deg_per_100m, n); ``too_long``: the
    requested lengths the GT path is too short for."""

    trans_pct: float
    rot_deg_per_100m: float
    n: int
    per_length: dict[float, tuple[float, float, int]]
    too_long: tuple[float, ...]


def kitti_segments(gt_poses: np.ndarray, est_poses: np.ndarray,
                   lengths_m=KITTI_LENGTHS_M, step_frames: int = STEP_FRAMES) -> KittiSegments:
    """Every KITTI segment of the requested lengths (see the module docstring)."""
    gt, est = check_pose_pair(gt_poses, est_poses)
    dist = path_distances(gt[:, :3, 3])
    starts = np.arange(0, len(gt), int(step_frames))
    s_all, e_all, l_all = [], [], []
    for length in (float(x) for x in lengths_m):
        end = np.searchsorted(dist, dist[starts] + length, side="right")  # first dist > d + L
        ok = end < len(gt)
        s_all.append(starts[ok])
        e_all.append(end[ok])
        l_all.append(np.full(int(ok.sum()), length))
    # grouped by length here (the devkit loops start-major); the means do not depend on it
    start = np.concatenate(s_all).astype(int)
    end = np.concatenate(e_all).astype(int)
    length = np.concatenate(l_all)
    with np.errstate(invalid="ignore", over="ignore"):
        d_est = inverse_se3(est[start]) @ est[end]
        d_gt = inverse_se3(gt[start]) @ gt[end]
        err = inverse_se3(d_est) @ d_gt
        trans = np.linalg.norm(err[:, :3, 3], axis=1)
        cos = 0.5 * (np.trace(err[:, :3, :3], axis1=1, axis2=2) - 1.0)
        rot = np.arccos(np.clip(cos, -1.0, 1.0))
        rot[~np.isfinite(cos)] = np.nan
    return KittiSegments(start, end, length, trans / length, rot / length)


def kitti_drift(gt_poses: np.ndarray, est_poses: np.ndarray, lengths_m=KITTI_LENGTHS_M,
                step_frames: int = STEP_FRAMES) -> KittiDrift:
    """KITTI drift over the requested lengths (see the module docstring)."""
    seg = kitti_segments(gt_poses, est_poses, lengths_m, step_frames)
    lengths = [float(x) for x in lengths_m]

    def means(mask) -> tuple[float, float, int]:
        n = int(np.count_nonzero(mask))
        if n == 0:
            return (float("nan"), float("nan"), 0)
        with np.errstate(invalid="ignore"):
            return (float(100.0 * np.mean(seg.trans_per_m[mask])),
                    float(100.0 * np.degrees(np.mean(seg.rot_rad_per_m[mask]))), n)

    per_length = {L: means(seg.length_m == L) for L in lengths}
    t, r, n = means(np.ones(seg.length_m.shape, dtype=bool))
    return KittiDrift(t, r, n, per_length, tuple(L for L in lengths if per_length[L][2] == 0))
