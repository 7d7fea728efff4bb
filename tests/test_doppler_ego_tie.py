"""doppler-ego's loosened tie (issue 49, ``tie_sigma_mps``; ``register_to_map(tie_sigma_m=)``):
the prior's solve against an independent optimiser (scipy) of the same cost, its two limits
(the exact tie, the free 6-DoF solve), the mechanism it fixes (a direction error of the measured
translation, absorbed by the rotation when tied exactly), and the method's use of it (only on a
sensor that re-publishes its detections; exact on a noise-free motion)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from conftest import constant_twist_sequence
from loaders.se3 import make_T, rotation_angle_deg
from methods.doppler_ego import DopplerEgo
from methods.local_map import LocalMap, register_to_map, scan_covariances
from test_doppler_ego import step_errors

FLOOR_M = 0.05  # every point's covariance: FLOOR_M^2 I (one neighbour: no surface term)
VERTICAL = np.array([[0.0, 0.0, 1.0]])


class Tied:
    """t(R) = t0 + R lever (the form of the Doppler translation's v_curr term)."""

    def __init__(self, t0, lever):
        self.t0, self.lever = np.asarray(t0, float), np.asarray(lever, float)

    def __call__(self, R):
        return self.t0 + R @ self.lever


def scene(seed: int, n: int = 400, spacing_m: float = 6.0):
    """Well separated world points (unambiguous pairs), a true pose T_world_sensor, the scan
    (sensor frame)."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(np.arange(-5, 6), np.arange(-5, 6), np.arange(-1, 3)), -1)
    world = grid.reshape(-1, 3) * spacing_m + np.array([40.0, 0.0, 0.0])
    world = world[rng.choice(len(world), n, replace=False)]
    R_true = Rotation.from_rotvec([0.004, -0.006, 0.02]).as_matrix()
    t_true = np.array([0.5, 0.1, 0.05])
    return rng, world, (world - t_true) @ R_true, R_true, t_true


def fit(world, scan, init, tied, sigma_m=0.0, free_axes=None):
    m = LocalMap(1, 1.0)
    m.add(world, scan_covariances(world, 1, FLOOR_M), np.eye(4))
    return register_to_map(m, scan, scan_covariances(scan, 1, FLOOR_M), init, tied, 1.0,
                           kernel_scale=1e6, max_iterations=50, tolerance_rad=1e-12,
                           free_axes_sensor=free_axes, tie_sigma_m=sigma_m)


def test_the_prior_solve_reaches_the_optimum_of_its_own_cost():
    """Noisy pairs, a measured translation 3 cm off sideways that turns with R through a long
    lever, the vertical free: the solve lands on the minimum of
    sum |R p + t - q|^2 / (2 floor^2) + |P (t - tied(R))|^2 / sigma^2 (P: off the vertical),
    found by scipy's least squares over all six unknowns."""
    rng, world, scan, R_true, t_true = scene(1)
    scan = scan + rng.normal(0, 0.05, scan.shape)
    lever = np.array([6.0, -2.0, 1.0])  # exaggerated, so that its term matters
    tied = Tied(t_true - R_true @ lever + R_true @ np.array([0.0, 0.03, 0.02]), lever)
    sigma_m = 0.01
    init = make_T(Rotation.from_rotvec([0.0, 0.0, 0.015]).as_matrix(), np.zeros(3))
    result = fit(world, scan, init, tied, sigma_m, VERTICAL)
    R_fit = result.T_world_sensor[:3, :3]
    u = R_fit @ VERTICAL[0]  # the free axis in the world (the solve takes it from R_init)
    u0 = init[:3, :3] @ VERTICAL[0]
    P = np.eye(3) - np.outer(u0, u0)

    def residuals(x):
        R = Rotation.from_rotvec(x[:3]).as_matrix()
        e = (scan @ R.T + x[3:] - world) / (np.sqrt(2) * FLOOR_M)
        return np.concatenate([e.ravel(), P @ (x[3:] - tied(R)) / sigma_m])

    start = np.concatenate([Rotation.from_matrix(R_true).as_rotvec(), t_true])
    best = least_squares(residuals, start, xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    got = np.concatenate([Rotation.from_matrix(R_fit).as_rotvec(),
                          result.T_world_sensor[:3, 3]])
    assert np.linalg.norm(got[:3] - best[:3]) < 1e-7  # rad
    assert np.linalg.norm(got[3:] - best[3:]) < 1e-6  # m
    assert abs(u @ u0) > 0.999  # the rotation is small: the free axis barely moved


def test_the_prior_spans_the_exact_tie_and_the_free_solve():
    """A tight prior gives the exact tie's pose (vertical free in both), a loose one the free
    6-DoF solve's."""
    rng, world, scan, R_true, t_true = scene(2)
    scan = scan + rng.normal(0, 0.05, scan.shape)
    tied = Tied(t_true + R_true @ np.array([0.01, 0.04, 0.03]), np.zeros(3))
    init = make_T(R_true, tied(R_true))
    exact = fit(world, scan, init, tied, 0.0, VERTICAL).T_world_sensor
    tight = fit(world, scan, init, tied, 1e-7, VERTICAL).T_world_sensor
    free = fit(world, scan, init, None).T_world_sensor
    loose = fit(world, scan, init, tied, 1e4, VERTICAL).T_world_sensor
    assert float(rotation_angle_deg(exact[:3, :3].T @ tight[:3, :3])) < 1e-5
    assert np.linalg.norm(exact[:3, 3] - tight[:3, 3]) < 1e-6
    assert float(rotation_angle_deg(free[:3, :3].T @ loose[:3, :3])) < 1e-5
    assert np.linalg.norm(free[:3, 3] - loose[:3, 3]) < 1e-6
    # and the two limits differ: the measured translation is 4 cm off sideways
    assert float(rotation_angle_deg(exact[:3, :3].T @ free[:3, :3])) > 1e-3


def test_a_direction_error_of_the_measured_translation_turns_only_the_exact_tie():
    """Exact geometry; the measured translation points 2 deg off the true one sideways (a
    velocity direction error). Tied exactly, the rotation absorbs it; held by a loose prior,
    the rotation is the geometry's, exact."""
    _, world, scan, R_true, t_true = scene(3)
    off = Rotation.from_rotvec([0.0, 0.0, np.radians(2.0)]).as_matrix()
    tied = Tied(off @ t_true, np.zeros(3))  # the step seen 2 deg off in yaw
    init = make_T(R_true, tied(R_true))
    exact = fit(world, scan, init, tied, 0.0, VERTICAL).T_world_sensor
    loose = fit(world, scan, init, tied, 1.0, VERTICAL).T_world_sensor
    assert float(rotation_angle_deg(R_true.T @ exact[:3, :3])) > 0.01
    assert float(rotation_angle_deg(R_true.T @ loose[:3, :3])) < 1e-4


@pytest.mark.parametrize("seed", [True, False])
def test_loosened_tie_recovers_a_noise_free_known_motion(seed):
    """With the vertical free (as on a re-publishing sensor) and the tie loosened (the
    decoupled ablation, 3 m/s), exact data still give the exact motion."""
    seq = constant_twist_sequence(n_frames=12, n_points=4000, v=(8.0, 0.3, 0.1),
                                  w=(0.0, 0.01, 0.08))
    method = DopplerEgo(free_vertical=True, tie_sigma_mps=3.0, lever_memory_s=0.0,
                        repeat_weight_power=0.0).configured_for(seq.sensor)
    trans, rot = step_errors(seq, method.run(seq, seed=seed))
    assert trans.max() < 1e-3 and rot.max() < 0.05


def test_the_tie_is_loosened_only_on_a_sensor_that_re_publishes_its_detections():
    """Fully tied (free_vertical False: independent detections), tie_sigma_mps changes
    nothing; with the vertical free it changes the poses."""
    seq = constant_twist_sequence(n_frames=6, n_points=2000, v=(8.0, 0.3, 0.1),
                                  w=(0.0, 0.01, 0.08))

    def poses(**kw):
        return DopplerEgo(**kw).configured_for(seq.sensor).run(seq, seed=True).poses

    assert np.array_equal(poses(free_vertical=False, tie_sigma_mps=0.0),
                          poses(free_vertical=False, tie_sigma_mps=3.0))
    assert not np.array_equal(poses(free_vertical=True, tie_sigma_mps=0.0),
                              poses(free_vertical=True, tie_sigma_mps=3.0))
