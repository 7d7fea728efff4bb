"""Confidence intervals of the APE: resampling the estimate's frame-to-frame errors.

The APE of one trajectory is a figure of its accumulated drift: the error of a frame is the
sum of every earlier frame-to-frame error (after the alignment). Its per-frame values form a
random walk, not a stationary series, so resampling them in blocks (what
``metrics.intervals`` does for segments) cannot reproduce how much the APE of another
realisation of the same odometry would differ; such intervals covered the long-run mean in
only about 40 % of synthetic trials.

Here the resampled objects are the estimate's **step errors** ``E_k = inv(G_k^-1 G_k+1)
(P_k^-1 P_k+1)`` (the estimated motion from frame k to k+1 is the true one followed by
``E_k``). A resample draws blocks of consecutive step errors (the circular block bootstrap of
``metrics.intervals``, blocks at least the Politis-White length of the step errors' six
components), puts them after the true motions ``G_k^-1 G_k+1`` of the same path, chains them
from the first estimated pose and scores the result with the same alignment: a new trajectory
with the same error process along the same path. Its APE RMSE is a draw from (approximately)
the distribution of the observed one; with ``m*`` the mean of the draws and ``q`` their
percentiles, the interval of the long-run APE is the pivotal one, ``[X - (q_hi - m*),
X - (q_lo - m*)]`` around the observed ``X`` (clipped at 0). Paired: both estimates' step
errors are drawn with the same blocks and the interval is that of the difference.

The number of independent pieces behind the figure is the number of whole blocks of step
errors. The alignment of every resample is a batched Umeyama (1991) fit, the same fit as
``metrics.ape`` (evo's) up to rounding; degenerate resamples (positions on one line) are
aligned by their orientations one by one, as ``metrics.ape.align`` does. Memory is bounded:
resamples are chained ``CHUNK`` at a time.
"""

from __future__ import annotations

import math
from functools import cached_property

import numba as nb
import numpy as np

from metrics.ape import Alignment, orientation_alignment
from metrics.intervals import (
    LEVEL,
    MIN_INDEPENDENT,
    REPS,
    Interval,
    block_index_chunks,
    correlation_length,
    widen,
)
from metrics.relative import check_pose_pair, inverse_se3

#: resamples chained together: memory about 100 bytes x frames x CHUNK, flat in the number of
#: resamples and a small share of a scan per frame
CHUNK = 32
#: the APE quantities: translation [m] and rotation [deg]
QUANTITIES = ("trans_m", "rot_deg")


def step_errors(gt: np.ndarray, est: np.ndarray) -> np.ndarray:
    """(n - 1, 4, 4) ``E_k = inv(G_k^-1 G_k+1) (P_k^-1 P_k+1)``."""
    gt_steps = inverse_se3(gt[:-1]) @ gt[1:]
    est_steps = inverse_se3(est[:-1]) @ est[1:]
    return inverse_se3(gt_steps) @ est_steps


def _twists(errors: np.ndarray) -> np.ndarray:
    """(n, 6) small-angle rotation vector and translation of each step error."""
    r = errors[:, :3, :3]
    rotvec = 0.5 * np.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0],
                             r[:, 1, 0] - r[:, 0, 1]], axis=1)
    return np.concatenate([rotvec, errors[:, :3, 3]], axis=1)


def drift_block(errors_list: list[np.ndarray]) -> int:
    """The block length [steps]: the largest Politis-White length of any component of any
    estimate's step errors, at least 1, at most half the steps."""
    n = len(errors_list[0])
    b = 1
    for errors in errors_list:
        tw = _twists(errors)
        b = max(b, *(correlation_length(tw[:, j]) for j in range(6)))
    return int(max(1, min(b, max(1, n // 2))))


@nb.njit(cache=True)
def _chain_kernel(first, gt_steps, gt_rot, errors, idx, pos, rel):  # pragma: no cover - numba
    """For every row r of ``idx`` (c, n - 1): the poses ``P_0 = first``, ``P_k+1 = P_k
    gt_steps[k] errors[idx[r, k]]``; writes their positions into ``pos`` (c, n, 3) and
    ``R(P_k) R(G_k)^T`` into ``rel`` (c, n, 3, 3)."""
    c, m = idx.shape
    rot = np.empty((3, 3))
    step_r = np.empty((3, 3))
    step_t = np.empty(3)
    new = np.empty((3, 3))
    for r in range(c):
        rot[:, :] = first[:3, :3]
        p = first[:3, 3].copy()
        for k in range(m + 1):
            pos[r, k] = p
            for i in range(3):
                for j in range(3):
                    rel[r, k, i, j] = (rot[i, 0] * gt_rot[k, j, 0] + rot[i, 1] * gt_rot[k, j, 1]
                                       + rot[i, 2] * gt_rot[k, j, 2])
            if k == m:
                break
            g, e = gt_steps[k], errors[idx[r, k]]
            for i in range(3):  # the step g e
                step_t[i] = g[i, 0] * e[0, 3] + g[i, 1] * e[1, 3] + g[i, 2] * e[2, 3] + g[i, 3]
                for j in range(3):
                    step_r[i, j] = g[i, 0] * e[0, j] + g[i, 1] * e[1, j] + g[i, 2] * e[2, j]
            for i in range(3):
                p[i] += rot[i, 0] * step_t[0] + rot[i, 1] * step_t[1] + rot[i, 2] * step_t[2]
                for j in range(3):
                    new[i, j] = (rot[i, 0] * step_r[0, j] + rot[i, 1] * step_r[1, j]
                                 + rot[i, 2] * step_r[2, j])
            rot[:, :] = new


def _umeyama_batch(src: np.ndarray, dst: np.ndarray, with_scale: bool
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per batch row (R (c,3,3), t (c,3), s (c,), degenerate (c,)) minimising
    ``|dst - (s R src + t)|^2`` (Umeyama 1991 with the reflection guard, as evo); degenerate:
    the cross-covariance has rank < 2 (``metrics.ape.positions_degenerate``)."""
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


def _rmse(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(x**2, axis=1))


def ape_rmse_batch(gt: np.ndarray, pos: np.ndarray, rel: np.ndarray, alignment: Alignment | str
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(translation RMSE [m], rotation RMSE [deg]) per row of the trajectories given by their
    positions ``pos`` (c, n, 3) and ``rel`` = ``R(P_k) R(G_k)^T`` (c, n, 3, 3), against ``gt``
    (n, 4, 4), after ``alignment`` (as ``metrics.ape.ape``)."""
    a = Alignment.parse(alignment)
    c, n = pos.shape[:2]
    r_al, t_al, scale = np.repeat(np.eye(3)[None], c, 0), np.zeros((c, 3)), np.ones(c)
    if a.kind in ("se3", "sim3"):
        m = n if a.first_n is None else min(a.first_n, n)
        r_al, t_al, scale, degenerate = _umeyama_batch(
            pos[:, :m], np.broadcast_to(gt[:m, :3, 3], (c, m, 3)), a.kind == "sim3")
        for i in np.flatnonzero(degenerate | (m < 3)):  # as metrics.ape.align
            poses = np.repeat(np.eye(4)[None], m, axis=0)
            poses[:, :3, :3], poses[:, :3, 3] = rel[i, :m] @ gt[:m, :3, :3], pos[i, :m]
            t_align = orientation_alignment(gt[:m], poses)
            r_al[i], t_al[i], scale[i] = t_align[:3, :3], t_align[:3, 3], 1.0
    elif a.kind == "origin":  # G_0 inv(P_0)
        r_al = np.swapaxes(rel[:, 0], 1, 2)
        t_al = gt[0, :3, 3] - (r_al @ pos[:, 0, :, None])[:, :, 0]
    aligned = scale[:, None, None] * (pos @ np.swapaxes(r_al, 1, 2)) + t_al[:, None]
    t_err = np.linalg.norm(aligned - gt[None, :, :3, 3], axis=2)
    # the angle of G_k^T R P_k from its trace: sum_ij R_ij (P_k G_k^T)_ji
    trace = (rel.reshape(c, n, 9) @ np.swapaxes(r_al, 1, 2).reshape(c, 9, 1))[:, :, 0]
    r_err = np.degrees(np.arccos(np.clip(0.5 * (trace - 1.0), -1.0, 1.0)))
    return _rmse(t_err), _rmse(r_err)


def _pivot(observed: float, draws: np.ndarray, level: float) -> tuple[float, float]:
    """``[X - (q_hi - m*), X - (q_lo - m*)]`` for the observed ``X`` and the draws' mean
    ``m*`` and percentiles ``q``."""
    draws = draws[np.isfinite(draws)]
    if draws.size == 0 or not math.isfinite(observed):
        return math.nan, math.nan
    alpha = 0.5 * (1.0 - level)
    lo, hi = np.quantile(draws, [alpha, 1.0 - alpha])
    centre = float(np.mean(draws))
    return observed - (float(hi) - centre), observed - (float(lo) - centre)


class Drift:
    """An APE figure's trajectory: the scored GT and estimated poses (N, 4, 4, ``T_world_body``)
    and the alignment; its step errors, observed RMSE and resampled RMSE are computed once."""

    def __init__(self, gt_poses: np.ndarray, est_poses: np.ndarray,
                 alignment: Alignment | str = "se3") -> None:
        self.gt, self.est = check_pose_pair(gt_poses, est_poses)
        self.alignment = Alignment.parse(alignment).name
        self.usable = len(self.gt) >= 3 and bool(np.all(np.isfinite(self.est)))
        self._draws: dict[tuple, dict[str, np.ndarray]] = {}

    @cached_property
    def errors(self) -> np.ndarray:
        return step_errors(self.gt, self.est)

    @cached_property
    def observed(self) -> dict[str, float]:
        """{"trans_m", "rot_deg"}: the RMSE of the estimate itself (``metrics.ape.ape``'s)."""
        rel = self.est[None, :, :3, :3] @ np.swapaxes(self.gt[None, :, :3, :3], -1, -2)
        t, r = ape_rmse_batch(self.gt, self.est[None, :, :3, 3], rel, self.alignment)
        return {"trans_m": float(t[0]), "rot_deg": float(r[0])}

    def same_frames(self, other: Drift) -> bool:
        """Scored on the same GT poses with the same alignment (a paired comparison)."""
        return (self.alignment == other.alignment and self.gt.shape == other.gt.shape
                and bool(np.array_equal(self.gt, other.gt)))

    def draws(self, block: int, reps: int = REPS, seed: int = 0) -> dict[str, np.ndarray]:
        """{quantity: (reps,) RMSE} of the trajectories re-chained from ``block``-step blocks
        of the step errors (seeded: two estimates of the same frames draw the same blocks)."""
        key = (int(block), int(reps), int(seed))
        if key not in self._draws:
            gt, n = self.gt, len(self.gt)
            gt_steps = inverse_se3(gt[:-1]) @ gt[1:]
            gt_rot = np.ascontiguousarray(gt[:, :3, :3])
            out = {q: np.empty(reps) for q in QUANTITIES}
            for c0, rows in block_index_chunks(n - 1, block, reps, seed, CHUNK):
                pos, rel = np.empty((len(rows), n, 3)), np.empty((len(rows), n, 3, 3))
                _chain_kernel(self.est[0], gt_steps, gt_rot, self.errors, rows, pos, rel)
                t_rmse, r_rmse = ape_rmse_batch(gt, pos, rel, self.alignment)
                out["trans_m"][c0:c0 + len(rows)] = t_rmse
                out["rot_deg"][c0:c0 + len(rows)] = r_rmse
            self._draws[key] = out
        return self._draws[key]


def ape_intervals(drift: Drift, level: float = LEVEL, reps: int = REPS, seed: int = 0,
                  block: int | None = None) -> dict[str, Interval]:
    """{"trans_m", "rot_deg"}: the interval of the long-run APE RMSE (module docstring),
    NaN with fewer than two whole blocks or a non-finite estimate."""
    if not drift.usable:
        return {q: Interval(math.nan, math.nan, level, 0, 0) for q in QUANTITIES}
    block = drift_block([drift.errors]) if block is None else int(block)
    n_ind = len(drift.errors) // block
    out = {}
    for q in QUANTITIES:
        lo, hi = math.nan, math.nan
        if n_ind >= MIN_INDEPENDENT:
            lo, hi = _pivot(drift.observed[q], drift.draws(block, reps, seed)[q], level)
            lo = max(0.0, lo)  # an RMSE
        out[q] = Interval(lo, hi, level, block, n_ind)
    return out


def paired_ape_interval(a: Drift, b: Drift, quantity: str = "trans_m", level: float = LEVEL,
                        reps: int = REPS, seed: int = 0, block: int | None = None) -> Interval:
    """The interval of ``APE(a) - APE(b)`` (``quantity``'s RMSE) of two estimates of the same
    frames (``Drift.same_frames``), both resampled with the same blocks, widened for the
    independent blocks (``metrics.intervals.widen``)."""
    if not (a.usable and b.usable and a.same_frames(b)):
        return Interval(math.nan, math.nan, level, 0, 0)
    block = drift_block([a.errors, b.errors]) if block is None else int(block)
    n_ind = len(a.errors) // block
    diff = a.observed[quantity] - b.observed[quantity]
    lo, hi = _pivot(diff, a.draws(block, reps, seed)[quantity]
                    - b.draws(block, reps, seed)[quantity], level)
    lo, hi = widen(diff, lo, hi, n_ind, level)
    return Interval(lo, hi, level, block, n_ind)
