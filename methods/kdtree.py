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
within the bound, ascending; ties in tree order.
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
def _insert_sorted(out_sq, out_pos, count, k, d2, p):  # pragma: no cover - compiled
    """Insert (d2, p) into the sorted list of ``count`` (ascending distance, ties by
    position), dropping the farthest when it holds k; returns the new count."""
    j = count if count < k else k - 1
    while j > 0 and (out_sq[j - 1] > d2 or (out_sq[j - 1] == d2 and out_pos[j - 1] > p)):
        out_sq[j] = out_sq[j - 1]
        out_pos[j] = out_pos[j - 1]
        j -= 1
    out_sq[j] = d2
    out_pos[j] = p
    return count + 1 if count < k else k


@nb.njit(cache=True, nogil=True, inline="always")
def _search_sorted(pts, lo, hi, dim, split, left, right, qx, qy, qz, k, bound_sq, out_sq,
                   out_pos, st_node, st_lb, st_off):  # pragma: no cover - compiled
    """The k nearest tree points strictly closer than sqrt(bound_sq) to (qx, qy, qz): fills
    out_sq / out_pos (positions in tree order) ascending and returns how many were found. The k
    best are kept in a sorted list (ties by position): an insertion shifts the farther ones and
    no final sort is needed (for k of tens 20 % faster than a heap: DICP's normals)."""
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
                count = _insert_sorted(out_sq, out_pos, count, k, d2, p)
                if count == k:
                    worst = out_sq[k - 1]
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
        c = _search_sorted(pts, lo, hi, dim, split, left, right, queries[i, 0],
                           queries[i, 1], queries[i, 2], k,
                           bounds_sq[0] if one else bounds_sq[i], out_sq, out_pos, st_node,
                           st_lb, st_off)
        for j in range(c):
            idx[i, j] = perm[out_pos[j]]
            sq[i, j] = out_sq[j]
    return idx, sq


@nb.njit(cache=True, nogil=True)
def links(pts, lo, hi, left, right):  # pragma: no cover - compiled
    """(parent of each node (-1: root), leaf of each tree position, each node's bounding box
    (min (nodes, 3), max (nodes, 3))) of a tree from ``build``: what ``nearest`` walks."""
    m = lo.shape[0]
    parent = np.full(m, -1, dtype=np.int64)
    leaf_of = np.empty(pts.shape[0], dtype=np.int64)
    bmin = np.empty((m, 3))
    bmax = np.empty((m, 3))
    for node in range(m - 1, -1, -1):  # children are numbered after their parent
        a, b = left[node], right[node]
        if a < 0:
            for x in range(3):
                bmin[node, x], bmax[node, x] = np.inf, -np.inf
            for p in range(lo[node], hi[node]):
                leaf_of[p] = node
                for x in range(3):
                    bmin[node, x] = min(bmin[node, x], pts[p, x])
                    bmax[node, x] = max(bmax[node, x], pts[p, x])
        else:
            parent[a], parent[b] = node, node
            for x in range(3):
                bmin[node, x] = min(bmin[a, x], bmin[b, x])
                bmax[node, x] = max(bmax[a, x], bmax[b, x])
    return parent, leaf_of, bmin, bmax


@nb.njit(cache=True, nogil=True, inline="always")
def _box_sq(bmin, bmax, node, qx, qy, qz):  # pragma: no cover - compiled
    """Squared distance from (qx, qy, qz) to a node's bounding box (0 inside)."""
    d2 = 0.0
    for x in range(3):
        q = qx if x == 0 else (qy if x == 1 else qz)
        if q < bmin[node, x]:
            d2 += (bmin[node, x] - q) ** 2
        elif q > bmax[node, x]:
            d2 += (q - bmax[node, x]) ** 2
    return d2


@nb.njit(cache=True, nogil=True, inline="always")
def _leaf_nn(pts, lo, hi, node, qx, qy, qz, best, best_pos):  # pragma: no cover
    for p in range(lo[node], hi[node]):
        dx = pts[p, 0] - qx
        dy = pts[p, 1] - qy
        dz = pts[p, 2] - qz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < best:
            best, best_pos = d2, p
    return best, best_pos


@nb.njit(cache=True, nogil=True, inline="always")
def _subtree_nn(pts, lo, hi, dim, split, left, right, bmin, bmax, start, qx, qy, qz, best,
                best_pos, stack):  # pragma: no cover - compiled
    """The nearest point of the subtree ``start`` strictly closer than sqrt(best), else the
    given (best, best_pos); subtrees whose box is not strictly closer are skipped."""
    top = 1
    stack[0] = start
    while top > 0:
        top -= 1
        node = stack[top]
        if not _box_sq(bmin, bmax, node, qx, qy, qz) < best:
            continue
        while dim[node] >= 0:
            d = dim[node]
            diff = (qx if d == 0 else (qy if d == 1 else qz)) - split[node]
            if diff < 0:
                near, far = left[node], right[node]
            else:
                near, far = right[node], left[node]
            if diff * diff < best:  # the far side may hold a closer point (checked at pop)
                stack[top] = far
                top += 1
            node = near
        best, best_pos = _leaf_nn(pts, lo, hi, node, qx, qy, qz, best, best_pos)
    return best, best_pos


@nb.njit(cache=True, nogil=True)
def nearest(pts, perm, lo, hi, dim, split, left, right, parent, leaf_of, bmin, bmax, queries,
            hints, bound_sq):  # pragma: no cover - compiled
    """(index (M,), squared distance (M,)) of each query's nearest tree point strictly closer
    than sqrt(bound_sq), -1 and inf when none; exact (as ``knn`` with k = 1, up to ties).

    The search starts at the leaf of a hint (``hints[i]``: a tree point, as an original index,
    likely close to query i, e.g. its last pair; -1: none, then the previous query's answer
    serves) and climbs to the root, searching each sibling subtree whose box is strictly
    closer than the best so far: every point is in the start leaf or one of those siblings,
    so the answer is exact, and a good hint skips the descent from the root."""
    m = queries.shape[0]
    n = pts.shape[0]
    out_idx = np.full(m, -1, dtype=np.int64)
    out_sq = np.full(m, np.inf)
    if n == 0:
        return out_idx, out_sq
    inv = np.empty(n, dtype=np.int64)
    for p in range(n):
        inv[perm[p]] = p
    stack = np.empty(_STACK, dtype=np.int64)
    last = -1  # tree position of the previous query's answer
    for i in range(m):
        qx, qy, qz = queries[i, 0], queries[i, 1], queries[i, 2]
        h = hints[i]
        start = inv[h] if h >= 0 else last
        best, best_pos = bound_sq, -1
        if start < 0:
            best, best_pos = _subtree_nn(pts, lo, hi, dim, split, left, right, bmin, bmax,
                                         0, qx, qy, qz, best, best_pos, stack)
        else:
            node = leaf_of[start]
            best, best_pos = _leaf_nn(pts, lo, hi, node, qx, qy, qz, best, best_pos)
            up = parent[node]
            while up >= 0:
                sibling = left[up] if right[up] == node else right[up]
                d = dim[up]
                diff = (qx if d == 0 else (qy if d == 1 else qz)) - split[up]
                # the sibling lies beyond the split plane when the query is on this side
                if (diff < 0) != (sibling == left[up]) and not diff * diff < best:
                    node = up
                    up = parent[node]
                    continue
                best, best_pos = _subtree_nn(pts, lo, hi, dim, split, left, right, bmin,
                                             bmax, sibling, qx, qy, qz, best, best_pos, stack)
                node = up
                up = parent[node]
        if best_pos >= 0:
            out_idx[i] = perm[best_pos]
            out_sq[i] = best
            last = best_pos
    return out_idx, out_sq


@nb.njit(cache=True, nogil=True, inline="always")
def _leaf_nn2(pts, lo, hi, node, qx, qy, qz, best, best_pos, second):  # pragma: no cover
    for p in range(lo[node], hi[node]):
        dx = pts[p, 0] - qx
        dy = pts[p, 1] - qy
        dz = pts[p, 2] - qz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < second:
            if d2 < best:
                second = best
                best, best_pos = d2, p
            else:
                second = d2
    return best, best_pos, second


@nb.njit(cache=True, nogil=True, inline="always")
def _subtree_nn2(pts, lo, hi, dim, split, left, right, bmin, bmax, start, qx, qy, qz, best,
                 best_pos, second, stack):  # pragma: no cover - compiled
    """``_subtree_nn`` keeping the two nearest (pruned by the second)."""
    top = 1
    stack[0] = start
    while top > 0:
        top -= 1
        node = stack[top]
        if not _box_sq(bmin, bmax, node, qx, qy, qz) < second:
            continue
        while dim[node] >= 0:
            d = dim[node]
            diff = (qx if d == 0 else (qy if d == 1 else qz)) - split[node]
            if diff < 0:
                near, far = left[node], right[node]
            else:
                near, far = right[node], left[node]
            if diff * diff < second:
                stack[top] = far
                top += 1
            node = near
        best, best_pos, second = _leaf_nn2(pts, lo, hi, node, qx, qy, qz, best, best_pos,
                                           second)
    return best, best_pos, second


#: ``NearestTracker``'s search radius over the bound's (larger: fewer searches again, each
#: slower); no effect on the answers
FAR = 1.25
_SLACK_M = 1e-9  # margin for rounding in the distance tests of ``nearest_tracked`` [m]


@nb.njit(cache=True, nogil=True)
def nearest_tracked(pts, perm, lo, hi, dim, split, left, right, parent, leaf_of, bmin, bmax,
                    queries, order, bound_sq, far_sq, track_sq, anchor, pos, clear_sq,
                    near_sq):  # pragma: no cover - compiled
    """``nearest`` (strictly closer than sqrt(bound_sq)) for queries that move a little
    between calls, reusing the last search of each. State per query: ``anchor`` (where it was
    last searched), ``pos`` (tree position of its nearest point there, -1: none, -2: never
    searched), ``clear_sq`` (every other point is at least sqrt(clear_sq) from the anchor: the
    second nearest's squared distance, or far_sq; -1: unknown) and ``near_sq`` (the nearest's
    squared distance there). A query moved by delta from its anchor keeps its nearest point p
    when |q - p| + delta < sqrt(clear_sq) (every other point is then strictly farther from q),
    or keeps having none within the bound when sqrt(clear_sq) - delta > sqrt(bound_sq); both
    with a margin of 1e-9 m for rounding. Otherwise it is searched again from its last nearest
    point's leaf and becomes its own anchor: for its two nearest within sqrt(far_sq) (far_sq
    >= bound_sq) when its last nearest was at least sqrt(track_sq) away (a query close to its
    nearest point usually has too small a gap to the second to keep it), else for its nearest
    within the bound alone (cheaper; gap unknown), as on its first search. The queries are
    visited in ``order`` (e.g. their own kd-tree's: consecutive searches touch the same
    memory, and a query without a last nearest point starts from its predecessor's); the
    answers are in query order. Exact: the same answers as ``nearest`` up to ties."""
    m = queries.shape[0]
    out_idx = np.full(m, -1, dtype=np.int64)
    out_sq = np.full(m, np.inf)
    stack = np.empty(_STACK, dtype=np.int64)
    gate = np.sqrt(bound_sq)
    last = -1
    for t in range(m):
        i = order[t]
        qx, qy, qz = queries[i, 0], queries[i, 1], queries[i, 2]
        p = pos[i]
        if p >= -1 and clear_sq[i] >= 0.0:
            ex, ey, ez = qx - anchor[i, 0], qy - anchor[i, 1], qz - anchor[i, 2]
            delta = np.sqrt(ex * ex + ey * ey + ez * ez) + _SLACK_M
            clear = np.sqrt(clear_sq[i])
            if p >= 0:
                dx = pts[p, 0] - qx
                dy = pts[p, 1] - qy
                dz = pts[p, 2] - qz
                d2 = dx * dx + dy * dy + dz * dz
                if np.sqrt(d2) + delta < clear:
                    if d2 < bound_sq:
                        out_idx[i] = perm[p]
                        out_sq[i] = d2
                    last = p
                    continue
            elif clear - delta > gate:
                continue
        start = p if p >= 0 else last
        two = p > -2 and near_sq[i] >= track_sq
        limit = far_sq if two else bound_sq
        best, best_pos, second = limit, -1, limit
        if start < 0:
            start_node = 0
        else:
            start_node = leaf_of[start]
            if two:
                best, best_pos, second = _leaf_nn2(pts, lo, hi, start_node, qx, qy, qz, best,
                                                   best_pos, second)
            else:
                best, best_pos = _leaf_nn(pts, lo, hi, start_node, qx, qy, qz, best, best_pos)
        node = start_node
        up = parent[node] if start >= 0 else -1
        if start < 0:  # from the root
            if two:
                best, best_pos, second = _subtree_nn2(pts, lo, hi, dim, split, left, right,
                                                      bmin, bmax, 0, qx, qy, qz, best,
                                                      best_pos, second, stack)
            else:
                best, best_pos = _subtree_nn(pts, lo, hi, dim, split, left, right, bmin, bmax,
                                             0, qx, qy, qz, best, best_pos, stack)
        while up >= 0:  # from the start leaf up: every sibling that may hold a closer point
            sibling = left[up] if right[up] == node else right[up]
            d = dim[up]
            diff = (qx if d == 0 else (qy if d == 1 else qz)) - split[up]
            prune = second if two else best
            if not ((diff < 0) != (sibling == left[up]) and not diff * diff < prune):
                if two:
                    best, best_pos, second = _subtree_nn2(
                        pts, lo, hi, dim, split, left, right, bmin, bmax, sibling, qx, qy, qz,
                        best, best_pos, second, stack)
                else:
                    best, best_pos = _subtree_nn(pts, lo, hi, dim, split, left, right, bmin,
                                                 bmax, sibling, qx, qy, qz, best, best_pos,
                                                 stack)
            node = up
            up = parent[node]
        anchor[i, 0], anchor[i, 1], anchor[i, 2] = qx, qy, qz
        pos[i] = best_pos
        clear_sq[i] = second if two else -1.0
        near_sq[i] = best
        if best_pos >= 0:
            last = best_pos
            if best < bound_sq:
                out_idx[i] = perm[best_pos]
                out_sq[i] = best
    return out_idx, out_sq


class NearestTracker:
    """``KdTree.nearest`` for one set of queries that move a little from call to call (the
    moved source of an ICP loop): ``nearest_tracked``'s state, kept between calls; ``order``:
    the order the queries are visited in (a permutation; default: theirs).
    ``track_m``: a query is searched for its two nearest (to be kept while it moves less than
    their gap) when its last nearest was at least this far; 0: always. Either way the answers
    are the same; only the time differs."""

    def __init__(self, tree: KdTree, count: int, bound_sq: float, far_sq: float,
                 track_m: float = 0.0, order: np.ndarray | None = None) -> None:
        self.tree, self.bound_sq, self.far_sq = tree, float(bound_sq), float(far_sq)
        self.order = np.arange(count) if order is None else np.asarray(order, dtype=np.int64)
        self.track_sq = float(track_m) ** 2
        self.anchor = np.zeros((count, 3))
        self.pos = np.full(count, -2, dtype=np.int64)
        self.clear_sq = np.full(count, -1.0)
        self.near_sq = np.zeros(count)

    def __call__(self, queries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(index (M,), squared distance (M,)) as ``KdTree.nearest(queries, ...,
        bound_sq)``."""
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        return nearest_tracked(*self.tree.arrays, *self.tree.links, q, self.order,
                               self.bound_sq, self.far_sq, self.track_sq, self.anchor,
                               self.pos, self.clear_sq, self.near_sq)


class KdTree:
    """Exact k-nearest-neighbour searches over ``points`` (N, 3) [m], within a bound."""

    def __init__(self, points: np.ndarray, leaf_size: int = LEAF_SIZE) -> None:
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        self.arrays = build(pts, leaf_size)
        self.points = pts
        self._links = None

    def __len__(self) -> int:
        return len(self.points)

    @property
    def links(self) -> tuple:
        """``links`` of this tree (parents, leaves, boxes), computed on first use."""
        if self._links is None:
            pts, _, lo, hi, _, _, left, right = self.arrays
            self._links = links(pts, lo, hi, left, right)
        return self._links

    def nearest(self, queries: np.ndarray, hints: np.ndarray | None = None,
                bound_sq: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """(index (M,) int64, squared distance (M,) [m^2]) of each query's nearest point
        strictly closer than sqrt(bound_sq), -1 and inf when none; ``hints``: an index per
        query of a point likely near it (-1: none), where the search starts (``nearest``)."""
        q = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        h = (np.full(len(q), -1, dtype=np.int64) if hints is None
             else np.ascontiguousarray(hints, dtype=np.int64))
        return nearest(*self.arrays, *self.links, q, h, float(bound_sq))

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
    tree.nearest(np.zeros((2, 3)), np.array([0, -1]), 25.0)
    for track_m in (0.0, 1.0):
        track = NearestTracker(tree, 2, 25.0, 30.0, track_m, np.array([1, 0]))
        track(np.zeros((2, 3)))
        track(np.full((2, 3), 1e-3))
