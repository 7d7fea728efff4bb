"""The compiled Doppler Correspondence step (``methods.doppler_kernel``, the default backend)
against a straightforward NumPy reference of the same rule: the same pairs, index for index,
and the same transform (to 1e-9), on random scans (ties and edge cases included) and on real
radar frames.

The reference states the rule once, plainly: each point's feature as the kernel rounds it
(float32 |p|^2 plus the Doppler term in float64, rounded to float32), the target's features
in stable sorted order, the number of target features <= each source feature
(``searchsorted``), the nearer of the two around it (the lower one on a tie) and both gates
compared in float64, then one rigid fit of the kept pairs."""

import numpy as np
import pytest

from conftest import constant_twist_sequence, real_sample_store
from methods import doppler_kernel as kernel
from methods.doppler import DopplerCorrespondence, DopplerScan
from methods.rigid import fit_rigid_t


def reference_features(points_t: np.ndarray, doppler: np.ndarray, dt_s: float,
                       sign: float) -> np.ndarray:
    x, y, z = (points_t[a].astype(np.float32) for a in range(3))
    r2 = x * x + y * y + z * z  # float32, left to right
    term = sign * np.sqrt(r2).astype(np.float64) * doppler.astype(np.float64) * dt_s
    return (r2.astype(np.float64) + term).astype(np.float32)


def reference_pairs(source: DopplerScan, target: DopplerScan, tau_spatial_m: float,
                    tau_doppler: float) -> tuple[np.ndarray, np.ndarray]:
    """(source indices ascending, their target indices) of the kept pairs."""
    dt_s = target.stamp - source.stamp
    f = reference_features(source.points_t, source.doppler, dt_s, 1.0)
    g = reference_features(target.points_t, target.doppler, dt_s, -1.0)
    order = np.argsort(g, kind="stable")
    gs = g[order]
    below = np.searchsorted(gs, f, side="right")  # target features <= f
    lo = np.maximum(below - 1, 0)
    hi = np.minimum(below, len(gs) - 1)
    pick = np.where(gs[hi] - f < f - gs[lo], hi, lo)
    match = order[pick]
    d = source.points_t - target.points_t[:, match]
    dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    keep = (dist2.astype(np.float64) <= tau_spatial_m**2) & (
        np.abs(f - g[match]).astype(np.float64) <= tau_doppler)
    idx = np.flatnonzero(keep)
    return idx, match[idx]


def compiled_pairs(source: DopplerScan, target: DopplerScan, tau_spatial_m: float,
                   tau_doppler: float) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's pairs (``sorted_scan_into`` + ``pair_sorted``), in original indices."""
    dt_s = target.stamp - source.stamp
    s, t = kernel.SortWorkspace().arrays(len(source)), kernel.SortWorkspace().arrays(len(target))
    s_keys = kernel.sorted_scan_into(source.points_t, source.doppler, dt_s, 1.0, *s)
    t_keys = kernel.sorted_scan_into(target.points_t, target.doppler, dt_s, -1.0, *t)
    pair = np.empty(len(source), dtype=np.int32)
    kernel.pair_sorted(s[3], s[4], t[3], t[4], tau_spatial_m**2, tau_doppler, pair)
    s_order = (s_keys & np.uint64(0xFFFFFFFF)).astype(np.int64)
    t_order = (t_keys & np.uint64(0xFFFFFFFF)).astype(np.int64)
    kept = np.flatnonzero(pair >= 0)
    src, tgt = s_order[kept], t_order[pair[kept]]
    first = np.argsort(src)
    return src[first], tgt[first]


def assert_same_step(source: DopplerScan, target: DopplerScan, tau_spatial_m: float = 3.0,
                     tau_doppler: float = 5.0) -> int:
    ref_src, ref_tgt = reference_pairs(source, target, tau_spatial_m, tau_doppler)
    got_src, got_tgt = compiled_pairs(source, target, tau_spatial_m, tau_doppler)
    np.testing.assert_array_equal(got_src, ref_src)
    np.testing.assert_array_equal(got_tgt, ref_tgt)
    if min(len(source), len(target)) < 3:  # the method does not register such scans
        return len(ref_src)
    method = DopplerCorrespondence(tau_spatial_m=tau_spatial_m, tau_doppler=tau_doppler)
    result = method.register(source, target, np.eye(4))
    assert result.correspondences == len(ref_src)
    expected = fit_rigid_t(source.points_t[:, ref_src].astype(np.float64),
                           target.points_t[:, ref_tgt].astype(np.float64))
    assert result.converged == (expected is not None)
    if expected is not None:
        np.testing.assert_allclose(result.T_target_source, expected, rtol=0, atol=1e-9)
    return len(ref_src)


def scan(stamp: float, points_t: np.ndarray, doppler: np.ndarray) -> DopplerScan:
    return DopplerScan(stamp, np.ascontiguousarray(points_t, dtype=np.float32),
                       np.ascontiguousarray(doppler, dtype=np.float32))


@pytest.mark.parametrize("n_points", [3000, 64000])
def test_random_scans_give_the_reference_pairs_and_transform(n_points):
    seq = constant_twist_sequence(n_frames=3, n_points=n_points, noise_m=0.02)
    method = DopplerCorrespondence()
    for k in range(2):
        src, tgt = method.preprocess(seq[k]), method.preprocess(seq[k + 1])
        assert assert_same_step(src, tgt) > 500  # dense random points: most pairs gated
        assert_same_step(src, tgt, 0.5, 0.2)  # tight gates: most pairs dropped


def test_ties_and_equal_features_across_the_scans_give_the_reference_pairs():
    # coordinates on a coarse grid and few Doppler values: many equal features within each
    # scan and between the two (the rank counts equal target features; the lower one wins)
    rng = np.random.default_rng(7)
    pts = rng.integers(-6, 7, (3, 5000)).astype(np.float32)
    dop = rng.integers(-2, 3, 5000).astype(np.float32)
    src = scan(0.0, pts, dop)
    tgt = scan(0.1, pts[:, ::-1] + rng.integers(0, 2, (3, 5000)), dop[::-1])
    f = reference_features(src.points_t, src.doppler, 0.1, 1.0)
    g = reference_features(tgt.points_t, tgt.doppler, 0.1, -1.0)
    assert np.isin(f, g).sum() > 1000 and len(np.unique(g)) < len(g) // 10  # ties, both kinds
    assert assert_same_step(src, tgt) > 300
    assert_same_step(src, scan(0.1, pts[:, ::2], np.zeros(2500)))  # Doppler term zero
    # every source feature below / above every target feature: the ends of the target
    far = scan(0.1, pts * 50, dop)
    assert_same_step(src, far, 1e3, 1e9)
    assert_same_step(far, src, 1e3, 1e9)


@pytest.mark.parametrize("n_src, n_tgt", [(3, 1), (3, 2), (3, 3), (5, 3), (1000, 4), (4, 1000)])
def test_small_and_unequal_scans_give_the_reference_pairs(n_src, n_tgt):
    rng = np.random.default_rng(n_src * 31 + n_tgt)
    src = scan(0.0, rng.uniform(-20, 20, (3, n_src)), rng.uniform(-5, 5, n_src))
    tgt = scan(0.1, rng.uniform(-20, 20, (3, n_tgt)), rng.uniform(-5, 5, n_tgt))
    assert_same_step(src, tgt, 40.0, 1e4)


def test_real_radar_frames_give_the_reference_pairs_and_transform():
    from loaders.store import StoreSequence

    seq = StoreSequence(real_sample_store())
    method = DopplerCorrespondence()
    try:
        scans = [method.preprocess(seq[i]) for i in range(0, 60, 6)]
    finally:
        seq.close()
    counts = [assert_same_step(a, b) for a, b in zip(scans[:-1], scans[1:], strict=True)]
    assert min(counts) > 100
