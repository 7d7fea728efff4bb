"""Tests for loaders.helipr on sequences written in HeLiPR's exact byte layout (packed 25- or
29-byte Aeva records named by their ns stamp, LiDAR_GT/Aeva_gt.txt): points, the released
ego-compensated velocities declared as such, the opt-in GT reconstruction of radial velocity,
T_world_aeva, the store round trip and bad input."""

import numpy as np
import pytest
from pydantic import ValidationError

from helpers_bags import Motion, doppler_sign_cosine, make_truth
from helpers_public import write_helipr
from loaders.errors import DataError, GroundTruthWarning
from loaders.helipr import INTENSITY_AFTER_NS, HeliprSequence
from loaders.store import StoreSequence, write_store

#: one second before / after the stamp where the records gain the intensity field
BEFORE_S = INTENSITY_AFTER_NS * 1e-9 - 100.0
AFTER_S = INTENSITY_AFTER_NS * 1e-9 + 100.0


def write_sequence(root, t0=BEFORE_S, frames=6, points=60, gt_step=0.02, gt_name="Aeva_gt.txt",
                   moving=None):
    """Static scene seen by a moving Aeva; ``moving`` points get a compensated (world) radial
    velocity. Returns (root, truth, compensated velocities, expected raw radial velocities)."""
    motion = Motion(t0=t0)
    t = make_truth(motion, frames=frames, points=points, period=0.1)
    rng = np.random.default_rng(5)
    comp = []
    for p in t.points:
        c = np.zeros(len(p), np.float32)
        if moving:
            c[:moving] = rng.uniform(-5, 5, moving)
        comp.append(c)
    # raw radial velocity at each point's own time (write_helipr's offsets: 0 .. 99 ms)
    raw = []
    for ts, p, c in zip(t.stamps, t.points, comp, strict=True):
        offsets = np.linspace(0, 99_000_000, len(p)).astype(np.int32) * 1e-9
        d = p / np.linalg.norm(p, axis=1, keepdims=True)
        v = np.array([motion.sensor_velocity(ts + o) for o in offsets])
        raw.append(c - np.einsum("ij,ij->i", d, v))
    stamps_ns = np.round(t.stamps * 1e9).astype(np.int64)
    gt_t = t0 + gt_step * np.arange(int((t.stamps[-1] - t0) / gt_step) + 3)
    write_helipr(root, stamps_ns, t.points, comp, np.round(gt_t * 1e9).astype(np.int64),
                 motion.sensor_pose(gt_t), gt_name=gt_name)
    return root, t, comp, raw


def test_released_velocities_are_loaded_as_ego_compensated(tmp_path):
    root, t, comp, _ = write_sequence(tmp_path / "Roundabout01", moving=10)
    seq = HeliprSequence(root)
    assert len(seq) == 6 and seq.sensor.kind == "lidar"
    assert seq.sensor.doppler_kind == "ego-compensated"
    np.testing.assert_allclose(seq.stamps, t.stamps, atol=1e-6)
    for i in range(len(seq)):
        s = seq[i]
        np.testing.assert_array_equal(s.points.astype(np.float32), t.points[i])
        np.testing.assert_array_equal(s.doppler.astype(np.float32), comp[i])
        assert sorted(s.fields) == ["line_index", "reflectivity", "time_offset_s"]  # 25 bytes
        assert s.fields["time_offset_s"][-1] == pytest.approx(0.099, abs=1e-9)
        np.testing.assert_array_equal(s.fields["line_index"][[0, 1, 59]], [0, 1, 59])
    np.testing.assert_allclose(seq.ground_truth.poses, t.sensor_poses(), atol=2e-4)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, np.eye(4))
    assert "identity" in seq.provenance["calibration_source"]
    # the LiDAR/Aeva folder itself is accepted too
    assert len(HeliprSequence(root / "LiDAR" / "Aeva")) == 6


def test_29_byte_records_after_the_intensity_stamp_and_the_global_gt_name(tmp_path):
    root, t, comp, _ = write_sequence(tmp_path / "Bridge01", t0=AFTER_S,
                                      gt_name="global_Aeva_gt.txt")
    seq = HeliprSequence(root)
    assert "6 files of 29 bytes" in seq.provenance["record_layout"]
    s = seq[2]
    np.testing.assert_array_equal(s.points.astype(np.float32), t.points[2])
    assert s.fields["intensity"][0] == pytest.approx(7.0)
    assert seq.provenance["gt_association"]["gt_file"].endswith("global_Aeva_gt.txt")
    np.testing.assert_allclose(seq.ground_truth.poses, t.sensor_poses(), atol=2e-4)


def test_reconstruction_from_gt_is_opt_in_and_recovers_radial_velocity(tmp_path):
    root, t, comp, raw = write_sequence(tmp_path / "Town01", moving=10)
    plain = HeliprSequence(root)
    assert np.abs(plain[1].doppler[10:]).max() == 0.0  # static points read 0: compensated
    seq = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    assert seq.sensor.doppler_kind == "gt-reconstructed"
    assert "GT-assisted" in seq.provenance["doppler_reconstruction"]
    for i in range(len(seq)):
        np.testing.assert_allclose(seq[i].doppler, raw[i], atol=2e-3)
    assert doppler_sign_cosine(seq) > 0.95  # 10 of 60 points move: the plain fit is biased
    store = StoreSequence(write_store(seq, tmp_path / "rec.h5"))
    assert store.sensor.doppler_kind == "gt-reconstructed"
    np.testing.assert_allclose(store[3].doppler, raw[3], atol=2e-3)
    store.close()


def test_store_round_trip_keeps_the_doppler_kind(tmp_path):
    root, t, comp, _ = write_sequence(tmp_path / "KAIST05")
    with pytest.raises(ValidationError):
        HeliprSequence.Options(reconstruct=True)
    seq = HeliprSequence.open([root], HeliprSequence.Options(name="kaist"))
    store = StoreSequence(write_store(seq, tmp_path / "h.h5"))
    assert store.sensor.doppler_kind == "ego-compensated" and store.name == "kaist"
    for i in range(len(seq)):
        np.testing.assert_array_equal(store[i].points, t.points[i])
        np.testing.assert_array_equal(store[i].fields["time_offset_s"],
                                      seq[i].fields["time_offset_s"])
    np.testing.assert_allclose(store.ground_truth.poses, seq.ground_truth.poses, atol=1e-12)
    store.close()


def test_bad_input_gets_one_clear_error(tmp_path):
    root, t, comp, _ = write_sequence(tmp_path / "seq")
    files = sorted((root / "LiDAR" / "Aeva").iterdir())
    seq = HeliprSequence(root)
    files[1].write_bytes(files[1].read_bytes()[:-7])
    with pytest.raises(DataError, match=rf"{files[1].name}, frame 1: \d+ bytes is not a whole "
                                        r"number of 25-byte records"):
        seq[1]
    # a file with the intensity field under a stamp that says it has none
    np.zeros(3 * 29, np.uint8).tofile(files[2])  # 87 bytes: three 29-byte records
    with pytest.raises(DataError, match=r"29-byte layout \(with intensity\)"):
        seq[2]
    with pytest.raises(DataError, match="no LiDAR/Aeva folder"):
        HeliprSequence(tmp_path)


def test_gt_shorter_than_the_scans_and_gaps(tmp_path):
    root, t, comp, _ = write_sequence(tmp_path / "seq", frames=8)
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt.read_text().splitlines(keepends=True)
    gt.write_text("".join(rows[:-20]))  # GT ends 0.4 s before the last scans
    with pytest.warns(GroundTruthWarning, match="no ground truth"):
        seq = HeliprSequence(root)
    assert len(seq) == 8 and len(seq.ground_truth) < 8
    with pytest.warns(GroundTruthWarning):
        rec = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    assert len(rec) == len(rec.ground_truth) < 8  # trimmed: no radial velocity without GT
    gt.write_text("".join(rows[:35] + rows[50:]))  # a 0.32 s hole around the scans at 0.8, 0.9 s
    with pytest.raises(DataError, match="cannot be reconstructed"), \
            pytest.warns(GroundTruthWarning):
        HeliprSequence(root, reconstruct_doppler_from_gt=True)
    gt.unlink()
    assert HeliprSequence(root).ground_truth is None
    with pytest.raises(DataError, match="needs the ground truth"):
        HeliprSequence(root, reconstruct_doppler_from_gt=True)


def test_reconstruction_takes_each_point_at_its_own_time(tmp_path):
    """Accelerating at 3 m/s^2 the speed changes 0.3 m/s over a 0.1 s scan: each point's
    radial velocity uses the sensor velocity at its own time (time_offset_ns)."""
    from loaders.se3 import make_T

    t0, v0, a = BEFORE_S, 5.0, 3.0
    gt_t = t0 + 0.01 * np.arange(200)
    gt_poses = np.stack([make_T(np.eye(3), [v0 * (s - t0) + 0.5 * a * (s - t0) ** 2, 0, 0])
                         for s in gt_t])
    stamps = t0 + 0.3 + 0.1 * np.arange(5)
    rng = np.random.default_rng(2)
    points = [rng.uniform([5, -20, -2], [40, 20, 2], (80, 3)).astype(np.float32)
              for _ in stamps]
    offsets = [np.sort(rng.integers(0, 100_000_000, 80)).astype(np.int32) for _ in stamps]
    root = write_helipr(tmp_path / "accel", np.round(stamps * 1e9).astype(np.int64), points,
                        [np.zeros(80, np.float32)] * 5, np.round(gt_t * 1e9).astype(np.int64),
                        gt_poses, time_offset_ns=offsets)
    seq = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    for i in range(len(seq)):
        p = points[i].astype(np.float64)
        d = p / np.linalg.norm(p, axis=1, keepdims=True)
        speed = v0 + a * (stamps[i] - t0 + offsets[i] * 1e-9)
        np.testing.assert_allclose(seq[i].doppler, -d[:, 0] * speed, atol=1e-3)


def test_store_icp_run_agrees_with_the_npy_frame_route(tmp_path):
    from helpers_public import runs_agree, synthetic_frames, write_npy_frames
    from loaders.npy_frames import NpyFramesSequence

    stamps, points, doppler, poses = synthetic_frames("tunnel", "lidar-aeva", frames=8, seed=2)
    stamps = stamps + AFTER_S
    ns = np.round(stamps * 1e9).astype(np.int64)
    # the synthetic frames are instantaneous: per-point times 0 (icp deskews with them)
    root = write_helipr(tmp_path / "Tunnel", ns, points, doppler, ns, poses,
                        time_offset_ns=[np.zeros(len(p), np.int32) for p in points])
    store = write_store(HeliprSequence(root), tmp_path / "helipr.h5")
    npy = write_npy_frames(tmp_path / "npy", points, doppler, ns * 1e-9, poses)
    ref = write_store(NpyFramesSequence(npy, stamps_from_gt=True, kind="lidar"),
                      tmp_path / "npy.h5")
    runs_agree(store, ref, tmp_path / "runs", methods=("icp-p2plane",))


def test_the_intensity_stamp_boundary_itself(tmp_path):
    """The devkit's rule is ``stamp > 1691936557946849179``: a file stamped exactly there has
    25-byte records, one nanosecond later 29 (the other tests sit 100 s from it)."""
    from helpers_public import write_helipr as write
    from loaders.se3 import make_T

    b = INTENSITY_AFTER_NS
    stamps = np.array([b - 100_000_000, b, b + 1, b + 100_000_000], dtype=np.int64)
    rng = np.random.default_rng(2)
    pts = [rng.uniform(-20, 20, (50, 3)).astype(np.float32) for _ in stamps]
    vel = [np.zeros(50, np.float32) for _ in stamps]
    gt_ns = b - 200_000_000 + 50_000_000 * np.arange(8, dtype=np.int64)
    gt_poses = np.stack([make_T(np.eye(3), [0.1 * k, 0, 0]) for k in range(8)])
    root = write(tmp_path / "Boundary", stamps, pts, vel, gt_ns, gt_poses)
    sizes = [(root / "LiDAR" / "Aeva" / f"{t}.bin").stat().st_size for t in stamps]
    assert sizes == [50 * 25, 50 * 25, 50 * 29, 50 * 29]  # as the devkit writes them
    seq = HeliprSequence(root)
    assert "2 files of 29 bytes a point, 2 of 25" in seq.provenance["record_layout"]
    for i in range(4):
        np.testing.assert_array_equal(seq[i].points.astype(np.float32), pts[i])
