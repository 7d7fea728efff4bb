"""Shared fixtures: a known-motion static scene with exact Doppler, and the real sample."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loaders.scan import MemorySequence, Scan, SensorInfo, Trajectory
from loaders.se3 import exp_se3, inv_T, transform_points

SAMPLE = Path(__file__).resolve().parents[2] / "shared" / "data" / "ntu4dradlm-loop1-sample"


def exact_doppler(points_sensor: np.ndarray, v_sensor: np.ndarray) -> np.ndarray:
    """Static points: doppler = -d . v_sensor (receding positive)."""
    d = points_sensor / np.linalg.norm(points_sensor, axis=1, keepdims=True)
    return -d @ v_sensor


def constant_twist_sequence(n_frames: int = 20, n_points: int = 3000, v=(8.0, 0.0, 0.0),
                            w=(0.0, 0.0, 0.05), dt: float = 0.1, seed: int = 0,
                            noise_m: float = 0.0, max_range_m: float = 80.0) -> MemorySequence:
    """Sensor moving with a constant body twist through static random world points.

    Every scan sees the world points within ``max_range_m``, with exact Doppler; GT is the
    exact sensor pose T_world_sensor at each stamp."""
    rng = np.random.default_rng(seed)
    v, w = np.asarray(v, float), np.asarray(w, float)
    world = np.column_stack([rng.uniform(-60, 60 + n_frames * dt * np.linalg.norm(v), n_points),
                             rng.uniform(-40, 40, n_points), rng.uniform(-2, 8, n_points)])
    poses, scans = [], []
    for k in range(n_frames):
        T_ws = exp_se3(np.concatenate([v, w]) * k * dt)
        pts = transform_points(inv_T(T_ws), world)
        keep = (np.linalg.norm(pts, axis=1) < max_range_m) & (np.linalg.norm(pts, axis=1) > 1)
        p = pts[keep]
        # with a constant body twist the sensor-frame linear velocity is v
        dop = exact_doppler(p, v)
        if noise_m:
            p = p + rng.normal(0, noise_m, p.shape)
        poses.append(T_ws)
        scans.append(Scan(k * dt, p, dop, {"power": rng.random(len(p))}))
    gt = Trajectory(np.arange(n_frames) * dt, np.array(poses))
    return MemorySequence("twist", SensorInfo("lidar", dt, model="test"), scans, gt, {"test": 1})


@pytest.fixture
def twist_sequence() -> MemorySequence:
    return constant_twist_sequence()


@pytest.fixture(scope="session")
def sample_dir() -> Path:
    if not SAMPLE.exists():
        pytest.skip(f"real sample not found at {SAMPLE}")
    return SAMPLE
