"""The spatial hash gives the exact nearest neighbour within a radius (scipy's kd-tree as the
reference), with collisions, negative coordinates, clusters and empty neighbourhoods."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from methods.local_map import _point_covariances, scan_covariances
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
    cov = _point_covariances(pts, idx, 0.01, 0.0, 0.0)
    ref = np.array([np.cov(pts[i].T) for i in idx]) + 0.01 * np.eye(3)
    np.testing.assert_allclose(cov, ref, atol=1e-12)


def test_angular_noise_covariance_is_the_propagated_spherical_noise():
    """The angular part equals J diag(0, s_az^2, s_el^2) J^T, J the Jacobian of
    (r, az, el) -> xyz (an independent derivation by finite differences)."""
    rng = np.random.default_rng(2)
    r, az, el = rng.uniform(5, 80, 50), rng.uniform(-1, 1, 50), rng.uniform(-0.3, 0.3, 50)

    def xyz(r, az, el):
        return np.stack([r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az),
                         r * np.sin(el)], axis=-1)

    pts = xyz(r, az, el)
    s_az, s_el = np.radians(0.5), np.radians(1.0)
    cov = scan_covariances(pts, 0, 0.0, (0.5, 1.0))  # no neighbours, no floor: noise only
    h = 1e-7
    J_az = (xyz(r, az + h, el) - xyz(r, az - h, el)) / (2 * h)
    J_el = (xyz(r, az, el + h) - xyz(r, az, el - h)) / (2 * h)
    ref = (s_az**2 * J_az[:, :, None] * J_az[:, None, :]
           + s_el**2 * J_el[:, :, None] * J_el[:, None, :])
    np.testing.assert_allclose(cov, ref, atol=1e-9 * np.abs(ref).max())
    # nothing along the ray: the range is not uncertain here
    d = pts / r[:, None]
    np.testing.assert_allclose(np.einsum("ni,nij,nj->n", d, cov, d), 0, atol=1e-9)
