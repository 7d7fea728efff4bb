"""Writers of tiny real-dataset inputs for the loader tests, from a known analytic motion.

- ``Motion``: constant forward speed + constant yaw rate + constant climb (exact poses and
  velocities at any time). Static scene: every point of a scan is static in the world, so its
  Doppler is exactly ``-d . v_sensor`` (positive = receding).
- ROS1 bags written with rosbags' Writer in the layouts of NTU4DRadLM (sensor_msgs/PointCloud
  with channels in a chosen order, or PointCloud2), Campus (msgs_radar/RadarScanExtended +
  nav_msgs/Odometry) and the three Aeva folder layouts.

Also a command-line generator of a large NTU-style bag for throughput measurements::

    .venv/bin/python -m tests.helpers_bags OUT.bag --frames 2000 --points 1500
"""

from __future__ import annotations

import argparse
import json
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from loaders.se3 import make_T, tum_from_T

T0 = 1654232000.0  # a realistic epoch (2022-06-03)


@dataclass
class Motion:
    """Body pose ``T_world_body(t)``: speed ``v`` [m/s] along body x, yaw rate ``w`` [rad/s],
    climb ``vz`` [m/s]; starts at the origin at ``t0``. ``T_body_sensor`` is the extrinsic."""

    v: float = 8.0
    w: float = 0.2
    vz: float = 0.1
    t0: float = T0
    T_body_sensor: np.ndarray = field(default_factory=lambda: np.eye(4))

    def body_pose(self, t) -> np.ndarray:
        tau = np.atleast_1d(np.asarray(t, dtype=np.float64)) - self.t0
        yaw = self.w * tau
        x = self.v / self.w * np.sin(yaw)
        y = self.v / self.w * (1.0 - np.cos(yaw))
        z = self.vz * tau
        R = Rotation.from_euler("z", yaw[:, None]).as_matrix()
        return make_T(R, np.column_stack([x, y, z]))

    def sensor_pose(self, t) -> np.ndarray:
        return self.body_pose(t) @ self.T_body_sensor

    def sensor_velocity(self, t: float) -> np.ndarray:
        """Linear velocity of the sensor origin in the sensor frame [m/s]."""
        yaw = self.w * (t - self.t0)
        v_world = np.array([self.v * np.cos(yaw), self.v * np.sin(yaw), self.vz])
        R_wb = Rotation.from_euler("z", yaw).as_matrix()
        v_body = R_wb.T @ v_world
        lever = self.T_body_sensor[:3, 3]
        v_body_at_sensor = v_body + np.cross([0.0, 0.0, self.w], lever)
        return self.T_body_sensor[:3, :3].T @ v_body_at_sensor


def scan_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random sensor-frame points ahead of the sensor (float32)."""
    az = rng.uniform(-1.2, 1.2, n)
    el = rng.uniform(-0.25, 0.25, n)
    r = rng.uniform(3.0, 60.0, n)
    ce = np.cos(el)
    return np.column_stack([r * ce * np.cos(az), r * ce * np.sin(az), r * np.sin(el)]).astype(
        np.float32)


def doppler_of(points: np.ndarray, v_sensor: np.ndarray) -> np.ndarray:
    p = points.astype(np.float64)
    d = p / np.linalg.norm(p, axis=1, keepdims=True)
    return (-(d @ v_sensor)).astype(np.float32)


@dataclass
class Truth:
    stamps: np.ndarray
    points: list[np.ndarray]
    doppler: list[np.ndarray]
    fields: list[dict[str, np.ndarray]]
    motion: Motion

    def sensor_poses(self) -> np.ndarray:
        return self.motion.sensor_pose(self.stamps)


def make_truth(motion: Motion, frames: int, points: int, period: float = 0.08,
               start: float = 0.5, seed: int = 0) -> Truth:
    rng = np.random.default_rng(seed)
    stamps = motion.t0 + start + period * np.arange(frames)
    pts, dop, flds = [], [], []
    for t in stamps:
        p = scan_points(rng, points)
        pts.append(p)
        dop.append(doppler_of(p, motion.sensor_velocity(t)))
        flds.append({"power": rng.uniform(0, 40, points).astype(np.float32),
                     "range": np.linalg.norm(p, axis=1).astype(np.float32)})
    return Truth(stamps, pts, dop, flds, motion)


def write_tum(path: Path, stamps: np.ndarray, poses: np.ndarray, header: bool = True) -> None:
    xyz, quat = tum_from_T(poses)
    with open(path, "w") as f:
        if header:
            f.write("# timestamp tx ty tz qx qy qz qw\n")
        for t, p, q in zip(stamps, xyz, quat, strict=True):
            f.write(f"{t:.9f} {p[0]:.9f} {p[1]:.9f} {p[2]:.9f} "
                    f"{q[0]:.12f} {q[1]:.12f} {q[2]:.12f} {q[3]:.12f}\n")


def write_gt_tum(path: Path, motion: Motion, t_start: float, t_end: float, step: float = 0.02,
                 stamp_shift: float = 0.0) -> np.ndarray:
    """Body GT rows every ``step`` s over [t_start, t_end] (sensor clock); the file stamps are
    ``t - stamp_shift`` (so ``gt_stamp + stamp_shift = sensor clock``). Returns the stamps."""
    k0 = int(np.floor((t_start - motion.t0) / step))
    k1 = int(np.ceil((t_end - motion.t0) / step))
    t = motion.t0 + step * np.arange(k0, k1 + 1)
    write_tum(path, t - stamp_shift, motion.body_pose(t))
    return t


def ego_velocity_from_doppler(points: np.ndarray, doppler: np.ndarray) -> np.ndarray:
    """Least-squares sensor velocity (sensor frame) from ``doppler = -d . v``."""
    d = points / np.linalg.norm(points, axis=1, keepdims=True)
    v, *_ = np.linalg.lstsq(-d, doppler, rcond=None)
    return v


def gt_sensor_velocity(stamps: np.ndarray, poses: np.ndarray, i: int) -> np.ndarray:
    """Central finite difference of the GT sensor positions at pose ``i``, in the sensor
    frame."""
    v_world = (poses[i + 1, :3, 3] - poses[i - 1, :3, 3]) / (stamps[i + 1] - stamps[i - 1])
    return poses[i, :3, :3].T @ v_world


def doppler_sign_cosine(sequence, frames: int = 5) -> float:
    """Mean cosine similarity between the Doppler-fitted and the GT ego velocity."""
    gt = sequence.ground_truth
    cos = []
    for i in range(1, min(frames + 1, len(sequence) - 1)):
        scan = sequence.scan(i)
        a = ego_velocity_from_doppler(scan.points, scan.doppler)
        b = gt_sensor_velocity(gt.stamps, gt.poses, i)
        cos.append(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.mean(cos))


# -- ROS1 bags -----------------------------------------------------------------------------------

def _stamp(store, t: float):
    sec = int(np.floor(t))
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def _header(store, t: float, seq: int, frame: str = "radar"):
    return store.types["std_msgs/msg/Header"](seq=seq, stamp=_stamp(store, t), frame_id=frame)


def _ns(t: float) -> int:
    return int(round(t * 1e9))


def pointcloud_msg(store, t, seq, points, channels: dict[str, np.ndarray]):
    P32 = store.types["geometry_msgs/msg/Point32"]
    CH = store.types["sensor_msgs/msg/ChannelFloat32"]
    return store.types["sensor_msgs/msg/PointCloud"](
        header=_header(store, t, seq),
        points=[P32(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points],
        channels=[CH(name=k, values=np.asarray(v, dtype=np.float32)) for k, v in channels.items()],
    )


def pointcloud2_msg(store, t, seq, points, values: dict[str, np.ndarray], big_endian=False,
                    pad: int = 4):
    """PointCloud2 with x, y, z then ``values`` as float32 fields, ``pad`` bytes of padding at
    the end of each point."""
    PF = store.types["sensor_msgs/msg/PointField"]
    names = ["x", "y", "z", *values]
    e = ">" if big_endian else "<"
    dtype = np.dtype({"names": names, "formats": [e + "f4"] * len(names),
                      "offsets": [4 * i for i in range(len(names))],
                      "itemsize": 4 * len(names) + pad})
    arr = np.zeros(len(points), dtype=dtype)
    arr["x"], arr["y"], arr["z"] = points[:, 0], points[:, 1], points[:, 2]
    for k, v in values.items():
        arr[k] = v
    return store.types["sensor_msgs/msg/PointCloud2"](
        header=_header(store, t, seq), height=1, width=len(points),
        fields=[PF(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate(names)],
        is_bigendian=big_endian, point_step=dtype.itemsize, row_step=dtype.itemsize * len(points),
        data=np.frombuffer(arr.tobytes(), dtype=np.uint8), is_dense=True,
    )


def imu_msg(store, t, seq):
    T = store.types
    return T["sensor_msgs/msg/Imu"](
        header=_header(store, t, seq, "imu"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )


def odometry_msg(store, t, seq, pose: np.ndarray):
    T = store.types
    xyz, quat = tum_from_T(pose[None])
    p, q = xyz[0], quat[0]
    cov = np.zeros(36)
    return T["nav_msgs/msg/Odometry"](
        header=_header(store, t, seq, "utm"), child_frame_id="base_link",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
                orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])),
            covariance=cov),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](
                linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
            covariance=cov),
    )


def write_ntu_bag(path: Path, truth: Truth, *, kind: str = "PointCloud",
                  topic: str = "/radar_enhanced_pcl", channel_order=("Power", "Doppler", "Range"),
                  doppler_name: str = "Doppler", big_endian: bool = False,
                  nan_frame: int | None = None, empty_frame: int | None = None,
                  extra_topics: bool = True, latency_s: float = 0.005,
                  compression: str | None = None) -> Path:
    """Bag with the radar scans of ``truth`` (record time = stamp + latency) and an IMU topic.

    kind "PointCloud": channels in ``channel_order`` (names among Power, Doppler, Range);
    kind "PointCloud2": float32 fields x, y, z, ``doppler_name``, power (4 bytes padding).
    nan_frame: that frame's first point gets NaN coordinates; empty_frame: that frame has none.
    compression: None, "lz4" or "bz2" (chunk compression).
    """
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    msgtype = f"sensor_msgs/msg/{kind}"
    writer = Writer(path)
    if compression:
        writer.set_compression(Writer.CompressionFormat[compression.upper()])
    with writer as w:
        conn = w.add_connection(topic, msgtype, typestore=store)
        imu = w.add_connection("/vectornav/imu", "sensor_msgs/msg/Imu", typestore=store) \
            if extra_topics else None
        for i, t in enumerate(truth.stamps):
            pts = truth.points[i].copy()
            values = {"Power": truth.fields[i]["power"], "Doppler": truth.doppler[i],
                      "Range": truth.fields[i]["range"]}
            if nan_frame == i:
                pts[0] = np.nan
            if empty_frame == i:
                pts = pts[:0]
                values = {k: v[:0] for k, v in values.items()}
            if kind == "PointCloud":
                chans = {doppler_name if k == "Doppler" else k: values[k] for k in channel_order}
                msg = pointcloud_msg(store, t, i, pts, chans)
            else:
                msg = pointcloud2_msg(store, t, i, pts, {doppler_name: values["Doppler"],
                                                         "power": values["Power"]},
                                      big_endian=big_endian)
            w.write(conn, _ns(t + latency_s), store.serialize_ros1(msg, msgtype))
            if imu is not None:
                w.write(imu, _ns(t + 0.001), store.serialize_ros1(imu_msg(store, t, i),
                                                                 "sensor_msgs/msg/Imu"))
    return path


def write_imu_only_bag(path: Path, topic: str, frames: int = 3) -> Path:
    """A bag whose ``topic`` carries sensor_msgs/Imu (a wrong type for a radar topic)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        conn = w.add_connection(topic, "sensor_msgs/msg/Imu", typestore=store)
        for i in range(frames):
            t = T0 + 0.1 * i
            w.write(conn, _ns(t), store.serialize_ros1(imu_msg(store, t, i),
                                                      "sensor_msgs/msg/Imu"))
    return path


def campus_targets(points: np.ndarray, doppler: np.ndarray, rng: np.random.Generator,
                   elevation_sign: float = 1.0) -> dict[str, np.ndarray]:
    """Spherical target columns (float32) for sensor-frame points."""
    p = points.astype(np.float64)
    r = np.linalg.norm(p, axis=1)
    return {
        "range": r.astype(np.float32),
        "azimuth": np.arctan2(p[:, 1], p[:, 0]).astype(np.float32),
        "elevation": (elevation_sign * np.arcsin(p[:, 2] / r)).astype(np.float32),
        "velocity": doppler.astype(np.float32),
        "snr": rng.uniform(5, 30, len(p)).astype(np.float32),
        "power": rng.uniform(0, 60, len(p)).astype(np.float32),
        "rcs": rng.uniform(-10, 20, len(p)).astype(np.float32),
    }


def write_campus_bag(path: Path, truth: Truth, *, topic: str = "/radar_scan",
                     gt_topic: str | None = "/ground_truth", gt_step: float = 0.02,
                     utm: tuple[float, float, float] = (351234.5, 3456789.25, 12.0),
                     store=None, seed: int = 1) -> tuple[Path, list[dict[str, np.ndarray]]]:
    """Bag with msgs_radar/RadarScanExtended scans and nav_msgs/Odometry GT (body poses at
    ``gt_step`` s, shifted by the ``utm`` origin). Returns the path and the target columns."""
    from rosbags.rosbag1 import Writer

    from loaders.campus import SCAN_TYPE, TARGET_TYPE, campus_typestore

    store = store or campus_typestore()
    rng = np.random.default_rng(seed)
    Target = store.types[TARGET_TYPE]
    names = [n for n, _ in store.fielddefs[TARGET_TYPE][1]]
    cols_all = []
    with Writer(path) as w:
        conn = w.add_connection(topic, SCAN_TYPE, typestore=store)
        gconn = w.add_connection(gt_topic, "nav_msgs/msg/Odometry", typestore=store) \
            if gt_topic else None
        for i, t in enumerate(truth.stamps):
            cols = campus_targets(truth.points[i], truth.doppler[i], rng)
            for n in names:
                cols.setdefault(n, rng.uniform(0, 1, len(truth.points[i])).astype(np.float32))
            cols_all.append(cols)
            kinds = {n: t[1][0] for n, t in store.fielddefs[TARGET_TYPE][1]}
            conv = {n: (float if kinds[n].startswith("float") else int) for n in names}
            targets = [Target(**{n: conv[n](cols[n][k]) for n in names})
                       for k in range(len(truth.points[i]))]
            kwargs = {"header": _header(store, t, i), "targets": targets}
            for n, _ in store.fielddefs[SCAN_TYPE][1]:
                if n.startswith("umabiguos"):
                    kwargs[n] = 100.0
            msg = store.types[SCAN_TYPE](**kwargs)
            w.write(conn, _ns(t + 0.003), store.serialize_ros1(msg, SCAN_TYPE))
        if gconn is not None:
            m = truth.motion
            k0 = int(np.floor((truth.stamps[0] - 0.1 - m.t0) / gt_step))
            k1 = int(np.ceil((truth.stamps[-1] + 0.1 - m.t0) / gt_step))
            for j, t in enumerate(m.t0 + gt_step * np.arange(k0, k1 + 1)):
                pose = m.body_pose(t)[0]
                pose[:3, 3] += utm
                w.write(gconn, _ns(t), store.serialize_ros1(
                    odometry_msg(store, t, j, pose), "nav_msgs/msg/Odometry"))
    return path, cols_all


# -- Aeva folders --------------------------------------------------------------------------------

def write_aeva_folder(root: Path, truth: Truth, layout: str, period: float = 0.1) -> Path:
    """One of the three Aeva layouts from ``truth`` (frames numbered from 1, sim stamps
    ``i * period`` in the GT file for dicp/open3d; epoch microseconds for steam)."""
    root.mkdir(parents=True, exist_ok=True)
    m = truth.motion
    poses = m.body_pose(truth.stamps)
    T = m.T_body_sensor
    xyz, quat = tum_from_T(T[None])
    n = len(truth.stamps)
    if layout == "dicp":
        (root / "point_clouds").mkdir()
        for i in range(n):
            data = np.column_stack([truth.points[i], truth.doppler[i]]).astype("<f4")
            data.tofile(root / "point_clouds" / f"{i + 1:05d}.bin")
        cal = {"T_V_to_S": {"translation": dict(zip("xyz", map(float, xyz[0]), strict=True)),
                            "quaternion": {"w": float(quat[0][3]), "x": float(quat[0][0]),
                                           "y": float(quat[0][1]), "z": float(quat[0][2])}}}
        (root / "calibration.json").write_text(json.dumps(cal))
        write_tum(root / "ref_poses.txt", period * np.arange(n), poses, header=False)
    elif layout == "open3d":
        (root / "xyzd_sequence").mkdir()
        for i in range(n):
            data = np.column_stack([truth.points[i], truth.doppler[i]])
            np.savetxt(root / "xyzd_sequence" / f"{i + 1:05d}.xyzd", data, fmt="%.9g")
        cal = {"transform_vehicle_to_sensor": T.ravel().tolist(), "period": period}
        (root / "calibration.json").write_text(json.dumps(cal))
        write_tum(root / "ground_truth_poses.txt", period * np.arange(n), poses, header=False)
    elif layout == "steam":
        (root / "frames").mkdir()
        for i in range(n):
            k = len(truth.points[i])
            t_ns = np.linspace(0, 0.099e9, k)
            data = np.column_stack([truth.points[i], truth.doppler[i], t_ns]).astype("<f4")
            data.tofile(root / "frames" / f"{i}.bin")
        us = np.round(truth.stamps * 1e6).astype(np.int64)
        np.savetxt(root / "timestamps.txt", us, fmt="%d")
        np.savetxt(root / "aeva_poses.txt", poses[:, :3, :].reshape(-1, 12), fmt="%.12e")
    else:
        raise ValueError(layout)
    return root


# -- large bag for throughput ---------------------------------------------------------------------

def _raw_pointcloud(seq: int, t: float, points: np.ndarray, channels: dict[str, np.ndarray]
                    ) -> bytes:
    """sensor_msgs/PointCloud in the ROS1 wire format, written with numpy (fast)."""
    sec = int(np.floor(t))
    nsec = int(round((t - sec) * 1e9))
    frame = b"radar"
    parts = [struct.pack("<III", seq, sec, nsec), struct.pack("<I", len(frame)), frame,
             struct.pack("<I", len(points)), points.astype("<f4").tobytes(),
             struct.pack("<I", len(channels))]
    for name, values in channels.items():
        b = name.encode()
        parts += [struct.pack("<I", len(b)), b, struct.pack("<I", len(values)),
                  np.asarray(values, dtype="<f4").tobytes()]
    return b"".join(parts)


def write_big_ntu_bag(path: Path, frames: int = 2000, points: int = 1500, seed: int = 0) -> Path:
    """A semi-dense NTU-style bag (PointCloud, channels Power, Doppler, Range) + an IMU topic at
    10x the radar rate, written from raw bytes."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    motion = Motion()
    rng = np.random.default_rng(seed)
    imu_raw = None
    with Writer(path) as w:
        conn = w.add_connection("/radar_enhanced_pcl", "sensor_msgs/msg/PointCloud",
                                typestore=store)
        imu = w.add_connection("/vectornav/imu", "sensor_msgs/msg/Imu", typestore=store)
        for i in range(frames):
            t = motion.t0 + 0.5 + 0.08 * i
            n = int(rng.integers(int(points * 0.7), int(points * 1.3)))
            p = scan_points(rng, n)
            d = doppler_of(p, motion.sensor_velocity(t))
            raw = _raw_pointcloud(i, t, p, {"Power": rng.uniform(0, 40, n), "Doppler": d,
                                            "Range": np.linalg.norm(p, axis=1)})
            w.write(conn, _ns(t + 0.005), raw)
            for k in range(10):
                if imu_raw is None:
                    imu_raw = bytes(store.serialize_ros1(imu_msg(store, t, i),
                                                         "sensor_msgs/msg/Imu"))
                w.write(imu, _ns(t + 0.008 * k), imu_raw)
        gt = path.with_suffix(".gt_odom.txt")
    write_gt_tum(gt, motion, motion.t0, motion.t0 + 0.5 + 0.08 * frames + 0.1, step=0.05)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description="write a large NTU-style bag for throughput tests")
    ap.add_argument("out", type=Path)
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--points", type=int, default=1500)
    a = ap.parse_args()
    if a.out.exists():
        a.out.unlink()
    t = time.perf_counter()
    write_big_ntu_bag(a.out, a.frames, a.points)
    print(f"wrote {a.out} ({a.out.stat().st_size / 1e6:.1f} MB) and "
          f"{a.out.with_suffix('.gt_odom.txt')} in {time.perf_counter() - t:.1f} s")


if __name__ == "__main__":
    main()
