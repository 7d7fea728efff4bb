"""Doppler 4D-ICP (the paper's Algorithm 1)."""

import numpy as np
import pytest

from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo
from loaders.se3 import inv_T, rotation_angle_deg
from methods.doppler import DopplerCorrespondence, doppler_pairs, register_numpy
from methods.doppler_icp import DopplerIcp, gauss_newton_step
from methods.registry import make_method


def test_noise_free_pair_recovers_the_motion():
    seq = constant_twist_sequence(n_frames=6, max_range_m=1e3)
    m = make_method("doppler-icp", {}, SensorInfo("radar", 0.1))
    src, tgt = (m.preprocess(seq[k]) for k in (4, 5))
    res = m.register(src, tgt, np.eye(4))
    E = inv_T(inv_T(seq.ground_truth.poses[5]) @ seq.ground_truth.poses[4]) @ res.T_target_source
    assert res.converged
    assert np.linalg.norm(E[:3, 3]) < 1e-3 and rotation_angle_deg(E[:3, :3]) < 0.05, E


def test_parameter_sets_follow_the_sensor_kind():
    radar = make_method("doppler-icp", {}, SensorInfo("radar", 0.08)).params
    lidar = make_method("doppler-icp", {}, SensorInfo("lidar", 0.1)).params
    assert (radar.tau_spatial_m, radar.tau_doppler, radar.alpha) == (3.0, 10.0, 0.7)
    assert (lidar.tau_spatial_m, lidar.tau_doppler, lidar.alpha) == (2.0, 5.0, 0.9)
    mine = make_method("doppler-icp", {"tau_doppler": 8.0}, SensorInfo("radar", 0.08)).params
    assert mine.tau_doppler == 8.0 and mine.alpha == 0.7


def test_doppler_pairs_are_those_of_algorithm_2():
    seq = constant_twist_sequence(n_frames=3, noise_m=0.02)
    dc = DopplerCorrespondence(backend="numpy")
    src, tgt = dc.preprocess(seq[0]), dc.preprocess(seq[1])
    s_idx, t_idx = doppler_pairs(src, tgt, 3.0, 5.0)
    T, n = register_numpy(src, tgt, 3.0, 5.0)
    assert len(s_idx) == n > 100
    # the same pairs give the same closed-form fit as Algorithm 2
    from methods.rigid import fit_rigid
    T_pairs = fit_rigid(src.points_t.T[s_idx].astype(float), tgt.points_t.T[t_idx].astype(float))
    np.testing.assert_allclose(T_pairs, T, atol=1e-9)
    # Doppler 4D-ICP's own preparation finds the same pairs
    icp = DopplerIcp()
    a, b = doppler_pairs(icp.preprocess(seq[0]), icp.preprocess(seq[1]), 3.0, 5.0)
    np.testing.assert_array_equal(a, s_idx)
    np.testing.assert_array_equal(b, t_idx)


def test_the_gauss_newton_step_solves_a_pure_translation_exactly():
    rng = np.random.default_rng(0)
    p = rng.uniform(-10, 10, (200, 3))
    xi = gauss_newton_step(p, p + [0.1, -0.2, 0.05], np.empty((0, 3)), np.empty((0, 3)),
                           0.0, 0.5)
    np.testing.assert_allclose(xi, [0.1, -0.2, 0.05, 0, 0, 0], atol=1e-12)
    # Huber: an outlier pair beyond 0.5 m has weight 0.5 / |r|, so it pulls less
    q = p + [0.1, 0.0, 0.0]
    q[0] += [20.0, 0.0, 0.0]
    xi = gauss_newton_step(p, q, np.empty((0, 3)), np.empty((0, 3)), 0.0, 0.5)
    plain = (q - p).mean(axis=0)[0]
    assert 0.1 < xi[0] < plain


def test_missing_doppler_is_a_clear_error():
    with pytest.raises(DataError, match="lidar.bin.*Doppler"):
        DopplerIcp().preprocess(Scan(0.0, np.ones((5, 3)), source="lidar.bin, frame 3"))
