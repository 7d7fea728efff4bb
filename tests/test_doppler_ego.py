"""doppler-ego: exact on a noise-free known motion (with and without seed), what each seed
option starts from, sensor defaults, ablation switches, the repeated-detection test."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import methods.doppler_ego as doppler_ego
from conftest import constant_twist_sequence
from loaders.scan import SensorInfo
from loaders.se3 import inv_T, make_T, rotation_angle_deg, transform_points
from methods.doppler_ego import DopplerEgo, repeats_detections
from methods.registry import make_method, seed_options


def step_errors(seq, result):
    """Per-step translation [m] and rotation [deg] errors of T_prev_curr against GT."""
    gt = seq.ground_truth.poses
    est = result.poses
    trans, rot = [], []
    for k in range(1, len(gt)):
        E = inv_T(inv_T(gt[k - 1]) @ gt[k]) @ (inv_T(est[k - 1]) @ est[k])
        trans.append(np.linalg.norm(E[:3, 3]))
        rot.append(float(rotation_angle_deg(E[:3, :3])))
    return np.array(trans), np.array(rot)


@pytest.mark.parametrize("seed", [True, False])
def test_recovers_a_noise_free_known_motion(seed):
    seq = constant_twist_sequence(n_frames=12, n_points=4000, v=(8.0, 0.3, 0.1),
                                  w=(0.0, 0.01, 0.08))
    # the copies' weighting off: every point of this sequence is re-published exactly, so
    # the weighting would act on voxel-centroid shifts (its own test: test_doppler_ego_repeat)
    method = DopplerEgo(repeat_weight_power=0.0).configured_for(seq.sensor)
    result = method.run(seq, seed=seed)
    trans, rot = step_errors(seq, result)
    assert trans.max() < 1e-3 and rot.max() < 0.05
    assert np.array_equal(result.poses[0], np.eye(4))
    for f in result.frames[1:]:  # the registration alone is part of the frame's work
        assert np.isfinite(f.time_ms) and 0 < f.register_ms <= f.time_ms


@pytest.mark.parametrize("seed", [True, False])
def test_seed_option_sets_where_the_rotation_starts(seed, monkeypatch):
    """With seed: the previous step's rotation rate carried on. No seed: each frame's rotation
    starts at the previous pose's (the identity step); the Doppler translation is used in
    both (a measurement, not a prior)."""
    starts = []
    real = doppler_ego.register_to_map

    def spy(local_map, points, covs, init, *args, **kwargs):
        starts.append(init.copy())
        return real(local_map, points, covs, init, *args, **kwargs)

    monkeypatch.setattr(doppler_ego, "register_to_map", spy)
    seq = constant_twist_sequence(n_frames=6, n_points=2000, w=(0.0, 0.0, 0.2))
    result = DopplerEgo(free_vertical=False).configured_for(seq.sensor).run(seq, seed=seed)
    for i, init in enumerate(starts[1:], start=2):  # frames with a previous step
        step = inv_T(result.poses[i - 1]) @ init
        angle = float(rotation_angle_deg(step[:3, :3]))
        if seed:  # 0.2 rad/s for 0.1 s
            assert angle == pytest.approx(np.degrees(0.02), abs=0.01)
        else:
            assert angle == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("switch", ["ego_translation", "static_filter", "use_map"])
def test_each_ablation_runs_and_stays_close_on_clean_data(switch):
    seq = constant_twist_sequence(n_frames=8, n_points=3000)
    result = DopplerEgo(**{switch: False}).configured_for(seq.sensor).run(seq, seed=True)
    trans, rot = step_errors(seq, result)
    assert trans.max() < 0.05 and rot.max() < 0.2


def test_ego_translation_is_what_fixes_a_degenerate_corridor():
    """Points only on two parallel walls along x: geometry cannot see motion along the walls,
    Doppler can. Without the ego translation the registration slides."""
    rng = np.random.default_rng(4)
    base = constant_twist_sequence(n_frames=10, n_points=10, w=(0, 0, 0))  # for the GT/stamps
    from loaders.scan import MemorySequence, Scan
    from loaders.se3 import transform_points
    n = 3000
    world = np.column_stack([rng.uniform(-100, 200, n), np.where(rng.random(n) < 0.5, -6, 6.0),
                             rng.uniform(-1, 4, n)])
    scans = []
    for k, T in enumerate(base.ground_truth.poses):
        p = transform_points(inv_T(T), world)
        keep = (np.abs(p[:, 0]) < 60)
        p = p[keep]
        d = p / np.linalg.norm(p, axis=1, keepdims=True)
        scans.append(Scan(base.stamps[k], p, -d @ np.array([8.0, 0, 0])))
    seq = MemorySequence("corridor", base.sensor, scans, base.ground_truth)
    with_ego = DopplerEgo().configured_for(seq.sensor).run(seq, True)
    without = DopplerEgo(ego_translation=False).configured_for(seq.sensor).run(seq, True)
    t_with, _ = step_errors(seq, with_ego)
    t_without, _ = step_errors(seq, without)
    assert t_with.max() < 1e-3
    assert t_without.mean() > 10 * t_with.mean()


def test_sensor_defaults_and_registry():
    radar = make_method("doppler-ego", {}, SensorInfo("radar", 1 / 12))
    lidar = make_method("doppler-ego", {"voxel_m": 0.7}, SensorInfo("lidar", 0.1))
    assert radar.params.threshold_mps > lidar.params.threshold_mps
    assert radar.params.map_seconds > lidar.params.map_seconds
    assert lidar.params.voxel_m == 0.7  # an explicit value is kept
    assert seed_options("doppler-ego") == [True, False]  # constant-velocity guess, or none


def test_repeated_detections_are_told_from_independent_ones():
    """A scan made of the previous scan's points carried by the motion (plus a few fresh
    ones), as an accumulating sensor publishes them, against independent re-detections of
    the same points with 5 cm of noise."""
    rng = np.random.default_rng(7)
    prev = np.column_stack([rng.uniform(5, 60, 3000), rng.uniform(-20, 20, 3000),
                            rng.uniform(-1, 5, 3000)])
    T_prev_curr = make_T(Rotation.from_rotvec([0, 0, 0.01]).as_matrix(), [0.5, 0.0, 0.0])
    carried = transform_points(inv_T(T_prev_curr), prev)
    fresh = carried[:300] + rng.normal(0, 0.3, (300, 3))
    p = DopplerEgo().configured_for(SensorInfo("radar", 1 / 12)).params
    assert repeats_detections(prev, np.vstack([carried[300:], fresh]), np.eye(4), p)
    redetected = carried + rng.normal(0, 0.05, carried.shape)
    assert not repeats_detections(prev, redetected, np.eye(4), p)
