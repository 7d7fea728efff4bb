"""The spatial hash gives the exact nearest neighbour within a radius (scipy's kd-tree as the
reference), with collisions, negative coordinates, clusters and empty neighbourhoods."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from methods.local_map import _neighbourhood_covariances
from methods.spatial_hash import SpatialHash, _build


@pytest.mark.parametrize("cell_m, radius_m", [(2.0, 2.0), (1.0, 0.7), (0.3, 0.3)])
def test_nearest_within_radius_equals_a_kd_tree(cell_m, radius_m):
    rng = np.random.default_rng(3)
    # a wide sparse cloud plus a dense cluster: long bucket chains and empty cells
    points = np.vstack([rng.uniform(-120, 80, (20000, 3)) * [1, 1, 0.05],
                        rng.normal([5, -3, 0], 0.5, (5000, 3))])
    near = points[rng.choice(len(points), 3000)] + rng.normal(0, radius_m / 2, (3000, 3))
    queries = np.vstack([near, rng.uniform(-150, 150, (500, 3))])
    idx, sq = SpatialHash(points, cell_m).nearest(queries, radius_m)
    d_ref, i_ref = cKDTree(points).query(queries, distance_upper_bound=radius_m)
    found = np.isfinite(d_ref) & (d_ref < radius_m)
    assert found.sum() > 1000 and (~found).sum() > 100  # both cases are exercised
    np.testing.assert_array_equal(idx >= 0, found)
    np.testing.assert_allclose(np.sqrt(sq[found]), d_ref[found], rtol=1e-12)
    assert np.all(np.isinf(sq[~found]))


def test_a_small_table_with_many_collisions_is_still_exact():
    rng = np.random.default_rng(5)
    points = rng.uniform(-30, 30, (3000, 3))
    h = SpatialHash(points, 1.5)
    h._head, h._next = _build(h.points, 1 / 1.5, 16)  # 16 buckets for thousands of cells
    queries = rng.uniform(-30, 30, (400, 3))
    idx, sq = h.nearest(queries, 1.5)
    d_ref, i_ref = cKDTree(points).query(queries, distance_upper_bound=1.5)
    found = np.isfinite(d_ref)
    np.testing.assert_array_equal(idx[found], i_ref[found])
    assert np.all(idx[~found] == -1)


def test_a_radius_beyond_the_cell_is_refused():
    with pytest.raises(ValueError, match="exceeds the cell size"):
        SpatialHash(np.zeros((3, 3)), 1.0).nearest(np.zeros((1, 3)), 1.5)


def test_neighbourhood_covariances_equal_numpy():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(200, 3))
    idx = rng.integers(0, 200, (200, 7))
    cov = _neighbourhood_covariances(pts, idx, 0.01)
    ref = np.array([np.cov(pts[i].T) for i in idx]) + 0.01 * np.eye(3)
    np.testing.assert_allclose(cov, ref, atol=1e-12)
