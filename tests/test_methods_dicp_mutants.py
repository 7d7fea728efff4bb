"""methods/dicp.py and methods/dicp_open3d.py, small and fast: Open3D's pose conventions built
by hand, normals of a plane, the preparation's frames, a scan moved by a known motion, and the
iterations against Open3D's own DICP (the authors' implementation, an independent program) on
small pairs: the same transform, pairs, iterations and convergence under every option."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from conftest import constant_twist_sequence, dev_dependency
from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo
from loaders.se3 import inv_T
from methods import dicp_open3d
from methods.dicp import Dicp, estimate_normals, euler_zyx, pose_to_T


def _rot(axis, a):
    """The right-handed rotation by ``a`` about axis 0, 1 or 2 (x, y, z)."""
    c, s = np.cos(a), np.sin(a)
    i, j = ((1, 2), (2, 0), (0, 1))[axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def _pair(v=(1.0, 0.0, 0.0), w=(0.0, 0.0, 0.0), n=3000, seed=0):
    """Two exact scans of static random points (all seen in both) of a sensor moving with a
    constant twist over 0.1 s; (source, target, T_target_source)."""
    seq = constant_twist_sequence(n_frames=2, n_points=n, v=v, w=w, seed=seed, max_range_m=1e4)
    return seq[0], seq[1], inv_T(seq.ground_truth.poses[1]) @ seq.ground_truth.poses[0]


def _extrinsic():
    T = np.eye(4)
    T[:3, :3] = pose_to_T(np.array([0.02, 0.05, 0.3, 0, 0, 0]))[:3, :3]
    T[:3, 3] = [1.5, -0.4, 0.9]
    return T


def _run(source, target, init, **params):
    m = Dicp(**params)
    return m.register(m.preprocess(source), m.preprocess(target), init)


def test_pose_conventions_are_open3ds():
    x = np.array([0.2, -0.1, 0.4, 1.0, -2.0, 0.5])
    T = pose_to_T(x)
    np.testing.assert_allclose(T[:3, :3], _rot(2, 0.4) @ _rot(1, -0.1) @ _rot(0, 0.2),
                               atol=1e-14)
    np.testing.assert_allclose(T[:3, 3], [1.0, -2.0, 0.5])
    np.testing.assert_allclose(T[3], [0, 0, 0, 1])
    np.testing.assert_allclose(euler_zyx(T[:3, :3]), [0.2, -0.1, 0.4], atol=1e-14)


@pytest.mark.parametrize("threads", [1, 2])
def test_normals_of_a_plane_and_of_isolated_points(threads):
    rng = np.random.default_rng(5)
    xy = rng.uniform(-5, 5, (200, 2))
    plane = np.column_stack([xy, 0.3 * xy[:, 0] - 0.2 * xy[:, 1] + 1.0])
    far = np.array([[100.0, 0, 0], [0, 100.0, 0]])
    normals = estimate_normals(np.vstack([plane, far]), 2.0, 12, threads)
    unit = np.array([-0.3, 0.2, 1.0]) / np.linalg.norm([-0.3, 0.2, 1.0])
    np.testing.assert_allclose(np.abs(normals[:200] @ unit), 1.0, atol=1e-9)
    np.testing.assert_array_equal(normals[200:], [[0, 0, 1], [0, 0, 1]])
    # fewer points than the neighbour cap (small_gicp's search is asked for all of them)
    few = estimate_normals(plane[:8], 50.0, 30, threads)
    np.testing.assert_allclose(np.abs(few @ unit), 1.0, atol=1e-9)


@pytest.mark.parametrize("threads", [1, 2])
def test_normals_use_the_neighbours_within_the_radius(threads):
    """A tilted triangle (sides 2.8 m, in the plane x = 100) and a fourth point 4.3 m from
    each corner: within a 3 m radius each corner has the triangle's normal (1, 0, 0)."""
    pts = np.array([[100.0, 0.0, 0.0], [100.0, 2.8, 0.0], [100.0, 1.4, 2.42],
                    [104.0, 1.4, 0.8]])
    normals = estimate_normals(pts, 3.0, 30, threads)
    np.testing.assert_allclose(np.abs(normals[:3, 0]), 1.0, atol=1e-9)
    np.testing.assert_array_equal(normals[3], [0.0, 0.0, 1.0])  # alone within 3 m


def test_preprocess_puts_points_and_directions_in_the_vehicle_frame():
    T_vs = _extrinsic()
    raw = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0, 2.0, 0],
                    [5.0, 5.0, 5.0], [-1.0, -2.0, 2.0]])
    scan = Scan(0.5, np.repeat(raw, 2, axis=0), np.repeat(np.arange(6.0), 2))
    prepared = Dicp(T_vehicle_sensor=T_vs.tolist()).preprocess(scan)  # downsample 2
    assert prepared.stamp == 0.5 and len(prepared) == 6
    np.testing.assert_allclose(prepared.points, raw @ T_vs[:3, :3].T + T_vs[:3, 3], atol=1e-12)
    np.testing.assert_array_equal(prepared.doppler, np.arange(6.0))
    assert prepared.doppler.dtype == np.float64
    unit = np.array([[0.6, 0.8, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0],
                     [3**-0.5] * 3, [-1 / 3, -2 / 3, 2 / 3]])
    np.testing.assert_allclose(prepared.directions, unit @ T_vs[:3, :3].T, atol=1e-12)
    assert prepared.normals.shape == (6, 3) and prepared.tree is not None
    one = Dicp(downsample=1)
    assert len(one.preprocess(scan)) == 12
    tiny = one.preprocess(Scan(0.0, raw[:2], np.zeros(2)))
    np.testing.assert_array_equal(tiny.normals, np.zeros((2, 3)))
    assert Dicp(num_threads=2).preprocess(scan).tree is None
    with pytest.raises(DataError, match="^lidar.bin, frame 3: the dicp method needs Doppler"):
        Dicp().preprocess(Scan(0.0, raw, None, source="lidar.bin, frame 3"))
    with pytest.raises(DataError, match="^scan: the dicp method needs Doppler"):
        Dicp().preprocess(Scan(0.0, raw, None))


def test_the_extrinsic_comes_from_the_sensor_unless_given():
    T = _extrinsic()
    sensor = SensorInfo("radar", 0.1, T_body_sensor=T)
    np.testing.assert_array_equal(Dicp().T_vehicle_sensor, np.eye(4))
    np.testing.assert_allclose(Dicp().configured_for(sensor).T_vehicle_sensor, T)
    kept = Dicp(max_iterations=7, downsample=3).configured_for(sensor)
    assert (kept.params.max_iterations, kept.params.downsample) == (7, 3)
    given = Dicp(T_vehicle_sensor=np.eye(4).tolist())
    assert given.configured_for(sensor) is given


def test_too_few_points_and_stamps_that_do_not_increase():
    source, target, _ = _pair(n=300)
    m = Dicp()
    a, b = m.preprocess(source), m.preprocess(target)
    init = np.eye(4)
    init[0, 3] = 0.1
    few = m.preprocess(Scan(0.0, source.points[:10], source.doppler[:10]))  # 5 after downsample
    for s, t in ((few, b), (a, few)):
        r = m.register(s, t, init)
        assert r.T_target_source is init and (r.correspondences, r.iterations,
                                              r.converged) == (0, 0, False)
    for stamp in (source.stamp, source.stamp - 0.1):
        late = m.preprocess(Scan(stamp, target.points, target.doppler))
        with pytest.raises(DataError, match=r"dicp: scan stamps must increase \(period"):
            m.register(a, late, init)


@pytest.mark.parametrize("threads", [1, 2])
def test_a_straight_motion_is_recovered_exactly(threads):
    source, target, T_true = _pair()
    r = _run(source, target, np.eye(4), num_threads=threads)
    assert r.converged and r.correspondences == 1500 and 1 < r.iterations < 10
    np.testing.assert_allclose(r.T_target_source, T_true, atol=1e-6)


def test_a_mounted_sensor_is_answered_in_its_own_frame():
    T_vs = _extrinsic()
    source, target, T_true = _pair(v=(0.6, 0.3, 0.0))
    r = _run(source, target, np.eye(4), T_vehicle_sensor=T_vs.tolist())
    np.testing.assert_allclose(r.T_target_source, T_true, atol=1e-5)


def test_no_pair_at_the_start_gives_the_identity():
    source, target, T_true = _pair(n=500)
    init = T_true.copy()
    init[2, 3] += 200.0
    r = _run(source, target, init)
    assert (r.correspondences, r.iterations, r.converged) == (0, 0, False)
    np.testing.assert_array_equal(r.T_target_source, np.eye(4))


@pytest.mark.parametrize("threads", [1, 2])
def test_the_pair_gate_is_the_correspondence_distance(threads):
    """Started 0.2 m off the truth, every point's true partner is within the 0.3 m gate: the
    motion is found; started 0.45 m off, none is (and no other target point is, checked by
    brute force): no pair, the identity."""
    source, target, T_true = _pair(n=500, seed=4)
    for offset, found in ((0.2, True), (0.45, False)):
        init = T_true.copy()
        init[:3, 3] += [offset, 0.0, 0.0]
        moved = source.points @ init[:3, :3].T + init[:3, 3]
        gaps = np.linalg.norm(moved[::2, None, :] - target.points[None, ::2, :], axis=2)
        assert (gaps.min() < 0.3) == found
        r = _run(source, target, init, num_threads=threads)
        if found:
            assert r.converged and r.correspondences == len(source.points[::2])
            np.testing.assert_allclose(r.T_target_source, T_true, atol=1e-6)
        else:
            assert (r.correspondences, r.iterations, r.converged) == (0, 0, False)


def test_a_singular_step_ends_the_run_at_its_start():
    """A flat scan without a Doppler term (lambda 0): every normal is the plane's, so the
    normal equations hold no rotation about it nor translation in it (exactly singular)."""
    g = np.arange(-5.0, 5.5, 1.0)
    pts = np.column_stack([np.repeat(g, len(g)), np.tile(g, len(g)), np.full(len(g)**2, -2.0)])
    scans = [Scan(t, pts, np.zeros(len(pts))) for t in (0.0, 0.1)]
    init = np.eye(4)
    init[2, 3] = 0.05
    r = _run(*scans, init, lambda_doppler=0.0, downsample=1)
    assert (r.correspondences, r.iterations, r.converged) == (len(pts), 1, False)
    np.testing.assert_array_equal(r.T_target_source, init)


def _dynamic(scan, rng, count=150, speed=5.0):
    """The scan with ``count`` points' Doppler off by ``speed`` (moving objects)."""
    dop = scan.doppler.copy()
    dop[rng.choice(len(dop), count, replace=False)] += speed
    return Scan(scan.stamp, scan.points, dop)


CASES = {
    "defaults": {},
    "no kernels": {"geometric_kernel": 0.0, "doppler_kernel": 0.0},
    "no geometric kernel": {"geometric_kernel": 0.0},
    "kernels later": {"geometric_kernel_from": 2, "doppler_kernel_from": 1,
                      "geometric_kernel": 0.05, "doppler_kernel": 0.5},
    "heavy doppler": {"lambda_doppler": 0.6, "max_correspondence_m": 0.5},
    "dynamic rejected": {"reject_dynamic": True, "reject_from": 1, "dynamic_threshold_mps": 1.5},
    "few iterations": {"max_iterations": 2},
    "two steps before the kernel": {"max_iterations": 2, "geometric_kernel_from": 5,
                                    "geometric_kernel": 0.05},
    "loose": {"convergence": 1e-2},
    "mounted": {"T_vehicle_sensor": _extrinsic().tolist(), "normal_neighbours": 8,
                "normal_radius_m": 6.0},
}


@pytest.mark.parametrize("case", list(CASES))
def test_same_steps_as_open3d(case):
    dev_dependency("open3d")
    params = CASES[case]
    source, target, T_true = _pair(v=(6.0, 0.5, 0.0), w=(0.0, 0.02, 0.3), n=2500, seed=3)
    source = _dynamic(source, np.random.default_rng(1))
    init = T_true.copy()
    init[:3, 3] += [0.08, -0.05, 0.03]
    ours = _run(source, target, init, **params)
    theirs = _run(source, target, init, backend="open3d", **params)
    assert np.abs(ours.T_target_source - theirs.T_target_source).max() < 1e-9
    assert ours.correspondences == theirs.correspondences > 100
    assert (ours.iterations, ours.converged) == (theirs.iterations, theirs.converged)
    if params.get("max_iterations") == 2:
        assert (ours.iterations, ours.converged) == (2, False)
    else:
        assert ours.converged and ours.iterations > 1


def test_open3d_normals_are_estimated_in_preprocess():
    dev_dependency("open3d")
    source, _, _ = _pair(n=600)
    ours = Dicp(normal_radius_m=7.0, normal_neighbours=9).preprocess(source)
    theirs = Dicp(backend="open3d", normal_radius_m=7.0, normal_neighbours=9).preprocess(source)
    assert theirs.tree is None
    dots = np.abs(np.einsum("ij,ij->i", ours.normals, theirs.normals))
    np.testing.assert_allclose(dots, 1.0, atol=1e-9)
    other = Dicp(backend="open3d", normal_radius_m=7.0, normal_neighbours=4).preprocess(source)
    assert np.abs(np.einsum("ij,ij->i", other.normals, theirs.normals)).min() < 0.9


def test_a_missing_open3d_is_one_error_naming_the_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "open3d", None)
    with pytest.raises(DataError) as err:
        dicp_open3d.estimate_normals_open3d(np.zeros((5, 3)), 1.0, 3)
    assert str(err.value) == (
        "dicp backend=open3d needs Open3D: pip install 'doppler-bench[open3d]' (on Debian also: "
        "apt-get install libusb-1.0-0); import failed: import of open3d halted; None in "
        "sys.modules")
    assert err.value.__suppress_context__


def test_a_zero_point_is_prepared_without_a_warning():
    import warnings

    raw = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 2.0], [3.0, 0.0, 4.0], [0.0, 5.0, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prepared = Dicp(downsample=1).preprocess(Scan(0.0, raw, np.zeros(4)))
    np.testing.assert_array_equal(prepared.directions[0], [0.0, 0.0, 0.0])


def test_three_points_have_their_planes_normal():
    raw = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]])
    normals = Dicp(downsample=1).preprocess(Scan(0.0, raw, np.zeros(3))).normals
    unit = np.cross(raw[1] - raw[0], raw[2] - raw[0])
    unit /= np.linalg.norm(unit)
    np.testing.assert_allclose(np.abs(normals @ unit), 1.0, atol=1e-9)


def test_six_points_are_enough_to_register():
    rng = np.random.default_rng(9)
    pts = rng.uniform(-3, 3, (6, 3))
    m = Dicp(downsample=1)
    a, b = (m.preprocess(Scan(t, pts, np.zeros(6))) for t in (0.0, 0.1))
    r = m.register(a, b, np.eye(4))
    assert r.correspondences == 6 and r.iterations >= 1


def test_the_period_is_the_stamps_difference():
    source, target, T_true = _pair(v=(0.6, 0.3, 0.0))
    late = [Scan(s.stamp + 50.0, s.points, s.doppler) for s in (source, target)]
    r = _run(*late, np.eye(4))
    np.testing.assert_allclose(r.T_target_source, T_true, atol=1e-5)


def test_the_open3d_backend_runs_open3d(monkeypatch):
    calls = []

    def fake(params, source, target, T_init, period_s, T_vs):
        calls.append(period_s)
        return np.eye(4), 7, 3, True

    monkeypatch.setattr(dicp_open3d, "register_open3d", fake)
    monkeypatch.setattr(dicp_open3d, "estimate_normals_open3d",
                        lambda points, radius_m, k: np.tile([0.0, 0.0, 1.0], (len(points), 1)))
    source, target, _ = _pair(n=300)
    r = _run(source, target, np.eye(4), backend="open3d")
    assert (r.correspondences, r.iterations, r.converged) == (7, 3, True)
    assert calls == [pytest.approx(0.1)]


@pytest.mark.parametrize("kernel_from", [0, 1, 3])
def test_a_singular_step_ends_open3d_as_it_ends_the_numba_backend(kernel_from):
    """Kernels of width 1e-12 weigh every residual ~0 from step ``kernel_from`` on: the system
    is singular. Both backends stop there, not converged, at the transform before that step
    with its pairs (Open3D raised a RuntimeError traceback before)."""
    dev_dependency("open3d")
    source, target, _ = _pair(v=(1.0, 0.2, 0.0), w=(0.0, 0.0, 0.3), n=300)
    params = dict(geometric_kernel=1e-12, doppler_kernel=1e-12, lambda_doppler=0.5,
                  geometric_kernel_from=kernel_from, doppler_kernel_from=kernel_from,
                  max_correspondence_m=2.0)
    ours = _run(source, target, np.eye(4), **params)
    theirs = _run(source, target, np.eye(4), backend="open3d", **params)
    assert not ours.converged and not theirs.converged
    assert ours.iterations == theirs.iterations == kernel_from + 1
    assert theirs.correspondences == ours.correspondences > 0
    np.testing.assert_allclose(theirs.T_target_source, ours.T_target_source, atol=1e-6)
    if kernel_from:
        assert not np.allclose(ours.T_target_source, np.eye(4))  # the steps before it moved
