"""Compiled parts of DICP: target normals and the Gauss-Newton normal equations.

The normal equations follow the authors' implementation in Open3D
(``ComputePoseDopplerICP``): per source point with a geometric pair, a point-to-plane residual
r_G = sqrt(1 - lambda) n . (p - q) with Jacobian sqrt(1 - lambda) [p x n, n], and a Doppler
residual r_D = sqrt(lambda) (doppler - doppler_pred) with Jacobian
sqrt(lambda) / period [d x r_vs, -d] (d: the point's direction attribute, r_vs: the lever arm),
doppler_pred = -(R_sv d) . v_s (R_sv: the extrinsic's inverse rotation, v_s: the predicted
sensor velocity in sensor axes); each weighted by a Tukey kernel on the scaled residual (or 1
before the kernel's first iteration).
The unknowns are (rotation x, y, z, translation x, y, z), as in Open3D.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def _tukey(r: float, k: float) -> float:  # pragma: no cover - compiled
    if k <= 0.0:
        return 1.0  # plain least squares
    if abs(r) > k:
        return 0.0
    u = 1.0 - (r / k) ** 2
    return u * u


@nb.njit(cache=True)
def normal_equations(points, idx, target_points, target_normals, dopplers, directions,
                     R_sv, v_sensor, lever_arm, period, lam, k_geometric, k_doppler,
                     reject, reject_mps):  # pragma: no cover - compiled
    """(A 6x6, b 6) of one DICP step over the source points with a pair (idx >= 0)."""
    A = np.zeros((6, 6))
    b = np.zeros(6)
    s_g = np.sqrt(1.0 - lam)
    s_d = np.sqrt(lam)
    s_dt = s_d / period
    JG = np.empty(6)
    JD = np.empty(6)
    for i in range(points.shape[0]):
        j = idx[i]
        if j < 0:
            continue
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        pred = 0.0
        for a in range(3):
            pred -= (R_sv[a, 0] * dx + R_sv[a, 1] * dy + R_sv[a, 2] * dz) * v_sensor[a]
        err_d = dopplers[i] - pred
        if reject and abs(err_d) > reject_mps:
            continue  # a dynamic point: neither residual (as upstream)
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        nx, ny, nz = target_normals[j, 0], target_normals[j, 1], target_normals[j, 2]
        r_g = s_g * ((px - target_points[j, 0]) * nx + (py - target_points[j, 1]) * ny
                     + (pz - target_points[j, 2]) * nz)
        JG[0] = s_g * (py * nz - pz * ny)
        JG[1] = s_g * (pz * nx - px * nz)
        JG[2] = s_g * (px * ny - py * nx)
        JG[3], JG[4], JG[5] = s_g * nx, s_g * ny, s_g * nz
        rx, ry, rz = lever_arm[0], lever_arm[1], lever_arm[2]
        JD[0] = s_dt * (dy * rz - dz * ry)
        JD[1] = s_dt * (dz * rx - dx * rz)
        JD[2] = s_dt * (dx * ry - dy * rx)
        JD[3], JD[4], JD[5] = -s_dt * dx, -s_dt * dy, -s_dt * dz
        r_d = s_d * err_d
        w_g = _tukey(r_g, k_geometric)
        w_d = _tukey(r_d, k_doppler)
        for a in range(6):
            b[a] += JG[a] * w_g * r_g + JD[a] * w_d * r_d
            for c in range(a + 1):
                A[a, c] += JG[a] * w_g * JG[c] + JD[a] * w_d * JD[c]
    for a in range(6):
        for c in range(a):
            A[c, a] = A[a, c]
    return A, b


@nb.njit(cache=True)
def transform(T, points):  # pragma: no cover - compiled
    """T applied to (N, 3) points in a plain loop (NumPy's matmul goes through BLAS, whose
    threads slow it up to 40x when the cores are busy); shared with doppler-icp."""
    out = np.empty_like(points)
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for a in range(3):
            out[i, a] = T[a, 0] * x + T[a, 1] * y + T[a, 2] * z + T[a, 3]
    return out


@nb.njit(cache=True)
def normals_from_neighbours(points, neighbours, sq_dists, radius_sq):  # pragma: no cover
    """Unit normals: the smallest-eigenvalue eigenvector of the covariance of each point's
    neighbours within the radius (zero when fewer than 3)."""
    n = points.shape[0]
    normals = np.zeros((n, 3))
    for i in range(n):
        m = 0
        mean = np.zeros(3)
        for k in range(neighbours.shape[1]):
            j = neighbours[i, k]
            if j >= 0 and sq_dists[i, k] <= radius_sq:
                mean += points[j]
                m += 1
        if m < 3:
            continue
        mean /= m
        C = np.zeros((3, 3))
        for k in range(neighbours.shape[1]):
            j = neighbours[i, k]
            if j >= 0 and sq_dists[i, k] <= radius_sq:
                d = points[j] - mean
                C += np.outer(d, d)
        _, vectors = np.linalg.eigh(C / m)
        normals[i] = vectors[:, 0]
    return normals
