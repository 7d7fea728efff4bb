"""Hostile and corrupt inputs in the public datasets' real layouts, corrupted one way at a time:
each ends in ONE clear error (file, frame, what was expected) with exit 2 and no traceback,
quickly and with bounded memory (the per-frame limit of ``loaders.limits`` is checked from file
sizes and headers before anything is read), and leaves no output behind.

The memory cases run ``bench convert`` in a child process under an address-space limit
(``RLIMIT_AS`` 1.5 GB: a regression fails with a MemoryError instead of exhausting the machine)
and read the child's own peak RSS; the huge files are sparse (``os.truncate``), so they take no
disk."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from helpers_bags import Motion, make_truth
from helpers_public import write_coloradar, write_helipr, write_vod
from helpers_snail import radar_array, stamp_name, write_snail_folder
from loaders.assemble import MAX_POINT_RANGE_M, finish_scan
from loaders.errors import DataError
from loaders.helipr import INTENSITY_AFTER_NS, RECORD_29, HeliprSequence
from loaders.limits import DEFAULT_MAX_FRAME_MB, ENV_VAR, max_frame_bytes
from loaders.posefile import read_kitti, read_tum
from loaders.se3 import make_T

ROOT = Path(__file__).resolve().parents[1]
#: the child's address-space limit and the peak RSS the refusal may take (imports: ~100 MB)
RLIMIT_MB, MAX_RSS_MB, MAX_WALL_S = 1500, 400, 60.0
_CHILD = """
import resource, sys, time
limit = {limit} * 2**20
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
sys.argv = ["bench", *{args!r}]
t0 = time.perf_counter()
try:
    from bench.cli import main
    main()
finally:
    # the peak of this process's own memory (VmHWM): ru_maxrss would keep the high-water mark
    # of the forked parent (the test runner) across exec
    hwm = [ln.split()[1] for ln in open("/proc/self/status") if ln.startswith("VmHWM:")]
    sys.stderr.write("\\nCHILD %s %.3f\\n" % (hwm[0], time.perf_counter() - t0))
"""


def bench_bounded(args: list[str], env: dict | None = None) -> tuple[int, str, float, float]:
    """(exit code, stdout + stderr, peak RSS [MB], wall [s]) of ``bench ARGS`` in a child."""
    child_env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1",
                 "OMP_NUM_THREADS": "1", "COLUMNS": "400", **(env or {})}
    proc = subprocess.run([sys.executable, "-c", _CHILD.format(limit=RLIMIT_MB, args=args)],
                          capture_output=True, text=True, env=child_env, timeout=300)
    out = proc.stdout + proc.stderr
    tail = [ln for ln in out.splitlines() if ln.startswith("CHILD ")]
    assert tail, out
    _, rss_kb, wall = tail[-1].split()
    return proc.returncode, out, int(rss_kb) / 1024, float(wall)


def assert_refused(code: int, out: str, rss_mb: float, wall_s: float, *needles: str) -> None:
    assert code == 2, out
    assert "Traceback" not in out and "MemoryError" not in out, out
    flat = " ".join(out.split())
    for needle in needles:
        assert needle in flat, (needle, out)
    assert rss_mb < MAX_RSS_MB, f"peak RSS {rss_mb:.0f} MB"
    assert wall_s < MAX_WALL_S, f"{wall_s:.1f} s"


def _frames(n=4, points=50, seed=0):
    rng = np.random.default_rng(seed)
    pts = [rng.uniform([-30, -30, -2], [30, 30, 3], (points, 3)).astype(np.float32)
           for _ in range(n)]
    return pts, [rng.uniform(-5, 5, points).astype(np.float32) for _ in range(n)]


def _poses(n):
    return np.stack([make_T(np.eye(3), [0.5 * i, 0.0, 0.0]) for i in range(n)])


def _helipr(root: Path, t0_ns: int = 1_690_000_000_000_000_000, n: int = 4, points: int = 50):
    pts, vel = _frames(n, points)
    stamps = t0_ns + 100_000_000 * np.arange(n, dtype=np.int64)
    gt = t0_ns - 50_000_000 + 50_000_000 * np.arange(2 * n + 2, dtype=np.int64)
    write_helipr(root, stamps, pts, vel, gt, _poses(len(gt)))
    return root, stamps


def _vod(root: Path, n: int = 4):
    pts, dop = _frames(n)
    return write_vod(root, pts, dop, _poses(n))


def _coloradar(run: Path, n: int = 4):
    pts, dop = _frames(n)
    t = 100.0 + 0.1 * np.arange(n)
    gt_t = 99.9 + 0.05 * np.arange(2 * n + 4)
    return write_coloradar(run, t, pts, dop, gt_t, _poses(len(gt_t)))


# -- memory on hostile sizes ---------------------------------------------------------------------

@pytest.mark.parametrize("dataset", ["helipr", "vod"])
def test_a_2gb_frame_file_is_refused_from_its_size(tmp_path, dataset):
    if dataset == "helipr":
        root, stamps = _helipr(tmp_path / "seq")
        frame = root / "LiDAR" / "Aeva" / f"{stamps[1]}.bin"
    else:
        root = _vod(tmp_path / "vod")
        frame = root / "radar" / "training" / "velodyne" / "00001.bin"
    os.truncate(frame, 2 * 2**30)  # sparse: no disk used
    out = tmp_path / "out.h5"
    res = bench_bounded(["convert", dataset, str(root), "--out", str(out)])
    assert_refused(*res, str(frame), "frame 1", "per-frame limit of 256 MB", ENV_VAR)
    assert not out.exists()


@pytest.mark.parametrize("dataset", ["helipr", "coloradar"])
def test_a_2gb_ground_truth_file_without_a_line_break_is_refused(tmp_path, dataset):
    """A text input (here the GT) of 2 GB of NUL bytes: one "line" that reading would hold
    whole; refused from its size like a frame."""
    if dataset == "helipr":
        root, _ = _helipr(tmp_path / "seq")
        gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    else:
        root = _coloradar(tmp_path / "runs" / "run0")
        gt = root / "groundtruth" / "groundtruth_poses.txt"
    gt.write_bytes(b"")
    os.truncate(gt, 2 * 2**30)
    res = bench_bounded(["convert", dataset, str(root), "--out", str(tmp_path / "o.h5")])
    assert_refused(*res, str(gt), "per-frame limit of 256 MB")


def test_the_frame_limit_is_raised_by_the_environment(tmp_path, monkeypatch):
    assert max_frame_bytes() == DEFAULT_MAX_FRAME_MB * 1_000_000
    root, stamps = _helipr(tmp_path / "seq")
    frame = root / "LiDAR" / "Aeva" / f"{stamps[1]}.bin"
    os.truncate(frame, 400 * 25 * 1000)  # 10 MB of zero records: genuine-sized
    monkeypatch.setenv(ENV_VAR, "5")
    with pytest.raises(DataError, match=r"frame 1: the file .* above the per-frame limit of 5 MB"):
        HeliprSequence(root)
    monkeypatch.setenv(ENV_VAR, "20")
    assert len(HeliprSequence(root)) == 4  # opens; the zero records are read as such
    monkeypatch.setenv(ENV_VAR, "lots")
    with pytest.raises(DataError, match="expected a number of megabytes"):
        max_frame_bytes()


def _snail_folder(tmp_path: Path) -> Path:
    truth = make_truth(Motion(), frames=3, points=20, period=0.1)
    rng = np.random.default_rng(0)
    items = [(t, radar_array("eagle", p, d, rng))
             for t, p, d in zip(truth.stamps, truth.points, truth.doppler, strict=True)]
    seq = tmp_path / "20240123" / "data5"
    write_snail_folder(seq / "eagleg7" / "enhanced", items)
    return seq, [seq / "eagleg7" / "enhanced" / f"{stamp_name(t)}.pcd" for t, _ in items]


def test_a_pcd_count_of_two_billion_is_refused_before_it_is_expanded(tmp_path):
    seq, files = _snail_folder(tmp_path)
    text = files[1].read_bytes()
    head, _, data = text.partition(b"DATA binary\n")
    lines = head.decode().splitlines()
    counts = next(ln for ln in lines if ln.startswith("COUNT")).split()
    counts[2] = "2000000000"  # on the second field
    head = "\n".join(" ".join(counts) if ln.startswith("COUNT") else ln for ln in lines)
    files[1].write_bytes(head.encode() + b"\nDATA binary\n" + data)
    out = tmp_path / "out.h5"
    res = bench_bounded(["convert", "snail-radar", str(seq), "--out", str(out)])
    assert_refused(*res, str(files[1]), "one point record of the PCD header", "per-frame limit")
    assert not out.exists()


def test_a_stray_coloradar_index_is_found_without_memory_growing(tmp_path):
    run = _coloradar(tmp_path / "runs" / "run0")
    stray = run / "single_chip" / "pointclouds" / "data" / "radar_pointcloud_20000000.bin"
    stray.write_bytes(np.zeros(5, "<f4").tobytes())
    res = bench_bounded(["convert", "coloradar", str(run), "--out", str(tmp_path / "o.h5")])
    assert_refused(*res, "radar_pointcloud_4.bin is missing", "radar_pointcloud_20000000.bin")
    assert res[3] < 10.0  # the index is checked from the names present, not range(20000001)


# -- silent wrong results ------------------------------------------------------------------------

@pytest.mark.parametrize("stamp_side", ["before", "after"])
def test_a_helipr_frame_in_the_other_record_layout_is_refused(tmp_path, stamp_side):
    """A 25-byte sequence with one frame in the 29-byte layout whose size is also a whole
    number of 25-byte records (50 points: 1450 bytes), and the reverse (58 points)."""
    t0 = (INTENSITY_AFTER_NS - 10**12 if stamp_side == "before" else INTENSITY_AFTER_NS + 10**12)
    root, stamps = _helipr(tmp_path / "seq", t0_ns=t0, points=50 if stamp_side == "before"
                           else 58)
    frame = root / "LiDAR" / "Aeva" / f"{stamps[2]}.bin"
    pts, vel = _frames(1, 50 if stamp_side == "before" else 58, seed=9)
    if stamp_side == "before":
        rec = np.zeros(50, dtype=RECORD_29)
        rec["intensity"] = 7.0
    else:
        from loaders.helipr import RECORD_25
        rec = np.zeros(58, dtype=RECORD_25)
    rec["x"], rec["y"], rec["z"] = pts[0].T
    rec["velocity"] = vel[0]
    rec["time_offset_ns"] = np.linspace(0, 99_000_000, len(rec)).astype(np.int32)
    rec["line_index"] = np.arange(len(rec)) % 64
    rec.tofile(frame)
    seq = HeliprSequence(root)
    for i in (0, 1, 3):
        assert np.abs(seq[i].points).max() < 100  # the other frames are fine
    other = "29-byte records (with intensity)" if stamp_side == "before" else \
        "25-byte records (without intensity)"
    with pytest.raises(DataError) as err:
        seq.scan(2)
    assert f"{frame}, frame 2" in str(err.value) and f"read as {other} they are plausible" \
        in str(err.value)
    out = tmp_path / "out.h5"
    res = bench_bounded(["convert", "helipr", str(root), "--out", str(out)])
    assert_refused(*res, "frame 2", "points are impossible")
    assert not out.exists()  # no partial store that could later pass as valid


def test_points_beyond_the_range_bound_are_dropped_or_refused():
    pts = np.random.default_rng(1).uniform(-50, 50, (200, 3))
    pts[5] = [3e38, 1.0, 1.0]  # one decoding error in 200: dropped like a NaN
    with pytest.warns(UserWarning, match=r"dropped 1 of 200 .*1 beyond 10,000 m"):
        scan = finish_scan(0.0, pts, np.zeros(200), {}, "f.bin, frame 0")
    assert len(scan.points) == 199
    pts[:5, 0] = 2 * MAX_POINT_RANGE_M  # 6 of 200 (3 %): a wrong layout
    with pytest.raises(DataError, match=r"f.bin, frame 0: 6 of 200 points lie beyond 10,000 m"):
        finish_scan(0.0, pts, np.zeros(200), {}, "f.bin, frame 0")


# -- tracebacks turned into one clear error ------------------------------------------------------

@pytest.mark.parametrize("dataset", ["helipr", "vod", "coloradar"])
def test_a_file_named_with_30_digits(tmp_path, dataset):
    name = "1" * 30
    if dataset == "helipr":
        root, _ = _helipr(tmp_path / "seq")
        stray = root / "LiDAR" / "Aeva" / f"{name}.bin"
    elif dataset == "vod":
        root = _vod(tmp_path / "vod")
        stray = root / "radar" / "training" / "velodyne" / f"{name}.bin"
    else:
        root = _coloradar(tmp_path / "runs" / "run0")
        stray = root / "single_chip" / "pointclouds" / "data" / f"radar_pointcloud_{name}.bin"
    stray.write_bytes(b"")
    from bench.cli import main

    code, out = _main(main, ["convert", dataset, str(root), "--out", str(tmp_path / "o.h5")])
    assert code == 2 and "Traceback" not in out, out
    assert str(stray.name) in out and "30 digits" in out, out


def _main(main, args):
    import contextlib
    import io

    err = io.StringIO()
    old = sys.argv
    sys.argv = ["bench", *args]
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err), \
                pytest.raises(SystemExit) as exit_, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            main()
    finally:
        sys.argv = old
    return exit_.value.code, err.getvalue()


def test_a_zero_quaternion_names_the_file_and_line(tmp_path):
    gt = tmp_path / "gt.txt"
    gt.write_text("# t x y z qx qy qz qw\n0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 0\n")
    with pytest.raises(DataError, match=r"gt.txt, line 3: quaternion .* has norm 0; expected a "
                                        "unit quaternion"):
        read_tum(gt)
    gt.write_text("0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0.5 0.5\n")  # norm 0.71: not a rotation
    with pytest.raises(DataError, match="line 2: .* norm 0.7071"):
        read_tum(gt)
    gt.write_text("0 0 0 0 0 0 0 1\n0.1 1 0 0 nan 0 0 1\n")
    with pytest.raises(DataError, match="line 2: non-finite"):
        read_tum(gt)
    # through a loader and the command line: exit 2, one line
    root, stamps = _helipr(tmp_path / "seq")
    gt_file = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt_file.read_text().splitlines()
    rows[2] = rows[2].rsplit(" ", 4)[0] + " 0 0 0 0"
    gt_file.write_text("\n".join(rows) + "\n")
    from bench.cli import main

    code, out = _main(main, ["convert", "helipr", str(root), "--out", str(tmp_path / "o.h5")])
    assert code == 2 and "Traceback" not in out and "Aeva_gt.txt, line 3" in out, out


def test_a_kitti_row_that_is_not_a_rotation(tmp_path):
    path = tmp_path / "poses.txt"
    path.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 1 0 1 0 0 0 0 1 0\n")
    with pytest.raises(DataError, match="poses.txt, pose row 2: not a rigid transform"):
        read_kitti(path)


def test_a_vod_pose_file_with_strings(tmp_path):
    root = _vod(tmp_path / "vod")
    pose = root / "radar" / "training" / "pose" / "00002.json"
    pose.write_text(json.dumps({"odomToCamera": ["a"] * 16}) + "\n")
    from bench.cli import main

    code, out = _main(main, ["convert", "vod", str(root), "--out", str(tmp_path / "o.h5")])
    assert code == 2 and "Traceback" not in out, out
    assert "00002.json: odomToCamera holds" in " ".join(out.split()) and "16 numbers" in out


# -- wrong exit / unclear messages ---------------------------------------------------------------

@pytest.fixture(scope="module")
def cloud_bag(tmp_path_factory):
    """A ROS1 bag with one PointCloud2 topic (Eagle layout: x y z Doppler ...) and no GT."""
    from helpers_snail import write_snail_bag

    truth = make_truth(Motion(), frames=6, points=40, period=0.1)
    rng = np.random.default_rng(0)
    items = [(t, radar_array("eagle", p, d, rng))
             for t, p, d in zip(truth.stamps, truth.points, truth.doppler, strict=True)]
    return write_snail_bag(tmp_path_factory.mktemp("bag") / "rec.bag",
                           {"/radar_enhanced_pcl2": items})


def test_rosbag_without_gt_warns_and_a_run_says_not_scored(cloud_bag, tmp_path):
    from bench.cli import main

    store = tmp_path / "rec.h5"
    code, out = _main_warnings(main, ["convert", "rosbag", str(cloud_bag), "--out", str(store)])
    assert code == 2 and "no Doppler field 'doppler'" in out and "--doppler-field" in out, out
    code, out = _main_warnings(main, ["convert", "rosbag", str(cloud_bag), "--doppler-field",
                                      "Doppler", "--out", str(store)])
    flat = " ".join(out.split())
    assert code == 0 and "rec: no ground truth found" in flat, out
    assert "scores none (give it with --gt or --gt-topic)" in flat
    code, out = _main_warnings(main, ["run", "--method", "doppler", "--data", str(store),
                                      "--out", str(tmp_path / "runs")])
    flat = " ".join(out.split())
    assert code == 0 and "1 done" in flat, out
    assert "not scored: " in flat and f"{store} has no ground truth" in flat, out


def test_inspect_on_a_bag_says_convert_it_first(cloud_bag):
    from bench.cli import main

    code, out = _main_warnings(main, ["inspect", str(cloud_bag)])
    flat = " ".join(out.split())
    assert code == 2 and "Traceback" not in out, out
    assert "a ROS1 bag, not a store: convert it first" in flat and "bench convert rosbag" in flat


def _main_warnings(main, args):
    """``_main`` with warnings shown the way the CLI shows them."""
    import contextlib
    import io

    err = io.StringIO()
    old = sys.argv
    sys.argv = ["bench", *args]
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err), \
                pytest.raises(SystemExit) as exit_, warnings.catch_warnings():
            warnings.simplefilter("always")
            main()
    finally:
        sys.argv = old
    return exit_.value.code, err.getvalue()


def test_a_calibration_with_a_zero_quaternion_names_its_file(tmp_path):
    from loaders.coloradar import ColoradarSequence

    run = _coloradar(tmp_path / "runs" / "run0")
    tf = run.parent / "calib" / "transforms" / "base_to_single_chip.txt"
    tf.write_text("0.1 0 0.05\n0 0 0 0\n")
    with pytest.raises(DataError, match=r"base_to_single_chip.txt: extrinsic .* not unit length"):
        ColoradarSequence(run)
    tf.write_text("nan 0 0.05\n0 0 0 1\n")
    with pytest.raises(DataError, match=r"base_to_single_chip.txt: .*expected finite numbers"):
        ColoradarSequence(run)


def test_a_nan_scan_stamp_names_the_file_and_line(tmp_path):
    from loaders.coloradar import ColoradarSequence

    run = _coloradar(tmp_path / "runs" / "run0")
    stamps = run / "single_chip" / "pointclouds" / "timestamps.txt"
    lines = stamps.read_text().splitlines()
    lines[2] = "nan"
    stamps.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"timestamps.txt, line 3: expected a stamp in seconds"):
        ColoradarSequence(run)
