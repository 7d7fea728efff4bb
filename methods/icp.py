"""Point-to-point ICP, the paper's baseline (its Section IV-A parameters).

Uniform downsampling by ``downsample`` (untimed preparation), then inside the timed call: a
kd-tree of the target (small_gicp's compiled kd-tree; building it is part of the
correspondence search), closest points of the moved source within tau_spatial, a closed-form
rigid fit (``methods.rigid``), repeated until the mean pair distance changes by less than
``convergence`` or ``max_iterations`` is reached.
Paper values: max iterations 100, convergence 1e-5, downsampling 2, tau_spatial 3 m.
"""

from __future__ import annotations

import numpy as np
import small_gicp
from pydantic import Field

from loaders.scan import Scan
from loaders.se3 import transform_points
from methods.base import MethodParams, Registration, RegistrationResult, uniform_downsample
from methods.rigid import fit_rigid


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
    idx, sq = tree.batch_nearest_neighbor_search(points, num_threads=num_threads)
    idx = np.asarray(idx, dtype=np.int64)
    dist = np.sqrt(np.asarray(sq, dtype=np.float64))
    far = (idx < 0) | ~(dist <= max_dist_m)
    idx[far] = -1
    dist[far] = np.inf
    return idx, dist


class PointToPointIcp(Registration):
    name = "icp-p2p"
    description = "Point-to-point ICP with kd-tree closest points (paper baseline)"
    Params = IcpParams

    def preprocess(self, scan: Scan) -> Scan:
        return uniform_downsample(scan, self.params.downsample)

    def register(self, source: Scan, target: Scan, init_T_target_source: np.ndarray):
        p = self.params
        if len(source) < 3 or len(target) < 3:
            return RegistrationResult(init_T_target_source, 0, 0, False)
        tree = small_gicp.KdTree(target.points, num_threads=p.num_threads)
        T = init_T_target_source.copy()
        prev_error = np.inf
        n = 0
        for iteration in range(1, p.max_iterations + 1):
            moved = transform_points(T, source.points)
            idx, dist = closest_points(tree, moved, p.tau_spatial_m, p.num_threads)
            keep = idx >= 0
            n = int(keep.sum())
            delta = fit_rigid(moved[keep], target.points[idx[keep]]) if n >= 3 else None
            if delta is None:
                return RegistrationResult(T, n, iteration, False)
            T = delta @ T
            error = float(dist[keep].mean())
            if abs(prev_error - error) < p.convergence:
                return RegistrationResult(T, n, iteration, True)
            prev_error = error
        return RegistrationResult(T, n, p.max_iterations, False)
