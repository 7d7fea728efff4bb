"""bench.data.export on tiny stores (a few scans of a few points, in-process): the bag's
layout read back with rosbags, the description, the read-back command and the printed summary,
the output rules (make mutate's survivors; the broad round trips: test_export.py)."""

import io
import json
import shlex
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console
from scipy.spatial.transform import Rotation

from bench.data.export import (
    DOPPLER_SIGN,
    ExportSummary,
    bag_path,
    default_out,
    description,
    doppler_kind_note,
    export_command,
    export_store,
    readback_out,
    reimport_command,
    write_bag,
)
from loaders.errors import DataError
from loaders.posefile import parse_extrinsic
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.store import StoreSequence, write_store
from loaders.trajectory import Trajectory

NS = 10**9


def pose(rotvec, xyz) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = xyz
    return T


T_BS = pose([0.01, -0.02, 0.3], [1.2, 0.1, 1.5])


def tiny_store(path, stamps=(10.0, 10.1, 10.2, 10.3), gt_stamps=None, doppler=True,
               kind="radar", model="radar-x", doppler_kind="radial", provenance=None):
    """Scans of 5 points with fields ``power`` and ``rcs``; GT (T_world_sensor) at
    ``gt_stamps`` (default: the scan stamps; () for none): a translation of k metres along x."""
    rng = np.random.default_rng(len(stamps))
    scans = [Scan(t, rng.uniform(-20, 20, (5, 3)), rng.normal(0, 2, 5) if doppler else None,
                  {"power": rng.uniform(0, 9, 5), "rcs": rng.uniform(-5, 5, 5)})
             for t in stamps]
    gt_stamps = stamps if gt_stamps is None else gt_stamps
    gt = None
    if len(gt_stamps):
        poses = np.array([pose([0, 0, 0.1 * k], [k, 0.5 * k, 0]) for k in range(len(gt_stamps))])
        gt = Trajectory(np.asarray(gt_stamps, float), poses)
    seq = MemorySequence("tiny", SensorInfo(kind, 0.1, T_BS, model, doppler_kind), scans, gt,
                         provenance or {"loader": "test"})
    return write_store(seq, path)


@pytest.fixture
def store(tmp_path):
    return tiny_store(tmp_path / "tiny.h5")


def read_bag(path):
    """[(topic, record time [ns], message)] in the bag's order, read by rosbags."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        return [(c.topic, t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages()]


def out_for(tmp_path, fmt, name="b"):
    return tmp_path / (f"{name}.bag" if fmt == "ros1" else name)


# -- paths -----------------------------------------------------------------------------------

def test_default_out_is_beside_the_store_named_by_the_format(tmp_path):
    store = tmp_path / "d" / "run.v2.h5"
    assert default_out(store, "ros1") == tmp_path / "d" / "run.v2.bag"
    assert default_out(store, "ros2") == tmp_path / "d" / "run.v2_ros2"
    assert default_out(str(store), "mcap") == tmp_path / "d" / "run.v2_mcap"


def test_bag_path_gives_a_ros1_bag_its_extension_only(tmp_path):
    assert bag_path(tmp_path / "a", "ros1") == tmp_path / "a.bag"
    assert bag_path(tmp_path / "a.bag", "ros1") == tmp_path / "a.bag"
    assert bag_path(tmp_path / "a.h5", "ros1") == tmp_path / "a.h5.bag"
    assert bag_path(str(tmp_path / "a"), "ros1") == tmp_path / "a.bag"
    for fmt in ("ros2", "mcap"):
        assert bag_path(tmp_path / "a", fmt) == tmp_path / "a"
        assert bag_path(tmp_path / "a.bag", fmt) == tmp_path / "a.bag"


def test_readback_out_never_names_an_existing_store(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert readback_out("run", "mcap") == "run.h5"
    (tmp_path / "run.h5").write_text("a store")
    assert readback_out("run", "mcap") == "run_mcap.h5"
    assert readback_out("run", "ros1") == "run_ros1.h5"
    assert readback_out("other", "ros1") == "other.h5"


# -- the description ---------------------------------------------------------------------------

def test_the_description_of_a_doppler_store(store):
    seq = StoreSequence(store)
    try:
        d = description(seq, store, ["doppler", "power", "rcs"])
    finally:
        seq.close()
    assert d["exported_by"] == "doppler-bench (bench export)"
    assert d["store"] == str(store) and d["sequence"] == "tiny"
    assert (d["points_topic"], d["ground_truth_topic"]) == ("/points", "/ground_truth")
    assert d["fields"] == ["x", "y", "z", "doppler", "power", "rcs"]
    assert d["units"] == "x y z [m] in the sensor frame; doppler [m/s]; other fields as stored"
    assert d["doppler"] == DOPPLER_SIGN and "positive when the point recedes" in d["doppler"]
    assert (d["doppler_kind"], d["sensor_kind"], d["sensor_model"]) == ("radial", "radar",
                                                                        "radar-x")
    assert d["period_s"] == pytest.approx(0.1)
    assert d["frames"] == {"world": "world", "body": "base_link", "sensor": "radar"}
    assert d["ground_truth"] == ("nav_msgs/Odometry: T_world_base_link at the scans with ground "
                                 "truth; the sensor (radar) pose is that @ T_base_link_radar "
                                 "(/tf_static)")
    assert d["stamps"] == "the store's stamps, rounded to the nanosecond"
    assert d["first_stamp_s"] == pytest.approx(10.0)
    np.testing.assert_allclose(d["T_body_sensor"], T_BS, atol=1e-15)
    json.dumps(d)  # a JSON text as written


def test_the_description_of_a_store_without_doppler_from_zero(tmp_path):
    path = tiny_store(tmp_path / "z.h5", stamps=(0.0, 0.1), doppler=False, kind="lidar",
                      model="")
    seq = StoreSequence(path)
    try:
        d = description(seq, path, ["power", "rcs"])
    finally:
        seq.close()
    assert d["fields"] == ["x", "y", "z", "power", "rcs"]
    assert d["doppler"] == "none (the store has no Doppler)"
    assert d["doppler_kind"] == "none" and d["sensor_kind"] == "lidar"
    assert d["stamps"].startswith("the store's clock starts at 0 s")
    assert d["first_stamp_s"] == 0.0


# -- the bag write_bag makes ------------------------------------------------------------------

def test_write_bag_interleaves_ground_truth_in_time_order_and_writes_every_pose(tmp_path):
    """GT before the first scan, between scans, at a scan's stamp and after the last: every
    pose is written, each at its own stamp, the record times never decrease, and a pose
    stamped like a scan comes before it (a player gives it before the scan)."""
    gt_stamps = (9.95, 10.0, 10.15, 10.3, 10.45)
    path = tiny_store(tmp_path / "g.h5", gt_stamps=gt_stamps)
    seq = StoreSequence(path)
    seen = []
    try:
        summary = write_bag(seq, path, tmp_path / "g.bag", "ros1", progress=seen.append)
    finally:
        seq.close()
    assert seen == [0, 1, 2, 3]
    assert summary == ExportSummary(tmp_path / "g.bag", "ros1", 4, 5, ["doppler", "power",
                                                                       "rcs"])
    msgs = read_bag(tmp_path / "g.bag")
    times = [t for _, t, _ in msgs]
    assert times == sorted(times)
    odom = [(t, m) for topic, t, m in msgs if topic == "/ground_truth"]
    assert [t for t, _ in odom] == [round(s * NS) for s in gt_stamps]
    # the poses are T_world_body = T_world_sensor @ inv(T_body_sensor), k metres along x
    for k, (_, m) in enumerate(odom):
        p = m.pose.pose.position
        want = pose([0, 0, 0.1 * k], [k, 0.5 * k, 0]) @ np.linalg.inv(T_BS)
        np.testing.assert_allclose([p.x, p.y, p.z], want[:3, 3], atol=1e-12)
    # the ROS1 header seq counts the messages as written: in time order, a pose before the
    # scan of its stamp
    seq_of = {(topic, t): m.header.seq for topic, t, m in msgs
              if topic in ("/points", "/ground_truth")}
    written = [key for _, key in sorted((s, key) for key, s in seq_of.items())]
    assert [t for _, t in written] == sorted(t for _, t in written)
    assert seq_of[("/ground_truth", round(10.3 * NS))] < seq_of[("/points", round(10.3 * NS))]


def test_a_store_without_ground_truth_has_no_ground_truth_topic(tmp_path):
    path = tiny_store(tmp_path / "n.h5", gt_stamps=())
    summary = export_store(path, "mcap", tmp_path / "n")
    assert summary.gt_poses == 0 and summary.frames == 4
    topics = {topic for topic, _, _ in read_bag(tmp_path / "n")}
    assert topics == {"/points", "/tf_static", "/doppler_bench/description"}
    from loaders.rosbag import bag_topics

    assert set(bag_topics([tmp_path / "n"])) == topics  # no empty ground-truth connection


@pytest.mark.parametrize("fmt", ["ros1", "ros2", "mcap"])
def test_the_bag_holds_scans_extrinsic_and_description_at_the_stores_stamps(store, tmp_path,
                                                                            fmt):
    summary = export_store(store, fmt, out_for(tmp_path, fmt))
    assert summary.path == out_for(tmp_path, fmt) and summary.format == fmt
    msgs = read_bag(summary.path)
    first = round(10.0 * NS)
    by_topic = {}
    for topic, t, m in msgs:
        by_topic.setdefault(topic, []).append((t, m))
    (tf,) = by_topic["/tf_static"]
    (info,) = by_topic["/doppler_bench/description"]
    assert tf[0] == info[0] == first  # both at the first scan's stamp
    (tr,) = tf[1].transforms
    assert (tr.header.frame_id, tr.child_frame_id) == ("base_link", "radar")
    np.testing.assert_allclose([tr.transform.translation.x, tr.transform.translation.y,
                                tr.transform.translation.z], T_BS[:3, 3], atol=1e-12)
    d = json.loads(info[1].data)
    assert d["fields"] == ["x", "y", "z", "doppler", "power", "rcs"] and d["sequence"] == "tiny"
    assert info[1].data == json.dumps(d, indent=1)  # an indented JSON text
    src = StoreSequence(store)
    try:
        clouds = by_topic["/points"]
        assert [t for t, _ in clouds] == [round(s * NS) for s in src.stamps]
        for i, (_, m) in enumerate(clouds):
            assert m.header.frame_id == "radar"
            assert [f.name for f in m.fields] == ["x", "y", "z", "doppler", "power", "rcs"]
            rows = np.frombuffer(bytes(m.data), dtype="<f4").reshape(-1, 6)
            scan = src.scan(i)
            np.testing.assert_array_equal(rows[:, :3], scan.points.astype(np.float32))
            np.testing.assert_array_equal(rows[:, 3], scan.doppler.astype(np.float32))
            np.testing.assert_array_equal(rows[:, 4], scan.fields["power"].astype(np.float32))
            np.testing.assert_array_equal(rows[:, 5], scan.fields["rcs"].astype(np.float32))
    finally:
        src.close()
    odom = by_topic["/ground_truth"]
    assert len(odom) == 4
    assert (odom[0][1].header.frame_id, odom[0][1].child_frame_id) == ("world", "base_link")


def test_a_store_without_doppler_exports_its_fields_only(tmp_path):
    path = tiny_store(tmp_path / "nd.h5", doppler=False)
    summary = export_store(path, "ros1", tmp_path / "nd")
    assert summary.path == tmp_path / "nd.bag" and summary.fields == ["power", "rcs"]
    clouds = [m for topic, _, m in read_bag(summary.path) if topic == "/points"]
    assert [f.name for f in clouds[0].fields] == ["x", "y", "z", "power", "rcs"]


def test_the_frames_of_the_stores_provenance_name_the_bags_frames(tmp_path):
    prov = {"loader": "x", "world_frame": "map", "body_frame": "imu", "sensor_frame": "front"}
    path = tiny_store(tmp_path / "f.h5", provenance=prov)
    summary = export_store(path, "mcap", tmp_path / "f")
    msgs = read_bag(summary.path)
    frames = {topic: m for topic, _, m in msgs}
    tf = frames["/tf_static"].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("imu", "front")
    assert (frames["/ground_truth"].header.frame_id,
            frames["/ground_truth"].child_frame_id) == ("map", "imu")
    assert frames["/points"].header.frame_id == "front"


# -- the output rules ---------------------------------------------------------------------------

def test_an_unknown_format_is_one_error_naming_the_option(store, tmp_path):
    with pytest.raises(DataError, match=r"^--format 'ros3': expected one of ros1, ros2, mcap$"):
        export_store(store, "ros3", tmp_path / "x")
    assert list(tmp_path.iterdir()) == [store]


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_without_out_the_bag_goes_beside_the_store(store, fmt):
    summary = export_store(store, fmt)
    assert summary.path == default_out(store, fmt) and summary.path.exists()


def test_an_empty_folder_is_filled_with_force_and_refused_without(store, tmp_path):
    folder = tmp_path / "empty"
    folder.mkdir()
    with pytest.raises(DataError, match="exists"):
        export_store(store, "ros2", folder)
    summary = export_store(store, "ros2", folder, force=True)
    assert (folder / "metadata.yaml").exists() and summary.frames == 4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "tiny.h5"]  # no work left


def test_a_rosbag2_bag_of_ours_is_replaced_with_force_in_its_format(store, tmp_path):
    folder = tmp_path / "r"
    export_store(store, "mcap", folder)
    summary = export_store(store, "ros2", folder, force=True)
    assert summary.path == folder and summary.format == "ros2"
    assert sorted(p.suffix for p in folder.iterdir()) == [".db3", ".yaml"]


def test_a_ros1_bag_of_ours_is_replaced_with_force_never_an_unreadable_one(store, tmp_path):
    ours = tmp_path / "o.bag"
    export_store(store, "ros1", ours)
    assert export_store(store, "ros1", ours, force=True).path == ours
    bad = tmp_path / "bad.bag"
    bad.write_bytes(b"#ROSBAG V2.0\nnot a bag at all")
    with pytest.raises(DataError, match="not a ROS1 bag this command wrote"):
        export_store(store, "ros1", bad, force=True)
    assert bad.read_bytes() == b"#ROSBAG V2.0\nnot a bag at all"


def test_a_ros1_bag_where_a_rosbag2_folder_goes_is_refused(store, tmp_path):
    bag = export_store(store, "ros1", tmp_path / "o.bag").path
    with pytest.raises(DataError, match="not a rosbag2 folder"):
        export_store(store, "mcap", bag, force=True)


# -- the read-back command and the printed summary -----------------------------------------

def summary_of(path="out dir/b.bag", gt_poses=3, fields=("doppler", "power")):
    return ExportSummary(Path(path), "ros1", 4, gt_poses, list(fields))


def test_the_reimport_command_spells_out_every_option():
    cmd = reimport_command(summary_of(), "my run", "radar", "radar x", "radial", T_BS)
    args = shlex.split(cmd)
    assert args[:4] == ["bench", "convert", "rosbag", "out dir/b.bag"]
    opts = dict(zip(args[4::2], args[5::2], strict=True))
    assert opts == {"--topic": "/points", "--gt-topic": "/ground_truth",
                    "--T-body-sensor": opts["--T-body-sensor"], "--sensor-kind": "radar",
                    "--model": "radar x", "--doppler-kind": "radial", "--name": "my run",
                    "--out": "my run.h5"}
    values = [float(v) for v in opts["--T-body-sensor"].split()]
    assert len(values) == 7
    np.testing.assert_allclose(values[:3], T_BS[:3, 3], rtol=0, atol=1e-15)
    q = Rotation.from_matrix(T_BS[:3, :3]).as_quat()
    np.testing.assert_allclose(values[3:], q if q[3] >= 0 else -q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(parse_extrinsic(opts["--T-body-sensor"]), T_BS, atol=1e-15)


def test_the_reimport_command_without_ground_truth_model_or_doppler():
    cmd = reimport_command(summary_of(gt_poses=0, fields=("power",)), "r", "lidar", "",
                           "radial", np.eye(4), out="x.h5")
    args = shlex.split(cmd)
    assert "--gt-topic" not in args and "--model" not in args and "--doppler-kind" not in args
    assert args[3:6] == ["out dir/b.bag", "--topic", "/points"]
    assert args[args.index("--T-body-sensor") + 2] == "--sensor-kind"
    assert args[args.index("--doppler-field") + 1] == "none"
    assert args[-2:] == ["--out", "x.h5"] and args[args.index("--sensor-kind") + 1] == "lidar"
    assert args[args.index("--T-body-sensor") + 1] == "0 0 0 0 0 0 1"


@pytest.mark.parametrize(("kind", "option"), [("radial", ["--doppler-kind", "radial"]),
                                              ("ego-compensated",
                                               ["--doppler-kind", "ego-compensated"]),
                                              ("gt-reconstructed", [])])
def test_the_reimport_command_declares_the_doppler_kinds_the_loader_takes(kind, option):
    args = shlex.split(reimport_command(summary_of(), "r", "radar", "m", kind, np.eye(4)))
    got = args[args.index("--doppler-kind"):args.index("--doppler-kind") + 2] \
        if "--doppler-kind" in args else []
    assert got == option and "--doppler-field" not in args
    opts = dict(zip(args[4::2], args[5::2], strict=True))
    assert (opts["--model"], opts["--name"], opts["--gt-topic"]) == ("m", "r", "/ground_truth")


def test_the_doppler_kind_note_only_for_a_kind_the_loader_does_not_take():
    assert doppler_kind_note(summary_of(), "radial") is None
    assert doppler_kind_note(summary_of(), "ego-compensated") is None
    assert doppler_kind_note(summary_of(fields=("power",)), "gt-reconstructed") is None
    assert doppler_kind_note(summary_of(), "gt-reconstructed") == (
        "this store's Doppler is gt-reconstructed, which the rosbag loader does not take (read "
        "back as radial): results from its bag are not independent of the ground truth")


def printed(store, fmt, out, force=False) -> list[str]:
    buf = io.StringIO()
    export_command(Console(file=buf, width=10_000, color_system=None), store, fmt, out, force)
    return buf.getvalue().splitlines()


def test_export_command_prints_what_it_wrote_and_how_to_read_it_back(store, tmp_path,
                                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    lines = printed(store, "ros1", tmp_path / "p")
    assert lines[0] == (
        f"wrote {tmp_path / 'p.bag'} (ros1): 4 scans on /points (fields x y z doppler power "
        "rcs), 4 ground-truth poses on /ground_truth, the extrinsic on /tf_static, the "
        f"description on /doppler_bench/description; {DOPPLER_SIGN}")
    assert "[m/s]" in lines[0]  # printed as text, not read as markup
    assert len(lines) == 2 and lines[1].startswith("read it back with: bench convert rosbag ")
    args = shlex.split(lines[1].removeprefix("read it back with: "))
    assert args[-4:] == ["--name", "tiny", "--out", "tiny_ros1.h5"]  # the store is tiny.h5
    assert args[args.index("--model") + 1] == "radar-x"


def test_export_command_notes_a_clock_from_zero_and_an_untaken_doppler_kind(tmp_path):
    path = tiny_store(tmp_path / "z.h5", stamps=(0.0, 0.1), doppler_kind="gt-reconstructed")
    lines = printed(path, "mcap", tmp_path / "zz")
    assert lines[1].startswith("note: the store's clock starts at 0 s")
    assert lines[2].startswith("note: this store's Doppler is gt-reconstructed")
    assert lines[3].startswith("read it back with: ") and len(lines) == 4
    assert "--doppler-kind" not in lines[3]


def test_export_command_says_a_store_without_doppler_has_none(tmp_path):
    path = tiny_store(tmp_path / "nd.h5", doppler=False)
    lines = printed(path, "ros2", tmp_path / "nd")
    assert lines[0].endswith("(fields x y z power rcs), 4 ground-truth poses on /ground_truth, "
                             "the extrinsic on /tf_static, the description on "
                             "/doppler_bench/description; no Doppler field: the store has no "
                             "Doppler (methods that need it cannot run on this bag)")
    assert "--doppler-field none" in lines[1]


# -- make mutate's survivors of the first run ------------------------------------------------

def test_an_empty_out_is_one_error_naming_the_option(store):
    for fmt in ("ros1", "mcap"):
        with pytest.raises(DataError, match=r"^--out '': empty; expected the path of a file or "
                           "folder to write$"):
            export_store(store, fmt, "")


def test_the_store_itself_or_its_folder_is_refused_as_an_input(tmp_path):
    store = tiny_store(tmp_path / "s" / "run.bag")  # a store named like a ROS1 bag
    before = store.read_bytes()
    for fmt, out in (("ros1", store), ("mcap", store.parent), ("ros2", store)):
        with pytest.raises(DataError, match="is an input of this command|holds an input of "
                           "this command"):
            export_store(store, fmt, out, force=True)
    assert store.read_bytes() == before and sorted(store.parent.iterdir()) == [store]


def test_an_existing_bag_without_force_names_what_it_is(store, tmp_path):
    export_store(store, "mcap", tmp_path / "m")
    with pytest.raises(DataError, match=r"exists \(a rosbag2 folder \(metadata.yaml and its "
                       r"storage files only\)\); give another --out or --force to replace it"):
        export_store(store, "mcap", tmp_path / "m")
    export_store(store, "ros1", tmp_path / "o.bag")
    with pytest.raises(DataError, match=r"exists \(a ROS1 bag\); give another --out or --force"):
        export_store(store, "ros1", tmp_path / "o.bag")


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_progress_is_called_once_a_scan_in_order(store, tmp_path, fmt):
    seen = []
    summary = export_store(store, fmt, out_for(tmp_path, fmt), progress=seen.append)
    assert seen == [0, 1, 2, 3] and summary.frames == 4


@pytest.mark.parametrize("fmt", ["ros1", "ros2"])
def test_the_description_in_the_bag_names_the_store(store, tmp_path, fmt):
    path = export_store(store, fmt, out_for(tmp_path, fmt)).path
    (info,) = [m for topic, _, m in read_bag(path) if topic == "/doppler_bench/description"]
    assert json.loads(info.data)["store"] == str(store)


def test_a_work_folder_left_by_a_crashed_export_of_this_process_is_cleared(store, tmp_path):
    import os

    stale = tmp_path / f".b.{os.getpid()}.export"
    (stale / "b").mkdir(parents=True)
    (stale / "b" / "half.db3").write_bytes(b"half written")
    summary = export_store(store, "ros2", tmp_path / "b")
    assert summary.frames == 4 and (tmp_path / "b" / "metadata.yaml").exists()
    assert not stale.exists()


def test_export_command_without_force_refuses_an_existing_bag_and_with_force_replaces_it(
        store, tmp_path):
    printed(store, "ros1", tmp_path / "x.bag")
    with pytest.raises(DataError, match=r"give another --out or --force to replace it$"):
        printed(store, "ros1", tmp_path / "x.bag")
    assert printed(store, "ros1", tmp_path / "x.bag", force=True)[0].startswith("wrote ")


def test_export_command_prints_brackets_in_paths_and_notes_as_they_are(tmp_path, monkeypatch):
    """Rich would read ``[i]`` or ``[b]`` as markup: every line is printed as plain text."""
    prov = {"loader": "x", "clock_origin_s": 1000.0, "stamp_source": "1000 s + frame [i] x "
            "0.1 s"}
    path = tiny_store(tmp_path / "st[b].h5", stamps=(1000.0, 1000.1), provenance=prov)
    monkeypatch.chdir(tmp_path)
    lines = printed(path, "ros1", tmp_path / "out[b]")
    assert lines[0].startswith(f"wrote {tmp_path / 'out[b].bag'} (ros1): 2 scans")
    assert lines[1].startswith("note: the store's stamps are 1000 s + frame [i] x 0.1 s, set")
    args = shlex.split(lines[2].removeprefix("read it back with: "))
    assert args[3] == str(tmp_path / "out[b].bag")
    assert args[args.index("--sensor-kind") + 1] == "radar"
    assert args[args.index("--doppler-kind") + 1] == "radial"


@pytest.mark.parametrize("fmt", ["ros1", "ros2", "mcap"])
def test_the_extrinsic_and_the_description_are_latched_the_scans_and_poses_not(store, tmp_path,
                                                                               fmt):
    """A node started after playback began still gets /tf_static and the description (ROS1:
    latched; ROS2: transient local, depth 1)."""
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import QosDurability

    path = export_store(store, fmt, out_for(tmp_path, fmt)).path
    with AnyReader([path]) as reader:
        conns = {c.topic: c for c in reader.connections}
    latched = {"/tf_static", "/doppler_bench/description"}
    assert set(conns) == latched | {"/points", "/ground_truth"}
    for topic, conn in conns.items():
        if fmt == "ros1":
            assert (conn.ext.latching or 0) == (1 if topic in latched else 0), topic
        else:
            qos = conn.ext.offered_qos_profiles
            assert ([(q.durability, q.depth) for q in qos] ==
                    ([(QosDurability.TRANSIENT_LOCAL, 1)] if topic in latched else [])), topic
