"""road_normal (bench.data.calibration.estimate) on planes placed on purpose: where its
candidate points end, which planes count as road, small patches, a second plane beside the
road, and that a seed gives the same answer (written against the survivors of a mutation
run)."""

import numpy as np

import bench.data.calibration.estimate as est
from loaders.scan import Scan


def _plane(xy, height, tilt_deg=0.0, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    z = -height + np.tan(np.radians(tilt_deg)) * xy[:, 0] + rng.uniform(-noise, noise, len(xy))
    return np.column_stack([xy, z])


def _ring(r_low, r_high, n=200, seed=0):
    rng = np.random.default_rng(seed)
    r, phi = rng.uniform(r_low, r_high, n), rng.uniform(0, 2 * np.pi, n)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi)])


def test_the_40_m_limit_is_horizontal_distance():
    # 39.8-39.95 m away horizontally, 4 m down: over 40 m in 3-D, still candidates
    out = est.road_normal(Scan(0.0, _plane(_ring(39.8, 39.95), 4.0)))
    assert out is not None and abs(out[1] - 4.0) < 1e-9
    # 40.2-40.8 m away: beyond the limit
    assert est.road_normal(Scan(0.0, _plane(_ring(40.2, 40.8), 1.5))) is None


def test_points_exactly_0_3_m_down_are_not_candidates():
    xy = np.random.default_rng(1).uniform(-10, 10, (200, 2))
    assert est.road_normal(Scan(0.0, _plane(xy, 0.3))) is None
    assert est.road_normal(Scan(0.0, _plane(xy, 0.31))) is not None


def test_a_small_patch_of_road_is_found():
    xy = np.random.default_rng(2).uniform(-0.4, 0.4, (200, 2))  # triangles well under 1 m^2
    normal, height = est.road_normal(Scan(0.0, _plane(xy, 1.5)))
    np.testing.assert_allclose(normal, [0, 0, 1], atol=1e-9)
    assert abs(height - 1.5) < 1e-9


def test_a_plane_tilted_just_over_20_deg_is_no_road():
    xy = np.random.default_rng(3).uniform(-10, 10, (300, 2))
    assert est.road_normal(Scan(0.0, _plane(xy, 5.0, tilt_deg=20.5))) is None
    assert est.road_normal(Scan(0.0, _plane(xy, 5.0, tilt_deg=19.5))) is not None


def test_the_plane_with_most_support_wins():
    rng = np.random.default_rng(4)
    road = _plane(rng.uniform(-20, 20, (300, 2)), 1.5)
    # a ramp 250 points strong, 2.5 m or more below the road (so none of its points is near it)
    ramp = _plane(rng.uniform([-20, -20], [-5, 20], (250, 2)), 3.0, tilt_deg=12.0)
    for seed in range(5):
        normal, height = est.road_normal(Scan(0.0, np.concatenate([ramp, road])), seed=seed)
        np.testing.assert_allclose(normal, [0, 0, 1], atol=1e-9)
        assert abs(height - 1.5) < 1e-9


def test_a_seed_gives_the_same_plane():
    xy = np.random.default_rng(5).uniform(-20, 20, (400, 2))
    scan = Scan(0.0, _plane(xy, 1.5, tilt_deg=2.0, noise=0.3))
    first = est.road_normal(scan, seed=7)
    for _ in range(3):
        again = est.road_normal(scan, seed=7)
        np.testing.assert_array_equal(again[0], first[0])
        assert again[1] == first[1]
