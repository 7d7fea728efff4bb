"""The compiled kd-tree against scipy's cKDTree and brute force, and DICP's compiled normals
against NumPy's eigh on the same neighbourhoods."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from methods.dicp_kernel import (
    _smallest_eigenvector,
    neighbourhood_normals,
    normals_from_neighbours,
    pair_bounds,
)
from methods.kdtree import KdTree, NearestTracker


def _cloud(n, seed):
    """A LiDAR-like mix: a dense ground plane, a wall, scattered points, duplicates."""
    rng = np.random.default_rng(seed)
    ground = np.column_stack([rng.uniform(-20, 20, n // 2), rng.uniform(-20, 20, n // 2),
                              rng.normal(0, 0.01, n // 2)])
    wall = np.column_stack([rng.uniform(-20, 20, n // 4), np.full(n // 4, 7.0),
                            rng.uniform(0, 3, n // 4)])
    rest = rng.uniform(-30, 30, (n - n // 2 - n // 4 - 10, 3))
    pts = np.vstack([ground, wall, rest])
    return np.vstack([pts, pts[:10]])  # exact duplicates


@pytest.mark.parametrize("k, max_dist", [(1, np.inf), (2, np.inf), (1, 0.3), (30, 10.0),
                                         (30, 0.5)])
def test_knn_equals_scipy(k, max_dist):
    pts = _cloud(6000, 0)
    queries = np.vstack([pts[::7] + np.random.default_rng(1).normal(0, 0.2, (len(pts[::7]), 3)),
                         pts[:50], [[500.0, 0, 0]]])
    tree = KdTree(pts, leaf_size=5)
    idx, sq = tree.knn(queries, k, max_dist)
    ref_d, ref_i = cKDTree(pts).query(queries, k, distance_upper_bound=max_dist)
    ref_d, ref_i = ref_d.reshape(len(queries), k), ref_i.reshape(len(queries), k)
    found = np.isfinite(ref_d) & (ref_d < max_dist)
    np.testing.assert_array_equal(idx >= 0, found)
    np.testing.assert_allclose(np.sqrt(sq[found]), ref_d[found], rtol=1e-12, atol=1e-12)
    # the indices are scipy's up to ties (duplicates): the distances they give are the same
    got = np.sqrt(((pts[idx[found]] - np.repeat(queries, k, 0).reshape(-1, k, 3)[found]) ** 2)
                  .sum(-1))
    np.testing.assert_allclose(got, ref_d[found], rtol=1e-12, atol=1e-12)
    assert all(len(set(row[row >= 0])) == (row >= 0).sum() for row in idx)  # distinct


def test_per_query_bounds_against_brute_force():
    pts = _cloud(3000, 2)
    rng = np.random.default_rng(3)
    queries = pts[rng.choice(len(pts), 400)] + rng.normal(0, 0.3, (400, 3))
    bounds = rng.uniform(0, 1.0, 400)
    idx, sq = KdTree(pts).knn(queries, 3, bounds_sq=bounds)
    d2 = ((queries[:, None, :] - pts[None, :, :]) ** 2).sum(-1)
    for i in range(len(queries)):
        inside = np.sort(d2[i][d2[i] < bounds[i]])[:3]
        np.testing.assert_allclose(sq[i][: len(inside)], inside, rtol=1e-12)
        assert np.all(idx[i][len(inside):] == -1)


def test_pair_bounds_are_the_last_pairs_distances_capped_by_the_gate():
    moved = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]])
    target = np.array([[0.1, 0, 0], [1.0, 0.2, 0]])
    b = pair_bounds(moved, target, np.array([0, 1, 0]), 0.09)
    d2 = ((moved - target[[0, 1, 0]]) ** 2).sum(1)
    assert b[0] == np.nextafter(d2[0], np.inf) and b[1] == np.nextafter(d2[1], np.inf)
    assert b[2] == np.nextafter(0.09, np.inf)  # farther from its last pair than the gate
    assert np.all(pair_bounds(moved, target, None, 0.09) == np.nextafter(0.09, np.inf))
    assert np.all(pair_bounds(moved, target, np.array([-1, -1, -1]), 0.09)
                  == np.nextafter(0.09, np.inf))


def test_closed_form_normals_equal_eigh():
    rng = np.random.default_rng(4)
    out = np.empty(3)
    cases = [rng.normal(size=(30, 3)) * [5.0, 2.0, 0.01] for _ in range(200)]
    cases += [rng.normal(size=(30, 3)) * [1.0, 1.0, 1.0]]  # nearly isotropic
    cases += [np.outer(rng.normal(size=30), [1.0, 2.0, 3.0])]  # a line: two zero eigenvalues
    cases += [rng.normal(size=(30, 3)) * [3.0, 1e-7, 1e-7]]  # nearly a line
    for P in cases:
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        Q = P @ R.T + rng.uniform(-50, 50, 3)
        C = np.cov(Q.T, bias=True)
        w, v = np.linalg.eigh(C)
        _smallest_eigenvector(C[0, 0], C[0, 1], C[0, 2], C[1, 1], C[1, 2], C[2, 2], out)
        assert abs(np.linalg.norm(out) - 1) < 1e-12
        # an eigenvector of the smallest eigenvalue: |C n - w0 n| tiny against the gap
        np.testing.assert_allclose(C @ out, w[0] * out, atol=1e-9 * w[2])
        if w[1] - w[0] > 1e-6 * w[2]:  # a unique normal: the same as eigh's up to its sign
            assert abs(abs(out @ v[:, 0]) - 1) < 1e-9


@pytest.mark.parametrize("leaf_size", [1, 4, 12])
def test_tree_normals_equal_normals_from_scipys_neighbours(leaf_size):
    pts = _cloud(4000, 5)
    ref_d, ref_i = cKDTree(pts).query(pts, 30)
    ref = normals_from_neighbours(pts, ref_i.astype(np.int64), ref_d**2, 4.0)
    got = neighbourhood_normals(*KdTree(pts, leaf_size).arrays, 30, 4.0)
    assert np.all((np.abs(ref).sum(1) == 0) == (np.abs(got).sum(1) == 0))
    dots = np.abs((ref * got).sum(1))[np.abs(ref).sum(1) > 0]
    assert np.all(dots > 1 - 1e-9)


@pytest.mark.parametrize("bound", [np.inf, 0.3, 2.0])
def test_nearest_from_hints_equals_knn(bound):
    pts = _cloud(6000, 4)
    rng = np.random.default_rng(5)
    queries = np.vstack([pts[::5] + rng.normal(0, 0.2, (len(pts[::5]), 3)), pts[:30],
                         [[500.0, 0, 0]]])
    tree = KdTree(pts, leaf_size=6)
    ref_idx, ref_sq = tree.knn(queries, 1, bound)
    for hints in (None, rng.integers(-1, len(pts), len(queries)), ref_idx.ravel()):
        idx, sq = tree.nearest(queries, hints, bound**2)
        np.testing.assert_array_equal(sq, ref_sq.ravel())
        # the same point up to ties (duplicates)
        same = idx == ref_idx.ravel()
        np.testing.assert_array_equal(pts[idx[~same]], pts[ref_idx.ravel()[~same]])


@pytest.mark.parametrize("track_m", [0.0, 0.1, np.inf])
@pytest.mark.parametrize("gate", [0.3, 2.0])
def test_tracked_nearest_equals_a_fresh_search_as_the_queries_move(track_m, gate):
    pts = _cloud(6000, 6)
    rng = np.random.default_rng(7)
    queries = pts[rng.choice(len(pts), 1500)] + rng.normal(0, 0.3, (1500, 3))
    tree = KdTree(pts, leaf_size=8)
    order = rng.permutation(len(queries)) if track_m else None
    tracker = NearestTracker(tree, len(queries), gate**2, (1.25 * gate)**2, track_m, order)
    for step in (0.5, 0.05, 0.01, 1e-3, 1e-4, 0.0, 1e-6, 0.2):  # moves, large and small
        idx, sq = tracker(queries)
        ref_idx, ref_sq = tree.nearest(queries, None, gate**2)
        np.testing.assert_array_equal(sq, ref_sq)
        same = idx == ref_idx
        np.testing.assert_array_equal(pts[idx[~same]], pts[ref_idx[~same]])
        # a small rigid motion (rotation about z and a shift), as an ICP step
        c, s = np.cos(step / 20), np.sin(step / 20)
        queries = queries @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + step


def test_a_point_without_a_plane_gets_open3ds_fallback_normal():
    """Fewer than 3 points within the radius (the point itself counts), or all of them at one
    place: (0, 0, 1), as Open3D's EstimateNormals gives (a zero normal dropped such a pair's
    geometric term in DICP, where Open3D keeps a height term)."""
    rng = np.random.default_rng(3)
    plane = np.column_stack([rng.uniform(-1, 1, 40), rng.uniform(-1, 1, 40),
                             0.3 * rng.uniform(-1, 1, 40)]) @ np.linalg.qr(
        rng.normal(size=(3, 3)))[0].T
    isolated = np.array([[50.0, 0, 0], [-50.0, 0, 0], [0, 50.0, 0.0], [0, 50.5, 0.0]])
    stack = np.tile([0.0, -50.0, 3.0], (3, 1))  # three coincident points
    pts = np.vstack([plane, isolated, stack])
    for normals in (neighbourhood_normals(*KdTree(pts, 4).arrays, 30, 4.0),
                    normals_from_neighbours(pts, *(lambda d, i: (i.astype(np.int64), d**2))(
                        *cKDTree(pts).query(pts, 30, distance_upper_bound=np.inf)), 4.0)):
        np.testing.assert_array_equal(normals[len(plane):], np.tile([0.0, 0.0, 1.0], (7, 1)))
        assert np.all(np.abs(normals[:len(plane), 2]) < 0.999)  # the plane's own, not +z
