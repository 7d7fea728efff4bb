"""bench export of a View-of-Delft store (frames written in VoD's byte layout, converted by the
vod loader): a clock that is not 0 s and says what it is (frame NNNNN at 1000 s + NNNNN x
period), frame ids that name what the poses and points are of (odom / camera / radar), the
bag read back by plain `bench convert rosbag BAG` in every format, and a trajectory made from
the bag scoring exactly like one made from the same frames on a clock from 0 s."""

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import bench_main

from bench.data.export import GT_TOPIC, INFO_TOPIC, POINTS_TOPIC, TF_TOPIC
from bench.runs.folders import read_run
from conftest import constant_twist_sequence
from helpers_public import VOD_T_CAMERA_RADAR, write_vod
from loaders.store import StoreSequence, write_store
from loaders.vod import VodSequence

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "external_odometry.py"
FIRST = 544  # frame 00544: stamped 1000 s + 544 x 0.1 s = 1054.4 s


def vod_store(tmp_path: Path, frames: int = 6, points: int = 200, noise_m: float = 0.0,
              world: str = "odom") -> tuple[Path, object]:
    """A VoD folder of frames 00544... of a constant-twist drive, converted to a store; returns
    (store, the drive as a MemorySequence stamped from 0 s)."""
    seq = constant_twist_sequence(n_frames=frames, n_points=points, noise_m=noise_m,
                                  max_range_m=70)
    root = write_vod(tmp_path / "vod", [s.points for s in seq], [s.doppler for s in seq],
                     seq.ground_truth.poses, first=FIRST)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "publishes no frame stamps": the loader's test
        vod = VodSequence(root, world=world)
    return write_store(vod, tmp_path / "vod.h5"), seq


def _messages(bag: Path, topic: str) -> list[tuple[int, object]]:
    """(record time [ns], message) of every message on ``topic``."""
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [(t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages(connections=conns)]


@pytest.mark.parametrize("fmt", ["ros1", "ros2", "mcap"])
def test_a_vod_bag_has_the_frame_clock_and_frames_and_plain_convert_reads_it_back(
        tmp_path, monkeypatch, capsys, fmt):
    store, _ = vod_store(tmp_path, world="map")
    out = tmp_path / ("vod.bag" if fmt == "ros1" else f"vod_{fmt}")
    code, text = bench_main(monkeypatch, capsys, "export", store, "--format", fmt, "--out", out)
    assert code == 0, text
    # the printed note: the clock's rule, its first stamp and the date ROS tools show for it
    assert "note: the store's stamps are 1000 s + frame number x period 0.1 s" in text, text
    assert "first stamp 1054.4 s, which ROS tools show as 1970-01-01 00:17:34 UTC" in text
    assert "clock starts at 0 s" not in text
    # every message of every topic stamped on that clock, none at 0 s
    clouds = _messages(out, POINTS_TOPIC)
    st = clouds[0][1].header.stamp
    assert (st.sec, st.nanosec) == (1054, 400_000_000)
    for topic in (POINTS_TOPIC, GT_TOPIC, TF_TOPIC, INFO_TOPIC):
        assert min(t for t, _ in _messages(out, topic)) == 1_054_400_000_000, topic
    stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for _, m in clouds]
    np.testing.assert_allclose(stamps, 1054.4 + 0.1 * np.arange(6), rtol=0, atol=1e-9)
    # frame ids: points in the radar frame, GT of the camera in the world the poses are in
    assert {m.header.frame_id for _, m in clouds} == {"radar"}
    odom = [m for _, m in _messages(out, GT_TOPIC)]
    assert {(m.header.frame_id, m.child_frame_id) for m in odom} == {("map", "camera")}
    ((_, tf),) = _messages(out, TF_TOPIC)
    assert (tf.transforms[0].header.frame_id, tf.transforms[0].child_frame_id) == \
        ("camera", "radar")
    ((_, info),) = _messages(out, INFO_TOPIC)
    d = json.loads(info.data)
    assert d["frames"] == {"world": "map", "body": "camera", "sensor": "radar"}
    assert "1000 s + frame number x period 0.1 s" in d["stamps"]
    assert d["first_stamp_s"] == pytest.approx(1054.4, abs=1e-9)
    # plain `bench convert rosbag BAG`: the description gives topics, GT, extrinsic, name
    back_path = tmp_path / "back.h5"
    code, text = bench_main(monkeypatch, capsys, "convert", "rosbag", out, "--out", back_path)
    assert code == 0, text
    src, back = StoreSequence(store), StoreSequence(back_path)
    assert back.name == src.name == "vod_00544-00549"
    assert back.sensor.model == src.sensor.model and back.sensor.doppler_kind == "radial"
    np.testing.assert_allclose(back.stamps, src.stamps, rtol=0, atol=1e-6)
    np.testing.assert_allclose(back.ground_truth.stamps, src.ground_truth.stamps, atol=1e-6)
    np.testing.assert_allclose(back.ground_truth.poses, src.ground_truth.poses, atol=1e-9)
    np.testing.assert_allclose(back.sensor.T_body_sensor, VOD_T_CAMERA_RADAR, atol=1e-12)
    np.testing.assert_array_equal(back.scan(3).doppler, src.scan(3).doppler)


def test_an_older_vod_store_from_zero_is_said_with_the_way_out_and_keeps_its_frames(
        tmp_path, monkeypatch, capsys):
    """A VoD store converted before the loader stamped frames by their numbers (clock from 0 s,
    provenance without the frame names): its clock is kept (a trajectory made from the bag
    still scores against it) and the note says how to get a clock from the frame numbers; the
    frames are still camera / radar, the world its ``world`` option's."""
    from loaders.scan import MemorySequence

    seq = constant_twist_sequence(n_frames=6, n_points=100, max_range_m=70)
    old = MemorySequence("vod_00000-00005", seq.sensor, list(seq), seq.ground_truth,
                         {"loader": "vod", "world": "utm (UTMToCamera)"})
    store = write_store(old, tmp_path / "old.h5")
    out = tmp_path / "old_mcap"
    code, text = bench_main(monkeypatch, capsys, "export", store, "--out", out)
    assert code == 0 and "clock starts at 0 s" in text, text
    assert "convert the View-of-Delft folder again" in text
    assert "frame NNNNN at 1000 s + NNNNN x period" in text
    ((_, info),) = _messages(out, INFO_TOPIC)
    assert json.loads(info.data)["frames"] == {"world": "utm", "body": "camera",
                                               "sensor": "radar"}
    clouds = _messages(out, POINTS_TOPIC)
    assert clouds[0][0] == 0 and clouds[0][1].header.frame_id == "radar"


def _score(tum: Path, store: Path, results: Path, monkeypatch, capsys):
    code, text = bench_main(monkeypatch, capsys, "score", tum, "--store", store, "--name",
                            "ext", "--out", results)
    assert code == 0, text
    assert "40 of the 40 scans with ground truth scored (100.0 %; 40 matched within 0.01 s, " \
           "no interpolation)" in text, text
    return read_run(results / StoreSequence(store).name / "ext").result


def test_a_trajectory_from_the_vod_bag_scores_as_one_from_the_same_frames_on_a_zero_clock(
        tmp_path, monkeypatch, capsys):
    """The round trip with the external odometry example (tests/test_external_example.py's
    route): the same 40 frames as a store stamped from 0 s and as a VoD store (stamped from
    1054.4 s), each exported, the example run on each bag and its TUM output scored with
    `bench score` against its own store: the VoD estimate's stamps are the VoD store's (every
    scan matched, none interpolated), its poses the other's, and every figure the same."""
    vod, seq = vod_store(tmp_path, frames=40, points=1500, noise_m=0.02)
    zero = write_store(seq, tmp_path / "zero.h5")
    results = tmp_path / "results"
    found = {}
    for name, store in (("vod", vod), ("zero", zero)):
        bag, tum = tmp_path / f"{name}_mcap", tmp_path / f"{name}.tum"
        code, text = bench_main(monkeypatch, capsys, "export", store, "--out", bag)
        assert code == 0, text
        done = subprocess.run([sys.executable, "-I", str(EXAMPLE), str(bag), str(tum)],
                              cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        found[name] = (np.loadtxt(tum), _score(tum, store, results, monkeypatch, capsys))
    (est_vod, res_vod), (est_zero, res_zero) = found["vod"], found["zero"]
    np.testing.assert_allclose(est_vod[:, 0], StoreSequence(vod).stamps, rtol=0, atol=1e-6)
    np.testing.assert_allclose(est_vod[:, 0] - est_zero[:, 0], 1054.4, rtol=0, atol=1e-6)
    np.testing.assert_allclose(est_vod[:, 1:], est_zero[:, 1:], rtol=0, atol=1e-9)
    assert res_vod.frames_scored == res_zero.frames_scored == 40
    assert 0 < res_vod.relative(8.0).trans_m_mean < 0.05  # the ICP did register
    for length in (8.0, 16.0):
        a, b = res_vod.relative(length), res_zero.relative(length)
        assert a.n == b.n > 0
        assert a.trans_m_mean == pytest.approx(b.trans_m_mean, abs=1e-9)
        assert a.rot_deg_mean == pytest.approx(b.rot_deg_mean, abs=1e-9)
    assert res_vod.ape.trans_rmse_m == pytest.approx(res_zero.ape.trans_rmse_m, abs=1e-9)
