"""Doppler 4D-ICP: the paper's Algorithm 1 (Doppler Correspondence combined with ICP).

Facts of the paper (Section "Practical Use") and its public reference code (C++ node):
1. Doppler correspondences from ``doppler``'s matching - the features f(p) = |p|^2 + |p| v_p dT
   and g(q) = |q|^2 - |q| v_q dT, each source point's nearest g in 1-D, kept when
   |f - g| <= tau_doppler and |p - q| <= tau_spatial on the untransformed points - computed
   once before the loop and kept fixed, then moved by the initial guess with the source.
2. Every iteration: closest points of the moved source in the target (within 2.0 m), then one
   Gauss-Newton step of point-to-point residuals r = q - p' with Jacobian [I, -[p']x] on the
   weighted sum (1 - alpha) * huber over the spatial pairs + alpha * huber over the Doppler
   pairs (Huber weight 1 or 0.5 / |r|; not normalised by pair counts), applied on the left.
3. At most 20 iterations; converged when the mean spatial pair distance (before the step)
   changes by less than 1e-4 m.
Parameter sets (paper): radar tau_spatial 3 m, tau_doppler 10 m^2, alpha 0.7; LiDAR 2, 5, 0.9,
chosen by the sequence's sensor kind (``configured_for``) unless set; without a sensor the
radar set is used. The reference code's radar config uses tau_doppler 8 and a fixed period of
1/12 s; here dT comes from the scans' stamps. No downsampling (the reference code's default:
"radar point clouds are already sparse"). The target kd-tree (small_gicp) is built inside the
timed call, as the reference code builds its tree per registration.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import small_gicp
from pydantic import Field

from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo
from loaders.se3 import exp_se3, transform_points
from methods.base import MethodParams, Registration, RegistrationResult, uniform_downsample
from methods.doppler import DopplerScan, doppler_pairs
from methods.icp import closest_points

PARAMETER_SETS = {  # sensor kind -> (tau_spatial [m], tau_doppler [m^2], alpha): the paper
    "radar": (3.0, 10.0, 0.7),
    "lidar": (2.0, 5.0, 0.9),
}


class DopplerIcpParams(MethodParams):
    tau_spatial_m: float | None = Field(None, gt=0, description="Doppler pair spatial gate [m]"
                                        " (None: radar 3, LiDAR 2)")
    tau_doppler: float | None = Field(None, gt=0, description="Doppler pair feature gate "
                                      "[m^2] (None: radar 10, LiDAR 5)")
    alpha: float | None = Field(None, ge=0, le=1, description="weight of the Doppler pairs "
                                "(None: radar 0.7, LiDAR 0.9)")
    max_correspondence_m: float = Field(2.0, gt=0, description="closest-point gate [m]")
    huber_m: float = Field(0.5, gt=0, description="Huber threshold on |r| [m]")
    max_iterations: int = Field(20, ge=1)
    convergence_m: float = Field(1e-4, gt=0, description="stop when the mean spatial pair "
                                 "distance changes less [m]")
    downsample: int = Field(1, ge=1, description="keep every k-th point")
    num_threads: int = Field(1, ge=1, description="kd-tree threads")


@nb.njit(cache=True)
def _accumulate(src, tgt, scale, huber, A, b):  # pragma: no cover - compiled
    """A += scale * sum w J^T J, b += scale * sum w J^T r for r = q - p, J = [I, -[p]x]."""
    J = np.zeros((3, 6))
    J[0, 0] = J[1, 1] = J[2, 2] = 1.0
    r = np.empty(3)
    for i in range(src.shape[0]):
        px, py, pz = src[i, 0], src[i, 1], src[i, 2]
        r[0], r[1], r[2] = tgt[i, 0] - px, tgt[i, 1] - py, tgt[i, 2] - pz
        e = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        w = scale * (1.0 if e <= huber else huber / e)
        # J rows: [1 0 0 | 0 pz -py], [0 1 0 | -pz 0 px], [0 0 1 | py -px 0]
        J[0, 4], J[0, 5] = pz, -py
        J[1, 3], J[1, 5] = -pz, px
        J[2, 3], J[2, 4] = py, -px
        for a in range(6):
            b[a] += w * (J[0, a] * r[0] + J[1, a] * r[1] + J[2, a] * r[2])
            for c in range(a, 6):
                A[a, c] += w * (J[0, a] * J[0, c] + J[1, a] * J[1, c] + J[2, a] * J[2, c])


def gauss_newton_step(spatial_src, spatial_tgt, doppler_src, doppler_tgt, alpha: float,
                      huber: float) -> np.ndarray | None:
    """The twist (rho, phi) of one weighted Gauss-Newton step, or None when singular."""
    A, b = np.zeros((6, 6)), np.zeros(6)
    _accumulate(spatial_src, spatial_tgt, 1.0 - alpha, huber, A, b)
    _accumulate(doppler_src, doppler_tgt, alpha, huber, A, b)
    A = np.triu(A) + np.triu(A, 1).T
    try:
        xi = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return None
    return xi if np.all(np.isfinite(xi)) else None


class DopplerIcp(Registration):
    name = "doppler-icp"
    description = "Doppler 4D-ICP: fixed Doppler pairs + closest points (paper Algorithm 1)"
    Params = DopplerIcpParams

    def configured_for(self, sensor: SensorInfo) -> DopplerIcp:
        tau_s, tau_d, alpha = PARAMETER_SETS[sensor.kind]
        p = self.params
        return DopplerIcp(p, tau_spatial_m=p.tau_spatial_m or tau_s,
                          tau_doppler=p.tau_doppler or tau_d,
                          alpha=p.alpha if p.alpha is not None else alpha)

    def _resolved(self) -> tuple[float, float, float]:
        tau_s, tau_d, alpha = PARAMETER_SETS["radar"]
        p = self.params
        return (p.tau_spatial_m or tau_s, p.tau_doppler or tau_d,
                p.alpha if p.alpha is not None else alpha)

    def preprocess(self, scan: Scan) -> DopplerScan:
        if scan.doppler is None:
            raise DataError(f"{scan.source or 'scan'}: the doppler-icp method needs Doppler "
                            "values")
        scan = uniform_downsample(scan, self.params.downsample)
        return DopplerScan(scan.stamp, np.ascontiguousarray(scan.points.T, dtype=np.float32),
                           scan.doppler.astype(np.float32), scan.points)

    def register(self, source: DopplerScan, target: DopplerScan,
                 init_T_target_source: np.ndarray) -> RegistrationResult:
        p = self.params
        tau_s, tau_d, alpha = self._resolved()
        if len(source) < 3 or len(target) < 3:
            return RegistrationResult(init_T_target_source, 0, 0, False)
        src_idx, tgt_idx = doppler_pairs(source, target, tau_s, tau_d)
        tree = small_gicp.KdTree(target.points, num_threads=p.num_threads)
        T = init_T_target_source.copy()
        doppler_src = transform_points(T, source.points[src_idx])
        doppler_tgt = target.points[tgt_idx]
        moved = transform_points(T, source.points)
        prev_error, n = np.inf, 0
        for iteration in range(1, p.max_iterations + 1):
            idx, dist = closest_points(tree, moved, p.max_correspondence_m, p.num_threads)
            keep = idx >= 0
            n = int(keep.sum())
            xi = gauss_newton_step(moved[keep], target.points[idx[keep]], doppler_src,
                                   doppler_tgt, alpha, p.huber_m)
            if xi is None:
                return RegistrationResult(T, n + len(src_idx), iteration, False)
            delta = exp_se3(xi)
            T = delta @ T
            moved = transform_points(delta, moved)
            doppler_src = transform_points(delta, doppler_src)
            error = float(dist[keep].mean()) if n else 0.0
            if abs(error - prev_error) < p.convergence_m:
                return RegistrationResult(T, n + len(src_idx), iteration, True)
            prev_error = error
        return RegistrationResult(T, n + len(src_idx), p.max_iterations, False)
