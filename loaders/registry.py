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
)}


def get_loader(name: str) -> LoaderEntry:
    try:
        return LOADERS[name]
    except KeyError:
        raise DataError(f"unknown loader {name!r}; expected one of {', '.join(LOADERS)}") from None
