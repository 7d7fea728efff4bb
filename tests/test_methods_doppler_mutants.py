"""methods/doppler.py against answers worked out by hand or by brute force: the features from
their definition, the 1-D nearest neighbour against an argmin, the gates at their boundaries,
a scan moved by a known rigid transform (Doppler chosen so that every true pair has equal
features), RANSAC with a scripted generator, and the method's own rules (threads, layout,
results)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from methods import doppler, doppler_kernel
from methods.doppler import (
    DopplerCorrespondence,
    DopplerScan,
    doppler_pairs,
    nearest_1d,
    ransac_rigid,
    register_numba,
    register_numpy,
    register_ransac,
)
from methods.rigid import fit_rigid_t

DT = 0.1
R_TRUE = Rotation.from_euler("zyx", [0.03, -0.01, 0.02]).as_matrix()
T_TRUE = np.eye(4)
T_TRUE[:3, :3] = R_TRUE
T_TRUE[:3, 3] = [0.4, -0.15, 0.05]


def _scan(stamp, points, dop):
    return DopplerScan(stamp, np.ascontiguousarray(np.asarray(points, float).T, np.float32),
                       np.asarray(dop, np.float32))


def _moved_pair(n=40, seed=1, perm=True):
    """Source points at ranges 5, 7, 9, ... m in random directions, the target the same points
    moved by T_TRUE (in shuffled order); both scans' Doppler (|q| - |p|) / dT, so that
    f(p) = g(q) = |p| |q| for every true pair and the features of different points are metres
    squared apart. Returns (source, target, order): target point k is source point order[k]."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    P = d * (5.0 + 2.0 * np.arange(n))[:, None]
    Q = P @ R_TRUE.T + T_TRUE[:3, 3]
    v = (np.linalg.norm(Q, axis=1) - np.linalg.norm(P, axis=1)) / DT
    order = rng.permutation(n) if perm else np.arange(n)
    return _scan(2.0, P, v), _scan(2.0 + DT, Q[order], v[order]), order


# ---- features and the 1-D nearest neighbour ------------------------------------------------

def test_features_follow_their_definition():
    P = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -2.0], [1.0, 2.0, 2.0]])
    v = np.array([1.5, -2.0, 0.25])
    r = np.array([5.0, 2.0, 3.0])
    np.testing.assert_allclose(doppler.source_feature(P, v, 0.2), r**2 + r * v * 0.2,
                               rtol=1e-6)
    np.testing.assert_allclose(doppler.target_feature(P, v, 0.2), r**2 - r * v * 0.2,
                               rtol=1e-6)


def test_order_keys_sort_as_the_floats_and_decode_back():
    x = np.array([3.5, -0.0, -7.25, 0.0, 1e-30, -1e30, 2.0, -1e-3, np.inf, -np.inf],
                 np.float32)
    keys = doppler._order_key(x)
    assert keys.dtype == np.uint32
    assert np.all(np.diff(x[np.argsort(keys)]) >= 0)
    assert list(np.argsort(keys, kind="stable")[[0, -1]]) == [9, 8]
    # strictly increasing keys for strictly increasing floats (and -0 before +0)
    ordered = np.array([-np.inf, -1e30, -7.25, -1e-3, -0.0, 0.0, 1e-30, 2.0, 3.5, np.inf],
                       np.float32)
    assert np.all(np.diff(doppler._order_key(ordered).astype(np.int64)) > 0)
    np.testing.assert_array_equal(doppler._decode_key(keys), x)


def _brute_nearest(values, queries):
    v = values.astype(np.float32).astype(np.float64)
    q = queries.astype(np.float32).astype(np.float64)
    return np.argmin(np.abs(q[:, None] - v[None, :]), axis=1)


@pytest.mark.parametrize("m, n", [(1, 5), (2, 7), (50, 300), (300, 40)])
def test_nearest_1d_is_the_argmin(m, n):
    rng = np.random.default_rng(m * 1000 + n)
    values = rng.uniform(-100, 100, m)
    queries = rng.uniform(-130, 130, n)  # some below and above every value
    np.testing.assert_array_equal(nearest_1d(values, queries), _brute_nearest(values, queries))


def test_nearest_1d_at_the_ends_and_between_two_values():
    values = np.array([10.0, -5.0, 3.0])
    queries = np.array([-50.0, 50.0, 2.0, 4.0, -1.5, 6.4, 6.6])
    np.testing.assert_array_equal(nearest_1d(values, queries), [1, 0, 2, 2, 1, 2, 0])
    assert nearest_1d(values, queries).dtype == np.int64


def test_nearest_1d_takes_the_lower_value_on_a_tie():
    values = np.array([3.0, 1.0, 7.0])
    np.testing.assert_array_equal(nearest_1d(values, np.array([2.0, 5.0])), [1, 0])


def test_nearest_1d_needs_a_value():
    with pytest.raises(ValueError, match="^nearest_1d needs at least one value$"):
        nearest_1d(np.array([]), np.array([1.0]))


# ---- the pairs and their gates --------------------------------------------------------------

def test_the_pairs_of_a_moved_scan_are_its_true_pairs():
    source, target, order = _moved_pair()
    src, tgt = doppler_pairs(source, target, 3.0, 5.0)
    np.testing.assert_array_equal(src, np.arange(len(source)))
    np.testing.assert_array_equal(order[tgt], src)


def test_the_spatial_gate_keeps_exactly_the_pairs_within_it():
    source, target, order = _moved_pair()
    P = source.points_t.T.astype(np.float64)
    Q = target.points_t.T.astype(np.float64)[np.argsort(order)]
    dist = np.linalg.norm(P - Q, axis=1)
    tau = float(np.median(dist))
    src, tgt = doppler_pairs(source, target, tau, 5.0)
    np.testing.assert_array_equal(src, np.flatnonzero(dist <= tau))
    np.testing.assert_array_equal(order[tgt], src)


def test_the_doppler_gate_drops_pairs_whose_features_differ_more():
    source, target, order = _moved_pair(perm=False)
    dop = source.doppler.copy()
    r = np.linalg.norm(source.points_t.astype(np.float64), axis=0)
    # feature offsets |p| dv dT of 7 and 3 m^2 (the next point's feature is > 20 m^2 away)
    dop[4] += 7.0 / (r[4] * DT)
    dop[9] -= 3.0 / (r[9] * DT)
    src, tgt = doppler_pairs(DopplerScan(source.stamp, source.points_t, dop), target, 3.0, 5.0)
    np.testing.assert_array_equal(src, np.delete(np.arange(len(source)), 4))
    np.testing.assert_array_equal(tgt, src)


def test_both_gates_are_inclusive():
    # exact in float32: |p - q| = 3, f(p) = 16 + 4 * 5 * 0.5 = 26, g(q) = 25 - 5 * 0.5 * 0.5
    source = _scan(1.0, [[4.0, 0.0, 0.0]], [5.0])
    target = _scan(1.5, [[4.0, 3.0, 0.0]], [0.5])
    assert doppler_pairs(source, target, 3.0, 2.25)[0].tolist() == [0]
    assert doppler_pairs(source, target, 2.99, 2.25)[0].tolist() == []
    assert doppler_pairs(source, target, 3.0, 2.24)[0].tolist() == []
    src, tgt = doppler_pairs(source, target, 3.0, 2.25)
    assert tgt.tolist() == [0]


# ---- one registration step, both backends ---------------------------------------------------

def test_numpy_step_recovers_the_known_motion():
    source, target, _ = _moved_pair()
    T, n = register_numpy(source, target, 3.0, 5.0)
    assert n == len(source)
    np.testing.assert_allclose(T, T_TRUE, atol=2e-5)


def test_numpy_step_needs_three_pairs():
    source, target, _ = _moved_pair(n=3, perm=False)
    assert register_numpy(source, target, 3.0, 5.0)[0] is not None
    two = DopplerScan(source.stamp, source.points_t[:, :2].copy(), source.doppler[:2].copy())
    assert register_numpy(two, target, 3.0, 5.0) == (None, 2)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("given", [False, True])
def test_numba_step_recovers_the_known_motion(threads, given):
    source, target, _ = _moved_pair(n=40)
    pool = ThreadPoolExecutor(1) if threads > 1 else None
    spaces = (doppler_kernel.SortWorkspace(), doppler_kernel.SortWorkspace()) if given else None
    try:
        for _ in range(2):  # workspaces reused from call to call
            T, n = register_numba(doppler_kernel, source, target, 3.0, 5.0, spaces, pool)
            assert n == len(source)
            np.testing.assert_allclose(T, T_TRUE, atol=2e-5)
        # a smaller target after a larger pair: the scratch is not stale
        small_t = DopplerScan(target.stamp, target.points_t[:, :30].copy(),
                              target.doppler[:30].copy())
        T, n = register_numba(doppler_kernel, source, small_t, 3.0, 5.0, spaces, pool)
        assert n == 30
        np.testing.assert_allclose(T, T_TRUE, atol=2e-5)
        far = register_numba(doppler_kernel, source, target, 0.01, 5.0, spaces, pool)
        assert far == (None, 0)
    finally:
        if pool is not None:
            pool.shutdown()


# ---- RANSAC ---------------------------------------------------------------------------------

class _Scripted:
    """A generator whose ``choice`` returns the given samples in turn (and counts its calls)."""

    def __init__(self, samples):
        self.samples = [np.asarray(s) for s in samples]
        self.calls = 0

    def choice(self, n, k, replace=True):
        assert k == 3 and replace is False
        self.calls += 1
        return self.samples[(self.calls - 1) % len(self.samples)]


def _ransac_data(n_in=12, n_out=4, seed=3):
    rng = np.random.default_rng(seed)
    P = rng.uniform(-10, 10, (3, n_in + n_out))
    Q = R_TRUE @ P + T_TRUE[:3, 3:]
    Q[:, n_in:] += rng.uniform(3, 5, (3, n_out)) * rng.choice([-1, 1], (3, n_out))
    truth = np.arange(n_in + n_out) < n_in
    return P, Q, truth


def test_ransac_finds_the_inliers_and_refits_on_them():
    P, Q, truth = _ransac_data()
    T, mask = ransac_rigid(P, Q, 50, 1.0, 0.8, np.random.default_rng(0))
    np.testing.assert_array_equal(mask, truth)
    np.testing.assert_allclose(T, T_TRUE, atol=1e-9)


def test_ransac_skips_a_collinear_draw_and_keeps_the_first_of_equals():
    P, Q, truth = _ransac_data()
    P[:, 12], Q[:, 12] = 0.5 * (P[:, 0] + P[:, 1]), 0.5 * (Q[:, 0] + Q[:, 1])  # collinear
    truth[12] = True
    # a collinear draw, then an outlier draw (3 + its own inliers), then the good one twice
    rng = _Scripted([[0, 1, 12], [13, 14, 15], [0, 1, 2], [3, 4, 5]])
    T, mask = ransac_rigid(P, Q, 4, 1.0, 0.99, rng)
    assert rng.calls == 4
    np.testing.assert_array_equal(mask, truth)
    np.testing.assert_allclose(T, T_TRUE, atol=1e-9)


def test_ransac_keeps_the_first_of_two_equally_good_hypotheses():
    """Two groups of six pairs, each moved rigidly by its own motion: each group's hypothesis
    has six inliers; the first drawn wins (a tie never replaces it)."""
    rng = np.random.default_rng(8)
    P = rng.uniform(-10, 10, (3, 12))
    T_b = np.eye(4)
    T_b[:3, 3] = [5.0, 0.0, 0.0]
    Q = np.hstack([R_TRUE @ P[:, :6] + T_TRUE[:3, 3:], P[:, 6:] + T_b[:3, 3:]])
    for first, T_first in (([0, 1, 2], T_TRUE), ([6, 7, 8], T_b)):
        second = [9, 10, 11] if first[0] == 0 else [3, 4, 5]
        T, mask = ransac_rigid(P, Q, 2, 0.5, 0.9, _Scripted([first, second]))
        np.testing.assert_allclose(T, T_first, atol=1e-9)
        assert mask.tolist() == [k // 6 == first[0] // 6 for k in range(12)]


def test_ransac_stops_once_more_than_the_ratio_agree():
    P, Q, _ = _ransac_data(n_in=10, n_out=0)
    early = _Scripted([[0, 1, 2]])
    ransac_rigid(P, Q, 5, 1.0, 0.8, early)
    assert early.calls == 1
    never = _Scripted([[0, 1, 2]])  # all agree: not *more* than all
    ransac_rigid(P, Q, 5, 1.0, 1.0, never)
    assert never.calls == 5
    P, Q, _ = _ransac_data(n_in=8, n_out=2)  # 8 of 10 agree: not more than 0.8
    exact = _Scripted([[0, 1, 2]])
    ransac_rigid(P, Q, 3, 1.0, 0.8, exact)
    assert exact.calls == 3


def test_ransac_threshold_is_a_distance_in_metres():
    P, Q, _ = _ransac_data(n_in=10, n_out=0)
    Q[:, 9] += [1.5, 0.0, 0.0]  # 1.5 m off: an inlier within 2 m (but not within 2**2 = 4
    # of a squared 1.5 m, 2.25, mistaken for a distance), an outlier within 1 m
    T, mask = ransac_rigid(P, Q, 1, 2.0, 1.0, _Scripted([[0, 1, 2]]))
    assert mask.all()
    T, mask = ransac_rigid(P, Q, 1, 1.0, 1.0, _Scripted([[0, 1, 2]]))
    assert mask.sum() == 9 and not mask[9]
    T, mask = ransac_rigid(P, Q, 1, 1.6, 1.0, _Scripted([[0, 1, 2]]))
    assert mask.all()


def test_ransac_without_three_agreeing_pairs_has_no_answer():
    P, Q, _ = _ransac_data()
    T, mask = ransac_rigid(P[:, :2], Q[:, :2], 10, 1.0, 0.8, np.random.default_rng(0))
    assert T is None and mask.tolist() == [False, False] and mask.dtype == bool
    T, mask = ransac_rigid(P, Q, 0, 1.0, 0.8, np.random.default_rng(0))
    assert T is None and not mask.any() and mask.shape == (16,) and mask.dtype == bool
    T, mask = ransac_rigid(P[:, :3], Q[:, :3], 1, 1.0, 0.8, np.random.default_rng(0))
    np.testing.assert_allclose(T, T_TRUE, atol=1e-9)  # three pairs are enough
    assert mask.tolist() == [True] * 3
    rng = np.random.default_rng(1)
    P3, Q3 = rng.uniform(-5, 5, (3, 6)), rng.uniform(-5, 5, (3, 6))
    # random pairs: a three-pair fit passes through none of them
    T, mask = ransac_rigid(P3, Q3, 30, 1e-6, 0.8, np.random.default_rng(2))
    assert T is None and not mask.any()
    # three exact pairs and three random ones: exactly three agree, enough for an answer
    Q3[:, :3] = R_TRUE @ P3[:, :3] + T_TRUE[:3, 3:]
    T, mask = ransac_rigid(P3, Q3, 1, 1e-6, 0.8, _Scripted([[0, 1, 2]]))
    assert mask.tolist() == [True] * 3 + [False] * 3
    np.testing.assert_allclose(T, T_TRUE, atol=1e-9)


def test_the_best_hypothesis_is_kept_even_with_a_single_inlier():
    """Three pairs that no rigid motion explains: the fit to all three leaves one residual
    below a threshold set between the smallest two: no answer, the mask of that one pair."""
    rng = np.random.default_rng(7)
    P, Q = rng.uniform(-5, 5, (3, 3)), rng.uniform(-5, 5, (3, 3))
    T = fit_rigid_t(P, Q)
    residuals = np.sort(np.linalg.norm(T[:3, :3] @ P + T[:3, 3:] - Q, axis=0))
    threshold = float(np.mean(residuals[:2]))
    T, mask = ransac_rigid(P, Q, 1, threshold, 0.8, _Scripted([[0, 1, 2]]))
    assert T is None and mask.sum() == 1


def test_register_ransac_draws_from_its_seed():
    """One hypothesis: which pairs it draws (a seeded PCG64, afresh per call) decides the
    answer; the same as RANSAC on the gated pairs with that seed's generator."""
    source, target, _ = _moved_pair(n=12, perm=False)
    Q = target.points_t.astype(np.float64).copy()
    Q[:, ::4] *= 1.0 + 0.5 / np.linalg.norm(Q[:, ::4], axis=0)  # 3 of 12 pairs 0.5 m off
    P = source.points_t.astype(np.float64)
    v = ((np.linalg.norm(Q, axis=0) - np.linalg.norm(P, axis=0)) / DT).astype(np.float32)
    src = DopplerScan(source.stamp, source.points_t, v)
    tgt = DopplerScan(target.stamp, np.ascontiguousarray(Q, np.float32), v)
    answers = set()
    for seed in range(8):
        params = DopplerCorrespondence.Params(ransac_iterations=1, ransac_threshold_m=0.05,
                                              ransac_seed=seed)
        T, n = register_ransac(params, src, tgt)
        i, j = doppler_pairs(src, tgt, params.tau_spatial_m, params.tau_doppler)
        P64 = src.points_t[:, i].astype(np.float64)
        Q64 = tgt.points_t[:, j].astype(np.float64)
        T_ref, mask = ransac_rigid(P64, Q64, 1, 0.05, 0.8, np.random.default_rng(seed))
        assert n == mask.sum()
        assert (T is None) == (T_ref is None)
        if T is not None:
            np.testing.assert_array_equal(T, T_ref)
        assert register_ransac(params, src, tgt)[1] == n  # afresh in every call
        answers.add(None if T is None else T.tobytes())
    assert len(answers) == 2  # the seed matters: no answer, or the good pairs' answer


def test_register_ransac_recovers_the_motion_despite_bad_doppler_pairs():
    source, target, order = _moved_pair(n=40, perm=False)
    # five target points moved 2 m along their ray with their Doppler matching: the features
    # still pair them, their positions are wrong
    Q = target.points_t.astype(np.float64).copy()
    bad = [3, 11, 17, 25, 33]
    Q[:, bad] *= 1.0 + 0.3 / np.linalg.norm(Q[:, bad], axis=0)
    P = source.points_t.astype(np.float64)
    v = ((np.linalg.norm(Q, axis=0) - np.linalg.norm(P, axis=0)) / DT).astype(np.float32)
    src = DopplerScan(source.stamp, source.points_t, v)
    tgt = DopplerScan(target.stamp, np.ascontiguousarray(Q, np.float32), v)
    params = DopplerCorrespondence.Params(ransac_iterations=100, ransac_threshold_m=0.1,
                                          ransac_seed=4)
    T, n = register_ransac(params, src, tgt)
    assert n == 35
    np.testing.assert_allclose(T, T_TRUE, atol=2e-5)
    method = DopplerCorrespondence(params)
    result = method.register(src, tgt, np.eye(4))
    assert result.correspondences == 35 and result.converged
    np.testing.assert_allclose(result.T_target_source, T_TRUE, atol=2e-5)
    plain = DopplerCorrespondence(backend="numpy").register(src, tgt, np.eye(4))
    assert plain.correspondences == 40
    assert np.abs(plain.T_target_source - T_TRUE).max() > 1e-3  # the bad pairs pull it off


# ---- the method -----------------------------------------------------------------------------

@pytest.mark.parametrize("params, threads", [
    ({}, 1), ({"num_threads": 2}, 2), ({"num_threads": 5}, 2),
    ({"num_threads": 4, "backend": "numpy"}, 1),
    ({"num_threads": 4, "ransac_iterations": 10}, 1)])
def test_threads(params, threads):
    m = DopplerCorrespondence(**params)
    assert m.threads == threads
    assert m.clock == ("cpu" if threads == 1 else "wall")


def test_preprocess_lays_out_float32_rows_and_downsamples():
    pts = np.arange(30, dtype=float).reshape(10, 3)
    scan = Scan(4.5, pts, np.linspace(-1, 1, 10))
    prepared = DopplerCorrespondence(downsample=3).preprocess(scan)
    assert prepared.stamp == 4.5 and len(prepared) == 4
    assert prepared.points_t.dtype == np.float32 and prepared.points_t.flags.c_contiguous
    np.testing.assert_array_equal(prepared.points_t, pts[::3].T)
    assert prepared.doppler.dtype == np.float32
    np.testing.assert_allclose(prepared.doppler, np.linspace(-1, 1, 10)[::3], rtol=1e-6)
    with pytest.raises(DataError, match="frame 7: the doppler method needs Doppler values"):
        DopplerCorrespondence().preprocess(Scan(0.0, pts, None, source="frame 7"))
    with pytest.raises(DataError, match="^scan: the doppler method needs"):
        DopplerCorrespondence().preprocess(Scan(0.0, pts, None))


@pytest.mark.parametrize("params", [{"backend": "numpy"}, {}, {"num_threads": 2}])
def test_register_results(params):
    method = DopplerCorrespondence(**params)
    source, target, _ = _moved_pair()
    init = np.diag([1.0, 1.0, 1.0, 1.0])
    init[0, 3] = 7.0
    r = method.register(source, target, init)
    assert (r.correspondences, r.iterations, r.converged) == (len(source), 1, True)
    np.testing.assert_allclose(r.T_target_source, T_TRUE, atol=2e-5)
    short = DopplerScan(source.stamp, source.points_t[:, :2].copy(), source.doppler[:2].copy())
    for a, b in ((short, target), (source, short)):
        r = method.register(a, b, init)
        assert r.T_target_source is init and (r.correspondences, r.iterations,
                                              r.converged) == (0, 1, False)
    three_s, three_t, _ = _moved_pair(n=3, perm=False)  # three points are enough
    r = method.register(three_s, three_t, init)
    assert (r.correspondences, r.converged) == (3, True)
    np.testing.assert_allclose(r.T_target_source, T_TRUE, atol=2e-5)
    far = DopplerCorrespondence(tau_spatial_m=0.01, **params).register(source, target, init)
    assert far.T_target_source is init
    assert (far.correspondences, far.iterations, far.converged) == (0, 1, False)


def test_warm_up_compiles_every_path_then_runs_the_pair(monkeypatch):
    calls = []
    monkeypatch.setattr(doppler_kernel, "warm_up", lambda: calls.append("kernel"))
    seq = MemorySequence("s", SensorInfo("radar", 0.1), [Scan(0.0, np.ones((4, 3)), np.ones(4)),
                                                         Scan(0.1, np.ones((4, 3)), np.ones(4))])
    for backend, expected in (("numba", ["kernel", "run"]), ("numpy", ["run"])):
        calls.clear()
        m = DopplerCorrespondence(backend=backend)
        m.run = lambda sequence, seed, on_frame=None: calls.append("run")
        m.warm_up(seq)
        assert calls == expected


def _spy_sorts(monkeypatch):
    """Record each compiled sort's thread and the address its sorted points go to."""
    import threading

    calls = []
    real = doppler_kernel.sorted_scan_into

    def spy(*args):
        # the array is kept alive: a buffer allocated afresh cannot take its address
        calls.append((threading.get_ident(), args[7].__array_interface__["data"][0], args[7]))
        return real(*args)

    monkeypatch.setattr(doppler_kernel, "sorted_scan_into", spy)
    return calls


@pytest.mark.parametrize("backend, threads, sorts, threaded", [
    ("numba", 1, 2, False), ("numba", 2, 2, True), ("numpy", 1, 0, False),
    ("numpy", 2, 0, False)])
def test_the_backend_and_its_threads_are_the_ones_asked_for(monkeypatch, backend, threads,
                                                            sorts, threaded):
    import threading

    calls = _spy_sorts(monkeypatch)
    method = DopplerCorrespondence(backend=backend, num_threads=threads)
    source, target, _ = _moved_pair()
    for _ in range(2):
        method.register(source, target, np.eye(4))
    assert len(calls) == 2 * sorts
    if sorts:
        main = threading.get_ident()
        assert any(t != main for t, _, _ in calls) == threaded
        # the sorting scratch is reused from call to call (one workspace per scan role)
        first, second = {a for _, a, _ in calls[:2]}, {a for _, a, _ in calls[2:]}
        assert first == second and len(first) == 2
