"""KISS-ICP wrapper: known motion over a short sequence, seed / no seed, refused deskew."""

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import exp_se3, inv_T, rotation_angle_deg, transform_points
from loaders.trajectory import Trajectory
from methods.kiss import KissIcp
from methods.registry import make_method
from test_gicp import _planar_world

ROOT = Path(__file__).resolve().parents[1]  # the child imports tests/ and the code from here


def _world() -> np.ndarray:
    """Dense planes plus 80 poles (1 m boxes, 3 m tall) scattered around: structure in every
    direction, as a scan-to-map method needs."""
    rng = np.random.default_rng(7)
    poles = []
    for cx, cy in rng.uniform([-25, -9], [45, 11], (80, 2)):
        poles.append(rng.uniform([cx, cy, -2], [cx + 1, cy + 1, 1], (400, 3)))
    return np.vstack([_planar_world(), *poles])


def _sequence(n_frames=12, twist=(8.0, 0.0, 0.0, 0.0, 0.0, 0.05), dt=0.1, times=None):
    world = _world()
    poses = [exp_se3(np.asarray(twist) * k * dt) for k in range(n_frames)]
    scans = []
    for k, T in enumerate(poses):
        fields = {} if times is None else {"time_offset_s": np.full(len(world), times)}
        scans.append(Scan(k * dt, transform_points(inv_T(T), world), fields=fields))
    return MemorySequence("planes", SensorInfo("lidar", dt), scans,
                          Trajectory(np.arange(n_frames) * dt, np.array(poses)))


def test_noise_free_sequence_is_recovered():
    seq = _sequence()
    method = make_method("kiss-icp", {}, seq.sensor)
    assert method.params.voxel_size_m is None  # kiss-icp's rule: the range used / 100
    assert method.params.range_per_voxel == 100.0
    result = method.run(seq, seed=True)
    E = inv_T(seq.ground_truth.poses[-1]) @ result.poses[-1]
    assert np.linalg.norm(E[:3, 3]) < 1e-3 and rotation_angle_deg(E[:3, :3]) < 0.05, E
    assert all(f.correspondences > 100 for f in result.frames)


def test_no_seed_resets_the_constant_velocity_prediction(monkeypatch):
    from kiss_icp.kiss_icp import KissICP

    guesses = []
    original = KissICP.register_frame

    def spy(self, frame, timestamps):
        guesses.append(self.last_delta.copy())
        return original(self, frame, timestamps)

    monkeypatch.setattr(KissICP, "register_frame", spy)
    seq = _sequence(n_frames=5)
    KissIcp().configured_for(seq.sensor).run(seq, seed=False)
    assert all(np.allclose(g, np.eye(4)) for g in guesses)
    guesses.clear()
    KissIcp().configured_for(seq.sensor).run(seq, seed=True)
    assert not np.allclose(guesses[-1], np.eye(4))


def test_constant_point_times_are_refused_not_aborted():
    # in a child process: if the check regressed, kiss-icp's abort would kill pytest itself
    code = textwrap.dedent("""
        import sys
        sys.path[:0] = ["tests", "."]
        from test_kiss import _sequence
        from methods.kiss import KissIcp
        from loaders.errors import DataError
        seq = _sequence(n_frames=3, times=0.05)
        try:
            KissIcp().configured_for(seq.sensor).run(seq, seed=True)
        except DataError as err:
            print("REFUSED", err)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "REFUSED" in out.stdout and "frame 0" in out.stdout and "deskew" in out.stdout


def test_deskew_true_without_times_is_an_error():
    seq = _sequence(n_frames=2)
    with pytest.raises(DataError, match="per-point"):
        KissIcp(deskew=True).configured_for(seq.sensor).run(seq, seed=True)


def test_poses_are_kiss_icps_own_and_only_registration_is_timed():
    # the timed wrapper around kiss-icp's registration must not change kiss-icp's answer
    from kiss_icp.kiss_icp import KissICP

    seq = _sequence(n_frames=4)
    method = KissIcp().configured_for(seq.sensor)
    result = method.run(seq, seed=True)
    from methods.kiss import data_range_m

    plain = KissICP(config=method._kiss(False, data_range_m(seq[0])).config)
    for i, scan in enumerate(seq):
        plain.register_frame(np.ascontiguousarray(scan.points), np.empty(0))
        np.testing.assert_array_equal(result.poses[i], plain.last_pose)
    times = [f.time_ms for f in result.frames[1:]]
    assert all(np.isfinite(t) and t > 0 for t in times)


def _later_scan_without_times():
    seq = _sequence(n_frames=3)
    rng = np.random.default_rng(0)
    scans = [Scan(s.stamp, s.points, fields={"time_offset_s": rng.uniform(0, 0.1, len(s))})
             for s in seq]
    scans[2] = Scan(scans[2].stamp, scans[2].points)
    return MemorySequence("planes", seq.sensor, scans, seq.ground_truth)


def test_a_later_scan_without_times_is_refused_when_deskewing():
    # in a child process: handed to kiss-icp with deskew on, the scan could abort pytest
    code = textwrap.dedent("""
        import sys
        sys.path[:0] = ["tests", "."]
        from test_kiss import _later_scan_without_times
        from methods.kiss import KissIcp
        from loaders.errors import DataError
        seq = _later_scan_without_times()
        try:
            KissIcp(max_range_m=30.0).configured_for(seq.sensor).run(seq, seed=True)
        except DataError as err:
            print("REFUSED", err)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "REFUSED frame 2" in out.stdout and "lacks" in out.stdout


def test_the_range_comes_from_the_data_and_keeps_whole_scans(monkeypatch):
    """kiss-icp's crop takes the first scan's farthest point (rounded up to 10 m), not a fixed
    100 m: on the real Eagle frames a third of a scan lies beyond 100 m."""
    from kiss_icp.kiss_icp import KissICP

    from conftest import real_sample_store
    from loaders.store import StoreSequence
    from methods.kiss import data_range_m

    seq = StoreSequence(real_sample_store())
    first = seq[0]
    far = np.linalg.norm(first.points, axis=1).max()
    assert (np.linalg.norm(first.points, axis=1) > 100).mean() > 0.2  # what 100 m dropped
    assert far < data_range_m(first) <= far + 10 and data_range_m(first) % 10 == 0
    seen, voxels = [], []
    original = KissICP.__init__

    def spy(self, config):
        seen.append(config.data.max_range)
        voxels.append(config.mapping.voxel_size)
        original(self, config)

    monkeypatch.setattr(KissICP, "__init__", spy)
    from loaders.scan import MemorySequence

    pair = MemorySequence(seq.name, seq.sensor, [seq[0], seq[1]], None)
    make_method("kiss-icp", {}, seq.sensor).run(pair, seed=True)
    assert seen == [data_range_m(first)]
    # kiss-icp's own voxel rule (its config loader: max_range / 100) at the range used
    assert voxels == [pytest.approx(data_range_m(first) / 100.0)]
    seen.clear(), voxels.clear()
    make_method("kiss-icp", {"max_range_m": 50.0}, seq.sensor).run(pair, seed=True)
    assert seen == [50.0]  # an explicit range is used as given
    assert voxels == [pytest.approx(0.5)]
    voxels.clear()
    make_method("kiss-icp", {"voxel_size_m": 1.0, "range_per_voxel": 50.0},
                seq.sensor).run(pair, seed=True)
    assert voxels == [pytest.approx(1.0)]  # an explicit voxel is used as given
