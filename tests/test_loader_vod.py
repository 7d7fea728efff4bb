"""Tests for loaders.vod on frames written in View-of-Delft's exact byte layout (radar N x 7
float32, pose JSON lines, KITTI calibration): points, Doppler (sign included), T_world_radar,
clips split at gaps, the store round trip, the NumPy-frame route and bad input."""

import warnings

import numpy as np
import pytest
from pydantic import ValidationError

from helpers_bags import Motion, doppler_sign_cosine, make_truth
from helpers_public import (
    MAP_FROM_ODOM,
    VOD_T_CAMERA_RADAR,
    runs_agree,
    synthetic_frames,
    write_npy_frames,
    write_vod,
)
from loaders.errors import DataError
from loaders.npy_frames import NpyFramesSequence
from loaders.store import StoreSequence, write_store
from loaders.vod import DEFAULT_PERIOD_S, VodSequence


def load(root, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return VodSequence(root, **kw)


def truth(frames=6, points=40, seed=0):
    return make_truth(Motion(), frames=frames, points=points, period=DEFAULT_PERIOD_S, seed=seed)


def test_points_doppler_and_gt_are_the_written_ones(tmp_path):
    t = truth()
    comp = [np.full(len(p), 0.25, np.float32) for p in t.points]
    root = write_vod(tmp_path / "vod", t.points, t.doppler, t.sensor_poses(), first=120,
                     compensated=comp)
    with pytest.warns(UserWarning, match="publishes no frame stamps.*0.1 s"):
        seq = VodSequence(root)
    assert len(seq) == 6 and seq.sensor.kind == "radar" and seq.sensor.doppler_kind == "radial"
    for i in range(6):
        s = seq[i]
        np.testing.assert_array_equal(s.points.astype(np.float32), t.points[i])
        np.testing.assert_array_equal(s.doppler.astype(np.float32), t.doppler[i])
        assert s.fields["rcs"][0] == pytest.approx(-10.0)
    # frame NNNNN at 1000 s + NNNNN x period: frames 00120-00125 at 1012.0-1012.5 s, to 1 ns
    np.testing.assert_allclose(seq.stamps, 1012.0 + 0.1 * np.arange(6), rtol=0, atol=1e-9)
    np.testing.assert_allclose(seq.ground_truth.stamps, seq.stamps, rtol=0, atol=0)
    np.testing.assert_allclose(seq.ground_truth.poses, t.sensor_poses(), atol=1e-9)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, VOD_T_CAMERA_RADAR, atol=1e-12)
    assert doppler_sign_cosine(seq) > 0.99  # receding positive, like the harness
    assert seq.provenance["frames"] == ["00120", "00125"]
    assert "VoD publishes no frame stamps" in seq.provenance["stamp_source"]
    assert "1000 s + frame number x period 0.1 s" in seq.provenance["stamp_source"]
    assert (seq.provenance["world_frame"], seq.provenance["body_frame"],
            seq.provenance["sensor_frame"]) == ("odom", "camera", "radar")
    # the other world frames and the compensated column
    in_map = load(root, world="map")
    np.testing.assert_allclose(in_map.ground_truth.poses, MAP_FROM_ODOM @ t.sensor_poses(),
                               atol=1e-9)
    comp_seq = load(root, doppler="v_r_compensated", period=0.05)
    assert comp_seq.sensor.doppler_kind == "ego-compensated"
    np.testing.assert_allclose(comp_seq[0].doppler, 0.25)
    np.testing.assert_allclose(comp_seq.stamps, 1006.0 + 0.05 * np.arange(6), rtol=0,
                               atol=1e-9)
    assert in_map.provenance["world_frame"] == "map"


def test_a_clip_from_frame_zero_is_not_stamped_zero_and_clips_share_one_clock(tmp_path):
    """Frames 00000-00002 and 00010-00012 (two clips of one folder): no stamp is 0 s (ROS
    reads 0 as "no time"), and the second clip's stamps continue the frame counter (10 frames
    later is 1.0 s later), not restart at its own first frame."""
    t = truth(frames=3)
    root = write_vod(tmp_path / "vod", t.points, t.doppler, t.sensor_poses())
    write_vod(tmp_path / "vod", t.points, t.doppler, t.sensor_poses(), first=10)
    first, second = load(root, segment=0), load(root, segment=1)
    np.testing.assert_allclose(first.stamps, [1000.0, 1000.1, 1000.2], rtol=0, atol=1e-9)
    np.testing.assert_allclose(second.stamps - first.stamps, 1.0, rtol=0, atol=1e-9)
    assert first.stamps.min() > 0
    with pytest.warns(UserWarning, match=r"1000 s \+ frame number x 0.1 s \(1000-1000.2 s"):
        VodSequence(root, segment=0)


def test_options_contract():
    assert VodSequence.Options().period == DEFAULT_PERIOD_S
    with pytest.raises(ValidationError):
        VodSequence.Options(perod=0.1)
    assert VodSequence.many_inputs is False and "velodyne" in VodSequence.inputs


def test_open_from_options_and_store_round_trip(tmp_path):
    t = truth()
    root = write_vod(tmp_path / "vod", t.points, t.doppler, t.sensor_poses())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = VodSequence.open([root], VodSequence.Options(name="clip0"))
    store = StoreSequence(write_store(seq, tmp_path / "vod.h5"))
    assert store.name == "clip0" and store.sensor.doppler_kind == "radial"
    assert store.provenance["loader"] == "vod"
    for i in range(len(seq)):
        np.testing.assert_array_equal(store[i].points, seq[i].points.astype(np.float32))
        np.testing.assert_array_equal(store[i].doppler, seq[i].doppler.astype(np.float32))
    np.testing.assert_allclose(store.ground_truth.poses, t.sensor_poses(), atol=1e-9)
    store.close()


def test_a_gap_ends_a_segment(tmp_path):
    a, b = truth(5, seed=1), truth(5, seed=2)
    root = write_vod(tmp_path / "vod", a.points, a.doppler, a.sensor_poses(), first=0)
    write_vod(tmp_path / "vod", b.points, b.doppler, b.sensor_poses(), first=40)
    with pytest.raises(DataError, match=r"2 clips separated by gaps \(first gap: frame 00004 "
                                        r"-> 00040\).*segment=K"):
        load(root)
    second = load(root, segment=1)
    assert second.provenance["frames"] == ["00040", "00044"] and len(second) == 5
    np.testing.assert_allclose(second.ground_truth.poses, b.sensor_poses(), atol=1e-9)
    np.testing.assert_array_equal(second[0].points.astype(np.float32), b.points[0])
    with pytest.raises(DataError, match="segment 2 does not exist"):
        load(root, segment=2)


def test_a_pose_jump_between_consecutive_numbers_ends_a_segment(tmp_path):
    t = truth(8)
    poses = t.sensor_poses().copy()
    poses[5:, 0, 3] += 300.0  # another recording's odometry frame, numbers continuous
    root = write_vod(tmp_path / "vod", t.points, t.doppler, poses)
    with pytest.raises(DataError, match="00004 -> 00005"):
        load(root)
    assert len(load(root, segment=0)) == 5 and len(load(root, segment=1)) == 3


def test_bad_input_gets_one_clear_error(tmp_path):
    t = truth(3)
    root = write_vod(tmp_path / "vod", t.points, t.doppler, t.sensor_poses())
    frames = root / "radar" / "training" / "velodyne"
    seq = load(root)
    # a truncated scan: not a whole number of 28-byte records
    (frames / "00001.bin").write_bytes((frames / "00001.bin").read_bytes()[:-5])
    with pytest.raises(DataError, match=r"00001\.bin, frame 1: \d+ bytes is not a whole "
                                        r"number of 28-byte records \(View-of-Delft radar N x 7: "
                                        r"x y z rcs v_r"):
        seq[1]
    # a LiDAR-like file: x y z intensity (no Doppler fields)
    np.zeros((5, 4), "<f4").tofile(frames / "00002.bin")
    with pytest.raises(DataError, match=r"00002\.bin, frame 2: .*no Doppler"):
        seq[2]
    # an empty scan
    (frames / "00000.bin").write_bytes(b"")
    with pytest.raises(DataError, match=r"00000\.bin, frame 0: empty file"):
        seq[0]
    # a frame without its pose file
    (root / "radar" / "training" / "pose" / "00002.json").unlink()
    with pytest.raises(DataError, match=r"pose/00002\.json: cannot read the pose file"):
        load(root)
    with pytest.raises(DataError, match="no View-of-Delft radar frames"):
        load(tmp_path)


def test_pose_and_calibration_errors(tmp_path):
    t = truth(3)
    root = write_vod(tmp_path / "vod", t.points, t.doppler, t.sensor_poses())
    base = root / "radar" / "training"
    (base / "pose" / "00001.json").write_text('{"odomToCamera": [1, 0, 0]}\n')
    with pytest.raises(DataError, match=r"00001\.json: odomToCamera has 3 values; expected 16"):
        load(root)
    write_vod(tmp_path / "vod", t.points, t.doppler, t.sensor_poses())
    calib = base / "calib" / "00002.txt"
    calib.write_text(calib.read_text().replace("Tr_velo_to_cam: 0", "Tr_velo_to_cam: 0.5"))
    with pytest.raises(DataError, match=r"00002\.txt: .*(differs|not a rigid)"):
        load(root)


def test_store_runs_agree_with_the_npy_frame_route(tmp_path):
    stamps, points, doppler, poses = synthetic_frames("campus", "radar-frgen21", frames=30)
    period = float(np.median(np.diff(stamps)))
    root = write_vod(tmp_path / "vod", points, doppler, poses, first=300)
    vod = write_store(load(root, period=period), tmp_path / "vod.h5")
    npy = write_npy_frames(tmp_path / "npy", points, doppler, stamps - stamps[0], poses)
    ref = write_store(NpyFramesSequence(npy, period_s=period), tmp_path / "npy.h5")
    found = runs_agree(vod, ref, tmp_path / "runs")
    assert found["doppler"][0].ape.trans_rmse_m < 1.0  # the runs did register
