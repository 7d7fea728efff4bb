"""Independent implementations of the ICP-family baselines, each a library's own pipeline as its
documentation drives it, as methods the harness runs like any other (a plugin, never
registered in the package):

    DOPPLER_BENCH_METHODS=bench.studies.independent_methods bench run \
        configs/experiments/independent-real-tuning.yaml

``python -m bench.studies.independent`` decides each one's settings by the tuning rule of
configs/splits.yaml (the rule our defaults are decided by: both halves of the real sample,
the synthetic radar as a veto) and compares it with its counterpart on each half at the
setting chosen on the other half (bench/studies/independent.py).

========================  ===============  ==================================================
reference                 counterpart      the library's pipeline
========================  ===============  ==================================================
``ref-open3d-p2plane``    ``icp-p2plane``  Open3D (legacy ``o3d.pipelines.registration``):
                                           ``voxel_down_sample``, ``estimate_normals`` (KNN),
                                           ``registration_icp`` with
                                           ``TransformationEstimationPointToPlane``
``ref-open3d-gicp``       ``gicp``         the same preparation, then
                                           ``registration_generalized_icp`` (covariances from
                                           the normals inside the call, Open3D's epsilon 1e-3)
``ref-small-gicp-vgicp``  ``vgicp``        small_gicp's ``preprocess_points`` (its parallel
                                           voxel grid, kd-tree, covariances),
                                           ``GaussianVoxelMap`` and ``align`` (VGICP)
``ref-open3d-dicp``       ``dicp``,        Open3D's Doppler ICP (the authors' implementation
                          ``doppler-icp``  of DICP, ``open3d.t.pipelines.registration.icp``
                                           with ``TransformationEstimationForDopplerICP``):
                                           ``methods.dicp`` with ``backend=open3d``
``ref-kiss-icp``          ``kiss-icp``     kiss-icp's ``KissICP`` with the library's default
                                           config, driven frame by frame as its
                                           ``OdometryPipeline`` drives it
========================  ===============  ==================================================

The Open3D and small_gicp pipelines are ``bench.studies.speed_reference``'s (the ones
``bench speed --reference`` times), built from this method's own parameters: each reference
has its own settings (defaults from the library's documentation where it has one: the rule's
reference point), decided by a sweep of its own, not ours.

``doppler-icp`` (the paper's Algorithm 1: fixed Doppler correspondences + closest points,
point-to-point Huber Gauss-Newton) has no library implementation. Its reference is Open3D's
Doppler ICP, the closest independent ICP that uses Doppler and geometry together
(point-to-plane + Doppler velocity residuals): a different algorithm, compared as the best
independent Doppler ICP available, not as the same one.

Thread counts: one, as every method of the harness (timed by the thread's CPU clock): Open3D
is limited with ``o3d.utility.set_max_threads(1)`` for the run (its oneTBB ignores
OMP_NUM_THREADS), small_gicp takes ``num_threads=1``, kiss-icp ``max_num_threads=1`` (its
default 0 takes every core; threads do not change what it computes beyond reproducibility).
Open3D is imported lazily (an optional extra); this module imports nothing of ``bench`` at
its top but the package itself, since ``methods.registry`` imports it while it loads. Loading
it imports ``bench``, whose import pins the thread counts (``bench.threads``): a process that
loads it should import ``bench`` before ``methods`` (the CLI, its workers, the driver and the
tests do), else numba has already started with another thread count and refuses the pinned
one at its next compilation (seen from a script importing ``methods.registry`` first).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from loaders.scan import Scan, SensorInfo, Sequence
from methods.base import (
    FrameRecord,
    MethodParams,
    Odometry,
    OdometryResult,
    Presentation,
    Registration,
    RegistrationResult,
)
from methods.dicp import Dicp, DicpParams
from methods.timing import timed_section

#: reference method -> the method(s) of ours it is the independent implementation of
COUNTERPARTS = {"ref-open3d-p2plane": ("icp-p2plane",), "ref-open3d-gicp": ("gicp",),
                "ref-small-gicp-vgicp": ("vgicp",), "ref-open3d-dicp": ("dicp", "doppler-icp"),
                "ref-kiss-icp": ("kiss-icp",)}


class Open3dIcpParams(MethodParams):
    """Open3D's ICP pipeline. Open3D documents no scale for radar: the voxel and the gate are
    swept from these defaults (the rule's reference point) on both real halves
    (configs/experiments/independent-real-tuning.yaml)."""

    voxel_downsample_m: float = Field(1.0, gt=0, description="voxel_down_sample size [m]")
    neighbours: int = Field(30, ge=3, description="estimate_normals KNN (Open3D's "
                            "KDTreeSearchParamKNN default: 30)")
    max_correspondence_m: float = Field(3.0, gt=0, description="max_correspondence_distance "
                                        "of registration_icp [m]")
    max_iterations: int = Field(30, ge=1, description="ICPConvergenceCriteria default: 30 "
                                "(relative fitness and RMSE 1e-6, its defaults)")
    downsample: int = Field(1, ge=1, description="keep every k-th point first (1: all)")


class SmallGicpVgicpParams(MethodParams):
    """small_gicp's VGICP pipeline (defaults of ``preprocess_points`` / ``align`` /
    ``GaussianVoxelMap`` in small_gicp 1.0.1, made for automotive LiDAR: 0.25 m voxel grid,
    1 m Gaussian voxels and gate; on radar these are swept from these values, the rule's
    reference point)."""

    voxel_downsample_m: float = Field(0.25, gt=0, description="preprocess_points "
                                      "downsampling_resolution [m] (small_gicp: 0.25)")
    voxel_size_m: float = Field(1.0, gt=0, description="GaussianVoxelMap resolution [m] "
                                "(small_gicp: 1.0)")
    max_correspondence_m: float = Field(1.0, gt=0, description="align "
                                        "max_correspondence_distance [m] (small_gicp: 1.0)")
    neighbours: int = Field(10, ge=5, description="preprocess_points num_neighbors (10)")
    max_iterations: int = Field(20, ge=1, description="align max_iterations (20)")
    rotation_eps_rad: float = Field(math.radians(0.1), gt=0, description="align "
                                    "rotation_epsilon (0.1 deg)")
    translation_eps_m: float = Field(1e-3, gt=0, description="align translation_epsilon")
    downsample: int = Field(1, ge=1, description="keep every k-th point first (1: all)")


@dataclass(frozen=True)
class Prepared:
    """A scan as the library's pipeline prepared it (``data``) and its point count after the
    preparation (the frame record's ``points``)."""

    data: Any
    points: int

    def __len__(self) -> int:
        return self.points


class _LibraryPipeline(Registration):
    """A library's own per-frame pipeline (``bench.studies.speed_reference``) as a
    ``Registration``: ``preprocess`` is the library's preparation of the new scan, ``register``
    its registration call; the harness chains the steps and seeds them as it does ours."""

    library: ClassVar[str]       # "open3d" or "small_gicp" (speed_reference.PIPELINES)
    counterpart: ClassVar[str]   # the method whose pipeline it is ("icp-p2plane", ...)
    reads_fields = frozenset()

    def __init__(self, params: MethodParams | None = None, **overrides) -> None:
        super().__init__(params, **overrides)
        self._pipeline = None

    @property
    def pipeline(self):
        if self._pipeline is None:
            from bench.studies.speed_reference import PIPELINES

            self._pipeline = PIPELINES[self.library](self.counterpart, self, 1)
        return self._pipeline

    def preprocess(self, scan: Scan) -> Prepared:
        prepared = self.pipeline.preprocess(scan)
        # small_gicp: (cloud, tree or voxels); Open3D: a PointCloud
        cloud = prepared[0] if isinstance(prepared, tuple) else prepared
        size = cloud.size() if hasattr(cloud, "size") else len(cloud.points)
        return Prepared(prepared, size)

    def register(self, source: Prepared, target: Prepared,
                 init_T_target_source: np.ndarray) -> RegistrationResult:
        return self.pipeline.register(source.data, target.data, init_T_target_source)

    def run(self, sequence: Sequence, seed: bool,
            on_frame: Callable[[int], None] | None = None) -> OdometryResult:
        from bench.studies.speed_reference import thread_limit

        with thread_limit(self.library, 1):
            return super().run(sequence, seed, on_frame)


class Open3dPointToPlane(_LibraryPipeline):
    name = "ref-open3d-p2plane"
    description = ("reference for icp-p2plane: Open3D's point-to-plane ICP pipeline "
                   "(voxel_down_sample, estimate_normals KNN, registration_icp PointToPlane)")
    presentation = Presentation("Open3D point-to-plane ICP (reference)", None, 101)
    Params = Open3dIcpParams
    library, counterpart = "open3d", "icp-p2plane"


class Open3dGicp(_LibraryPipeline):
    name = "ref-open3d-gicp"
    description = ("reference for gicp: Open3D's Generalized ICP pipeline (voxel_down_sample, "
                   "estimate_normals KNN, registration_generalized_icp)")
    presentation = Presentation("Open3D Generalized-ICP (reference)", None, 102)
    Params = Open3dIcpParams
    library, counterpart = "open3d", "gicp"


class SmallGicpVgicp(_LibraryPipeline):
    name = "ref-small-gicp-vgicp"
    description = ("reference for vgicp: small_gicp's own VGICP pipeline (preprocess_points, "
                   "GaussianVoxelMap, align)")
    presentation = Presentation("small_gicp VGICP pipeline (reference)", None, 103)
    Params = SmallGicpVgicpParams
    library, counterpart = "small_gicp", "vgicp"


class Open3dDicpParams(DicpParams):
    backend: Literal["open3d"] = Field("open3d", description="Open3D's implementation (only)")


class Open3dDicp(Dicp):
    """``methods.dicp`` with ``backend=open3d``: Open3D's own Doppler ICP on the scans
    ``methods.dicp`` prepares (``methods.dicp_open3d``), its settings its own (swept from the
    authors' values on both real halves). The reference of ``dicp`` and, as the closest
    independent Doppler ICP, of ``doppler-icp`` (a different algorithm, see the module
    docstring)."""

    name = "ref-open3d-dicp"
    description = ("reference for dicp (and, as the closest independent Doppler ICP, for "
                   "doppler-icp): Open3D's Doppler ICP (the authors' implementation)")
    presentation = Presentation("Open3D Doppler ICP (reference)", None, 104)
    Params = Open3dDicpParams

    def configured_for(self, sensor: SensorInfo) -> Open3dDicp:
        resolved = super().configured_for(sensor).params  # a Dicp's, the extrinsic resolved
        return type(self)(self.Params.model_validate(resolved.model_dump()))

    def run(self, sequence: Sequence, seed: bool,
            on_frame: Callable[[int], None] | None = None) -> OdometryResult:
        from bench.studies.speed_reference import thread_limit

        with thread_limit("open3d", 1):
            return super().run(sequence, seed, on_frame)


class KissReferenceParams(MethodParams):
    """kiss-icp's configuration: its defaults (``kiss_icp.config``: ``KISSConfig``) except
    what the data demands."""

    max_range_m: float = Field(100.0, gt=0, description="data.max_range [m] (kiss-icp: 100)")
    min_range_m: float = Field(0.0, ge=0, description="data.min_range [m] (kiss-icp: 0)")
    voxel_size_m: float | None = Field(None, gt=0, description="mapping.voxel_size [m] (None: "
                                       "kiss-icp's rule in load_config, max_range / 100)")


class KissIcpReference(Odometry):
    """kiss-icp's ``KissICP`` with the library's default configuration (``KISSConfig()`` and
    ``load_config``'s voxel rule), ``data.max_range`` / ``min_range`` from this method's
    parameters, one thread; each scan passed to ``register_frame`` with its per-point times
    (an empty array when it has none, as kiss-icp's generic loader passes; its deskewing, on
    by default, then leaves the scan as it is), the pose read from ``last_pose``: the loop of
    ``kiss_icp.pipeline.OdometryPipeline._run_pipeline``. With seed, kiss-icp's own
    constant-velocity prediction; without, ``last_delta`` reset before every frame (as ours)."""

    name = "ref-kiss-icp"
    description = ("reference for kiss-icp: kiss-icp's own pipeline (KissICP, the library's "
                   "default config, max_range / min_range from the data)")
    presentation = Presentation("kiss-icp default pipeline (reference)", None, 105)
    motion_prior = "own constant-velocity prediction"
    reads_fields = frozenset({"time_offset_s"})
    Params = KissReferenceParams

    def __init__(self, params: KissReferenceParams | None = None, **overrides) -> None:
        base = params if params is not None else KissReferenceParams()
        self.params = (KissReferenceParams.model_validate({**base.model_dump(), **overrides})
                       if overrides else base)

    def config(self):
        """kiss-icp's ``KISSConfig``: its defaults, the ranges set, the voxel by its rule."""
        from kiss_icp.config import KISSConfig

        p = self.params
        config = KISSConfig()
        config.data.max_range = p.max_range_m
        config.data.min_range = p.min_range_m
        # kiss_icp.config.parser.load_config: voxel_size None -> max_range / 100
        config.mapping.voxel_size = (p.voxel_size_m if p.voxel_size_m is not None
                                     else float(p.max_range_m / 100.0))
        config.registration.max_num_threads = 1
        return config

    def run(self, sequence: Sequence, seed: bool,
            on_frame: Callable[[int], None] | None = None) -> OdometryResult:
        from kiss_icp.kiss_icp import KissICP

        from methods import kiss as ours

        if ours._process_threads and ours._process_threads[0] != 1:
            raise RuntimeError("ref-kiss-icp runs on one thread, but this process's kiss-icp "
                               f"thread count is fixed at {ours._process_threads[0]}")
        ours._process_threads[:] = ours._process_threads or [1]  # kiss-icp's is process-wide
        odometry = KissICP(config=self.config())
        odometry.registration = ours._TimedRegistration(odometry.registration)
        n = len(sequence)
        poses = np.repeat(np.eye(4)[None], n, axis=0)
        stamps = np.empty(n)
        frames: list[FrameRecord] = []
        for i, scan in enumerate(sequence):  # reading the scan (file I/O) is not timed
            with timed_section(self.clock == "wall") as total:
                times = ours.point_times(scan, i)
                if not seed:
                    odometry.last_delta = np.eye(4)
                odometry.registration.watch = None
                points = np.ascontiguousarray(scan.points, dtype=np.float64)
                _, source = odometry.register_frame(
                    points, np.empty(0) if times is None else times)
            stamps[i] = scan.stamp
            poses[i] = odometry.last_pose
            frames.append(self.frame_record(i, scan.stamp, total if i else None,
                                            odometry.registration.watch if i else None,
                                            len(scan), len(source), 0, True))
            if on_frame:
                on_frame(i)
        if n and not np.allclose(poses[0], np.eye(4)):  # first frame = identity
            poses = np.linalg.inv(poses[0]) @ poses
        return OdometryResult(stamps, poses, frames)


METHODS = [Open3dPointToPlane, Open3dGicp, SmallGicpVgicp, Open3dDicp, KissIcpReference]
