"""Per-axis drift of an estimated trajectory against its ground truth, from the first frame.

A relative-error table says how large a drift is; this says along which axis it grows, so an
odometry whose attitude slowly rolls over, or whose scale is off along the road, shows at a
glance. Arrays in, arrays out (no I/O, no plotting: ``bench`` draws the figure).

Frames and definitions
----------------------
Poses are ``T_world_body`` (N, 4, 4), GT and estimate associated 1:1 (same length, same
stamps). Each is first re-based on its own first frame, ``A_k = inv(A_0) @ A_k``, so both start
at the identity and any constant world offset between them drops out.

- ``distance_m[k]``: distance travelled along the GT path up to frame k (sum of the GT position
  steps, ``distance_m[0] = 0``; the same as ``metrics.relative.path_distances``).
- Attitude error ``R_err[k] = R_gt[k]^T @ R_est[k]``: the estimate's attitude seen from the GT
  body frame k (identity when they agree). ``rot_err_deg[k] = (roll, pitch, yaw)`` are the
  components of its rotation vector along the GT body axes x (forward), y (left), z (up) [deg]:
  a roll error is a rotation about the car's own forward axis, whichever way it heads. For
  errors of a few degrees these equal the differences of the estimated and GT roll, pitch and
  yaw angles to first order.
- Position error ``t_err[k] = R_gt[k]^T @ (t_est[k] - t_gt[k])``: the estimated position minus
  the GT position, expressed along the GT body axes at frame k: (along = x, forward; across =
  y, left; vertical = z, up) [m].

Both are errors from the first frame (accumulated drift), not per-segment errors: a rotation
error made early moves every later position, as it does for a user of the odometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from metrics.relative import check_pose_pair, inverse_se3, path_distances

AXES_ROT = ("roll", "pitch", "yaw")
AXES_TRANS = ("along", "across", "vertical")


@dataclass(frozen=True)
class Drift:
    """Per frame: ``distance_m`` (N,) [m], ``rot_err_deg`` (N, 3) roll/pitch/yaw [deg],
    ``trans_err_m`` (N, 3) along/across/vertical [m]; NaN rows where the estimate is not
    finite."""

    distance_m: np.ndarray
    rot_err_deg: np.ndarray
    trans_err_m: np.ndarray


def drift_from_first_frame(gt_poses: np.ndarray, est_poses: np.ndarray) -> Drift:
    """Per-axis attitude and position error of ``est_poses`` against ``gt_poses``, both
    re-based on their first frame (see the module docstring for the frames)."""
    gt, est = check_pose_pair(gt_poses, est_poses)
    gt_rel = inverse_se3(gt[0]) @ gt
    est_rel = inverse_se3(est[0]) @ est if np.all(np.isfinite(est[0])) else est * np.nan
    R_gt_T = np.swapaxes(gt_rel[:, :3, :3], 1, 2)
    n = len(gt)
    rot = np.full((n, 3), np.nan)
    trans = np.full((n, 3), np.nan)
    finite = np.all(np.isfinite(est_rel), axis=(1, 2))
    if finite.any():
        R_err = R_gt_T[finite] @ est_rel[finite, :3, :3]
        rot[finite] = np.degrees(Rotation.from_matrix(R_err).as_rotvec())
        d = est_rel[finite, :3, 3] - gt_rel[finite, :3, 3]
        trans[finite] = np.einsum("nij,nj->ni", R_gt_T[finite], d)
    return Drift(path_distances(gt_rel[:, :3, 3]), rot, trans)
