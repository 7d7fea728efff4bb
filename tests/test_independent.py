"""The independent reference pipelines of the ICP-family baselines (bench/studies/
independent_methods.py, a plugin) and the driver's comparison table (bench/studies/
independent.py). Open3D is a dev dependency: these tests fail without it, never skip."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.studies import independent
from bench.studies import independent_methods as plugin
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import inv_T, make_T, rotation_angle_deg, transform_points
from methods import registry

ROOT = Path(__file__).resolve().parents[1]
REFERENCES = [cls.name for cls in plugin.METHODS]


@pytest.fixture
def registered(monkeypatch):
    for cls in plugin.METHODS:
        monkeypatch.setitem(registry.METHODS, cls.name, cls)


def test_plugin_registers_every_reference_through_the_environment():
    """``DOPPLER_BENCH_METHODS=bench.studies.independent_methods`` registers the five
    references (in a fresh process, as a worker loads them), each the reference of a
    baseline of the driver's table."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), registry.PLUGINS_ENV: independent.PLUGIN}
    code = ("import bench; from methods.registry import METHODS; "
            "print(' '.join(m for m in METHODS if m.startswith('ref-')))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    assert sorted(out) == sorted(REFERENCES)
    assert {b.reference for b in independent.BASELINES} == set(REFERENCES)
    assert {b.method for b in independent.BASELINES} == {
        "icp-p2plane", "gicp", "vgicp", "dicp", "doppler-icp", "kiss-icp"}
    assert all(m in registry.METHODS for b in independent.BASELINES for m in [b.method])


def test_experiments_run_ours_at_defaults_and_tune_on_the_tuning_frames_only(registered):
    """The tuning YAML sweeps every reference on store frames 0-124 only; the validation YAML
    runs on frames 125-249, ours without any parameter (their defaults) and every reference
    once, all with seed."""
    from bench.runs.experiment import load_experiment

    tuning = load_experiment(independent.TUNING)
    validation = load_experiment(independent.VALIDATION)
    assert [(s.start, s.frames) for s in tuning.sequences] == [(0, 125)]
    assert [(s.start, s.frames) for s in validation.sequences] == [(125, 125)]
    assert {m.name for m in tuning.methods} == set(REFERENCES)
    assert all(m.sweep and m.seeds == [True] for m in tuning.methods)
    assert tuning.criterion.error == "translation" and tuning.criterion.lengths_m == [8, 48]
    names = [m.name for m in validation.methods]
    assert sorted(names) == sorted({b.method for b in independent.BASELINES} | set(REFERENCES))
    for m in validation.methods:
        assert m.seeds == [True] and m.label is None and not m.sweep
        if not m.name.startswith("ref-"):
            assert m.params == {}, f"{m.name} must run at its defaults"


def _room_pair(frames: int = 3) -> tuple[MemorySequence, np.ndarray]:
    """Static structure (a floor, four walls, four pillars) seen from a sensor moving 0.8 m
    and turning 1.5 deg per 0.1 s frame, with exact radial Doppler (positive receding);
    returns the sequence and the true motion T_curr_prev of each step."""
    rng = np.random.default_rng(7)

    def plane(n, fixed_axis, value, lo, hi):
        p = rng.uniform(lo, hi, (n, 3))
        p[:, fixed_axis] = value
        return p

    parts = [plane(2500, 2, -1.5, [-30, -30, 0], [30, 30, 0]),
             plane(700, 0, 25.0, [0, -22, -1.5], [0, 22, 4]),
             plane(700, 0, -25.0, [0, -22, -1.5], [0, 22, 4]),
             plane(700, 1, 22.0, [-25, 0, -1.5], [25, 0, 4]),
             plane(700, 1, -22.0, [-25, 0, -1.5], [25, 0, 4])]
    for cx, cy in [(8, 6), (-6, 9), (10, -7), (-9, -5)]:
        a, z = rng.uniform(0, 2 * np.pi, 250), rng.uniform(-1.5, 3, 250)
        parts.append(np.c_[cx + 0.6 * np.cos(a), cy + 0.6 * np.sin(a), z])
    world = np.vstack(parts)
    period_s, yaw = 0.1, np.radians(1.5)
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    T_prev_curr = make_T(R, np.array([0.8, 0.05, 0.0]))  # the sensor's motion per frame
    scans, T_world_sensor = [], np.eye(4)
    for k in range(frames):
        pts = transform_points(inv_T(T_world_sensor), world)
        # sensor velocity in its own frame (the motion over the period): Doppler of a static
        # point = -(unit direction) . v
        v = T_prev_curr[:3, 3] / period_s
        doppler = -(pts / np.linalg.norm(pts, axis=1, keepdims=True)) @ v
        scans.append(Scan(k * period_s, pts, doppler))
        T_world_sensor = T_world_sensor @ T_prev_curr
    sensor = SensorInfo("radar", period_s, np.eye(4), "test-room")
    return MemorySequence("room", sensor, scans), inv_T(T_prev_curr)


@pytest.mark.parametrize("name", REFERENCES)
def test_each_reference_pipeline_recovers_a_known_motion(name, registered):
    """Each library's pipeline, run by the harness's driver with seed, recovers the true
    frame-to-frame motion (0.8 m, 1.5 deg) of a static scene within 2 cm and 0.05 deg per
    step (a method that does not move is 0.8 m off)."""
    seq, T_true = _room_pair()
    method = registry.make_method(name, {}, seq.sensor, True)
    result = method.run(seq, seed=True)
    for k in range(1, len(seq)):
        T_curr_prev = inv_T(result.poses[k]) @ result.poses[k - 1]
        D = inv_T(T_true) @ T_curr_prev
        assert np.linalg.norm(D[:3, 3]) < 0.02, (name, k, D[:3, 3])
        assert rotation_angle_deg(D[:3, :3]) < 0.05, (name, k)
    assert all(f.points > 100 for f in result.frames)


def test_dicp_reference_is_open3d_dicp_with_the_sequence_extrinsic(registered):
    """The DICP reference is ``methods.dicp`` on Open3D's backend (not a copy), keeps its
    class and backend when the sensor's extrinsic is resolved, and refuses the other
    backend."""
    from pydantic import ValidationError

    from methods.dicp import Dicp

    T = make_T(np.eye(3), np.array([1.0, 0.0, 0.5]))
    method = registry.make_method("ref-open3d-dicp", {}, SensorInfo("radar", 0.1, T), True)
    assert isinstance(method, Dicp) and type(method).name == "ref-open3d-dicp"
    assert method.params.backend == "open3d"
    assert np.allclose(method.T_vehicle_sensor, T)
    with pytest.raises(ValidationError):
        registry.make_method("ref-open3d-dicp", {"backend": "numba"})


def test_kiss_reference_takes_kiss_icps_default_config_and_voxel_rule(registered):
    """kiss-icp's own defaults (KISSConfig) but the ranges, and its voxel rule max_range /
    100 unless a voxel is given."""
    from kiss_icp.config import KISSConfig

    default = KISSConfig()
    config = registry.make_method("ref-kiss-icp", {"max_range_m": 200.0}).config()
    assert config.data.max_range == 200.0 and config.mapping.voxel_size == 2.0
    assert config.adaptive_threshold == default.adaptive_threshold
    assert config.data.deskew == default.data.deskew
    assert config.registration.max_num_iterations == default.registration.max_num_iterations
    assert config.mapping.max_points_per_voxel == default.mapping.max_points_per_voxel
    given = registry.make_method("ref-kiss-icp", {"voxel_size_m": 0.5}).config()
    assert given.data.max_range == 100.0 and given.mapping.voxel_size == 0.5


def _errors(rot8, trans8, rot48, trans48):
    return {8.0: (rot8, trans8), 48.0: (rot48, trans48)}


def test_comparison_table_computes_ours_over_reference_and_the_limit():
    """On hand-made errors: each ratio is ours / reference per length and error, a baseline
    passes only when all four are at most 1.15, a missing run or length is no pass, and the
    table shows each ratio (over the limit in bold) and the verdict."""
    errors = {"icp-p2plane": _errors(1.0, 0.5, 2.0, 2.0),
              "ref-open3d-p2plane": _errors(1.0, 0.5, 2.0, 1.6),       # 48 m translation 1.25x
              "gicp": _errors(0.9, 0.45, 1.9, 2.3),
              "ref-open3d-gicp": _errors(1.0, 0.5, 2.0, 2.0),          # 1.15x exactly: passes
              "vgicp": _errors(0.5, 0.5, 1.0, 1.0),
              "ref-small-gicp-vgicp": {8.0: (0.5, 0.5)},               # no 48 m segments
              "dicp": _errors(0.6, 0.6, 1.2, 3.0),
              "ref-open3d-dicp": _errors(0.5, 0.6, 1.2, 3.0),          # rotation 8 m 1.2x
              "doppler-icp": _errors(0.45, 0.5, 1.0, 2.0),             # better: at most 0.9x
              "ref-kiss-icp": _errors(1.0, 1.0, 1.0, 1.0)}             # kiss-icp: no run
    rows = {c.baseline.method: c for c in independent.compare(errors)}
    p2plane = rows["icp-p2plane"]
    assert p2plane.ratios() == pytest.approx([1.0, 1.0, 1.0, 1.25])
    assert p2plane.worst == pytest.approx(1.25) and not p2plane.passed
    assert rows["gicp"].ratio(48.0, 1) == pytest.approx(1.15) and rows["gicp"].passed
    assert rows["gicp"].ratio(8.0, 0) == pytest.approx(0.9)
    assert rows["vgicp"].ratio(48.0, 0) is None and rows["vgicp"].worst is None
    assert not rows["vgicp"].passed
    assert rows["dicp"].ratio(8.0, 0) == pytest.approx(1.2) and not rows["dicp"].passed
    assert rows["doppler-icp"].worst == pytest.approx(0.9) and rows["doppler-icp"].passed
    assert rows["kiss-icp"].ours is None and not rows["kiss-icp"].passed
    text = independent.table_markdown(list(rows.values()))
    assert "| `icp-p2plane` | `ref-open3d-p2plane` |" in text
    assert "1.00 / **1.25**" in text and "NO (worst 1.25x)" in text
    assert "yes (worst 1.15x)" in text and "no run" in text
    assert "NOT the same algorithm" in text  # doppler-icp's reference says what it is


def test_stale_choices_names_a_validation_setting_that_is_not_the_tuning_choice(
        registered, monkeypatch):
    """The driver stops when the validation YAML does not run a reference at its tuning
    choice (here: every choice as the YAML runs it, then one gate changed, one sweep with no
    finished point)."""
    from bench.report import tables_sweep
    from bench.runs.experiment import load_experiment

    entries = [m for m in load_experiment(independent.VALIDATION).methods
               if m.name.startswith("ref-")]
    choices = [tables_sweep.Choice(m.name, m.name, True, dict(m.params), 1.0, None, [])
               for m in entries]
    monkeypatch.setattr(tables_sweep, "sweep_choices", lambda _: choices)
    assert independent.stale_choices(Path("unused"), independent.VALIDATION) == []
    p2plane = next(c for c in choices if c.method == "ref-open3d-p2plane")
    gate = p2plane.point["max_correspondence_m"]
    p2plane.point["max_correspondence_m"] = gate + 1.0
    choices.append(tables_sweep.Choice("ref-kiss-icp", "ref-kiss-icp", True, None, None, None,
                                       []))
    stale = independent.stale_choices(Path("unused"), independent.VALIDATION)
    assert len(stale) == 2
    assert stale[0].startswith("ref-open3d-p2plane: ")
    assert f"runs max_correspondence_m={gate} but the tuning sweep chose " \
        f"max_correspondence_m={gate + 1.0}" in stale[0]
    assert "no point of the tuning sweep finished" in stale[1]
