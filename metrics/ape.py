"""Absolute pose error (APE) after aligning the estimate onto the ground truth.

Poses are ``T_world_body`` as (N, 4, 4) float64 arrays, associated 1:1. The alignment transform
``T_align`` maps the estimate's world frame into the GT world frame; the aligned estimate is
``T_align @ P_k``. Per pose: translation error ``|t(G_k) - t(T_align @ P_k)|`` [m] and rotation
error = angle of ``R(G_k)^T R(T_align @ P_k)`` [deg].

Alignments:
- ``"se3"``: Umeyama (1991) least-squares rotation + translation (no scale) of est positions
  onto GT positions. When the positions cannot fix the rotation (all identical, e.g. a method
  that returns the identity on every frame, or all on one line), the rotation is taken from the
  orientations instead (``ApeStats.alignment == "se3-orientation"``), so the run is scored.
- ``"origin"``: ``T_align = G_0 @ inv(P_0)`` (first estimated pose put onto the first GT pose).
- ``"none"``: identity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from metrics.relative import MetricError, check_pose_pair, inverse_se3, rotation_angle_deg

ALIGNMENTS = ("se3", "origin", "none")


@dataclass(frozen=True)
class ApeStats:
    """APE summary: translation in metres, rotation in degrees; std is population (ddof=0)."""

    trans_rmse_m: float
    trans_mean_m: float
    trans_median_m: float
    trans_std_m: float
    trans_max_m: float
    rot_rmse_deg: float
    rot_mean_deg: float
    rot_median_deg: float
    rot_std_deg: float
    rot_max_deg: float
    n: int
    alignment: str


def umeyama_se3(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """4x4 rigid transform T (no scale) minimising ``sum |dst_k - (R src_k + t)|^2``.

    ``src``/``dst`` are (N, 3) corresponding points. Raises MetricError if the points are
    degenerate (covariance rank < 2, e.g. all points on one line), where R is not unique.
    """
    mean_src = src.mean(axis=0)
    mean_dst = dst.mean(axis=0)
    cov = (dst - mean_dst).T @ (src - mean_src) / src.shape[0]
    u, d, vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(float).eps) < 2:
        raise MetricError(
            "se3 alignment is degenerate: estimated/GT positions are (nearly) collinear or "
            "identical; use alignment='origin'"
        )
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        s[2, 2] = -1.0  # reflection -> proper rotation
    transform = np.eye(4)
    transform[:3, :3] = u @ s @ vt
    transform[:3, 3] = mean_dst - transform[:3, :3] @ mean_src
    return transform


def orientation_alignment(gt: np.ndarray, est: np.ndarray) -> np.ndarray:
    """``T_align`` whose rotation best maps the estimated orientations onto the GT ones
    (minimises ``sum |R(G_k) - R R(P_k)|_F^2``: the polar factor of ``sum R(G_k) R(P_k)^T``)
    and whose translation then fits the position means (``mean t(G) - R mean t(P)``)."""
    m = np.einsum("kij,klj->il", gt[:, :3, :3], est[:, :3, :3])
    u, _, vt = np.linalg.svd(m)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        s[2, 2] = -1.0
    transform = np.eye(4)
    transform[:3, :3] = u @ s @ vt
    transform[:3, 3] = gt[:, :3, 3].mean(axis=0) - transform[:3, :3] @ est[:, :3, 3].mean(axis=0)
    return transform


def positions_degenerate(est: np.ndarray, gt: np.ndarray) -> bool:
    """True when the positions do not fix an SE(3) alignment (rank of their cross-covariance
    below 2: all positions identical, or on one line)."""
    src, dst = est[:, :3, 3], gt[:, :3, 3]
    cov = (dst - dst.mean(axis=0)).T @ (src - src.mean(axis=0)) / len(src)
    d = np.linalg.svd(cov, compute_uv=False)
    return bool(np.count_nonzero(d > np.finfo(float).eps * max(1.0, d[0])) < 2)


def alignment_transform(gt: np.ndarray, est: np.ndarray, alignment: str) -> np.ndarray:
    """``T_align`` (4x4) mapping the estimate's world frame into the GT world frame.

    "se3" on degenerate positions (an estimate that never moves, or a straight line) falls
    back to :func:`orientation_alignment`, so such a run is still scored."""
    if alignment == "se3":
        if positions_degenerate(est, gt):
            return orientation_alignment(gt, est)
        return umeyama_se3(est[:, :3, 3], gt[:, :3, 3])
    if alignment == "origin":
        return gt[0] @ inverse_se3(est[0])
    if alignment == "none":
        return np.eye(4)
    raise MetricError(f"unknown alignment {alignment!r}, expected one of {ALIGNMENTS}")


def ape_errors(
    gt_poses: np.ndarray, est_poses: np.ndarray, alignment: str = "se3"
) -> tuple[np.ndarray, np.ndarray]:
    """Per-pose (translation error [m], rotation error [deg]) after alignment."""
    gt, est = check_pose_pair(gt_poses, est_poses)
    if alignment not in ALIGNMENTS:
        raise MetricError(f"unknown alignment {alignment!r}, expected one of {ALIGNMENTS}")
    if not np.all(np.isfinite(est)):
        nan = np.full(gt.shape[0], np.nan)
        return nan, nan.copy()
    aligned = alignment_transform(gt, est, alignment) @ est
    trans = np.linalg.norm(aligned[:, :3, 3] - gt[:, :3, 3], axis=1)
    rel_rot = np.swapaxes(gt[:, :3, :3], 1, 2) @ aligned[:, :3, :3]
    return trans, rotation_angle_deg(rel_rot)


def ape(gt_poses: np.ndarray, est_poses: np.ndarray, alignment: str = "se3") -> ApeStats:
    """APE statistics after ``alignment`` in {"se3", "origin", "none"}.

    If any estimated pose is non-finite (diverged run) every statistic is NaN. ``alignment`` of
    the result says which alignment was used ("se3-orientation" for the degenerate fallback).
    """
    trans, rot = ape_errors(gt_poses, est_poses, alignment)
    used = alignment
    if alignment == "se3" and np.all(np.isfinite(est_poses)):
        if positions_degenerate(np.asarray(est_poses, float), np.asarray(gt_poses, float)):
            used = "se3-orientation"

    def summary(x: np.ndarray) -> tuple[float, ...]:
        return (
            float(np.sqrt(np.mean(x**2))),
            float(np.mean(x)),
            float(np.median(x)),
            float(np.std(x)),
            float(np.max(x)),
        )

    return ApeStats(*summary(trans), *summary(rot), n=int(trans.size), alignment=used)
