"""A compiled kd-tree (numba) for exact k-nearest-neighbour searches with a distance bound.

Why not only small_gicp's kd-tree: the ICP-style methods search the moved source points again
and again, and each point usually knows an upper bound for its answer beforehand (its last
neighbours, moved by the last step, or the pair gate). A search started with that bound prunes
nearly the whole tree, which small_gicp's API cannot be told. The same tree also serves
neighbourhoods of the tree's own points (normals), walked in the tree's order so that
consecutive searches touch the same memory.

The tree: points copied in tree order (each leaf's points contiguous), split at the median of
the widest axis of each node's bounding box until at most ``leaf_size`` points remain (left
side <= split <= right side). A search keeps the k best as a sorted list and prunes a subtree
whose box is not strictly closer than the current k-th distance (or the bound), using the
per-axis offsets of the box (as nanoflann does), so it is exact: the k nearest points strictly
within the bound, ascending; ties keep the point found first.
"""

from __future__ import annotations

import numba as nb
import numpy as np

LEAF_SIZE = 12
_STACK = 96  # > the depth of any tree (log2 of the points over the leaf size, plus slack)


@nb.njit(cache=True, nogil=True)
def _select(pts, perm, lo, hi, k, dim):  # pragma: no cover - compiled
    """Reorder rows lo..hi-1 so that row k holds the k-th smallest coordinate ``dim``, rows
    before it are <= and rows after it >= (Wirth's selection)."""
    left, right = lo, hi - 1
    while left < right:
        x = pts[k, dim]
        i, j = left, right
        while i <= j:
            while pts[i, dim] < x:
                i += 1
            while x < pts[j, dim]:
                j -= 1
            if i <= j:
                for a in range(3):
                    t = pts[i, a]
                    pts[i, a] = pts[j, a]
                    pts[j, a] = t
                t2 = perm[i]
                perm[i] = perm[j]
                perm[j] = t2
                i += 1
                j -= 1
        if j < k:
            left = i
        if k < i:
            right = j


@nb.njit(cache=True, nogil=True)
def build(points, leaf_size):  # pragma: no cover - compiled
    """(tree-ordered points (N, 3), perm: original index of each, and the nodes: lo, hi (point
    range), dim (-1: leaf), split, left, right)."""
    n = points.shape[0]
    pts = np.empty((n, 3))
    for i in range(n):
        for a in range(3):
            pts[i, a] = points[i, a]
    perm = np.arange(n)
    cap = 4 * (n // max(leaf_size, 1) + 1) + 1
    lo = np.empty(cap, dtype=np.int64)
    hi = np.empty(cap, dtype=np.int64)
    dim = np.full(cap, -1, dtype=np.int64)
    split = np.zeros(cap)
    left = np.full(cap, -1, dtype=np.int64)
    right = np.full(cap, -1, dtype=np.int64)
    lo[0], hi[0] = 0, n
    count = 1
    todo = np.empty(cap, dtype=np.int64)
    top = 0
    todo[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = todo[top]
        a0, a1 = lo[node], hi[node]
        if a1 - a0 <= leaf_size:
            continue
        mn = np.full(3, np.inf)
        mx = np.full(3, -np.inf)
        for i in range(a0, a1):
            for a in range(3):
                v = pts[i, a]
                if v < mn[a]:
                    mn[a] = v
                if v > mx[a]:
                    mx[a] = v
        d = 0
        for a in range(1, 3):
            if mx[a] - mn[a] > mx[d] - mn[d]:
                d = a
        if not mx[d] - mn[d] > 0:
            continue  # identical points: one leaf
        mid = (a0 + a1) // 2
        _select(pts, perm, a0, a1, mid, d)
        dim[node] = d
        split[node] = pts[mid, d]
        left[node], right[node] = count, count + 1
        lo[count], hi[count] = a0, mid
        lo[count + 1], hi[count + 1] = mid, a1
        todo[top] = count + 1
        todo[top + 1] = count
        top += 2
        count += 2
    return pts, perm, lo[:count], hi[:count], dim[:count], split[:count], left[:count], \
        right[:count]


@nb.njit(cache=True, nogil=True, inline="always")
def _search(pts, lo, hi, dim, split, left, right, qx, qy, qz, k, bound_sq, out_sq, out_pos,
            st_node, st_lb, st_off):  # pragma: no cover - compiled
    """The k nearest tree points strictly closer than sqrt(bound_sq) to (qx, qy, qz): fills
    out_sq / out_pos (positions in tree order) ascending and returns how many were found."""
    count = 0
    worst = bound_sq
    top = 1
    st_node[0] = 0
    st_lb[0] = 0.0
    st_off[0, 0] = st_off[0, 1] = st_off[0, 2] = 0.0
    while top > 0:
        top -= 1
        node = st_node[top]
        lb = st_lb[top]
        if lb >= worst:
            continue
        o0, o1, o2 = st_off[top, 0], st_off[top, 1], st_off[top, 2]
        while dim[node] >= 0:
            d = dim[node]
            diff = (qx if d == 0 else (qy if d == 1 else qz)) - split[node]
            if diff < 0:
                near, far = left[node], right[node]
            else:
                near, far = right[node], left[node]
            old = o0 if d == 0 else (o1 if d == 1 else o2)
            far_lb = lb - old * old + diff * diff
            if far_lb < worst:
                st_node[top] = far
                st_lb[top] = far_lb
                st_off[top, 0] = diff if d == 0 else o0
                st_off[top, 1] = diff if d == 1 else o1
                st_off[top, 2] = diff if d == 2 else o2
                top += 1
            node = near
        for p in range(lo[node], hi[node]):
            dx = pts[p, 0] - qx
            dy = pts[p, 1] - qy
            dz = pts[p, 2] - qz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < worst:
                if count < k:  # append, then sift up (a max-heap on the distance)
                    j = count
                    count += 1
                    while j > 0:
                        parent = (j - 1) >> 1
                        if out_sq[parent] >= d2:
                            break
                        out_sq[j] = out_sq[parent]
                        out_pos[j] = out_pos[parent]
                        j = parent
                    out_sq[j] = d2
                    out_pos[j] = p
                    if count == k:
                        worst = out_sq[0]
                else:  # replace the farthest, then sift down
                    j = 0
                    while True:
                        c = 2 * j + 1
                        if c >= k:
                            break
                        if c + 1 < k and out_sq[c + 1] > out_sq[c]:
                            c += 1
                        if out_sq[c] <= d2:
                            break
                        out_sq[j] = out_sq[c]
                        out_pos[j] = out_pos[c]
                        j = c
                    out_sq[j] = d2
                    out_pos[j] = p
                    worst = out_sq[0]
    # the heap in ascending order of distance (ties by position: a deterministic order)
    for end in range(count - 1, 0, -1):
        top_sq, top_pos = out_sq[0], out_pos[0]
        last_sq, last_pos = out_sq[end], out_pos[end]
        j = 0
        while True:
            c = 2 * j + 1
            if c >= end:
                break
            if c + 1 < end and (out_sq[c + 1] > out_sq[c] or (out_sq[c + 1] == out_sq[c]
                                                               and out_pos[c + 1] > out_pos[c])):
                c += 1
            if out_sq[c] < last_sq or (out_sq[c] == last_sq and out_pos[c] <= last_pos):
                break
            out_sq[j] = out_sq[c]
            out_pos[j] = out_pos[c]
            j = c
        out_sq[j] = last_sq
        out_pos[j] = last_pos
        out_sq[end] = top_sq
        out_pos[end] = top_pos
    return count


@nb.njit(cache=True, nogil=True)
def knn(pts, perm, lo, hi, dim, split, left, right, queries, k, bounds_sq
        ):  # pragma: no cover - compiled
    """(index (M, k), squared distance (M, k)) of the k nearest tree points of each query
    strictly within its bound (bounds_sq: (M,) or (1,) for one bound for all); -1 and inf
    where fewer are found."""
    m = queries.shape[0]
    idx = np.full((m, k), -1, dtype=np.int64)
    sq = np.full((m, k), np.inf)
    st_node = np.empty(_STACK, dtype=np.int64)
    st_lb = np.empty(_STACK)
    st_off = np.empty((_STACK, 3))
    out_sq = np.empty(k)
    out_pos = np.empty(k, dtype=np.int64)
    one = bounds_sq.shape[0] == 1
    for i in range(m):
        c = _search(pts, lo, hi, dim, split, left, right, queries[i, 0], queries[i, 1],
                    queries[i, 2], k, bounds_sq[0] if one else bounds_sq[i], out_sq, out_pos,
                    st_node, st_lb, st_off)
        for j in range(c):
            idx[i, j] = perm[out_pos[j]]
            sq[i, j] = out_sq[j]
    return idx, sq


class KdTree:
    """Exact k-nearest-neighbour searches over ``points`` (N, 3) [m], within a bound."""

    def __init__(self, points: np.ndarray, leaf_size: int = LEAF_SIZE) -> None:
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        self.arrays = build(pts, leaf_size)
        self.points = pts

    def __len__(self) -> int:
        return len(self.points)

    def knn(self, queries: np.ndarray, k: int, max_dist_m: float = np.inf,
            bounds_sq: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(index (M, k) int64, squared distance (M, k) [m^2]) of each query's k nearest
        points strictly closer than ``max_dist_m`` (or, per query, than sqrt(bounds_sq)),
        ascending; -1 and inf where fewer are found."""
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        b = (np.array([max_dist_m**2]) if bounds_sq is None
             else np.ascontiguousarray(bounds_sq, dtype=np.float64))
        return knn(*self.arrays, q, k, b)


def warm_up() -> None:
    """Compile (or load from numba's cache) once, so no timed call pays for it."""
    tree = KdTree(np.arange(60.0).reshape(20, 3), leaf_size=2)
    tree.knn(np.zeros((2, 3)), 3, 5.0)
    tree.knn(np.zeros((2, 3)), 1, bounds_sq=np.ones(2))
