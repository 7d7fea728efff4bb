"""KISS-ICP (Vizzo et al., RA-L 2023) through the kiss-icp package (1.3): scan-to-map odometry
with its own voxel-hash local map, adaptive threshold and constant-velocity prediction.

Frames: poses are T_world_sensor of each scan, the first one the identity [m].

Configuration (set explicitly, so a run records it; kiss-icp leaves the voxel size unset
unless its own config loader runs): ``min_range_m`` is kiss-icp's 0 m. ``max_range_m`` comes
from the data, not a constant: None (default) takes the farthest point of the first scan,
rounded up to the next 10 m, when the run starts (one-time set-up, before the first frame), so
kiss-icp's range crop keeps whole scans and its local map keeps what the sensor sees. The old
fixed 100 m (kiss-icp's default, set when the synthetic radar scans reached 99.4 m) threw away
4-35 % of each real Oculii Eagle scan of NTU4DRadLM, which reaches 140-260 m. A value given
explicitly is used as it is. The voxel size follows kiss-icp's own rule (its config loader:
``voxel_size = max_range / 100``) at the range actually used: ``voxel_size_m`` None (default)
is ``max_range / range_per_voxel`` with ``range_per_voxel`` 100 (kiss-icp's), so a real Eagle
run whose first scan reaches 200 m maps with 2.0 m voxels. kiss-icp registers a 1.5 x voxel
subsample of each scan and maps a 0.5 x voxel subsample. ``range_per_voxel`` stays kiss-icp's
100: the cross-validated sweep configs/tuning/kiss-icp-radar-voxel.yaml (the rule of
configs/splits.yaml) decides whether another ratio may replace it. A ``voxel_size_m`` given
explicitly is used as it is.

Deskewing needs per-point times (``scan.fields['time_offset_s']``) that vary within each scan;
with constant times the library aborts the whole process (SIGABRT), so every scan is checked
first and a bad one is refused with a DataError naming the frame. ``deskew`` None (default)
deskews exactly when the first scan carries per-point times; then every scan must.

Threads: kiss-icp fixes its thread count process-wide with the first instance (a static
``tbb::global_control`` in its C++ ``Registration``; a later instance with another count keeps
the first one), and multi-threaded runs are not bit-reproducible, so ``num_threads`` defaults
to 1 (reproducible). Each run honours its own count: a run whose count differs from the one
this process's first instance fixed runs (warm-up and timed run) in a fresh process
(``_run_in_fresh_process``), so ``bench speed --threads N`` times N threads and a one-thread
run after an N-thread one (the notebook API, ``--executor local``) times one.

Seed / no seed: with seed, kiss-icp predicts each frame with its constant-velocity model (its
``last_delta``, the last relative motion); with no seed ``last_delta`` is reset to the identity
before every frame, so the prediction is the last pose (and deskewing sees no motion).

Timing (``methods.base``): ``time_ms`` = kiss-icp's whole ``register_frame`` (deskewing,
voxelisation, the adaptive threshold, registration and the map update) plus the checks of the
per-point times; ``register_ms`` = its registration call alone (``align_points_to_map``:
correspondence search in the local map and the robust Gauss-Newton iterations).
``correspondences`` records the points kiss-icp registers (its 1.5 x voxel subsample); kiss-icp
does not report iterations (recorded as 0).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pydantic import Field

from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo, Sequence
from methods.base import FrameRecord, MethodParams, Odometry, OdometryResult, Presentation
from methods.timing import stopwatch, timed_section


class KissParams(MethodParams):
    max_range_m: float | None = Field(
        None, gt=0, description="farthest point used [m] (kiss-icp's crop and map range); "
        "None: the first scan's farthest point, rounded up to 10 m (keeps whole scans)")
    min_range_m: float = Field(0.0, ge=0, description="nearest point used [m] (kiss-icp)")
    voxel_size_m: float | None = Field(
        None, gt=0, description="map voxel [m]; None: kiss-icp's rule, the range used / "
        "range_per_voxel")
    range_per_voxel: float = Field(100.0, gt=0, description="kiss-icp's config loader: "
                                   "voxel_size = max_range / 100")
    deskew: bool | None = Field(None, description="None: when scans carry per-point times")
    max_points_per_voxel: int = Field(20, ge=1, description="kiss-icp default")
    num_threads: int = Field(1, ge=1, description="kiss-icp threads (1: reproducible)")


def _where(scan: Scan, frame: int) -> str:
    return scan.source or f"frame {frame}"


def point_times(scan: Scan, frame: int) -> np.ndarray | None:
    """Per-point times [s] of a scan for deskewing, or None when it has none; DataError when
    they cannot be used (kiss-icp would abort the process on constant times)."""
    t = scan.fields.get("time_offset_s")
    if t is None:
        return None
    t = np.asarray(t, dtype=np.float64)
    if t.shape != (len(scan),) or not np.all(np.isfinite(t)) or np.ptp(t) <= 0:
        raise DataError(f"{_where(scan, frame)}: kiss-icp deskew needs one finite per-point "
                        f"time per point that varies within the scan (time_offset_s is "
                        f"constant, non-finite or of the wrong length; kiss-icp would abort "
                        f"the process); run with -p deskew=false")
    return t


def data_range_m(scan: Scan) -> float:
    """The range that keeps all of ``scan``: its farthest point, rounded up to the next 10 m."""
    far = float(np.sqrt((scan.points**2).sum(axis=1).max())) if len(scan) else 0.0
    return max(10.0, 10.0 * np.floor(far / 10.0) + 10.0)


def voxel_size_m(params: KissParams, max_range_m: float) -> float:
    """The map voxel [m]: ``params.voxel_size_m`` when given, else kiss-icp's rule
    ``max_range_m / params.range_per_voxel``."""
    if params.voxel_size_m is not None:
        return float(params.voxel_size_m)
    return float(max_range_m) / params.range_per_voxel


class _TimedRegistration:
    """kiss-icp's registration object with its one call timed (``register_ms``)."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.watch = None

    def align_points_to_map(self, **kwargs) -> np.ndarray:
        with stopwatch() as self.watch:
            pose = self.inner.align_points_to_map(**kwargs)
        return pose


#: kiss-icp's thread count in this process, fixed by its first instance (empty: none yet)
_process_threads: list[int] = []


def _fresh_run(params: dict, sequence: MemorySequence, seed: bool) -> OdometryResult:
    """The warm-up and the timed run of kiss-icp in this (fresh) process."""
    method = KissIcp(KissParams.model_validate(params))
    method.warm_up(sequence)
    return method.run(sequence, seed)


class KissIcp(Odometry):
    name = "kiss-icp"
    reads_fields = frozenset({"time_offset_s"})  # deskewing
    presentation = Presentation("KISS-ICP", "#8c564b", 7)
    description = "KISS-ICP scan-to-map odometry (kiss-icp package; own local map)"
    motion_prior = "own constant-velocity prediction"
    Params = KissParams

    def __init__(self, params: KissParams | None = None, **overrides) -> None:
        base = params if params is not None else KissParams()
        self.params = (KissParams.model_validate({**base.model_dump(), **overrides})
                       if overrides else base)

    def configured_for(self, sensor: SensorInfo) -> KissIcp:
        return self

    def _kiss(self, deskew: bool, max_range_m: float):
        from kiss_icp.config import KISSConfig
        from kiss_icp.kiss_icp import KissICP

        p = self.params
        config = KISSConfig()
        config.data.max_range = max_range_m
        config.data.min_range = p.min_range_m
        config.data.deskew = deskew
        config.mapping.voxel_size = voxel_size_m(p, max_range_m)
        config.mapping.max_points_per_voxel = p.max_points_per_voxel
        config.registration.max_num_threads = p.num_threads
        if not _process_threads:
            _process_threads.append(p.num_threads)
        kiss = KissICP(config=config)
        kiss.registration = _TimedRegistration(kiss.registration)
        return kiss

    @property
    def needs_fresh_process(self) -> bool:
        """This process's kiss-icp runs on another thread count than this run asks for."""
        return bool(_process_threads) and _process_threads[0] != self.params.num_threads

    def warm_up(self, sequence: Sequence) -> None:
        if not self.needs_fresh_process:  # else the fresh process warms up itself
            super().warm_up(sequence)

    def _run_in_fresh_process(self, sequence: Sequence, seed: bool,
                              on_frame: Callable[[int], None] | None) -> OdometryResult:
        """Warm-up and timed run in a fresh (spawned) process whose first kiss-icp instance
        has this run's thread count; the scans are read here (untimed) and sent over."""
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        scans = MemorySequence(sequence.name, sequence.sensor, list(sequence))
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            result = pool.submit(_fresh_run, self.params.model_dump(), scans, seed).result()
        for i in range(len(result.frames)) if on_frame else ():
            on_frame(i)
        return result

    def run(self, sequence: Sequence, seed: bool,
            on_frame: Callable[[int], None] | None = None) -> OdometryResult:
        if self.needs_fresh_process:
            return self._run_in_fresh_process(sequence, seed, on_frame)
        n = len(sequence)
        poses = np.repeat(np.eye(4)[None], n, axis=0)
        stamps = np.empty(n)
        frames: list[FrameRecord] = []
        kiss = None
        deskew = self.params.deskew
        for i, scan in enumerate(sequence):  # reading the scan (file I/O) is not timed
            if kiss is None:  # one-time set-up, decided by the first scan
                times = point_times(scan, i) if deskew is not False else None
                deskew = times is not None if deskew is None else deskew
                kiss = self._kiss(deskew, self.params.max_range_m or data_range_m(scan))
            with timed_section(self.clock == "wall") as total:
                times = point_times(scan, i) if deskew else None
                if deskew and times is None:
                    raise DataError(f"{_where(scan, i)}: deskew needs per-point times (scan "
                                    "field time_offset_s), which this scan lacks")
                if not seed:
                    kiss.last_delta = np.eye(4)
                kiss.registration.watch = None
                points = np.ascontiguousarray(scan.points, dtype=np.float64)
                _, source = kiss.register_frame(points, times if deskew else np.empty(0))
            stamps[i] = scan.stamp
            poses[i] = kiss.last_pose
            # the first frame only starts the map: no registration, not timed
            frames.append(self.frame_record(i, scan.stamp, total if i else None,
                                            kiss.registration.watch if i else None, len(scan),
                                            len(source), 0, True))
            if on_frame:
                on_frame(i)
        if n and not np.allclose(poses[0], np.eye(4)):  # first frame = identity
            poses = np.linalg.inv(poses[0]) @ poses
        return OdometryResult(stamps, poses, frames)
