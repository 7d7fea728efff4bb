"""The pieces of the sensor-to-GT rotation estimate (bench.data.calibration.estimate) against
independent answers: scipy's rotations (Rodrigues, Euler angles, Kabsch), rotations fitted to
direction pairs made from a known rotation, a road plane placed on purpose, and the words
``bench inspect`` prints for a consistent, a loose and an unobservable angle."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import bench.data.calibration.estimate as est
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import make_T
from loaders.trajectory import Trajectory


def _unit(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("w", [[0.3, -0.2, 0.9], [1e-3, 0, 0], [0.0, 0.0, 0.0],
                               [2.0, 1.0, -0.5]])
def test_the_exponential_is_scipys_rotation_vector(w):
    np.testing.assert_allclose(est._exp_so3(np.array(w, float)),
                               Rotation.from_rotvec(w).as_matrix(), atol=1e-12)


def test_the_euler_matrix_is_z_y_x_and_angles_come_back():
    ang = np.array([0.2, -0.35, 1.1])  # roll, pitch, yaw
    R = Rotation.from_euler("ZYX", ang[::-1]).as_matrix()
    np.testing.assert_allclose(est.euler_matrix(ang), R, atol=1e-12)
    np.testing.assert_allclose(est.rotation_angles(R), np.degrees(ang), atol=1e-9)


def test_the_axial_vector_is_twice_the_antisymmetric_part():
    M = np.arange(9.0).reshape(3, 3) ** 1.5
    A = M - M.T
    np.testing.assert_allclose(est._axial(M), [A[1, 2], A[2, 0], A[0, 1]])
    rng = np.random.default_rng(0)
    u, b = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    np.testing.assert_allclose(est._axial(u.T @ b), np.cross(u, b).sum(axis=0), atol=1e-12)


def test_kabsch_recovers_a_rotation_and_never_reflects():
    rng = np.random.default_rng(1)
    R = Rotation.from_euler("xyz", [10, -20, 35], degrees=True).as_matrix()
    a = _unit(rng, 40)
    np.testing.assert_allclose(est.kabsch(a, a @ R.T), R, atol=1e-12)
    # pairs that a reflection would fit best: still a rotation (det +1)
    flat = a * [1, 1, 0]
    out = est.kabsch(flat, flat * [1, 1, -1])
    assert np.linalg.det(out) == pytest.approx(1.0)


def test_fitting_only_free_axes():
    rng = np.random.default_rng(2)
    a = _unit(rng, 60)
    R = Rotation.from_euler("z", 12, degrees=True).as_matrix()
    fit = est.fit_rotation(a, a @ R.T, np.array([True, True, True]))
    np.testing.assert_allclose(fit, R, atol=1e-9)
    # only yaw free: the same rotation (it is a yaw)
    np.testing.assert_allclose(est.fit_rotation(a, a @ R.T, np.array([False, False, True])), R,
                               atol=1e-9)
    # only roll free: no yaw can be fitted, the rotation stays about x
    only_x = est.fit_rotation(a, a @ R.T, np.array([True, False, False]))
    rv = Rotation.from_matrix(only_x).as_rotvec()
    assert abs(rv[1]) < 1e-12 and abs(rv[2]) < 1e-12


def test_fitting_angles_from_two_cues():
    rng = np.random.default_rng(3)
    true = np.radians([1.5, -2.0, 3.0])
    R = est.euler_matrix(true)
    a = _unit(rng, 80)
    ang = est.fit_angles([(a.T @ (a @ R.T), np.array([True, True, True]))])
    np.testing.assert_allclose(ang, true, atol=1e-10)
    # pitch and yaw from one cue, roll from another: both exact on exact pairs
    n = _unit(rng, 30)
    ang = est.fit_angles([(a.T @ (a @ R.T), np.array([False, True, True])),
                          (n.T @ (n @ R.T), np.array([True, False, False]))])
    np.testing.assert_allclose(ang, true, atol=1e-10)
    # an angle in no mask stays 0
    ang = est.fit_angles([(a.T @ (a @ R.T), np.array([False, True, True]))])
    assert abs(ang[0]) < 1e-12


def test_the_outlier_cut_drops_pairs_beyond_three_robust_sigmas():
    rng = np.random.default_rng(4)
    a = _unit(rng, 50)
    R = Rotation.from_euler("z", 5, degrees=True).as_matrix()
    b = a @ R.T
    # exact pairs: every one kept (the 0.05 deg floor)
    assert est.outlier_cut(a, b).all()
    bad = b.copy()
    bad[:3] = _unit(rng, 3)
    keep = est.outlier_cut(a, bad)
    assert not keep[:3].any() and keep[3:].all()


def _road_scan(height=1.2, tilt_deg=0.0, n=400, seed=0, extra=()):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-25, 25, (n, 2))  # all within 40 m
    z = -height + np.tan(np.radians(tilt_deg)) * xy[:, 0]
    p = np.column_stack([xy, z])
    if len(extra):
        p = np.concatenate([p, np.asarray(extra, float)])
    return Scan(0.0, p)


def test_the_road_plane_gives_its_normal_and_the_sensor_height():
    normal, height = est.road_normal(_road_scan(1.2, tilt_deg=3.0))
    expected = np.array([-np.sin(np.radians(3.0)), 0.0, np.cos(np.radians(3.0))])
    np.testing.assert_allclose(normal, expected, atol=1e-9)
    # the plane through (0, 0, -1.2): its distance from the sensor along the normal
    assert height == pytest.approx(1.2 * np.cos(np.radians(3.0)), abs=1e-9)


def test_no_road_plane_from_too_few_points_or_a_wall():
    assert est.road_normal(_road_scan(n=29)) is None
    assert est.road_normal(_road_scan(n=30)) is not None
    # points above -0.3 m are not road candidates
    assert est.road_normal(_road_scan(height=0.25)) is None
    # points beyond 40 m are not either
    far = _road_scan(n=300)
    far = Scan(0.0, far.points * [3.0, 3.0, 1.0] + [200.0, 0, 0])
    assert est.road_normal(far) is None
    # a plane tilted 30 deg is no road
    assert est.road_normal(_road_scan(tilt_deg=30.0)) is None


def _moving_seq(n=30, speed=5.0, doppler=True, gt=True):
    t = np.arange(n) * 0.125
    rng = np.random.default_rng(5)
    scans = []
    v = np.array([speed, 0.0, 0.0])
    for k in range(n):
        p = rng.uniform(-1, 1, (300, 3)) * [40, 40, 3] + [0, 0, 1]
        d = -(p / np.linalg.norm(p, axis=1, keepdims=True)) @ v
        scans.append(Scan(t[k], p, d if doppler else None))
    traj = Trajectory(t, np.array([make_T(np.eye(3), np.array([speed * s, 0, 0])) for s in t]))
    return MemorySequence("m", SensorInfo("lidar", 0.125), scans, traj if gt else None)


def test_collecting_cues_refuses_without_gt_doppler_or_speed():
    with pytest.raises(DataError, match="^m: calibration needs ground truth; this store has "
                                        "none$"):
        est.collect_cues(_moving_seq(gt=False))
    with pytest.raises(DataError, match="frame 0: calibration needs Doppler"):
        est.collect_cues(_moving_seq(doppler=False))
    with pytest.raises(DataError, match=r"^m: only 0 frames faster than 2\.0 m/s with an "
                                        "observable ego velocity; calibration needs at least 5$"):
        est.collect_cues(_moving_seq(speed=1.5))
    seq = _moving_seq()
    late = Trajectory(seq.ground_truth.stamps + 100, seq.ground_truth.poses)
    with pytest.raises(DataError, match=r"m: no scan has ground truth \(its ground truth spans "
                                        r"100\.000-103\.625 s, the 30 scans 0\.000-3\.625 s\)"):
        est.collect_cues(MemorySequence("m", seq.sensor, list(seq), late))


def test_the_cues_of_a_straight_drive():
    cues = est.collect_cues(_moving_seq())
    assert cues.n_frames == 30 and cues.period_s == 0.125
    np.testing.assert_array_equal(cues.vel_frame, np.arange(30))
    np.testing.assert_allclose(cues.a, np.tile([1.0, 0, 0], (30, 1)), atol=1e-6)
    np.testing.assert_allclose(cues.b, np.tile([1.0, 0, 0], (30, 1)), atol=1e-9)
    piece = cues.piece(10, 20)
    assert piece.n_frames == 10 and list(piece.vel_frame) == list(range(10))
    v, r = cues.rows(np.array([3, 3, 29]))
    assert list(v) == [3, 3, 29] and len(r) == len(set(cues.road_frame) & {3, 29}) + \
        (3 in set(cues.road_frame))


def _cal(std, source):
    return est.CalibrationResult(np.eye(3), dict.fromkeys(est.ANGLES, 0.0),
                                 dict(zip(est.ANGLES, std, strict=True)),
                                 dict(zip(est.ANGLES, source, strict=True)), 10)


def test_what_inspect_says_of_a_consistent_rotation():
    cal = _cal([0.1, 0.2, 0.05], ["road plane", "velocity", "velocity"])  # 3 sd: 0.6 deg
    assert est.rotation_consistent_text(cal) == (
        "sensor-to-GT rotation (Doppler ego velocity vs GT velocity): roll, yaw consistent "
        "within 0.5 deg; known only loosely, none found off: pitch +-0.20 deg (sd); see "
        "`bench calibrate`")
    cal = _cal([0.1, 0.1, 0.1], ["not observable", "velocity", "velocity"])
    assert est.rotation_consistent_text(cal) == (
        "sensor-to-GT rotation (Doppler ego velocity vs GT velocity): pitch, yaw consistent "
        "within 0.5 deg; not observable: roll; see `bench calibrate`")
    cal = _cal([1.0, 1.0, 1.0], ["velocity"] * 3)
    assert est.rotation_consistent_text(cal, limit_deg=2).startswith(
        "sensor-to-GT rotation (Doppler ego velocity vs GT velocity): no angle fixed to 2 deg")
    tight = _cal([0.1, 0.1, 0.1], ["velocity"] * 3)
    assert est.rotation_consistent_text(tight).endswith("roll, pitch, yaw consistent within "
                                                        "0.5 deg")


def test_why_an_angle_is_not_observable():
    spread = np.array([0.01, 0.2, 0.03])
    out = est._reasons(spread, 0.05, 2, np.array([False, True, False]),
                       np.array([False, False, False]))
    assert out == {
        "roll": "the velocity directions hardly turn about the sensor's x axis (RMS spread "
                "0.010, below 0.05), and the road plane was found in only 2 frames (5 needed)",
        "yaw": "the velocity directions hardly turn about the sensor's z axis (RMS spread "
               "0.030, below 0.05)"}
    assert est._reasons(spread, 0.05, 9, np.array([False, True, False]),
                        np.array([True, False, True])) == {}


# --- tests written against the survivors of a mutation run (tools/mutate.py) ---


def test_the_exponential_of_a_tiny_rotation_turns_the_right_way():
    w = np.array([1e-13, -2e-13, 3e-13])
    R = est._exp_so3(w)
    # first order: R = I + [w]x, so R[2, 1] = w_x, R[0, 2] = w_y, R[1, 0] = w_z
    np.testing.assert_allclose([R[2, 1], R[0, 2], R[1, 0]], w, rtol=1e-6)


def test_kabsch_of_mirrored_pairs_is_still_a_rotation():
    a = _unit(np.random.default_rng(7), 30)
    out = est.kabsch(a, a * [1, 1, -1])  # a reflection in z would fit them exactly
    assert np.linalg.det(out) == pytest.approx(1.0)
    np.testing.assert_allclose(out @ out.T, np.eye(3), atol=1e-12)


def test_free_axes_given_as_zero_one_flags():
    a = _unit(np.random.default_rng(8), 40)
    R = Rotation.from_euler("z", 12, degrees=True).as_matrix()
    np.testing.assert_allclose(est.fit_rotation(a, a @ R.T, [0, 0, 1]), R, atol=1e-9)


def _dtrace(S, ang, k, h=1e-6):
    """d tr(R(ang) S) / d ang_k by central differences of scipy's Z-Y-X Euler matrix."""
    def f(x):
        return np.trace(Rotation.from_euler("ZYX", x[::-1]).as_matrix() @ S)
    e = np.zeros(3)
    e[k] = h
    return (f(ang + e) - f(ang - e)) / (2 * h)


def test_two_disagreeing_cues_each_stationary_in_their_own_angles():
    rng = np.random.default_rng(9)
    a, n = _unit(rng, 50), _unit(rng, 20) * [0.3, 0.3, 1.0]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    R1 = Rotation.from_euler("ZYX", [40, 20, 8], degrees=True).as_matrix()
    R2 = Rotation.from_euler("ZYX", [35, 15, -10], degrees=True).as_matrix()
    S_v, S_r = a.T @ (a @ R1.T), n.T @ (n @ R2.T)
    ang = est.fit_angles([(S_v, np.array([False, True, True])),
                          (S_r, np.array([True, False, False]))])
    for k in (1, 2):
        assert abs(_dtrace(S_v, ang, k)) < 1e-6
    assert abs(_dtrace(S_r, ang, 0)) < 1e-6
    # pitch alone free, the other angles held at 0
    ang = est.fit_angles([(S_v, np.array([False, True, False]))])
    assert ang[0] == 0 and ang[2] == 0 and abs(_dtrace(S_v, ang, 1)) < 1e-6
    ang = est.fit_angles([(S_v, np.array([False, True, True])),
                          (S_r, np.array([True, False, False]))])
    # a fit away from the identity (the roll the road holds turns pitch and yaw somewhat)
    assert np.degrees(ang[2]) > 25 and np.degrees(ang[1]) > 10


def test_one_cue_with_large_angles_gives_them_back():
    # (from zero, Newton found up to some 45 deg only; it starts from the free fit now: a
    # sensor mounted sideways or backwards is found too)
    a = _unit(np.random.default_rng(10), 60)
    for true_deg, free in (([-15.0, 22.5, 45.0], [True, True, True]),
                           ([0.0, 22.5, 45.0], [False, True, True]),
                           ([30.0, -40.0, 90.0], [True, True, True]),
                           ([0.0, 10.0, 170.0], [False, True, True]),
                           ([0.0, 0.0, -120.0], [False, False, True])):
        R = Rotation.from_euler("ZYX", true_deg[::-1], degrees=True).as_matrix()
        ang = est.fit_angles([(a.T @ (a @ R.T), np.array(free))])
        np.testing.assert_allclose(np.degrees(ang), true_deg, atol=1e-8)


def test_large_angles_split_between_velocity_and_road():
    """Yaw and pitch from velocity pairs, roll from road normals, a sensor turned 100 deg in
    yaw: both cues fitted together give the angles back (scipy's ZYX Euler angles)."""
    rng = np.random.default_rng(11)
    a, n = _unit(rng, 60), _unit(rng, 20)
    true_deg = [12.0, -8.0, 100.0]
    R = Rotation.from_euler("ZYX", true_deg[::-1], degrees=True).as_matrix()
    ang = est.fit_angles([(a.T @ (a @ R.T), np.array([False, True, True])),
                          (n.T @ (n @ R.T), np.array([True, False, False]))])
    np.testing.assert_allclose(np.degrees(ang), true_deg, atol=1e-8)


def test_gt_velocity_and_up_in_the_gt_frame():
    t = np.arange(6) * 0.1
    rot = Rotation.from_euler("ZYX", [30, 0, 10], degrees=True)
    poses = np.array([make_T(rot.as_matrix(), np.array([4.0 * s, 0, 0])) for s in t[1:4]])
    gt = Trajectory(t[1:4], poses)  # covers exactly 3 of the 6 stamps
    vel, up = est.gt_velocity_directions(gt, t)
    inside = np.array([False, True, True, True, False, False])
    assert np.isnan(vel[~inside]).all() and np.isnan(up[~inside]).all()
    np.testing.assert_allclose(vel[inside], np.tile(rot.inv().apply([4.0, 0, 0]), (3, 1)),
                               atol=1e-9)
    np.testing.assert_allclose(up[inside], np.tile(rot.inv().apply([0, 0, 1.0]), (3, 1)),
                               atol=1e-12)


def _tilted(a, deg, rng):
    """Each a_i turned by ``deg`` degrees about a random axis perpendicular to it."""
    axis = np.cross(a, _unit(rng, len(a)))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return Rotation.from_rotvec(np.radians(np.asarray(deg))[:, None] * axis).apply(a)


def test_the_outlier_cut_threshold_is_three_robust_sigmas():
    rng = np.random.default_rng(11)
    a = _unit(rng, 300)
    errs = np.full(300, 0.1)
    errs[:3] = [0.3, 0.52, 1.0]  # 3 x 1.4826 x 0.1 deg = 0.445 deg
    keep = est.outlier_cut(a, _tilted(a, errs, rng))
    assert keep[0] and not keep[1] and not keep[2] and keep[3:].all()


def _cues():
    # 10 frames; velocity rows at frames 0, 2, 5, 9; road rows at frames 0, 1, 5, 8
    return est.FrameCues(10, 0.1, np.array([0, 2, 5, 9]), np.arange(12.0).reshape(4, 3),
                         -np.arange(12.0).reshape(4, 3), np.array([0, 1, 5, 8]),
                         np.arange(12.0).reshape(4, 3) + 100, np.arange(12.0).reshape(4, 3) + 200,
                         np.array([1.0, 1.1, 1.2, 1.3]))


def test_rows_of_drawn_frames_with_the_first_and_missing_rows():
    v, r = _cues().rows(np.array([0, 1, 9, 0, 3, 8]))
    assert list(v) == [0, 3, 0] and list(r) == [0, 1, 0, 3]
    v, r = _cues().rows(np.array([3, 4]))
    assert list(v) == [] and list(r) == []


def test_a_piece_keeps_its_own_road_rows_renumbered():
    p = _cues().piece(1, 8)
    assert p.n_frames == 7 and p.period_s == 0.1
    assert list(p.vel_frame) == [1, 4] and list(p.road_frame) == [0, 4]
    np.testing.assert_array_equal(p.a, [[3, 4, 5], [6, 7, 8]])
    np.testing.assert_array_equal(p.b, [[-3, -4, -5], [-6, -7, -8]])
    np.testing.assert_array_equal(p.normals, [[103, 104, 105], [106, 107, 108]])
    np.testing.assert_array_equal(p.ups, [[203, 204, 205], [206, 207, 208]])
    np.testing.assert_allclose(p.heights, [1.1, 1.2])


def test_what_inspect_says_at_the_edge_of_the_limit():
    # 3 sd equal to the limit is still consistent; 0.15 sd: 3 sd = 0.45 < 0.5
    cal = _cal([0.25, 0.15, 0.3], ["velocity", "velocity", "velocity"])
    assert est.rotation_consistent_text(cal, limit_deg=0.75) == (
        "sensor-to-GT rotation (Doppler ego velocity vs GT velocity): roll, pitch consistent "
        "within 0.75 deg; known only loosely, none found off: yaw +-0.30 deg (sd); see "
        "`bench calibrate`")
    cal = _cal([0.15, 0.4, 0.5], ["velocity", "velocity", "velocity"])
    assert est.rotation_consistent_text(cal) == (
        "sensor-to-GT rotation (Doppler ego velocity vs GT velocity): roll consistent within "
        "0.5 deg; known only loosely, none found off: pitch +-0.40 deg (sd), yaw +-0.50 deg "
        "(sd); see `bench calibrate`")
    cal = _cal([2.0, 2.0, 0.1], ["not observable", "not observable", "velocity"])
    assert est.rotation_consistent_text(cal) == (
        "sensor-to-GT rotation (Doppler ego velocity vs GT velocity): yaw consistent within "
        "0.5 deg; not observable: roll, pitch; see `bench calibrate`")
