"""Compiled inner loop of Doppler Correspondence (numba), same answer as the NumPy reference.

Algorithm 2 is: features f, g; nearest g for every f; two masks; one rigid fit. Here NumPy's
SIMD integer sort orders both feature arrays (float32 order key + index packed in a uint64),
and one compiled pass walks the two sorted arrays together (a merge: the nearest g of each f is
one of the two g's around it), applies both masks and accumulates the sums the rigid fit needs,
so no intermediate array is made. Ties follow ``methods.doppler.nearest_1d``.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def features(points_t, doppler, dt_s, sign):
    """|p|^2 + sign |p| v dT (float32) for (3, N) float32 points."""
    n = points_t.shape[1]
    out = np.empty(n, dtype=np.float32)
    for i in range(n):
        x, y, z = points_t[0, i], points_t[1, i], points_t[2, i]
        r2 = x * x + y * y + z * z
        out[i] = r2 + sign * np.sqrt(r2) * doppler[i] * dt_s
    return out


@nb.njit(cache=True)
def sort_keys(values):
    """uint64 keys whose order is the float32 order of ``values`` (ties by index): the float's
    order-preserving bits in the high half, the index in the low half. Sort them with NumPy."""
    bits = values.view(np.uint32)
    keys = np.empty(len(values), dtype=np.uint64)
    for i in range(len(values)):
        b = bits[i]
        k = ~b if b >> np.uint32(31) else b | np.uint32(0x80000000)
        keys[i] = (np.uint64(k) << np.uint64(32)) | np.uint64(i)
    return keys


def sorted_keys(values: np.ndarray) -> np.ndarray:
    keys = sort_keys(values)
    keys.sort()  # NumPy's SIMD sort of unsigned integers
    return keys


@nb.njit(cache=True)
def _gather_sorted(points_t, values, keys):
    """Points and values in key order, as contiguous arrays (simple loops: misses overlap)."""
    n = len(keys)
    order = np.empty(n, dtype=np.int64)
    vals = np.empty(n, dtype=np.float32)
    pts = np.empty((3, n), dtype=np.float32)
    for i in range(n):
        order[i] = np.int64(keys[i] & np.uint64(0xFFFFFFFF))
    for i in range(n):
        vals[i] = values[order[i]]
    for a in range(3):
        row = points_t[a]
        for i in range(n):
            pts[a, i] = row[order[i]]
    return pts, vals


@nb.njit(cache=True)
def match_and_accumulate(p_t, f, f_keys, q_t, g, g_keys, tau_spatial2, tau_doppler):
    """Nearest g for every f (a merge of the two sorted orders), masks, and the fit's sums.

    ``f_keys`` / ``g_keys``: sorted keys from ``sorted_keys``. Returns (n, sum_p (3,),
    sum_q (3,), sum_pq (3, 3)) in float64 over the kept pairs.
    """
    ps, fs = _gather_sorted(p_t, f, f_keys)
    qs, gs = _gather_sorted(q_t, g, g_keys)
    m = len(gs)
    sum_p = np.zeros(3)
    sum_q = np.zeros(3)
    sum_pq = np.zeros((3, 3))
    n = 0
    j = 0  # number of g values <= the current f
    for i in range(len(fs)):
        fi = fs[i]
        while j < m and gs[j] <= fi:
            j += 1
        if j == 0:
            k = 0
        elif j == m:
            k = m - 1
        else:
            k = j if gs[j] - fi < fi - gs[j - 1] else j - 1
        if abs(fi - gs[k]) > tau_doppler:
            continue
        dx = ps[0, i] - qs[0, k]
        dy = ps[1, i] - qs[1, k]
        dz = ps[2, i] - qs[2, k]
        if dx * dx + dy * dy + dz * dz > tau_spatial2:
            continue
        n += 1
        for a in range(3):
            pa = np.float64(ps[a, i])
            sum_p[a] += pa
            sum_q[a] += qs[a, k]
            for b in range(3):
                sum_pq[a, b] += pa * qs[b, k]
    return n, sum_p, sum_q, sum_pq


def warm_up() -> None:
    """Compile (or load from the cache) once, so no timed call pays for it."""
    pts = np.ones((3, 4), dtype=np.float32) + np.arange(4, dtype=np.float32)
    dop = np.zeros(4, dtype=np.float32)
    f = features(pts, dop, 0.1, 1.0)
    keys = sorted_keys(f)
    match_and_accumulate(pts, f, keys, pts, f, keys, 9.0, 5.0)
