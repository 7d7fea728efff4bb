"""A researcher's own recording: any ROS1 bag or ROS2 bag (sqlite3 or mcap storage) with a
``sensor_msgs/PointCloud2`` or ``sensor_msgs/PointCloud`` topic of Doppler scans.

- Input: ROS1 ``.bag`` file(s) of one recording (merged in time order), or one ROS2 bag (its
  folder with ``metadata.yaml``, or a bare ``.db3`` / ``.mcap`` file). rosbags (>= 0.11) reads
  all three; its ``rosbag2.Writer`` writes both sqlite3 and mcap (``StoragePlugin.MCAP``), which
  is how the tests make their bags.
- Scans: ``topic`` (default: the only PointCloud2 / PointCloud topic of the bag). Fields are
  read by NAME: ``x``, ``y``, ``z`` (PointCloud: its Point32 points) and the Doppler field
  ``doppler_field`` (PointCloud: a channel of that name), multiplied by ``doppler_sign`` so that
  the stored value is positive when the point recedes (the harness's convention; a driver that
  reports approach as positive needs ``doppler_sign=-1``). ``doppler_kind`` declares what the
  values are (``radial``, or ``ego-compensated`` when the driver already removed the ego
  motion). Every other scalar field becomes a per-point field (lowercased name).
- Stamps: ``header.stamp`` (default) or the bag's record time (``stamp="record"``); repeated
  stamps are dropped with a warning.
- Ground truth (optional): a pose file (``gt``: TUM rows at their own rate, interpolated at the
  scan stamps; or KITTI rows, exactly one per scan) or a topic of the same bag(s) (``gt_topic``:
  ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or ``PoseWithCovarianceStamped``, stamped
  by ``header.stamp``), giving ``T_world_body``; ``T_body_sensor`` (the sensor in the GT body
  frame, default identity) moves it to the sensor: ``T_world_sensor = T_world_body @
  T_body_sensor``. A gap in the GT longer than ``max_gap_s`` is never interpolated across.
- A bag ``bench export`` wrote carries its description (``DESCRIPTION_TOPIC``, JSON): the
  options not given take its values (scan and GT topics, extrinsic, sensor kind and model,
  Doppler kind, ``doppler_field none`` when it has no Doppler, the sequence name), so
  ``bench convert rosbag BAG --out S.h5`` alone reads it back to the store it came from.
- ``doppler_field none``: the scans carry no Doppler (``x y z`` and other fields only).
- Streaming: an index pass reads only the stamps; ``scan(i)`` then reads one message (ROS1: a
  file seek, ``loaders.ros1.BagTopic``; ROS2: a read positioned by record time, continuing the
  previous read when frames are taken in order), so memory holds a few frames at most.
"""

from __future__ import annotations

import json
import struct
import warnings
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from loaders.assemble import finish_scan, median_period
from loaders.errors import DataError
from loaders.gt import associate
from loaders.options import LoaderOptions, OpensFromOptions
from loaders.posefile import detect_pose_format, parse_extrinsic, read_gt_file
from loaders.ros1 import BagTopic, sort_unique_stamps, topic_stamps
from loaders.ros1_msgs import cloud2_array, parse_pointcloud, parse_pointcloud2
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.se3 import T_from_tum
from loaders.trajectory import Trajectory

POINTCLOUD = "sensor_msgs/msg/PointCloud"
POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
CLOUD_TYPES = (POINTCLOUD2, POINTCLOUD)
POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped",
              "geometry_msgs/msg/PoseWithCovarianceStamped")
DEFAULT_PERIOD_S = 0.1
#: the topic of the JSON description ``bench export`` writes into every bag
DESCRIPTION_TOPIC = "/doppler_bench/description"
#: ``doppler_field`` of scans without Doppler
NO_DOPPLER = "none"
#: the body frame a pose topic is of when the description names none
BODY_FRAME = "base_link"


class Options(LoaderOptions):
    topic: str | None = Field(None, description="PointCloud2 / PointCloud topic of the scans "
                              "(default: the bag's only such topic)")
    doppler_field: str = Field("doppler", description="name of the Doppler field (PointCloud2) "
                               f"or channel (PointCloud) [m/s]; '{NO_DOPPLER}': the scans have "
                               "no Doppler")
    doppler_sign: float = Field(
        1.0, description="+1 when the field is positive for a receding point, -1 when positive "
        "means approaching")
    doppler_kind: Literal["radial", "ego-compensated"] = Field(
        "radial", description="what the Doppler values are: radial (raw, relative to the moving "
        "sensor) or ego-compensated (the driver removed the ego motion)")
    sensor_kind: Literal["radar", "lidar"] = Field("radar", description="radar or lidar")
    model: str = Field("", description="sensor model / class, e.g. radar-semidense")
    gt: Path | None = Field(None, description="ground-truth pose file: TUM (t x y z qx qy qz "
                            "qw) or KITTI (12 values a row, one row per scan)")
    gt_format: Literal["auto", "tum", "kitti"] = Field(
        "auto", description="format of --gt (auto: from its first row)")
    gt_topic: str | None = Field(None, description="ground-truth topic of the bag(s): "
                                 "nav_msgs/Odometry, PoseStamped or PoseWithCovarianceStamped")
    T_body_sensor: str | None = Field(
        None, description="the sensor in the GT body frame: 'x y z qx qy qz qw' or 16 numbers "
        "(default identity)")
    time_offset_s: float = Field(0.0, description="gt_stamp + offset = scan stamp [s]")
    max_gap_s: float = Field(0.5, description="largest GT gap interpolated across [s]")
    uncovered: Literal["keep", "trim", "error"] = Field(
        "keep", description="scans without GT: keep (unscored), trim (leading / trailing) or "
        "error")
    stamp: Literal["header", "record"] = Field(
        "header", description="scan stamp: header.stamp or the bag's record time")

    @field_validator("doppler_sign")
    @classmethod
    def _unit_sign(cls, v: float) -> float:
        if v not in (1.0, -1.0):
            raise ValueError(f"doppler_sign must be +1 or -1, got {v}")
        return v


# -- bag access ------------------------------------------------------------------------------

def _is_ros1(path: Path) -> bool:
    return path.is_file() and path.suffix == ".bag"


def _any_reader(paths: list[Path]):
    from rosbags.highlevel import AnyReader

    try:
        reader = AnyReader(paths)
        reader.open()
    except Exception as err:  # rosbags raises its own error types per format
        raise DataError(
            f"{', '.join(map(str, paths))}: cannot open the bag ({type(err).__name__}: {err}); "
            "expected ROS1 .bag file(s) or one ROS2 bag (folder with metadata.yaml, .db3 or "
            ".mcap)"
        ) from None
    return reader


def bag_topics(paths: list[Path]) -> dict[str, str]:
    """{topic: message type} of the bag(s)."""
    reader = _any_reader(paths)
    try:
        return {c.topic: c.msgtype for c in reader.connections}
    finally:
        reader.close()


class _Ros2Topic:
    """Lazy access to one topic of a ROS2 bag: an index of record times and header stamps,
    then one message at a time."""

    def __init__(self, path: Path, topic: str, accept: tuple[str, ...]) -> None:
        from rosbags.rosbag2 import Reader

        self.path, self.topic = path, topic
        try:
            reader = Reader(path)
            reader.open()
        except Exception as err:  # rosbags raises its own error types per storage
            raise DataError(f"{path}: cannot open the ROS2 bag ({type(err).__name__}: {err}); "
                            "expected a folder with metadata.yaml, a .db3 or a .mcap file"
                            ) from None
        try:
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns:
                have = sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections)
                raise DataError(f"{path}: no topic {topic}; the bag has "
                                + (", ".join(have) or "no topics"))
            self.msgtype = conns[0].msgtype
            if self.msgtype not in accept:
                raise DataError(f"{path}: topic {topic} has message type {self.msgtype}; "
                                f"expected one of {', '.join(accept)}")
            self.msgdef = conns[0].msgdef
            log, head = [], []
            for _, t, raw in reader.messages(connections=conns):
                log.append(t)
                head.append(_cdr_header_stamp(raw))
        finally:
            reader.close()
        order = np.argsort(np.asarray(log, dtype=np.int64), kind="stable")
        self.record_time_ns = np.asarray(log, dtype=np.int64)[order]
        self._header = np.asarray(head, dtype=np.float64)[order]
        self._reader = None
        self._cursor = None
        self._next = -1

    def __len__(self) -> int:
        return len(self.record_time_ns)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state.update(_reader=None, _cursor=None, _next=-1)
        return state

    def where(self, k: int) -> str:
        return f"{self.path}, {self.topic} message {k}"

    def header_stamps(self) -> np.ndarray:
        return self._header.copy()

    def raw(self, k: int) -> bytes:
        if self._cursor is None or self._next != k:
            from rosbags.rosbag2 import Reader

            if self._reader is None:
                self._reader = Reader(self.path)
                self._reader.open()
            t = int(self.record_time_ns[k])
            rank = k - int(np.searchsorted(self.record_time_ns, t))
            conns = [c for c in self._reader.connections if c.topic == self.topic]
            self._cursor = self._reader.messages(connections=conns, start=t)
            for _ in range(rank):
                next(self._cursor, None)
        item = next(self._cursor, None)
        if item is None:
            raise DataError(f"{self.where(k)}: message missing on re-reading the bag")
        self._next = k + 1
        return item[2]

    def close(self) -> None:
        self._cursor = None
        self._next = -1
        if self._reader is not None:
            self._reader.close()
            self._reader = None


def _cdr_header_stamp(raw: bytes) -> float:
    """``header.stamp`` of a CDR message that starts with a std_msgs/Header."""
    if len(raw) < 12:
        return float("nan")
    endian = "<" if raw[1] & 1 else ">"
    sec, nsec = struct.unpack_from(endian + "iI", raw, 4)
    return sec + nsec * 1e-9


def _ros2_typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.LATEST)


def _cloud_from_ros2(msg, msgtype: str, where: str) -> dict[str, np.ndarray]:
    if msgtype == POINTCLOUD2:
        fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
        arr, names = cloud2_array(fields, bool(msg.is_bigendian), msg.height, msg.width,
                                  msg.point_step, msg.row_step, np.asarray(msg.data), where)
        return {n: arr[n] for n in names}
    pts = np.array([[p.x, p.y, p.z] for p in msg.points], dtype=np.float32).reshape(-1, 3)
    out = {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2]}
    for ch in msg.channels:
        values = np.asarray(ch.values, dtype=np.float32)
        if len(values) != len(pts):
            raise DataError(f"{where}: channel {ch.name!r} has {len(values)} values for "
                            f"{len(pts)} points; expected one per point")
        out.setdefault(ch.name, values)
    return out


def _cloud_from_ros1(data: bytes, msgtype: str, where: str) -> dict[str, np.ndarray]:
    if msgtype == POINTCLOUD2:
        _, arr, names = parse_pointcloud2(data, where)
        return {n: arr[n] for n in names}
    _, pts, channels = parse_pointcloud(data, where)
    out = {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2]}
    for name, values in channels.items():
        out.setdefault(name, values)
    return out


def _pose_of(msg, msgtype: str) -> tuple[np.ndarray, np.ndarray]:
    pose = msg.pose if msgtype == "geometry_msgs/msg/PoseStamped" else msg.pose.pose
    p, q = pose.position, pose.orientation
    return np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])


def read_gt_topic(paths: list[Path], topic: str, what: str = "ground-truth") -> Trajectory:
    """``T_world_body`` from a pose topic of the bag(s), stamped by ``header.stamp`` and sorted
    (record order is not stamp order); ``what`` names the poses in errors."""
    reader = _any_reader(paths)
    try:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})  # once
            raise DataError(f"{', '.join(map(str, paths))}: no {what} topic {topic}; the "
                            f"bag has {', '.join(have) or 'no topics'}")
        msgtype = conns[0].msgtype
        if msgtype not in POSE_TYPES:
            raise DataError(f"{paths[0]}: {what} topic {topic} has type {msgtype}; "
                            f"expected one of {', '.join(POSE_TYPES)}")
        stamps, xyz, quat = [], [], []
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            st = msg.header.stamp
            stamps.append(st.sec + st.nanosec * 1e-9)
            p, q = _pose_of(msg, conn.msgtype)
            xyz.append(p)
            quat.append(q)
    finally:
        reader.close()
    if not stamps:
        raise DataError(f"{paths[0]}: {what} topic {topic} has no messages")
    order = np.argsort(stamps, kind="stable")
    q = np.asarray(quat)[order]
    norms = np.linalg.norm(q, axis=1)
    if np.any(np.abs(norms - 1.0) > 1e-3):
        bad = int(np.flatnonzero(np.abs(norms - 1.0) > 1e-3)[0])
        raise DataError(f"{paths[0]}, {topic} pose {bad}: orientation quaternion is not unit "
                        f"length (norm {norms[bad]:.4f})")
    return Trajectory(np.asarray(stamps)[order],
                      T_from_tum(np.asarray(xyz)[order], q / norms[:, None]))


# -- the description of a bag bench export wrote ----------------------------------------------

def read_description(paths: list[Path]) -> dict | None:
    """The JSON object on ``DESCRIPTION_TOPIC`` (its first message), None when the bag has no
    such topic; a description that is not a JSON object is ignored with a warning."""
    reader = _any_reader(paths)
    try:
        conns = [c for c in reader.connections if c.topic == DESCRIPTION_TOPIC]
        if not conns:
            return None
        for conn, _, raw in reader.messages(connections=conns):
            text = getattr(reader.deserialize(raw, conn.msgtype), "data", "")
            break
        else:
            return None
    finally:
        reader.close()
    try:
        found = json.loads(text)
    except (TypeError, ValueError):
        found = None
    if not isinstance(found, dict):
        warnings.warn(f"{paths[0]}: {DESCRIPTION_TOPIC} is not a JSON object; ignored",
                      stacklevel=3)
        return None
    return found


def described_options(o: Options, d: dict, topics: dict[str, str]) -> Options:
    """``o`` with every option not given taken from the bag's description ``d``."""
    values: dict = {}
    if d.get("points_topic") in topics:
        values["topic"] = d["points_topic"]
    if d.get("ground_truth_topic") in topics and "gt" not in o.model_fields_set:
        values["gt_topic"] = d["ground_truth_topic"]
    T = d.get("T_body_sensor")
    if isinstance(T, list) and np.asarray(T).shape == (4, 4):
        values["T_body_sensor"] = " ".join(f"{float(v):.17g}" for v in np.ravel(T))
    if d.get("sensor_kind") in ("radar", "lidar"):
        values["sensor_kind"] = d["sensor_kind"]
    if isinstance(d.get("sensor_model"), str):
        values["model"] = d["sensor_model"]
    if d.get("doppler_kind") in ("radial", "ego-compensated"):
        values["doppler_kind"] = d["doppler_kind"]
    if isinstance(d.get("fields"), list):
        values["doppler_field"] = "doppler" if "doppler" in d["fields"] else NO_DOPPLER
    if isinstance(d.get("sequence"), str) and d["sequence"]:
        values["name"] = d["sequence"]
    values = {k: v for k, v in values.items() if k not in o.model_fields_set}
    return _options(o, values) if values else o


# -- the sequence ------------------------------------------------------------------------------

def _options(options: Options | None, overrides: dict) -> Options:
    from pydantic import ValidationError

    try:
        o = options or Options()
        return Options.model_validate({**o.model_dump(exclude_unset=True), **overrides}) \
            if overrides else o
    except ValidationError as err:
        raise DataError(f"rosbag options: {err}") from None


class RosbagSequence(Sequence, OpensFromOptions):
    """Doppler scans of one topic of a ROS1 / ROS2 bag, read one message at a time, with
    optional ground truth in the sensor frame (see the module docstring)."""

    Options = Options
    inputs = ("ROS1 .bag file(s) of one recording, or one ROS2 bag (folder with metadata.yaml, "
              ".db3 or .mcap)")
    many_inputs = True

    @classmethod
    def open(cls, paths: list[Path], options: LoaderOptions) -> RosbagSequence:
        return cls(paths, Options.model_validate(options.model_dump(exclude_unset=True)))

    def __init__(self, bags, options: Options | None = None, **overrides) -> None:
        o = _options(options, overrides)
        self.options = o
        paths = [Path(b) for b in ([bags] if isinstance(bags, str | Path) else bags)]
        if not paths:
            raise DataError("rosbag: no bag given")
        for p in paths:
            if not p.exists():
                raise DataError(f"{p}: bag not found")
        self.bags = paths
        self.ros1 = all(_is_ros1(p) for p in paths)
        if not self.ros1 and len(paths) != 1:
            raise DataError(f"{', '.join(map(str, paths))}: give several ROS1 .bag files or "
                            "exactly one ROS2 bag")
        description = read_description(paths)
        o = self.options = described_options(o, description, bag_topics(paths)) \
            if description else o
        if o.gt is not None and o.gt_topic is not None:
            raise DataError("give the ground truth either as a file (gt) or as a topic "
                            "(gt_topic), not both")
        topic = o.topic or self._only_cloud_topic()
        self.topic = topic
        if self.ros1:
            self._index = BagTopic(paths, topic, accept=CLOUD_TYPES)
        else:
            self._index = _Ros2Topic(paths[0], topic, CLOUD_TYPES)
            self._typestore = None
        if len(self._index) == 0:
            raise DataError(f"{paths[0]}: topic {topic} has no messages")
        self.msgtype = self._index.msgtype
        label = ", ".join(map(str, paths))
        stamps = topic_stamps(self._index, o.stamp, label)
        if not np.all(np.isfinite(stamps)):
            bad = int(np.flatnonzero(~np.isfinite(stamps))[0])
            raise DataError(f"{self._index.where(bad)}: message too short for a std_msgs/Header "
                            f"stamp; is {topic} a point cloud?")
        order, dropped = sort_unique_stamps(stamps, label)
        self.name = o.name or paths[0].stem
        T = parse_extrinsic(o.T_body_sensor)
        self.provenance: dict = {
            "loader": "rosbag",
            "bags": [str(p) for p in paths],
            "format": "ros1" if self.ros1 else "ros2",
            "topic": topic,
            "msgtype": self.msgtype,
            "doppler_field": o.doppler_field,
            "doppler_sign": o.doppler_sign,
            "stamp": o.stamp,
            "messages": int(len(stamps)),
            "repeated_stamps_dropped": dropped,
            "T_body_sensor": T.tolist(),
            "nan_points_dropped": 0,
            "description": DESCRIPTION_TOPIC if description else None,
        }
        self.ground_truth = None
        gt, gt_label, mode = self._ground_truth(stamps[order])
        if gt is not None:
            assoc = associate(gt, stamps[order], offset_s=o.time_offset_s,
                              max_gap_s=o.max_gap_s, uncovered=o.uncovered, T_body_sensor=T,
                              gt_file=gt_label, scan_file=label, mode=mode,
                              tolerance_s=1e-6 if mode == "nearest" else 0.0)
            order = order[assoc.keep]
            self.ground_truth = assoc.ground_truth
            self.provenance["gt_association"] = assoc.report
        self._order = order
        self._stamps = stamps[order]
        self.sensor = SensorInfo(o.sensor_kind, median_period(self._stamps, DEFAULT_PERIOD_S),
                                 T, o.model, o.doppler_kind)

    def _only_cloud_topic(self) -> str:
        topics = bag_topics(self.bags)
        clouds = sorted(t for t, m in topics.items() if m in CLOUD_TYPES)
        if len(clouds) != 1:
            have = ", ".join(f"{t} ({m})" for t, m in sorted(topics.items()))
            raise DataError(f"{self.bags[0]}: {len(clouds)} PointCloud2 / PointCloud topics; "
                            f"choose one with --topic (the bag has {have or 'no topics'})")
        return clouds[0]

    def _ground_truth(self, scan_stamps: np.ndarray):
        o = self.options
        if o.gt_topic is not None:
            return read_gt_topic(self.bags, o.gt_topic), f"{self.bags[0]}:{o.gt_topic}", \
                "interpolate"
        if o.gt is None:
            return None, None, None
        if not Path(o.gt).is_file():
            raise DataError(f"{o.gt}: ground-truth file not found")
        fmt = detect_pose_format(o.gt) if o.gt_format == "auto" else o.gt_format
        if fmt == "kitti":
            rows = read_gt_file(o.gt, "kitti")
            if len(rows) != len(scan_stamps):
                raise DataError(
                    f"{o.gt}: {len(rows)} KITTI pose rows but {self.topic} has "
                    f"{len(scan_stamps)} scans; a KITTI file has no stamps and needs exactly "
                    "one row per scan"
                )
            shifted = scan_stamps - o.time_offset_s
            return Trajectory(shifted, rows.poses), str(o.gt), "nearest"
        return read_gt_file(o.gt, fmt), str(o.gt), "interpolate"

    def __len__(self) -> int:
        return len(self._order)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def _columns(self, k: int, where: str) -> dict[str, np.ndarray]:
        data = self._index.raw(k)
        if self.ros1:
            return _cloud_from_ros1(data, self.msgtype, where)
        if self._typestore is None:
            self._typestore = _ros2_typestore()
        try:
            msg = self._typestore.deserialize_cdr(data, self.msgtype)
        except Exception as err:  # rosbags raises assorted errors on bad bytes
            raise DataError(f"{where}: cannot deserialize {self.msgtype} ({err})") from None
        return _cloud_from_ros2(msg, self.msgtype, where)

    def scan(self, index: int) -> Scan:
        k = int(self._order[index])
        where = f"{self._index.where(k)} (frame {index})"
        cols = self._columns(k, where)
        dname = self.options.doppler_field
        missing = [f for f in ("x", "y", "z") if f not in cols]
        if missing:
            raise DataError(f"{where}: no {', '.join(missing)} field(s); fields are "
                            f"{' '.join(cols)}")
        if dname != NO_DOPPLER and dname not in cols:
            raise DataError(f"{where}: no Doppler field {dname!r}; the {self.msgtype} has "
                            f"{' '.join(cols)} (name it with --doppler-field, option "
                            f"doppler_field; --doppler-field {NO_DOPPLER}: scans without Doppler)")
        points = np.column_stack([cols["x"], cols["y"], cols["z"]]).astype(np.float64)
        doppler = None if dname == NO_DOPPLER else \
            cols[dname].astype(np.float64) * self.options.doppler_sign
        fields = {}
        for name, values in cols.items():
            if name in ("x", "y", "z", dname):
                continue
            key = name.lower()
            if key in ("x", "y", "z", "doppler") or key in fields:
                key = f"field_{key}"
            fields[key] = np.asarray(values, dtype=np.float32)
        return finish_scan(float(self._stamps[index]), points, doppler, fields, where,
                           self.provenance)

    def close(self) -> None:
        self._index.close()

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        if "_typestore" in state:
            state["_typestore"] = None
        return state
