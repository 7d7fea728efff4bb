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

from methods.kdtree import _STACK, _search_sorted


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


@nb.njit(cache=True, nogil=True)
def _smallest_eigenvector(c00, c01, c02, c11, c12, c22, out):  # pragma: no cover - compiled
    """The unit eigenvector of the smallest eigenvalue of the symmetric 3x3 matrix C, into
    ``out``: in closed form (the eigenvalue from the trigonometric solution of the
    characteristic polynomial, the vector as the longest cross product of two rows of
    C - lambda I), or by LAPACK's ``eigh`` when the closed form is ill-conditioned (the two
    smallest eigenvalues nearly equal, or C nearly a multiple of I)."""
    scale = max(abs(c00), abs(c01), abs(c02), abs(c11), abs(c12), abs(c22))
    if scale > 0.0:
        a00, a01, a02 = c00 / scale, c01 / scale, c02 / scale
        a11, a12, a22 = c11 / scale, c12 / scale, c22 / scale
        q = (a00 + a11 + a22) / 3.0
        b00, b11, b22 = a00 - q, a11 - q, a22 - q
        p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)
        if p2 > 1e-12:
            p = np.sqrt(p2 / 6.0)
            det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
                   + a02 * (a01 * a12 - b11 * a02))
            r = det / (2.0 * p * p * p)
            r = min(max(r, -1.0), 1.0)
            lam = q + 2.0 * p * np.cos(np.arccos(r) / 3.0 + 2.0 * np.pi / 3.0)
            r0x, r0y, r0z = a00 - lam, a01, a02
            r1x, r1y, r1z = a01, a11 - lam, a12
            r2x, r2y, r2z = a02, a12, a22 - lam
            ax, ay, az = r0y * r1z - r0z * r1y, r0z * r1x - r0x * r1z, r0x * r1y - r0y * r1x
            bx, by, bz = r0y * r2z - r0z * r2y, r0z * r2x - r0x * r2z, r0x * r2y - r0y * r2x
            cx, cy, cz = r1y * r2z - r1z * r2y, r1z * r2x - r1x * r2z, r1x * r2y - r1y * r2x
            na = ax * ax + ay * ay + az * az
            nb_ = bx * bx + by * by + bz * bz
            nc = cx * cx + cy * cy + cz * cz
            if nb_ > na and nb_ >= nc:
                ax, ay, az, na = bx, by, bz, nb_
            elif nc > na:
                ax, ay, az, na = cx, cy, cz, nc
            # |cross|^2 is the product of the other two eigenvalues' gaps squared (scaled C):
            # well above rounding, the closed form is accurate to ~1e-12
            if na > 1e-10:
                inv = 1.0 / np.sqrt(na)
                out[0], out[1], out[2] = ax * inv, ay * inv, az * inv
                return
    C = np.empty((3, 3))
    C[0, 0], C[0, 1], C[0, 2] = c00, c01, c02
    C[1, 0], C[1, 1], C[1, 2] = c01, c11, c12
    C[2, 0], C[2, 1], C[2, 2] = c02, c12, c22
    _, vectors = np.linalg.eigh(C)
    out[0], out[1], out[2] = vectors[0, 0], vectors[1, 0], vectors[2, 0]


@nb.njit(cache=True, nogil=True)
def _normal(points, neighbours, sq_dists, count, radius_sq, out):  # pragma: no cover
    """The normal of one neighbourhood: ``neighbours[:count]`` (indices into points, -1 for
    none) with ``sq_dists``; those within the radius count. Fewer than 3 of them, or all at
    one place: (0, 0, 1), as Open3D's ``EstimateNormals`` gives (its covariance is then the
    identity, or zero, and it falls back to +z), so such a target point still constrains the
    height of a pair (a zero normal left it out, and the two implementations' steps differed
    whenever a source point paired with an isolated far target point)."""
    m = 0
    mx = my = mz = 0.0
    for k in range(count):
        j = neighbours[k]
        if j >= 0 and sq_dists[k] <= radius_sq:
            mx += points[j, 0]
            my += points[j, 1]
            mz += points[j, 2]
            m += 1
    out[0] = out[1] = 0.0
    out[2] = 1.0
    if m < 3:
        return
    mx /= m
    my /= m
    mz /= m
    c00 = c01 = c02 = c11 = c12 = c22 = 0.0
    for k in range(count):
        j = neighbours[k]
        if j >= 0 and sq_dists[k] <= radius_sq:
            dx, dy, dz = points[j, 0] - mx, points[j, 1] - my, points[j, 2] - mz
            c00 += dx * dx
            c01 += dx * dy
            c02 += dx * dz
            c11 += dy * dy
            c12 += dy * dz
            c22 += dz * dz
    if c00 == 0.0 and c11 == 0.0 and c22 == 0.0:
        return  # every neighbour at one place: no plane (Open3D: +z too)
    _smallest_eigenvector(c00 / m, c01 / m, c02 / m, c11 / m, c12 / m, c22 / m, out)


@nb.njit(cache=True, nogil=True)
def normals_from_neighbours(points, neighbours, sq_dists, radius_sq):  # pragma: no cover
    """Unit normals: the smallest-eigenvalue eigenvector of the covariance of each point's
    neighbours within the radius ((0, 0, 1) when fewer than 3, as Open3D); neighbours (N, k),
    -1 for none."""
    n = points.shape[0]
    normals = np.zeros((n, 3))
    for i in range(n):
        _normal(points, neighbours[i], sq_dists[i], neighbours.shape[1], radius_sq,
                normals[i])
    return normals


@nb.njit(cache=True, nogil=True)
def neighbourhood_normals(pts, perm, lo, hi, dim, split, left, right, k, radius_sq
                          ):  # pragma: no cover - compiled
    """``normals_from_neighbours`` of a kd-tree's own points (``methods.kdtree`` arrays) with
    their k nearest neighbours within the radius, searched here: points are visited in tree
    order (consecutive searches touch the same leaves) and each search starts bounded by its
    predecessor's k neighbours (k distinct points: the k-th nearest is no farther than the
    farthest of them), which prunes most of the tree. Normals in the original point order."""
    n = pts.shape[0]
    normals = np.zeros((n, 3))
    st_node = np.empty(_STACK, dtype=np.int64)
    st_lb = np.empty(_STACK)
    st_off = np.empty((_STACK, 3))
    out_sq = np.empty(k)
    out_pos = np.empty(k, dtype=np.int64)
    bound_all = np.nextafter(radius_sq, np.inf)  # within the radius, inclusive
    count = 0
    for p in range(n):
        qx, qy, qz = pts[p, 0], pts[p, 1], pts[p, 2]
        bound = bound_all
        if count == k:  # the last search's k neighbours bound this one
            far = 0.0
            for j in range(k):
                o = out_pos[j]
                dx, dy, dz = pts[o, 0] - qx, pts[o, 1] - qy, pts[o, 2] - qz
                far = max(far, dx * dx + dy * dy + dz * dz)
            bound = min(bound_all, np.nextafter(far, np.inf))
        count = _search_sorted(pts, lo, hi, dim, split, left, right, qx, qy, qz, k, bound,
                               out_sq, out_pos, st_node, st_lb, st_off)
        _normal(pts, out_pos, out_sq, count, radius_sq, normals[perm[p]])
    return normals


@nb.njit(cache=True, nogil=True)
def pair_bounds(moved, target, idx, gate_sq):  # pragma: no cover - compiled
    """Per moved point, a bound (squared, exclusive) on its nearest target point within the
    gate (inclusive): just above its distance to its last pair ``idx`` (None or -1: the gate),
    never above the gate."""
    n = moved.shape[0]
    gate = np.nextafter(gate_sq, np.inf)
    bounds = np.full(n, gate)
    if idx is None:
        return bounds
    for i in range(n):
        j = idx[i]
        if j >= 0:
            d2 = 0.0
            for a in range(3):
                d2 += (moved[i, a] - target[j, a]) ** 2
            bounds[i] = min(gate, np.nextafter(d2, np.inf))
    return bounds
