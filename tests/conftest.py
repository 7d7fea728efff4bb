"""Shared fixtures: a known-motion static scene with exact Doppler, and the real sample."""

from __future__ import annotations

# the numerical libraries' thread counts are pinned before NumPy loads, as on every timed path
# (bench/threads.py: importing bench pins them)
import bench  # noqa: F401  # isort: skip

import importlib
from pathlib import Path

import numpy as np
import pytest

from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import exp_se3, inv_T, transform_points
from loaders.trajectory import Trajectory

#: the vendored real radar frames (samples/README.md); frames 0-59 are the 60-frame sample
SAMPLE_STORE = Path(__file__).resolve().parents[1] / "samples" / "ntu4dradlm-loop1.h5"


def dev_dependency(module: str):
    """Import ``module``, a dev dependency (pyproject.toml's ``dev`` extra: Open3D, rerun, ...),
    or FAIL the test: a cross-check that skips when its library is missing guards nothing in
    `make test`. Never ``pytest.importorskip`` (tests/test_suite_rules.py checks)."""
    try:
        return importlib.import_module(module)
    except (ImportError, OSError) as error:  # OSError: a shared library missing (libusb)
        pytest.fail(f"{module} is not importable ({error}): it is a dev dependency, install it "
                    "with `make install-dev` (Open3D also needs libusb-1.0: `make system-deps`)",
                    pytrace=False)


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


@pytest.fixture(scope="session", autouse=True)
def _outputs_in_a_temporary_folder(tmp_path_factory):
    """Commands that write to default places relative to the working folder (results/...,
    data/...) write into a temporary folder, never into the checkout."""
    import os

    old = os.getcwd()
    os.chdir(tmp_path_factory.mktemp("cwd"))
    yield
    os.chdir(old)


@pytest.fixture(scope="session")
def ci_data_dir(tmp_path_factory) -> Path:
    """The CI suite (configs/experiments/ci.yaml), generated once per test session into a
    temporary folder (about 8 s)."""
    from loaders.synthetic import ensure_suite

    folder = tmp_path_factory.mktemp("ci-data")
    ensure_suite("synthetic-ci", folder)
    return folder


@pytest.fixture
def twist_sequence() -> MemorySequence:
    return constant_twist_sequence()


def real_sample_store() -> Path:
    """The vendored store; a missing file fails the test (it is part of the repository)."""
    assert SAMPLE_STORE.exists(), f"the vendored real sample {SAMPLE_STORE} is missing"
    return SAMPLE_STORE


@pytest.fixture(scope="session")
def sample_dir(tmp_path_factory) -> Path:
    """The real 60-frame sample in the reference code's NumPy-frame layout, as published:
    frames/frame_001.npy (float64 points) + frame_001_dop.npy and gt_tum.txt with one row per
    frame at 0.1 s steps (not the radar clock), written from the vendored store."""
    from loaders.posefile import write_tum
    from loaders.store import StoreSequence

    folder = tmp_path_factory.mktemp("ntu4dradlm-loop1-sample")
    (folder / "frames").mkdir()
    seq = StoreSequence(real_sample_store())
    try:
        for i in range(60):
            scan = seq[i]
            np.save(folder / "frames" / f"frame_{i + 1:03d}.npy", scan.points)
            np.save(folder / "frames" / f"frame_{i + 1:03d}_dop.npy", scan.doppler)
        gt = seq.ground_truth
        write_tum(Trajectory(np.arange(60) * 0.1, gt.poses[:60]), folder / "gt_tum.txt")
    finally:
        seq.close()
    return folder
