"""The loaders by name: what ``bench convert LOADER`` and ``configs/datasets/*.yaml`` call them.

Each entry names the ``Sequence`` class that reads the format; the class is imported only when
used (the bag loaders pull in rosbags).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from loaders.errors import DataError
from loaders.scan import Sequence


@dataclass(frozen=True)
class LoaderEntry:
    """One loader and its catalogue facts (``bench datasets`` and the README's real-data table
    are made from these)."""

    name: str
    description: str
    module: str
    cls: str
    #: catalogue: dataset name, sensor, sensor class, Doppler kind (see ``loaders.scan``),
    #: licence, where its owners publish it, the layout the loader expects, an exact command
    dataset: str = ""
    sensor: str = ""
    sensor_class: str = ""
    doppler_kind: str = "radial"
    licence: str = ""
    published_at: str = ""
    layout: str = ""
    example: str = ""

    def load_class(self) -> type[Sequence]:
        return getattr(importlib.import_module(self.module), self.cls)


LOADERS: dict[str, LoaderEntry] = {e.name: e for e in (
    LoaderEntry("npy-frames", "NumPy frame folders: frame_XXX.npy + frame_XXX_dop.npy + a TUM "
                "file", "loaders.npy_frames", "NpyFramesSequence"),
    LoaderEntry("ntu4dradlm", "NTU4DRadLM ROS1 bags (sensor_msgs/PointCloud or PointCloud2) + "
                "gt_odom.txt", "loaders.ntu4dradlm", "NtuSequence"),
    LoaderEntry("campus", "Campus (Li, Zhang, Chen, RA-L 2023; ZF FRGen21 sparse 4D radar) ROS1 "
                "bags with msgs_radar/RadarScanExtended + Odometry GT", "loaders.campus",
                "CampusSequence"),
    LoaderEntry("aeva", "Aeva / CARLA per-frame folders (Doppler-ICP, Open3D demo, steam_icp "
                "layouts)", "loaders.aeva", "AevaSequence"),
    LoaderEntry("snail-radar", "Snail-Radar (Oculii Eagle G7 or Continental ARS548) from a "
                "sequence's ROS1 bag or extracted PCD folders + a TUM file of T_world_xt32",
                "loaders.snail_radar", "SnailRadarSequence",
                dataset="Snail-Radar", sensor="Oculii Eagle G7 / Continental ARS548 (--sensor)",
                sensor_class="Semi-Dense 4D Radar (Eagle) / Sparse 4D Radar (ARS548)",
                doppler_kind="radial", licence="ODbL 1.0 + DbCL 1.0",
                published_at="https://snail-radar.github.io (tools: "
                "github.com/snail-radar/dataset_tools)",
                layout="<day>/dataN.bag (/radar_enhanced_pcl2, /radar_pcl2, /ars548) or "
                "<day>/dataN/{eagleg7/enhanced,eagleg7/pcl,ars548/points}/<sec.nsec>.pcd + "
                "times.txt; GT: TUM rows of the XT32 lidar pose",
                example="bench convert snail-radar data/raw/snail-radar/20240123/data3 "
                "--gt data/raw/snail-radar/20240123/data3/utm50r_T_xt32.txt --sensor eagle"),
    LoaderEntry("rosbag", "Your own recording: ROS1 bag(s) or a ROS2 bag (sqlite3 / mcap) with "
                "a PointCloud2 / PointCloud topic, a named Doppler field and GT from a topic "
                "or a TUM / KITTI file", "loaders.rosbag", "RosbagSequence",
                dataset="your own ROS recording", sensor="any Doppler radar / FMCW LiDAR",
                sensor_class="set --model (radar-sparse, radar-semidense, lidar-dense)",
                doppler_kind="radial (or --doppler-kind ego-compensated)", licence="yours",
                published_at="-",
                layout="rec.bag [rec_1.bag ...] or rec/ (metadata.yaml + .db3 / .mcap) or "
                "rec.mcap / rec.db3",
                example="bench convert rosbag rec.mcap --topic /radar/points --doppler-field "
                "doppler --gt-topic /odom --T-body-sensor '1.2 0 1.5 0 0 0 1'"),
)}


def get_loader(name: str) -> LoaderEntry:
    try:
        return LOADERS[name]
    except KeyError:
        raise DataError(f"unknown loader {name!r}; expected one of {', '.join(LOADERS)}") from None
