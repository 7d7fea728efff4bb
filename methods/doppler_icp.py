"""Doppler 4D-ICP: the paper's Algorithm 1 (Doppler Correspondence combined with ICP).

Returns T_target_source: source = previous scan, target = current scan, both in the sensor
frame; points in m, Doppler in m/s (positive receding), dT [s] from the scans' stamps.

Facts of the paper (Section "Practical Use") and its public reference code
(github.com/Tars0523/Doppler_Correspondence, pipeline/icp_doppler.cpp, icp_iter.cpp):
1. Doppler correspondences from ``doppler``'s matching (``methods.doppler.doppler_pairs``: the
   features f(p) = |p|^2 + |p| v_p dT and g(q) = |q|^2 - |q| v_q dT in float32, each source
   point's nearest g in 1-D with the same tie rules, kept when |f - g| <= tau_doppler and
   |p - q| <= tau_spatial on the untransformed points), computed once before the loop and kept
   fixed, then moved by the initial guess with the source.
2. Every iteration: closest points of the moved source in the target (exact; pairs closer
   than 2.0 m, strict as the reference), then one
   Gauss-Newton step of point-to-point residuals r = q - p' with Jacobian [I, -[p']x] on the
   weighted sum (1 - alpha) * Huber over the spatial pairs + alpha * Huber over the Doppler
   pairs (Huber weight 1 or 0.5 / |r| on the residual norm; not normalised by pair counts),
   applied on the left.
3. At most 20 iterations; converged when the mean distance of the iteration's spatial pairs
   (before its step) changes by less than 1e-4 m.
Parameter sets (paper): radar tau_spatial 3 m, tau_doppler 10 m^2, alpha 0.7; LiDAR 2, 5, 0.9,
chosen by the sequence's sensor kind (``configured_for``) unless set; without a sensor the
radar set is used. The reference code's radar config uses tau_doppler 8 (not 10) and a fixed
period of 1/12 s; here dT comes from the scans' stamps. Downsampling as the reference code:
a uniform stride on both scans before the Doppler pairs, default 1 ("radar point clouds are
already sparse"), in ``preprocess``. The reference code builds the target's kd-tree per
registration; here (one thread) ``preprocess`` builds each scan's kd-tree once
(``methods.kdtree``, compiled): the new scan's is searched in its step (as the target), and
orders the searches of the next (as the source). The closest-point searches keep each point's
pair while it moves less than the gap to its second nearest point
(``methods.kdtree.NearestTracker``: exact, the same pairs). With
``num_threads`` > 1 they are small_gicp's parallel kd-tree's, built per call. The Doppler
pairs come from ``methods.doppler_kernel.pairs``, the compiled twin of
``methods.doppler.doppler_pairs`` (the same pairs, bit for bit). Timing (``methods.base``):
``time_ms`` = ``preprocess`` (stride, layouts, kd-tree) + ``register``; ``register_ms`` =
``register`` alone (Doppler pairs, iterations). The reference's 1-D search is a
PCL kd-tree on float32 casts of double features: the same pairs up to ties and rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import small_gicp
from pydantic import Field

from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo
from loaders.se3 import exp_se3
from methods import doppler_kernel
from methods.base import (
    MethodParams,
    Presentation,
    Registration,
    RegistrationResult,
    uniform_downsample,
)
from methods.dicp_kernel import transform as _transform
from methods.doppler import DopplerScan
from methods.kdtree import FAR, KdTree, NearestTracker
from methods.kdtree import warm_up as _warm_up_tree

#: the closest-point searches keep a point's pair while it moves less than the gap to its
#: second nearest when its pair was at least this far [m] (``methods.kdtree.NearestTracker``;
#: nearer ones are searched again every iteration, which is cheaper there); the answers do not
#: depend on it
TRACK_M = 0.1

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
def _accumulate(src, tgt, tgt_idx, scale, huber, A, b):  # pragma: no cover - compiled
    """A += scale * sum w J^T J, b += scale * sum w J^T r over the pairs (src[i], tgt[tgt_idx[i]])
    with tgt_idx[i] >= 0, for r = q - p, J = [I, -[p]x] (the step is applied on the left) and the
    Huber weight w = 1 if |r| <= huber else huber / |r|. Returns (pairs, sum of |r| [m]).

    Only the upper triangle of A is filled (``gauss_newton_step`` mirrors it)."""
    n, dist_sum = 0, 0.0
    for i in range(src.shape[0]):
        k = tgt_idx[i]
        if k < 0:
            continue
        px, py, pz = src[i, 0], src[i, 1], src[i, 2]
        rx, ry, rz = tgt[k, 0] - px, tgt[k, 1] - py, tgt[k, 2] - pz
        e = np.sqrt(rx * rx + ry * ry + rz * rz)
        w = scale * (1.0 if e <= huber else huber / e)
        n += 1
        dist_sum += e
        # J^T r = (r, p x r); J^T J = [[I, -[p]x], [[p]x, -[p]x^2]] (with [p]x^T = -[p]x)
        cx, cy, cz = py * rz - pz * ry, pz * rx - px * rz, px * ry - py * rx
        b[0] += w * rx
        b[1] += w * ry
        b[2] += w * rz
        b[3] += w * cx
        b[4] += w * cy
        b[5] += w * cz
        A[0, 0] += w
        A[1, 1] += w
        A[2, 2] += w
        A[0, 4] += w * pz
        A[0, 5] -= w * py
        A[1, 3] -= w * pz
        A[1, 5] += w * px
        A[2, 3] += w * py
        A[2, 4] -= w * px
        xx, yy, zz = px * px, py * py, pz * pz
        A[3, 3] += w * (yy + zz)
        A[4, 4] += w * (xx + zz)
        A[5, 5] += w * (xx + yy)
        A[3, 4] -= w * px * py
        A[3, 5] -= w * px * pz
        A[4, 5] -= w * py * pz
    return n, dist_sum


def normal_equations(spatial: tuple, doppler: tuple, alpha: float, huber: float):
    """(A, b, spatial pairs, mean spatial |r| [m]) of the weighted sum (1 - alpha) * Huber over
    the spatial pairs + alpha * Huber over the Doppler pairs; each pair set is (source points
    (N, 3), target points (M, 3), target index per source point, -1 for none)."""
    A, b = np.zeros((6, 6)), np.zeros(6)
    n, dist_sum = _accumulate(*spatial, 1.0 - alpha, huber, A, b)
    _accumulate(*doppler, alpha, huber, A, b)
    A = np.triu(A) + np.triu(A, 1).T
    return A, b, n, (dist_sum / n if n else 0.0)


def solve_step(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The twist (rho, phi) solving A xi = b, or None when A is singular."""
    try:
        xi = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return None
    return xi if np.all(np.isfinite(xi)) else None


def gauss_newton_step(spatial_src, spatial_tgt, doppler_src, doppler_tgt, alpha: float,
                      huber: float) -> np.ndarray | None:
    """One weighted Gauss-Newton step for paired rows (src[i], tgt[i]) (test helper)."""
    A, b, _, _ = normal_equations(
        (spatial_src, spatial_tgt, np.arange(len(spatial_src))),
        (doppler_src, doppler_tgt, np.arange(len(doppler_src))), alpha, huber)
    return solve_step(A, b)


def warm_up() -> None:
    """Compile (or load from numba's cache) once, so no timed call pays for it."""
    p = np.ones((2, 3))
    _accumulate(p, p, np.zeros(2, dtype=np.int64), 1.0, 0.5, np.zeros((6, 6)), np.zeros(6))
    _transform(np.eye(4), p)
    _warm_up_tree()
    doppler_kernel.warm_up()


@dataclass(frozen=True)
class DopplerIcpScan(DopplerScan):
    """A ``DopplerScan`` with its kd-tree (one thread; None on several)."""

    tree: KdTree | None = None


class DopplerIcp(Registration):
    name = "doppler-icp"
    reads_fields = frozenset({"doppler"})
    presentation = Presentation("Doppler 4D-ICP (Ours)", "#ff7f0e", 6)
    description = "Doppler 4D-ICP: fixed Doppler pairs + closest points (paper Algorithm 1)"
    needs_doppler = True
    Params = DopplerIcpParams

    def warm_up(self, sequence) -> None:
        warm_up()  # every compiled path, not only the warm-up pair's
        super().warm_up(sequence)

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

    def preprocess(self, scan: Scan) -> DopplerIcpScan:
        if scan.doppler is None:
            raise DataError(f"{scan.source or 'scan'}: the doppler-icp method needs Doppler "
                            "values")
        scan = uniform_downsample(scan, self.params.downsample)
        points = np.ascontiguousarray(scan.points, dtype=np.float64)
        # one thread: the compiled kd-tree of the scan, built once here (the scan is the
        # target of one step, then the source of the next)
        tree = KdTree(points) if self.params.num_threads == 1 and len(points) else None
        return DopplerIcpScan(scan.stamp, np.ascontiguousarray(scan.points.T, dtype=np.float32),
                              scan.doppler.astype(np.float32), points, tree)

    def register(self, source: DopplerScan, target: DopplerIcpScan,
                 init_T_target_source: np.ndarray) -> RegistrationResult:
        p = self.params
        tau_s, tau_d, alpha = self._resolved()
        if len(source) < 3 or len(target) < 3:
            return RegistrationResult(init_T_target_source, 0, 0, False)
        # Doppler pairs: once, on the untransformed points, then kept (moved with the source)
        src_idx, tgt_idx = doppler_kernel.pairs(source.points_t, source.doppler,
                                                target.points_t, target.doppler,
                                                target.stamp - source.stamp, tau_s**2, tau_d)
        tree = getattr(target, "tree", None)
        searched = tree is not None
        if not searched:  # several threads: small_gicp's parallel search
            tree = small_gicp.KdTree(target.points, num_threads=p.num_threads)
        else:
            # the source's points visited in its own kd-tree's order (``NearestTracker``)
            tree_s = getattr(source, "tree", None)
            order = tree_s.arrays[1] if tree_s is not None else None
            nearest = NearestTracker(tree, len(source), p.max_correspondence_m**2,
                                     (FAR * p.max_correspondence_m)**2, TRACK_M, order)
        T = init_T_target_source.copy()
        doppler_src = _transform(T, source.points[src_idx])
        moved = _transform(T, source.points)
        max_sq = p.max_correspondence_m**2
        prev_error, n = np.inf, 0
        for iteration in range(1, p.max_iterations + 1):
            if searched:
                # strictly within the gate, as the reference code's; a point that moved less
                # than the gap to its second nearest keeps its pair (exact, see
                # ``methods.kdtree.nearest_tracked``); others are searched again
                idx, sq = nearest(moved)
            else:
                idx, sq = self._nearest(tree, moved, p.num_threads)
                idx[~(sq < max_sq)] = -1  # strict, as the reference code's gate
            A, b, n, error = normal_equations((moved, target.points, idx),
                                              (doppler_src, target.points, tgt_idx),
                                              alpha, p.huber_m)
            xi = solve_step(A, b)
            if xi is None:
                return RegistrationResult(T, n + len(src_idx), iteration, False)
            delta = exp_se3(xi)
            T = delta @ T
            moved = _transform(delta, moved)
            doppler_src = _transform(delta, doppler_src)
            # the mean distance of this iteration's pairs, before the step (as the reference)
            if abs(error - prev_error) < p.convergence_m:
                return RegistrationResult(T, n + len(src_idx), iteration, True)
            prev_error = error
        return RegistrationResult(T, n + len(src_idx), p.max_iterations, False)

    @staticmethod
    def _nearest(tree, points: np.ndarray, num_threads: int) -> tuple[np.ndarray, np.ndarray]:
        """(closest target index (int64, -1 for none), squared distance [m^2]) per point."""
        # batch_knn_search returns arrays (batch_nearest_neighbor_search returns lists, whose
        # conversion costs ~2 ms per 60k points)
        idx, sq = tree.batch_knn_search(points, 1, num_threads=num_threads)
        return idx.ravel().view(np.int64), sq.ravel()
