"""loaders.coloradar on small run folders in the dataset's layout (helpers_public.
write_coloradar, or its text files written here): the stamp, pose and transform readers (each
error message naming file and line), where the calibration is looked for, the run's checks
(missing indices, stamp counts, order), the GT gap default and what a sequence states and
returns."""

import numpy as np
import pytest
from pydantic import ValidationError

from helpers_public import COLORADAR_T_BASE_RADAR, write_coloradar
from loaders.coloradar import (
    NOMINAL_PERIOD_S,
    ColoradarSequence,
    find_calib,
    read_poses,
    read_stamps,
    read_transform,
)
from loaders.errors import DataError, GroundTruthWarning
from loaders.se3 import make_T


def rot_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0, 0, 1.0]])


def run_folder(tmp_path, n=4, period=0.1, gt_step=0.05, seed=0, **kw):
    rng = np.random.default_rng(seed)
    stamps = 100.0 + period * np.arange(n)
    points = [rng.uniform(-10, 10, (5, 3)).astype(np.float32) for _ in range(n)]
    doppler = [rng.uniform(-2, 2, 5).astype(np.float32) for _ in range(n)]
    gt_stamps = np.arange(stamps[0] - 0.2, stamps[-1] + 0.2 + 1e-9, gt_step)
    poses = np.stack([make_T(np.eye(3), [2.0 * (t - 100.0), 0.0, 0.0]) for t in gt_stamps])
    run = write_coloradar(tmp_path / "run0", stamps, points, doppler, gt_stamps, poses, **kw)
    return run, stamps, points, doppler


# --- readers ----------------------------------------------------------------------------------


def test_read_stamps(tmp_path):
    p = tmp_path / "timestamps.txt"
    p.write_text("1.5 extra\n\n  2.25\n3\n")
    np.testing.assert_array_equal(read_stamps(p), [1.5, 2.25, 3.0])
    assert read_stamps(p).dtype == np.float64
    p.write_text("1.0\n2.0\nabc\n")
    with pytest.raises(DataError) as err:
        read_stamps(p)
    assert str(err.value) == f"{p}, line 3: expected a stamp in seconds, got 'abc'"
    p.write_text("1.0\n\ninf\n")
    with pytest.raises(DataError, match=r"timestamps\.txt, line 3: expected a stamp in seconds, "
                                        r"got 'inf'"):
        read_stamps(p)
    p.write_text("1.0\n" + "x" * 50 + "\n")
    with pytest.raises(DataError, match="got '" + "x" * 40 + "'$"):
        read_stamps(p)
    p.write_bytes(b"1.0\n\xff\n")
    with pytest.raises(DataError, match="line 2: expected a stamp"):
        read_stamps(p)
    with pytest.raises(DataError) as err:
        read_stamps(tmp_path / "none.txt")
    assert str(err.value) == (f"{tmp_path / 'none.txt'}: timestamps file not found; expected one "
                              "stamp [s] a line")


def test_read_poses(tmp_path):
    p = tmp_path / "poses.txt"
    q = np.array([0.0, 0.0, np.sin(np.radians(15)), np.cos(np.radians(15))])
    p.write_text(f"1 2 3 {q[0]} {q[1]} {q[2]} {q[3]}\n\n4 5 6 0 0 0 1\n")
    T = read_poses(p)
    np.testing.assert_allclose(T[0], make_T(rot_z(30.0), [1, 2, 3]), atol=1e-12)
    # a quaternion of norm within 1e-3 of 1 is normalised
    p.write_text("4 5 6 0 0 0 1.0009\n")
    np.testing.assert_allclose(read_poses(p)[0], make_T(np.eye(3), [4, 5, 6]), atol=1e-12)
    p.write_text("1 2 3 0 0 0 1\n4 5 6 0 0 0 1.0011\n")
    with pytest.raises(DataError) as err:
        read_poses(p)
    assert str(err.value) == f"{p}, line 2: not a finite pose with a unit quaternion"
    p.write_text("1 2 3 0 0 0 1\n1 2 3 0 0 0 0.9989\n")
    with pytest.raises(DataError, match="line 2: not a finite pose"):
        read_poses(p)
    p.write_text("1 2 3 0 0 0 1\n1 nan 3 0 0 0 1\n")
    with pytest.raises(DataError, match="line 2: not a finite pose"):
        read_poses(p)
    p.write_text("1 2 3 0 0 0 1\n1 2 3 0 0 1\n")
    with pytest.raises(DataError) as err:
        read_poses(p)
    assert str(err.value) == (f"{p}, line 2: expected 7 numbers 'x y z qx qy qz qw', got "
                              "'1 2 3 0 0 1'")
    p.write_text("1 2 3 0 0 0 one\n")
    with pytest.raises(DataError, match="line 1: expected 7 numbers"):
        read_poses(p)
    p.write_text("\n\n")
    with pytest.raises(DataError) as err:
        read_poses(p)
    assert str(err.value) == f"{p}: no pose rows"
    with pytest.raises(DataError) as err:
        read_poses(tmp_path / "none.txt")
    assert str(err.value) == (f"{tmp_path / 'none.txt'}: ground-truth poses not found; expected "
                              "'x y z qx qy qz qw' a line")


def test_read_transform(tmp_path):
    p = tmp_path / "base_to_single_chip.txt"
    q = [0.0, 0.0, np.sin(np.radians(45)), np.cos(np.radians(45))]
    p.write_text("\n0.1 0.2 0.3\n\n" + " ".join(map(str, q)) + "\n")
    np.testing.assert_allclose(read_transform(p), make_T(rot_z(90.0), [0.1, 0.2, 0.3]),
                               atol=1e-12)
    for bad in ("0.1 0.2\n0 0 0 1\n", "0.1 0.2 0.3\n0 0 1\n", "0.1 0.2 0.3\n"):
        p.write_text(bad)
        with pytest.raises(DataError) as err:
            read_transform(p)
        assert str(err.value) == f"{p}: expected a line 'x y z' and a line 'qx qy qz qw'"
    p.write_text("0.1 0.2 x\n0 0 0 1\n")
    with pytest.raises(DataError) as err:
        read_transform(p)
    assert str(err.value) == f"{p}: expected numbers 'x y z' / 'qx qy qz qw'"
    p.write_text("0 0 0\n0 0 0 3\n")
    with pytest.raises(DataError, match=f"^{p}: .*unit"):
        read_transform(p)
    with pytest.raises(DataError, match=r"none\.txt: extrinsic not found; expected 'x y z' and "
                                        r"'qx qy qz qw' lines \(ColoRadar ships calib/ beside"):
        read_transform(tmp_path / "none.txt")


def test_find_calib_order(tmp_path):
    run = tmp_path / "runs" / "run0"
    run.mkdir(parents=True)
    assert find_calib(run, None) == run / "calib"  # (nothing found: the first place, named)
    assert find_calib(run, tmp_path / "x") == tmp_path / "x"
    assert find_calib(run, str(tmp_path / "x")) == tmp_path / "x"
    (run.parent / "calib" / "transforms").mkdir(parents=True)
    assert find_calib(run, None) == run.parent / "calib"
    (run / "calib").mkdir()  # no transforms/ inside: not taken
    assert find_calib(run, None) == run.parent / "calib"
    (run / "calib" / "transforms").mkdir()
    assert find_calib(run, None) == run / "calib"


# --- the run ----------------------------------------------------------------------------------


def test_what_a_run_states_and_reads(tmp_path):
    run, stamps, points, doppler = run_folder(tmp_path)
    opts = ColoradarSequence.Options()
    seq = ColoradarSequence(run, options=opts)
    assert seq.options is opts
    assert len(seq) == 4 and seq.name == "run0"
    assert ColoradarSequence(run, name="mine").name == "mine"
    np.testing.assert_allclose(seq.stamps, stamps, rtol=0, atol=1e-9)
    got = seq.stamps
    got[:] = 0
    assert seq.stamps[0] == pytest.approx(100.0)
    s = seq.sensor
    assert (s.kind, s.model, s.doppler_kind) == (
        "radar", "radar-sparse (TI AWR1843 single-chip, ColoRadar)", "radial")
    assert s.period_s == pytest.approx(0.1)
    np.testing.assert_allclose(s.T_body_sensor, COLORADAR_T_BASE_RADAR, atol=1e-9)
    tf = run.parent / "calib" / "transforms" / "base_to_single_chip.txt"
    p = seq.provenance
    assert (p["loader"], p["root"], p["frames_found"], p["stamp_source"],
            p["calibration_source"], p["doppler_sign"], p["nan_points_dropped"]) == (
        "coloradar", str(run), 4, str(run / "single_chip" / "pointclouds" / "timestamps.txt"),
        str(tf), 1.0, 0)
    assert p["gt"] == ("T_world_base (groundtruth_poses.txt + timestamps.txt) @ "
                       "T_base_single_chip")
    np.testing.assert_allclose(p["T_base_sensor"], COLORADAR_T_BASE_RADAR, atol=1e-9)
    # GT: the base 2 m/s along x, then the radar extrinsic; gap default 3 x 0.05 s
    expect = np.stack([make_T(np.eye(3), [2.0 * (t - 100.0), 0, 0]) @ COLORADAR_T_BASE_RADAR
                       for t in stamps])
    np.testing.assert_allclose(seq.ground_truth.poses, expect, atol=1e-6)
    assert p["gt_association"]["max_gap_s"] == pytest.approx(0.15)
    scan = seq[2]
    np.testing.assert_array_equal(scan.points, points[2].astype(np.float64))
    np.testing.assert_array_equal(scan.doppler, doppler[2].astype(np.float64))
    np.testing.assert_array_equal(scan.fields["intensity"], np.ones(5, np.float32))
    assert scan.stamp == pytest.approx(stamps[2])
    flipped = ColoradarSequence(run, doppler_sign=-1)
    np.testing.assert_array_equal(flipped[2].doppler, -doppler[2].astype(np.float64))
    assert flipped.provenance["doppler_sign"] == -1.0
    given = ColoradarSequence(run, extrinsic="0 0 0 0 0 0 1")
    assert given.provenance["calibration_source"] == "option extrinsic"
    np.testing.assert_allclose(given.sensor.T_body_sensor, np.eye(4), atol=0)


def test_one_scan_takes_the_nominal_period(tmp_path):
    run, *_ = run_folder(tmp_path, n=1)
    assert NOMINAL_PERIOD_S == 0.1
    assert ColoradarSequence(run).sensor.period_s == 0.1


def test_gap_option_offset_and_trim(tmp_path):
    run, stamps, *_ = run_folder(tmp_path, n=6, gt_step=0.05)
    gt_t = run / "groundtruth" / "timestamps.txt"
    values = read_stamps(gt_t)
    poses_file = run / "groundtruth" / "groundtruth_poses.txt"
    rows = poses_file.read_text().splitlines()
    # drop the GT rows strictly between 100.12 and 100.38 s: a 0.3 s gap
    keep = [i for i, t in enumerate(values) if not (100.12 < t < 100.38)]
    gt_t.write_text("".join(f"{values[i]:.6f}\n" for i in keep))
    poses_file.write_text("".join(rows[i] + "\n" for i in keep))
    clouds = run / "single_chip" / "pointclouds"
    with pytest.warns(GroundTruthWarning, match=(
            f"^{clouds}: 2 of the 6 scans kept have no ground truth in {poses_file} and are "
            r"excluded from scoring \(0 before, 0 after its span, 2 inside gaps > 0\.1499")):
        seq = ColoradarSequence(run)  # default: 3 median steps = 0.15 s
    assert len(seq) == 6 and len(seq.ground_truth) == 4
    assert len(ColoradarSequence(run, max_gap=0.31).ground_truth) == 6
    with pytest.raises(ValidationError):
        ColoradarSequence.Options(max_gap=0.0)
    with pytest.raises(DataError, match="not covered"):
        ColoradarSequence(run, uncovered="error")
    with pytest.warns(GroundTruthWarning, match="trimmed"):
        late = ColoradarSequence(run, time_offset=0.3, max_gap=1.0, uncovered="trim")
    # GT 0.3 s later: it starts at 100.1 s; the scan at 100.0 s is trimmed
    assert len(late) == 5 and late.stamps[0] == pytest.approx(100.1)
    assert late[0].stamp == pytest.approx(100.1)


def test_run_errors(tmp_path):
    with pytest.raises(DataError) as err:
        ColoradarSequence(tmp_path)
    assert str(err.value) == (
        f"{tmp_path}: no single_chip/pointclouds/data folder; expected a ColoRadar run with "
        "single_chip/pointclouds/data/radar_pointcloud_<i>.bin and "
        "single_chip/pointclouds/timestamps.txt")
    with pytest.raises(DataError, match="doppler_sign must be \\+1 or -1, got 0.5"):
        ColoradarSequence(tmp_path, doppler_sign=0.5)
    run, *_ = run_folder(tmp_path, n=4)
    data = run / "single_chip" / "pointclouds" / "data"
    stamps_file = data.parent / "timestamps.txt"
    (data / "radar_pointcloud_1.bin").rename(data / "radar_pointcloud_7.bin")
    with pytest.raises(DataError) as err:
        ColoradarSequence(run)
    assert str(err.value) == (
        f"{data}: radar_pointcloud_1.bin is missing (4 of indices 0..7; the highest is "
        "radar_pointcloud_7.bin); expected one file per line of timestamps.txt, indices 0..N-1")
    (data / "radar_pointcloud_7.bin").rename(data / "radar_pointcloud_4.bin")
    (data / "radar_pointcloud_1.txt").write_text("not a frame")
    with pytest.raises(DataError, match=r"radar_pointcloud_1\.bin is missing \(1 of indices "
                                        r"0\.\.4"):
        ColoradarSequence(run)
    (data / "radar_pointcloud_4.bin").rename(data / "radar_pointcloud_1.bin")
    stamps_file.write_text("100.0\n100.1\n100.2\n")
    with pytest.raises(DataError) as err:
        ColoradarSequence(run)
    assert str(err.value) == (f"{stamps_file}: 3 stamps for 4 scans in {data}; expected one "
                              "stamp per radar_pointcloud file")
    stamps_file.write_text("100.0\n100.1\n100.1\n100.3\n")
    with pytest.raises(DataError) as err:
        ColoradarSequence(run)
    assert str(err.value) == (f"{stamps_file}, line 3: stamps must increase (100.100000 -> "
                              "100.100000 s)")
    stamps_file.write_text("100.0\n100.1\n100.2\n100.3\n")
    gt_t = run / "groundtruth" / "timestamps.txt"
    gt_t.write_text("".join(gt_t.read_text().splitlines(keepends=True)[1:]))
    with pytest.raises(DataError) as err:
        ColoradarSequence(run)
    gt_dir = run / "groundtruth"
    rows = len(read_poses(gt_dir / "groundtruth_poses.txt"))
    assert str(err.value) == (f"{gt_dir / 'groundtruth_poses.txt'}: {rows} pose rows but "
                              f"{rows - 1} stamps in {gt_t}; expected one pose per stamp")
    for f in data.iterdir():
        f.unlink()
    with pytest.raises(DataError) as err:
        ColoradarSequence(run)
    assert str(err.value) == f"{data}: no radar_pointcloud_<i>.bin files"


# --- survivors of the second mutation run ----------------------------------------------------


def test_read_poses_rows_after_a_blank_line_long_lines_and_qx(tmp_path):
    p = tmp_path / "poses.txt"
    h = np.sqrt(0.5)
    p.write_text(f"1 2 3 {h} 0 0 {h}\n\n4 5 6 0 0 0 1\n")  # 90 deg about x
    T = read_poses(p)
    assert len(T) == 2
    np.testing.assert_allclose(T[0][:3, :3] @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(T[1], make_T(np.eye(3), [4, 5, 6]), atol=1e-12)
    # qx carries the norm too: (0.6, 0, 0, 0.6) has norm 0.85, not a unit quaternion
    p.write_text("1 2 3 0.6 0 0 0.6\n")
    with pytest.raises(DataError, match="line 1: not a finite pose with a unit quaternion"):
        read_poses(p)
    p.write_text("1 2 3 0 0 0 1 " + "9" * 70 + "\n")  # eight values, the line cut at 60
    with pytest.raises(DataError) as err:
        read_poses(p)
    assert str(err.value).endswith("got '1 2 3 0 0 0 1 " + "9" * 46 + "'")


def test_readers_replace_bytes_that_are_not_utf8(tmp_path):
    p = tmp_path / "poses.txt"
    p.write_bytes(b"1 2 3 0 0 0 1\n\xff\xfe\n")
    with pytest.raises(DataError, match="line 2: expected 7 numbers 'x y z qx qy qz qw', got "
                                        "'\ufffd\ufffd'"):
        read_poses(p)
    t = tmp_path / "base_to_single_chip.txt"
    t.write_bytes(b"0.1 0.2 0.3\n0 0 0 1\n# \xff\n")
    np.testing.assert_allclose(read_transform(t), make_T(np.eye(3), [0.1, 0.2, 0.3]))


def test_files_over_the_frame_limit_are_named(tmp_path, monkeypatch):
    for name, read in (("stamps.txt", read_stamps), ("poses.txt", read_poses),
                       ("transform.txt", read_transform)):
        p = tmp_path / name
        p.write_text("0 0 0 0 0 0 1\n" * 20)
        monkeypatch.setenv("BENCH_MAX_FRAME_MB", "0.0001")  # 100 bytes
        with pytest.raises(DataError, match=f"^{p}: the file .* above the per-frame limit"):
            read(p)
        monkeypatch.delenv("BENCH_MAX_FRAME_MB")


def test_a_missing_transform_says_how_to_give_one(tmp_path):
    with pytest.raises(DataError) as err:
        read_transform(tmp_path / "none.txt")
    assert str(err.value) == (
        f"{tmp_path / 'none.txt'}: extrinsic not found; expected 'x y z' and 'qx qy qz qw' lines "
        "(ColoRadar ships calib/ beside the run folders: give --calib DIR, or --extrinsic "
        "'x y z qx qy qz qw' (radar -> base; '0 0 0 0 0 0 1' when the GT is the radar's own "
        "pose))")


def test_one_gt_row_sets_no_gap_and_stray_names_are_named(tmp_path):
    run, stamps, *_ = run_folder(tmp_path, n=1)
    gt = run / "groundtruth"
    (gt / "timestamps.txt").write_text(f"{stamps[0]:.6f}\n")
    (gt / "groundtruth_poses.txt").write_text("0 0 0 0 0 0 1\n")
    seq = ColoradarSequence(run)
    assert seq.provenance["gt_association"]["max_gap_s"] is None
    assert len(seq.ground_truth) == 1
    stray = run / "single_chip" / "pointclouds" / "data" / ("radar_pointcloud_" + "1" * 20
                                                           + ".bin")
    stray.write_bytes(b"")
    with pytest.raises(DataError, match=f"^{stray}: the number in the file name has 20 digits"):
        ColoradarSequence(run)


def test_calib_and_extrinsic_options_and_a_frame_named_in_scan_errors(tmp_path):
    run, stamps, points, doppler = run_folder(tmp_path)
    moved = tmp_path / "elsewhere" / "calib"
    moved.parent.mkdir()
    (run.parent / "calib").rename(moved)
    with pytest.raises(DataError, match="extrinsic not found"):
        ColoradarSequence(run)
    seq = ColoradarSequence(run, calib=moved)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, COLORADAR_T_BASE_RADAR, atol=1e-9)
    given = ColoradarSequence(run, extrinsic="1 2 3 0 0 0 1")
    np.testing.assert_allclose(given.sensor.T_body_sensor, make_T(np.eye(3), [1, 2, 3]))
    # a NaN point: dropped, named and counted
    data = run / "single_chip" / "pointclouds" / "data"
    rec = np.fromfile(data / "radar_pointcloud_1.bin", "<f4").reshape(-1, 5)
    rec[0, 0] = np.nan
    rec.tofile(data / "radar_pointcloud_1.bin")
    f1 = data / "radar_pointcloud_1.bin"
    with pytest.warns(UserWarning, match=f"^{f1}, frame 1: dropped 1 of 5 points"):
        assert len(seq[1].points) == 4
    assert seq.provenance["nan_points_dropped"] == 1
    # a truncated frame: the layout is named
    f2 = data / "radar_pointcloud_2.bin"
    f2.write_bytes(f2.read_bytes()[:-3])
    with pytest.raises(DataError, match=f"^{f2}, frame 2: .*ColoRadar single-chip radar N x 5"):
        seq[2]
