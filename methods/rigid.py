"""Closed-form rigid fit (Arun / Umeyama without scale) shared by the point-to-point methods."""

from __future__ import annotations

import numpy as np

# the second singular value below this fraction of the first: points (nearly) collinear
_DEGENERATE_RATIO = 1e-9


def fit_rigid(
    source: np.ndarray, target: np.ndarray, weights: np.ndarray | None = None
) -> np.ndarray | None:
    """``T_target_source`` minimising sum w_i |q_i - (R p_i + t)|^2, or None when degenerate.

    source, target: (N, 3) corresponding points. The SVD solution is guarded against
    reflections (det(R) = +1). Fewer than 3 pairs, zero total weight or collinear points give
    None.
    """
    return fit_rigid_t(np.ascontiguousarray(source.T), np.ascontiguousarray(target.T), weights)


def fit_rigid_t(
    source_t: np.ndarray, target_t: np.ndarray, weights: np.ndarray | None = None
) -> np.ndarray | None:
    """``fit_rigid`` for points given as (3, N) arrays (contiguous rows: fast sums)."""
    n = source_t.shape[1]
    if n < 3:
        return None
    if weights is None:
        mu_p = source_t.sum(axis=1) / n
        mu_q = target_t.sum(axis=1) / n
        H = source_t @ target_t.T - n * np.outer(mu_p, mu_q)
    else:
        w = np.asarray(weights, dtype=np.float64)
        w_sum = w.sum()
        if not w_sum > 0:
            return None
        mu_p = source_t @ w / w_sum
        mu_q = target_t @ w / w_sum
        H = (source_t * w) @ target_t.T - w_sum * np.outer(mu_p, mu_q)
    U, S, Vt = np.linalg.svd(H)
    if not np.all(np.isfinite(S)) or S[0] <= 0 or S[1] < _DEGENERATE_RATIO * S[0]:
        return None
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = mu_q - R @ mu_p
    return T
