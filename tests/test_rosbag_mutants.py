"""loaders.rosbag on tiny bags written here with rosbags' own writers (a few clouds of a few
points, in-process): random access in a ROS2 bag, the stamps, the fields by name, the ground
truth topics, the description of a bag `bench export` wrote, and one clear error for each bad
input (make mutate's survivors; the broad cases: test_loader_rosbag.py)."""

import re
import struct

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loaders.errors import DataError
from loaders.rosbag import (
    DESCRIPTION_TOPIC,
    Options,
    RosbagSequence,
    _cdr_header_stamp,
    bag_topics,
    described_options,
    read_description,
    read_gt_topic,
)

CLOUD2 = "sensor_msgs/msg/PointCloud2"
CLOUD1 = "sensor_msgs/msg/PointCloud"
ODOM = "nav_msgs/msg/Odometry"
POSE = "geometry_msgs/msg/PoseStamped"
POSE_COV = "geometry_msgs/msg/PoseWithCovarianceStamped"
STRING = "std_msgs/msg/String"


def typestore(ros1: bool):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def header(T, t: float, ros1: bool, frame: str = "radar"):
    sec = int(np.floor(t))
    stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)))
    if ros1:
        return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
    return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)


def cloud2(store, t, cols: dict[str, np.ndarray], ros1: bool):
    """A PointCloud2 of float32 fields ``cols`` (name -> values), packed at 4-byte steps."""
    T = store.types
    names = list(cols)
    arr = np.zeros(len(cols[names[0]]), dtype=[(n, "<f4") for n in names])
    for n in names:
        arr[n] = cols[n]
    PF = T["sensor_msgs/msg/PointField"]
    return T[CLOUD2](
        header=header(T, t, ros1), height=1, width=len(arr),
        fields=[PF(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate(names)],
        is_bigendian=False, point_step=4 * len(names), row_step=4 * len(names) * len(arr),
        data=np.frombuffer(arr.tobytes(), dtype=np.uint8), is_dense=True)


def cloud1(store, t, points: np.ndarray, channels: dict[str, np.ndarray], ros1: bool):
    T = store.types
    P32, CH = T["geometry_msgs/msg/Point32"], T["sensor_msgs/msg/ChannelFloat32"]
    return T[CLOUD1](
        header=header(T, t, ros1),
        points=[P32(x=float(x), y=float(y), z=float(z)) for x, y, z in points],
        channels=[CH(name=n, values=np.asarray(v, dtype=np.float32))
                  for n, v in channels.items()])


def pose_msg(store, msgtype, t, xyz, quat, ros1: bool):
    T = store.types
    pose = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
        orientation=T["geometry_msgs/msg/Quaternion"](x=quat[0], y=quat[1], z=quat[2],
                                                      w=quat[3]))
    h = header(T, t, ros1, "map")
    if msgtype == POSE:
        return T[POSE](header=h, pose=pose)
    with_cov = T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36))
    if msgtype == POSE_COV:
        return T[POSE_COV](header=h, pose=with_cov)
    zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    return T[ODOM](header=h, child_frame_id="base_link", pose=with_cov,
                   twist=T["geometry_msgs/msg/TwistWithCovariance"](
                       twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                       covariance=np.zeros(36)))


def write(path, topics, ros1: bool | None = None, storage: str = "sqlite3"):
    """A bag at ``path`` (ROS1 when it ends in .bag) of ``topics``: [(topic, msgtype,
    [(record time [s], message)])]."""
    ros1 = path.suffix == ".bag" if ros1 is None else ros1
    T = typestore(ros1)
    if ros1:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(path, version=9, storage_plugin=plugin)
    with writer as w:
        for topic, msgtype, msgs in topics:
            conn = w.add_connection(topic, msgtype, typestore=T)
            for t, msg in msgs:
                data = T.serialize_ros1(msg, msgtype) if ros1 else T.serialize_cdr(msg, msgtype)
                w.write(conn, int(round(t * 1e9)), data)
    return path


RNG = np.random.default_rng(7)
PTS = [RNG.uniform(-10, 10, (4, 3)) for _ in range(4)]
VEL = [RNG.uniform(-3, 3, 4) for _ in range(4)]


def xyzv(k: int, **extra) -> dict[str, np.ndarray]:
    p = PTS[k]
    return {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "velocity": VEL[k], **extra}


def cloud_bag(path, stamps, records=None, ros1=None, storage="sqlite3", extra=None):
    """Clouds of frame k = 0, 1, ... at header stamps ``stamps`` and record times
    ``records`` (default: the stamps + 3 ms)."""
    ros1 = path.suffix == ".bag" if ros1 is None else ros1
    T = typestore(ros1)
    records = [t + 0.003 for t in stamps] if records is None else records
    msgs = [(r, cloud2(T, t, xyzv(k, **(extra or {})), ros1))
            for k, (t, r) in enumerate(zip(stamps, records, strict=True))]
    return write(path, [("/radar", CLOUD2, msgs)], ros1, storage)


def f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


# -- stamps and random access ------------------------------------------------------------------

@pytest.mark.parametrize("name", ["rec.bag", "rec"])
def test_clouds_recorded_out_of_stamp_order_are_read_in_stamp_order(tmp_path, name):
    # frame k is at stamp s[k]; recorded in the order 2, 0, 3, 1 at times 1..4 s; frames 0
    # and 1 share record time 2 s
    stamps = [10.2, 10.0, 10.3, 10.1]
    path = cloud_bag(tmp_path / name, stamps, records=[3.0, 2.0, 4.0, 2.0])
    seq = RosbagSequence(path, doppler_field="velocity")
    try:
        np.testing.assert_allclose(seq.stamps, [10.0, 10.1, 10.2, 10.3], rtol=0, atol=1e-9)
        by_time = [1, 3, 0, 2]  # the frame at each sorted stamp
        for i in (2, 0, 3, 1, 1, 2, 3, 0):  # random order, repeats
            s = seq.scan(i)
            k = by_time[i]
            np.testing.assert_array_equal(s.points, f32(PTS[k]))
            np.testing.assert_array_equal(s.doppler, f32(VEL[k]))
            assert s.stamp == pytest.approx(stamps[k], abs=1e-9)
        assert [seq.scan(i).stamp for i in range(4)] == pytest.approx(sorted(stamps), abs=1e-9)
    finally:
        seq.close()
    assert seq.sensor.period_s == pytest.approx(0.1)


def test_ros2_messages_sharing_a_record_time_are_each_found_again(tmp_path):
    stamps = [1.0, 1.1, 1.2, 1.3]
    path = cloud_bag(tmp_path / "same", stamps, records=[5.0, 5.0, 5.0, 6.0])
    seq = RosbagSequence(path, doppler_field="velocity")
    try:
        for i in (2, 1, 0, 3, 2, 3, 0, 1, 2):
            np.testing.assert_array_equal(seq.scan(i).points, f32(PTS[i]))
    finally:
        seq.close()
    again = RosbagSequence(path, doppler_field="velocity")  # after close: opened again
    try:
        np.testing.assert_array_equal(again.scan(1).points, f32(PTS[1]))
        again.close()
        np.testing.assert_array_equal(again.scan(2).points, f32(PTS[2]))
    finally:
        again.close()


@pytest.mark.parametrize("name", ["r.bag", "r"])
def test_record_stamps_are_the_record_times(tmp_path, name):
    path = cloud_bag(tmp_path / name, [0.0, 0.0, 0.0], records=[2.5, 2.6, 2.75])
    seq = RosbagSequence(path, doppler_field="velocity", stamp="record")
    np.testing.assert_allclose(seq.stamps, [2.5, 2.6, 2.75], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(seq.scan(2).points, f32(PTS[2]))
    seq.close()


def test_a_repeated_header_stamp_drops_the_later_frame_with_a_warning(tmp_path):
    path = cloud_bag(tmp_path / "rep", [1.0, 1.1, 1.1, 1.2])
    with pytest.warns(UserWarning, match="1 scans with a repeated header stamp dropped"):
        seq = RosbagSequence(path, doppler_field="velocity")
    assert len(seq) == 3 and seq.provenance["repeated_stamps_dropped"] == 1
    assert seq.provenance["messages"] == 4
    np.testing.assert_array_equal(seq.scan(2).points, f32(PTS[3]))
    seq.close()


def test_cdr_header_stamp_reads_either_byte_order():
    little = bytes([0, 1, 0, 0]) + struct.pack("<iI", 7, 250_000_000) + b"rest"
    big = bytes([0, 0, 0, 0]) + struct.pack(">iI", 7, 250_000_000)
    assert _cdr_header_stamp(little) == pytest.approx(7.25, abs=1e-12)
    assert _cdr_header_stamp(big) == pytest.approx(7.25, abs=1e-12)
    assert _cdr_header_stamp(bytes([0, 1, 0, 0]) + struct.pack("<iI", -3, 5)) == \
        pytest.approx(-3 + 5e-9, abs=1e-15)
    assert np.isnan(_cdr_header_stamp(b"\x00\x01\x00\x00" + b"\x00" * 7))


def test_one_cloud_has_the_default_period_and_the_bags_stem_as_name(tmp_path):
    seq = RosbagSequence(cloud_bag(tmp_path / "drive_7.bag", [3.0]), doppler_field="velocity")
    assert seq.name == "drive_7" and len(seq) == 1
    assert seq.sensor.period_s == 0.1  # no step between stamps: the default
    seq.close()


# -- fields -------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["f.bag", "f"])
def test_fields_by_name_lowercased_and_clashes_renamed(tmp_path, name):
    extra = {"Power": np.arange(4.0), "power": 10 + np.arange(4.0), "Doppler": -np.ones(4),
             "X": 5 * np.ones(4)}
    path = cloud_bag(tmp_path / name, [1.0, 1.1], extra=extra)
    seq = RosbagSequence(path, doppler_field="velocity", doppler_sign=-1)
    s = seq.scan(1)
    assert sorted(s.fields) == ["field_doppler", "field_power", "field_x", "power"]
    np.testing.assert_array_equal(s.fields["power"], np.arange(4.0))  # the first of the name
    np.testing.assert_array_equal(s.fields["field_power"], 10 + np.arange(4.0))
    np.testing.assert_array_equal(s.fields["field_doppler"], -np.ones(4))
    np.testing.assert_array_equal(s.fields["field_x"], 5 * np.ones(4))
    assert s.fields["power"].dtype == np.float32
    np.testing.assert_array_equal(s.doppler, -f32(VEL[1]))  # the sign applied
    np.testing.assert_array_equal(s.points, f32(PTS[1]))
    seq.close()


def test_scans_without_doppler_keep_the_velocity_as_a_field(tmp_path):
    seq = RosbagSequence(cloud_bag(tmp_path / "n.bag", [1.0, 1.1]), doppler_field="none")
    s = seq.scan(0)
    assert s.doppler is None and sorted(s.fields) == ["velocity"]
    np.testing.assert_array_equal(s.fields["velocity"], f32(VEL[0]))
    assert seq.provenance["doppler_field"] == "none"
    seq.close()


def test_a_cloud_without_z_names_the_missing_field(tmp_path):
    T = typestore(False)
    msgs = [(1.0, cloud2(T, 1.0, {"x": np.ones(2), "y": np.ones(2), "v": np.ones(2)}, False))]
    path = write(tmp_path / "noz", [("/radar", CLOUD2, msgs)], False)
    seq = RosbagSequence(path, doppler_field="v")
    with pytest.raises(DataError, match=r"no z field\(s\); fields are x y v$") as err:
        seq.scan(0)
    assert str(path) in str(err.value) and "(frame 0)" in str(err.value)
    seq.close()


def test_a_missing_doppler_field_says_how_to_name_it(tmp_path):
    seq = RosbagSequence(cloud_bag(tmp_path / "m.bag", [1.0]))
    with pytest.raises(DataError, match="no Doppler field 'doppler'; the sensor_msgs/msg/"
                       "PointCloud2 has x y z velocity \\(name it with --doppler-field, option "
                       "doppler_field; --doppler-field none: scans without Doppler\\)"):
        seq.scan(0)
    seq.close()


@pytest.mark.parametrize("ros1", [True, False])
def test_pointcloud_channels_are_fields_the_first_of_a_name_kept(tmp_path, ros1):
    T = typestore(ros1)
    pts = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [-1.0, 0.5, 2.0]])
    chans = {"velocity": np.array([0.5, -1.0, 2.0]), "power": np.array([1.0, 2.0, 3.0])}
    msg = cloud1(T, 2.0, pts, chans, ros1)
    msg.channels.append(T.types["sensor_msgs/msg/ChannelFloat32"](
        name="power", values=np.array([9.0, 9.0, 9.0], dtype=np.float32)))
    path = write(tmp_path / ("p.bag" if ros1 else "p"), [("/pc", CLOUD1, [(2.0, msg)])], ros1)
    seq = RosbagSequence(path, doppler_field="velocity")
    s = seq.scan(0)
    np.testing.assert_array_equal(s.points, pts)
    np.testing.assert_array_equal(s.doppler, chans["velocity"])
    assert list(s.fields) == ["power"]
    np.testing.assert_array_equal(s.fields["power"], chans["power"])
    seq.close()


def test_a_ros2_channel_of_the_wrong_length_is_refused(tmp_path):
    T = typestore(False)
    msg = cloud1(T, 2.0, np.ones((3, 3)), {"velocity": np.ones(3), "power": np.ones(2)}, False)
    path = write(tmp_path / "bad", [("/pc", CLOUD1, [(2.0, msg)])], False)
    seq = RosbagSequence(path, doppler_field="velocity")
    with pytest.raises(DataError, match="channel 'power' has 2 values for 3 points; expected "
                       "one per point"):
        seq.scan(0)
    seq.close()


# -- ground truth topics -----------------------------------------------------------------------

POSES_T = [5.2, 5.0, 5.1]  # recorded out of stamp order
XYZ = np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.5, 0.0]])
ROTVEC = np.array([[0, 0, 0.2], [0, 0, 0.0], [0.1, 0, 0.1]])


def gt_bag(path, msgtype, scale=1.0, ros1=None):
    ros1 = path.suffix == ".bag" if ros1 is None else ros1
    T = typestore(ros1)
    msgs = []
    for k, t in enumerate(POSES_T):
        q = Rotation.from_rotvec(ROTVEC[k]).as_quat() * scale
        msgs.append((1.0 + k, pose_msg(T, msgtype, t, XYZ[k], q, ros1)))
    return write(path, [("/gt", msgtype, msgs)], ros1)


@pytest.mark.parametrize("msgtype", [ODOM, POSE, POSE_COV])
@pytest.mark.parametrize("name", ["g.bag", "g"])
def test_a_pose_topic_is_read_sorted_by_header_stamp(tmp_path, msgtype, name):
    path = gt_bag(tmp_path / name, msgtype, scale=1.0004)  # within 1e-3 of unit: normalised
    traj = read_gt_topic([path], "/gt")
    np.testing.assert_allclose(traj.stamps, [5.0, 5.1, 5.2], rtol=0, atol=1e-9)
    for row, k in enumerate((1, 2, 0)):
        np.testing.assert_allclose(traj.poses[row][:3, 3], XYZ[k], atol=1e-12)
        np.testing.assert_allclose(traj.poses[row][:3, :3],
                                   Rotation.from_rotvec(ROTVEC[k]).as_matrix(), atol=1e-12)


def test_a_pose_topic_with_a_quaternion_not_of_unit_length_is_refused(tmp_path):
    path = gt_bag(tmp_path / "q", ODOM, scale=1.002)
    with pytest.raises(DataError, match=r", /gt pose 0: orientation quaternion is not unit "
                       r"length \(norm 1.0020\)") as err:
        read_gt_topic([path], "/gt")
    assert str(path) in str(err.value)
    path = gt_bag(tmp_path / "q2", ODOM, scale=0.998)
    with pytest.raises(DataError, match=r"norm 0.9980"):
        read_gt_topic([path], "/gt")


def test_pose_topic_errors_name_the_topic_and_what_is_there(tmp_path):
    path = gt_bag(tmp_path / "e", POSE)
    with pytest.raises(DataError, match=r"no ground-truth topic /odom; the bag has /gt "
                       r"\(geometry_msgs/msg/PoseStamped\)"):
        read_gt_topic([path], "/odom")
    with pytest.raises(DataError, match="no reference topic /odom"):
        read_gt_topic([path], "/odom", what="reference")
    clouds = cloud_bag(tmp_path / "c", [1.0])
    with pytest.raises(DataError, match="ground-truth topic /radar has type sensor_msgs/msg/"
                       "PointCloud2; expected one of nav_msgs/msg/Odometry, geometry_msgs/msg/"
                       "PoseStamped, geometry_msgs/msg/PoseWithCovarianceStamped"):
        read_gt_topic([clouds], "/radar")
    empty = write(tmp_path / "empty", [("/gt", ODOM, [])], False)
    with pytest.raises(DataError, match="ground-truth topic /gt has no messages"):
        read_gt_topic([empty], "/gt")


def test_gt_topic_of_the_bag_gives_sensor_poses_with_the_extrinsic(tmp_path):
    T = typestore(False)
    stamps = [5.0, 5.1, 5.2]
    clouds = [(t, cloud2(T, t, xyzv(k), False)) for k, t in enumerate(stamps)]
    poses = [(t, pose_msg(T, ODOM, t, [t, 0.0, 0.0], [0, 0, 0, 1], False)) for t in stamps]
    path = write(tmp_path / "b", [("/radar", CLOUD2, clouds), ("/odom", ODOM, poses)], False)
    seq = RosbagSequence(path, doppler_field="velocity", gt_topic="/odom",
                         T_body_sensor="0 1 0 0 0 0 1")
    # T_world_sensor = T_world_body @ T_body_sensor: x = t, y = 1
    np.testing.assert_allclose(seq.ground_truth.poses[:, :3, 3],
                               [[t, 1.0, 0.0] for t in stamps], atol=1e-9)
    assert seq.provenance["gt_association"]["with_gt"] == 3
    seq.close()


# -- the description of a bag bench export wrote ------------------------------------------------

def described_bag(path, text, topic=DESCRIPTION_TOPIC):
    T = typestore(False)
    msgs = [] if text is None else [(0.5, T.types[STRING](data=text))]
    clouds = [(t, cloud2(T, t, xyzv(k), False)) for k, t in enumerate([1.0, 1.1])]
    return write(path, [("/radar", CLOUD2, clouds), (topic, STRING, msgs)], False)


def test_a_description_that_is_no_json_object_is_ignored_with_a_warning(tmp_path):
    for k, text in enumerate(("[1, 2]", "not json", "")):
        path = described_bag(tmp_path / f"d{k}", text)
        with pytest.warns(UserWarning, match=f"{DESCRIPTION_TOPIC} is not a JSON object; "
                          "ignored"):
            assert read_description([path]) is None
    assert read_description([described_bag(tmp_path / "none", None)]) is None
    assert read_description([described_bag(tmp_path / "other", "{}", "/x")]) is None
    assert read_description([described_bag(tmp_path / "obj", '{"a": 1}')]) == {"a": 1}


def test_a_described_bag_reads_with_the_descriptions_options(tmp_path):
    text = ('{"points_topic": "/radar", "fields": ["x", "y", "z", "velocity"], '
            '"sensor_kind": "lidar", "sensor_model": "m1", "doppler_kind": "ego-compensated", '
            '"sequence": "seq9"}')
    path = described_bag(tmp_path / "desc", text)
    seq = RosbagSequence(path)
    assert (seq.name, seq.sensor.kind, seq.sensor.model, seq.sensor.doppler_kind) == (
        "seq9", "lidar", "m1", "ego-compensated")
    assert seq.provenance["description"] == DESCRIPTION_TOPIC
    assert seq.scan(0).doppler is None  # no "doppler" among its fields
    plain = RosbagSequence(cloud_bag(tmp_path / "plain", [1.0]), doppler_field="velocity")
    assert plain.provenance["description"] is None
    seq.close()
    plain.close()


T4 = [[1.0, 0, 0, 0.5], [0, 1.0, 0, -0.25], [0, 0, 1.0, 2.0], [0, 0, 0, 1.0]]
FULL = {"points_topic": "/p", "ground_truth_topic": "/g", "T_body_sensor": T4,
        "sensor_kind": "lidar", "sensor_model": "m", "doppler_kind": "ego-compensated",
        "fields": ["x", "y", "z", "doppler"], "sequence": "s"}
TOPICS = {"/p": CLOUD2, "/g": ODOM}


def test_described_options_take_every_value_not_given():
    o = described_options(Options(), FULL, TOPICS)
    assert (o.topic, o.gt_topic, o.sensor_kind, o.model, o.doppler_kind, o.doppler_field,
            o.name) == ("/p", "/g", "lidar", "m", "ego-compensated", "doppler", "s")
    assert o.T_body_sensor.split() == ["1", "0", "0", "0.5", "0", "1", "0", "-0.25", "0", "0",
                                       "1", "2", "0", "0", "0", "1"]


def test_described_options_given_options_win_and_bad_values_are_skipped():
    given = Options(topic="/q", gt_topic="/h", sensor_kind="radar", model="mine",
                    doppler_kind="radial", doppler_field="v", name="n", T_body_sensor="0 0 0")
    assert described_options(given, FULL, TOPICS).model_dump() == given.model_dump()
    with_file = described_options(Options(gt="poses.txt"), FULL, TOPICS)
    assert with_file.gt_topic is None and str(with_file.gt) == "poses.txt"
    bad = {"points_topic": "/missing", "ground_truth_topic": "/missing", "T_body_sensor":
           [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]], "sensor_kind": "sonar", "sensor_model": 3,
           "doppler_kind": "gt-reconstructed", "fields": "x y z", "sequence": ""}
    o = Options()
    assert described_options(o, bad, TOPICS) is o
    assert described_options(o, {"T_body_sensor": "1 0 0"}, TOPICS) is o
    assert described_options(o, {"fields": ["x", "y", "z"]}, TOPICS).doppler_field == "none"


# -- one clear error for each bad input ----------------------------------------------------------

def test_bad_inputs_give_one_clear_error(tmp_path):
    with pytest.raises(DataError, match="^rosbag: no bag given$"):
        RosbagSequence([])
    missing = tmp_path / "gone.bag"
    with pytest.raises(DataError, match="gone.bag: bag not found$"):
        RosbagSequence(missing)
    a, b = cloud_bag(tmp_path / "a", [1.0]), cloud_bag(tmp_path / "b", [1.0])
    with pytest.raises(DataError, match="give several ROS1 .bag files or exactly one ROS2 bag"):
        RosbagSequence([a, b])
    with pytest.raises(DataError, match="(?s)^rosbag options: .*sensor_kind"):
        RosbagSequence(a, sensor_kind="sonar")
    with pytest.raises(DataError, match="nope.txt: ground-truth file not found$"):
        RosbagSequence(a, doppler_field="velocity", gt=tmp_path / "nope.txt")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"junk")
    with pytest.raises(DataError, match="junk.bag: cannot open the bag .*expected ROS1 .bag "
                       "file\\(s\\) or one ROS2 bag"):
        bag_topics([junk])


def test_two_ros1_bags_are_one_recording_in_time_order(tmp_path):
    a = cloud_bag(tmp_path / "a.bag", [1.2, 1.3])
    b = cloud_bag(tmp_path / "b.bag", [1.0, 1.1])
    seq = RosbagSequence([a, b], doppler_field="velocity")
    np.testing.assert_allclose(seq.stamps, [1.0, 1.1, 1.2, 1.3], atol=1e-9)
    assert seq.provenance["bags"] == [str(a), str(b)] and seq.provenance["format"] == "ros1"
    assert seq.name == "a"
    seq.close()


def test_a_bag_of_several_or_no_cloud_topics_asks_for_the_topic(tmp_path):
    T = typestore(False)
    one = [(1.0, cloud2(T, 1.0, xyzv(0), False))]
    two = write(tmp_path / "two", [("/b", CLOUD2, one), ("/a", CLOUD2, one)], False)
    with pytest.raises(DataError, match=r": 2 PointCloud2 / PointCloud topics; choose one with "
                       r"--topic \(the bag has /a \(sensor_msgs/msg/PointCloud2\), /b "
                       r"\(sensor_msgs/msg/PointCloud2\)\)"):
        RosbagSequence(two)
    seq = RosbagSequence(two, topic="/b", doppler_field="velocity")
    assert seq.topic == "/b" and seq.provenance["topic"] == "/b"
    seq.close()
    none = gt_bag(tmp_path / "none", ODOM)
    with pytest.raises(DataError, match=r"0 PointCloud2 / PointCloud topics; choose one with "
                       r"--topic \(the bag has /gt \(nav_msgs/msg/Odometry\)\)"):
        RosbagSequence(none)


def test_ros2_topic_errors_name_the_topic_and_the_types(tmp_path):
    path = gt_bag(tmp_path / "g", ODOM)
    with pytest.raises(DataError, match=r": no topic /radar; the bag has /gt "
                       r"\(nav_msgs/msg/Odometry\)$"):
        RosbagSequence(path, topic="/radar")
    with pytest.raises(DataError, match="topic /gt has message type nav_msgs/msg/Odometry; "
                       "expected one of sensor_msgs/msg/PointCloud2, sensor_msgs/msg/PointCloud$"):
        RosbagSequence(path, topic="/gt")
    empty = write(tmp_path / "e", [("/radar", CLOUD2, [])], False)
    with pytest.raises(DataError, match="topic /radar has no messages$"):
        RosbagSequence(empty, topic="/radar")


def test_the_provenance_records_how_the_bag_was_read(tmp_path):
    path = cloud_bag(tmp_path / "pv", [1.0, 1.1, 1.2])
    seq = RosbagSequence(path, doppler_field="velocity", doppler_sign=-1,
                         T_body_sensor="1 2 3 0 0 0 1")
    p = seq.provenance
    assert {k: p[k] for k in ("loader", "bags", "format", "topic", "msgtype", "doppler_field",
                              "doppler_sign", "stamp", "messages", "repeated_stamps_dropped",
                              "nan_points_dropped", "description")} == {
        "loader": "rosbag", "bags": [str(path)], "format": "ros2", "topic": "/radar",
        "msgtype": CLOUD2, "doppler_field": "velocity", "doppler_sign": -1.0,
        "stamp": "header", "messages": 3, "repeated_stamps_dropped": 0,
        "nan_points_dropped": 0, "description": None}
    want = np.eye(4)
    want[:3, 3] = [1, 2, 3]
    np.testing.assert_allclose(p["T_body_sensor"], want)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, want)
    assert seq.ground_truth is None and "gt_association" not in p
    seq.close()


# -- make mutate's survivors of the first run ------------------------------------------------

@pytest.mark.parametrize("name", ["bad.bag", "bad"])
def test_a_malformed_cloud_names_the_bag_and_the_frame(tmp_path, name):
    """A PointField of unknown datatype (ROS1 and ROS2) and a ROS1 PointCloud channel of the
    wrong length: one error naming the bag, the topic message and the frame."""
    ros1 = name.endswith(".bag")
    T = typestore(ros1)
    msg = cloud2(T, 1.0, xyzv(0), ros1)
    msg.fields[3].datatype = 42
    path = write(tmp_path / name, [("/radar", CLOUD2, [(1.0, msg)])], ros1)
    seq = RosbagSequence(path, doppler_field="velocity")
    with pytest.raises(DataError, match="PointField 'velocity' has unknown datatype 42") as err:
        seq.scan(0)
    assert str(path) in str(err.value) and "/radar message 0 (frame 0)" in str(err.value)
    seq.close()
    if ros1:
        pc = cloud1(T, 2.0, np.ones((3, 3)), {"velocity": np.ones(3), "power": np.ones(2)}, True)
        path = write(tmp_path / "pc.bag", [("/pc", CLOUD1, [(2.0, pc)])], True)
        seq = RosbagSequence(path, doppler_field="velocity")
        with pytest.raises(DataError, match="channel 'power' has 2 values for 3 points") as err:
            seq.scan(0)
        assert str(path) in str(err.value) and "(frame 0)" in str(err.value)
        seq.close()


def test_open_from_loader_options_takes_the_description_for_what_is_not_given(tmp_path):
    text = '{"points_topic": "/radar", "fields": ["x", "y", "z"], "sequence": "seq9"}'
    path = described_bag(tmp_path / "desc", text)
    seq = RosbagSequence.open([path], Options())
    assert seq.name == "seq9" and seq.topic == "/radar" and seq.options.doppler_field == "none"
    seq.close()
    named = RosbagSequence.open([path], Options(name="mine"))
    assert named.name == "mine"
    named.close()


def test_errors_about_several_bags_name_each_bag(tmp_path):
    a, b = cloud_bag(tmp_path / "a.bag", [1.0]), cloud_bag(tmp_path / "b.bag", [1.1])
    # the topic both bags have is named once
    with pytest.raises(DataError, match=f"^{re.escape(f'{a}, {b}')}: no ground-truth topic "
                       r"/odom; the bag has /radar \(sensor_msgs/msg/PointCloud2\)$"):
        read_gt_topic([a, b], "/odom")
    c, d = cloud_bag(tmp_path / "c", [1.0]), cloud_bag(tmp_path / "d", [1.0])
    with pytest.raises(DataError, match=f"^{re.escape(f'{c}, {d}')}: give several ROS1 .bag "
                       "files or exactly one ROS2 bag$"):
        RosbagSequence([c, d])
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"junk")
    with pytest.raises(DataError, match=f"^{re.escape(f'{a}, {junk}')}: cannot open the bag"):
        bag_topics([a, junk])


@pytest.mark.parametrize("name", ["empty.bag", "empty"])
def test_a_missing_pose_topic_lists_every_topic_or_says_there_is_none(tmp_path, name):
    empty = write(tmp_path / name, [], name.endswith(".bag"))
    with pytest.raises(DataError, match="no ground-truth topic /gt; the bag has no topics$"):
        read_gt_topic([empty], "/gt")
    path = described_bag(tmp_path / "two", "{}")
    with pytest.raises(DataError, match=r"no ground-truth topic /gt; the bag has "
                       r"/doppler_bench/description \(std_msgs/msg/String\), /radar "
                       r"\(sensor_msgs/msg/PointCloud2\)$"):
        read_gt_topic([path], "/gt")


def test_the_first_pose_off_unit_length_in_stamp_order_is_named(tmp_path):
    T = typestore(False)
    msgs = []
    for k, (t, scale) in enumerate(zip(POSES_T, (1.0, 1.0, 1.01), strict=True)):
        q = Rotation.from_rotvec(ROTVEC[k]).as_quat() * scale
        msgs.append((1.0 + k, pose_msg(T, ODOM, t, XYZ[k], q, False)))
    path = write(tmp_path / "q", [("/gt", ODOM, msgs)], False)
    # the third recorded pose has stamp 5.1 s: row 1 in stamp order
    with pytest.raises(DataError, match=r"/gt pose 1: orientation quaternion is not unit length "
                       r"\(norm 1.0100\)"):
        read_gt_topic([path], "/gt")


def test_a_ros2_bag_changed_after_its_index_is_one_clear_error(tmp_path):
    import shutil

    path = cloud_bag(tmp_path / "ch", [1.0, 1.1, 1.2])
    seq = RosbagSequence(path, doppler_field="velocity")
    shutil.rmtree(path)
    cloud_bag(path, [1.0])  # one message where the index has three
    with pytest.raises(DataError, match=r"ch, /radar message 2: message missing on re-reading "
                       "the bag$"):
        seq.scan(2)
    seq.close()


def test_frames_read_in_order_continue_one_read_of_the_ros2_bag(tmp_path, monkeypatch):
    from rosbags.rosbag2 import Reader

    path = cloud_bag(tmp_path / "ord", [1.0, 1.1, 1.2, 1.3], records=[2.0, 2.0, 3.0, 4.0])
    seq = RosbagSequence(path, doppler_field="velocity")
    reads = []
    messages = Reader.messages

    def counted(self, *args, **kwargs):
        reads.append(kwargs.get("start"))
        return messages(self, *args, **kwargs)

    monkeypatch.setattr(Reader, "messages", counted)
    for i in range(4):
        np.testing.assert_array_equal(seq.scan(i).points, f32(PTS[i]))
    assert len(reads) == 1  # one read from the first frame on
    np.testing.assert_array_equal(seq.scan(1).points, f32(PTS[1]))  # back: read again
    assert len(reads) == 2 and reads[1] == 2 * 10**9
    seq.close()


@pytest.mark.parametrize("name", ["be.bag", "be"])
def test_a_big_endian_cloud_reads_the_same_values(tmp_path, name):
    ros1 = name.endswith(".bag")
    T = typestore(ros1)
    cols = xyzv(2)
    msg = cloud2(T, 1.0, cols, ros1)
    big = np.zeros(4, dtype=[(n, ">f4") for n in cols])
    for n in cols:
        big[n] = cols[n]
    msg.is_bigendian = True
    msg.data = np.frombuffer(big.tobytes(), dtype=np.uint8)
    path = write(tmp_path / name, [("/radar", CLOUD2, [(1.0, msg)])], ros1)
    seq = RosbagSequence(path, doppler_field="velocity")
    s = seq.scan(0)
    np.testing.assert_array_equal(s.points, f32(PTS[2]))
    np.testing.assert_array_equal(s.doppler, f32(VEL[2]))
    seq.close()


def test_a_ros2_cloud_that_does_not_deserialize_names_the_frame(tmp_path):
    from rosbags.rosbag2 import Writer

    T = typestore(False)
    good = T.serialize_cdr(cloud2(T, 1.0, xyzv(0), False), CLOUD2)
    path = tmp_path / "cut"
    with Writer(path, version=9) as w:
        conn = w.add_connection("/radar", CLOUD2, typestore=T)
        w.write(conn, 10**9, bytes(good[:40]))  # the header, then cut short
    seq = RosbagSequence(path, doppler_field="velocity")
    with pytest.raises(DataError, match=r"cut, /radar message 0 \(frame 0\): cannot deserialize "
                       r"sensor_msgs/msg/PointCloud2 \("):
        seq.scan(0)
    seq.close()


def test_a_cloud_without_y_and_z_names_both(tmp_path):
    T = typestore(False)
    msgs = [(1.0, cloud2(T, 1.0, {"x": np.ones(2), "v": np.ones(2)}, False))]
    seq = RosbagSequence(write(tmp_path / "xy", [("/radar", CLOUD2, msgs)], False),
                         doppler_field="v")
    with pytest.raises(DataError, match=r"no y, z field\(s\); fields are x v$"):
        seq.scan(0)
    seq.close()


def test_fields_named_like_the_coordinates_in_capitals_are_renamed(tmp_path):
    extra = {"Y": np.full(4, 2.0), "Z": np.full(4, 3.0)}
    seq = RosbagSequence(cloud_bag(tmp_path / "yz", [1.0], extra=extra),
                         doppler_field="velocity")
    s = seq.scan(0)
    assert sorted(s.fields) == ["field_y", "field_z"]
    np.testing.assert_array_equal(s.fields["field_y"], np.full(4, 2.0))
    np.testing.assert_array_equal(s.points, f32(PTS[0]))
    seq.close()


def test_a_float64_field_is_stored_as_float32(tmp_path):
    T = typestore(False)
    arr = np.zeros(2, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("v", "<f4"),
                             ("range", "<f8")])
    arr["x"], arr["range"] = [1.0, 2.0], [1.0 + 1e-12, 2.5]
    PF = T.types["sensor_msgs/msg/PointField"]
    msg = T.types[CLOUD2](
        header=header(T.types, 1.0, False), height=1, width=2,
        fields=[PF(name=n, offset=4 * i, datatype=7, count=1) for i, n in
                enumerate("xyzv")] + [PF(name="range", offset=16, datatype=8, count=1)],
        is_bigendian=False, point_step=24, row_step=48,
        data=np.frombuffer(arr.tobytes(), dtype=np.uint8), is_dense=True)
    seq = RosbagSequence(write(tmp_path / "f8", [("/radar", CLOUD2, [(1.0, msg)])], False),
                         doppler_field="v")
    s = seq.scan(0)
    assert s.fields["range"].dtype == np.float32
    np.testing.assert_array_equal(s.fields["range"], np.array([1.0, 2.5], dtype=np.float32))
    seq.close()


def test_nan_points_are_dropped_counted_and_named(tmp_path):
    cols = xyzv(1)
    cols["x"] = cols["x"].copy()
    cols["x"][2] = np.nan
    T = typestore(False)
    path = write(tmp_path / "nan", [("/radar", CLOUD2, [(1.0, cloud2(T, 1.0, cols, False))])],
                 False)
    seq = RosbagSequence(path, doppler_field="velocity")
    with pytest.warns(UserWarning, match=r"nan, /radar message 0 \(frame 0\): dropped 1 of 4 "
                      "points"):
        s = seq.scan(0)
    assert len(s.points) == 3 and seq.provenance["nan_points_dropped"] == 1
    np.testing.assert_array_equal(s.points, f32(PTS[1])[[0, 1, 3]])
    seq.close()


def test_a_ros2_topic_index_names_what_it_cannot_open_or_find(tmp_path):
    from loaders.rosbag import CLOUD_TYPES, _Ros2Topic

    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a bag")
    with pytest.raises(DataError, match=r"junk.mcap: cannot open the ROS2 bag \(\w+Error: .*\); "
                       "expected a folder with metadata.yaml, a .db3 or a .mcap file$") as err:
        _Ros2Topic(junk, "/radar", CLOUD_TYPES)
    assert str(err.value).startswith(str(junk))
    empty = write(tmp_path / "empty", [], False)
    with pytest.raises(DataError, match="empty: no topic /radar; the bag has no topics$"):
        RosbagSequence(empty, topic="/radar")
    with pytest.raises(DataError, match=r"empty: 0 PointCloud2 / PointCloud topics; choose one "
                       r"with --topic \(the bag has no topics\)$"):
        RosbagSequence(empty)
    two = described_bag(tmp_path / "two", "{}")
    with pytest.raises(DataError, match=r"two: no topic /points; the bag has "
                       r"/doppler_bench/description \(std_msgs/msg/String\), /radar "
                       r"\(sensor_msgs/msg/PointCloud2\)$"):
        RosbagSequence(two, topic="/points")


def test_an_explicit_gt_format_is_read_as_given_not_detected(tmp_path):
    path = cloud_bag(tmp_path / "k", [1.0, 1.1, 1.2])
    tum = tmp_path / "gt.txt"
    tum.write_text("".join(f"{t} {k} 0 0 0 0 0 1\n" for k, t in enumerate((1.0, 1.1, 1.2))))
    seq = RosbagSequence(path, doppler_field="velocity", gt=tum)  # detected: TUM
    np.testing.assert_allclose(seq.ground_truth.poses[:, 0, 3], [0.0, 1.0, 2.0], atol=1e-9)
    seq.close()
    with pytest.raises(DataError, match="expected 12 values per KITTI row, got 8") as err:
        RosbagSequence(path, doppler_field="velocity", gt=tum, gt_format="kitti")
    assert str(tum) in str(err.value)


def test_a_kitti_file_of_another_length_says_it_needs_one_row_per_scan(tmp_path):
    path = cloud_bag(tmp_path / "k", [1.0, 1.1, 1.2])
    kitti = tmp_path / "poses.txt"
    kitti.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n" * 2)
    with pytest.raises(DataError, match=r"poses.txt: 2 KITTI pose rows but /radar has 3 scans; a "
                       "KITTI file has no stamps and needs exactly one row per scan$"):
        RosbagSequence(path, doppler_field="velocity", gt=kitti)


def test_the_association_report_names_the_ground_truth_source(tmp_path):
    stamps = (1.0, 1.1, 1.2)
    path = cloud_bag(tmp_path / "k", list(stamps))
    tum = tmp_path / "gt.txt"
    tum.write_text("".join(f"{t} {k} 0 0 0 0 0 1\n" for k, t in enumerate(stamps)))
    kitti = tmp_path / "poses.txt"
    kitti.write_text("".join(f"1 0 0 {k} 0 1 0 0 0 0 1 0\n" for k in range(3)))
    # a TUM file is interpolated at the scans; KITTI rows are the scans' own (1 us tolerance)
    for gt, mode, tolerance in ((tum, "interpolate", 0.0), (kitti, "nearest", 1e-6)):
        seq = RosbagSequence(path, doppler_field="velocity", gt=gt)
        report = seq.provenance["gt_association"]
        assert (report["gt_file"], report["mode"]) == (str(gt), mode)
        assert report["tolerance_s"] == tolerance and report["max_gap_s"] == 0.5
        np.testing.assert_allclose(seq.ground_truth.poses[:, 0, 3], [0.0, 1.0, 2.0], atol=1e-9)
        seq.close()
    with pytest.raises(DataError, match="expected 8 values"):  # told TUM: not read as KITTI
        RosbagSequence(path, doppler_field="velocity", gt=kitti, gt_format="tum")


def test_gt_given_twice_and_a_repeat_across_bags_are_said_plainly(tmp_path):
    a = cloud_bag(tmp_path / "a.bag", [1.0, 1.1])
    b = cloud_bag(tmp_path / "b.bag", [1.1, 1.2])
    with pytest.raises(DataError, match=r"^give the ground truth either as a file \(gt\) or as a "
                       r"topic \(gt_topic\), not both$"):
        RosbagSequence(a, doppler_field="velocity", gt=a, gt_topic="/odom")
    with pytest.warns(UserWarning, match=f"^{re.escape(f'{a}, {b}')}: 1 scans with a repeated "
                      "header stamp dropped"):
        seq = RosbagSequence([a, b], doppler_field="velocity")
    assert len(seq) == 3
    seq.close()


def test_a_ros2_message_too_short_for_a_header_is_named(tmp_path):
    from rosbags.rosbag2 import Writer

    T = typestore(False)
    path = tmp_path / "short"
    with Writer(path, version=9) as w:
        conn = w.add_connection("/radar", CLOUD2, typestore=T)
        w.write(conn, 10**9, T.serialize_cdr(cloud2(T, 1.0, xyzv(0), False), CLOUD2))
        w.write(conn, 2 * 10**9, b"\x00\x01\x00\x00\x05")
    with pytest.raises(DataError, match=r"short, /radar message 1: message too short for a "
                       r"std_msgs/Header stamp; is /radar a point cloud\?$"):
        RosbagSequence(path, doppler_field="velocity")


def test_the_gap_and_uncovered_options_reach_the_association(tmp_path):
    """GT at 1.0 and 2.0 s, scans at 0.9, 1.0, 1.5, 2.0 s: a 1 s gap is not bridged with the
    default largest gap 0.5 s, it is with 2 s; the scan before the GT is kept unscored, trimmed,
    or refused naming the bag and the GT file."""
    path = cloud_bag(tmp_path / "gap", [0.9, 1.0, 1.5, 2.0])
    tum = tmp_path / "gt.txt"
    tum.write_text("1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n")
    opts = {"doppler_field": "velocity", "gt": tum}
    with pytest.warns(UserWarning, match="2 of the 4 scans kept have no ground truth"):
        seq = RosbagSequence(path, **opts)
    np.testing.assert_allclose(seq.ground_truth.stamps, [1.0, 2.0], atol=1e-9)
    assert len(seq) == 4
    seq.close()
    with pytest.warns(UserWarning, match="1 scans before/after its span trimmed"):
        seq = RosbagSequence(path, max_gap_s=2.0, uncovered="trim", **opts)
    np.testing.assert_allclose(seq.ground_truth.stamps, [1.0, 1.5, 2.0], atol=1e-9)
    np.testing.assert_allclose(seq.ground_truth.poses[1][0, 3], 0.5, atol=1e-9)
    assert len(seq) == 3
    seq.close()
    with pytest.raises(DataError, match=f"^{re.escape(str(path))}, frame 0: scan stamp 0.900 s "
                       f"is not covered by {re.escape(str(tum))} "):
        RosbagSequence(path, uncovered="error", **opts)


def test_the_description_is_its_topics_first_message_whatever_comes_before(tmp_path):
    T = typestore(False)
    text = '{"points_topic": "/radar", "fields": ["x", "y", "z"], "sequence": "late"}'
    clouds = [(t, cloud2(T, t, xyzv(k), False)) for k, t in enumerate([1.0, 1.1])]
    path = write(tmp_path / "late", [("/radar", CLOUD2, clouds),
                                     (DESCRIPTION_TOPIC, STRING,
                                      [(5.0, T.types[STRING](data=text))])], False)
    assert read_description([path])["sequence"] == "late"
    seq = RosbagSequence(path, model="mine")  # an option given: the others still described
    assert (seq.name, seq.sensor.model, seq.options.doppler_field) == ("late", "mine", "none")
    seq.close()


def test_a_description_topic_of_another_type_is_ignored_with_a_warning(tmp_path):
    T = typestore(False)
    odom = pose_msg(T, ODOM, 1.0, [0.0, 0.0, 0.0], [0, 0, 0, 1], False)
    path = write(tmp_path / "odd", [(DESCRIPTION_TOPIC, ODOM, [(1.0, odom)])], False)
    with pytest.warns(UserWarning, match="is not a JSON object; ignored"):
        assert read_description([path]) is None


def test_a_bag_rosbags_cannot_open_names_rosbags_error(tmp_path):
    from rosbags.highlevel import AnyReader

    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"junk")
    try:
        AnyReader([junk]).open()
    except Exception as err:  # noqa: BLE001 - whatever rosbags raises is named
        name = type(err).__name__
    with pytest.raises(DataError, match=f"^{re.escape(str(junk))}: cannot open the bag \\({name}: "
                       ".*\\); expected ROS1 .bag file\\(s\\) or one ROS2 bag \\(folder with "
                       "metadata.yaml, .db3 or .mcap\\)$"):
        bag_topics([junk])
