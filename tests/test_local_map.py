"""doppler-ego's registration step (methods/local_map.py): the tied translation's exact
Jacobian, the free vertical offset, and the free 6-DoF solve, against known answers and an
independent optimiser (scipy)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from loaders.se3 import make_T
from methods.local_map import LocalMap, register_to_map, scan_covariances


class Tied:
    """t(R) = t0 + R lever (the form of the Doppler translation's v_curr term)."""

    def __init__(self, t0, lever):
        self.t0, self.lever = np.asarray(t0, float), np.asarray(lever, float)

    def __call__(self, R):
        return self.t0 + R @ self.lever


def scene(rng, n=400, spacing=6.0):
    """Well separated world points (pairs are unambiguous), a true pose, the scan."""
    grid = np.stack(np.meshgrid(np.arange(-5, 6), np.arange(-5, 6), np.arange(-1, 3)), -1)
    world = grid.reshape(-1, 3) * spacing + np.array([40.0, 0.0, 0.0])
    world = world[rng.choice(len(world), n, replace=False)]
    R_true = Rotation.from_rotvec([0.004, -0.006, 0.02]).as_matrix()
    t_true = np.array([0.5, 0.1, 0.05])
    scan = (world - t_true) @ R_true  # sensor-frame points
    return world, scan, R_true, t_true


def fit(world, scan, init, tied, free_axes=None, floor=0.05):
    m = LocalMap(1, 1.0)
    m.add(world, scan_covariances(world, 1, floor), np.eye(4))
    return register_to_map(m, scan, scan_covariances(scan, 1, floor), init, tied, 1.0,
                           kernel_scale=1e6, max_iterations=50, tolerance_rad=1e-12,
                           free_axes_sensor=free_axes)


def test_tied_solve_reaches_the_optimum_of_its_own_constrained_cost():
    """Noisy pairs and a tied translation that turns with R through a long lever: the solve
    must land on the minimum of sum |R p + t(R) - q|^2 (scipy over the rotation vector); the
    Jacobian without the lever term would stop beside it."""
    rng = np.random.default_rng(1)
    world, scan, R_true, t_true = scene(rng)
    scan = scan + rng.normal(0, 0.05, scan.shape)
    lever = np.array([6.0, -2.0, 1.0])  # exaggerated, so that the term matters
    tied = Tied(t_true - R_true @ lever + np.array([0.0, 0.0, 0.05]), lever)
    init = make_T(Rotation.from_rotvec([0.0, 0.0, 0.015]).as_matrix(), np.zeros(3))
    result = fit(world, scan, init, tied)

    def cost(rv):
        R = Rotation.from_rotvec(rv).as_matrix()
        return float(np.sum((scan @ R.T + tied(R) - world) ** 2))

    best = minimize(cost, Rotation.from_matrix(R_true).as_rotvec(), method="BFGS",
                    options={"gtol": 1e-12}).x
    got = Rotation.from_matrix(result.T_world_sensor[:3, :3]).as_rotvec()
    assert np.linalg.norm(got - best) < 1e-7
    np.testing.assert_allclose(result.T_world_sensor[:3, 3],
                               tied(result.T_world_sensor[:3, :3]), atol=1e-12)

    class Misreported(Tied):  # the same translation; the solver is told it does not turn
        def __init__(self, t0, lever):
            super().__init__(t0, lever)
            self.turning, self.lever = self.lever, np.zeros(3)

        def __call__(self, R):
            return self.t0 + R @ self.turning

    wrong = fit(world, scan, init, Misreported(tied.t0, lever))
    off = Rotation.from_matrix(wrong.T_world_sensor[:3, :3]).as_rotvec()
    assert np.linalg.norm(off - best) > 100 * np.linalg.norm(got - best)


def test_a_vertical_disagreement_moves_the_vertical_not_the_rotation():
    """Exact geometry, tied translation wrong by 5 cm along the sensor's z: tied alone, the
    rotation tilts to absorb it; with the vertical free it is exact and the offset is found."""
    rng = np.random.default_rng(2)
    world, scan, R_true, t_true = scene(rng)
    bias = R_true @ np.array([0.0, 0.0, 0.05])
    tied = Tied(t_true - bias, np.zeros(3))
    init = make_T(R_true, t_true)
    free = fit(world, scan, init, tied, free_axes=np.array([[0.0, 0.0, 1.0]]))
    np.testing.assert_allclose(free.T_world_sensor[:3, :3], R_true, atol=1e-9)
    np.testing.assert_allclose(free.T_world_sensor[:3, 3], t_true, atol=1e-9)
    tied_only = fit(world, scan, init, tied)
    tilt = Rotation.from_matrix(tied_only.T_world_sensor[:3, :3] @ R_true.T).magnitude()
    assert np.degrees(tilt) > 0.01


def test_free_six_dof_recovers_an_exact_pose():
    rng = np.random.default_rng(3)
    world, scan, R_true, t_true = scene(rng)
    result = fit(world, scan, np.eye(4), None)
    np.testing.assert_allclose(result.T_world_sensor[:3, :3], R_true, atol=1e-9)
    np.testing.assert_allclose(result.T_world_sensor[:3, 3], t_true, atol=1e-8)
    assert result.converged


def test_the_map_holds_exactly_the_last_scans():
    """Scans of different sizes (the ring grows), more than the window: the map's points are
    exactly the last max_frames scans', and nearest() agrees with brute force over them."""
    rng = np.random.default_rng(5)
    m = LocalMap(3, 1.0)
    scans = [rng.uniform(-20, 20, (n, 3)) for n in (50, 80, 30, 200, 60)]
    for k, pts in enumerate(scans):
        T = make_T(np.eye(3), [k * 0.5, 0.0, 0.0])
        m.add(pts, np.repeat(np.eye(3)[None], len(pts), 0), T)
    expected = np.vstack([pts + [k * 0.5, 0.0, 0.0] for k, pts in enumerate(scans)][-3:])
    held = m.points[m.alive]
    assert len(m) == len(expected) == len(held)
    np.testing.assert_allclose(np.sort(held, axis=0), np.sort(expected, axis=0))
    queries = rng.uniform(-20, 20, (300, 3))
    idx, sq = m.nearest(queries)
    d = np.linalg.norm(queries[:, None] - held[None], axis=2)
    within = d.min(axis=1) < 1.0
    np.testing.assert_array_equal(idx >= 0, within)
    np.testing.assert_allclose(np.sqrt(sq[within]), d.min(axis=1)[within], atol=1e-12)
    assert np.all(m.alive[idx[within]])


def test_a_re_published_detection_replaces_its_older_copy():
    rng = np.random.default_rng(6)
    pts = rng.uniform(-20, 20, (100, 3))
    covs = np.repeat(np.eye(3)[None], 100, 0)
    m = LocalMap(5, 1.0)
    m.add(pts, covs, np.eye(4))
    copies = pts[:60] + rng.normal(0, 0.005, (60, 3))  # within 5 cm: the same detection
    moved = pts[60:] + [0.3, 0.0, 0.0]  # 30 cm away: another one
    m.add(np.vstack([copies, moved]), covs, np.eye(4), replace_within_m=0.05)
    assert len(m) == 100 + 40
    held = m.points[m.alive]
    assert not np.any(np.all(np.isclose(held[:, None], pts[None, :60]), axis=2))
    m.add(pts, covs, np.eye(4))  # without replacement every copy stays
    assert len(m) == 240
