"""The loaders by name: what ``bench convert LOADER`` and ``configs/datasets/*.yaml`` call them,
and the dataset catalogue (``bench datasets``, the README's real-data table) made from the same
rows.

Each entry names the ``Sequence`` class that reads the format; the class is imported only when
used (the bag loaders pull in rosbags), so listing the catalogue imports no loader. An entry
whose module does not exist (yet) is still listed; converting with it says it is unavailable.
Adding a loader = one entry here + one module with its ``Options`` model and ``open()`` (see
``loaders/options.py``) + its test.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from loaders.errors import DataError

if TYPE_CHECKING:  # loaders.scan pulls in numpy and scipy: not needed to list the catalogue
    from loaders.scan import Sequence

#: the paper's sensor classes (``loaders.sensor_classes``), repeated to keep this module light
SPARSE, SEMI_DENSE, DENSE = "Sparse 4D Radar", "Semi-Dense 4D Radar", "Dense 4D LiDAR"


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
    #: further catalogue rows read by the same loader (another sensor of the dataset, another
    #: release of the layout): each a mapping of the catalogue fields that differ
    more_rows: tuple[Mapping[str, str], ...] = field(default=())

    def load_class(self) -> type[Sequence]:
        """The loader's ``Sequence`` class; ``DataError`` when its module is not there."""
        if not self.available:
            raise DataError(f"loader {self.name!r} is listed but unavailable in this "
                            f"installation: module {self.module} not found")
        return getattr(importlib.import_module(self.module), self.cls)

    @property
    def available(self) -> bool:
        """The loader's module exists (found without importing it)."""
        try:
            return importlib.util.find_spec(self.module) is not None
        except ModuleNotFoundError:
            return False

    def rows(self) -> list[LoaderEntry]:
        """The catalogue rows of this loader: itself, then one per ``more_rows`` entry."""
        return [self] + [replace(self, more_rows=(), **dict(r)) for r in self.more_rows]


LOADERS: dict[str, LoaderEntry] = {e.name: e for e in (
    LoaderEntry(
        "ntu4dradlm", "NTU4DRadLM ROS1 bags (sensor_msgs/PointCloud or PointCloud2) + "
        "gt_odom.txt", "loaders.ntu4dradlm", "NtuSequence",
        dataset="NTU4DRadLM (cp, garden, nyl, loop1-3; 17.6 km)",
        sensor="Oculii Eagle 4D radar, ~12 Hz", sensor_class=SEMI_DENSE,
        licence="MIT (repository); download terms on its page",
        published_at="github.com/junzhang2016/NTU4DRadLM (download link in its README)",
        layout="SEQ/*.bag (ROS1, /radar_enhanced_pcl sensor_msgs/PointCloud, channels Doppler, "
               "Power) + SEQ/gt_odom.txt (TUM, R2LIVE)",
        example="bench convert ntu4dradlm data/raw/ntu4dradlm/loop2/loop2_2022-06-03_*.bag "
                "--gt data/raw/ntu4dradlm/loop2/gt_odom.txt --out data/real/NTU4DRadLM_loop2.h5"),
    LoaderEntry(
        "snail-radar", "Snail-Radar ROS1 bags or extracted folders (Oculii Eagle G7 or "
        "Continental ARS548)", "loaders.snail_radar", "SnailRadarSequence",
        dataset="Snail-Radar (44 sequences, 59 m-8.5 km)",
        sensor="Oculii Eagle G7 4D radar", sensor_class=SEMI_DENSE,
        licence="ODbL + DbCL",
        published_at="github.com/snail-radar/dataset_tools (links to the download page)",
        layout="DATE/dataN.bag (ROS1, /radar_enhanced_pcl2 PointCloud2) or the extracted "
               "eagleg7/enhanced/<sec.nsec>.pcd + times.txt; GT from the TLS-localised LIO "
               "(only where the scan map covers), found without --gt: tls_T_xt32.txt, "
               "ref_tls_T_xt32.csv or utm50r_T_xt32.txt in the sequence folder or in "
               "ref_trajs/DATE/dataN/",
        example="bench convert snail-radar data/raw/snail-radar/20231213/data1.bag "
                "--sensor eagle --out data/real/SnailRadar_Eagle_20231213_1.h5",
        more_rows=({"sensor": "Continental ARS548 4D radar", "sensor_class": SPARSE,
                    "layout": "DATE/dataN.bag (ROS1, /ars548 PointCloud2: x y z doppler "
                              "intensity ...) or the extracted ars548/points/<sec.nsec>.pcd + "
                              "times.txt",
                    "example": "bench convert snail-radar data/raw/snail-radar/20231213/"
                               "data1.bag --sensor ars548 --out "
                               "data/real/SnailRadar_ARS548_20231213_1.h5"},)),
    LoaderEntry(
        "vod", "View-of-Delft radar frames (radar/training/velodyne/*.bin + pose/*.json)",
        "loaders.vod", "VodSequence",
        dataset="View-of-Delft", sensor="ZF FRGen21 4D radar, ~10 Hz (no stamps published)",
        sensor_class=SPARSE, licence="research use only (VoD licence agreement)",
        published_at="github.com/tudelft-iv/view-of-delft-dataset (request access)",
        layout="radar/training/velodyne/NNNNN.bin (float32 N x 7: x y z RCS v_r "
               "v_r_compensated time) + pose/NNNNN.json + calib (KITTI-style); clips with gaps",
        example="bench convert vod data/raw/view_of_delft --period 0.1 --out "
                "data/real/VoD.h5"),
    LoaderEntry(
        "coloradar", "ColoRadar single-chip radar point clouds + ground-truth poses",
        "loaders.coloradar", "ColoradarSequence",
        dataset="ColoRadar", sensor="TI AWR1843 single-chip radar", sensor_class=SPARSE,
        licence="see the dataset page (terms not checked here)",
        published_at="arpg.github.io/coloradar (ARPG, CU Boulder)",
        layout="RUN/single_chip/pointclouds/data/radar_pointcloud_<i>.bin (float32 N x 5: x y "
               "z intensity doppler) + timestamps.txt; RUN/groundtruth/groundtruth_poses.txt + "
               "timestamps.txt; calib/transforms/",
        example="bench convert coloradar data/raw/coloradar/ec_hallways_run0 --out "
                "data/real/ColoRadar_ec_hallways_run0.h5"),
    LoaderEntry(
        "helipr", "HeLiPR / HeRCULES Aeva Aeries II frames (LiDAR/Aeva/<t_ns>.bin) + "
        "Aeva_gt.txt", "loaders.helipr", "HeliprSequence",
        dataset="HeLiPR / HeRCULES (Aeva)", sensor="Aeva Aeries II FMCW LiDAR",
        sensor_class=DENSE, doppler_kind="ego-compensated",
        licence="CC BY-NC-SA 4.0 (dataset site; unverified)",
        published_at="sites.google.com/view/heliprdataset",
        layout="SEQ/LiDAR/Aeva/<t_ns>.bin (25 or 29 bytes a point) + "
               "SEQ/LiDAR_GT/Aeva_gt.txt or global_Aeva_gt.txt (t_ns x y z qx qy qz qw)",
        example="bench convert helipr data/raw/helipr/Roundabout01 --out "
                "data/real/HeLiPR_Aeva_Roundabout01.h5"),
    LoaderEntry(
        "aeva", "Aeva / CARLA per-frame folders (Doppler-ICP, Open3D demo, steam_icp "
        "layouts)", "loaders.aeva", "AevaSequence",
        dataset="Doppler-ICP CARLA (Town04 straight walls, Town05 curved walls)",
        sensor="simulated FMCW LiDAR (CARLA), 10 Hz", sensor_class=DENSE,
        licence="MIT (aevainc/Doppler-ICP)",
        published_at="github.com/aevainc/Doppler-ICP (dataset zip linked in its README)",
        layout="SEQ/point_clouds/*.bin (float32 N x 4: x y z doppler) + calibration.json + "
               "ref_poses.txt (TUM); the Open3D demo copy (xyzd_sequence/) loads too",
        example="bench convert aeva data/raw/carla/carla-town04-straight-walls --out "
                "data/real/StraightWall.h5",
        more_rows=({"dataset": "Aeva Aeries I tunnels (Baker-Barry Empty / Vehicles)",
                    "sensor": "Aeva Aeries I FMCW LiDAR, 10 Hz",
                    "licence": "never released by Aeva (Doppler-ICP issue #4)",
                    "published_at": "not public",
                    "layout": "SEQ/frames/*.bin (float32 x y z v t) + timestamps.txt + "
                              "*poses.txt (KITTI), steam_icp's copy",
                    "example": "bench convert aeva data/raw/aeva/00 --layout steam --out "
                               "data/real/Tunnel_Empty.h5"},)),
    LoaderEntry(
        "campus", "Campus (Li, Zhang, Chen, RA-L 2023; ZF FRGen21 sparse 4D radar) ROS1 "
        "bags with msgs_radar/RadarScanExtended + Odometry GT", "loaders.campus",
        "CampusSequence",
        dataset="Campus (Li, Zhang, Chen, RA-L 2023)", sensor="ZF FRGen21 4D radar, ~16.7 Hz",
        sensor_class=SPARSE, licence="not a public download",
        published_at="not public (ask the authors)",
        layout="Campus_N.bag (ROS1, /radar_scan msgs_radar/RadarScanExtended, /ground_truth "
               "nav_msgs/Odometry)",
        example="bench convert campus data/raw/campus/Campus_1.bag --out "
                "data/real/Campus1.h5"),
    LoaderEntry(
        "rosbag", "any ROS1 or ROS2 bag (sqlite3, mcap) with a PointCloud2 / PointCloud topic "
        "and a named Doppler field", "loaders.rosbag", "RosbagSequence",
        dataset="your own recording (generic ROS bag)", sensor="any radar / FMCW LiDAR",
        sensor_class="set per recording", licence="yours",
        published_at="-",
        layout="a ROS1 .bag or ROS2 bag folder (sqlite3 / mcap) with a PointCloud2 or "
               "PointCloud topic and a Doppler field; GT from a TUM / KITTI file or an "
               "Odometry / PoseStamped topic",
        example="bench convert rosbag my_run/ --topic /radar/points --doppler-field velocity "
                "--gt gt_tum.txt --out data/real/MyRun.h5"),
    LoaderEntry(
        "npy-frames", "NumPy frame folders: frame_XXX.npy + frame_XXX_dop.npy + a TUM "
        "file", "loaders.npy_frames", "NpyFramesSequence",
        dataset="NumPy frames (the paper's reference-code format)",
        sensor="any radar / FMCW LiDAR (--kind)", sensor_class="set per recording",
        licence="yours", published_at="-",
        layout="DIR[/frames]/frame_XXX.npy (N x 3) + frame_XXX_dop.npy (N) + one TUM .txt",
        example="bench convert npy-frames path/to/frames --period 0.0833333 --model "
                "radar-semidense --out data/real/my-sequence.h5"),
)}


def get_loader(name: str) -> LoaderEntry:
    try:
        return LOADERS[name]
    except KeyError:
        from loaders.errors import did_you_mean

        raise DataError(f"unknown loader {name!r}{did_you_mean(name, LOADERS)}; expected one "
                        f"of {', '.join(LOADERS)}") from None


def catalogue() -> list[LoaderEntry]:
    """Every catalogue row (one or more per loader), in the table's order."""
    return [row for entry in LOADERS.values() for row in entry.rows()]
