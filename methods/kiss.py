"""KISS-ICP (Vizzo et al., RA-L 2023) through the kiss-icp package: scan-to-map odometry with
its own voxel-hash local map, adaptive threshold and constant-velocity prediction.

Configuration (kiss-icp 1.3): ``max_range_m`` / ``min_range_m`` as its defaults (100 m, 0 m);
the voxel size is set explicitly (it stays unset unless kiss-icp's own config loader runs) to
its rule max_range / 100, i.e. 1.0 m. Deskewing needs per-point times
(``scan.fields['time_offset_s']``) that vary within the scan; with constant times the library
aborts the whole process (SIGABRT), so this wrapper validates first and refuses with a clear
error. ``deskew`` None (default) deskews exactly when the scans carry per-point times.

Threads: kiss-icp fixes its thread count process-wide with the first instance, and
multi-threaded runs are not bit-reproducible, so ``num_threads`` defaults to 1 (reproducible)
and the harness runs every job in its own worker process.

Seed / no seed: with seed, kiss-icp predicts each frame with its constant-velocity model (the
last relative motion); with no seed that prediction is reset to the identity before every
frame (which also turns deskewing's motion model off). Timed: ``register_frame`` per frame
(its preprocessing, voxelisation, registration and map update: KISS-ICP's whole step).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pydantic import Field

from loaders.errors import DataError
from loaders.scan import Scan, SensorInfo, Sequence
from methods.base import FrameRecord, MethodParams, Odometry, OdometryResult
from methods.timing import timed_section


class KissParams(MethodParams):
    max_range_m: float = Field(100.0, gt=0, description="farthest point used [m] (kiss-icp)")
    min_range_m: float = Field(0.0, ge=0, description="nearest point used [m] (kiss-icp)")
    voxel_size_m: float | None = Field(None, gt=0, description="map voxel [m]; None: "
                                       "max_range / 100 (kiss-icp's rule)")
    deskew: bool | None = Field(None, description="None: when scans carry per-point times")
    max_points_per_voxel: int = Field(20, ge=1, description="kiss-icp default")
    num_threads: int = Field(1, ge=1, description="kiss-icp threads (1: reproducible)")


def _times(scan: Scan, frame: int) -> np.ndarray | None:
    """Per-point times of a scan for deskewing, or None when it has none; DataError when they
    cannot be used (kiss-icp would abort the process on constant times)."""
    t = scan.fields.get("time_offset_s")
    if t is None:
        return None
    t = np.asarray(t, dtype=np.float64)
    if not np.all(np.isfinite(t)) or np.ptp(t) <= 0:
        raise DataError(f"{scan.source or f'frame {frame}'}: kiss-icp deskew needs per-point "
                        "times that vary within the scan (time_offset_s is constant or "
                        "non-finite; kiss-icp would abort the process); run with "
                        "-p deskew=false")
    return t


class KissIcp(Odometry):
    name = "kiss-icp"
    description = "KISS-ICP scan-to-map odometry (kiss-icp package; own local map)"
    Params = KissParams

    def __init__(self, params: KissParams | None = None, **overrides) -> None:
        base = params if params is not None else KissParams()
        self.params = (KissParams.model_validate({**base.model_dump(), **overrides})
                       if overrides else base)

    def configured_for(self, sensor: SensorInfo) -> KissIcp:
        if self.params.voxel_size_m is not None:
            return self
        return KissIcp(self.params, voxel_size_m=self.params.max_range_m / 100.0)

    def _kiss(self, deskew: bool):
        from kiss_icp.config import KISSConfig
        from kiss_icp.kiss_icp import KissICP

        p = self.params
        config = KISSConfig()
        config.data.max_range = p.max_range_m
        config.data.min_range = p.min_range_m
        config.data.deskew = deskew
        config.mapping.voxel_size = p.voxel_size_m or p.max_range_m / 100.0
        config.mapping.max_points_per_voxel = p.max_points_per_voxel
        config.registration.max_num_threads = p.num_threads
        return KissICP(config=config)

    def run(self, sequence: Sequence, seed: bool,
            on_frame: Callable[[int], None] | None = None) -> OdometryResult:
        n = len(sequence)
        poses = np.repeat(np.eye(4)[None], n, axis=0)
        stamps = np.empty(n)
        frames: list[FrameRecord] = []
        kiss = None
        for i, scan in enumerate(sequence):
            times = _times(scan, i) if self.params.deskew is not False else None
            if self.params.deskew and times is None:
                raise DataError(f"{scan.source or f'frame {i}'}: deskew=true needs per-point "
                                "times (scan field time_offset_s)")
            if kiss is None:
                kiss = self._kiss(deskew=times is not None)
            if not seed:
                kiss.last_delta = np.eye(4)
            points = np.ascontiguousarray(scan.points, dtype=np.float64)
            with timed_section() as watch:
                _, source = kiss.register_frame(points, times if times is not None
                                                else np.empty(0))
            stamps[i] = scan.stamp
            poses[i] = kiss.last_pose
            frames.append(FrameRecord(i, scan.stamp, watch.time_ms if i else float("nan"),
                                      len(scan), len(source), 0, True))
            if on_frame:
                on_frame(i)
        if n and not np.allclose(poses[0], np.eye(4)):  # first frame = identity
            poses = np.linalg.inv(poses[0]) @ poses
        return OdometryResult(stamps, poses, frames)
