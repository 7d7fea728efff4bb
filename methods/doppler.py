"""Doppler Correspondence: the paper's non-iterative scan matching (Algorithm 2).

For a source (previous) point p with Doppler v_p and a target (current) point q with Doppler
v_q, the features (paper Eq. 8/9) are

    f(p) = |p|^2 + |p| v_p dT        g(q) = |q|^2 - |q| v_q dT      [m^2]

with dT the time between the two scans (from their stamps, not a nominal rate). Each source
point is matched to the target point with the nearest g in this 1-D feature space (sorting +
binary search, no kd-tree); pairs farther apart than tau_spatial [m] in space or tau_doppler
[m^2] in feature space are dropped, and one closed-form rigid fit gives T_target_source.
No iteration, no robust kernel, no initial guess.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from loaders.errors import DataError
from loaders.scan import Scan
from methods.base import MethodParams, Registration, RegistrationResult, uniform_downsample
from methods.rigid import fit_rigid


class DopplerParams(MethodParams):
    tau_spatial_m: float = Field(3.0, gt=0, description="max |p - q| of a pair [m]")
    tau_doppler: float = Field(5.0, gt=0, description="max |f(p) - g(q)| of a pair [m^2]")
    downsample: int = Field(1, ge=1, description="keep every k-th point")


def source_feature(points: np.ndarray, doppler: np.ndarray, dt_s: float) -> np.ndarray:
    """f(p) = |p|^2 + |p| v_p dT for the source (previous) scan [m^2]."""
    r = np.sqrt(np.einsum("ij,ij->i", points, points))
    return r * (r + doppler * dt_s)


def target_feature(points: np.ndarray, doppler: np.ndarray, dt_s: float) -> np.ndarray:
    """g(q) = |q|^2 - |q| v_q dT for the target (current) scan [m^2]."""
    r = np.sqrt(np.einsum("ij,ij->i", points, points))
    return r * (r - doppler * dt_s)


_U32 = np.uint64(32)
_QUERY_FLAG = 1 << 31


def _order_key(x: np.ndarray) -> np.ndarray:
    """float -> uint64 whose unsigned order is the float32 order of ``x`` (high 32 bits)."""
    bits = x.astype(np.float32).view(np.uint32)
    flipped = np.where(bits >> np.uint32(31), ~bits, bits | np.uint32(0x80000000))
    return flipped.astype(np.uint64) << _U32


def nearest_1d(values: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """Index into ``values`` of the nearest value to each query (1-D nearest neighbour).

    One sort of the values and queries together (float32 sort key in the high 32 bits, index
    and a query flag in the low 32 bits of a uint64, so NumPy's SIMD integer sort applies); the
    number of values before a query in the merged order gives its two neighbours, and the
    closer one in float64 wins. Equivalent to argsort + searchsorted on the values, up to ties
    within float32 resolution (about 1e-7 relative: 1e-3 m^2 at 100 m range), and about twice
    as fast.
    """
    m, n = len(values), len(queries)
    if m == 0:
        raise ValueError("nearest_1d needs at least one value")
    keys = np.empty(m + n, dtype=np.uint64)
    keys[:m] = _order_key(values)
    keys[:m] |= np.arange(m, dtype=np.uint64)
    keys[m:] = _order_key(queries)
    keys[m:] |= np.arange(_QUERY_FLAG, _QUERY_FLAG + n, dtype=np.uint64)
    keys.sort()
    low = (keys & np.uint64(0xFFFFFFFF)).astype(np.int64)
    is_query = low >= _QUERY_FLAG
    query_pos = np.flatnonzero(is_query)
    value_order = low[~is_query]  # value indices in ascending order
    query_idx = low[query_pos] - _QUERY_FLAG
    before = query_pos - np.arange(n)  # values sorted before each query
    lo = value_order[np.maximum(before - 1, 0)]
    hi = value_order[np.minimum(before, m - 1)]
    q = queries[query_idx]
    nearest = np.empty(n, dtype=np.int64)
    nearest[query_idx] = np.where(np.abs(values[hi] - q) < np.abs(q - values[lo]), hi, lo)
    return nearest


class DopplerCorrespondence(Registration):
    name = "doppler"
    description = "Doppler Correspondence, non-iterative (paper Algorithm 2); no initial guess"
    uses_initial_guess = False
    Params = DopplerParams

    def preprocess(self, scan: Scan) -> Scan:
        if scan.doppler is None:
            raise DataError(f"{scan.source or 'scan'}: the doppler method needs Doppler values")
        return uniform_downsample(scan, self.params.downsample)

    def register(self, source: Scan, target: Scan, init_T_target_source: np.ndarray):
        p = self.params
        if len(source) < 3 or len(target) < 3:
            return RegistrationResult(init_T_target_source, 0, 1, False)
        dt_s = target.stamp - source.stamp
        f = source_feature(source.points, source.doppler, dt_s)
        g = target_feature(target.points, target.doppler, dt_s)
        match = nearest_1d(g, f)
        matched = target.points[match]
        diff = source.points - matched
        keep = (np.einsum("ij,ij->i", diff, diff) <= p.tau_spatial_m**2) & (
            np.abs(f - g[match]) <= p.tau_doppler
        )
        n = int(keep.sum())
        T = fit_rigid(source.points[keep], matched[keep]) if n >= 3 else None
        if T is None:
            return RegistrationResult(init_T_target_source, n, 1, False)
        return RegistrationResult(T, n, 1, True)
