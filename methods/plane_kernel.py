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
def transform(T, points):  # pragma: no cover - compiled
    """``points`` (N, 3) moved by the 4x4 ``T``."""
    out = np.empty_like(points)
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for a in range(3):
            out[i, a] = T[a, 0] * x + T[a, 1] * y + T[a, 2] * z + T[a, 3]
    return out


def warm_up() -> None:
    """Compile (or load from numba's cache) before any timed call."""
    pts = np.zeros((2, 3))
    normal_equations(transform(np.eye(4), pts), np.array([0, -1]), pts, pts)
