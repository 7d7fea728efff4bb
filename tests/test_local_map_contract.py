"""The local map's contract (methods/local_map.py) against definitions and independent
computations: neighbourhood covariances against a kd-tree and numpy, the replaced copies'
publication counts, the registration's early exits, and the prior-held translation against
scipy's optimiser."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from loaders.se3 import make_T
from methods.local_map import LocalMap, register_to_map, scan_covariances


def test_scan_covariances_equal_a_kd_tree_neighbourhood_plus_the_floor():
    """Each point's covariance is the sample covariance of its k nearest points (itself
    included) plus floor^2 on the diagonal; k larger than the scan is the whole scan."""
    rng = np.random.default_rng(11)
    pts = rng.uniform(-5, 5, (60, 3))
    cov = scan_covariances(pts, 6, 0.2)
    _, nn = cKDTree(pts).query(pts, k=6)
    ref = np.array([np.cov(pts[i].T) for i in nn]) + 0.04 * np.eye(3)
    np.testing.assert_allclose(cov, ref, atol=1e-12)
    three = scan_covariances(pts, 3, 0.0)  # three neighbours: a (flat) neighbourhood
    _, nn = cKDTree(pts).query(pts, k=3)
    np.testing.assert_allclose(three, [np.cov(pts[i].T) for i in nn], atol=1e-12)
    few = pts[:5]
    whole = scan_covariances(few, 50, 0.0)
    np.testing.assert_allclose(whole, np.repeat(np.cov(few.T)[None], 5, 0), atol=1e-12)


def test_fewer_than_three_neighbours_leave_only_the_noise():
    """Below 3 neighbours there is no neighbourhood spread: floor^2 I plus the angular noise."""
    rng = np.random.default_rng(12)
    pts = rng.uniform(5, 20, (40, 3))
    np.testing.assert_allclose(scan_covariances(pts, 2, 0.3),
                               np.repeat(0.09 * np.eye(3)[None], 40, 0), atol=1e-15)
    angular = scan_covariances(pts, 0, 0.0, (0.5, 1.0))
    both = scan_covariances(pts, 2, 0.3, (0.5, 1.0))
    np.testing.assert_allclose(both, angular + 0.09 * np.eye(3), atol=1e-12)
    # the angles are in degrees: 1 deg of azimuth at horizontal range rh is (rh * pi / 180)^2
    az_only = scan_covariances(pts, 0, 0.0, (1.0, 0.0))
    rh2 = pts[:, 0] ** 2 + pts[:, 1] ** 2
    np.testing.assert_allclose(np.trace(az_only, axis1=1, axis2=2), rh2 * np.radians(1.0) ** 2,
                               rtol=1e-12)


def test_a_re_published_detection_counts_its_publications():
    """Replaced copies carry their copy's count + 1; new detections count 1; a scan added
    without replacement counts 1 everywhere and replaces nothing."""
    rng = np.random.default_rng(13)
    pts = rng.uniform(-20, 20, (50, 3))
    covs = np.repeat(np.eye(3)[None], 50, 0)
    m = LocalMap(4, 1.0)
    m.add(pts, covs, np.eye(4), replace_within_m=0.05)  # empty map: nothing to replace
    assert len(m) == 50 and np.all(m.counts[m.alive] == 1)
    for publications in (2, 3):
        m.add(pts + rng.normal(0, 0.002, pts.shape), covs, np.eye(4), replace_within_m=0.05)
        assert len(m) == 50
        np.testing.assert_array_equal(m.counts[m.alive], publications)
    far = pts + [0.2, 0.0, 0.0]  # beyond replace_within_m: new detections
    m.add(far, covs, np.eye(4), replace_within_m=0.05)
    assert len(m) == 100
    idx, sq = m.nearest(far)
    np.testing.assert_allclose(sq, 0.0, atol=1e-20)
    np.testing.assert_array_equal(m.counts[idx], 1)
    idx, _ = m.nearest(pts + [0.001, 0, 0])
    np.testing.assert_array_equal(m.counts[idx], 3)


def test_replacement_reaches_no_farther_than_the_search_radius():
    """replace_within_m above the map's search radius is capped at it: a point 1.5 m from a
    new one stays when the map searches 1 m."""
    pts = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    covs = np.repeat(np.eye(3)[None], 2, 0)
    m = LocalMap(3, 1.0)
    m.add(pts, covs, np.eye(4))
    m.add(pts + [[1.5, 0, 0], [0.5, 0, 0]], covs, np.eye(4), replace_within_m=3.0)
    held = m.points[m.alive]
    assert len(m) == 3
    assert np.any(np.all(held == [0.0, 0.0, 0.0], axis=1))  # 1.5 m away: kept
    assert not np.any(np.all(held == [10.0, 0.0, 0.0], axis=1))  # 0.5 m away: replaced


def test_a_scan_is_added_in_the_world_frame_with_rotated_covariances():
    rng = np.random.default_rng(14)
    pts = rng.uniform(-5, 5, (20, 3))
    A = rng.normal(size=(20, 3, 3))
    covs = A @ A.transpose(0, 2, 1)
    R = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix()
    t = np.array([1.0, 2.0, -3.0])
    m = LocalMap(2, 1.0)
    m.add(pts, covs, make_T(R, t))
    idx, sq = m.nearest(pts @ R.T + t)
    np.testing.assert_allclose(sq, 0.0, atol=1e-20)
    np.testing.assert_allclose(m.covs[idx], np.einsum("ij,njk,lk->nil", R, covs, R),
                               atol=1e-12)


def _map_and_scan(rng, n=300):
    world = rng.uniform(-30, 30, (n, 3)) * [1, 1, 0.2] + [40, 0, 0]
    m = LocalMap(1, 1.0)
    m.add(world, scan_covariances(world, 1, 0.05), np.eye(4))
    R_true = Rotation.from_rotvec([0.003, -0.004, 0.01]).as_matrix()
    t_true = np.array([0.3, -0.1, 0.05])
    scan = (world - t_true) @ R_true
    return m, world, scan, R_true, t_true


def test_an_empty_map_or_too_few_pairs_return_the_initial_pose():
    rng = np.random.default_rng(15)
    m, world, scan, R_true, t_true = _map_and_scan(rng)
    covs = scan_covariances(scan, 1, 0.05)
    init = make_T(Rotation.from_rotvec([0, 0, 0.01]).as_matrix(), [0.1, 0.2, 0.3])
    empty = register_to_map(LocalMap(2, 1.0), scan, covs, init, None, 1.0)
    np.testing.assert_allclose(empty.T_world_sensor, init, atol=1e-12)
    assert (empty.correspondences, empty.iterations, empty.converged) == (0, 0, False)
    few = register_to_map(m, scan[:5], covs[:5], make_T(R_true, t_true), None, 1.0)
    assert (few.correspondences, few.iterations, few.converged) == (5, 1, False)
    np.testing.assert_allclose(few.T_world_sensor, make_T(R_true, t_true), atol=1e-12)
    just = register_to_map(m, scan[:10], covs[:10], make_T(R_true, t_true), None, 1.0,
                           geometry_step=True)  # exactly min_correspondences (10): enough
    assert just.correspondences == 10 and just.converged and just.T_geometry is not None


def test_a_pair_gate_beyond_the_search_radius_is_refused():
    rng = np.random.default_rng(16)
    m, world, scan, R_true, t_true = _map_and_scan(rng)
    with pytest.raises(ValueError, match="exceeds the map's search radius"):
        register_to_map(m, scan, scan_covariances(scan, 1, 0.05), np.eye(4), None, 1.5)


def test_an_iteration_budget_is_respected_and_reported():
    rng = np.random.default_rng(17)
    m, world, scan, R_true, t_true = _map_and_scan(rng)
    covs = scan_covariances(scan, 1, 0.05)
    init = make_T(np.eye(3), [0.0, 0.0, 0.0])
    one = register_to_map(m, scan, covs, init, None, 1.0, kernel_scale=1e6, max_iterations=1)
    assert one.iterations == 1 and not one.converged
    full = register_to_map(m, scan, covs, init, None, 1.0, kernel_scale=1e6,
                           max_iterations=30, tolerance_rad=1e-9)
    assert full.converged and 1 < full.iterations < 30
    np.testing.assert_allclose(full.T_world_sensor, make_T(R_true, t_true), atol=1e-8)
    # the one step moved towards the pose
    err = np.linalg.norm(one.T_world_sensor[:3, 3] - t_true)
    assert err < 0.5 * np.linalg.norm(t_true)


class _Tied:
    def __init__(self, t0, lever):
        self.t0, self.lever = np.asarray(t0, float), np.asarray(lever, float)

    def __call__(self, R):
        return self.t0 + R @ self.lever


def test_a_loosened_tie_minimises_the_geometric_cost_plus_its_prior():
    """tie_sigma_m > 0: the solved pose minimises sum e^T (C_p + C_q)^-1 e + |P (t - tied(R))|^2
    / sigma^2 (P: off the free axes) over all 6 unknowns, checked with scipy's BFGS."""
    rng = np.random.default_rng(18)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 120)
    scan = scan + rng.normal(0, 0.03, scan.shape)
    covs = scan_covariances(scan, 1, 0.05)
    lever = np.array([2.0, 0.5, -0.3])
    tied = _Tied(t_true - R_true @ lever + [0.04, -0.03, 0.06], lever)
    sigma = 0.02
    free = np.array([[0.0, 0.0, 1.0]])
    init = make_T(R_true, tied(R_true))
    fit = register_to_map(m, scan, covs, init, tied, 1.0, kernel_scale=1e6, max_iterations=60,
                          tolerance_rad=1e-13, free_axes_sensor=free, tie_sigma_m=sigma)
    u = R_true @ free[0]
    P = np.eye(3) - np.outer(u, u)
    w = 1.0 / (2 * 0.05**2)  # both covariances are floor^2 I (one neighbour: no spread)

    def cost(x):
        R = Rotation.from_rotvec(x[:3]).as_matrix()
        e = scan @ R.T + x[3:] - world
        r = P @ (x[3:] - tied(R))
        return w * float(np.sum(e * e)) + float(r @ r) / sigma**2

    x0 = np.concatenate([Rotation.from_matrix(R_true).as_rotvec(), tied(R_true)])
    best = minimize(cost, x0, method="BFGS", options={"gtol": 1e-10}).x
    got = np.concatenate([Rotation.from_matrix(fit.T_world_sensor[:3, :3]).as_rotvec(),
                          fit.T_world_sensor[:3, 3]])
    np.testing.assert_allclose(got, best, atol=1e-5)
    assert cost(got) <= cost(best) * (1 + 1e-9)  # at least as low as scipy's minimum
    # and the prior matters: the free solve lands elsewhere
    loose = register_to_map(m, scan, covs, init, None, 1.0, kernel_scale=1e6,
                            max_iterations=60, tolerance_rad=1e-13)
    assert np.linalg.norm(loose.T_world_sensor[:3, 3] - best[3:]) > 1e-3


def _gn_step(scan, world, R, t, w):
    """One free 6-DoF Gauss-Newton step of sum w_i |R p_i + t - q_i|^2 from (R, t), pairs
    i <-> i, perturbation R <- exp(d) R, t <- t + dt (numpy, from the definition)."""
    Rp = scan @ R.T
    e = Rp + t - world
    H, g = np.zeros((6, 6)), np.zeros(6)
    for rp, ei, wi in zip(Rp, e, w, strict=True):
        J = np.hstack([-np.array([[0, -rp[2], rp[1]], [rp[2], 0, -rp[0]],
                                  [-rp[1], rp[0], 0]]), np.eye(3)])
        H += wi * J.T @ J
        g += wi * J.T @ ei
    d = -np.linalg.solve(H, g)
    return Rotation.from_rotvec(d[:3]).as_matrix() @ R, t + d[3:]


def test_the_geometry_step_is_one_free_gauss_newton_step_from_the_solved_pose():
    """Exact geometry, the tied translation 5 cm off: the solve absorbs it, and T_geometry is
    one free step of the geometric cost from the solved pose (numpy), close to the true pose."""
    rng = np.random.default_rng(19)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 150)
    covs = scan_covariances(scan, 1, 0.05)
    tied = _Tied(t_true + [0.0, 0.05, 0.0], np.zeros(3))
    fit = register_to_map(m, scan, covs, make_T(R_true, tied(R_true)), tied, 0.5,
                          kernel_scale=1e6, max_iterations=40, tolerance_rad=1e-12,
                          geometry_step=True)
    assert fit.converged and fit.correspondences == 150
    R, t = fit.T_world_sensor[:3, :3], fit.T_world_sensor[:3, 3]
    R_ref, t_ref = _gn_step(scan, world, R, t, np.ones(150))
    np.testing.assert_allclose(fit.T_geometry[:3, :3], R_ref, atol=1e-9)
    np.testing.assert_allclose(fit.T_geometry[:3, 3], t_ref, atol=1e-9)
    np.testing.assert_allclose(fit.T_geometry[:3, 3], t_true, atol=1e-3)
    plain = register_to_map(m, scan, covs, make_T(R_true, tied(R_true)), tied, 1.0,
                            kernel_scale=1e6, max_iterations=40, tolerance_rad=1e-12)
    assert plain.T_geometry is None
    np.testing.assert_allclose(plain.T_world_sensor, fit.T_world_sensor, atol=1e-12)


@pytest.mark.parametrize("geometry_step", [False, True])
def test_re_published_copies_are_down_weighted_by_their_publications(geometry_step):
    """repeat_power p: the last step re-weights each pair within repeat_within_m by
    (map count + 1)^-p; that step equals one numpy Gauss-Newton step of the weighted cost from
    the unweighted solution, and it moves the pose towards the fresh detections."""
    rng = np.random.default_rng(20)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 200)
    covs_w = scan_covariances(world, 1, 0.05)
    m = LocalMap(3, 1.0)
    for _ in range(3):  # the first 140 published 3 times, the rest once
        m.add(world[:140], covs_w[:140], np.eye(4), replace_within_m=0.01)
    m.add(world[140:], covs_w[140:], np.eye(4), replace_within_m=0.01)
    idx, _ = m.nearest(world)
    np.testing.assert_array_equal(m.counts[idx], [3] * 140 + [1] * 60)
    # the copies exactly at the true pose, the fresh ones 4 cm off along x
    scan = scan.copy()
    scan[140:] += R_true.T @ np.array([0.04, 0.0, 0.0])
    covs = scan_covariances(scan, 1, 0.05)
    kw = dict(kernel_scale=1e6, max_iterations=40, tolerance_rad=1e-12)
    plain = register_to_map(m, scan, covs, make_T(R_true, t_true), None, 1.0, **kw)
    fit = register_to_map(m, scan, covs, make_T(R_true, t_true), None, 1.0, repeat_power=1.0,
                          repeat_within_m=0.02, geometry_step=geometry_step, **kw)
    assert plain.converged and fit.converged
    R, t = plain.T_world_sensor[:3, :3], plain.T_world_sensor[:3, 3]
    world_of = m.points[m.nearest(scan @ R.T + t)[0]]
    near = np.linalg.norm(scan @ R.T + t - world_of, axis=1) < 0.02
    # the copies (1.2 cm from the unweighted pose), not the fresh ones (2.8 cm)
    np.testing.assert_array_equal(near, np.arange(200) < 140)
    w = np.where(near, 1.0 / 4.0, 1.0)  # (3 + 1) ** -1
    R_ref, t_ref = _gn_step(scan, world_of, R, t, w)
    np.testing.assert_allclose(fit.T_world_sensor[:3, :3], R_ref, atol=1e-9)
    np.testing.assert_allclose(fit.T_world_sensor[:3, 3], t_ref, atol=1e-9)
    # the weighted mean of the offsets: 4 cm * 60 / (60 + 140 / 4) = 2.53 cm (unweighted 1.2)
    shift = np.linalg.norm(fit.T_world_sensor[:3, 3] - t_true)
    assert shift == pytest.approx(0.0253, abs=2e-3)
    if geometry_step:  # the geometry step from the same (unweighted) pairs and pose
        R_g, t_g = _gn_step(scan, world_of, R, t, np.ones(200))
        np.testing.assert_allclose(fit.T_geometry[:3, 3], t_g, atol=1e-9)
    else:
        assert fit.T_geometry is None


def test_the_ring_forgets_exactly_the_oldest_scan_after_every_add():
    """Equal scans (no growth) into a window of 4: after each add the map is the last
    min(k, 4) scans, and a forgotten scan's points are no longer found."""
    rng = np.random.default_rng(21)
    m = LocalMap(4, 1.0)
    assert len(m) == 0 and m.index is None
    scans = [rng.uniform(-20, 20, (15, 3)) + [100.0 * k, 0, 0] for k in range(7)]
    for k, pts in enumerate(scans):
        m.add(pts, np.repeat(np.eye(3)[None], 15, 0), np.eye(4))
        expected = np.vstack(scans[max(0, k - 3):k + 1])
        assert len(m) == len(expected)
        np.testing.assert_allclose(np.sort(m.points[m.alive], axis=0),
                                   np.sort(expected, axis=0))
        for j, old in enumerate(scans[:k + 1]):
            idx, sq = m.nearest(old)
            if j > k - 4:
                np.testing.assert_allclose(sq, 0.0, atol=1e-20)
                np.testing.assert_allclose(m.points[idx], old)
            else:  # forgotten: nothing within the radius
                assert np.all(idx == -1) and np.all(np.isinf(sq))


def test_growing_the_ring_keeps_the_held_points_covariances_and_counts():
    rng = np.random.default_rng(22)
    m = LocalMap(3, 1.0)
    small = rng.uniform(-20, 20, (10, 3))
    A = rng.normal(size=(10, 3, 3))
    covs = A @ A.transpose(0, 2, 1)
    m.add(small, covs, np.eye(4))
    m.add(small + rng.normal(0, 0.001, small.shape), covs, np.eye(4), replace_within_m=0.05)
    m.add(rng.uniform(-20, 20, (50, 3)) + [100, 0, 0], np.repeat(np.eye(3)[None], 50, 0),
          np.eye(4))  # grows the slots
    assert len(m) == 60
    idx, sq = m.nearest(small)
    assert np.all(idx >= 0) and np.all(sq < 1e-4)
    np.testing.assert_allclose(m.covs[idx], covs, atol=1e-12)
    np.testing.assert_array_equal(m.counts[idx], 2)


def test_a_map_that_forgot_everything_is_empty_again():
    """Empty scans push the last points out: the map is empty, and registering to it returns
    the initial pose without an iteration, as for a new map."""
    rng = np.random.default_rng(23)
    m = LocalMap(2, 1.0)
    pts = rng.uniform(-5, 5, (30, 3))
    m.add(pts, np.repeat(np.eye(3)[None], 30, 0), np.eye(4))
    for _ in range(2):
        m.add(np.zeros((0, 3)), np.zeros((0, 3, 3)), np.eye(4), replace_within_m=0.1)
    assert len(m) == 0 and m.index is None
    fit = register_to_map(m, pts, np.repeat(np.eye(3)[None], 30, 0), np.eye(4), None, 1.0)
    assert (fit.correspondences, fit.iterations, fit.converged) == (0, 0, False)


def test_each_iteration_is_one_gauss_newton_step_and_zero_iterations_change_nothing():
    """Pairs found at the start (exact geometry, true rotation, translation 30 cm off): the
    solve's first and second iterations equal one and two numpy Gauss-Newton steps; with no
    iteration the initial pose comes back with no pairs counted."""
    rng = np.random.default_rng(24)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 150)
    covs = scan_covariances(scan, 1, 0.05)
    R0 = Rotation.from_rotvec([0.0, 0.0, 0.004]).as_matrix() @ R_true
    init = make_T(R0, np.zeros(3))
    kw = dict(kernel_scale=1e9, tolerance_rad=1e-15)
    R1, t1 = _gn_step(scan, world, R0, np.zeros(3), np.ones(150))
    R2, t2 = _gn_step(scan, world, R1, t1, np.ones(150))
    for n, (R, t) in ((1, (R1, t1)), (2, (R2, t2))):
        fit = register_to_map(m, scan, covs, init, None, 1.0, max_iterations=n, **kw)
        assert fit.iterations == n and not fit.converged and fit.correspondences == 150
        np.testing.assert_allclose(fit.T_world_sensor[:3, :3], R, atol=1e-10)
        np.testing.assert_allclose(fit.T_world_sensor[:3, 3], t, atol=1e-10)
    none = register_to_map(m, scan, covs, init, None, 1.0, max_iterations=0,
                           geometry_step=True, **kw)
    assert (none.correspondences, none.iterations, none.converged) == (0, 0, False)
    assert none.T_geometry is None
    np.testing.assert_allclose(none.T_world_sensor, init, atol=1e-12)


def test_convergence_needs_both_updates_below_their_tolerances():
    """A translation error alone (along x): the first update is that translation, not below
    1e-4 m, so the solve converges at the second iteration; a 0.1 deg rotation error with the
    default tolerance (1e-4 rad) likewise takes more than one."""
    rng = np.random.default_rng(25)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 150)
    covs = scan_covariances(scan, 1, 0.05)
    shifted = make_T(R_true, t_true - [0.3, 0.0, 0.0])
    fit = register_to_map(m, scan, covs, shifted, None, 1.0, kernel_scale=1e9,
                          tolerance_rad=1e-3)
    assert fit.converged and fit.iterations == 2
    np.testing.assert_allclose(fit.T_world_sensor, make_T(R_true, t_true), atol=1e-9)
    turned = make_T(Rotation.from_rotvec([0, 0, np.radians(0.1)]).as_matrix() @ R_true,
                    t_true)
    fit = register_to_map(m, scan, covs, turned, None, 1.0, kernel_scale=1e9)
    assert fit.converged and fit.iterations >= 2
    np.testing.assert_allclose(fit.T_world_sensor[:3, :3], R_true, atol=1e-7)


def test_pairs_beyond_the_gate_are_not_counted():
    """Gate 0.5 m in a 1 m map: points 0.45 m from their map point pair, 0.7 m do not."""
    rng = np.random.default_rng(26)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 150)
    covs = scan_covariances(scan, 1, 0.05)
    off = scan.copy()
    off[:40] += R_true.T @ np.array([0.45, 0.0, 0.0])
    off[40:70] += R_true.T @ np.array([0.0, 0.7, 0.0])
    fit = register_to_map(m, off, covs, make_T(R_true, t_true), None, 0.5, max_iterations=1,
                          min_correspondences=1)
    assert fit.correspondences == 150 - 30


def test_the_default_cauchy_kernel_is_the_minimum_of_its_robust_cost():
    """Default kernel_scale (3, on the Mahalanobis distance): the pose minimises
    sum log(1 + d^2 / 9), d^2 = e^T (C_p + C_q)^-1 e (scipy), with gross outliers present."""
    rng = np.random.default_rng(27)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 150)
    scan = scan + rng.normal(0, 0.03, scan.shape)
    scan[:15] += R_true.T @ np.array([0.5, 0.3, 0.0])  # outliers, still within the gate
    covs = scan_covariances(scan, 1, 0.05)
    fit = register_to_map(m, scan, covs, make_T(R_true, t_true), None, 1.0, max_iterations=100,
                          tolerance_rad=1e-13)
    assert fit.converged and fit.correspondences == 150

    def cost(x):
        R = Rotation.from_rotvec(x[:3]).as_matrix()
        e = scan @ R.T + x[3:] - world
        return float(np.sum(np.log1p(np.sum(e * e, axis=1) / (2 * 0.05**2) / 9.0)))

    x0 = np.concatenate([Rotation.from_matrix(R_true).as_rotvec(), t_true])
    best = minimize(cost, x0, method="BFGS", options={"gtol": 1e-10}).x
    got = np.concatenate([Rotation.from_matrix(fit.T_world_sensor[:3, :3]).as_rotvec(),
                          fit.T_world_sensor[:3, 3]])
    np.testing.assert_allclose(got, best, atol=2e-5)
    plain = register_to_map(m, scan, covs, make_T(R_true, t_true), None, 1.0,
                            kernel_scale=1e9, max_iterations=100, tolerance_rad=1e-13)
    assert np.linalg.norm(plain.T_world_sensor[:3, 3] - best[3:]) > 1e-3  # it matters


def test_a_degenerate_scene_stops_without_a_step():
    """All points on one line through the sensor: the rotation about it is unobservable (a
    singular system): the initial pose comes back, not converged, and no geometry step."""
    x = np.linspace(5, 50, 40)
    line = np.stack([x, np.zeros(40), np.zeros(40)], axis=1)
    covs = np.repeat(0.01 * np.eye(3)[None], 40, 0)
    m = LocalMap(1, 1.0)
    m.add(line, covs, np.eye(4))
    fit = register_to_map(m, line, covs, np.eye(4), None, 1.0, geometry_step=True)
    assert (fit.correspondences, fit.iterations, fit.converged) == (40, 1, False)
    assert fit.T_geometry is None
    np.testing.assert_allclose(fit.T_world_sensor, np.eye(4), atol=1e-12)


def test_any_layout_of_the_inputs_reuses_the_compiled_kernel():
    """Points and covariances of another dtype or a strided view (a subsample) are made
    contiguous float64 first: after a warm-up no numba compilation happens in the solve (it
    would land inside a timed frame) and the result is the one of the float64 copy."""
    from methods import timing

    rng = np.random.default_rng(28)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 200)
    covs = scan_covariances(scan, 1, 0.05)
    init = make_T(R_true, t_true + [0.1, 0.0, 0.0])
    ref = register_to_map(m, scan[::2].copy(), covs[::2].copy(), init, None, 1.0)
    pts32 = scan[::2].astype(np.float32)
    with timing.stopwatch() as watch:
        fit = register_to_map(m, pts32, covs[::2].astype(np.float32), init, None, 1.0)
        strided = register_to_map(m, scan[::2], covs[::2], init, None, 1.0)
    assert watch.compiles == 0
    np.testing.assert_allclose(strided.T_world_sensor, ref.T_world_sensor, atol=1e-12)
    assert fit.converged and fit.correspondences == 100


def test_a_new_map_given_an_empty_scan_stays_empty_and_then_works():
    m = LocalMap(2, 1.0)
    m.add(np.zeros((0, 3)), np.zeros((0, 3, 3)), np.eye(4), replace_within_m=0.1)
    assert len(m) == 0 and m.index is None
    pts = np.array([[1.0, 2.0, 3.0], [5.0, 5.0, 5.0]])
    m.add(pts, np.repeat(np.eye(3)[None], 2, 0), np.eye(4))
    idx, sq = m.nearest(pts)
    np.testing.assert_allclose(m.points[idx], pts)
    np.testing.assert_array_equal(m.counts[idx], 1)


def test_replacement_within_a_wide_radius_uses_the_distance_not_its_square():
    """A 5 m map, replace_within_m 4: a new point 3 m from an old one replaces it, 4.5 m
    does not."""
    m = LocalMap(3, 5.0)
    old = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    covs = np.repeat(np.eye(3)[None], 2, 0)
    m.add(old, covs, np.eye(4))
    m.add(old + [[3.0, 0, 0], [4.5, 0, 0]], covs, np.eye(4), replace_within_m=4.0)
    held = m.points[m.alive]
    assert len(m) == 3
    assert not np.any(np.all(held == [0.0, 0.0, 0.0], axis=1))
    assert np.any(np.all(held == [100.0, 0.0, 0.0], axis=1))


def test_single_precision_points_give_the_covariances_of_their_double_values():
    rng = np.random.default_rng(29)
    pts32 = rng.uniform(5, 40, (50, 3)).astype(np.float32)
    np.testing.assert_allclose(scan_covariances(pts32, 5, 0.1, (0.5, 1.0)),
                               scan_covariances(pts32.astype(np.float64), 5, 0.1, (0.5, 1.0)),
                               rtol=1e-12, atol=1e-15)


def test_the_default_budget_is_fifteen_iterations():
    rng = np.random.default_rng(30)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 100)
    fit = register_to_map(m, scan, scan_covariances(scan, 1, 0.05), make_T(R_true, t_true),
                          None, 1.0, tolerance_rad=0.0)  # never below: every iteration runs
    assert fit.iterations == 15 and not fit.converged


def test_a_tiny_translation_error_converges_at_once():
    """50 um off in x alone: the first update (rotation 0, translation 5e-5 m) is below both
    tolerances (the translation's is 0.1 mm, not the rotation's 1e-9 rad)."""
    rng = np.random.default_rng(31)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 100)
    fit = register_to_map(m, scan, scan_covariances(scan, 1, 0.05),
                          make_T(R_true, t_true - [5e-5, 0, 0]), None, 1.0, kernel_scale=1e9,
                          tolerance_rad=1e-9)
    assert fit.converged and fit.iterations == 1
    np.testing.assert_allclose(fit.T_world_sensor, make_T(R_true, t_true), atol=1e-9)


def test_the_geometry_step_gates_its_pairs_at_the_solved_pose():
    """Gate 0.5 m: pairs 0.45 m off count in the geometry step, pairs 0.7 m off do not; the
    step equals a numpy Gauss-Newton step over exactly the gated pairs."""
    rng = np.random.default_rng(32)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 150)
    off = scan.copy()
    off[:10] += R_true.T @ np.array([0.45, 0.0, 0.0])
    off[10:20] += R_true.T @ np.array([0.0, 0.7, 0.0])
    covs = scan_covariances(off, 1, 0.05)
    fit = register_to_map(m, off, covs, make_T(R_true, t_true), None, 0.5, kernel_scale=1e9,
                          max_iterations=40, tolerance_rad=1e-12, geometry_step=True)
    assert fit.converged
    R, t = fit.T_world_sensor[:3, :3], fit.T_world_sensor[:3, 3]
    d = np.linalg.norm(off @ R.T + t - world, axis=1)
    kept = d < 0.5
    assert kept[:10].all() and not kept[10:20].any() and fit.correspondences == 140
    R_ref, t_ref = _gn_step(off[kept], world[kept], R, t, np.ones(kept.sum()))
    np.testing.assert_allclose(fit.T_geometry[:3, :3], R_ref, atol=1e-10)
    np.testing.assert_allclose(fit.T_geometry[:3, 3], t_ref, atol=1e-10)


def test_re_weighting_a_turned_scan_and_a_tie_with_a_free_axis():
    """Fresh detections turned 1 mrad about the sensor: the re-weighted step and the geometry
    step (from the pose the last pairs were found at, with those pairs) equal numpy steps; with
    an exact tie and a free vertical the re-weighted pose still keeps t = tied(R) + s u."""
    rng = np.random.default_rng(33)
    m, world, scan, R_true, t_true = _map_and_scan(rng, 200)
    covs_w = scan_covariances(world, 1, 0.05)
    m = LocalMap(3, 1.0)
    for _ in range(3):
        m.add(world[:140], covs_w[:140], np.eye(4), replace_within_m=0.01)
    m.add(world[140:], covs_w[140:], np.eye(4), replace_within_m=0.01)
    scan = scan.copy()
    scan[140:] = scan[140:] @ Rotation.from_rotvec([0, 0, 0.001]).as_matrix().T
    covs = scan_covariances(scan, 1, 0.05)
    kw = dict(kernel_scale=1e9, max_iterations=40, tolerance_rad=1e-13)
    plain = register_to_map(m, scan, covs, make_T(R_true, t_true), None, 1.0, **kw)
    fit = register_to_map(m, scan, covs, make_T(R_true, t_true), None, 1.0, repeat_power=1.0,
                          repeat_within_m=0.02, geometry_step=True, **kw)
    R, t = plain.T_world_sensor[:3, :3], plain.T_world_sensor[:3, 3]
    near = np.linalg.norm(scan @ R.T + t - world, axis=1) < 0.02
    assert near[:140].sum() > 100  # most copies are re-weighted, some fresh ones too
    publications = np.where(np.arange(200) < 140, 3 + 1, 1 + 1)
    R_w, t_w = _gn_step(scan, world, R, t, np.where(near, 1.0 / publications, 1.0))
    np.testing.assert_allclose(fit.T_world_sensor[:3, :3], R_w, atol=1e-10)
    np.testing.assert_allclose(fit.T_world_sensor[:3, 3], t_w, atol=1e-10)
    assert Rotation.from_matrix(R_w @ R.T).magnitude() > 1e-4  # the weights turned it
    R_g, t_g = _gn_step(scan, world, R, t, np.ones(200))
    np.testing.assert_allclose(fit.T_geometry[:3, :3], R_g, atol=1e-10)
    np.testing.assert_allclose(fit.T_geometry[:3, 3], t_g, atol=1e-10)
    tied = _Tied(t_true + [0.0, 0.0, 0.03], np.zeros(3))
    free = np.array([[0.0, 0.0, 1.0]])
    fit = register_to_map(m, scan, covs, make_T(R_true, tied(R_true)), tied, 1.0,
                          free_axes_sensor=free, repeat_power=1.0, repeat_within_m=0.02, **kw)
    assert fit.converged
    R, t = fit.T_world_sensor[:3, :3], fit.T_world_sensor[:3, 3]
    along = R_true @ free[0]
    rest = t - tied(R)
    np.testing.assert_allclose(rest - along * (rest @ along), 0.0, atol=1e-9)
    assert abs(rest @ along + 0.03) < 5e-3  # the vertical found (about -3 cm)
