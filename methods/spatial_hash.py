"""Exact nearest neighbour within a radius, from a spatial hash that is cheap to rebuild.

``doppler-ego``'s local map changes every frame (a scan joins, the oldest leaves), so its search
structure is rebuilt every frame; a kd-tree over ~40k radar map points costs about 6 ms to
build, more than the whole registration. Here the points are binned into cubic cells of side
``cell_m`` >= the search radius, each cell hashed into a table of chained lists (built in one
O(N) pass). A query walks the 27 cells around it: every point within ``cell_m`` of the query is
in one of them, so the answer is the exact nearest neighbour within the radius (hash collisions
only add candidates, which are checked by their true distance).
"""

from __future__ import annotations

import numba
import numpy as np

_P1, _P2, _P3 = 73856093, 19349663, 83492791  # the usual spatial-hash primes


@numba.njit(cache=True, inline="always")
def _bucket(i: int, j: int, k: int, mask: int) -> int:
    return ((i * _P1) ^ (j * _P2) ^ (k * _P3)) & mask


@numba.njit(cache=True)
def _build(points: np.ndarray, inv_cell: float, table_size: int, valid=None):
    head = np.full(table_size, -1, dtype=np.int64)
    nxt = np.full(len(points), -1, dtype=np.int64)
    mask = table_size - 1
    for n in range(len(points)):
        if valid is not None and not valid[n]:
            continue
        b = _bucket(int(np.floor(points[n, 0] * inv_cell)),
                    int(np.floor(points[n, 1] * inv_cell)),
                    int(np.floor(points[n, 2] * inv_cell)), mask)
        nxt[n] = head[b]
        head[b] = n
    return head, nxt


@numba.njit(cache=True)
def _nearest(points, head, nxt, inv_cell, queries, max_sq):
    mask = len(head) - 1
    cell = 1.0 / inv_cell
    m = len(queries)
    idx = np.full(m, -1, dtype=np.int64)
    sq = np.full(m, np.inf)
    gap = np.empty((3, 3))  # gap[axis, d + 1]: distance from the query to the neighbour cell
    for q in range(m):
        x, y, z = queries[q, 0], queries[q, 1], queries[q, 2]
        ci = int(np.floor(x * inv_cell))
        cj = int(np.floor(y * inv_cell))
        ck = int(np.floor(z * inv_cell))
        for a, (v, c) in enumerate(((x, ci), (y, cj), (z, ck))):
            gap[a, 0] = v - c * cell
            gap[a, 1] = 0.0
            gap[a, 2] = (c + 1) * cell - v
        best, best_i = max_sq, -1
        for visit in range(27):  # the query's own cell first: it usually bounds the rest
            code = (visit + 13) % 27
            di, dj, dk = code // 9 - 1, (code // 3) % 3 - 1, code % 3 - 1
            g0, g1, g2 = gap[0, di + 1], gap[1, dj + 1], gap[2, dk + 1]
            if g0 * g0 + g1 * g1 + g2 * g2 >= best:
                continue  # the whole cell is farther than the best so far
            n = head[_bucket(ci + di, cj + dj, ck + dk, mask)]
            while n >= 0:
                dx = points[n, 0] - x
                dy = points[n, 1] - y
                dz = points[n, 2] - z
                d2 = dx * dx + dy * dy + dz * dz
                if d2 < best or (d2 == best and best_i >= 0 and n < best_i):
                    best, best_i = d2, n
                n = nxt[n]
        if best_i >= 0:
            idx[q], sq[q] = best_i, best
    return idx, sq


class SpatialHash:
    """Points (N, 3) [m] binned for exact radius-limited nearest-neighbour queries."""

    def __init__(self, points: np.ndarray, cell_m: float, valid: np.ndarray | None = None
                 ) -> None:
        """``valid`` (N,) bool: only those points are searched (indices stay those of
        ``points``); None: all."""
        if not cell_m > 0:
            raise ValueError(f"cell size must be positive, got {cell_m}")
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        self.cell_m = float(cell_m)
        n = len(points) if valid is None else int(np.count_nonzero(valid))
        table = 1 << max(4, int(2 * max(n, 1) - 1).bit_length())  # >= 2 N, power of 2
        self._head, self._next = _build(self.points, 1.0 / self.cell_m, table, valid)

    def nearest(self, queries: np.ndarray, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Index of each query's nearest point and its squared distance [m^2], among the points
        strictly closer than ``radius_m`` (<= the cell size); -1 and inf where there is none.
        Ties go to the lower index."""
        if radius_m > self.cell_m * (1 + 1e-12):
            raise ValueError(f"radius {radius_m} m exceeds the cell size {self.cell_m} m")
        q = np.ascontiguousarray(queries, dtype=np.float64)
        return _nearest(self.points, self._head, self._next, 1.0 / self.cell_m, q,
                        float(radius_m) ** 2)
