"""Writers of Snail-Radar inputs and of ROS1 / ROS2 (sqlite3, mcap) Doppler bags for the loader
tests, from frames whose truth is known.

Snail-Radar layouts as the dataset's tools make them (snail-radar/dataset_tools):
- bags: ``/radar_enhanced_pcl2`` / ``/radar_pcl2`` PointCloud2 with the 17 float32 Eagle fields
  packed at 4-byte steps, ``/ars548`` with x y z at 0, 4, 8, four bytes of padding, then the six
  other float32 fields from byte 16 (``python/folder_to_bag.py``, ``create_point_cloud2_msg``);
- folders: ``<sec>.<nsec:09d>.pcd`` (``DATA binary`` or ``ascii``, all SIZE 4 TYPE F) named by
  the header stamp, plus ``times.txt`` (``python/bag_to_folder.py``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from helpers_bags import odometry_msg
from loaders.pcd import write_pcd
from loaders.se3 import tum_from_T

EAGLE_FIELDS = ("x y z Doppler Range Power Alpha Beta rangeAccu aziAccu eleAccu dopplerAccu "
                "recoveredSpeed dotFlags denoiseFlag historyFrameFlag "
                "dopplerCorrectionFlag").split()
ARS548_FIELDS = "x y z doppler intensity range_std azimuth_std elevation_std doppler_std".split()
#: byte offsets of the fields in the bags' PointCloud2 and the point step
EAGLE_OFFSETS = [4 * i for i in range(len(EAGLE_FIELDS))]
EAGLE_STEP = 4 * len(EAGLE_FIELDS)
ARS548_OFFSETS = [0, 4, 8] + [16 + 4 * i for i in range(6)]
ARS548_STEP = 40


def sec_nsec(t: float) -> tuple[int, int]:
    sec = int(np.floor(t))
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return sec, nsec


def stamp_name(t: float) -> str:
    sec, nsec = sec_nsec(t)
    return f"{sec}.{nsec:09d}"


def radar_array(sensor: str, points: np.ndarray, doppler: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
    """A structured float32 array in ``sensor``'s field order ("eagle" / "ars548"): points and
    Doppler as given, range = |p|, the other fields random."""
    names = EAGLE_FIELDS if sensor == "eagle" else ARS548_FIELDS
    arr = np.zeros(len(points), dtype=[(n, "<f4") for n in names])
    arr["x"], arr["y"], arr["z"] = points[:, 0], points[:, 1], points[:, 2]
    arr[names[3]] = doppler
    for n in names[4:]:
        arr[n] = rng.uniform(0.0, 30.0, len(points))
    arr["Range" if sensor == "eagle" else "range_std"] = np.linalg.norm(points, axis=1)
    return arr


def cloud2_msg(store, t: float, arr: np.ndarray, offsets: list[int], step: int,
               seq: int | None = 0, frame: str = "oculii"):
    """A PointCloud2 of ``store`` (ROS1 when ``seq`` is not None, else ROS2) with the fields of
    ``arr`` (float32) at ``offsets`` and ``step`` bytes a point."""
    T = store.types
    names = list(arr.dtype.names)
    dt = np.dtype({"names": names, "formats": ["<f4"] * len(names), "offsets": offsets,
                   "itemsize": step})
    packed = np.zeros(len(arr), dtype=dt)
    for n in names:
        packed[n] = arr[n]
    sec, nsec = sec_nsec(t)
    stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    header = (T["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame) if seq is not None
              else T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame))
    PF = T["sensor_msgs/msg/PointField"]
    return T["sensor_msgs/msg/PointCloud2"](
        header=header, height=1, width=len(arr),
        fields=[PF(name=n, offset=o, datatype=7, count=1) for n, o in zip(names, offsets,
                                                                            strict=True)],
        is_bigendian=False, point_step=step, row_step=step * len(arr),
        data=np.frombuffer(packed.tobytes(), dtype=np.uint8), is_dense=True)


def write_snail_bag(path: Path, frames: dict[str, list[tuple[float, np.ndarray]]],
                    latency_s: float = 0.004) -> Path:
    """A ROS1 bag with ``frames[topic] = [(stamp, array)]`` on the Snail-Radar topics (the
    layout of each topic as the dataset's bags have it)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    msgtype = "sensor_msgs/msg/PointCloud2"
    with Writer(path) as w:
        for topic, items in frames.items():
            conn = w.add_connection(topic, msgtype, typestore=store)
            ars = topic == "/ars548"
            for i, (t, arr) in enumerate(items):
                msg = cloud2_msg(store, t, arr, ARS548_OFFSETS if ars else EAGLE_OFFSETS,
                                 ARS548_STEP if ars else EAGLE_STEP, seq=i,
                                 frame="ars548" if ars else "oculii")
                w.write(conn, int(round((t + latency_s) * 1e9)),
                        store.serialize_ros1(msg, msgtype))
    return path


def write_snail_folder(folder: Path, items: list[tuple[float, np.ndarray]],
                       data: str = "binary") -> Path:
    """An extracted frame folder: ``<sec>.<nsec>.pcd`` + ``times.txt``."""
    folder.mkdir(parents=True, exist_ok=True)
    names = []
    for t, arr in items:
        name = stamp_name(t)
        write_pcd(folder / f"{name}.pcd", arr, data)
        names.append(name)
    (folder / "times.txt").write_text("".join(f"{n}\n" for n in names))
    return folder


def write_ros2_bag(path: Path, items: list[tuple[float, np.ndarray]], storage: str,
                   topic: str = "/radar/points", gt: tuple[str, np.ndarray, np.ndarray] | None
                   = None, kind: str = "PointCloud2", latency_s: float = 0.003,
                   unset_header: bool = False) -> Path:
    """A ROS2 bag (``storage`` "sqlite3" or "mcap") with the clouds of ``items`` on ``topic``
    (PointCloud2 with the arrays' fields packed at 4-byte steps, or PointCloud with the
    non-xyz fields as channels) and optionally ``gt = (topic, stamps, T_world_body poses)`` as
    nav_msgs/Odometry. ``unset_header``: every cloud's header.stamp is 0 (a driver that leaves
    it unset)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    T = store.types
    msgtype = f"sensor_msgs/msg/{kind}"
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection(topic, msgtype, typestore=store)
        for t, arr in items:
            if kind == "PointCloud2":
                names = list(arr.dtype.names)
                msg = cloud2_msg(store, 0.0 if unset_header else t, arr,
                                 [4 * i for i in range(len(names))], 4 * len(names), seq=None,
                                 frame="radar")
            else:
                sec, nsec = sec_nsec(t)
                P32, CH = T["geometry_msgs/msg/Point32"], T["sensor_msgs/msg/ChannelFloat32"]
                msg = T["sensor_msgs/msg/PointCloud"](
                    header=T["std_msgs/msg/Header"](
                        stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                        frame_id="radar"),
                    points=[P32(x=float(r["x"]), y=float(r["y"]), z=float(r["z"])) for r in arr],
                    channels=[CH(name=n, values=np.ascontiguousarray(arr[n], dtype=np.float32))
                              for n in arr.dtype.names if n not in ("x", "y", "z")])
            w.write(conn, int(round((t + latency_s) * 1e9)), store.serialize_cdr(msg, msgtype))
        if gt is not None:
            gtopic, stamps, poses = gt
            gconn = w.add_connection(gtopic, "nav_msgs/msg/Odometry", typestore=store)
            for t, pose in zip(stamps, poses, strict=True):
                msg = ros2_odometry(store, t, pose)
                w.write(gconn, int(round(t * 1e9)), store.serialize_cdr(
                    msg, "nav_msgs/msg/Odometry"))
    return path


def ros2_odometry(store, t: float, pose: np.ndarray):
    T = store.types
    xyz, quat = tum_from_T(pose[None])
    p, q = xyz[0], quat[0]
    sec, nsec = sec_nsec(t)
    cov = np.zeros(36)
    return T["nav_msgs/msg/Odometry"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
            sec=sec, nanosec=nsec), frame_id="map"),
        child_frame_id="base_link",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
                orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])),
            covariance=cov),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](
                linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
            covariance=cov))


def write_ros1_odometry_bag(path: Path, items: list[tuple[float, np.ndarray]], topic: str,
                            gt: tuple[str, np.ndarray, np.ndarray]) -> Path:
    """A ROS1 bag with PointCloud2 clouds (fields at 4-byte steps) and nav_msgs/Odometry GT."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    msgtype = "sensor_msgs/msg/PointCloud2"
    with Writer(path) as w:
        conn = w.add_connection(topic, msgtype, typestore=store)
        for i, (t, arr) in enumerate(items):
            names = list(arr.dtype.names)
            msg = cloud2_msg(store, t, arr, [4 * k for k in range(len(names))], 4 * len(names),
                             seq=i, frame="radar")
            w.write(conn, int(round((t + 0.003) * 1e9)), store.serialize_ros1(msg, msgtype))
        gtopic, stamps, poses = gt
        gconn = w.add_connection(gtopic, "nav_msgs/msg/Odometry", typestore=store)
        for j, (t, pose) in enumerate(zip(stamps, poses, strict=True)):
            w.write(gconn, int(round(t * 1e9)), store.serialize_ros1(
                odometry_msg(store, t, j, pose), "nav_msgs/msg/Odometry"))
    return path


def main() -> None:
    """Write a large bag for streaming / throughput checks of the rosbag loader::

        .venv/bin/python -m tests.helpers_snail OUT --storage mcap --frames 1500 --points 1500
    """
    import argparse

    from helpers_bags import T0

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("out", type=Path)
    ap.add_argument("--storage", choices=["ros1", "sqlite3", "mcap"], default="mcap")
    ap.add_argument("--frames", type=int, default=1500)
    ap.add_argument("--points", type=int, default=1500)
    args = ap.parse_args()
    rng = np.random.default_rng(0)

    def clouds():
        for i in range(args.frames):
            arr = np.zeros(args.points, dtype=[(n, "<f4") for n in ("x", "y", "z", "doppler",
                                                                     "power")])
            for n in arr.dtype.names:
                arr[n] = rng.uniform(-50, 50, args.points)
            yield T0 + 0.1 * i, arr

    if args.storage == "ros1":
        from rosbags.rosbag1 import Writer
        from rosbags.typesys import Stores, get_typestore

        store = get_typestore(Stores.ROS1_NOETIC)
        with Writer(args.out) as w:
            conn = w.add_connection("/radar/points", "sensor_msgs/msg/PointCloud2",
                                    typestore=store)
            for i, (t, arr) in enumerate(clouds()):
                msg = cloud2_msg(store, t, arr, [0, 4, 8, 12, 16], 20, seq=i)
                w.write(conn, int(t * 1e9), store.serialize_ros1(
                    msg, "sensor_msgs/msg/PointCloud2"))
    else:
        write_ros2_bag(args.out, clouds(), args.storage)
    print(args.out)


if __name__ == "__main__":
    main()
