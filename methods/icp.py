"""Point-to-point ICP, the paper's baseline (its Section IV-A parameters).

Uniform downsampling by ``downsample`` (untimed preparation, which also lays the points out as
contiguous float64), then inside the timed call: a kd-tree of the target (small_gicp's
compiled kd-tree; building it is part of the correspondence search, as in Open3D's ICP that
times DICP), and per iteration the closest target point of every moved source point (the
kd-tree's batch search, ``num_threads`` threads), pairs within tau_spatial, a closed-form rigid
fit (``methods.rigid``, from sums gathered by one compiled pass), repeated until the mean pair
distance changes by less than ``convergence`` or ``max_iterations`` is reached.
Paper values: max iterations 100, convergence 1e-5 [m], downsampling 2, tau_spatial 3 m.
Cost: the nearest-neighbour search is ~85 % of an iteration (about 0.3 us per query point on
one core here), so a frame costs about iterations x source points x 0.35 us.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import small_gicp
from pydantic import Field

from loaders.scan import Scan
from methods.base import MethodParams, Registration, RegistrationResult, uniform_downsample
from methods.rigid import rigid_from_sums


class IcpParams(MethodParams):
    max_iterations: int = Field(100, ge=1)
    convergence: float = Field(1e-5, gt=0, description="stop when mean error changes less [m]")
    downsample: int = Field(2, ge=1, description="keep every k-th point")
    tau_spatial_m: float = Field(3.0, gt=0, description="max closest-point distance [m]")
    num_threads: int = Field(1, ge=1, description="kd-tree build and query threads")


def closest_points(tree: small_gicp.KdTree, points: np.ndarray, max_dist_m: float,
                   num_threads: int) -> tuple[np.ndarray, np.ndarray]:
    """(index of the closest target point, distance [m]) per query point; pairs farther than
    ``max_dist_m`` get index -1 and an infinite distance."""
    idx, sq = tree.batch_knn_search(points, 1, num_threads=num_threads)
    idx = idx[:, 0].astype(np.int64)  # small_gicp marks "none" as uint64(-1), i.e. -1 here
    dist = np.sqrt(sq[:, 0])
    far = (idx < 0) | ~(dist <= max_dist_m)
    idx[far] = -1
    dist[far] = np.inf
    return idx, dist


@nb.njit(cache=True)
def _transform(T, points):  # pragma: no cover - compiled
    """T applied to (N, 3) points in a plain loop (NumPy's matmul goes through BLAS, whose
    threads are slow when the cores are busy)."""
    out = np.empty_like(points)
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for a in range(3):
            out[i, a] = T[a, 0] * x + T[a, 1] * y + T[a, 2] * z + T[a, 3]
    return out


@nb.njit(cache=True)
def _pair_sums(moved, target, idx, sq_dist, max_sq_dist):  # pragma: no cover - compiled
    """Over the pairs (moved[i], target[idx[i]]) within sqrt(max_sq_dist): their count, sum p,
    sum q, sum p q^T and the sum of pair distances [m]."""
    n = 0
    sum_p = np.zeros(3)
    sum_q = np.zeros(3)
    sum_pq = np.zeros((3, 3))
    dist_sum = 0.0
    n_target = target.shape[0]
    for i in range(moved.shape[0]):
        j = idx[i]
        if j >= n_target or not sq_dist[i] <= max_sq_dist:  # no neighbour / beyond the gate
            continue
        n += 1
        dist_sum += np.sqrt(sq_dist[i])
        for a in range(3):
            sum_p[a] += moved[i, a]
            sum_q[a] += target[j, a]
            for b in range(3):
                sum_pq[a, b] += moved[i, a] * target[j, b]
    return n, sum_p, sum_q, sum_pq, dist_sum


def warm_up() -> None:
    """Compile (or load from numba's cache) once, so no timed call pays for it."""
    pts = np.zeros((4, 3))
    _pair_sums(_transform(np.eye(4), pts), pts, np.zeros(4, dtype=np.uint64), np.zeros(4), 1.0)


class PointToPointIcp(Registration):
    name = "icp-p2p"
    description = "Point-to-point ICP with kd-tree closest points (paper baseline)"
    Params = IcpParams

    def __init__(self, params: IcpParams | None = None, **overrides) -> None:
        super().__init__(params, **overrides)
        warm_up()  # compile outside the timed call

    def preprocess(self, scan: Scan) -> Scan:
        scan = uniform_downsample(scan, self.params.downsample)
        return Scan(scan.stamp, np.ascontiguousarray(scan.points, dtype=np.float64),
                    scan.doppler, scan.fields, scan.source)

    def register(self, source: Scan, target: Scan, init_T_target_source: np.ndarray):
        p = self.params
        if len(source) < 3 or len(target) < 3:
            return RegistrationResult(init_T_target_source, 0, 0, False)
        src = np.ascontiguousarray(source.points, dtype=np.float64)
        tgt = np.ascontiguousarray(target.points, dtype=np.float64)
        tree = small_gicp.KdTree(tgt, num_threads=p.num_threads)
        max_sq = p.tau_spatial_m ** 2
        T = np.array(init_T_target_source, dtype=np.float64)
        prev_error = np.inf
        n = 0
        for iteration in range(1, p.max_iterations + 1):
            moved = _transform(T, src)
            idx, sq = tree.batch_knn_search(moved, 1, num_threads=p.num_threads)
            n, sum_p, sum_q, sum_pq, dist_sum = _pair_sums(moved, tgt, idx[:, 0], sq[:, 0],
                                                           max_sq)
            delta = rigid_from_sums(n, sum_p, sum_q, sum_pq)
            if delta is None:
                return RegistrationResult(T, n, iteration, False)
            T = delta @ T
            error = dist_sum / n
            if abs(prev_error - error) < p.convergence:
                return RegistrationResult(T, n, iteration, True)
            prev_error = error
        return RegistrationResult(T, n, p.max_iterations, False)
