"""The "Campus" sequences (sparse 4D radar, ZF FRGen21, about 16.7 Hz) from ROS1 bags.

- Radar topic (default ``/radar_scan``) of the custom type ``msgs_radar/RadarScanExtended``.
  The type is registered with rosbags from the definition stored in the bag itself; when a bag
  carries none, from the built-in .msg text below (``RADAR_SCAN_MSG`` / ``RADAR_TARGET_MSG``,
  whose six ``mean_square_error_*`` names are plausible guesses: only range, azimuth,
  elevation and velocity are required, every other target field is kept under its own name).
- There is no xyz: ``x = r cos(el) cos(az)``, ``y = r cos(el) sin(az)``,
  ``z = elevation_sign * r sin(el)``. The sign of the elevation is disputed in third-party code;
  check it with ``low_points_median_z`` (the road surface must come out below the sensor).
- Doppler = ``doppler_sign * velocity``; +1 assumes the radar reports the range rate
  (positive = receding) like the other datasets. Verify with the ego-velocity check described
  in loaders/README.md (a static scene ahead of a forward-moving car must read negative).
- Ground truth: a ``nav_msgs/Odometry`` topic (default ``/ground_truth``, NovAtel GNSS/INS in
  UTM, 50 Hz) or a TUM file; the first GT position is subtracted (UTM origin removed; stored in
  ``provenance["gt_origin_removed"]``), the extrinsic ``T_body_radar`` (default identity:
  UNKNOWN for this dataset) is applied.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.assemble import finish_scan
from loaders.bag_sequence import BagRadarSequence
from loaders.doppler_check import low_points_median_z  # noqa: F401 (re-exported)
from loaders.errors import DataError
from loaders.gt import remove_origin
from loaders.layout import require_files
from loaders.options import GroundTruthTimeOptions, OpensFromOptions
from loaders.posefile import parse_extrinsic, read_gt_file
from loaders.ros1 import iter_topic_messages, make_typestore, register_bag_definition
from loaders.ros1_msgs import Cursor
from loaders.scan import Scan
from loaders.se3 import T_from_tum
from loaders.trajectory import Trajectory

SCAN_TYPE = "msgs_radar/msg/RadarScanExtended"
TARGET_TYPE = "msgs_radar/msg/RadarTargetExtended"
ODOMETRY = "nav_msgs/msg/Odometry"
REQUIRED_TARGET_FIELDS = ("range", "azimuth", "elevation", "velocity")

RADAR_TARGET_MSG = """\
float32 range
float32 azimuth
float32 elevation
float32 velocity
float32 snr
float32 power
float32 rcs
float32 detectionconfidence
float32 mean_square_error_range
float32 mean_square_error_velocity
float32 mean_square_error_azimuth
float32 mean_square_error_elevation
float32 mean_square_error_rcs
float32 mean_square_error_power
float32 std_dev_range
float32 std_dev_velocity
float32 std_dev_azimuthAngle
float32 std_dev_elevationAngle
float32 std_dev_rcs
"""

RADAR_SCAN_MSG = """\
std_msgs/Header header
msgs_radar/RadarTargetExtended[] targets
float32 umabiguos_int_range
float32 umabiguos_int_velocity
float32 umabiguos_int_azimuth
float32 umabiguos_int_elevation
"""

DEFAULT_PERIOD_S = 0.06
DEFAULT_MAX_GAP_S = 0.2


class Options(GroundTruthTimeOptions):
    """``bench convert campus`` / a dataset config's ``options``."""

    topic: str = Field("/radar_scan", description="radar topic (msgs_radar/RadarScanExtended)")
    gt_topic: str | None = Field("/ground_truth", description="nav_msgs/Odometry GT topic "
                                 "in the bags ('' for none)")
    gt: Path | None = Field(None, description="TUM GT file instead of the topic")
    elevation_sign: Literal[1.0, -1.0] = Field(
        1.0, description="z = sign * r sin(el); check with `bench inspect` (road below the "
        "sensor)")
    doppler_sign: Literal[1.0, -1.0] = Field(1.0, description="doppler = sign * velocity")
    T_body_radar: str | None = Field(
        None, json_schema_extra={"cli": "extrinsic"},
        description='radar -> GT body "x y z qx qy qz qw" (default identity: unknown)')
    remove_gt_origin: bool = Field(
        True, json_schema_extra={"cli": "remove-gt-origin/keep-utm"},
        description="subtract the first GT position (--keep-utm keeps the UTM origin)")
    stamp: Literal["header", "record"] = Field(
        "header", description="scan stamps: header (header.stamp) or record (bag record time)")


def campus_typestore():
    """ROS1 type store with the built-in msgs_radar definitions registered."""
    return make_typestore({TARGET_TYPE: RADAR_TARGET_MSG, SCAN_TYPE: RADAR_SCAN_MSG})


def spherical_to_xyz(r, az, el, elevation_sign: float = 1.0) -> np.ndarray:
    """(N,) range [m], azimuth and elevation [rad] -> (N, 3) sensor-frame points."""
    r = np.asarray(r, dtype=np.float64)
    az = np.asarray(az, dtype=np.float64)
    el = np.asarray(el, dtype=np.float64)
    ce = np.cos(el)
    return np.column_stack([r * ce * np.cos(az), r * ce * np.sin(az),
                            elevation_sign * r * np.sin(el)])


class CampusSequence(OpensFromOptions, BagRadarSequence):
    """Campus radar scans streamed from ROS1 bags.

    bags: bag files (merged in time order). topic: radar topic. gt_topic: nav_msgs/Odometry
    topic in the same bags (used when ``gt`` is None; pass ``gt_topic=None`` for no GT).
    gt: a TUM file instead of the topic. elevation_sign: +1 (default) or -1 for z.
    doppler_sign: +1 (default: ``velocity`` is the range rate) or -1. T_body_radar: extrinsic
    (default identity: unknown). remove_gt_origin: subtract the first GT position (UTM ->
    local). time_offset_s: ``gt_stamp + time_offset_s = header.stamp``. max_gap_s: largest GT gap
    interpolated across (GT at 50 Hz). uncovered: "keep" | "trim" | "error".
    stamp: "header" (header.stamp, default) or "record" (bag record time).
    """

    Options = Options
    inputs = "ROS1 bag(s) with RadarScanExtended, merged in time order"
    many_inputs = True

    @classmethod
    def open(cls, paths: list[Path], options: Options) -> CampusSequence:
        o = options
        paths = require_files(paths, "Campus bag(s)")
        gt = require_files([o.gt], "ground truth")[0] if o.gt is not None else None
        return cls(paths, topic=o.topic, gt_topic=o.gt_topic or None, gt=gt,
                   elevation_sign=o.elevation_sign, doppler_sign=o.doppler_sign,
                   T_body_radar=o.T_body_radar, remove_gt_origin=o.remove_gt_origin,
                   time_offset_s=o.time_offset_s, uncovered=o.uncovered, stamp=o.stamp,
                   max_gap_s=DEFAULT_MAX_GAP_S if o.max_gap_s is None else o.max_gap_s,
                   name=o.name)

    def __init__(
        self,
        bags: list[Path] | list[str] | Path | str,
        topic: str = "/radar_scan",
        gt_topic: str | None = "/ground_truth",
        gt: Path | str | None = None,
        elevation_sign: float = 1.0,
        doppler_sign: float = 1.0,
        T_body_radar: str | np.ndarray | None = None,
        remove_gt_origin: bool = True,
        time_offset_s: float = 0.0,
        max_gap_s: float = DEFAULT_MAX_GAP_S,
        uncovered: str = "keep",
        stamp: str = "header",
        name: str | None = None,
    ) -> None:
        for label, v in (("elevation_sign", elevation_sign), ("doppler_sign", doppler_sign)):
            if float(v) not in (1.0, -1.0):
                raise DataError(f"{label} must be +1 or -1, got {v}")
        self.elevation_sign = float(elevation_sign)
        self.doppler_sign = float(doppler_sign)
        self._open_topic(bags, topic)
        self.name = name or self.bags[0].stem
        if self._index.msgtype != SCAN_TYPE:
            raise DataError(
                f"{self.bags[0]}: topic {topic} has type {self._index.msgtype}; expected "
                f"{SCAN_TYPE} (header, RadarTargetExtended[] targets with fields "
                f"{', '.join(REQUIRED_TARGET_FIELDS)}, ...)"
            )
        self._setup_types()
        stamps, order, dup = self._frame_stamps(stamp)
        where = self.where
        T = parse_extrinsic(T_body_radar)
        self.provenance: dict = {
            "loader": "campus",
            "bags": [str(b) for b in self.bags],
            "topic": topic,
            "target_fields": self._target_names,
            "elevation_sign": self.elevation_sign,
            "doppler_sign": self.doppler_sign,
            "stamp": stamp,
            "messages": int(len(stamps)),
            "repeated_stamps_dropped": dup,
            "T_body_radar": T.tolist(),
            "extrinsic_note": "radar extrinsic unknown for this dataset (identity by default)",
            "nan_points_dropped": 0,
        }
        gt_traj, gt_label = None, None
        if gt is not None:
            gt_traj, gt_label = read_gt_file(gt, "tum"), str(gt)
        elif gt_topic:
            gt_traj = read_odometry(self.bags, gt_topic)
            gt_label = f"{gt_topic} in {where}"
        fix = None
        if gt_traj is not None and remove_gt_origin:
            _, origin = remove_origin(gt_traj)
            fix = np.eye(4)
            fix[:3, 3] = -origin
            self.provenance["gt_origin_removed"] = origin.tolist()
        self._finish(stamps, order, gt_traj, gt_label, T, DEFAULT_PERIOD_S,
                     "radar-sparse (ZF FRGen21)", offset_s=time_offset_s, max_gap_s=max_gap_s,
                     T_world_fix=fix, uncovered=uncovered)

    def _setup_types(self) -> None:
        store = make_typestore(None)
        from_bag = register_bag_definition(store, SCAN_TYPE, self._index.msgdef)
        if not from_bag:
            store = campus_typestore()
        scan_fields = dict(store.fielddefs[SCAN_TYPE][1])
        where = f"{self.bags[0]}: {SCAN_TYPE}"
        targets = scan_fields.get("targets")
        if targets is None or targets[0].name != "SEQUENCE" or targets[1][0][1] != TARGET_TYPE:
            raise DataError(
                f"{where}: expected a field 'RadarTargetExtended[] targets'; the definition "
                f"has {list(scan_fields)}"
            )
        tfields = store.fielddefs[TARGET_TYPE][1]
        names = [n for n, _ in tfields]
        missing = [f for f in REQUIRED_TARGET_FIELDS if f not in names]
        if missing:
            raise DataError(
                f"{where}: RadarTargetExtended lacks {missing}; expected fields "
                f"{', '.join(REQUIRED_TARGET_FIELDS)} (+ snr, power, rcs, ...), found {names}"
            )
        self._target_names = names
        self._store = store
        self._fast_dtype = None
        all_f32 = all(t[0].name == "BASE" and t[1] == ("float32", 0) for _, t in tfields)
        first = list(scan_fields)[:2] == ["header", "targets"]
        if all_f32 and first:
            self._fast_dtype = np.dtype([(n, "<f4") for n in names])

    def _targets(self, data: bytes, where: str) -> tuple[float, dict[str, np.ndarray]]:
        if self._fast_dtype is not None:
            c = Cursor(data, where)
            stamp, _ = c.header()
            n = c.u32()
            arr = c.array(self._fast_dtype, n)
            return stamp, {name: arr[name] for name in self._target_names}
        try:
            msg = self._store.deserialize_ros1(data, SCAN_TYPE)
        except Exception as err:
            raise DataError(f"{where}: cannot deserialize {SCAN_TYPE} ({err})") from None
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        cols = {name: np.array([float(getattr(t, name)) for t in msg.targets])
                for name in self._target_names}
        return stamp, cols

    def scan(self, index: int) -> Scan:
        k = int(self._order[index])
        where = f"{self._index.where(k)} (frame {index})"
        _, cols = self._targets(self._index.raw(k), where)
        points = spherical_to_xyz(cols["range"], cols["azimuth"], cols["elevation"],
                                  self.elevation_sign)
        doppler = self.doppler_sign * np.asarray(cols["velocity"], dtype=np.float64)
        fields = {name.lower(): np.asarray(v, dtype=np.float32)
                  for name, v in cols.items() if name != "velocity"}
        return finish_scan(float(self._stamps[index]), points, doppler, fields, where,
                           self.provenance)


def read_odometry(bags: list[Path], topic: str) -> Trajectory:
    """All ``nav_msgs/Odometry`` poses of ``topic`` (stamp = header.stamp) as a Trajectory."""
    store = make_typestore(None)
    stamps, xyz, quat = [], [], []
    for msg, _ in iter_topic_messages(bags, topic, store, accept=(ODOMETRY,)):
        st = msg.header.stamp
        stamps.append(st.sec + st.nanosec * 1e-9)
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        xyz.append((p.x, p.y, p.z))
        quat.append((q.x, q.y, q.z, q.w))
    if not stamps:
        raise DataError(f"{bags[0]}: ground-truth topic {topic} has no messages")
    # messages come in record order (bag by bag); the poses' own clock is header.stamp
    order = np.argsort(np.asarray(stamps), kind="stable")
    stamps = list(np.asarray(stamps)[order])
    xyz = list(np.asarray(xyz)[order])
    quat = list(np.asarray(quat)[order])
    q = np.asarray(quat, dtype=np.float64)
    norms = np.linalg.norm(q, axis=1)
    if np.any(norms < 1e-6):
        raise DataError(f"{bags[0]}: {topic} has {int((norms < 1e-6).sum())} zero quaternions")
    return Trajectory(np.asarray(stamps), T_from_tum(np.asarray(xyz), q / norms[:, None]))
