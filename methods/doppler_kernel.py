"""Compiled inner loop of Doppler Correspondence (numba), same answer as the NumPy reference.

Algorithm 2 is: features f, g; nearest g for every f; two masks; one rigid fit. Here a radix
sort orders both feature arrays (float32 order key + index packed in a uint64: the order of
NumPy's sort of the same keys),
and one compiled pass walks the two sorted arrays together (a merge: the nearest g of each f is
one of the two g's around it) and applies both masks in float32 as the reference does, noting
each f's kept partner in a reused int32 scratch; a second pass accumulates the sums the rigid
fit needs (vectorised: reassociated float64 sums). Ties follow ``methods.doppler.nearest_1d``.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def features(points_t, doppler, dt_s, sign):
    """|p|^2 + sign |p| v dT (float32) for (3, N) float32 points."""
    out = np.empty(points_t.shape[1], dtype=np.float32)
    features_into(points_t, doppler, dt_s, sign, out)
    return out


@nb.njit(cache=True, nogil=True)
def features_into(points_t, doppler, dt_s, sign, out):
    for i in range(points_t.shape[1]):
        x, y, z = points_t[0, i], points_t[1, i], points_t[2, i]
        r2 = x * x + y * y + z * z
        out[i] = r2 + sign * np.sqrt(r2) * doppler[i] * dt_s


@nb.njit(cache=True, nogil=True)
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


@nb.njit(cache=True, nogil=True, inline="always")
def _bucket_starts(c):  # pragma: no cover - compiled
    """The 2048 digit counts ``c`` turned, in place, into each bucket's first position."""
    start = 0
    for b in range(2048):
        count = c[b]
        c[b] = start
        start += count


@nb.njit(cache=True, nogil=True, inline="always")
def _radix_pass(src, dst, c, p):  # pragma: no cover - compiled
    """One stable pass on digit ``p`` (11 bits of the high half, from bit 32 + 11 p): each key
    of ``src`` to its bucket's next position in ``dst`` (``c``: the buckets' starts)."""
    shift = np.uint64(32 + 11 * p)
    for i in range(len(src)):
        k = src[i]
        b = (k >> shift) & np.uint64(0x7FF)
        dst[c[b]] = k
        c[b] += 1


@nb.njit(cache=True, nogil=True)
def radix_sort_high32(keys):
    """``keys`` sorted by their high 32 bits, stably (equal high halves keep their input
    order): an LSD radix sort in three passes of 11, 11 and 10 bits, one counting pass for all
    three; a pass whose digit is the same for every key is skipped. For the keys of
    ``sort_keys`` (index in the low half, so every key is distinct and the input is in index
    order) the result is exactly ``np.sort(keys)``, 6-8x faster at 64k keys."""
    n = len(keys)
    counts = np.zeros((3, 2048), dtype=np.int64)
    for i in range(n):
        h = keys[i] >> np.uint64(32)
        counts[0, h & np.uint64(0x7FF)] += 1
        counts[1, (h >> np.uint64(11)) & np.uint64(0x7FF)] += 1
        counts[2, h >> np.uint64(22)] += 1
    src = keys.copy()
    dst = np.empty_like(keys)
    for p in range(3):
        c = counts[p]
        if n == 0 or c.max() == n:
            continue  # one digit value: the pass would not move anything
        _bucket_starts(c)
        _radix_pass(src, dst, c, p)
        src, dst = dst, src
    return src


@nb.njit(cache=True, nogil=True)
def sorted_keys(values):
    """``sort_keys(values)`` in ascending order (the float32 order of ``values``, ties by
    index)."""
    return radix_sort_high32(sort_keys(values))


@nb.njit(cache=True, nogil=True)
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


@nb.njit(cache=True, nogil=True)
def sorted_scan(points_t, doppler, dt_s, sign):
    """One scan's half of the step: its features (as ``features``) and its points, both in the
    features' float32 order with ties by index (the order of ``sorted_keys``): (pts (3, N),
    vals (N,)), float32. Releases the GIL: the source's and the target's halves can run on two
    threads."""
    n = points_t.shape[1]
    pts = np.empty((3, n), dtype=np.float32)
    vals = np.empty(n, dtype=np.float32)
    sorted_scan_into(points_t, doppler, dt_s, sign, np.empty(n, dtype=np.float32),
                     np.empty(n, dtype=np.uint64), np.empty(n, dtype=np.uint64), pts, vals)
    return pts, vals


@nb.njit(cache=True, nogil=True)
def sorted_scan_into(points_t, doppler, dt_s, sign, values, keys, spare, pts, vals):
    """``sorted_scan`` into caller-owned arrays of N elements (scratch: ``values`` float32,
    ``keys`` and ``spare`` uint64; out: ``pts`` (3, N) and ``vals`` float32), so that repeated
    calls touch no fresh memory (page faults cost as much as the sort). The radix sort of
    ``radix_sort_high32``, then one sequential pass that writes the values (decoded from the
    sorted keys' high halves) and gathers the points. The step is memory-bound: scattering
    the points themselves in the last radix pass (4 arrays x 2048 buckets of scattered
    writes) measured 15 % slower in the whole step than this in-order gather."""
    n = points_t.shape[1]
    bits = values.view(np.uint32)
    counts = np.zeros((3, 2048), dtype=np.int64)
    for i in range(n):  # features, the keys of ``sort_keys`` and the passes' digit counts
        x, y, z = points_t[0, i], points_t[1, i], points_t[2, i]
        r2 = x * x + y * y + z * z
        values[i] = r2 + sign * np.sqrt(r2) * doppler[i] * dt_s  # as ``features_into``
        b = bits[i]
        h = ~b if b >> np.uint32(31) else b | np.uint32(0x80000000)
        keys[i] = (np.uint64(h) << np.uint64(32)) | np.uint64(i)
        counts[0, h & np.uint32(0x7FF)] += 1
        counts[1, (h >> np.uint32(11)) & np.uint32(0x7FF)] += 1
        counts[2, h >> np.uint32(22)] += 1
    passes = [p for p in range(3) if n and counts[p].max() != n]
    src = keys
    dst = spare
    for p in passes:  # none when every key has the same high half: index order is the order
        _bucket_starts(counts[p])
        _radix_pass(src, dst, counts[p], p)
        src, dst = dst, src
    out_bits = vals.view(np.uint32)
    for i in range(n):  # in sorted order: the value from the key, the point by its index
        k = src[i]
        h = np.uint32(k >> np.uint64(32))
        out_bits[i] = h ^ np.uint32(0x80000000) if h >> np.uint32(31) else ~h
        j = np.int64(k & np.uint64(0xFFFFFFFF))
        pts[0, i] = points_t[0, j]
        pts[1, i] = points_t[1, j]
        pts[2, i] = points_t[2, j]


@nb.njit(cache=True, nogil=True)
def match_sorted(ps, fs, qs, gs, tau_spatial2, tau_doppler):
    """Nearest g for every f (a merge of the two sorted orders), masks, and the fit's sums,
    from the halves of ``sorted_scan`` (source: ps, fs; target: qs, gs). Returns (n,
    sum_p (3,), sum_q (3,), sum_pq (3, 3)) in float64 over the kept pairs."""
    return match_sorted_into(ps, fs, qs, gs, tau_spatial2, tau_doppler,
                             np.empty(len(fs), dtype=np.int32))


@nb.njit(cache=True, nogil=True)
def match_sorted_into(ps, fs, qs, gs, tau_spatial2, tau_doppler, pair):
    """``match_sorted`` with caller-owned scratch ``pair`` (int32, len(fs)): the matching
    pass (``pair_sorted``) writes each f's kept partner there, the summing pass
    (``sum_pairs``) reads it."""
    pair_sorted(ps, fs, qs, gs, tau_spatial2, tau_doppler, pair)
    return sum_pairs(ps, qs, pair)


@nb.njit(cache=True, nogil=True)
def pair_sorted(ps, fs, qs, gs, tau_spatial2, tau_doppler, pair):
    """The matching and both masks, in float32 exactly as the NumPy reference: ``pair[i]``
    the index into the sorted target of the g nearest to ``fs[i]`` (the lower one on a tie),
    or -1 when the pair fails a gate. Unsigned loop counters (no negative-index checks in
    the merge's dependent chain)."""
    m = np.uint64(len(gs))
    if m == 0:
        pair[:] = -1
        return
    one = np.uint64(1)
    zero = np.uint64(0)
    last = m - one
    j = zero  # number of g values <= the current f
    for i in range(len(fs)):
        fi = fs[i]
        while j < m and gs[j] <= fi:
            j += one
        lo = j - one if j > zero else zero
        hi = j if j < m else last
        k = hi if gs[hi] - fi < fi - gs[lo] else lo  # the nearer; the lower one on a tie
        dx, dy, dz = ps[0, i] - qs[0, k], ps[1, i] - qs[1, k], ps[2, i] - qs[2, k]
        keep = (abs(fi - gs[k]) <= tau_doppler) & (dx * dx + dy * dy + dz * dz <= tau_spatial2)
        pair[i] = np.int32(k) if keep else np.int32(-1)


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "nsz", "contract"})
def sum_pairs(ps, qs, pair):
    """(n, sum_p (3,), sum_q (3,), sum_pq (3, 3)) in float64 over the pairs (ps[:, i],
    qs[:, pair[i]]) with pair[i] >= 0. Branch-free: a dropped pair adds products with a zero
    weight (finite points assumed, as everywhere). The sums may be reassociated (vectorised):
    they differ from a sequential sum by rounding only (~1e-16 relative); which pairs count
    is decided in ``pair_sorted``, without fast math."""
    sp0 = sp1 = sp2 = sq0 = sq1 = sq2 = 0.0
    s00 = s01 = s02 = s10 = s11 = s12 = s20 = s21 = s22 = 0.0
    n = 0
    for i in range(len(pair)):
        k = pair[i]
        keep = k >= 0
        k = max(k, 0)
        w = 1.0 if keep else 0.0
        n += 1 if keep else 0
        a0 = w * np.float64(ps[0, i])
        a1 = w * np.float64(ps[1, i])
        a2 = w * np.float64(ps[2, i])
        b0, b1, b2 = np.float64(qs[0, k]), np.float64(qs[1, k]), np.float64(qs[2, k])
        sp0 += a0
        sp1 += a1
        sp2 += a2
        sq0 += w * b0
        sq1 += w * b1
        sq2 += w * b2
        s00 += a0 * b0
        s01 += a0 * b1
        s02 += a0 * b2
        s10 += a1 * b0
        s11 += a1 * b1
        s12 += a1 * b2
        s20 += a2 * b0
        s21 += a2 * b1
        s22 += a2 * b2
    sum_pq = np.array([[s00, s01, s02], [s10, s11, s12], [s20, s21, s22]])
    return n, np.array([sp0, sp1, sp2]), np.array([sq0, sq1, sq2]), sum_pq


@nb.njit(cache=True, nogil=True)
def match_and_accumulate(p_t, f, f_keys, q_t, g, g_keys, tau_spatial2, tau_doppler):
    """``match_sorted`` from features and their sorted keys (``sorted_keys``)."""
    ps, fs = _gather_sorted(p_t, f, f_keys)
    qs, gs = _gather_sorted(q_t, g, g_keys)
    return match_sorted(ps, fs, qs, gs, tau_spatial2, tau_doppler)


@nb.njit(cache=True, nogil=True)
def features_f32(points_t, doppler, scale):  # pragma: no cover - compiled
    """``methods.doppler._feature`` operation for operation in float32 (``scale``: the
    float32 of sign * dT): the same values bit for bit."""
    n = points_t.shape[1]
    out = np.empty(n, dtype=np.float32)
    for i in range(n):
        x, y, z = points_t[0, i], points_t[1, i], points_t[2, i]
        r2 = x * x
        r2 += y * y
        r2 += z * z
        r = np.sqrt(r2)
        r *= doppler[i]
        r *= scale
        out[i] = r2 + r
    return out


@nb.njit(cache=True, nogil=True)
def pairs(p_t, p_doppler, q_t, q_doppler, dt_s, tau_spatial2, tau_doppler
          ):  # pragma: no cover - compiled
    """``methods.doppler.doppler_pairs`` compiled: the same features (``features_f32``), the
    same nearest g per f and tie rules (the merge of ``match_sorted`` over both scans' sorted
    keys: ``nearest_1d``'s order) and the same float32 masks; (source indices ascending, their
    target indices)."""
    f = features_f32(p_t, p_doppler, np.float32(dt_s))
    g = features_f32(q_t, q_doppler, np.float32(-dt_s))
    f_keys = sorted_keys(f)
    g_keys = sorted_keys(g)
    n, m = len(f), len(g)
    low = np.uint64(0xFFFFFFFF)
    gs = np.empty(m, dtype=np.float32)
    for j in range(m):
        gs[j] = g[np.int64(g_keys[j] & low)]
    match = np.empty(n, dtype=np.int64)
    j = 0  # number of g values <= the current f
    for t in range(n):
        i = np.int64(f_keys[t] & low)
        fi = f[i]
        while j < m and gs[j] <= fi:
            j += 1
        lo = j - 1 if j > 0 else 0
        hi = j if j < m else m - 1
        k = hi if gs[hi] - fi < fi - gs[lo] else lo  # the nearer; the lower one on a tie
        match[i] = np.int64(g_keys[k] & low)
    ts = np.float32(tau_spatial2)
    td = np.float32(tau_doppler)
    keep = np.empty(n, dtype=np.bool_)
    count = 0
    for i in range(n):
        k = match[i]
        d0 = p_t[0, i] - q_t[0, k]
        d1 = p_t[1, i] - q_t[1, k]
        d2 = p_t[2, i] - q_t[2, k]
        dist2 = d0 * d0 + d1 * d1
        dist2 += d2 * d2
        keep[i] = dist2 <= ts and abs(f[i] - g[k]) <= td
        count += keep[i]
    src = np.empty(count, dtype=np.int64)
    tgt = np.empty(count, dtype=np.int64)
    c = 0
    for i in range(n):
        if keep[i]:
            src[c] = i
            tgt[c] = match[i]
            c += 1
    return src, tgt


class SortWorkspace:
    """Arrays reused by ``sorted_scan_into`` from call to call (grown when a scan is larger);
    one per scan role, used by one thread at a time."""

    def __init__(self) -> None:
        self._capacity = -1

    def arrays(self, n: int) -> tuple[np.ndarray, ...]:
        """(values, keys, spare, pts (3, n), vals) views of n elements."""
        if n > self._capacity:
            self._capacity = max(n, int(self._capacity * 1.25))
            c = self._capacity
            self._f32 = np.empty(5 * c, dtype=np.float32)
            self._u64 = np.empty(2 * c, dtype=np.uint64)
        c = self._capacity
        f, u = self._f32, self._u64
        return (f[:n], u[:n], u[c:c + n], f[c:c + 3 * n].reshape(3, n), f[4 * c:4 * c + n])


def warm_up() -> None:
    """Compile (or load from the cache) once, so no timed call pays for it."""
    pts = np.ones((3, 4), dtype=np.float32) + np.arange(4, dtype=np.float32)
    dop = np.zeros(4, dtype=np.float32)
    f = features(pts, dop, 0.1, 1.0)
    keys = sorted_keys(f)
    match_and_accumulate(pts, f, keys, pts, f, keys, 9.0, 5.0)
    ps, fs = sorted_scan(pts, dop, 0.1, 1.0)
    match_sorted(ps, fs, ps, fs, 9.0, 5.0)
    arrays = SortWorkspace().arrays(4)
    sorted_scan_into(pts, dop, 0.1, 1.0, *arrays)
    match_sorted(arrays[3], arrays[4], ps, fs, 9.0, 5.0)
    pairs(pts, dop, pts, dop, 0.1, 9.0, 5.0)
    match_sorted_into(arrays[3], arrays[4], ps, fs, 9.0, 5.0, arrays[0].view(np.int32))
