"""Tests for loaders.coloradar on runs written in ColoRadar's exact byte layout (single-chip
radar N x 5 float32, timestamps.txt, groundtruth poses + stamps, calib/transforms beside the
run): points, Doppler (sign included), T_world_radar, the store round trip, the NumPy-frame
route and bad input."""

import numpy as np
import pytest
from pydantic import ValidationError

from helpers_bags import Motion, doppler_sign_cosine, make_truth
from helpers_public import (
    COLORADAR_T_BASE_RADAR,
    runs_agree,
    synthetic_frames,
    write_coloradar,
    write_npy_frames,
)
from loaders.coloradar import ColoradarSequence
from loaders.errors import DataError
from loaders.npy_frames import NpyFramesSequence
from loaders.se3 import inv_T
from loaders.store import StoreSequence, write_store


def write_run(tmp_path, frames=8, points=40, gt_step=0.02):
    motion = Motion(T_body_sensor=COLORADAR_T_BASE_RADAR)
    t = make_truth(motion, frames=frames, points=points, period=0.1, start=0.513)
    gt_stamps = motion.t0 + gt_step * np.arange(int((t.stamps[-1] - motion.t0) / gt_step) + 3)
    intensity = [np.linspace(0, 1, len(p)).astype(np.float32) for p in t.points]
    run = write_coloradar(tmp_path / "runs" / "ec_hallways_run0", t.stamps, t.points, t.doppler,
                          gt_stamps, motion.body_pose(gt_stamps), intensity=intensity)
    return run, t


def test_points_doppler_and_gt_are_the_written_ones(tmp_path):
    run, t = write_run(tmp_path)
    seq = ColoradarSequence(run)
    assert len(seq) == 8 and seq.sensor.kind == "radar" and seq.sensor.doppler_kind == "radial"
    np.testing.assert_allclose(seq.stamps, t.stamps, atol=1e-6)
    for i in range(len(seq)):
        s = seq[i]
        np.testing.assert_array_equal(s.points.astype(np.float32), t.points[i])
        np.testing.assert_array_equal(s.doppler.astype(np.float32), t.doppler[i])
        assert s.fields["intensity"][-1] == pytest.approx(1.0)
    # GT at its own rate (50 Hz), interpolated at the scan stamps, extrinsic applied
    np.testing.assert_allclose(seq.ground_truth.stamps, seq.stamps)
    np.testing.assert_allclose(seq.ground_truth.poses, t.sensor_poses(), atol=2e-4)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, COLORADAR_T_BASE_RADAR, atol=1e-9)
    assert seq.provenance["calibration_source"].endswith("base_to_single_chip.txt")
    assert doppler_sign_cosine(seq) > 0.99
    assert doppler_sign_cosine(ColoradarSequence(run, doppler_sign=-1)) < -0.99
    # the extrinsic option replaces the calibration file
    plain = ColoradarSequence(run, extrinsic="0 0 0 0 0 0 1")
    np.testing.assert_allclose(plain.ground_truth.poses,
                               t.sensor_poses() @ inv_T(COLORADAR_T_BASE_RADAR), atol=2e-4)


def test_options_contract_and_store_round_trip(tmp_path):
    run, t = write_run(tmp_path)
    with pytest.raises(ValidationError):
        ColoradarSequence.Options(calibration="x")
    seq = ColoradarSequence.open([run], ColoradarSequence.Options(name="hall0"))
    store = StoreSequence(write_store(seq, tmp_path / "c.h5"))
    assert store.name == "hall0" and store.provenance["loader"] == "coloradar"
    assert store.sensor.doppler_kind == "radial" and sorted(store[0].fields) == ["intensity"]
    for i in range(len(seq)):
        np.testing.assert_array_equal(store[i].points, t.points[i])
        np.testing.assert_array_equal(store[i].doppler, t.doppler[i])
    np.testing.assert_allclose(store.ground_truth.poses, seq.ground_truth.poses, atol=1e-12)
    store.close()


def test_bad_input_gets_one_clear_error(tmp_path):
    run, t = write_run(tmp_path)
    data = run / "single_chip" / "pointclouds" / "data"
    seq = ColoradarSequence(run)
    (data / "radar_pointcloud_3.bin").write_bytes((data / "radar_pointcloud_3.bin")
                                                  .read_bytes()[:-3])
    with pytest.raises(DataError, match=r"radar_pointcloud_3\.bin, frame 3: \d+ bytes is not a "
                                        r"whole number of 20-byte records"):
        seq[3]
    np.zeros((6, 4), "<f4").tofile(data / "radar_pointcloud_4.bin")  # x y z intensity only
    with pytest.raises(DataError, match=r"radar_pointcloud_4\.bin.*no Doppler"):
        seq[4]
    # a pose file with fewer rows than stamps
    poses = run / "groundtruth" / "groundtruth_poses.txt"
    poses.write_text("".join(poses.read_text().splitlines(keepends=True)[:-2]))
    with pytest.raises(DataError, match=r"groundtruth_poses\.txt: \d+ pose rows but \d+ stamps"):
        ColoradarSequence(run)


def test_missing_files_are_named(tmp_path):
    run, t = write_run(tmp_path)
    stamps = run / "single_chip" / "pointclouds" / "timestamps.txt"
    stamps.write_text("".join(stamps.read_text().splitlines(keepends=True)[:-1]))
    with pytest.raises(DataError, match=r"timestamps\.txt: 7 stamps for 8 scans"):
        ColoradarSequence(run)
    run, t = write_run(tmp_path / "b")
    (run / "single_chip" / "pointclouds" / "data" / "radar_pointcloud_2.bin").unlink()
    with pytest.raises(DataError, match=r"radar_pointcloud_2\.bin is missing"):
        ColoradarSequence(run)
    run, t = write_run(tmp_path / "c")
    (run.parent / "calib" / "transforms" / "base_to_single_chip.txt").unlink()
    with pytest.raises(DataError, match=r"base_to_single_chip\.txt: extrinsic not found"):
        ColoradarSequence(run)
    with pytest.raises(DataError, match=r"no single_chip/pointclouds/data folder"):
        ColoradarSequence(tmp_path)


def test_store_runs_agree_with_the_npy_frame_route(tmp_path):
    stamps, points, doppler, poses = synthetic_frames("loop", "radar-sparse", frames=30, seed=3)
    stamps = stamps + 1600000000.0  # a Unix clock, as released
    period = float(np.median(np.diff(stamps)))
    base = poses @ inv_T(COLORADAR_T_BASE_RADAR)
    run = write_coloradar(tmp_path / "runs" / "outdoors_run0", stamps, points, doppler, stamps,
                          base)
    col = write_store(ColoradarSequence(run), tmp_path / "col.h5")
    npy = write_npy_frames(tmp_path / "npy", points, doppler, stamps, poses)
    ref = write_store(NpyFramesSequence(npy, stamps_from_gt=True), tmp_path / "npy.h5")
    a, b = StoreSequence(col), StoreSequence(ref)
    assert abs(a.sensor.period_s - period) < 1e-5
    np.testing.assert_allclose(a.stamps, b.stamps, atol=2e-6)
    np.testing.assert_allclose(a.ground_truth.poses, b.ground_truth.poses, atol=1e-5)
    a.close()
    b.close()
    runs_agree(col, ref, tmp_path / "runs_out")
