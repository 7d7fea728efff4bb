"""Point-to-point ICP, the paper's baseline (Algorithm 1 of the paper's Section III).

Closest points from a kd-tree of the target (built inside the timed call: it is part of the
correspondence search), pairs farther than tau_spatial dropped, closed-form rigid fit, repeat
until the mean pair distance changes by less than ``convergence`` or ``max_iterations``.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field
from scipy.spatial import cKDTree

from loaders.scan import Scan
from loaders.se3 import transform_points
from methods.base import MethodParams, Registration, RegistrationResult, uniform_downsample
from methods.rigid import fit_rigid


class IcpParams(MethodParams):
    max_iterations: int = Field(100, ge=1)
    convergence: float = Field(1e-5, gt=0, description="stop when mean error changes less [m]")
    downsample: int = Field(2, ge=1, description="keep every k-th point")
    tau_spatial_m: float = Field(3.0, gt=0, description="max closest-point distance [m]")
    workers: int = Field(1, description="kd-tree query threads (-1: all cores)")


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
        tree = cKDTree(target.points)
        T = init_T_target_source.copy()
        prev_error = np.inf
        n = 0
        for iteration in range(1, p.max_iterations + 1):
            moved = transform_points(T, source.points)
            dist, idx = tree.query(moved, distance_upper_bound=p.tau_spatial_m,
                                   workers=p.workers)
            keep = np.isfinite(dist)
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
