"""The compiled inner step of point-to-plane ICP (``methods.gicp.PointToPlaneIcp``).

``normal_equations`` accumulates the Gauss-Newton system of the point-to-plane residuals in one
pass over the paired source points (no (M, 6) Jacobian array, no gathers):
r_i = n_i . (q_i - p_i), J_i = [n_i, p_i x n_i]; H = sum J_i^T J_i, b = sum J_i^T r_i (an
update exp(xi) on the left, xi = (rho, phi): p_i + rho + phi x p_i gives r_i - J_i . xi; the
step is xi = H^-1 b). tests/test_gicp.py checks it against a NumPy version of the same sums.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from methods.dicp_kernel import transform  # the iterations' point transform (shared)


@nb.njit(cache=True, nogil=True)
def normal_equations(moved, idx, target, normals):  # pragma: no cover - compiled
    """(H (6, 6), b (6,), pairs) over the rows of ``moved`` (M, 3) paired with ``target`` /
    ``normals`` rows ``idx`` (M,; -1: no pair)."""
    H = np.zeros((6, 6))
    b = np.zeros(6)
    J = np.empty(6)
    pairs = 0
    for i in range(moved.shape[0]):
        k = idx[i]
        if k < 0:
            continue
        px, py, pz = moved[i, 0], moved[i, 1], moved[i, 2]
        nx, ny, nz = normals[k, 0], normals[k, 1], normals[k, 2]
        r = nx * (target[k, 0] - px) + ny * (target[k, 1] - py) + nz * (target[k, 2] - pz)
        J[0], J[1], J[2] = nx, ny, nz
        J[3] = py * nz - pz * ny
        J[4] = pz * nx - px * nz
        J[5] = px * ny - py * nx
        for a in range(6):
            b[a] += J[a] * r
            for c in range(a, 6):
                H[a, c] += J[a] * J[c]
        pairs += 1
    for a in range(6):
        for c in range(a):
            H[a, c] = H[c, a]
    return H, b, pairs


@nb.njit(cache=True, nogil=True)
def solve_update(H, b, T):  # pragma: no cover - compiled
    """(exp(xi) T (4, 4), xi (6,)) with xi = H^-1 b, the Gauss-Newton step (xi = (rho, phi):
    translation then rotation vector; ``loaders.se3.exp_se3``'s closed form: Rodrigues for
    the rotation, the left Jacobian of SO(3) for the translation); (T, NaNs) when H is singular
    or the step is not finite. One compiled call instead of a LAPACK solve, SciPy's rotation
    and five small NumPy products per iteration."""
    xi = np.full(6, np.nan)
    try:
        x = np.linalg.solve(H, b)
    except Exception:  # noqa: BLE001 - numba raises a plain exception for a singular matrix
        return T, xi
    for k in range(6):
        if not np.isfinite(x[k]):
            return T, xi
        xi[k] = x[k]
    wx, wy, wz = xi[3], xi[4], xi[5]
    theta2 = wx * wx + wy * wy + wz * wz
    theta = np.sqrt(theta2)
    K = np.array([[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]])
    K2 = K @ K
    if theta < 1e-9:  # to first order: R = I + K, V = I + K / 2
        R = np.eye(3) + K
        V = np.eye(3) + 0.5 * K
    else:
        sin_t, one_cos = np.sin(theta) / theta, (1.0 - np.cos(theta)) / theta2
        R = np.eye(3) + sin_t * K + one_cos * K2
        V = np.eye(3) + one_cos * K + (theta - np.sin(theta)) / (theta2 * theta) * K2
    step = np.eye(4)
    step[:3, :3] = R
    for r in range(3):
        step[r, 3] = V[r, 0] * xi[0] + V[r, 1] * xi[1] + V[r, 2] * xi[2]
    return step @ T, xi


def warm_up() -> None:
    """Compile (or load from numba's cache) before any timed call."""
    pts = np.zeros((2, 3))
    normal_equations(transform(np.eye(4), pts), np.array([0, -1]), pts, pts)
    solve_update(np.eye(6), np.full(6, 1e-3), np.eye(4))
    solve_update(np.eye(6), np.zeros(6), np.eye(4))
    solve_update(np.zeros((6, 6)), np.zeros(6), np.eye(4))
