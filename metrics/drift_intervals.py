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

The figure's interval follows the three steps of ``metrics.intervals``: blocks of
``BLOCK_FACTOR`` (1.5) times the Politis-White length of the step errors' six components (at most
half the steps), the pivotal interval widened about ``X`` by ``t_{K-1} / z`` for the ``K``
whole blocks, and stretched to hold ``X``. The number of independent pieces behind the figure
is the number of whole blocks of step errors. A paired comparison keeps blocks of one
Politis-White length.

**Cost.** A resample is chained, aligned and scored one at a time by a compiled kernel
(``_draw_kernel``) that keeps one path in memory, never the resamples' paths: each step's
error index is computed from the block starts, what the Umeyama (1991) fit needs
(the cross-covariance with the GT positions, the positions' mean and variance) is summed while
chaining, the 3 x 3 fit solved, and the aligned errors summed in a second pass over the one
path. It gives the draws of the batched computation (``draws_batched``: every path of a chunk
materialised, then ``ape_rmse_batch``, the same fit as ``metrics.ape``, evo's, up to rounding)
to rounding. A resample whose positions do not fix the alignment (all on one line: a straight
drive) is aligned by its orientations, as ``metrics.ape.align`` does, in the kernel too. The
kernel releases the GIL: ``set_threads`` draws chunks of resamples on several threads
(``bench score`` uses every core; the draws are the same).
"""

from __future__ import annotations

import itertools
import math
import queue
from concurrent.futures import ThreadPoolExecutor
from functools import cached_property

import numba as nb
import numpy as np

from metrics import intervals as _iv
from metrics.ape import Alignment, orientation_alignment, umeyama_batch
from metrics.intervals import (
    LEVEL,
    MIN_INDEPENDENT,
    REPS,
    Interval,
    block_index_chunks,
    block_start_chunks,
    contain,
    correlation_length,
    widen,
)
from metrics.relative import check_pose_pair, inverse_se3

#: resamples chained together by the reference :func:`draws_batched`: memory about 100 bytes x
#: frames x CHUNK, flat in the number of
#: resamples and a small share of a scan per frame
CHUNK = 32
#: the APE quantities: translation [m] and rotation [deg]
QUANTITIES = ("trans_m", "rot_deg")

#: threads the resamples are drawn on (``set_threads``); 1 unless a command that scores alone
#: asks for more: inside an experiment's workers, a second thread would take the core another
#: worker times its method on
_threads = 1


def set_threads(threads: int) -> None:
    """Draw the APE resamples on ``threads`` threads (the draws are the same: each resample
    is seeded by its row, whatever thread computes it)."""
    global _threads
    _threads = max(1, int(threads))


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


#: alignment kinds as the draw kernel's codes
_KIND_CODE = {"none": 0, "origin": 1, "se3": 2, "sim3": 3}

#: ``asin(sqrt(x))^2 = sum_n c_n x^n`` with ``c_n = 2^(2n-1) ((n-1)!)^2 / (2n)!`` (n = 1..10):
#: the squared angle of a rotation from ``x = (1 - cos) / 2`` is ``4 asin(sqrt(x))^2``. Up to
#: ``_SERIES_X`` (angles up to 20 deg) the ten terms leave less than 2e-17 of it, and cost a
#: tenth of a call to ``arccos``; larger angles take ``arccos``.
_ASIN_SQ = np.array([2.0 ** (2 * n - 1) * math.factorial(n - 1) ** 2 / math.factorial(2 * n)
                     for n in range(1, 11)])
_SERIES_X = 0.03


@nb.njit(cache=True, nogil=True, fastmath={"contract", "reassoc", "nsz", "arcp"})
def _angle_sq(cos):  # pragma: no cover - numba
    """The squared rotation angle [rad^2] of a rotation whose angle has cosine ``cos``:
    ``arccos(cos)^2``, by the series ``_ASIN_SQ`` for small angles."""
    c = min(1.0, max(-1.0, cos))
    x = 0.5 * (1.0 - c)
    if x > _SERIES_X:
        ang = np.arccos(c)
        return ang * ang
    s = _ASIN_SQ[9]
    for i in range(8, -1, -1):
        s = s * x + _ASIN_SQ[i]
    return 4.0 * s * x


@nb.njit(cache=True, nogil=True, fastmath={"contract", "reassoc", "nsz", "arcp"})
def _chain_one(first, gt_steps, gt_rot, errors, starts_r, block, pos, rel, xd, m_fit,
               sums):  # pragma: no cover - numba
    """One resample's path (module docstring): ``P_0 = first``, ``P_k+1 = P_k gt_steps[k]
    errors[i_k]``, ``i_k = (starts_r[k // block] + k % block) mod (n - 1)``; positions into
    ``pos`` (n, 3) and ``R(P_k) R(G_k)^T`` into ``rel`` (n, 9, row-major). Over the first
    ``m_fit`` poses it accumulates what the Umeyama fit needs into ``sums`` (13,): ``sum xd_k
    p_k^T`` (9; ``xd`` (n + 1, 3): the GT positions less their mean ``c = xd[n]``, so that this
    is ``m`` times the cross-covariance), ``sum p_k - c`` (3) and ``sum |p_k - c|^2`` (for the
    positions' variance). Scalar locals (registers), no allocation."""
    n = pos.shape[0]
    c0, c1, c2 = xd[n, 0], xd[n, 1], xd[n, 2]
    for i in range(sums.size):
        sums[i] = 0.0
    m = n - 1
    r00, r01, r02 = first[0, 0], first[0, 1], first[0, 2]
    r10, r11, r12 = first[1, 0], first[1, 1], first[1, 2]
    r20, r21, r22 = first[2, 0], first[2, 1], first[2, 2]
    p0, p1, p2 = first[0, 3], first[1, 3], first[2, 3]
    # i_k by counters, not by k // block, k % block and mod m (three integer divisions a step)
    j, left, src = 0, 0, 0
    for k in range(n):
        pos[k, 0] = p0
        pos[k, 1] = p1
        pos[k, 2] = p2
        if k < m_fit:
            x0, x1, x2 = xd[k, 0], xd[k, 1], xd[k, 2]
            sums[0] += x0 * p0
            sums[1] += x0 * p1
            sums[2] += x0 * p2
            sums[3] += x1 * p0
            sums[4] += x1 * p1
            sums[5] += x1 * p2
            sums[6] += x2 * p0
            sums[7] += x2 * p1
            sums[8] += x2 * p2
            d0, d1, d2 = p0 - c0, p1 - c1, p2 - c2
            sums[9] += d0
            sums[10] += d1
            sums[11] += d2
            sums[12] += d0 * d0 + d1 * d1 + d2 * d2
        g = gt_rot[k]  # R(P_k) R(G_k)^T
        rel[k, 0] = r00 * g[0, 0] + r01 * g[0, 1] + r02 * g[0, 2]
        rel[k, 1] = r00 * g[1, 0] + r01 * g[1, 1] + r02 * g[1, 2]
        rel[k, 2] = r00 * g[2, 0] + r01 * g[2, 1] + r02 * g[2, 2]
        rel[k, 3] = r10 * g[0, 0] + r11 * g[0, 1] + r12 * g[0, 2]
        rel[k, 4] = r10 * g[1, 0] + r11 * g[1, 1] + r12 * g[1, 2]
        rel[k, 5] = r10 * g[2, 0] + r11 * g[2, 1] + r12 * g[2, 2]
        rel[k, 6] = r20 * g[0, 0] + r21 * g[0, 1] + r22 * g[0, 2]
        rel[k, 7] = r20 * g[1, 0] + r21 * g[1, 1] + r22 * g[1, 2]
        rel[k, 8] = r20 * g[2, 0] + r21 * g[2, 1] + r22 * g[2, 2]
        if k == m:
            break
        if left == 0:  # a new block
            src, left = starts_r[j] % m, block
            j += 1
        s = gt_steps[k]
        e = errors[src]
        src += 1
        left -= 1
        if src == m:
            src = 0
        # the step s e: rotation a, translation t
        t0 = s[0, 0] * e[0, 3] + s[0, 1] * e[1, 3] + s[0, 2] * e[2, 3] + s[0, 3]
        t1 = s[1, 0] * e[0, 3] + s[1, 1] * e[1, 3] + s[1, 2] * e[2, 3] + s[1, 3]
        t2 = s[2, 0] * e[0, 3] + s[2, 1] * e[1, 3] + s[2, 2] * e[2, 3] + s[2, 3]
        a00 = s[0, 0] * e[0, 0] + s[0, 1] * e[1, 0] + s[0, 2] * e[2, 0]
        a01 = s[0, 0] * e[0, 1] + s[0, 1] * e[1, 1] + s[0, 2] * e[2, 1]
        a02 = s[0, 0] * e[0, 2] + s[0, 1] * e[1, 2] + s[0, 2] * e[2, 2]
        a10 = s[1, 0] * e[0, 0] + s[1, 1] * e[1, 0] + s[1, 2] * e[2, 0]
        a11 = s[1, 0] * e[0, 1] + s[1, 1] * e[1, 1] + s[1, 2] * e[2, 1]
        a12 = s[1, 0] * e[0, 2] + s[1, 1] * e[1, 2] + s[1, 2] * e[2, 2]
        a20 = s[2, 0] * e[0, 0] + s[2, 1] * e[1, 0] + s[2, 2] * e[2, 0]
        a21 = s[2, 0] * e[0, 1] + s[2, 1] * e[1, 1] + s[2, 2] * e[2, 1]
        a22 = s[2, 0] * e[0, 2] + s[2, 1] * e[1, 2] + s[2, 2] * e[2, 2]
        p0 += r00 * t0 + r01 * t1 + r02 * t2
        p1 += r10 * t0 + r11 * t1 + r12 * t2
        p2 += r20 * t0 + r21 * t1 + r22 * t2
        r00, r01, r02 = (r00 * a00 + r01 * a10 + r02 * a20, r00 * a01 + r01 * a11 + r02 * a21,
                         r00 * a02 + r01 * a12 + r02 * a22)
        r10, r11, r12 = (r10 * a00 + r11 * a10 + r12 * a20, r10 * a01 + r11 * a11 + r12 * a21,
                         r10 * a02 + r11 * a12 + r12 * a22)
        r20, r21, r22 = (r20 * a00 + r21 * a10 + r22 * a20, r20 * a01 + r21 * a11 + r22 * a21,
                         r20 * a02 + r21 * a12 + r22 * a22)


@nb.njit(cache=True, nogil=True, fastmath={"contract", "reassoc", "nsz", "arcp"})
def _draw_kernel(first, gt_steps, gt_rot, gt_pos, errors, starts, block, kind, m_fit,
                 out_t, out_r, pos, rel):  # pragma: no cover - numba
    """For every resample r (row of ``starts``: the first step error of each block): its path
    (``_chain_one``) into the buffers ``pos`` (n, 3) and ``rel`` (n, 9), aligned (``kind``:
    0 none, 1 origin, 2 se3, 3 sim3; Umeyama on the first ``m_fit`` poses as
    ``metrics.ape.umeyama_batch``), its translation RMSE [m] and rotation RMSE [deg] written into
    ``out_t[r]``, ``out_r[r]``. A resample whose positions do not fix the alignment is aligned
    by its orientations (``metrics.ape.orientation_alignment``). One path in memory, never
    the resamples' paths."""
    n = gt_pos.shape[0]
    reps = starts.shape[0]
    # the GT positions of the fit less their mean c (row n: c)
    xd = np.empty((n + 1, 3))
    c = np.zeros(3)
    for k in range(m_fit):
        for i in range(3):
            c[i] += gt_pos[k, i] / m_fit
    for k in range(n):
        for i in range(3):
            xd[k, i] = gt_pos[k, i] - c[i]
    xd[n] = c
    sums = np.empty(13)
    r_al = np.empty((3, 3))
    t_al = np.empty(3)
    cov = np.empty((3, 3))
    mu_s = np.empty(3)
    mu_d = np.empty(3)
    eps = np.finfo(np.float64).eps
    for r in range(reps):
        _chain_one(first, gt_steps, gt_rot, errors, starts[r], block, pos, rel, xd,
                   m_fit if kind >= 2 else 0, sums)
        scale = 1.0
        for i in range(3):
            t_al[i] = 0.0
            for j in range(3):
                r_al[i, j] = 1.0 if i == j else 0.0
        if kind == 1:  # G_0 inv(P_0)
            for i in range(3):
                for j in range(3):
                    r_al[i, j] = rel[0, 3 * j + i]
            for i in range(3):
                t_al[i] = gt_pos[0, i] - (r_al[i, 0] * pos[0, 0] + r_al[i, 1] * pos[0, 1]
                                          + r_al[i, 2] * pos[0, 2])
        elif kind >= 2:
            for i in range(3):
                mu_s[i] = c[i] + sums[9 + i] / m_fit
                mu_d[i] = c[i]
                for j in range(3):
                    cov[i, j] = sums[3 * i + j] / m_fit
            var = sums[12] / m_fit - ((sums[9] / m_fit) ** 2 + (sums[10] / m_fit) ** 2
                                      + (sums[11] / m_fit) ** 2)
            u, d, vt = np.linalg.svd(cov)
            rank = 0
            for i in range(3):
                if d[i] > eps * max(1.0, d[0]):
                    rank += 1
            degenerate = rank < 2 or m_fit < 3
            if degenerate:
                # the positions do not fix the rotation: the polar factor of sum R(G_k) R(P_k)^T
                # (metrics.ape.orientation_alignment; rel holds its transposed terms), no scale
                for i in range(3):
                    for j in range(3):
                        cov[i, j] = 0.0
                for k in range(m_fit):
                    for i in range(3):
                        for j in range(3):
                            cov[i, j] += rel[k, 3 * j + i]
                u, d, vt = np.linalg.svd(cov)
            sign = -1.0 if np.linalg.det(u) * np.linalg.det(vt) < 0.0 else 1.0
            for i in range(3):
                for j in range(3):
                    r_al[i, j] = (u[i, 0] * vt[0, j] + u[i, 1] * vt[1, j]
                                  + sign * u[i, 2] * vt[2, j])
            if kind == 3 and not degenerate:
                scale = (d[0] + d[1] + sign * d[2]) / var
            for i in range(3):
                t_al[i] = mu_d[i] - scale * (r_al[i, 0] * mu_s[0] + r_al[i, 1] * mu_s[1]
                                             + r_al[i, 2] * mu_s[2])
        s00, s01, s02 = scale * r_al[0, 0], scale * r_al[0, 1], scale * r_al[0, 2]
        s10, s11, s12 = scale * r_al[1, 0], scale * r_al[1, 1], scale * r_al[1, 2]
        s20, s21, s22 = scale * r_al[2, 0], scale * r_al[2, 1], scale * r_al[2, 2]
        q00, q01, q02 = r_al[0, 0], r_al[0, 1], r_al[0, 2]
        q10, q11, q12 = r_al[1, 0], r_al[1, 1], r_al[1, 2]
        q20, q21, q22 = r_al[2, 0], r_al[2, 1], r_al[2, 2]
        u0, u1, u2 = t_al[0], t_al[1], t_al[2]
        t_sum = 0.0
        r_sum = 0.0
        for k in range(n):
            x0 = s00 * pos[k, 0] + s01 * pos[k, 1] + s02 * pos[k, 2] + u0 - gt_pos[k, 0]
            x1 = s10 * pos[k, 0] + s11 * pos[k, 1] + s12 * pos[k, 2] + u1 - gt_pos[k, 1]
            x2 = s20 * pos[k, 0] + s21 * pos[k, 1] + s22 * pos[k, 2] + u2 - gt_pos[k, 2]
            t_sum += x0 * x0 + x1 * x1 + x2 * x2
            cos = 0.5 * (rel[k, 0] * q00 + rel[k, 1] * q10 + rel[k, 2] * q20
                         + rel[k, 3] * q01 + rel[k, 4] * q11 + rel[k, 5] * q21
                         + rel[k, 6] * q02 + rel[k, 7] * q12 + rel[k, 8] * q22 - 1.0)
            r_sum += _angle_sq(cos)
        out_t[r] = np.sqrt(t_sum / n)
        out_r[r] = np.degrees(np.sqrt(r_sum / n))


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
        r_al, t_al, scale, degenerate = umeyama_batch(
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

    @cached_property
    def _kernel_inputs(self) -> tuple[np.ndarray, ...]:
        """What ``_draw_kernel`` reads, contiguous: the first estimated pose, the GT steps
        ``G_k^-1 G_k+1``, rotations and positions, the step errors. Of the steps and errors
        only the upper 3 x 4 (fewer cache lines where each block jumps to another error)."""
        gt = self.gt
        return (np.ascontiguousarray(self.est[0]),
                np.ascontiguousarray((inverse_se3(gt[:-1]) @ gt[1:])[:, :3, :]),
                np.ascontiguousarray(gt[:, :3, :3]), np.ascontiguousarray(gt[:, :3, 3]),
                np.ascontiguousarray(self.errors[:, :3, :]))

    def draws(self, block: int, reps: int = REPS, seed: int = 0) -> dict[str, np.ndarray]:
        """{quantity: (reps,) RMSE} of the trajectories re-chained from ``block``-step blocks
        of the step errors (seeded: two estimates of the same frames draw the same blocks).
        One resample at a time in a compiled kernel (``_draw_kernel``): memory is one path,
        whatever the number of resamples; a resample whose positions do not fix the alignment
        is aligned by its orientations (as ``metrics.ape.align``)."""
        key = (int(block), int(reps), int(seed))
        if key not in self._draws:
            n = len(self.gt)
            b = max(1, int(block))
            first, gt_steps, gt_rot, gt_pos, errors = self._kernel_inputs
            a = Alignment.parse(self.alignment)
            m_fit = n if a.first_n is None else min(a.first_n, n)
            out_t, out_r = np.empty(reps), np.empty(reps)
            buffers = queue.SimpleQueue()  # one path's buffers per thread at work

            def chunk(c0: int, starts: np.ndarray) -> None:
                c = len(starts)
                try:
                    pos, rel = buffers.get_nowait()
                except queue.Empty:
                    pos, rel = np.empty((n, 3)), np.empty((n, 9))
                _draw_kernel(first, gt_steps, gt_rot, gt_pos, errors, starts, b,
                             _KIND_CODE[a.kind], m_fit, out_t[c0:c0 + c], out_r[c0:c0 + c],
                             pos, rel)
                buffers.put((pos, rel))

            chunks = block_start_chunks(n - 1, b, reps, seed)
            if _threads <= 1:
                for c0, starts in chunks:
                    chunk(c0, starts)
            else:  # the kernel releases the GIL: chunks of resamples on several cores, as
                # many at a time as threads (the block starts of the others not yet drawn)
                with ThreadPoolExecutor(_threads) as pool:
                    while batch := list(itertools.islice(chunks, _threads)):
                        for done in [pool.submit(chunk, c0, starts) for c0, starts in batch]:
                            done.result()
            self._draws[key] = {"trans_m": out_t, "rot_deg": out_r}
        return self._draws[key]


def draws_batched(drift: Drift, block: int, reps: int = REPS, seed: int = 0
                  ) -> dict[str, np.ndarray]:
    """:meth:`Drift.draws` the straightforward way (the reference the kernel is tested
    against): ``CHUNK`` resamples' paths chained together, then aligned and scored by
    :func:`ape_rmse_batch`."""
    gt, n = drift.gt, len(drift.gt)
    gt_steps = inverse_se3(gt[:-1]) @ gt[1:]
    gt_rot = np.ascontiguousarray(gt[:, :3, :3])
    out = {q: np.empty(reps) for q in QUANTITIES}
    for c0, rows in block_index_chunks(n - 1, block, reps, seed, CHUNK):
        pos, rel = np.empty((len(rows), n, 3)), np.empty((len(rows), n, 3, 3))
        _chain_kernel(drift.est[0], gt_steps, gt_rot, drift.errors, rows, pos, rel)
        t_rmse, r_rmse = ape_rmse_batch(gt, pos, rel, drift.alignment)
        out["trans_m"][c0:c0 + len(rows)] = t_rmse
        out["rot_deg"][c0:c0 + len(rows)] = r_rmse
    return out


def ape_intervals(drift: Drift, level: float = LEVEL, reps: int = REPS, seed: int = 0,
                  block: int | None = None) -> dict[str, Interval]:
    """{"trans_m", "rot_deg"}: the interval of the long-run APE RMSE (module docstring),
    NaN with fewer than two whole blocks or a non-finite estimate."""
    if not drift.usable:
        return {q: Interval(math.nan, math.nan, level, 0, 0) for q in QUANTITIES}
    n_steps = len(drift.errors)
    if block is None:
        block = max(1, min(math.ceil(_iv.BLOCK_FACTOR * drift_block([drift.errors])),
                           max(1, n_steps // 2)))
    block = int(block)
    n_ind = n_steps // block
    out = {}
    for q in QUANTITIES:
        lo, hi = math.nan, math.nan
        if n_ind >= MIN_INDEPENDENT:
            x = drift.observed[q]
            lo, hi = _pivot(x, drift.draws(block, reps, seed)[q], level)
            lo, hi = contain(x, *widen(x, lo, hi, n_ind, level, True))
            lo = max(0.0, lo)  # an RMSE
        out[q] = Interval(lo, hi, level, block, n_ind)
    return out


def paired_ape_interval(a: Drift, b: Drift, quantity: str = "trans_m", level: float = LEVEL,
                        reps: int = REPS, seed: int = 0, block: int | None = None) -> Interval:
    """The interval of ``APE(a) - APE(b)`` (``quantity``'s RMSE) of two estimates of the same
    frames (``Drift.same_frames``), both resampled with the same blocks, widened for the
    independent blocks (``metrics.intervals.widen``). For a notebook comparing two estimates;
    the tables' marks read each figure's own printed interval."""
    if not (a.usable and b.usable and a.same_frames(b)):
        return Interval(math.nan, math.nan, level, 0, 0)
    block = drift_block([a.errors, b.errors]) if block is None else int(block)
    n_ind = len(a.errors) // block
    diff = a.observed[quantity] - b.observed[quantity]
    lo, hi = _pivot(diff, a.draws(block, reps, seed)[quantity]
                    - b.draws(block, reps, seed)[quantity], level)
    lo, hi = widen(diff, lo, hi, n_ind, level)
    return Interval(lo, hi, level, block, n_ind)
