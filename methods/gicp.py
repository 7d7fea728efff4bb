"""Point-to-plane ICP, Generalized-ICP and VGICP through small_gicp (Koide), the baselines of
the paper's Tables IV and V.

The paper does not list these baselines' parameters, so they follow its point-to-point ICP
(Section IV-A): uniform downsampling by 2, correspondences within tau_spatial = 3 m, at most
100 iterations, converged when an update changes the transform by less than 1e-5 (m and
rad; small_gicp's defaults, 1 mm and 0.1 deg, stop earlier than the paper's ICP would).
Normals / covariances come from 20 nearest neighbours (small_gicp's default).

Preparation (untimed, like downsampling): each scan becomes a small_gicp ``PointCloud`` with
normals and covariances, computed with a kd-tree of the scan that is kept and reused as the
target's search tree (as small_gicp's own ``preprocess_points`` does); for VGICP the target's
Gaussian voxel map is also built then. Timed (inside ``register``): small_gicp's registration
alone, i.e. per iteration the correspondence search (kd-tree, or voxel lookup for VGICP) and
the Gauss-Newton linearisation and solve. The target kd-tree build is not timed here, unlike
icp-p2p / dicp / doppler-icp, which build it inside their timed call (about 4.5 ms per 30k
points on this machine; add it when comparing).

VGICP voxel resolution 1.0 m: small_gicp's default. Measured here on synthetic pairs
(seeded; median translation error, time): radar (4k points) 0.5 m 2.7 cm but it never
converges within 100 iterations (16 ms), 1.0 m 6.2 cm / 2.3 ms, 2.0 m 13 cm, 3.0 m 27 cm;
LiDAR (61k) 0.5 m 0.3 cm / 32 ms, 1.0 m 1.5 cm / 25 ms, 2.0 m 2.1 cm, 3.0 m 7.5 cm. So 1.0 m
is kept for both sensor kinds: finer never converges on radar (voxels of one or two points),
coarser loses accuracy on both.

Threads: ``num_threads`` 1 by default. On this 2-core machine, shared with other jobs, 2
threads measured slower for every method here (OpenMP threads wait for each other when a core
is busy), and one thread keeps the comparison with the single-threaded methods fair.
small_gicp takes (N, 3) float64 points only: a 4th column would be read as homogeneous w.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import small_gicp
from pydantic import Field

from loaders.scan import Scan
from methods.base import MethodParams, Registration, RegistrationResult, uniform_downsample


class GicpParams(MethodParams):
    downsample: int = Field(2, ge=1, description="keep every k-th point (paper's ICP: 2)")
    max_correspondence_m: float = Field(3.0, gt=0, description="max pair distance [m] "
                                        "(paper's ICP tau_spatial)")
    max_iterations: int = Field(100, ge=1, description="paper's ICP: 100")
    convergence: float = Field(1e-5, gt=0, description="stop when an update moves less "
                               "[m, rad] (paper's ICP: 1e-5)")
    neighbours: int = Field(20, ge=5, description="neighbours for normals / covariances")
    voxel_size_m: float = Field(1.0, gt=0, description="VGICP voxel resolution [m]")
    num_threads: int = Field(1, ge=1, description="small_gicp threads")


@dataclass(frozen=True)
class GicpScan:
    """A scan prepared for small_gicp: cloud with normals and covariances, its kd-tree and,
    for VGICP, its Gaussian voxel map."""

    cloud: small_gicp.PointCloud
    tree: small_gicp.KdTree
    voxels: small_gicp.GaussianVoxelMap | None

    def __len__(self) -> int:
        return self.cloud.size()


class _SmallGicp(Registration):
    Params = GicpParams
    registration_type: ClassVar[str]

    def preprocess(self, scan: Scan) -> GicpScan:
        p = self.params
        points = np.ascontiguousarray(uniform_downsample(scan, p.downsample).points,
                                      dtype=np.float64)
        cloud = small_gicp.PointCloud(points)
        tree = small_gicp.KdTree(cloud, num_threads=p.num_threads)
        if len(points) >= 5:
            small_gicp.estimate_normals_covariances(cloud, tree, p.neighbours, p.num_threads)
        voxels = None
        if self.registration_type == "VGICP":
            voxels = small_gicp.GaussianVoxelMap(p.voxel_size_m)
            voxels.insert(cloud)
        return GicpScan(cloud, tree, voxels)

    def register(self, source: GicpScan, target: GicpScan,
                 init_T_target_source: np.ndarray) -> RegistrationResult:
        p = self.params
        if len(source) < 5 or len(target) < 5:
            return RegistrationResult(init_T_target_source, 0, 0, False)
        if target.voxels is not None:
            r = small_gicp.align(target.voxels, source.cloud, init_T_target_source,
                                 max_correspondence_distance=p.max_correspondence_m,
                                 num_threads=p.num_threads, max_iterations=p.max_iterations,
                                 rotation_epsilon=p.convergence,
                                 translation_epsilon=p.convergence)
        else:
            r = small_gicp.align(target.cloud, source.cloud, target.tree, init_T_target_source,
                                 registration_type=self.registration_type,
                                 max_correspondence_distance=p.max_correspondence_m,
                                 num_threads=p.num_threads, max_iterations=p.max_iterations,
                                 rotation_epsilon=p.convergence,
                                 translation_epsilon=p.convergence)
        ok = bool(r.converged) and r.num_inliers >= 6
        return RegistrationResult(np.asarray(r.T_target_source), int(r.num_inliers),
                                  int(r.iterations), ok)


class PointToPlaneIcp(_SmallGicp):
    name = "icp-p2plane"
    description = "Point-to-plane ICP (small_gicp), paper Tables IV/V baseline"
    registration_type = "PLANE_ICP"


class GeneralizedIcp(_SmallGicp):
    name = "gicp"
    description = "Generalized-ICP (small_gicp), paper Tables IV/V baseline"
    registration_type = "GICP"


class VoxelizedGicp(_SmallGicp):
    name = "vgicp"
    description = "Voxelized GICP (small_gicp), paper Tables IV/V baseline"
    registration_type = "VGICP"
