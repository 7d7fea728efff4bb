"""Closed-form rigid fit (Arun / Umeyama without scale) shared by the point-to-point methods."""

from __future__ import annotations

import numba as nb
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
        return rigid_from_sums(n, source_t.sum(axis=1), target_t.sum(axis=1),
                               source_t @ target_t.T)
    else:
        w = np.asarray(weights, dtype=np.float64)
        w_sum = w.sum()
        if not w_sum > 0:
            return None
        mu_p = source_t @ w / w_sum
        mu_q = target_t @ w / w_sum
        H = (source_t * w) @ target_t.T - w_sum * np.outer(mu_p, mu_q)
    return _rigid_from_cross_covariance(H, mu_p, mu_q)


def rigid_from_sums(n: int, sum_p: np.ndarray, sum_q: np.ndarray, sum_pq: np.ndarray
                    ) -> np.ndarray | None:
    """The fit from the sums over n pairs: sum p, sum q (3,) and sum p q^T (3, 3)."""
    if n < 3:
        return None
    mu_p, mu_q = sum_p / n, sum_q / n
    return _rigid_from_cross_covariance(sum_pq - n * np.outer(mu_p, mu_q), mu_p, mu_q)


@nb.njit(cache=True)
def rigid_update_from_sums(n, sum_p, sum_q, sum_pq, T):  # pragma: no cover - compiled
    """(delta T, True) with delta ``rigid_from_sums``' fit of the pair sums, or (T, False) where
    that returns None: the same algorithm compiled, for a loop that fits once per iteration
    (icp-p2p: one call instead of NumPy's small-array overhead, about 30 us). The NumPy version
    stays for the others: doppler reproduces the reference notebook with NumPy's LAPACK."""
    if n < 3:
        return T, False
    mu_p, mu_q = sum_p / n, sum_q / n
    H = sum_pq - n * np.outer(mu_p, mu_q)
    U, S, Vt = np.linalg.svd(H)
    if not (np.isfinite(S[0]) and np.isfinite(S[1]) and np.isfinite(S[2])) or S[0] <= 0 \
            or S[1] < _DEGENERATE_RATIO * S[0]:
        return T, False
    D = np.eye(3)
    det = np.linalg.det(Vt.T @ U.T)
    D[2, 2] = 1.0 if det >= 0 else -1.0
    R = Vt.T @ D @ U.T
    delta = np.eye(4)
    delta[:3, :3] = R
    delta[:3, 3] = mu_q - R @ mu_p
    return delta @ T, True


def _rigid_from_cross_covariance(H: np.ndarray, mu_p: np.ndarray, mu_q: np.ndarray
                                 ) -> np.ndarray | None:
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
