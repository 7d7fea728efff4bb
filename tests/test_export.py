"""bench export: a store as a ROS1 / ROS2 sqlite3 / mcap bag, read back by the generic bag
loader (loaders.rosbag) to the same store contents; the extrinsic on /tf_static, the Doppler
sign in the description; memory flat in the sequence length."""

import json
import tracemalloc

import numpy as np
import pytest
from helpers_cli import bench_main
from typer.testing import CliRunner

from bench.cli import app
from bench.data.export import (
    GT_TOPIC,
    INFO_TOPIC,
    POINTS_TOPIC,
    TF_TOPIC,
    default_out,
    export_store,
    reimport_command,
)
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.posefile import parse_extrinsic
from loaders.rosbag import RosbagSequence
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import T_from_tum
from loaders.store import StoreSequence, write_store
from loaders.trajectory import Trajectory

EXTRINSIC = "1.2 0.1 1.5 0.0087265 -0.0130896 0.0043633 0.9998719"
T_BS = parse_extrinsic(EXTRINSIC)


def radar_sequence(frames: int = 12, points: int = 300, t0: float = 1654232000.25,
                   gt_every: int = 1, doppler: bool = True,
                   provenance: dict | None = None) -> MemorySequence:
    """A radar-like sequence with an extrinsic, intensity and power fields, epoch stamps, GT on
    every ``gt_every``-th scan (without Doppler when not ``doppler``)."""
    base = constant_twist_sequence(n_frames=frames, n_points=points, max_range_m=70, seed=3)
    rng = np.random.default_rng(1)
    scans = [Scan(t0 + s.stamp, s.points, s.doppler if doppler else None,
                  {"intensity": rng.uniform(0, 50, len(s)), "power": s.fields["power"]})
             for s in base]
    keep = np.arange(frames)[::gt_every]
    gt = Trajectory(t0 + base.ground_truth.stamps[keep], base.ground_truth.poses[keep])
    return MemorySequence("radar_run", SensorInfo("radar", 0.1, T_BS, "radar-semidense"),
                          scans, gt, provenance or {"loader": "test"})


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return write_store(radar_sequence(), tmp_path_factory.mktemp("export") / "radar_run.h5")


def read_back(bag, tmp_path, src: StoreSequence) -> StoreSequence:
    seq = RosbagSequence([bag], topic=POINTS_TOPIC, gt_topic=GT_TOPIC, T_body_sensor=EXTRINSIC,
                         sensor_kind=src.sensor.kind, model=src.sensor.model, name=src.name)
    return StoreSequence(write_store(seq, tmp_path / "back.h5"))


@pytest.mark.parametrize("fmt", ["ros1", "ros2", "mcap"])
def test_round_trip_gives_the_same_store_contents(store, tmp_path, fmt):
    out = tmp_path / ("run.bag" if fmt == "ros1" else f"run_{fmt}")
    summary = export_store(store, fmt, out)
    assert summary.path == out and summary.frames == 12 and summary.gt_poses == 12
    assert summary.fields == ["doppler", "intensity", "power"]
    src = StoreSequence(store)
    back = read_back(out, tmp_path, src)
    assert len(back) == len(src) == 12
    np.testing.assert_allclose(back.stamps, src.stamps, rtol=0, atol=1e-6)  # ns stamps
    assert sorted(back.fields) == sorted(src.fields) == ["intensity", "power"]
    for a, b in zip(src, back, strict=True):
        np.testing.assert_array_equal(b.points, a.points)  # float32 both ways: exact
        np.testing.assert_array_equal(b.doppler, a.doppler)  # the same sign
        for name in src.fields:
            np.testing.assert_array_equal(b.fields[name], a.fields[name])
    # GT exported as T_world_body, read back with the extrinsic: the same T_world_sensor
    np.testing.assert_allclose(back.ground_truth.stamps, src.ground_truth.stamps, atol=1e-6)
    np.testing.assert_allclose(back.ground_truth.poses, src.ground_truth.poses, atol=1e-9)
    np.testing.assert_allclose(back.sensor.T_body_sensor, src.sensor.T_body_sensor, atol=1e-12)
    assert (back.sensor.kind, back.sensor.model, back.sensor.doppler_kind) == \
        (src.sensor.kind, src.sensor.model, src.sensor.doppler_kind)
    assert abs(back.sensor.period_s - src.sensor.period_s) < 1e-6


def _topic_messages(bag, topic):
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in
                reader.messages(connections=conns)]


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_tf_static_holds_the_extrinsic_and_the_description_the_doppler_sign(store, tmp_path,
                                                                            fmt):
    out = export_store(store, fmt, tmp_path / ("b.bag" if fmt == "ros1" else "b")).path
    (tf,) = _topic_messages(out, TF_TOPIC)
    (t,) = tf.transforms
    assert (t.header.frame_id, t.child_frame_id) == ("base_link", "radar")
    tr, q = t.transform.translation, t.transform.rotation
    T = T_from_tum(np.array([[tr.x, tr.y, tr.z]]), np.array([[q.x, q.y, q.z, q.w]]))[0]
    np.testing.assert_allclose(T, T_BS, atol=1e-12)
    (info,) = _topic_messages(out, INFO_TOPIC)
    text = json.loads(info.data)
    assert "positive when the point recedes" in text["doppler"]
    assert text["fields"] == ["x", "y", "z", "doppler", "intensity", "power"]
    odom = _topic_messages(out, GT_TOPIC)
    assert odom[0].header.frame_id == "world" and odom[0].child_frame_id == "base_link"
    if fmt == "mcap":  # a node started after playback began still gets the extrinsic
        from rosbags.highlevel import AnyReader
        from rosbags.interfaces import QosDurability

        with AnyReader([out]) as reader:
            (conn,) = [c for c in reader.connections if c.topic == TF_TOPIC]
            assert conn.ext.offered_qos_profiles[0].durability == QosDurability.TRANSIENT_LOCAL
    clouds = _topic_messages(out, POINTS_TOPIC)
    assert [f.name for f in clouds[0].fields] == ["x", "y", "z", "doppler", "intensity",
                                                   "power"]
    assert clouds[0].header.frame_id == "radar"  # the sensor's kind names its frame


def test_scans_without_ground_truth_stay_unscored_after_the_round_trip(tmp_path):
    # GT on every 4th scan: exported poses only there; a gap of 0.4 s is within the loader's
    # max gap, so read back with --max-gap below it, exactly those scans have GT again
    store = write_store(radar_sequence(gt_every=4), tmp_path / "sparse.h5")
    summary = export_store(store, "mcap", tmp_path / "sparse_mcap")
    assert summary.gt_poses == 3
    src = StoreSequence(store)
    with pytest.warns(UserWarning, match="no ground truth"):
        seq = RosbagSequence([summary.path], topic=POINTS_TOPIC, gt_topic=GT_TOPIC,
                             T_body_sensor=EXTRINSIC, sensor_kind="radar", max_gap_s=0.3)
    np.testing.assert_allclose(seq.ground_truth.stamps, src.ground_truth.stamps, atol=1e-6)
    np.testing.assert_allclose(seq.ground_truth.poses, src.ground_truth.poses, atol=1e-9)


def test_existing_output_is_refused_without_force_and_bad_format(store, tmp_path):
    out = tmp_path / "x.bag"
    export_store(store, "ros1", out)
    with pytest.raises(DataError, match=r"exists \(a ROS1 bag\); give another --out or --force"):
        export_store(store, "ros1", out)
    first = out.stat().st_mtime_ns
    export_store(store, "ros1", out, force=True)
    assert out.stat().st_mtime_ns >= first
    assert not list(tmp_path.glob(".*tmp")) and not list(tmp_path.glob(".*export"))
    with pytest.raises(DataError, match="--format 'ros3': expected one of ros1, ros2, mcap"):
        export_store(store, "ros3", tmp_path / "y")


def test_default_out_and_reimport_command(store, tmp_path):
    assert default_out(store, "ros1") == store.with_suffix(".bag")
    assert default_out(store, "mcap") == store.parent / "radar_run_mcap"
    summary = export_store(store, "ros2", tmp_path / "r2")
    cmd = reimport_command(summary, "radar_run", "radar", "radar-semidense", "radial", T_BS)
    assert cmd.startswith(f"bench convert rosbag {tmp_path / 'r2'} --topic /points "
                          "--gt-topic /ground_truth --T-body-sensor '")
    # the extrinsic in the command is the store's, to 17 digits
    ext = cmd.split("--T-body-sensor '")[1].split("'")[0]
    np.testing.assert_allclose(parse_extrinsic(ext), T_BS, atol=1e-12)


def test_cli_export_prints_what_it_wrote(store, tmp_path):
    out = tmp_path / "cli_mcap"
    res = CliRunner().invoke(app, ["export", str(store), "--format", "mcap", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "12 scans on /points (fields x y z doppler intensity power)" in res.output
    assert "positive when the point recedes" in res.output
    assert (out / "metadata.yaml").exists()


def random_store(path, frames: int, points: int = 1000):
    """Random scans (the export does not care what they show) with GT, written frame by frame."""
    rng = np.random.default_rng(frames)
    scans = [Scan(0.1 * k, rng.uniform(-50, 50, (points, 3)), rng.normal(0, 3, points),
                  {"intensity": rng.uniform(0, 1, points)}) for k in range(frames)]
    poses = np.repeat(np.eye(4)[None], frames, axis=0)
    poses[:, 0, 3] = np.arange(frames)
    seq = MemorySequence("random", SensorInfo("radar", 0.1, T_BS), scans,
                         Trajectory(0.1 * np.arange(frames), poses))
    return write_store(seq, path)


def _peak_bytes(store, out, fmt) -> int:
    tracemalloc.start()
    try:
        export_store(store, fmt, out, force=True)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_export_memory_is_flat_in_the_sequence_length(tmp_path, monkeypatch, fmt):
    """Peak Python-side memory (tracemalloc: NumPy's buffers and rosbags' messages) of exporting
    300 vs 900 scans of 1000 points (3x the data, 24 MB more), the store's read-ahead block set
    to one chunk (65536 points) so that both exports read several whole blocks (a shorter store
    reads a smaller last block, which lowers its peak by up to a block): the peaks differ by
    far less than the extra data (measured: 6.79 / 6.83 / 6.90 MB at 300 / 600 / 1200 scans),
    the export holds one scan (and one read block) at a time."""
    import loaders.store

    monkeypatch.setattr(loaders.store, "BLOCK_POINTS", loaders.store.CHUNK_POINTS)
    short = random_store(tmp_path / "short.h5", 300)
    long = random_store(tmp_path / "long.h5", 900)
    extra_bytes = 2 * 600 * 1000 * 4 * 5  # store arrays + serialised clouds
    name = "b.bag" if fmt == "ros1" else "b"
    _peak_bytes(short, tmp_path / name, fmt)  # imports and type stores loaded once
    p_short = _peak_bytes(short, tmp_path / name, fmt)
    p_long = _peak_bytes(long, tmp_path / name, fmt)
    assert p_long - p_short < 0.05 * extra_bytes, (p_short, p_long, extra_bytes)


def test_the_vendored_real_sample_round_trips(tmp_path):
    """A converted public layout (samples/: NTU4DRadLM loop1 radar frames, bench convert's
    store) exported as mcap and read back by the rosbag loader: the same store contents."""
    from conftest import SAMPLE_STORE

    summary = export_store(SAMPLE_STORE, "mcap", tmp_path / "loop1_mcap")
    src = StoreSequence(SAMPLE_STORE)
    assert summary.frames == len(src) == 250 and summary.gt_poses == len(src.ground_truth)
    seq = RosbagSequence([summary.path], topic=POINTS_TOPIC, gt_topic=GT_TOPIC,
                         sensor_kind="radar", model=src.sensor.model, name=src.name)
    back = StoreSequence(write_store(seq, tmp_path / "back.h5"))
    np.testing.assert_allclose(back.stamps, src.stamps, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(back.points_per_frame(), src.points_per_frame())
    for i in (0, 1, 124, 249):
        a, b = src.scan(i), back.scan(i)
        np.testing.assert_array_equal(b.points, a.points)
        np.testing.assert_array_equal(b.doppler, a.doppler)
    np.testing.assert_allclose(back.ground_truth.poses, src.ground_truth.poses, atol=1e-9)
    np.testing.assert_allclose(back.ground_truth.stamps, src.ground_truth.stamps, atol=1e-6)


def _run_printed(output: str, cwd, monkeypatch) -> None:
    """Run the `bench convert rosbag ...` command `bench export` printed, as a shell would
    split it, in ``cwd``."""
    import shlex

    (line,) = [x for x in output.splitlines() if x.startswith("read it back with: ")]
    args = shlex.split(line.removeprefix("read it back with: "))
    assert args[:3] == ["bench", "convert", "rosbag"]
    monkeypatch.chdir(cwd)
    res = CliRunner().invoke(app, args[1:])
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize("fmt", ["ros1", "ros2", "mcap"])
def test_a_store_without_doppler_and_an_out_without_extension_read_back_as_printed(
        tmp_path, monkeypatch, fmt):
    """A Doppler-less store exported to ``--out NAME`` (no extension): a ROS1 bag gets
    ``.bag``; the message lists x y z and the stored fields only and says there is no Doppler
    (no Doppler sign); the printed read-back command runs and gives the same store (no
    Doppler), and so does plain `bench convert rosbag BAG --out S.h5` (the description)."""
    store = write_store(radar_sequence(doppler=False), tmp_path / "nodop.h5")
    res = CliRunner().invoke(app, ["export", str(store), "--format", fmt, "--out",
                                   str(tmp_path / "NAME")])
    assert res.exit_code == 0, res.output
    bag = tmp_path / ("NAME.bag" if fmt == "ros1" else "NAME")
    assert bag.exists() and not (fmt == "ros1" and (tmp_path / "NAME").exists())
    assert "(fields x y z intensity power)" in res.output
    assert "no Doppler field" in res.output and "recedes" not in res.output
    _run_printed(res.output, tmp_path, monkeypatch)
    src = StoreSequence(store)
    plain = tmp_path / "plain.h5"
    res = CliRunner().invoke(app, ["convert", "rosbag", str(bag), "--out", str(plain)])
    assert res.exit_code == 0, res.output
    named = tmp_path / "named.h5"  # an option given wins over the description
    res = CliRunner().invoke(app, ["convert", "rosbag", str(bag), "--name", "other",
                                   "--out", str(named)])
    assert res.exit_code == 0 and StoreSequence(named).name == "other", res.output
    for path in (tmp_path / "radar_run.h5", plain):
        back = StoreSequence(path)
        assert not back.has_doppler and back.name == "radar_run"
        assert sorted(back.fields) == ["intensity", "power"]
        np.testing.assert_array_equal(back.scan(5).points, src.scan(5).points)
        np.testing.assert_allclose(back.stamps, src.stamps, rtol=0, atol=1e-6)
        np.testing.assert_allclose(back.ground_truth.poses, src.ground_truth.poses, atol=1e-9)
        np.testing.assert_allclose(back.sensor.T_body_sensor, T_BS, atol=1e-12)


@pytest.mark.parametrize("fmt", ["ros1", "ros2", "mcap"])
def test_the_printed_command_of_a_doppler_store_runs_and_plain_convert_agrees(
        store, tmp_path, monkeypatch, fmt):
    res = CliRunner().invoke(app, ["export", str(store), "--format", fmt, "--out",
                                   str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
    assert "positive when the point recedes" in res.output
    _run_printed(res.output, tmp_path, monkeypatch)
    bag = tmp_path / ("b.bag" if fmt == "ros1" else "b")
    assert CliRunner().invoke(app, ["convert", "rosbag", str(bag), "--out", "plain.h5"]
                              ).exit_code == 0
    src = StoreSequence(store)
    for path in (tmp_path / "radar_run.h5", tmp_path / "plain.h5"):
        back = StoreSequence(path)
        assert (back.sensor.model, back.sensor.doppler_kind) == ("radar-semidense", "radial")
        np.testing.assert_array_equal(back.scan(3).doppler, src.scan(3).doppler)
        np.testing.assert_allclose(back.ground_truth.poses, src.ground_truth.poses, atol=1e-9)


def test_stamps_are_rounded_to_the_nanosecond_not_truncated(tmp_path):
    """Stamps whose exact binary value lies more than half a nanosecond above a whole
    nanosecond (x.0000000017 s: truncating gives ...001, rounding ...002): the header stamps
    and record times are the nearest nanosecond of the exact value, compared to 1 ns."""
    from fractions import Fraction

    from rosbags.highlevel import AnyReader

    base = radar_sequence(frames=12, t0=0.0)
    stamps = 5.0 + 0.1 * np.arange(12) + np.array([1.7e-9, 2.6e-9, 0.6e-9, 7.9e-9] * 3)
    scans = [Scan(t, s.points, s.doppler, s.fields) for t, s in zip(stamps, base, strict=True)]
    seq = MemorySequence("ns", base.sensor, scans, Trajectory(stamps, base.ground_truth.poses))
    out = export_store(write_store(seq, tmp_path / "ns.h5"), "ros1", tmp_path / "ns.bag").path
    want = [int(round(Fraction(float(t)) * 10**9)) for t in stamps]
    assert want != [int(Fraction(float(t)) * 10**9) for t in stamps]  # truncation differs
    with AnyReader([out]) as reader:
        conns = [c for c in reader.connections if c.topic == POINTS_TOPIC]
        got, logged = [], []
        for c, t, raw in reader.messages(connections=conns):
            st = reader.deserialize(raw, c.msgtype).header.stamp
            got.append(st.sec * 10**9 + st.nanosec)
            logged.append(t)
    assert got == want and logged == want


def test_a_clock_from_zero_is_kept_and_said_and_a_lidar_frame_is_named_lidar(
        tmp_path, monkeypatch, capsys):
    """A store stamped from 0 s (synthetic): the bag keeps the store's clock (a trajectory made
    from the bag scores against the store unchanged) and the export says that ROS may read 0 s
    as no time; a LiDAR's points are in the frame ``lidar``, its GT of ``base_link`` in
    ``world`` (no loader names them). View-of-Delft's clock and frames: test_export_vod.py."""
    from dataclasses import replace as dc_replace

    seq = radar_sequence(t0=0.0)
    seq.sensor = dc_replace(seq.sensor, kind="lidar")
    store = write_store(seq, tmp_path / "zero.h5")
    code, text = bench_main(monkeypatch, capsys, "export", store, "--out", tmp_path / "z_mcap")
    assert code == 0 and "clock starts at 0 s" in text and "'no time'" in text, text
    assert "View-of-Delft" not in text
    out = tmp_path / "z_mcap"
    clouds = _topic_messages(out, POINTS_TOPIC)
    assert (clouds[0].header.stamp.sec, clouds[0].header.stamp.nanosec) == (0, 0)
    assert clouds[0].header.frame_id == "lidar"
    (info,) = _topic_messages(out, INFO_TOPIC)
    d = json.loads(info.data)
    assert d["frames"] == {"world": "world", "body": "base_link", "sensor": "lidar"}
    assert "clock starts at 0 s" in d["stamps"]
    odom = _topic_messages(out, GT_TOPIC)[0]
    assert (odom.header.frame_id, odom.child_frame_id) == ("world", "base_link")
    back = RosbagSequence([out])
    np.testing.assert_allclose(back.stamps, StoreSequence(store).stamps, rtol=0, atol=1e-9)
    # a store with an epoch clock says nothing of it
    code, text = bench_main(monkeypatch, capsys, "export", write_store(
        radar_sequence(), tmp_path / "epoch.h5"), "--out", tmp_path / "epoch_mcap")
    assert code == 0 and "clock starts" not in text and "note:" not in text
    (info,) = _topic_messages(tmp_path / "epoch_mcap", INFO_TOPIC)
    assert json.loads(info.data)["stamps"] == "the store's stamps, rounded to the nanosecond"


def test_export_never_writes_onto_its_store_nor_deletes_a_folders_other_files(
        store, tmp_path, monkeypatch, capsys):
    """--out the store itself, or a folder holding it: refused with or without --force; a
    folder of other files: refused even with --force, every file kept; a bag the export made:
    replaced with --force."""
    for out, fmt in ((store, "mcap"), (store, "ros2"), (store.parent, "mcap")):
        for force in (False, True):
            with pytest.raises(DataError, match="input of this command"):
                export_store(store, fmt, out, force=force)
    assert StoreSequence(store).name == "radar_run"
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me")
    (folder / "metadata.yaml").write_text("not a bag of mine\n")
    for force in (False, True):
        code, text = bench_main(monkeypatch, capsys, "export", store, "--format", "mcap",
                                "--out", folder, *(["--force"] if force else []))
        assert code == 2 and "is a folder that is not a rosbag2 folder" in text, text
        assert "Traceback" not in text
    assert sorted(p.name for p in folder.iterdir()) == ["metadata.yaml", "notes.txt"]
    text = tmp_path / "t.bag"
    text.write_text("a file of my own")
    with pytest.raises(DataError, match="not a ROS1 bag this command wrote"):
        export_store(store, "ros1", text, force=True)
    assert text.read_text() == "a file of my own"
    bag = export_store(store, "mcap", tmp_path / "m").path
    export_store(store, "mcap", bag, force=True)  # its own bag: replaced
    assert (bag / "metadata.yaml").exists()


def test_a_doppler_kind_the_loader_does_not_take_is_noted_beside_a_command_that_runs(
        tmp_path, monkeypatch):
    """GT-reconstructed Doppler: the note is its own line, the printed command stays one a
    shell runs (no remark inside it) and reads the bag back (as radial)."""
    from dataclasses import replace as dc_replace

    seq = radar_sequence()
    seq.sensor = dc_replace(seq.sensor, doppler_kind="gt-reconstructed")
    store = write_store(seq, tmp_path / "rec.h5")
    res = CliRunner().invoke(app, ["export", str(store), "--format", "ros1", "--out",
                                   str(tmp_path / "rec")])
    assert res.exit_code == 0, res.output
    assert "note: this store's Doppler is gt-reconstructed" in res.output
    (line,) = [x for x in res.output.splitlines() if x.startswith("read it back with: ")]
    assert "(" not in line.split("--T-body-sensor")[0] and not line.rstrip().endswith(")")
    _run_printed(res.output, tmp_path, monkeypatch)
    assert StoreSequence(tmp_path / "radar_run.h5").sensor.doppler_kind == "radial"


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_the_printed_command_run_beside_a_store_named_by_its_sequence_does_not_touch_it(
        tmp_path, monkeypatch, fmt):
    """`bench export radar_run.h5` run in the store's own folder (the store named like its
    sequence, as `bench convert` names it): the printed read-back command writes
    radar_run_FMT.h5, not radar_run.h5 (it would be refused, the store being there), runs, and
    leaves the store as it was."""
    store = write_store(radar_sequence(), tmp_path / "radar_run.h5")
    before = store.read_bytes()
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["export", "radar_run.h5", "--format", fmt])
    assert res.exit_code == 0, res.output
    (line,) = [x for x in res.output.splitlines() if x.startswith("read it back with: ")]
    assert line.endswith(f"--out radar_run_{fmt}.h5"), line
    _run_printed(res.output, tmp_path, monkeypatch)
    assert store.read_bytes() == before
    back, src = StoreSequence(tmp_path / f"radar_run_{fmt}.h5"), StoreSequence(store)
    np.testing.assert_array_equal(back.scan(4).doppler, src.scan(4).doppler)
    np.testing.assert_allclose(back.ground_truth.poses, src.ground_truth.poses, atol=1e-9)


def test_force_never_replaces_a_dataset_recording(store, tmp_path):
    """--force replaces a bag `bench export` wrote (it carries the description topic), never
    a dataset's own recording of the same format: a ROS1 bag of NTU4DRadLM's layout and a
    rosbag2 folder of another topic are left as they were."""
    from helpers_bags import Motion, make_truth, write_ntu_bag

    recording = write_ntu_bag(tmp_path / "drive.bag", make_truth(Motion(), 4, 30))
    before = recording.read_bytes()
    with pytest.raises(DataError, match="not a ROS1 bag this command wrote"):
        export_store(store, "ros1", recording, force=True)
    assert recording.read_bytes() == before
    ours = tmp_path / "ours.bag"
    export_store(store, "ros1", ours)
    export_store(store, "ros1", ours, force=True)  # its own bag: made again
    folder = tmp_path / "ros2"
    export_store(store, "ros2", folder)
    from rosbags.highlevel import AnyReader

    with AnyReader([folder]) as reader:
        assert any(c.topic == "/doppler_bench/description" for c in reader.connections)
    export_store(store, "ros2", folder, force=True)
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    other = tmp_path / "recorded"
    with Writer(other, version=8) as writer:
        conn = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=typestore)
        msg = typestore.types["std_msgs/msg/String"](data="hello")
        writer.write(conn, 1, typestore.serialize_cdr(msg, "std_msgs/msg/String"))
    files = sorted((p.name, p.read_bytes()) for p in other.iterdir())
    with pytest.raises(DataError, match="not a rosbag2 folder"):
        export_store(store, "ros2", other, force=True)
    assert sorted((p.name, p.read_bytes()) for p in other.iterdir()) == files
