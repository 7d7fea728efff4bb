"""Absolute pose error (APE) after a stated alignment of the estimate onto the ground truth.

Poses are ``T_world_body`` as (N, 4, 4) float64 arrays, associated 1:1. The alignment maps the
estimate's world frame into the GT world frame: ``P'_k = T_align @ P_k`` (for Sim(3) the
positions are scaled first: ``t'_k = s R t_k + t``, as evo's ``PosePath3D.align(...,
correct_scale=True)``). Per pose: translation error ``|t(G_k) - t(P'_k)|`` [m] and rotation
error = angle of ``R(G_k)^T R(P'_k)`` [deg] (evo's ``APE`` with ``PoseRelation.translation_part``
and ``rotation_angle_deg``).

Alignments (``Alignment.parse``; the names of evo_ape's options in brackets):
- ``"se3"``: Umeyama (1991) rotation + translation of all positions [``-a``].
- ``"sim3"``: Umeyama rotation + translation + scale [``-as``].
- ``"se3-first-N"`` / ``"first-N"`` and ``"sim3-first-N"``: the same fitted on the first N
  poses only [``-a --n_to_align N``]; the error is still over all poses.
- ``"origin"``: ``T_align = G_0 @ inv(P_0)``, the first poses coincide [``--align_origin``].
- ``"none"``: identity [no option].

Umeyama and both errors are computed here, vectorised, and compared with evo's
(``evo.core.geometry.umeyama_alignment``, ``APE``) in the tests: evo loops over the poses in
Python (its Umeyama and translation APE about 14 us a pose together, its rotation APE 3.5 s on
a 12k-pose trajectory), a large share of scoring a long drive.
When the positions cannot fix the rotation (all identical, e.g. a method that returns
the identity on every frame, or all on one line) evo raises; the rotation is then taken from the
orientations instead (``ApeStats.alignment == "se3-orientation"``), so the run is scored.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from metrics.relative import MetricError, check_pose_pair, inverse_se3, rotation_angle_deg

#: the alignment kinds; a fitted kind may be restricted to the first N poses ("se3-first-50")
ALIGNMENTS = ("se3", "sim3", "origin", "none")
_SPEC = re.compile(r"^(?:(se3|sim3)-)?first-(\d+)$")


@dataclass(frozen=True)
class Alignment:
    """How the estimate is aligned before APE: ``kind`` in ``ALIGNMENTS`` and, for a fitted
    kind, ``first_n`` (fit on the first N poses only; None = all)."""

    kind: str = "se3"
    first_n: int | None = None

    @classmethod
    def parse(cls, text: str | Alignment) -> Alignment:
        """"se3", "sim3", "origin", "none", "first-N" (= "se3-first-N"), "sim3-first-N"."""
        if isinstance(text, Alignment):
            return text
        spec = str(text).strip().lower()
        if spec in ALIGNMENTS:
            return cls(spec)
        m = _SPEC.match(spec)
        if m and int(m.group(2)) >= 1:
            return cls(m.group(1) or "se3", int(m.group(2)))
        raise MetricError(f"unknown alignment {text!r}: expected one of {', '.join(ALIGNMENTS)}"
                          ", first-N or sim3-first-N (N >= 1 poses)")

    @property
    def name(self) -> str:
        """The spec string (what ``parse`` reads back): "se3", "sim3-first-50" ..."""
        return self.kind if self.first_n is None else f"{self.kind}-first-{self.first_n}"

    @property
    def description(self) -> str:
        """Caption words: "SE(3) alignment (Umeyama, all poses)" ..."""
        if self.kind == "none":
            return "no alignment"
        if self.kind == "origin":
            return "origin alignment (first estimated pose on the first GT pose)"
        group = {"se3": "SE(3)", "sim3": "Sim(3)"}[self.kind]
        poses = "all poses" if self.first_n is None else f"first {self.first_n} poses"
        return f"{group} alignment (Umeyama, {poses})"

    @property
    def evo_options(self) -> str:
        """The evo_ape options that give the same alignment."""
        opts = {"none": "", "origin": "--align_origin", "se3": "-a", "sim3": "-as"}[self.kind]
        return opts + (f" --n_to_align {self.first_n}" if self.first_n is not None else "")


@dataclass(frozen=True)
class ApeStats:
    """APE summary: translation in metres, rotation in degrees; std is population (ddof=0).
    ``alignment`` is the alignment used (``Alignment.name``, or "<kind>-orientation" for the
    degenerate fallback); ``scale`` the Sim(3) scale (1 otherwise)."""

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
    scale: float = 1.0


def umeyama_batch(src: np.ndarray, dst: np.ndarray, with_scale: bool
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per batch row of corresponding points ``src``, ``dst`` (c, N, 3): (R (c, 3, 3),
    t (c, 3), s (c,), degenerate (c,)) minimising ``|dst - (s R src + t)|^2`` (Umeyama 1991,
    with the reflection guard, as evo's ``umeyama_alignment``; ``s`` = 1 without scale);
    degenerate: the cross-covariance has rank < 2 (:func:`positions_degenerate`), where R is
    not unique."""
    mu_s, mu_d = src.mean(axis=1), dst.mean(axis=1)
    xs, xd = src - mu_s[:, None], dst - mu_d[:, None]
    cov = np.swapaxes(xd, 1, 2) @ xs / src.shape[1]
    u, d, vt = np.linalg.svd(cov)
    degenerate = np.count_nonzero(
        d > np.finfo(float).eps * np.maximum(1.0, d[:, :1]), axis=1) < 2
    sign = np.where(np.linalg.det(u) * np.linalg.det(vt) < 0.0, -1.0, 1.0)
    s_diag = np.ones((len(src), 3))
    s_diag[:, 2] = sign
    rot = u @ (s_diag[:, :, None] * vt)
    if with_scale:
        var = np.mean(np.sum(xs**2, axis=2), axis=1)
        scale = np.sum(d * s_diag, axis=1) / var
    else:
        scale = np.ones(len(src))
    trans = mu_d - scale[:, None] * (rot @ mu_s[:, :, None])[:, :, 0]
    return rot, trans, scale, degenerate


def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = False
            ) -> tuple[np.ndarray, float]:
    """(4x4 rigid T, scale s) minimising ``sum |dst_k - (s R src_k + t)|^2`` (evo's Umeyama,
    vectorised: evo's loops over the points in Python; the tests compare the two). ``src`` /
    ``dst`` are (N, 3) corresponding points. Raises MetricError if the points are degenerate
    (covariance rank < 2), where R is not unique."""
    src = np.asarray(src, float)[None]
    dst = np.asarray(dst, float)[None]
    rot, trans, scale, degenerate = umeyama_batch(src, dst, with_scale)
    if degenerate[0] or src.shape[1] < 3:
        raise MetricError("se3 alignment is degenerate: estimated/GT positions are (nearly) "
                          "collinear or identical; use alignment='origin'")
    transform = np.eye(4)
    transform[:3, :3] = rot[0]
    transform[:3, 3] = trans[0]
    return transform, float(scale[0])


def umeyama_se3(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """4x4 rigid transform T (no scale) minimising ``sum |dst_k - (R src_k + t)|^2``."""
    return umeyama(src, dst)[0]


def orientation_alignment(gt: np.ndarray, est: np.ndarray) -> np.ndarray:
    """``T_align`` whose rotation best maps the estimated orientations onto the GT ones
    (minimises ``sum |R(G_k) - R R(P_k)|_F^2``: the polar factor of ``sum R(G_k) R(P_k)^T``)
    and whose translation then fits the position means (``mean t(G) - R mean t(P)``).
    evo has no such fallback."""
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


def align(gt: np.ndarray, est: np.ndarray, alignment: Alignment | str
          ) -> tuple[np.ndarray, str, float]:
    """(aligned estimate, alignment used, scale). Fitted kinds on degenerate positions (an
    estimate that never moves, or a straight line) fall back to
    :func:`orientation_alignment` ("<kind>-orientation", scale 1), so such a run is scored."""
    a = Alignment.parse(alignment)
    if a.kind == "none":
        return est.copy(), a.name, 1.0
    if a.kind == "origin":
        return gt[0] @ inverse_se3(est[0]) @ est, a.name, 1.0
    n = len(est) if a.first_n is None else min(a.first_n, len(est))
    if n < 3 or positions_degenerate(est[:n], gt[:n]):
        return orientation_alignment(gt[:n], est[:n]) @ est, f"{a.kind}-orientation", 1.0
    transform, scale = umeyama(est[:n, :3, 3], gt[:n, :3, 3], a.kind == "sim3")
    out = est.copy()
    out[:, :3, 3] *= scale
    return transform @ out, a.name, scale


def ape_errors(gt_poses: np.ndarray, est_poses: np.ndarray,
               alignment: Alignment | str = "se3") -> tuple[np.ndarray, np.ndarray]:
    """Per-pose (translation error [m], rotation error [deg]) after alignment."""
    return _ape(gt_poses, est_poses, alignment)[:2]


def _ape(gt_poses, est_poses, alignment) -> tuple[np.ndarray, np.ndarray, str, float]:
    gt, est = check_pose_pair(gt_poses, est_poses)
    a = Alignment.parse(alignment)
    if not np.all(np.isfinite(est)):
        nan = np.full(gt.shape[0], np.nan)
        return nan, nan.copy(), a.name, np.nan
    aligned, used, scale = align(gt, est, a)
    trans = np.linalg.norm(gt[:, :3, 3] - aligned[:, :3, 3], axis=1)
    rel_rot = np.swapaxes(gt[:, :3, :3], 1, 2) @ aligned[:, :3, :3]
    return trans, rotation_angle_deg(rel_rot), used, scale


def _summary(x: np.ndarray) -> tuple[float, ...]:
    return (float(np.sqrt(np.mean(x**2))), float(np.mean(x)), float(np.median(x)),
            float(np.std(x)), float(np.max(x)))


def ape(gt_poses: np.ndarray, est_poses: np.ndarray,
        alignment: Alignment | str = "se3") -> ApeStats:
    """APE statistics after ``alignment`` (see the module docstring).

    If any estimated pose is non-finite (diverged run) every statistic is NaN. ``alignment`` of
    the result says which alignment was used ("se3-orientation" for the degenerate fallback).
    """
    return ape_with_errors(gt_poses, est_poses, alignment)[0]


def ape_with_errors(gt_poses: np.ndarray, est_poses: np.ndarray,
                    alignment: Alignment | str = "se3"
                    ) -> tuple[ApeStats, np.ndarray, np.ndarray]:
    """(:func:`ape`'s statistics, per-pose translation errors [m], rotation errors [deg])."""
    trans, rot, used, scale = _ape(gt_poses, est_poses, alignment)
    return (ApeStats(*_summary(trans), *_summary(rot), n=int(trans.size), alignment=used,
                     scale=scale), trans, rot)
