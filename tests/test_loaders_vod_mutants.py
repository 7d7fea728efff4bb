"""loaders.vod on small View-of-Delft folders written in the dataset's layout (helpers_public.
write_vod, or pose / calibration files written here): the folder search, the pose and KITTI
calibration readers (formats, rigidity, each error message), the clip split, the frame clock
(1000 s + frame number x period), and what a sequence states (name, sensor, provenance,
warning) and returns (copies, scans)."""

import json
import warnings

import numpy as np
import pytest
from pydantic import ValidationError

from helpers_public import VOD_T_CAMERA_RADAR, write_vod
from loaders.errors import DataError
from loaders.se3 import make_T
from loaders.vod import (
    CLOCK_ORIGIN_S,
    DEFAULT_PERIOD_S,
    VodSequence,
    find_radar_root,
    frame_stamps,
    read_calib,
    read_pose_file,
    rigid,
    split_segments,
)


def rot_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0, 0, 1.0]])


def frames(n: int, step_m: float = 1.0, seed: int = 0):
    """``n`` frames of 4 points moving ``step_m`` along x each: points, doppler, poses."""
    rng = np.random.default_rng(seed)
    points = [rng.uniform(-20, 20, (4, 3)).astype(np.float32) for _ in range(n)]
    doppler = [rng.uniform(-3, 3, 4).astype(np.float32) for _ in range(n)]
    poses = np.stack([make_T(rot_z(5.0 * i), [step_m * i, 0.5 * i, 0.0]) for i in range(n)])
    return points, doppler, poses


def folder(tmp_path, n=3, first=0, step_m=1.0, seed=0, **kw):
    p, d, T = frames(n, step_m, seed)
    return write_vod(tmp_path / "vod", p, d, T, first=first, **kw), p, d, T


def quiet(root, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return VodSequence(root, **kw)


# --- the folder --------------------------------------------------------------------------------


def test_the_radar_folder_is_found_from_the_root_the_split_or_itself(tmp_path):
    root, *_ = folder(tmp_path)
    base = root / "radar" / "training"
    assert find_radar_root(root, "training") == base
    assert find_radar_root(root / "radar", "training") == base
    assert find_radar_root(base, "training") == base
    assert find_radar_root(base / "velodyne", "training") == base
    assert find_radar_root(str(root), "training") == base


def test_the_split_option_picks_the_subfolder(tmp_path):
    p, d, T = frames(2)
    root = write_vod(tmp_path / "vod", p, d, T, split="testing")
    assert find_radar_root(root, "testing") == root / "radar" / "testing"
    seq = quiet(root, split="testing")
    assert len(seq) == 2 and seq.root == root / "radar" / "testing"
    with pytest.raises(DataError) as err:
        find_radar_root(root, "training")
    assert str(err.value) == (f"{root}: no View-of-Delft radar frames; expected radar/training/"
                              "velodyne/NNNNN.bin (with pose/ and calib/ beside velodyne/)")


def test_a_missing_folder_is_named(tmp_path):
    with pytest.raises(DataError) as err:
        find_radar_root(tmp_path / "nope", "val")
    assert str(err.value) == (f"{tmp_path / 'nope'}: not found; expected the View-of-Delft "
                              "folder with radar/val/velodyne/NNNNN.bin")


def test_a_file_named_velodyne_is_not_a_frame_folder(tmp_path):
    (tmp_path / "velodyne").write_text("x")
    with pytest.raises(DataError, match="no View-of-Delft radar frames"):
        find_radar_root(tmp_path / "velodyne", "training")


def test_only_numbered_bin_files_are_frames(tmp_path):
    root, *_ = folder(tmp_path, n=3)
    velo = root / "radar" / "training" / "velodyne"
    (velo / "notes.bin").write_bytes(b"x")
    (velo / "00007.txt").write_text("x")
    (velo / "00009.bin.bak").write_bytes(b"x")
    assert len(quiet(root)) == 3
    for f in velo.glob("0000[012].bin"):
        f.unlink()
    with pytest.raises(DataError) as err:
        quiet(root)
    assert str(err.value) == f"{velo}: no NNNNN.bin radar frames"


def test_a_missing_pose_folder_is_named(tmp_path):
    root, *_ = folder(tmp_path)
    pose = root / "radar" / "training" / "pose"
    for f in pose.iterdir():
        f.unlink()
    pose.rmdir()
    with pytest.raises(DataError) as err:
        quiet(root)
    assert str(err.value) == (f"{pose}: pose folder not found; expected pose/NNNNN.json beside "
                              "velodyne/")


# --- pose files --------------------------------------------------------------------------------

T_POSE = make_T(rot_z(30.0), [1.0, -2.0, 3.0])


def pose_text(T=T_POSE, key="odomToCamera") -> str:
    return json.dumps({key: [float(v) for v in T.ravel()]})


def test_pose_file_of_lines_of_one_object_or_one_object(tmp_path):
    lines = tmp_path / "lines.json"
    other = make_T(np.eye(3), [9.0, 9.0, 9.0])
    lines.write_text(pose_text(other, "mapToCamera") + "\n\n" + pose_text() + "\n")
    np.testing.assert_allclose(read_pose_file(lines, "odomToCamera"), T_POSE, atol=1e-12)
    np.testing.assert_allclose(read_pose_file(lines, "mapToCamera"), other, atol=1e-12)
    # one pretty-printed object over several lines, a nested 4x4 list
    one = tmp_path / "one.json"
    one.write_text(json.dumps({"UTMToCamera": T_POSE.tolist(), "odomToCamera": [0] * 16},
                              indent=2))
    np.testing.assert_allclose(read_pose_file(one, "UTMToCamera"), T_POSE, atol=1e-12)


def test_a_rotation_printed_to_eight_digits_is_made_exact(tmp_path):
    path = tmp_path / "p.json"
    rounded = np.round(T_POSE, 8)
    path.write_text(json.dumps({"odomToCamera": rounded.ravel().tolist()}))
    T = read_pose_file(path, "odomToCamera")
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(T, T_POSE, atol=1e-8)


def test_pose_file_errors(tmp_path):
    path = tmp_path / "p.json"
    path.write_text("{not json")
    with pytest.raises(DataError, match=r"p\.json: not JSON \(.*\); expected lines like "
                                        r'\{"odomToCamera": \[16 numbers\]\}'):
        read_pose_file(path, "odomToCamera")
    path.write_text("[1, 2]")  # JSON, but not an object
    with pytest.raises(DataError, match=r"p\.json: not JSON"):
        read_pose_file(path, "odomToCamera")
    path.write_text(pose_text(key="mapToCamera") + "\n" + pose_text(key="UTMToCamera"))
    with pytest.raises(DataError) as err:
        read_pose_file(path, "odomToCamera")
    assert str(err.value) == (f"{path}: no 'odomToCamera' (has ['UTMToCamera', 'mapToCamera']); "
                              "expected odomToCamera, mapToCamera and UTMToCamera")
    path.write_text(json.dumps({"odomToCamera": ["a"] * 16}))
    with pytest.raises(DataError) as err:
        read_pose_file(path, "odomToCamera")
    assert str(err.value) == (f"{path}: odomToCamera holds {str(['a'] * 16)[:60]!r}; expected "
                              "16 numbers (a row-major 4x4)")
    values = T_POSE.ravel().tolist()
    values[5] = float("nan")
    path.write_text(json.dumps({"odomToCamera": values}))
    with pytest.raises(DataError) as err:
        read_pose_file(path, "odomToCamera")
    assert str(err.value) == (f"{path}: odomToCamera has 16 values; expected 16 finite numbers "
                              "(a row-major 4x4)")
    path.write_text(json.dumps({"odomToCamera": [1.0] * 17}))
    with pytest.raises(DataError, match="odomToCamera has 17 values"):
        read_pose_file(path, "odomToCamera")
    path.write_text(json.dumps({"odomToCamera": (2.0 * np.eye(4)).ravel().tolist()}))
    with pytest.raises(DataError, match=r"p\.json: odomToCamera: not a rigid transform "
                                        r"\(singular values \[2\. 2\. 2\.\]\)"):
        read_pose_file(path, "odomToCamera")
    missing = tmp_path / "none.json"
    with pytest.raises(DataError) as err:
        read_pose_file(missing, "odomToCamera")
    assert str(err.value) == (f"{missing}: cannot read the pose file (No such file or "
                              "directory); expected one per radar frame")


# --- calibration -------------------------------------------------------------------------------


def calib_text(T=VOD_T_CAMERA_RADAR, key="Tr_velo_to_cam") -> str:
    row = " ".join(f"{v:.10g}" for v in T[:3].ravel())
    return f"P2: 1 0 0 0 0 1 0 0 0 0 1 0\nTr_imu_to_velo: 1 2 3\n{key}: {row}\n"


def test_calibration_row_is_the_radar_to_camera_transform(tmp_path):
    path = tmp_path / "c.txt"
    path.write_text(calib_text())
    np.testing.assert_allclose(read_calib(path), VOD_T_CAMERA_RADAR, atol=1e-9)
    path.write_text(calib_text().replace("Tr_velo_to_cam:", "  Tr_velo_to_cam  :"))
    np.testing.assert_allclose(read_calib(path), VOD_T_CAMERA_RADAR, atol=1e-9)


def test_calibration_errors(tmp_path):
    path = tmp_path / "c.txt"
    path.write_text(calib_text(key="Tr_cam_to_velo"))
    with pytest.raises(DataError) as err:
        read_calib(path)
    assert str(err.value) == f"{path}: no Tr_velo_to_cam row; expected a KITTI calibration file"
    path.write_text("Tr_velo_to_cam: 1 0 0 0 0 1 0 0 0 0 1\n")
    with pytest.raises(DataError) as err:
        read_calib(path)
    assert str(err.value) == (f"{path}: Tr_velo_to_cam has 11 values; expected 12 (a 3x4 "
                              "row-major radar -> camera transform)")
    path.write_text("Tr_velo_to_cam: 1 0 0 0 0 1 0 0 0 0 1 x\n")
    with pytest.raises(DataError, match="Tr_velo_to_cam has 0 values; expected 12"):
        read_calib(path)
    path.write_text("Tr_velo_to_cam: 1 0 0 0 0 -1 0 0 0 0 1 0\n")  # a reflection
    with pytest.raises(DataError, match=r"c\.txt: Tr_velo_to_cam: not a rigid transform"):
        read_calib(path)
    missing = tmp_path / "none.txt"
    with pytest.raises(DataError) as err:
        read_calib(missing)
    assert str(err.value) == (f"{missing}: cannot read the calibration (No such file or "
                              "directory)")


def test_rigid_tolerates_print_rounding_only():
    T = make_T(rot_z(10.0), [1.0, 2.0, 3.0])
    near = T.copy()
    near[:3, :3] *= 1.0009  # singular values 1.0009: within 1e-3, projected
    out = rigid(near, "t")
    np.testing.assert_allclose(out, T, atol=1e-12)
    assert near[0, 0] != out[0, 0]  # a copy; the input is not changed
    far = T.copy()
    far[:3, :3] *= 1.00123  # said to four decimals
    with pytest.raises(DataError, match=r"t: not a rigid transform \(singular values "
                                        r"\[1\.0012 1\.0012 1\.0012\]\)"):
        rigid(far, "t")
    shrunk = T.copy()
    shrunk[:3, :3] *= 0.9989
    with pytest.raises(DataError, match="not a rigid transform"):
        rigid(shrunk, "t")
    bottom = T.copy()
    bottom[3] = [0, 0, 0, 2]
    with pytest.raises(DataError, match="not a rigid transform"):
        rigid(bottom, "t")
    bottom[3] = [0, 0.5, 0, 1]
    with pytest.raises(DataError, match="not a rigid transform"):
        rigid(bottom, "t")


# --- clips and clock ----------------------------------------------------------------------------


def test_split_segments_at_number_gaps_and_fast_steps():
    numbers = np.array([3, 4, 5, 7, 8, 9, 10])
    pos = np.zeros((7, 3))
    assert split_segments(numbers, pos, 0.1, 40.0) == [(0, 3), (3, 7)]
    # a step of exactly max_speed x period is allowed; a bit more ends the clip
    pos = np.zeros((4, 3))
    pos[2:, 1] = 4.0
    assert split_segments(np.arange(4), pos, 0.1, 40.0) == [(0, 4)]
    pos[3, 1] = 8.01
    assert split_segments(np.arange(4), pos, 0.1, 40.0) == [(0, 3), (3, 4)]
    # the step is a 3-D distance: 3-4-0 is 5 m
    pos = np.array([[0, 0, 0], [3.0, 0, 4.0]])
    assert split_segments(np.arange(2), pos, 0.5, 9.9) == [(0, 1), (1, 2)]
    assert split_segments(np.arange(2), pos, 0.5, 10.0) == [(0, 2)]
    # a frame number that repeats or goes back is a gap too
    assert split_segments(np.array([1, 1]), np.zeros((2, 3)), 0.1, 40.0) == [(0, 1), (1, 2)]
    assert split_segments(np.array([5]), np.zeros((1, 3)), 0.1, 40.0) == [(0, 1)]


def test_frame_stamps_are_the_frame_counter_from_1000_s():
    assert CLOCK_ORIGIN_S == 1000.0 and DEFAULT_PERIOD_S == 0.1
    np.testing.assert_allclose(frame_stamps(np.array([0, 544, 9999]), 0.1),
                               [1000.0, 1054.4, 1999.9], rtol=0, atol=1e-9)
    out = frame_stamps([2, 3], 0.25)
    assert out.dtype == np.float64
    np.testing.assert_allclose(out, [1000.5, 1000.75], rtol=0, atol=0)


def test_default_speed_limit_splits_a_41_m_per_s_step_not_a_39(tmp_path):
    p, d, _ = frames(4)
    poses = np.stack([make_T(np.eye(3), [x, 0, 0]) for x in (0.0, 3.9, 7.8, 11.9)])
    root = write_vod(tmp_path / "vod", p, d, poses)
    with pytest.raises(DataError, match="00002 -> 00003"):
        quiet(root)
    assert len(quiet(root, max_speed_mps=42.0)) == 4
    assert len(quiet(root, segment=0)) == 3
    # a longer period allows a longer step
    assert len(quiet(root, period=0.2)) == 4


def clips_of_one_frame(root, count):
    p, d, T = frames(1)
    for first in range(0, 2 * count, 2):
        write_vod(root, p, d, T, first=first)
    return root


def test_missing_and_many_segments_are_listed(tmp_path):
    root = clips_of_one_frame(tmp_path / "vod", 9)
    velo = root / "radar" / "training" / "velodyne"
    with pytest.raises(DataError) as err:
        quiet(root)
    shown = "; ".join(f"{k}: frames {2 * k:05d}-{2 * k:05d} (1)" for k in range(8))
    assert str(err.value) == (
        f"{velo}: the frames form 9 clips separated by gaps (first gap: frame 00000 -> "
        "00002); a sequence must not jump across a gap: choose one with segment=K (--segment "
        f"K): {shown}; ...")
    last = quiet(root, segment=8)
    assert last.provenance["frames"] == ["00016", "00016"] and last.provenance["segment"] == 8
    assert last.provenance["segments_in_folder"] == 9
    with pytest.raises(DataError) as err:
        quiet(root, segment=9)
    assert str(err.value) == (f"{velo}: segment 9 does not exist; the folder has 9 clip(s): "
                              f"{shown}")


def test_eight_clips_are_all_listed_without_an_ellipsis(tmp_path):
    root = clips_of_one_frame(tmp_path / "vod", 8)
    with pytest.raises(DataError) as err:
        quiet(root)
    shown = "; ".join(f"{k}: frames {2 * k:05d}-{2 * k:05d} (1)" for k in range(8))
    assert str(err.value).endswith(f"(--segment K): {shown}")
    root2 = clips_of_one_frame(tmp_path / "vod2", 2)
    with pytest.raises(DataError) as err:
        quiet(root2)
    assert str(err.value).endswith("(--segment K): 0: frames 00000-00000 (1); 1: frames "
                                   "00002-00002 (1)")


def test_segment_option_on_a_one_clip_folder(tmp_path):
    root, *_ = folder(tmp_path, n=3, first=5)
    velo = root / "radar" / "training" / "velodyne"
    assert len(quiet(root, segment=0)) == 3
    with pytest.raises(DataError) as err:
        quiet(root, segment=1)
    assert str(err.value) == (f"{velo}: segment 1 does not exist; the folder has 1 clip(s): "
                              "0: frames 00005-00007 (3)")


def test_a_second_calibration_that_differs_is_named(tmp_path):
    root, *_ = folder(tmp_path, n=3)
    calib = root / "radar" / "training" / "calib"
    T = VOD_T_CAMERA_RADAR.copy()
    T[0, 3] += 1e-5
    (calib / "00001.txt").write_text(calib_text(T))
    with pytest.raises(DataError) as err:
        quiet(root)
    assert str(err.value) == (f"{calib / '00001.txt'}: Tr_velo_to_cam differs from frame "
                              "00000's; expected one radar calibration per clip")
    # 0.05 m + 9e-7: within 1e-6 + 1e-5 x 0.05 (np.allclose's atol and rtol): the same one
    T[0, 3] = VOD_T_CAMERA_RADAR[0, 3] + 9e-7
    (calib / "00001.txt").write_text(calib_text(T))
    assert len(quiet(root)) == 3


def test_options_defaults_and_limits():
    o = VodSequence.Options()
    assert (o.period, o.segment, o.split, o.world, o.doppler, o.max_speed_mps, o.name) == (
        0.1, None, "training", "odom", "v_r", 40.0, None)
    for bad in ({"period": 0.0}, {"segment": -1}, {"world": "gps"}, {"doppler": "v"},
                {"max_speed_mps": 0.0}, {"period": float("inf")}):
        with pytest.raises(ValidationError):
            VodSequence.Options(**bad)
    assert VodSequence.Options(segment=0).segment == 0
    assert "1000 s + NNNNN x period" in VodSequence.Options.model_fields["period"].description


# --- the sequence ----------------------------------------------------------------------------


def test_what_a_sequence_states(tmp_path):
    root, p, d, T = folder(tmp_path, n=3, first=42)
    velo = root / "radar" / "training" / "velodyne"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        seq = VodSequence(root)
    said = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert said == [f"{velo}: View-of-Delft publishes no frame stamps: frames 00042-00044 "
                    "stamped 1000 s + frame number x 0.1 s (1004.2-1004.4 s; option period)"]
    assert seq.name == "vod_00042-00044"
    assert quiet(root, name="clip").name == "clip"
    s = seq.sensor
    assert (s.kind, s.period_s, s.model, s.doppler_kind) == (
        "radar", 0.1, "radar-sparse (ZF FRGen21, VoD)", "radial")
    np.testing.assert_allclose(s.T_body_sensor, VOD_T_CAMERA_RADAR, atol=1e-9)
    prov = seq.provenance
    assert prov == {
        "loader": "vod",
        "root": str(root / "radar" / "training"),
        "segment": 0,
        "segments_in_folder": 1,
        "frames": ["00042", "00044"],
        "stamp_source": "1000 s + frame number x period 0.1 s (VoD publishes no frame stamps: "
                        "a frame counter, not a time of day; option period)",
        "clock_origin_s": 1000.0,
        "period_s": 0.1,
        "world": "odom (odomToCamera)",
        "world_frame": "odom",
        "body_frame": "camera",
        "sensor_frame": "radar",
        "T_body_sensor": "T_camera_radar from calib/NNNNN.txt Tr_velo_to_cam; GT = "
                         "T_odom_camera @ T_camera_radar",
        "doppler_column": "v_r",
        "doppler_sign": "+1 (v_r is receding-positive like the harness)",
        "nan_points_dropped": 0,
    }
    utm = quiet(root, world="utm", doppler="v_r_compensated", period=0.05)
    assert utm.provenance["world"] == "utm (UTMToCamera)"
    assert utm.provenance["T_body_sensor"].endswith("T_utm_camera @ T_camera_radar")
    assert utm.provenance["doppler_column"] == "v_r_compensated"
    assert utm.sensor.period_s == 0.05 and utm.provenance["period_s"] == 0.05
    assert utm.sensor.doppler_kind == "ego-compensated"
    assert "period 0.05 s" in utm.provenance["stamp_source"]
    shift = np.array([593000.0, 5762000.0, 0.0])  # helpers_public.UTM_FROM_ODOM
    np.testing.assert_allclose(utm.ground_truth.poses[:, :3, 3], T[:, :3, 3] + shift, atol=1e-6)


def test_stamps_and_ground_truth_are_copies(tmp_path):
    root, *_ = folder(tmp_path, n=3)
    seq = quiet(root)
    got = seq.stamps
    got[:] = -1.0
    np.testing.assert_allclose(seq.stamps, [1000.0, 1000.1, 1000.2], rtol=0, atol=1e-12)
    seq.ground_truth.stamps[:] = 0.0  # (the trajectory's own copy)
    np.testing.assert_allclose(seq.stamps, [1000.0, 1000.1, 1000.2], rtol=0, atol=1e-12)
    assert seq[2].stamp == pytest.approx(1000.2, abs=1e-12)


def test_a_scan_holds_the_written_values(tmp_path):
    p, d, T = frames(2)
    rcs = [np.array([-5.0, 0.0, 2.5, 30.0], np.float32)] * 2
    comp = [np.array([0.1, 0.2, 0.3, 0.4], np.float32)] * 2
    root = write_vod(tmp_path / "vod", p, d, T, first=7, rcs=rcs, compensated=comp)
    seq = quiet(root)
    assert len(seq) == 2
    s = seq[1]
    np.testing.assert_array_equal(s.points, p[1].astype(np.float64))
    assert s.doppler.dtype == np.float64
    np.testing.assert_array_equal(s.doppler, d[1].astype(np.float64))
    np.testing.assert_array_equal(s.fields["rcs"], rcs[1])
    assert s.stamp == pytest.approx(1000.8, abs=1e-12)
    comp_seq = quiet(root, doppler="v_r_compensated")
    np.testing.assert_allclose(comp_seq[0].doppler, comp[0], rtol=1e-7)
    np.testing.assert_allclose(seq.ground_truth.poses, T, atol=1e-6)
    np.testing.assert_allclose(seq.ground_truth.stamps, [1000.7, 1000.8], rtol=0, atol=1e-12)


def test_files_over_the_frame_limit_and_stray_names_are_named(tmp_path, monkeypatch):
    root, *_ = folder(tmp_path, n=2)
    base = root / "radar" / "training"
    monkeypatch.setenv("BENCH_MAX_FRAME_MB", "0.0001")  # 100 bytes
    pose = base / "pose" / "00000.json"
    with pytest.raises(DataError, match=f"^{pose}: the file .* above the per-frame limit"):
        read_pose_file(pose, "odomToCamera")
    calib = base / "calib" / "00000.txt"
    with pytest.raises(DataError, match=f"^{calib}: the file .* above the per-frame limit"):
        read_calib(calib)
    monkeypatch.delenv("BENCH_MAX_FRAME_MB")
    stray = base / "velodyne" / ("1" * 20 + ".bin")
    stray.write_bytes(b"")
    with pytest.raises(DataError, match=f"^{stray}: the number in the file name has 20 digits"):
        quiet(root)


def test_bytes_that_are_not_utf8_are_replaced(tmp_path):
    pose = tmp_path / "p.json"
    pose.write_bytes(pose_text().encode() + b'\n{"note": "\xff\xfe"}\n')
    np.testing.assert_allclose(read_pose_file(pose, "odomToCamera"), T_POSE, atol=1e-12)
    calib = tmp_path / "c.txt"
    calib.write_bytes(b"note: \xff\xfe\n" + calib_text().encode())
    np.testing.assert_allclose(read_calib(calib), VOD_T_CAMERA_RADAR, atol=1e-9)


def test_options_are_kept_and_dropped_points_are_named_and_counted(tmp_path):
    p, d, T = frames(2)
    p[1][2] = np.nan
    root = write_vod(tmp_path / "vod", p, d, T)
    opts = VodSequence.Options(period=0.2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = VodSequence(root, options=opts)
    assert seq.options is opts
    frame = root / "radar" / "training" / "velodyne" / "00001.bin"
    with pytest.warns(UserWarning, match=f"^{frame}, frame 1: dropped 1 of 4 points"):
        s = seq[1]
    assert len(s.points) == 3
    assert seq.provenance["nan_points_dropped"] == 1
