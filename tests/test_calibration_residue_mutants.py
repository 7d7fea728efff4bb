"""Residue survivors of bench.data.calibration.estimate: the radar's wider Doppler inlier band
in collect_cues (0.2 m/s against the lidar's 0.1 m/s) and road_normal's RANSAC draws (every
point can be drawn, a hypothesis whose normal points down is turned up)."""

import numpy as np

import bench.data.calibration.estimate as est
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import make_T
from loaders.trajectory import Trajectory


def _drive(kind, n=6, speed=5.0, height=1.5, off=0.15):
    """A sensor driving along its x axis at ``speed`` over a flat road ``height`` below it,
    whose Doppler is ``off`` m/s (alternating sign) away from the motion's, plus exact clutter
    above; GT along x at the same speed."""
    t = np.arange(n) * 0.1
    rng = np.random.default_rng(5)
    v = np.array([speed, 0.0, 0.0])
    scans = []
    for k in range(n):
        road = np.column_stack([rng.uniform(-20, 20, (200, 2)), np.full(200, -height)])
        clutter = rng.uniform(-1, 1, (600, 3)) * [30, 30, 1] + [0, 0, 2.5]
        p = np.concatenate([road, clutter])
        d = -(p / np.linalg.norm(p, axis=1, keepdims=True)) @ v
        d[:200] += off * np.where(np.arange(200) % 2, 1.0, -1.0)
        scans.append(Scan(t[k], p, d))
    poses = np.array([make_T(np.eye(3), [speed * s, 0, 0]) for s in t])
    return MemorySequence("m", SensorInfo(kind, 0.1), scans, Trajectory(t, poses))


def test_a_radar_keeps_doppler_residuals_of_0_15_mps_and_a_lidar_drops_them():
    # kills collect_cues 59/63/64: the road's returns are 0.15 m/s off, inside the radar's
    # 0.2 m/s band (road cue found: normal up, 1.5 m) but outside the lidar's 0.1 m/s band
    # (no road point is an inlier, the clutter has none below -0.3 m: no road cue)
    radar = est.collect_cues(_drive("radar"))
    np.testing.assert_array_equal(radar.road_frame, np.arange(6))
    np.testing.assert_allclose(radar.normals, np.tile([0, 0, 1.0], (6, 1)), atol=1e-9)
    np.testing.assert_allclose(radar.heights, np.full(6, 1.5), atol=1e-9)
    lidar = est.collect_cues(_drive("lidar"))
    assert len(lidar.road_frame) == 0
    np.testing.assert_allclose(lidar.a, np.tile([1.0, 0, 0], (6, 1)), atol=1e-6)
