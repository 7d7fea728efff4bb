"""``dicp`` with ``backend=open3d``: the authors' own implementation, upstream in Open3D, run
on the scans ``methods.dicp`` prepared (downsampled, vehicle frame, directions, normals from
Open3D's own ``estimate_normals``: hybrid search, 10 m, at most 30 neighbours, in ``preprocess``
as the authors' script estimates them before registration)."""

from __future__ import annotations

import numpy as np

from loaders.errors import DataError


def _open3d():
    try:
        import open3d as o3d
    except ImportError as err:
        raise DataError("dicp backend=open3d needs Open3D: pip install 'doppler-bench[open3d]'"
                        " (on Debian also: apt-get install libusb-1.0-0); import failed: "
                        f"{err}") from None
    return o3d


def estimate_normals_open3d(points: np.ndarray, radius_m: float, max_neighbours: int
                            ) -> np.ndarray:
    """(N, 3) normals of ``points`` [m] by Open3D's ``estimate_normals`` with the hybrid search
    (at most ``max_neighbours`` within ``radius_m``).

    Open3D's legacy point cloud: the tensor cloud's ``estimate_normals`` computes the same
    normals (the same neighbours and eigensolver; measured equal within 1e-11, up to the sign,
    which DICP's point-to-plane terms do not see) but its hybrid search took about 6 s per
    32k-point LiDAR scan against 0.1-0.2 s here."""
    o3d = _open3d()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
        np.ascontiguousarray(points, dtype=np.float64)))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius_m,
                                                                max_nn=max_neighbours))
    return np.asarray(cloud.normals)


def _tukey(kernel, k: float):
    """Open3D's Tukey kernel of width ``k``; k = 0 (the parameter's "none") is plain least
    squares, as in ``methods.dicp_kernel``: Open3D's Tukey of width 0 weighs every residual 0
    (its solve then fails on a singular system)."""
    if k <= 0:
        return kernel.RobustKernel(kernel.RobustKernelMethod.L2Loss, 1.0)
    return kernel.RobustKernel(kernel.RobustKernelMethod.TukeyLoss, k)


def register_open3d(params, source, target, T_init: np.ndarray, period_s: float,
                    T_vehicle_sensor: np.ndarray) -> tuple[np.ndarray, int, int, bool]:
    """(T_target_source in the vehicle frame, pairs, iterations, converged)."""
    o3d = _open3d()
    reg = o3d.t.pipelines.registration
    f64 = o3d.core.float64
    src = o3d.t.geometry.PointCloud(o3d.core.Tensor(source.points, f64))
    src.point["dopplers"] = o3d.core.Tensor(source.doppler.reshape(-1, 1), f64)
    src.point["directions"] = o3d.core.Tensor(source.directions, f64)
    tgt = o3d.t.geometry.PointCloud(o3d.core.Tensor(target.points, f64))
    tgt.point.normals = o3d.core.Tensor(target.normals, f64)
    estimation = reg.TransformationEstimationForDopplerICP(
        period=period_s, lambda_doppler=params.lambda_doppler,
        reject_dynamic_outliers=params.reject_dynamic,
        doppler_outlier_threshold=params.dynamic_threshold_mps,
        outlier_rejection_min_iteration=params.reject_from,
        geometric_robust_loss_min_iteration=params.geometric_kernel_from,
        doppler_robust_loss_min_iteration=params.doppler_kernel_from,
        geometric_kernel=_tukey(reg.robust_kernel, params.geometric_kernel),
        doppler_kernel=_tukey(reg.robust_kernel, params.doppler_kernel),
        transform_vehicle_to_sensor=o3d.core.Tensor(T_vehicle_sensor, f64))
    iterations = []  # the transform after each step (Open3D's callback)
    T_start = o3d.core.Tensor(T_init, f64)
    try:
        result = reg.icp(src, tgt, params.max_correspondence_m, T_start, estimation,
                         reg.ICPConvergenceCriteria(params.convergence, params.convergence,
                                                    params.max_iterations),
                         -1.0, lambda info: iterations.append(info["transformation"].numpy()))
    except RuntimeError as error:
        if "Singular" not in str(error):
            raise
        # as the numba backend: a step whose system is singular ends the registration, not
        # converged, at the transform before it, with that transform's pairs; the failed
        # step counts
        T = iterations[-1] if iterations else T_init
        fit = reg.evaluate_registration(src, tgt, params.max_correspondence_m,
                                        o3d.core.Tensor(T, f64))
        return T, int(round(fit.fitness * len(source.points))), len(iterations) + 1, False
    pairs = int(round(result.fitness * len(source.points)))
    # iterations: Gauss-Newton steps, counted by the callbacks (Open3D 0.20's num_iterations
    # equals them, measured; the source of 0.17-0.19 reads as counting one fewer on converging)
    return result.transformation.numpy(), pairs, len(iterations), bool(result.converged)
