"""DICP: known motion, the turning bias of its velocity model, and the cross-check against the
authors' own implementation in Open3D on synthetic radar and LiDAR pairs."""

import numpy as np
import pytest

from conftest import constant_twist_sequence, dev_dependency
from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo
from loaders.se3 import inv_T, rotation_angle_deg
from methods.dicp import Dicp, euler_zyx, pose_to_T
from methods.registry import make_method


def _twist_pair(v, w, T_body_sensor=None):
    """Two exact scans of static random points (all visible in both) from a sensor moving with
    a constant body twist; returns (scans, true T_target_source, sensor)."""
    seq = constant_twist_sequence(n_frames=2, n_points=20000, v=v, w=w, max_range_m=1e4)
    sensor = SensorInfo("lidar", 0.1, **({} if T_body_sensor is None
                                         else {"T_body_sensor": T_body_sensor}))
    return [seq[0], seq[1]], inv_T(seq.ground_truth.poses[1]) @ seq.ground_truth.poses[0], sensor


def _error(T, T_true):
    E = inv_T(T_true) @ T
    return np.linalg.norm(E[:3, 3]), rotation_angle_deg(E[:3, :3])


def _register(backend, scans, sensor, init, **params):
    m = make_method("dicp", {"backend": backend, **params}, sensor)
    return m.register(m.preprocess(scans[0]), m.preprocess(scans[1]), init)


def test_straight_noise_free_motion_is_recovered():
    scans, T_true, sensor = _twist_pair((8.0, 0.0, 0.0), (0.0, 0.0, 0.0))  # 0.8 m per scan
    r = _register("numba", scans, sensor, np.eye(4))
    trans, rot = _error(r.T_target_source, T_true)
    assert r.converged and trans < 1e-3 and rot < 0.05, (trans, rot)


def test_the_first_order_velocity_model_biases_a_turn():
    # 12 m/s and 0.15 rad/s over 0.1 s, started at the truth: -t / period is not the velocity
    # at the source scan, and the Doppler term pulls the estimate off by millimetres (the
    # docstring states the figure); Open3D's implementation has the same bias
    scans, T_true, sensor = _twist_pair((12.0, 0.0, 0.0), (0.0, 0.0, 0.15))
    r = _register("numba", scans, sensor, T_true)
    trans, _ = _error(r.T_target_source, T_true)
    assert 3e-3 < trans < 1.5e-2, trans
    dev_dependency("open3d")
    upstream = _register("open3d", scans, sensor, T_true)
    assert abs(_error(upstream.T_target_source, T_true)[0] - trans) < 1e-6


def test_pose_conventions_are_open3ds():
    x = np.array([0.1, -0.2, 0.3, 1.0, 2.0, 3.0])
    T = pose_to_T(x)
    Rx = np.array([[1, 0, 0], [0, np.cos(0.1), -np.sin(0.1)], [0, np.sin(0.1), np.cos(0.1)]])
    Ry = np.array([[np.cos(-0.2), 0, np.sin(-0.2)], [0, 1, 0], [-np.sin(-0.2), 0, np.cos(-0.2)]])
    Rz = np.array([[np.cos(0.3), -np.sin(0.3), 0], [np.sin(0.3), np.cos(0.3), 0], [0, 0, 1]])
    np.testing.assert_allclose(T[:3, :3], Rz @ Ry @ Rx, atol=1e-12)
    np.testing.assert_allclose(euler_zyx(T[:3, :3]), x[:3], atol=1e-12)


def _rotated_extrinsic(sensor: SensorInfo) -> SensorInfo:
    """The sensor with a yawed and pitched mounting (Open3D rotates the directions with it)."""
    T = np.array(sensor.T_body_sensor, dtype=float)
    T[:3, :3] = pose_to_T(np.array([0.0, 0.05, 0.3, 0, 0, 0]))[:3, :3]
    return SensorInfo(sensor.kind, sensor.period_s, T_body_sensor=T, model=sensor.model)


@pytest.mark.parametrize("scene, sensor, points, seeded, rotated", [
    ("loop", "radar-semidense", None, False, False),
    ("loop", "radar-semidense", None, True, False),
    ("loop", "radar-semidense", None, False, True),
    ("campus", "lidar-dense", 12000, False, False),
    ("campus", "lidar-dense", 12000, True, False),
])
def test_same_transform_as_open3d(scene, sensor, points, seeded, rotated):
    dev_dependency("open3d")
    from loaders.synthetic import SyntheticSequence

    options = {"points": points} if points else {}
    seq = SyntheticSequence(scene, sensor, frames=3, seed=7, noise=True, **options)
    info = _rotated_extrinsic(seq.sensor) if rotated else seq.sensor
    init = np.eye(4)
    if seeded:
        init = inv_T(seq.ground_truth.poses[2]) @ seq.ground_truth.poses[1]
        init[:3, 3] += [0.05, -0.03, 0.01]
    ours, upstream = (_register(b, [seq[1], seq[2]], info, init) for b in ("numba", "open3d"))
    # the same algorithm on the same normals: equal up to rounding (1e-14 measured; 1e-9 leaves
    # room for other CPUs' BLAS and still fails on any difference in pairs, weights or steps)
    diff = np.abs(ours.T_target_source - upstream.T_target_source).max()
    assert diff < 1e-9, diff
    assert ours.correspondences == upstream.correspondences > 100
    assert ours.iterations == upstream.iterations
    assert ours.converged and upstream.converged
    truth = inv_T(seq.ground_truth.poses[2]) @ seq.ground_truth.poses[1]
    assert _error(ours.T_target_source, truth)[0] < 0.1  # and both found the motion


def test_no_pair_at_the_start_gives_the_identity_as_open3ds():
    """A start 200 m above the truth leaves no target point within the 0.3 m gate: not
    converged, no pairs, no step, and the answer is the identity as Open3D's (its evaluation
    resets the transformation), not the start."""
    scans, T_true, sensor = _twist_pair((8.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    init = T_true.copy()
    init[2, 3] += 200.0
    r = _register("numba", scans, sensor, init)
    assert (r.converged, r.correspondences, r.iterations) == (False, 0, 0)
    np.testing.assert_array_equal(r.T_target_source, np.eye(4))
    dev_dependency("open3d")
    upstream = _register("open3d", scans, sensor, init)
    assert (upstream.converged, upstream.correspondences, upstream.iterations) == (False, 0, 0)
    np.testing.assert_array_equal(upstream.T_target_source, np.eye(4))


def test_a_pair_that_loses_its_pairs_ends_as_open3ds():
    """The CI suite's sparse radar (campus, radar-sparse, seed 201), frames 9 -> 10 without a
    seed: started at the identity, 0.42 m from the truth, both implementations lose every pair
    after some steps (with the field-of-view edge band; 3 steps on the generator of issue 40).
    Ours returned its drifted transform there (47 deg off, ci-sparse/dicp/noseed's 8 m rotation
    12 deg), Open3D the identity; now the same answer, pairs and iterations."""
    dev_dependency("open3d")
    from loaders.synthetic import SyntheticSequence

    seq = SyntheticSequence("campus", "radar-sparse", frames=60, seed=201, noise=True)
    ours, upstream = (_register(b, [seq[9], seq[10]], seq.sensor, np.eye(4))
                      for b in ("numba", "open3d"))
    assert np.abs(ours.T_target_source - upstream.T_target_source).max() < 1e-9
    assert ours.correspondences == upstream.correspondences
    assert ours.iterations == upstream.iterations
    assert ours.converged == upstream.converged


def test_normals_are_open3ds_also_where_a_point_has_no_plane():
    """Target normals against Open3D's estimate_normals (10 m, at most 30), on a radar-like
    cloud with isolated far points (fewer than 3 within 10 m) and a stack of coincident ones:
    Open3D gives those (0, 0, 1). Ours were zero, which dropped a pair's point-to-plane term:
    on the loop radar pair of test_same_transform_as_open3d (seed 7, with the field-of-view
    edge band) one source point pairs with such a target from the second iteration on, and the
    two implementations then stopped 7 vs 8 iterations, 3.3e-4 apart."""
    dev_dependency("open3d")
    from methods.dicp import estimate_normals
    from methods.dicp_open3d import estimate_normals_open3d

    rng = np.random.default_rng(11)
    near = np.column_stack([rng.uniform(5, 40, 600), rng.uniform(-20, 20, 600),
                            rng.normal(0, 0.3, 600)])
    far = np.array([[150.0, 0, 2], [120, 60, 5], [120, 64, 5], [90, -80, 1]])
    pts = np.vstack([near, far, np.tile([60.0, -50.0, 3.0], (3, 1))])
    ours, theirs = estimate_normals(pts, 10.0, 30), estimate_normals_open3d(pts, 10.0, 30)
    np.testing.assert_array_equal(ours[len(near):], np.tile([0.0, 0.0, 1.0], (7, 1)))
    assert np.all(np.abs(np.einsum("ij,ij->i", ours, theirs)) > 1 - 1e-9)


def test_bad_input():
    with pytest.raises(DataError, match="radar.bag, frame 4.*Doppler"):
        Dicp().preprocess(Scan(0.0, np.ones((10, 3)), source="radar.bag, frame 4"))
    m = Dicp()
    tiny = [m.preprocess(Scan(t, np.eye(3) + 1.0, np.zeros(3))) for t in (0.0, 0.1)]
    r = m.register(tiny[0], tiny[1], np.eye(4))
    assert not r.converged and np.array_equal(r.T_target_source, np.eye(4))


def test_the_extrinsic_is_taken_from_the_sequence():
    T_bs = np.eye(4)
    T_bs[:3, 3] = [1.4, 0.2, 1.3]
    scans, T_true, sensor = _twist_pair((2.0, 0.0, 0.0), (0.0, 0.0, 0.0), T_bs)
    m = make_method("dicp", {}, sensor)
    np.testing.assert_allclose(m.T_vehicle_sensor, T_bs)
    r = m.register(m.preprocess(scans[0]), m.preprocess(scans[1]), np.eye(4))
    assert _error(r.T_target_source, T_true)[0] < 1e-3  # answered in the sensor frame
    assert make_method("dicp", {}, SensorInfo("lidar", 0.1)).T_vehicle_sensor.tolist() \
        == np.eye(4).tolist()


@pytest.mark.parametrize("turned", [False, True])
def test_a_turning_vehicle_with_an_offset_sensor(turned):
    """The lever arm, without Open3D, on geometry computed by hand. The vehicle drives at 5 m/s
    along its x axis and turns at 0.5 rad/s about its z axis; the sensor sits 2 m ahead, 0.5 m
    left and 1 m up (``T_body_sensor``; ``turned``: also yawed 0.3 rad and pitched 0.05 rad).
    In vehicle axes the sensor moves at v + w x r = (5 - 0.25, 1.0, 0) m/s: the turn swings it
    sideways at 1 m/s. Its scans carry the Doppler of that velocity. DICP registers in the
    vehicle frame and predicts the sensor velocity as the vehicle's plus w x lever arm:
    from the truth or from the identity it ends within its first-order bias (8 mm here, see
    the module docstring). The lever arm's sign flipped predicts (5.25, -1, 0) m/s and ends
    13 cm off; the lever arm dropped, 7 cm."""
    r = np.array([2.0, 0.5, 1.0])
    v_vehicle, w_vehicle = np.array([5.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.5])
    v_by_hand = np.array([5.0 - 0.5 * 0.5, 0.5 * 2.0, 0.0])  # w x r = (-w r_y, w r_x, 0)
    np.testing.assert_allclose(v_vehicle + np.cross(w_vehicle, r), v_by_hand, atol=1e-15)
    T_bs = np.eye(4)
    T_bs[:3, 3] = r
    if turned:
        T_bs[:3, :3] = pose_to_T(np.array([0.0, 0.05, 0.3, 0, 0, 0]))[:3, :3]
    R_sb = T_bs[:3, :3].T
    # the sensor's own constant twist (sensor axes); the scans' Doppler is -d . v_sensor
    scans, T_true, sensor = _twist_pair(R_sb @ v_by_hand, R_sb @ w_vehicle, T_bs)
    d = scans[0].points / np.linalg.norm(scans[0].points, axis=1, keepdims=True)
    np.testing.assert_allclose(scans[0].doppler, -(d @ (R_sb @ v_by_hand)), atol=1e-9)
    for init in (T_true, np.eye(4)):
        res = _register("numba", scans, sensor, init)
        trans, rot = _error(res.T_target_source, T_true)
        assert res.converged and trans < 0.02 and rot < 0.005, (turned, trans, rot)


def test_the_doppler_jacobian_holds_the_lever_arm():
    """The Gauss-Newton normal equations (``dicp_kernel.normal_equations``) of one point with a
    Doppler residual only (lambda 1, no kernels) are J J^T and J r. At the identity the
    residual's Jacobian over a left pose update (Open3D's angles about x, y, z, translation)
    is computed here by central differences of the model written out by hand: velocity
    -t / period, angular rate -angles / period, sensor velocity R_sv (v + w x lever arm),
    predicted Doppler -(R_sv d) . v_sensor."""
    from methods.dicp_kernel import normal_equations

    period, doppler = 0.1, 0.7
    lever = np.array([1.5, -0.4, 0.9])
    R_vs = pose_to_T(np.array([0.02, -0.05, 0.3, 0, 0, 0]))[:3, :3]
    R_sv = R_vs.T
    d = R_vs @ np.array([0.6, 0.64, 0.48])  # a unit direction, in vehicle axes

    def residual(x):
        T = pose_to_T(x)  # the update applied to the identity
        w = -euler_zyx(T[:3, :3]) / period
        v_sensor = R_sv @ (-T[:3, 3] / period + np.cross(w, lever))
        return doppler - (-(R_sv @ d) @ v_sensor)

    h = 1e-6
    J = np.array([(residual(h * e) - residual(-h * e)) / (2 * h) for e in np.eye(6)])
    assert np.abs(J[:3]).max() > 1.0  # the lever arm's rotation terms are not small
    A, b = normal_equations(np.zeros((1, 3)), np.array([0]), np.zeros((1, 3)),
                            np.array([[0.0, 0.0, 1.0]]), np.array([doppler]), d[None, :],
                            R_sv, np.zeros(3), lever, period, 1.0, 0.0, 0.0, False, 2.0)
    np.testing.assert_allclose(A, np.outer(J, J), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(b, J * residual(np.zeros(6)), rtol=1e-6, atol=1e-6)
