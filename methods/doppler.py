"""Doppler Correspondence: the paper's non-iterative scan matching (Algorithm 2).

For a source (previous) point p with Doppler v_p and a target (current) point q with Doppler
v_q, the features (paper Eq. 8/9) are

    f(p) = |p|^2 + |p| v_p dT        g(q) = |q|^2 - |q| v_q dT      [m^2]

with dT the time between the two scans (from their stamps, not a nominal rate). Each source
point is matched to the target point with the nearest g in this 1-D feature space (sorting +
binary search, no kd-tree); pairs farther apart than tau_spatial [m] in space or tau_doppler
[m^2] in feature space are dropped, and one closed-form rigid fit gives T_target_source.
No iteration, no robust kernel, no initial guess.

Optional RANSAC (off by default; ``ransac_iterations > 0``). The paper's Algorithm 2 has no
RANSAC; the authors' reference notebook (example/example.ipynb of Tars0523/Doppler_Correspondence)
adds it after the two gates: hypotheses from 3 pairs drawn at random without replacement, a pair
is an inlier when |R p + t - q| < ``ransac_threshold_m``, the hypothesis with the most inliers
wins (the first on ties), the search stops early once more than ``ransac_stop_ratio`` of the
pairs are inliers, and a final rigid fit on the winner's inliers gives T_target_source (the
notebook: 200 hypotheses, 1 m, 0.8). The random generator is NumPy's PCG64 seeded with
``ransac_seed`` afresh in every call, so a registration is a function of its two scans alone.
RANSAC works on the pairs of the reference matching (``doppler_pairs``) with either backend.

Two interchangeable backends compute the same step: ``numpy`` (the reference below, readable
array code) and ``numba`` (``methods.doppler_kernel``: the same order by a compiled radix sort,
then a branch-free merge, the pick and the gates, the sums and the fit, all compiled; the
default, about 10x faster). Both use float32 features and the same tie rules, so they find the
same correspondences (the compiled pairs against a plain NumPy statement of the rule:
tests/test_doppler_pairs_reference.py). ``num_threads`` 2 (numba backend) sorts the source's
and the target's features on two threads; the default is 1. ``preprocess`` only
puts the points in the (3, N) float32 layout both work on; ranges, features, matching, masks
and the fit are all inside ``register``.
Timing (``methods.base``): ``time_ms`` = that layout + ``register``; ``register_ms`` =
``register`` alone.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.errors import DataError
from loaders.scan import Scan
from methods.base import (
    MethodParams,
    Presentation,
    Registration,
    RegistrationResult,
    uniform_downsample,
)
from methods.rigid import fit_rigid_t


class DopplerParams(MethodParams):
    tau_spatial_m: float = Field(3.0, gt=0, description="max |p - q| of a pair [m]")
    tau_doppler: float = Field(5.0, gt=0, description="max |f(p) - g(q)| of a pair [m^2]")
    downsample: int = Field(1, ge=1, description="keep every k-th point")
    backend: Literal["numba", "numpy"] = Field("numba", description="compiled or reference")
    ransac_iterations: int = Field(
        0, ge=0, description="RANSAC hypotheses over the pairs (0: off, as in the paper)")
    ransac_threshold_m: float = Field(
        1.0, gt=0, description="RANSAC inlier when |R p + t - q| is below this [m]")
    ransac_stop_ratio: float = Field(
        0.8, gt=0, le=1, description="RANSAC stops once more than this fraction are inliers")
    ransac_seed: int = Field(0, ge=0, description="seed of RANSAC's random generator (PCG64)")
    num_threads: int = Field(1, ge=1, description="numba backend: 2 or more sorts the two "
                             "scans' features on two threads (no more are used)")


def _feature(points_t: np.ndarray, doppler: np.ndarray, dt_s: float, sign: float) -> np.ndarray:
    """|p|^2 + sign |p| v dT for (3, N) points (contiguous rows: 1-D passes are fast)."""
    r2 = points_t[0] * points_t[0]
    r2 += points_t[1] * points_t[1]
    r2 += points_t[2] * points_t[2]
    r = np.sqrt(r2)
    r *= doppler
    r *= r.dtype.type(sign * dt_s)
    r2 += r
    return r2


def source_feature(points: np.ndarray, doppler: np.ndarray, dt_s: float) -> np.ndarray:
    """f(p) = |p|^2 + |p| v_p dT for the source (previous) scan [m^2]; points (N, 3)."""
    return _feature(np.ascontiguousarray(points.T), np.asarray(doppler), dt_s, 1.0)


def target_feature(points: np.ndarray, doppler: np.ndarray, dt_s: float) -> np.ndarray:
    """g(q) = |q|^2 - |q| v_q dT for the target (current) scan [m^2]; points (N, 3)."""
    return _feature(np.ascontiguousarray(points.T), np.asarray(doppler), dt_s, -1.0)


_U32 = np.uint64(32)
_FLAG = 1 << 31
_SIGN = np.uint32(31)
_TOP = np.uint32(0x80000000)


def _order_key(x: np.ndarray) -> np.ndarray:
    """float -> uint32 whose unsigned order is the float32 order of ``x``."""
    bits = x.astype(np.float32).view(np.uint32)
    return np.where(bits >> _SIGN, ~bits, bits | _TOP)


def _decode_key(key: np.ndarray) -> np.ndarray:
    """Inverse of ``_order_key``: the float32 values."""
    return np.where(key >> _SIGN, key ^ _TOP, ~key).view(np.float32)


def nearest_1d(values: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """Index into ``values`` of the nearest value to each query (1-D nearest neighbour).

    One sort of values and queries together: a uint64 key holds the float32 order key in its
    high 32 bits and the index (plus a query flag) in its low 32 bits, so NumPy's SIMD integer
    sort applies. In the merged order, the values just before and after each query are its
    two candidates; the closer one wins. All comparisons walk the merged order (cache
    friendly); only the final scatter back to query order is random access.

    Same answer as argsort + searchsorted up to ties within float32 resolution (1e-7
    relative: about 1e-3 m^2 at 100 m range, far below the feature noise), and 2-3x faster.
    """
    m, n = len(values), len(queries)
    if m == 0:
        raise ValueError("nearest_1d needs at least one value")
    keys = np.empty(m + n, dtype=np.uint64)
    keys[:m] = _order_key(values)
    keys[m:] = _order_key(queries)
    keys <<= _U32
    keys[:m] |= np.arange(m, dtype=np.uint64)
    keys[m:] |= np.arange(_FLAG, _FLAG + n, dtype=np.uint64)
    keys.sort()
    low = keys.astype(np.uint32)  # index and query flag
    is_query = low >= _FLAG
    query_pos = np.flatnonzero(is_query)
    value_pos = np.flatnonzero(~is_query)
    before = query_pos - np.arange(n)  # values sorted before each query
    lo = value_pos[np.maximum(before - 1, 0)]
    hi = value_pos[np.minimum(before, m - 1)]
    v = _decode_key((keys >> _U32).astype(np.uint32))
    q = v[query_pos]
    pick = np.where(v[hi] - q < q - v[lo], hi, lo)
    nearest = np.empty(n, dtype=np.int64)
    nearest[low[query_pos] - np.uint32(_FLAG)] = low[pick]
    return nearest


@dataclass(frozen=True)
class DopplerScan:
    """A scan prepared for the timed step: (3, N) float32 points and float32 Doppler."""

    stamp: float
    points_t: np.ndarray
    doppler: np.ndarray
    points: np.ndarray | None = None  # (N, 3) float64, for methods that iterate on the points

    def __len__(self) -> int:
        return self.points_t.shape[1]


def doppler_pairs(source: DopplerScan, target: DopplerScan, tau_spatial_m: float,
                  tau_doppler: float) -> tuple[np.ndarray, np.ndarray]:
    """Doppler correspondences (Algorithm 2's matching and masks): indices of the kept source
    points and of their matched target points."""
    dt_s = target.stamp - source.stamp
    P, Q = source.points_t, target.points_t
    f = _feature(P, source.doppler, dt_s, 1.0)
    g = _feature(Q, target.doppler, dt_s, -1.0)
    match = nearest_1d(g, f)
    d = P - np.take(Q, match, axis=1)
    d *= d
    dist2 = d[0] + d[1]
    dist2 += d[2]
    keep = dist2 <= np.float32(tau_spatial_m**2)
    keep &= np.abs(f - g.take(match)) <= np.float32(tau_doppler)
    idx = np.flatnonzero(keep)
    return idx, match[idx]


def register_numpy(source: DopplerScan, target: DopplerScan, tau_spatial_m: float,
                   tau_doppler: float) -> tuple[np.ndarray | None, int]:
    """Reference implementation of one step: (T_target_source or None, correspondences)."""
    src_idx, tgt_idx = doppler_pairs(source, target, tau_spatial_m, tau_doppler)
    if len(src_idx) < 3:
        return None, len(src_idx)
    P64 = np.take(source.points_t, src_idx, axis=1).astype(np.float64)
    Q64 = np.take(target.points_t, tgt_idx, axis=1).astype(np.float64)
    return fit_rigid_t(P64, Q64), len(src_idx)


def register_numba(kernel, source: DopplerScan, target: DopplerScan, tau_spatial_m: float,
                   tau_doppler: float, workspaces=None, pool: ThreadPoolExecutor | None = None
                   ) -> tuple[np.ndarray | None, int]:
    """The same step with the compiled kernel (``methods.doppler_kernel``, imported once by
    the method, outside the timed call): each scan's features sorted with its points (into the
    two ``workspaces``, one per scan, reused from call to call), then the matching and the fit.
    On one thread the two sorts share the first workspace's scratch (features, keys): the
    second sort finds it in the cache. With a ``pool`` (one worker), the source's half runs
    on a second thread, each with its own scratch."""
    dt_s = target.stamp - source.stamp
    if workspaces is None:
        workspaces = (kernel.SortWorkspace(), kernel.SortWorkspace())
    if pool is None:  # grown first, so that the views below all see the same arrays
        workspaces[0].arrays(max(len(source), len(target)))
    src_arrays = workspaces[0].arrays(len(source))
    tgt_arrays = workspaces[1].arrays(len(target))
    if pool is None:
        kernel.sorted_scan_into(source.points_t, source.doppler, dt_s, 1.0, *src_arrays)
        scratch = workspaces[0].arrays(len(target))[:3]
        kernel.sorted_scan_into(target.points_t, target.doppler, dt_s, -1.0, *scratch,
                                *tgt_arrays[3:])
    else:
        pending = pool.submit(kernel.sorted_scan_into, source.points_t, source.doppler, dt_s,
                              1.0, *src_arrays)
        kernel.sorted_scan_into(target.points_t, target.doppler, dt_s, -1.0, *tgt_arrays)
        pending.result()
    # the source's feature scratch (read by the sorts only) holds the pairs of the match
    n, T, fitted = kernel.match_fit_into(*src_arrays[3:], *tgt_arrays[3:], tau_spatial_m**2,
                                         tau_doppler, src_arrays[0].view(np.int32))
    return (T if fitted else None), n


def ransac_rigid(P: np.ndarray, Q: np.ndarray, iterations: int, threshold_m: float,
                 stop_ratio: float, rng: np.random.Generator
                 ) -> tuple[np.ndarray | None, np.ndarray]:
    """RANSAC rigid fit of (3, N) float64 pairs P -> Q: (T_target_source refitted on the best
    hypothesis' inliers, or None when fewer than 3 pairs agree; the inlier mask).

    Each hypothesis is the closed-form fit of 3 pairs drawn without replacement (collinear
    draws are skipped); it replaces the best one only with strictly more inliers."""
    n = P.shape[1]
    best = np.zeros(n, dtype=bool)
    best_count = 0
    if n < 3:
        return None, best
    threshold_sq = threshold_m * threshold_m
    for _ in range(iterations):
        sample = rng.choice(n, 3, replace=False)
        T = fit_rigid_t(P[:, sample], Q[:, sample])
        if T is None:
            continue
        r = T[:3, :3] @ P
        r += T[:3, 3:]
        r -= Q
        inliers = np.einsum("ij,ij->j", r, r) < threshold_sq
        count = int(inliers.sum())
        if count > best_count:
            best, best_count = inliers, count
            if count > stop_ratio * n:
                break
    if best_count < 3:
        return None, best
    return fit_rigid_t(P[:, best], Q[:, best]), best


def register_ransac(params: DopplerParams, source: DopplerScan, target: DopplerScan
                    ) -> tuple[np.ndarray | None, int]:
    """One step with RANSAC over the gated pairs: (T_target_source or None, inliers)."""
    src_idx, tgt_idx = doppler_pairs(source, target, params.tau_spatial_m, params.tau_doppler)
    P64 = np.take(source.points_t, src_idx, axis=1).astype(np.float64)
    Q64 = np.take(target.points_t, tgt_idx, axis=1).astype(np.float64)
    T, inliers = ransac_rigid(P64, Q64, params.ransac_iterations, params.ransac_threshold_m,
                              params.ransac_stop_ratio, np.random.default_rng(params.ransac_seed))
    return T, int(inliers.sum())


class DopplerCorrespondence(Registration):
    name = "doppler"
    reads_fields = frozenset({"doppler"})
    presentation = Presentation("Doppler Correspondence (Ours)", "#d62728", 5)
    description = "Doppler Correspondence, non-iterative (paper Algorithm 2); no initial guess"
    needs_doppler = True
    motion_prior = None
    uses_initial_guess = False
    Params = DopplerParams

    def __init__(self, params: DopplerParams | None = None, **overrides) -> None:
        super().__init__(params, **overrides)
        self._step = register_numpy
        if self.params.backend == "numba":
            from methods import doppler_kernel  # numba loads only when this backend is used

            pool = ThreadPoolExecutor(1) if self.threads > 1 else None
            # sorting scratch reused by every call (one instance registers one pair at a time)
            workspaces = (doppler_kernel.SortWorkspace(), doppler_kernel.SortWorkspace())
            self._step = partial(register_numba, doppler_kernel, workspaces=workspaces,
                                 pool=pool)

    def warm_up(self, sequence) -> None:
        if self.params.backend == "numba":
            from methods import doppler_kernel

            doppler_kernel.warm_up()  # every compiled path, not only the warm-up pair's
        super().warm_up(sequence)

    @property
    def threads(self) -> int:
        """Threads it computes with: 2 at most (the two scans' halves), 1 for the NumPy
        backend and RANSAC."""
        p = self.params
        one = p.backend == "numpy" or p.ransac_iterations > 0
        return 1 if one else min(p.num_threads, 2)

    def preprocess(self, scan: Scan) -> DopplerScan:
        if scan.doppler is None:
            raise DataError(f"{scan.source or 'scan'}: the doppler method needs Doppler values")
        scan = uniform_downsample(scan, self.params.downsample)
        return DopplerScan(scan.stamp, np.ascontiguousarray(scan.points.T, dtype=np.float32),
                           scan.doppler.astype(np.float32))

    def register(self, source: DopplerScan, target: DopplerScan,
                 init_T_target_source: np.ndarray) -> RegistrationResult:
        if len(source) < 3 or len(target) < 3:
            return RegistrationResult(init_T_target_source, 0, 1, False)
        p = self.params
        if p.ransac_iterations:
            T, n = register_ransac(p, source, target)
        else:
            T, n = self._step(source, target, p.tau_spatial_m, p.tau_doppler)
        if T is None:
            return RegistrationResult(init_T_target_source, n, 1, False)
        return RegistrationResult(T, n, 1, True)
