"""The ROS messages of ``bench export`` and one writer over rosbags' ROS1 and rosbag2 writers
(ROS1: Noetic's type store plus tf2_msgs/TFMessage, which it lacks; ROS2: Humble's; messages
serialised as each format needs, stamped with the scan's time to the nanosecond)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench import guard
from loaders.se3 import tum_from_T

CLOUD, ODOM, TF, STRING = ("sensor_msgs/msg/PointCloud2", "nav_msgs/msg/Odometry",
                           "tf2_msgs/msg/TFMessage", "std_msgs/msg/String")


def _sec_nsec(t: float) -> tuple[int, int]:
    """(sec, nanosec) of ``t`` [s], rounded to the nearest nanosecond (never truncated: a
    stamp 0.3 s is 0.29999999999999999 as a float)."""
    sec = int(np.floor(t))
    nsec = int(round((t - sec) * 1e9))
    return (sec + 1, nsec - 1_000_000_000) if nsec >= 1_000_000_000 else (sec, nsec)


class BagWriter:
    """One writer interface over rosbags' ROS1 and rosbag2 writers (serialisation included)."""

    def __init__(self, path: Path, fmt: str) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ros1 = fmt == "ros1"
        self.store = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        if TF not in self.store.types:  # rosbags' ROS1 store lacks tf2_msgs: its one-line def
            from rosbags.typesys import get_types_from_msg

            self.store.register(get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", TF))
        if self.ros1:
            from rosbags.rosbag1 import Writer

            self.writer = guard.bag_writer(Writer, path)
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if fmt == "mcap" else StoragePlugin.SQLITE3
            self.writer = guard.bag_writer(Writer, path, version=9, storage_plugin=plugin)
        self.writer.open()
        self.seq = 0

    def connection(self, topic: str, msgtype: str, latched: bool = False):
        kw = {}
        if latched:  # ROS1 latched; ROS2 transient local, depth 1 (as tf_static's publisher)
            kw = {"latching": 1} if self.ros1 else {"offered_qos_profiles": [latched_qos()]}
        return self.writer.add_connection(topic, msgtype, typestore=self.store, **kw)

    def header(self, t: float, frame: str):
        T = self.store.types
        sec, nsec = _sec_nsec(t)
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        self.seq += 1
        if self.ros1:
            return T["std_msgs/msg/Header"](seq=self.seq, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def write(self, conn, t: float, msg) -> None:
        data = (self.store.serialize_ros1(msg, conn.msgtype) if self.ros1
                else self.store.serialize_cdr(msg, conn.msgtype))
        sec, nsec = _sec_nsec(t)
        self.writer.write(conn, sec * 1_000_000_000 + nsec, data)

    def close(self) -> None:
        self.writer.close()


def cloud_msg(bag: BagWriter, t: float, points: np.ndarray, values: dict[str, np.ndarray],
              sensor: str):
    """A PointCloud2 of float32 fields x, y, z and ``values`` (packed, little-endian) in the
    frame ``sensor``."""
    T = bag.store.types
    names = ["x", "y", "z", *values]
    dtype = np.dtype({"names": names, "formats": ["<f4"] * len(names),
                      "offsets": [4 * i for i in range(len(names))], "itemsize": 4 * len(names)})
    arr = np.empty(len(points), dtype=dtype)
    for k, axis in enumerate("xyz"):
        arr[axis] = points[:, k]
    for name, v in values.items():
        arr[name] = v
    PF = T["sensor_msgs/msg/PointField"]  # datatype 7: FLOAT32
    return T[CLOUD](
        header=bag.header(t, sensor), height=1, width=len(arr),
        fields=[PF(name=n, offset=4 * i, datatype=7, count=1)
                for i, n in enumerate(names)],
        is_bigendian=False, point_step=dtype.itemsize, row_step=dtype.itemsize * len(arr),
        data=np.frombuffer(arr.tobytes(), dtype=np.uint8), is_dense=True)


def _pose(T, pose: np.ndarray):
    xyz, quat = tum_from_T(pose[None])
    (x, y, z), (qx, qy, qz, qw) = xyz[0], quat[0]
    return T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=float(z)),
        orientation=T["geometry_msgs/msg/Quaternion"](x=float(qx), y=float(qy), z=float(qz),
                                                      w=float(qw)))


def odometry_msg(bag: BagWriter, t: float, T_world_body: np.ndarray, world: str, body: str):
    """``T_world_body`` as a nav_msgs/Odometry (header frame ``world``, child ``body``; twist
    zero: not given)."""
    T = bag.store.types
    cov = np.zeros(36)
    zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    return T[ODOM](
        header=bag.header(t, world), child_frame_id=body,
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(T, T_world_body),
                                                       covariance=cov),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=cov))


def tf_static_msg(bag: BagWriter, t: float, T_body_sensor: np.ndarray, body: str, sensor: str):
    """The extrinsic as a tf2_msgs/TFMessage of one transform ``body -> sensor``."""
    T = bag.store.types
    xyz, quat = tum_from_T(np.asarray(T_body_sensor, dtype=np.float64)[None])
    (x, y, z), (qx, qy, qz, qw) = xyz[0], quat[0]
    tf = T["geometry_msgs/msg/TransformStamped"](
        header=bag.header(t, body), child_frame_id=sensor,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z)),
            rotation=T["geometry_msgs/msg/Quaternion"](x=float(qx), y=float(qy), z=float(qz),
                                                       w=float(qw))))
    return T[TF](transforms=[tf])


def latched_qos():
    """rosbag2's offered QoS of a latched topic: reliable, transient local, keep last 1."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    return Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
               QosTime(0, 0), QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False)
