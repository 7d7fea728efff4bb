"""NTU4DRadLM (semi-dense 4D radar, Oculii Eagle, about 12 Hz) from its ROS1 bags.

- Radar topic (default ``/radar_enhanced_pcl``) of type ``sensor_msgs/PointCloud``: Point32
  points and named float32 channels, matched by NAME (never by index): ``Doppler`` -> Scan
  doppler, ``Power`` -> field ``power``, any other channel -> a per-point field with the
  lowercased name. ``sensor_msgs/PointCloud2`` is also accepted (the Doppler field name is
  configurable: "doppler", "velocity", ...).
- Scan stamp = ``header.stamp`` (sensor clock). Frames from several bags are merged and sorted
  by stamp; repeated stamps are dropped with a warning.
- Ground truth ``gt_odom.txt`` (TUM, optional header line; R2LIVE pseudo ground truth) is
  associated by time (``gt_stamp + time_offset_s = header.stamp``), interpolated at the scan
  stamps and moved into the radar frame with ``T_gtbody_radar``. Scans it does not cover stay
  in the sequence and are excluded from scoring (counted in ``provenance["gt_association"]``).
- Doppler is the raw relative radial velocity (positive = receding, not ego-compensated).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.assemble import finish_scan
from loaders.bag_sequence import BagRadarSequence
from loaders.errors import DataError
from loaders.layout import require_files
from loaders.options import GroundTruthTimeOptions, OpensFromOptions
from loaders.posefile import parse_extrinsic, read_gt_file
from loaders.ros1_msgs import parse_pointcloud, parse_pointcloud2
from loaders.scan import Scan

POINTCLOUD = "sensor_msgs/msg/PointCloud"
POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"

#: Radar -> GT body (R2LIVE, probably the Livox LiDAR/IMU) extrinsic, TUM order
#: "x y z qx qy qz qw". Translation from public SLAM code for this dataset, rotation taken as
#: identity. UNCONFIRMED: the GT body frame itself is not documented by the dataset.
DEFAULT_T_GTBODY_RADAR = "0.296 -0.130 -0.005 0 0 0 1"
DEFAULT_PERIOD_S = 1.0 / 12.0
DEFAULT_MAX_GAP_S = 0.5


class Options(GroundTruthTimeOptions):
    """``bench convert ntu4dradlm`` / a dataset config's ``options``."""

    gt: Path | None = Field(None, description="gt_odom.txt (TUM, R2LIVE)")
    topic: str = Field("/radar_enhanced_pcl", description="radar topic (PointCloud or "
                       "PointCloud2); /radar_pcl is the sparser cloud")
    doppler_field: str = Field("Doppler", description="Doppler channel / PointField name")
    T_gtbody_radar: str = Field(
        DEFAULT_T_GTBODY_RADAR, json_schema_extra={"cli": "extrinsic"},
        description='radar -> GT body "x y z qx qy qz qw" or 16 numbers (default: '
        "0.296 -0.130 -0.005, identity rotation; unconfirmed)")
    doppler_sign: Literal[1.0, -1.0] = Field(1.0, description="+1 or -1")
    stamp: Literal["header", "record"] = Field(
        "header", description="scan stamps: header (header.stamp) or record (bag record time)")


class NtuSequence(OpensFromOptions, BagRadarSequence):
    """NTU4DRadLM radar scans streamed from ROS1 bags.

    bags: one or more bags of one route (e.g. ``ntu-car-day-loop1_2022-06-03_{0..4}.bag``),
    merged in time order. gt: ``gt_odom.txt`` or None. topic: radar topic. doppler_field:
    channel (PointCloud) or PointField (PointCloud2) name holding Doppler [m/s].
    T_gtbody_radar: "x y z qx qy qz qw", 16 numbers or a 4x4 array (GT body <- radar).
    time_offset_s: ``gt_stamp + time_offset_s = header.stamp``. max_gap_s: largest GT gap
    interpolated across. uncovered: "keep" | "trim" | "error" (see ``loaders.gt.associate``).
    doppler_sign: multiply the Doppler channel by this (+1: already positive = receding).
    stamp: "header" (header.stamp, default) or "record" (bag record time, for drivers that
    leave header.stamp unset). name: sequence name (default: first bag's stem).
    """

    Options = Options
    inputs = "ROS1 bag(s) of one route, merged in time order"
    many_inputs = True

    @classmethod
    def open(cls, paths: list[Path], options: Options) -> NtuSequence:
        o = options
        paths = require_files(paths, "NTU4DRadLM bag(s)")
        gt = require_files([o.gt], "ground truth")[0] if o.gt is not None else None
        return cls(paths, gt=gt, topic=o.topic, doppler_field=o.doppler_field,
                   T_gtbody_radar=o.T_gtbody_radar, doppler_sign=o.doppler_sign,
                   stamp=o.stamp, name=o.name, time_offset_s=o.time_offset_s,
                   max_gap_s=DEFAULT_MAX_GAP_S if o.max_gap_s is None else o.max_gap_s,
                   uncovered=o.uncovered)

    def __init__(
        self,
        bags: list[Path] | list[str] | Path | str,
        gt: Path | str | None = None,
        topic: str = "/radar_enhanced_pcl",
        doppler_field: str = "Doppler",
        T_gtbody_radar: str | np.ndarray | None = DEFAULT_T_GTBODY_RADAR,
        time_offset_s: float = 0.0,
        max_gap_s: float = DEFAULT_MAX_GAP_S,
        uncovered: str = "keep",
        doppler_sign: float = 1.0,
        stamp: str = "header",
        name: str | None = None,
    ) -> None:
        self._open_topic(bags, topic, accept=(POINTCLOUD, POINTCLOUD2))
        self.doppler_field = doppler_field
        self.doppler_sign = float(doppler_sign)
        if self.doppler_sign not in (1.0, -1.0):
            raise DataError(f"doppler_sign must be +1 or -1, got {doppler_sign}")
        self.name = name or self.bags[0].stem
        stamps, order, dup = self._frame_stamps(stamp)
        T = parse_extrinsic(T_gtbody_radar)
        self.provenance: dict = {
            "loader": "ntu4dradlm",
            "bags": [str(b) for b in self.bags],
            "topic": topic,
            "msgtype": self._index.msgtype,
            "doppler_field": doppler_field,
            "doppler_sign": self.doppler_sign,
            "stamp": stamp,
            "messages": int(len(stamps)),
            "repeated_stamps_dropped": dup,
            "T_gtbody_radar": T.tolist(),
            "extrinsic_note": "radar->GT body extrinsic unconfirmed (default from public SLAM "
                              "code, identity rotation)",
            "nan_points_dropped": 0,
        }
        self._finish(stamps, order, read_gt_file(gt, "tum") if gt is not None else None,
                     str(gt) if gt is not None else None, T, DEFAULT_PERIOD_S,
                     "radar-semidense (Oculii Eagle)", offset_s=time_offset_s,
                     max_gap_s=max_gap_s, uncovered=uncovered)

    def scan(self, index: int) -> Scan:
        k = int(self._order[index])
        where = f"{self._index.where(k)} (frame {index})"
        data = self._index.raw(k)
        if self._index.msgtype == POINTCLOUD:
            _, points, channels = parse_pointcloud(data, where)
            if self.doppler_field not in channels:
                raise DataError(
                    f"{where}: no Doppler channel {self.doppler_field!r}; the PointCloud has "
                    f"channels {sorted(channels)}; name the Doppler channel with --doppler-field "
                    "NAME (bench convert ntu4dradlm)"
                )
            doppler = channels.pop(self.doppler_field).astype(np.float64) * self.doppler_sign
            fields = {}
            for cname, values in channels.items():
                key = cname.lower()
                if key in ("x", "y", "z", "doppler"):
                    key = f"channel_{key}"
                fields[key] = values
        else:
            _, arr, names = parse_pointcloud2(data, where)
            missing = [f for f in ("x", "y", "z") if f not in names]
            if missing:
                raise DataError(
                    f"{where}: PointCloud2 has no {missing} field(s); fields are {names}"
                )
            if self.doppler_field not in names:
                raise DataError(
                    f"{where}: no Doppler field {self.doppler_field!r} in the PointCloud2; "
                    f"fields are {names}; name the Doppler field with --doppler-field NAME (bench "
                    "convert ntu4dradlm)"
                )
            points = np.column_stack([arr["x"], arr["y"], arr["z"]])
            doppler = arr[self.doppler_field].astype(np.float64) * self.doppler_sign
            fields = {}
            for fname in names:
                if fname in ("x", "y", "z", self.doppler_field):
                    continue
                key = fname.lower()
                fields["field_doppler" if key == "doppler" else key] = arr[fname].astype(
                    np.float32)
        return finish_scan(float(self._stamps[index]), points, doppler, fields, where,
                           self.provenance)
