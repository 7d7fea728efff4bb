"""Tests for loaders.rosbag: a researcher's own ROS1 / ROS2 (sqlite3, mcap) bag, written with
rosbags' writers from frames whose truth is known; Doppler with its sign, GT from an Odometry
topic or a TUM / KITTI file with an extrinsic."""

import pickle

import numpy as np
import pytest

from helpers_bags import Motion, doppler_sign_cosine, make_truth, write_tum
from helpers_snail import write_ros1_odometry_bag, write_ros2_bag
from loaders.errors import DataError
from loaders.posefile import parse_extrinsic, write_kitti
from loaders.rosbag import Options, RosbagSequence
from loaders.trajectory import Trajectory

T_BS = parse_extrinsic("1.2 0.1 1.5 0.0087265 -0.0130896 0.0043633 0.9998719")
MOTION = Motion(T_body_sensor=T_BS)
STORAGES = ["ros1", "sqlite3", "mcap"]


@pytest.fixture(scope="module")
def truth():
    return make_truth(MOTION, frames=7, points=40, period=0.1)


def items(truth, sign=-1.0):
    """Clouds with fields x y z velocity power; velocity = sign * doppler (a driver that reports
    approach as positive when sign = -1)."""
    out = []
    for t, p, d, f in zip(truth.stamps, truth.points, truth.doppler, truth.fields, strict=True):
        arr = np.zeros(len(p), dtype=[(n, "<f4") for n in ("x", "y", "z", "velocity", "power")])
        arr["x"], arr["y"], arr["z"] = p.T
        arr["velocity"] = sign * d
        arr["power"] = f["power"]
        out.append((t, arr))
    return out


def gt_rows(truth, step=0.02):
    t = truth.stamps[0] - 0.2 + step * np.arange(int(round((truth.stamps[-1] - truth.stamps[0]
                                                            + 0.4) / step)) + 1)
    return t, MOTION.body_pose(t)


def write_bag(tmp, truth, storage, **kw):
    stamps, poses = gt_rows(truth)
    gt = ("/odom", stamps, poses)
    if storage == "ros1":
        return write_ros1_odometry_bag(tmp / "rec.bag", items(truth), "/radar/points", gt)
    return write_ros2_bag(tmp / f"rec_{storage}", items(truth), storage, gt=gt, **kw)


@pytest.fixture(scope="module", params=STORAGES)
def bag(request, tmp_path_factory, truth):
    return request.param, write_bag(tmp_path_factory.mktemp(request.param), truth, request.param)


OPTS = {"doppler_field": "velocity", "doppler_sign": -1, "T_body_sensor": "1.2 0.1 1.5 "
        "0.0087265 -0.0130896 0.0043633 0.9998719"}


def check(seq, truth):
    assert len(seq) == len(truth.stamps)
    np.testing.assert_allclose(seq.stamps, truth.stamps, atol=1e-6)
    for i in range(len(seq)):
        s = seq.scan(i)
        np.testing.assert_array_equal(s.points.astype(np.float32), truth.points[i])
        np.testing.assert_array_equal(s.doppler.astype(np.float32), truth.doppler[i])
        np.testing.assert_array_equal(s.fields["power"], truth.fields[i]["power"])


def test_points_doppler_sign_and_gt_topic(bag, truth):
    storage, path = bag
    seq = RosbagSequence(path, gt_topic="/odom", **OPTS)
    assert seq.provenance["format"] == ("ros1" if storage == "ros1" else "ros2")
    check(seq, truth)
    np.testing.assert_allclose(seq.ground_truth.stamps, seq.stamps)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-5)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, T_BS)
    assert seq.sensor.doppler_kind == "radial" and seq.sensor.period_s == pytest.approx(0.1)
    assert doppler_sign_cosine(seq) > 0.99
    assert doppler_sign_cosine(RosbagSequence(path, gt_topic="/odom",
                                              **{**OPTS, "doppler_sign": 1})) < -0.99
    seq.close()


def test_random_access_and_pickle(bag, truth):
    _, path = bag
    seq = RosbagSequence(path, **OPTS)
    for i in (5, 2, 3, 6, 0):
        np.testing.assert_array_equal(seq.scan(i).points.astype(np.float32), truth.points[i])
    clone = pickle.loads(pickle.dumps(seq))
    np.testing.assert_array_equal(clone.scan(4).doppler.astype(np.float32), truth.doppler[4])
    clone.close()
    seq.close()


@pytest.mark.parametrize("storage", ["ros1", "mcap"])
def test_gt_from_tum_and_kitti_files(tmp_path, truth, storage):
    path = write_bag(tmp_path, truth, storage)
    tum = tmp_path / "gt.txt"
    t, poses = gt_rows(truth, step=0.05)
    write_tum(tum, t, poses)
    seq = RosbagSequence(path, gt=tum, **OPTS)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=2e-3)
    kitti = tmp_path / "poses.txt"
    write_kitti(Trajectory(truth.stamps, MOTION.body_pose(truth.stamps)), kitti)
    seq = RosbagSequence(path, gt=kitti, **OPTS)
    np.testing.assert_allclose(seq.ground_truth.stamps, truth.stamps, atol=1e-6)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-6)
    # a KITTI file has no stamps: row k is scan k whatever the time offset (here 0.37 s: an
    # offset applied with the wrong sign would move every row 0.74 s off its scan)
    shifted = RosbagSequence(path, gt=kitti, time_offset_s=0.37, **OPTS)
    np.testing.assert_allclose(shifted.ground_truth.stamps, truth.stamps, atol=1e-6)
    np.testing.assert_allclose(shifted.ground_truth.poses, truth.sensor_poses(), atol=1e-6)
    assert shifted.provenance["gt_association"]["with_gt"] == len(truth.stamps)
    short = tmp_path / "short.txt"
    write_kitti(Trajectory(truth.stamps[:-2], MOTION.body_pose(truth.stamps[:-2])), short)
    with pytest.raises(DataError, match="5 KITTI pose rows but .* 7 scans") as err:
        RosbagSequence(path, gt=short, **OPTS)
    assert str(short) in str(err.value)


def test_ros2_pointcloud_channels(tmp_path, truth):
    path = write_ros2_bag(tmp_path / "pc1", items(truth, sign=1.0), "sqlite3",
                          kind="PointCloud")
    seq = RosbagSequence(path, doppler_field="velocity")
    assert seq.msgtype == "sensor_msgs/msg/PointCloud"
    check(seq, truth)


def test_bare_mcap_file_and_topic_autodetect(tmp_path, truth):
    folder = write_bag(tmp_path, truth, "mcap")
    mcap = next(folder.glob("*.mcap"))
    from loaders.registry import get_loader

    cls = get_loader("rosbag").load_class()
    assert cls is RosbagSequence and cls.Options is Options and cls.many_inputs
    seq = cls.open([mcap], Options(doppler_field="velocity", doppler_sign=-1,
                                              name="mine"))
    assert seq.topic == "/radar/points" and seq.name == "mine"
    check(seq, truth)


def test_missing_doppler_field_names_bag_and_fields(bag):
    storage, path = bag
    seq = RosbagSequence(path, doppler_field="doppler")
    with pytest.raises(DataError, match="no Doppler field 'doppler'") as err:
        seq.scan(0)
    assert str(path) in str(err.value) and "velocity" in str(err.value)


def test_bad_topic_and_gt_topic(bag):
    _, path = bag
    with pytest.raises(DataError, match="no topic /radar") as err:
        RosbagSequence(path, topic="/radar", **OPTS)
    assert "/radar/points" in str(err.value)
    with pytest.raises(DataError, match="has message type nav_msgs/msg/Odometry"):
        RosbagSequence(path, topic="/odom", **OPTS)
    with pytest.raises(DataError, match="no ground-truth topic /gt"):
        RosbagSequence(path, gt_topic="/gt", **OPTS)
    with pytest.raises(DataError, match="either as a file"):
        RosbagSequence(path, gt_topic="/odom", gt=path, **OPTS)


@pytest.mark.parametrize("name", ["junk.bag", "junk.mcap", "junk.db3"])
@pytest.mark.parametrize("topic", [None, "/radar/points"])
def test_not_a_bag(tmp_path, name, topic):
    junk = tmp_path / name
    junk.write_bytes(b"not a bag at all")
    with pytest.raises(DataError) as err:
        RosbagSequence(junk, topic=topic, **OPTS)
    assert str(junk) in str(err.value)


def test_store_round_trip_and_doppler_run_match_memory(tmp_path):
    """Synthetic radar frames in an mcap bag: the loader's store gives the same `doppler`
    odometry as the frames in memory."""
    from loaders.scan import MemorySequence
    from loaders.se3 import inv_T
    from loaders.store import StoreSequence, write_store
    from loaders.synthetic import SyntheticSequence
    from methods.registry import make_method

    syn = SyntheticSequence("loop", "radar-semidense", frames=6, seed=4, t0=1706001762.4)
    mem = MemorySequence(syn.name, syn.sensor, list(syn), syn.ground_truth)
    clouds = []
    for s in mem:
        arr = np.zeros(len(s), dtype=[(n, "<f4") for n in ("x", "y", "z", "doppler")])
        arr["x"], arr["y"], arr["z"] = s.points.T
        arr["doppler"] = s.doppler
        clouds.append((s.stamp, arr))
    path = write_ros2_bag(tmp_path / "syn", clouds, "mcap",
                          gt=("/gt", mem.stamps, mem.ground_truth.poses))
    loaded = RosbagSequence(path, gt_topic="/gt", model="radar-semidense")
    stored = StoreSequence(write_store(loaded, tmp_path / "syn.h5"))
    np.testing.assert_allclose(stored.ground_truth.poses, mem.ground_truth.poses, atol=1e-6)

    def steps(seq):
        res = make_method("doppler", {}, seq.sensor).run(seq, seed=True)
        return np.linalg.norm((inv_T(res.poses[:-1]) @ res.poses[1:])[:, :3, 3], axis=1)

    np.testing.assert_allclose(steps(stored), steps(mem), rtol=0.02)
    stored.close()


def test_unset_header_stamps_need_record_time(tmp_path, truth):
    path = write_ros2_bag(tmp_path / "zero", items(truth), "sqlite3", unset_header=True)
    with pytest.raises(DataError, match="distinct header stamps .* stamp='record'") as err:
        RosbagSequence(path, **OPTS)
    assert str(path) in str(err.value)
    seq = RosbagSequence(path, stamp="record", **OPTS)
    np.testing.assert_allclose(seq.stamps, truth.stamps + 0.003, atol=1e-6)
    check_points = seq.scan(3).points.astype(np.float32)
    np.testing.assert_array_equal(check_points, truth.points[3])


def test_options_from_strings_and_bad_values(bag):
    _, path = bag
    o = Options(doppler_field="velocity", doppler_sign="-1")
    assert o.doppler_sign == -1.0
    with pytest.raises(DataError, match="doppler_sign must be \\+1 or -1"):
        RosbagSequence(path, doppler_sign=0.5)
