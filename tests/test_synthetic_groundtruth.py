"""Ground-truth pipelines of the synthetic generator (loaders/synthetic/groundtruth.py), the
Aeva scan pattern (patterns.py), the generator-code hash and the suites built from them."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.data.calibration.estimate import calibrate_sequence
from loaders.se3 import inv_T
from loaders.store import StoreSequence
from loaders.synthetic import SyntheticSequence, ensure_suite, generator_code_hash
from loaders.synthetic import groundtruth as G
from loaders.synthetic import patterns as P
from loaders.synthetic.codehash import GENERATOR_DIR
from loaders.synthetic.sensors import SENSORS
from loaders.synthetic.suite import SUITES, SuiteEntry, store_is_current, suite_entries


def _angle_deg(R: np.ndarray) -> np.ndarray:
    return np.degrees(Rotation.from_matrix(R).magnitude())


# ground-truth pipelines ------------------------------------------------------------------------

def test_nearest_sample_and_gt_clock_known_answers():
    t_gt = G.gt_clock(0.0, 1.0, 10.0, 0.03)
    np.testing.assert_allclose(np.diff(t_gt), 0.1)
    assert t_gt[0] < 0.0 and t_gt[-1] > 1.0 and np.isclose(t_gt[1] % 0.1, 0.03)
    scans = np.arange(13) / 12.0  # 12 Hz against 10 Hz, phase 0: one repeat in six scans
    idx = G.nearest_sample(np.arange(-2, 14) / 10.0, scans)
    expected_gt = np.array([0.0, 0.1, 0.2, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.7, 0.8, 0.9, 1.0])
    # scan 3 (0.25 s) ties between 0.2 and 0.3 and takes the earlier; scan 9 (0.75 s) too
    np.testing.assert_allclose((np.arange(-2, 14) / 10.0)[idx], expected_gt, atol=1e-12)


@pytest.fixture(scope="module")
def ntu_loop():
    return SyntheticSequence("loop", "radar-semidense", 60, seed=3, noise=False,
                             gt="ntu4dradlm")


def test_ntu_pipeline_samples_the_tilted_body_at_10_hz(ntu_loop):
    seq = ntu_loop
    steps = np.linalg.norm(np.diff(seq.ground_truth.poses[:, :3, 3], axis=0), axis=1)
    repeats = np.mean(steps < 1e-9)
    assert abs(repeats - 1 / 6) < 0.03  # 10 Hz GT on 12 Hz scans
    # every GT pose is the exact sensor pose at a 10 Hz clock instant within 50 ms of the stamp,
    # times the fixed T_sensor_gt
    T_sensor_gt = inv_T(G.ntu_T_gt_sensor())
    t = seq._rel
    for k in (0, 7, 31, 59):
        cands = np.arange(t[k] - 0.06, t[k] + 0.06, 1e-4)
        poses = seq.motion.sensor_pose(cands) @ T_sensor_gt
        err = np.linalg.norm(poses[:, :3, 3] - seq.ground_truth.poses[k, :3, 3], axis=1)
        j = int(np.argmin(err))
        assert err[j] < 2e-3 and abs(cands[j] - t[k]) <= 0.0501
    # consecutive distinct GT instants are 0.1 s apart: the distinct steps cover 0.1 s of travel
    speed = np.linalg.norm(seq.sensor_twist(30)[0])
    assert np.median(steps[steps > 1e-9]) == pytest.approx(0.1 * speed, rel=0.05)


def test_bench_calibrate_recovers_the_ntu_tilt(ntu_loop):
    """Cross-check with the estimator that measured the real sample (Doppler ego velocity vs
    GT velocity for pitch and yaw, road plane for roll): it finds the pipeline's angles."""
    cal = calibrate_sequence(ntu_loop)
    for name in ("roll", "pitch", "yaw"):
        assert cal.angles_deg[name] == pytest.approx(G.NTU_R_GT_SENSOR_DEG[name], abs=0.1), name


def test_exact_and_campus_pipelines():
    exact = SyntheticSequence("campus", "radar-sparse", 40, seed=4)
    camp = SyntheticSequence("campus", "radar-sparse", 40, seed=4, gt="campus")
    truth = exact.motion.sensor_pose(exact._rel)
    np.testing.assert_array_equal(exact.ground_truth.poses, truth)
    np.testing.assert_array_equal(camp.ground_truth.stamps, exact.ground_truth.stamps)
    d_pos = camp.ground_truth.poses[:, :3, 3] - truth[:, :3, 3]
    rms = np.sqrt(np.mean(d_pos ** 2))
    # 1 cm per axis at 50 Hz, interpolated between two samples: 0.7-1 cm
    assert 0.005 < rms < 0.012
    d_rot = _angle_deg(np.einsum("nji,njk->nik", truth[:, :3, :3],
                                 camp.ground_truth.poses[:, :3, :3]))
    assert 0.03 < np.sqrt(np.mean(d_rot ** 2)) < 0.16  # 0.08 deg per axis
    # the scans and the data are those of the exact sequence
    np.testing.assert_array_equal(camp.scan(5).points, exact.scan(5).points)
    assert camp.provenance["gt_pipeline"]["name"] == "campus"


def test_unknown_pipeline_is_refused():
    with pytest.raises(ValueError, match="ground-truth pipeline"):
        SyntheticSequence("campus", "radar-sparse", 5, seed=1, gt="kitti")


# Aeva scan pattern -----------------------------------------------------------------------------

def test_aeva_pattern_lines_and_azimuths():
    az, el, line, col = P.aeva_angles(509)
    assert len(az) == 64 * 509
    lines = np.unique(np.round(np.degrees(el), 6))
    assert len(lines) == 64
    assert lines.min() == pytest.approx(-7.8 - 1.718873) and \
        lines.max() == pytest.approx(7.5 + 1.718873)
    assert np.max(np.diff(lines)) < 0.47 and np.min(np.diff(lines)) > 0.24  # ~0.3 deg apart
    assert np.degrees(az).max() == pytest.approx(72.0) and np.degrees(az).min() == \
        pytest.approx(-72.0)
    assert P.aeva_columns(64 * 3051) == 3051 and P.aeva_columns(64 * 509) == 509
    full_az, _, _, _ = P.aeva_angles(3051)
    assert np.degrees(np.diff(np.unique(full_az))).mean() == pytest.approx(144 / 3050)


def test_aeva_firing_times_line_by_line():
    period = 0.1
    tau = P.firing_offsets("aeva-64", 64 * 509, 72.0, 9.6, period)
    _, el, line, col = P.aeva_angles(509)
    assert tau.min() == 0.0 and tau.max() < period
    # the 4 beams fire at once: same line and column, same time
    per_beam = tau.reshape(4, -1)
    assert np.all(per_beam == per_beam[0])
    # line k fires in [k, k + 1) * period / 16, its columns in order (left to right)
    np.testing.assert_array_equal(np.floor(tau * 16 / period + 1e-9), line)
    one_line = tau[(line == 3) & (np.arange(len(tau)) < 16 * 509)]
    assert np.all(np.diff(one_line) >= 0) and len(np.unique(one_line)) == \
        P.AEVA_SWEEP_GROUPS_PER_LINE


def test_aeva_lidar_scan_counts_noise_and_sweep():
    opts = {"sweep": True, "rib_spacing": 0}  # the suite's smooth tunnel
    seq = SyntheticSequence("tunnel", "lidar-aeva", 4, seed=2, **opts)
    exact = SyntheticSequence("tunnel", "lidar-aeva", 4, seed=2, noise=False, **opts)
    scan = seq.scan(2)
    # tens of thousands of points: 32,576 rays, 30 % dropout, nearly every ray hits the tube
    assert 20000 < len(scan) < 24000
    tau = scan.fields["time_offset_s"]
    assert len(np.unique(tau)) == 16 * P.AEVA_SWEEP_GROUPS_PER_LINE
    # noise-free points mapped with the pose at their own time lie on the tube or the road;
    # the noisy ones are 0.05 m off along the ray (the pattern's range noise)
    ex = exact.scan(2)
    T = exact.motion.sensor_pose(exact.stamps[2] + ex.fields["time_offset_s"])
    world = np.einsum("nij,nj->ni", T[:, :3, :3], ex.points) + T[:, :3, 3]
    tun = exact.scene_model.tunnel
    radial = np.hypot(world[:, 1] - tun.axis_y, world[:, 2] - tun.axis_z)
    assert np.all((np.abs(world[:, 2]) < 1e-6) | (np.abs(radial - tun.radius) < 1e-6))
    # at the stamp's pose instead (ignoring the sweep) most late points are off the surfaces
    at_stamp = np.einsum("ij,nj->ni", exact.ground_truth.poses[2][:3, :3], ex.points) + \
        exact.ground_truth.poses[2][:3, 3]
    late = ex.fields["time_offset_s"] > 0.05
    r_stamp = np.hypot(at_stamp[late, 1] - tun.axis_y, at_stamp[late, 2] - tun.axis_z)
    assert np.median(np.minimum(np.abs(at_stamp[late, 2]), np.abs(r_stamp - tun.radius))) > 1e-3
    # the noisy scan keeps the same rays (same dropouts): directions exact, range noise
    # 0.05 m, Doppler noise 0.03 m/s
    r_noisy, r_exact = np.linalg.norm(scan.points, axis=1), np.linalg.norm(ex.points, axis=1)
    np.testing.assert_allclose(scan.points / r_noisy[:, None], ex.points / r_exact[:, None],
                               atol=1e-12)
    assert np.std(r_noisy - r_exact) == pytest.approx(0.05, rel=0.05)
    assert np.std(scan.doppler - ex.doppler) == pytest.approx(0.03, rel=0.05)
    spec = SENSORS["lidar-aeva"]
    assert spec.sigma_range == 0.05 and spec.dropout == 0.3 and spec.lever_arm[2] == 1.69


# generator-code hash and suites ----------------------------------------------------------------

def test_a_changed_generator_file_changes_the_hash(tmp_path):
    copy = tmp_path / "synthetic"
    shutil.copytree(GENERATOR_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert generator_code_hash(copy) == generator_code_hash()
    entry = suite_entries("synthetic-paper")[0]
    before = entry.entry_hash(generator_code_hash(copy))
    target = copy / "sensors.py"
    target.write_text(target.read_text().replace("0.05", "0.051", 1))
    changed = generator_code_hash(copy)
    assert changed != generator_code_hash()
    assert entry.entry_hash(changed) != before
    # a file that is not code (the README) does not count
    (copy / "README.md").write_text("changed")
    assert generator_code_hash(copy) == changed


def test_a_new_generator_regenerates_the_stores(tmp_path, monkeypatch):
    import loaders.synthetic.suite as suite

    entry = SuiteEntry("A", "A", suite.SPARSE, "campus", "radar-sparse", 3, 1)
    monkeypatch.setitem(suite.SUITES, "tiny", [entry])
    (path,) = ensure_suite("tiny", tmp_path)
    assert store_is_current(path, entry)
    monkeypatch.setattr(suite, "current_code_hash", lambda: "another-generator")
    assert not store_is_current(path, entry)
    ensure_suite("tiny", tmp_path)
    store = StoreSequence(path)
    assert store.provenance["suite_entry_hash"] == entry.entry_hash("another-generator")
    store.close()


def test_suites_use_the_imitated_datasets_pipelines_and_say_they_are_synthetic():
    paper = {e.name: e for e in suite_entries("synthetic-paper")}
    clean = {e.name: e for e in suite_entries("synthetic-clean")}
    assert list(paper) == list(clean) and len(paper) == 11
    want = {"Campus1": "campus", "Loop1_0": "ntu4dradlm", "Loop1_4": "ntu4dradlm",
            "StraightWall": None, "Tunnel_Empty": None}
    for name, gt in want.items():
        assert paper[name].options.get("gt") == gt, name
        assert "gt" not in clean[name].options
        assert {k: v for k, v in paper[name].options.items() if k != "gt"} == \
            clean[name].options
        assert paper[name].sensor == clean[name].sensor and paper[name].seed == clean[name].seed
    assert {e.sensor for e in paper.values()} == {"radar-frgen21", "radar-eagle", "lidar-aeva"}
    seq = paper["Loop1_2"].sequence("synthetic-paper")
    prov = seq.provenance
    assert "NTU4DRadLM loop 1" in prov["imitates"]
    assert prov["notice"].startswith("synthetic data imitating") and \
        "not the paper's data" in prov["notice"]
    assert prov["gt_pipeline"]["name"] == "ntu4dradlm"
    # CI keeps the generic sensors with exact ground truth
    assert all("gt" not in e.options for e in SUITES["synthetic-ci"])
    assert {e.sensor for e in SUITES["synthetic-ci"]} <= {"radar-sparse", "radar-semidense",
                                                          "lidar-dense"}
