"""bench.data.bag_messages: the messages `bench export` writes and its writer over rosbags,
read back with rosbags' own reader and checked against independent expectations (exact
nanosecond arithmetic with fractions, scipy's rotations, the ROS message definitions)
(make mutate's survivors)."""

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from strategies import examples

from bench.data.bag_messages import (
    CLOUD,
    ODOM,
    STRING,
    TF,
    BagWriter,
    _sec_nsec,
    cloud_msg,
    latched_qos,
    odometry_msg,
    tf_static_msg,
)

NS = 10**9


def exact_ns(t: float) -> int:
    """The nearest whole nanosecond of the exact binary value of ``t`` (ties to even, as
    Python rounds)."""
    return round(Fraction(t) * NS)


@pytest.mark.parametrize(("t", "want"), [
    (0.0, (0, 0)), (0.3, (0, 300_000_000)), (1.9999999999, (2, 0)),
    (-0.25, (-1, 750_000_000)), (7.0000000017, (7, 2)), (1654232000.25, (1654232000, 250_000_000)),
])
def test_sec_nsec_known_values(t, want):
    assert _sec_nsec(t) == want


@examples(40)
@given(st.floats(min_value=-1e6, max_value=2e9, allow_nan=False))
def test_sec_nsec_is_the_nearest_nanosecond_with_nsec_in_range(t):
    sec, nsec = _sec_nsec(t)
    assert 0 <= nsec < NS
    assert sec * NS + nsec == exact_ns(t)


def pose(rotvec, xyz) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = xyz
    return T


T_WB = pose([0.1, -0.2, 2.5], [10.0, -3.0, 0.5])
T_BS = pose([0.0, 0.02, -0.01], [1.2, 0.1, 1.5])
POINTS = np.array([[1.0, 2.0, 3.0], [-4.5, 0.25, 8.0], [30.0, -7.0, -1.5]])
VALUES = {"doppler": np.array([-1.5, 0.0, 2.25]), "power": np.array([10.0, 20.5, 0.125])}
STAMPS = (100.5, 100.6, 100.7, 100.8)


def write_all(path, fmt):
    """A bag of one of each message: tf (latched), description (latched), odometry, cloud."""
    bag = BagWriter(path, fmt)
    try:
        tf = bag.connection("/tf_static", TF, latched=True)
        info = bag.connection("/info", STRING, latched=True)
        odom = bag.connection("/gt", ODOM)
        cloud = bag.connection("/points", CLOUD)
        bag.write(tf, STAMPS[0], tf_static_msg(bag, STAMPS[0], T_BS, "base", "sens"))
        bag.write(info, STAMPS[1], bag.store.types[STRING](data="hello"))
        bag.write(odom, STAMPS[2], odometry_msg(bag, STAMPS[2], T_WB, "odom", "base"))
        bag.write(cloud, STAMPS[3], cloud_msg(bag, STAMPS[3], POINTS, VALUES, "sens"))
    finally:
        bag.close()
    return path


def read_all(path):
    """{topic: (connection, record time [ns], message)} read by rosbags."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        return {c.topic: (c, t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages()}


@pytest.fixture(params=["ros1", "ros2", "mcap"])
def fmt(request):
    return request.param


def bag_of(tmp_path, fmt):
    return write_all(tmp_path / ("b.bag" if fmt == "ros1" else "b"), fmt)


def assert_stamp(header, t):
    assert header.stamp.sec * NS + header.stamp.nanosec == exact_ns(t)


def test_record_times_and_header_stamps_are_the_stamps_to_the_nanosecond(tmp_path, fmt):
    msgs = read_all(bag_of(tmp_path, fmt))
    assert sorted(msgs) == ["/gt", "/info", "/points", "/tf_static"]
    for topic, t in zip(("/tf_static", "/info", "/gt", "/points"), STAMPS, strict=True):
        assert msgs[topic][1] == exact_ns(t)
    assert_stamp(msgs["/tf_static"][2].transforms[0].header, STAMPS[0])
    assert_stamp(msgs["/gt"][2].header, STAMPS[2])
    assert_stamp(msgs["/points"][2].header, STAMPS[3])
    assert msgs["/info"][2].data == "hello"


def test_the_cloud_is_packed_little_endian_float32_fields_by_name(tmp_path, fmt):
    msg = read_all(bag_of(tmp_path, fmt))["/points"][2]
    assert msg.header.frame_id == "sens"
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("doppler", 12, 7, 1),
        ("power", 16, 7, 1)]  # sensor_msgs/PointField FLOAT32 = 7
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 3, 20, 60)
    assert msg.is_bigendian is False and msg.is_dense is True
    rows = np.frombuffer(bytes(msg.data), dtype="<f4").reshape(3, 5)
    np.testing.assert_array_equal(rows[:, :3], POINTS.astype(np.float32))
    np.testing.assert_array_equal(rows[:, 3], VALUES["doppler"].astype(np.float32))
    np.testing.assert_array_equal(rows[:, 4], VALUES["power"].astype(np.float32))


def test_an_empty_cloud_has_no_points_and_the_same_fields(tmp_path):
    bag = BagWriter(tmp_path / "e.bag", "ros1")
    try:
        msg = cloud_msg(bag, 1.0, np.zeros((0, 3)), {}, "radar")
    finally:
        bag.close()
    assert [f.name for f in msg.fields] == ["x", "y", "z"]
    assert (msg.width, msg.point_step, msg.row_step, len(msg.data)) == (0, 12, 0, 0)


def rotation_of(q) -> np.ndarray:
    return Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()


def test_odometry_is_the_pose_in_its_frames_with_zero_twist_and_covariance(tmp_path, fmt):
    msg = read_all(bag_of(tmp_path, fmt))["/gt"][2]
    assert (msg.header.frame_id, msg.child_frame_id) == ("odom", "base")
    p = msg.pose.pose.position
    np.testing.assert_allclose([p.x, p.y, p.z], T_WB[:3, 3], atol=1e-12)
    np.testing.assert_allclose(rotation_of(msg.pose.pose.orientation), T_WB[:3, :3], atol=1e-12)
    assert msg.pose.pose.orientation.w >= 0
    tw = msg.twist.twist
    assert [tw.linear.x, tw.linear.y, tw.linear.z, tw.angular.x, tw.angular.y,
            tw.angular.z] == [0.0] * 6
    np.testing.assert_array_equal(msg.pose.covariance, np.zeros(36))
    np.testing.assert_array_equal(msg.twist.covariance, np.zeros(36))


def test_tf_static_is_one_transform_body_to_sensor(tmp_path, fmt):
    msg = read_all(bag_of(tmp_path, fmt))["/tf_static"][2]
    (tf,) = msg.transforms
    assert (tf.header.frame_id, tf.child_frame_id) == ("base", "sens")
    tr = tf.transform.translation
    np.testing.assert_allclose([tr.x, tr.y, tr.z], T_BS[:3, 3], atol=1e-12)
    np.testing.assert_allclose(rotation_of(tf.transform.rotation), T_BS[:3, :3], atol=1e-12)


def test_ros1_headers_count_up_by_one_in_write_order(tmp_path):
    msgs = read_all(bag_of(tmp_path, "ros1"))
    seqs = [msgs["/tf_static"][2].transforms[0].header.seq, msgs["/gt"][2].header.seq,
            msgs["/points"][2].header.seq]
    assert seqs == [seqs[0], seqs[0] + 1, seqs[0] + 2] and seqs[0] >= 0


def test_ros1_latches_tf_static_and_the_description_only(tmp_path):
    msgs = read_all(bag_of(tmp_path, "ros1"))
    latching = {topic: c.ext.latching or 0 for topic, (c, _, _) in msgs.items()}
    assert latching == {"/tf_static": 1, "/info": 1, "/gt": 0, "/points": 0}


def test_rosbag2_offers_latched_topics_as_transient_local_depth_one(tmp_path, fmt):
    if fmt == "ros1":
        return
    from rosbags.interfaces import QosDurability, QosHistory, QosLiveliness, QosReliability

    msgs = read_all(bag_of(tmp_path, fmt))
    for topic in ("/tf_static", "/info"):
        (qos,) = msgs[topic][0].ext.offered_qos_profiles
        assert (qos.history, qos.depth, qos.reliability, qos.durability, qos.liveliness) == (
            QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
            QosLiveliness.AUTOMATIC)
        assert qos.avoid_ros_namespace_conventions is False
        for time in (qos.deadline, qos.lifespan, qos.liveliness_lease_duration):
            assert (time.sec, time.nsec) == (0, 0)
    for topic in ("/gt", "/points"):
        assert msgs[topic][0].ext.offered_qos_profiles == []


def test_latched_qos_is_the_tf_static_publishers_profile():
    from rosbags.interfaces import QosDurability, QosHistory, QosReliability

    qos = latched_qos()
    assert (qos.history, qos.depth) == (QosHistory.KEEP_LAST, 1)
    assert qos.reliability == QosReliability.RELIABLE
    assert qos.durability == QosDurability.TRANSIENT_LOCAL


@pytest.mark.parametrize(("fmt", "storage", "suffix"), [("ros2", "sqlite3", ".db3"),
                                                         ("mcap", "mcap", ".mcap")])
def test_rosbag2_storage_is_the_formats(tmp_path, fmt, storage, suffix):
    import yaml

    bag = bag_of(tmp_path, fmt)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == storage
    assert [p.suffix for p in bag.iterdir() if p.name != "metadata.yaml"] == [suffix]
    assert meta["message_count"] == 4


def test_a_bag_is_written_only_to_a_new_path(tmp_path):
    from loaders.errors import DataError

    path = tmp_path / "x.bag"
    path.write_text("mine")
    with pytest.raises(DataError, match="exists; a bag is written only to a new path"):
        BagWriter(path, "ros1")
    assert path.read_text() == "mine"
