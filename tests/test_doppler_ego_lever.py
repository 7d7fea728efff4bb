"""doppler-ego's lever-arm tie (issue 49, ``lever_memory_s``): the translation of the frame the
geometry registers, tied to the Doppler translation of a point a lever arm r away
(``t + (R - I) r``, its derivative for the solve), r estimated online from the geometry's
disagreement (``LeverArm``, fed by ``register_to_map(geometry_step=True)``), and the method's
use of it (only on a sensor that re-publishes its detections)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import constant_twist_sequence
from loaders.scan import MemorySequence, Scan
from loaders.se3 import inv_T, make_T, rotation_angle_deg
from methods.doppler_ego import DopplerEgo, EgoTranslation, LeverArm
from methods.local_map import LocalMap, register_to_map, scan_covariances


def test_the_offset_tie_is_the_rigid_body_relation_and_its_lever_its_derivative():
    """t(R) = Doppler translation + R_wp (R_prev_curr - I) r, and t(exp(d) R) - t(R) =
    d x (R lever) to first order (what register_to_map's Jacobian uses)."""
    rng = np.random.default_rng(0)
    T_wp = make_T(Rotation.from_rotvec(rng.normal(0, 0.3, 3)).as_matrix(), rng.normal(0, 5, 3))
    v_prev, v_curr, dt, r = np.array([5.0, 0.2, 0.1]), np.array([5.2, -0.1, 0.0]), 0.08, \
        np.array([-2.0, 0.4, 0.0])
    plain = EgoTranslation(T_wp, v_prev, v_curr, dt)
    tied = EgoTranslation(T_wp, v_prev, v_curr, dt, r)
    R_pc = Rotation.from_rotvec([0.002, -0.001, 0.03]).as_matrix()
    R = T_wp[:3, :3] @ R_pc
    expected = plain(R) + T_wp[:3, :3] @ (R_pc - np.eye(3)) @ r
    assert np.allclose(tied(R), expected, atol=1e-12)
    assert tied.without_offset()(R) == pytest.approx(plain(R), abs=1e-12)
    for d in (np.array([1e-6, 0, 0]), np.array([0, 1e-6, 0]), np.array([0, 0, 1e-6])):
        moved = tied(Rotation.from_rotvec(d).as_matrix() @ R) - tied(R)
        assert np.allclose(moved, np.cross(d, R @ tied.lever), atol=1e-12)


def test_the_online_estimate_recovers_a_lever_arm_from_turning_steps():
    """Steps turning in yaw (0-0.3 rad/s at 12 Hz) with the disagreement (R - I) r plus 3 mm
    of noise: the estimate reaches r within 10 cm; on a straight drive (no rotation) it stays
    at zero, whatever the noise."""
    rng = np.random.default_rng(1)
    r = np.array([-2.0, 0.4, 0.0])
    dt = 1 / 12

    def feed(est, yaw_rate):
        R_pc = Rotation.from_rotvec([0.0, 0.0, yaw_rate * dt]).as_matrix()
        d_prev = (R_pc - np.eye(3)) @ r + rng.normal(0, 0.003, 3)
        T_wp = np.eye(4)
        doppler = EgoTranslation(T_wp, np.array([5.4, 0.0, 0.0]), np.array([5.4, 0.1, 0.0]), dt)
        est.update(T_wp, make_T(R_pc, doppler(R_pc) + d_prev), doppler, dt)

    turning = LeverArm(30.0)
    for _ in range(250):
        feed(turning, rng.uniform(-0.3, 0.3))
    assert np.linalg.norm(turning.value() - r) < 0.1
    straight = LeverArm(30.0)
    for _ in range(250):
        feed(straight, 0.0)
    assert np.linalg.norm(straight.value()) < 1e-6


def test_the_geometry_step_lands_on_the_free_solve():
    """One free 6-DoF step of the geometric cost from a solve tied to a translation 4 cm off
    sideways lands on the free solve's pose (exact data)."""
    rng = np.random.default_rng(2)
    grid = np.stack(np.meshgrid(np.arange(-5, 6), np.arange(-5, 6), np.arange(-1, 3)), -1)
    world = grid.reshape(-1, 3) * 6.0 + np.array([40.0, 0.0, 0.0])
    world = world[rng.choice(len(world), 400, replace=False)]
    R_true = Rotation.from_rotvec([0.004, -0.006, 0.02]).as_matrix()
    t_true = np.array([0.5, 0.1, 0.05])
    scan = (world - t_true) @ R_true
    m = LocalMap(1, 1.0)
    m.add(world, scan_covariances(world, 1, 0.05), np.eye(4))

    class Off:
        lever = np.zeros(3)

        def __call__(self, R):
            return t_true + np.array([0.0, 0.04, 0.0])

    fit = register_to_map(m, scan, scan_covariances(scan, 1, 0.05), make_T(R_true, Off()(R_true)),
                          Off(), 1.0, kernel_scale=1e6, max_iterations=50, tolerance_rad=1e-12,
                          geometry_step=True)
    assert float(rotation_angle_deg(R_true.T @ fit.T_world_sensor[:3, :3])) > 1e-3  # tied: off
    assert float(rotation_angle_deg(R_true.T @ fit.T_geometry[:3, :3])) < 1e-4
    assert np.linalg.norm(fit.T_geometry[:3, 3] - t_true) < 1e-4


def lever_sequence(r, n_frames=24):
    """A constant twist of the frame the points are in (its GT), with the Doppler of each
    point computed from the velocity of a point ``-r`` away (v - w x r): the velocity applies
    somewhere else than the geometry's frame."""
    seq = constant_twist_sequence(n_frames=n_frames, n_points=3000, v=(6.0, 0.0, 0.0),
                                  w=(0.0, 0.0, 0.15), dt=0.1)
    v_d = np.array([6.0, 0.0, 0.0]) - np.cross([0.0, 0.0, 0.15], r)
    scans = []
    for s in seq:
        dirs = s.points / np.linalg.norm(s.points, axis=1, keepdims=True)
        scans.append(Scan(s.stamp, s.points, -dirs @ v_d, s.fields))
    return MemorySequence("lever", seq.sensor, scans, seq.ground_truth, {"test": 1})


def step_rotation_errors(seq, poses):
    gt = seq.ground_truth.poses
    return np.array([float(rotation_angle_deg((inv_T(inv_T(gt[k - 1]) @ gt[k])
                                               @ (inv_T(poses[k - 1]) @ poses[k]))[:3, :3]))
                     for k in range(1, len(gt))])


def test_a_lever_arm_turns_the_exact_tie_and_not_the_lever_tie():
    """Exact data whose Doppler velocity applies 2 m ahead of the points' frame: tied exactly,
    the yaw absorbs the lateral w x r each step; with the lever estimated online, the later
    steps' rotation is the true one."""
    seq = lever_sequence(np.array([-2.0, 0.0, 0.0]))

    def rot(**kw):  # the copies' weighting off: this sequence's points are all exact copies
        m = DopplerEgo(free_vertical=True, repeat_weight_power=0.0, **kw).configured_for(
            seq.sensor)
        return step_rotation_errors(seq, m.run(seq, seed=True).poses)

    tied, lever = rot(lever_memory_s=0.0), rot(lever_memory_s=30.0)
    assert np.median(tied[5:]) > 0.004  # deg per step (0.007: the 0.3 m/s sideways of w x r)
    assert np.median(lever[5:]) < 0.3 * np.median(tied[5:])


def test_the_lever_tie_is_used_only_on_a_sensor_that_re_publishes_its_detections():
    """Fully tied (free_vertical False: independent detections), lever_memory_s changes
    nothing; without a lever arm in the data it changes the rotation by almost nothing."""
    seq = constant_twist_sequence(n_frames=8, n_points=2000, v=(8.0, 0.3, 0.1),
                                  w=(0.0, 0.01, 0.08))

    def poses(**kw):
        return DopplerEgo(repeat_weight_power=0.0, **kw).configured_for(seq.sensor).run(
            seq, seed=True).poses

    assert np.array_equal(poses(free_vertical=False, lever_memory_s=0.0),
                          poses(free_vertical=False, lever_memory_s=30.0))
    off = poses(free_vertical=True, lever_memory_s=0.0)
    on = poses(free_vertical=True, lever_memory_s=30.0)
    assert step_rotation_errors(seq, on).max() < 0.01
    assert step_rotation_errors(seq, off).max() < 0.01


def _T(t=(0.0, 0.0, 0.0), yaw=0.0):
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = t
    return T


def test_one_velocity_alone_moves_over_the_whole_step():
    """Without v_curr: the displacement is dT v_prev in the previous frame and the lever is
    zero (the offset alone with one); without v_prev: the lever is dT v_curr."""
    from methods.doppler_ego import EgoTranslation

    tr = EgoTranslation(_T((1.0, 0.0, 0.0), np.pi / 2), np.array([2.0, 0.0, 0.0]), None, 0.5)
    np.testing.assert_allclose(tr(np.eye(3)), [1.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(tr.lever, np.zeros(3))
    off = EgoTranslation(_T(), np.array([2.0, 0.0, 0.0]), None, 0.5, offset=[0, 3, 0])
    np.testing.assert_array_equal(off.lever, [0.0, 3.0, 0.0])
    alone = EgoTranslation(_T(), None, np.array([4.0, 0.0, 0.0]), 0.5)
    np.testing.assert_allclose(alone.lever, [2.0, 0.0, 0.0])
    both = EgoTranslation(_T(), np.array([4.0, 0.0, 0.0]), np.array([4.0, 0.0, 0.0]), 0.5)
    np.testing.assert_allclose(both.lever, [1.0, 0.0, 0.0])


def test_the_lever_estimates_first_steps_are_its_forgotten_ridge_least_squares(monkeypatch):
    """Two steps by the class's model d = (R_prev_curr - I) r: after them r solves
    (lam S_1 + S_2 + ridge I) r = lam b_1 + b_2 with S_k = A_k^T A_k, b_k = A_k^T d_k, and
    ridge = (ss / n) / prior_m^2 from the residuals measured before each update (ss starts at
    noise_m^2 with a count of 1, each step adds its two horizontal rows). The Doppler step of
    each update is recorded for the diagnostics when asked."""
    from methods import doppler_ego
    from methods.doppler_ego import EgoTranslation, LeverArm

    monkeypatch.setattr(doppler_ego, "DIAG", [])
    memory, prior, noise, dt = 0.7, 0.6, 0.2, 0.1
    lam = np.exp(-dt / memory)
    arm = LeverArm(memory, prior_m=prior, noise_m=noise)
    still = EgoTranslation(_T((1.0, 2.0, 0.0)), np.zeros(3), np.zeros(3), dt)
    steps = [(0.3, np.array([0.05, 0.3, 0.0])), (-0.4, np.array([-0.2, 0.1, 0.0]))]
    ss, n, S, b, r = noise**2, 1.0, np.zeros((2, 2)), np.zeros(2), np.zeros(2)
    for yaw, step in steps:
        T_geo = _T((1.0, 2.0, 0.0) + step, yaw)
        arm.update(_T((1.0, 2.0, 0.0)), T_geo, still, dt)
        A = (_T(yaw=yaw)[:3, :3] - np.eye(3))[:2, :2]
        e = step[:2] - A @ r
        ss, n = lam * ss + e @ e, lam * n + 2.0
        S, b = lam * S + A.T @ A, lam * b + A.T @ step[:2]
        r = np.linalg.solve(S + (ss / n) / prior**2 * np.eye(2), b)
        np.testing.assert_allclose(arm.value()[:2], r, rtol=1e-10)
    assert abs(arm.value()[1]) > 0.1 and arm.value()[2] == 0.0
    # the Doppler step in the previous frame: a vehicle standing still moved nowhere; the
    # geometry's step is all of the difference
    assert len(doppler_ego.DIAG) == 2
    np.testing.assert_allclose(doppler_ego.DIAG[0][2], np.zeros(3), atol=1e-12)
    np.testing.assert_allclose(doppler_ego.DIAG[1][1], steps[1][1], atol=1e-12)


def test_the_lever_estimates_defaults_are_the_documented_prior_and_noise():
    """LeverArm's defaults are those the manual states (a 2 m zero-mean prior, 1 cm residual
    noise to start from): after the same small turning steps the default estimate equals the
    explicit one, and a 1 m prior or 2 cm noise would give another (the steps are small enough
    for the prior to matter)."""
    from methods.doppler_ego import EgoTranslation, LeverArm

    dt = 0.1
    still = EgoTranslation(_T((0.0, 0.0, 0.0)), np.zeros(3), np.zeros(3), dt)
    steps = [(0.02, np.array([0.001, 0.03, 0.0])), (-0.015, np.array([-0.002, 0.02, 0.0])),
             (0.03, np.array([0.0, 0.05, 0.0]))]

    def estimate(arm):
        for yaw, step in steps:
            arm.update(_T((0.0, 0.0, 0.0)), _T(tuple(step), yaw), still, dt)
        return arm.value()

    default = estimate(LeverArm(30.0))
    np.testing.assert_allclose(default, estimate(LeverArm(30.0, prior_m=2.0, noise_m=0.01)),
                               rtol=1e-12, atol=1e-15)
    for other in (LeverArm(30.0, prior_m=1.0), LeverArm(30.0, noise_m=0.02)):
        assert np.max(np.abs(estimate(other) - default)) > 1e-3 * np.max(np.abs(default))
