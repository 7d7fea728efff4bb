"""The compiled kernel of Doppler Correspondence against NumPy: its radix sort against
``np.sort``, its sorted halves against an argsort, and its step against the NumPy reference on
one and two threads."""

import numpy as np
import pytest

from conftest import constant_twist_sequence
from methods import doppler_kernel as kernel
from methods.doppler import DopplerCorrespondence, DopplerScan, doppler_pairs


@pytest.mark.parametrize("n", [0, 1, 7, 5000, 70000])
def test_radix_sort_equals_numpy_sort(n):
    rng = np.random.default_rng(n)
    # features with repeats, negative values and a wide range of magnitudes
    values = np.concatenate([rng.normal(0, 1e4, n - n // 4),
                             rng.choice([0.0, -0.0, 3.5, 1e-30], n // 4)]).astype(np.float32)
    keys = kernel.sort_keys(values)
    np.testing.assert_array_equal(kernel.sorted_keys(values), np.sort(keys))
    # sorted by the high halves only, stably
    high = (keys >> np.uint64(32)).astype(np.uint32) if n else keys
    np.testing.assert_array_equal(kernel.radix_sort_high32(keys),
                                  keys[np.argsort(high, kind="stable")])


def test_a_pass_with_one_digit_is_skipped_without_changing_the_answer():
    values = np.full(1000, 7.25, dtype=np.float32)  # one key: no pass moves anything
    values[::3] = np.nextafter(np.float32(7.25), np.float32(8))  # one low digit differs
    keys = kernel.sort_keys(values)
    np.testing.assert_array_equal(kernel.sorted_keys(values), np.sort(keys))
    pts, vals = kernel.sorted_scan(np.ones((3, 1000), np.float32) * np.arange(1000,
                                   dtype=np.float32), np.zeros(1000, np.float32), 0.1, 1.0)
    assert np.all(np.diff(vals) >= 0)


def test_sorted_halves_are_the_argsort_of_the_features():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-80, 80, (3, 20000)).astype(np.float32)
    dop = rng.uniform(-20, 20, 20000).astype(np.float32)
    f = kernel.features(pts, dop, 0.1, -1.0)
    order = np.argsort(f, kind="stable")  # float32 order, ties by index
    got_pts, got_f = kernel.sorted_scan(pts, dop, 0.1, -1.0)
    np.testing.assert_array_equal(got_f, f[order])
    np.testing.assert_array_equal(got_pts, pts[:, order])
    # into reused, larger arrays: the same
    ws = kernel.SortWorkspace()
    ws.arrays(30000)
    arrays = ws.arrays(20000)
    kernel.sorted_scan_into(pts, dop, 0.1, -1.0, *arrays)
    np.testing.assert_array_equal(arrays[3], pts[:, order])
    np.testing.assert_array_equal(arrays[4], f[order])


@pytest.mark.parametrize("threads", [1, 2])
def test_the_step_equals_the_numpy_reference(threads):
    seq = constant_twist_sequence(n_frames=4, n_points=6000, noise_m=0.02)
    fast = DopplerCorrespondence(num_threads=threads)
    ref = DopplerCorrespondence(backend="numpy")
    assert fast.threads == threads and ref.threads == 1
    for k in range(3):  # the workspaces are reused from pair to pair
        src, tgt = fast.preprocess(seq[k]), fast.preprocess(seq[k + 1])
        a, b = fast.register(src, tgt, np.eye(4)), ref.register(src, tgt, np.eye(4))
        assert a.correspondences == b.correspondences == len(doppler_pairs(src, tgt, 3.0,
                                                                           5.0)[0]) > 100
        np.testing.assert_allclose(a.T_target_source, b.T_target_source, atol=1e-9)
    # the sums of kept pairs: those of the reference's pairs
    ps, fs = kernel.sorted_scan(src.points_t, src.doppler, tgt.stamp - src.stamp, 1.0)
    qs, gs = kernel.sorted_scan(tgt.points_t, tgt.doppler, tgt.stamp - src.stamp, -1.0)
    n, sum_p, sum_q, sum_pq = kernel.match_sorted(ps, fs, qs, gs, 9.0, 5.0)
    s_idx, t_idx = doppler_pairs(src, tgt, 3.0, 5.0)
    P = src.points_t[:, s_idx].astype(float)
    Q = tgt.points_t[:, t_idx].astype(float)
    assert n == len(s_idx)
    np.testing.assert_allclose(sum_p, P.sum(axis=1))
    np.testing.assert_allclose(sum_q, Q.sum(axis=1))
    np.testing.assert_allclose(sum_pq, P @ Q.T)


@pytest.mark.parametrize("tau_spatial, tau_doppler", [(3.0, 5.0), (2.0, 5.0), (0.5, 0.2)])
def test_compiled_pairs_equal_doppler_pairs(tau_spatial, tau_doppler):
    seq = constant_twist_sequence(n_frames=3, n_points=6000, noise_m=0.02)
    m = DopplerCorrespondence()
    for k in range(2):
        src, tgt = m.preprocess(seq[k]), m.preprocess(seq[k + 1])
        ref = doppler_pairs(src, tgt, tau_spatial, tau_doppler)
        got = kernel.pairs(src.points_t, src.doppler, tgt.points_t, tgt.doppler,
                           tgt.stamp - src.stamp, tau_spatial**2, tau_doppler)
        np.testing.assert_array_equal(got[0], ref[0])
        np.testing.assert_array_equal(got[1], ref[1])
    # ties: repeated features and points
    src = DopplerScan(0.0, np.repeat(src.points_t[:, :50], 3, axis=1),
                      np.repeat(src.doppler[:50], 3))
    tgt = DopplerScan(0.1, np.repeat(tgt.points_t[:, :60], 2, axis=1),
                      np.repeat(tgt.doppler[:60], 2))
    ref = doppler_pairs(src, tgt, tau_spatial, tau_doppler)
    got = kernel.pairs(src.points_t, src.doppler, tgt.points_t, tgt.doppler, 0.1,
                       tau_spatial**2, tau_doppler)
    np.testing.assert_array_equal(got[0], ref[0])
    np.testing.assert_array_equal(got[1], ref[1])
