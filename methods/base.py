"""Method interface: a registration step, the scan-to-scan odometry driver, seed / no seed.

A ``Registration`` aligns a source scan (previous) to a target scan (current) and returns
``T_target_source`` (maps source-frame points into the target frame, i.e. ``T_curr_prev``).
``ScanToScan`` chains steps over a sequence: ``T_world_curr = T_world_prev @ inv(T_curr_prev)``.

Seed options (as in the paper): **with seed** the initial guess of a step is the previous
step's estimate (constant-velocity model, scaled to the current time step); **no seed** uses
the identity. Methods that keep their own state (a map) subclass ``Odometry`` directly.
Only the ``register`` call is timed (``methods.timing.timed_section``: exclusive of other
jobs' timed sections when jobs run in parallel); ``preprocess`` (downsampling) is not.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict
from scipy.spatial.transform import Rotation

from loaders.scan import Scan, SensorInfo, Sequence
from loaders.se3 import inv_T, make_T
from methods.timing import timed_section


class MethodParams(BaseModel):
    """Base of every method's parameters: unknown keys are an error, not a silent default."""

    model_config = ConfigDict(extra="forbid", frozen=True)


@dataclass(frozen=True)
class RegistrationResult:
    T_target_source: np.ndarray
    correspondences: int
    iterations: int
    converged: bool


@dataclass
class FrameRecord:
    """One registered frame. ``time_ms``: all per-frame work from the scan in memory to its
    pose; ``register_ms``: the registration call alone (NaN where a method has none)."""

    index: int
    stamp: float
    time_ms: float
    points: int
    correspondences: int
    iterations: int
    converged: bool
    register_ms: float = float("nan")


@dataclass
class OdometryResult:
    """Estimated ``T_world_sensor`` per frame (first frame = identity) and per-frame records."""

    stamps: np.ndarray
    poses: np.ndarray
    frames: list[FrameRecord] = field(default_factory=list)


def uniform_downsample(scan: Scan, factor: int) -> Scan:
    """Keep every ``factor``-th point (all per-point arrays together)."""
    return scan if factor <= 1 else scan.select(slice(None, None, factor))


def scale_motion(T: np.ndarray, ratio: float) -> np.ndarray:
    """The constant-velocity motion ``T`` scaled to a time step ``ratio`` times as long."""
    if abs(ratio - 1.0) < 1e-6:
        return T.copy()
    rotvec = Rotation.from_matrix(T[:3, :3]).as_rotvec() * ratio
    return make_T(Rotation.from_rotvec(rotvec).as_matrix(), T[:3, 3] * ratio)


class Odometry(ABC):
    """Anything that turns a sequence into an estimated trajectory."""

    name: ClassVar[str]
    description: ClassVar[str]
    uses_initial_guess: ClassVar[bool] = True

    def configured_for(self, sensor: SensorInfo) -> Odometry:
        """This method with the parameters that depend on the sensor resolved for ``sensor``
        (e.g. radar or LiDAR defaults, the vehicle-to-sensor extrinsic). Called once before a
        run; the resolved parameters are what a run records. Default: nothing to resolve."""
        return self

    @abstractmethod
    def run(
        self, sequence: Sequence, seed: bool, on_frame: Callable[[int], None] | None = None
    ) -> OdometryResult: ...


class Registration(Odometry):
    """A pairwise registration step; ``run`` chains it over a sequence (scan to scan)."""

    Params: ClassVar[type[MethodParams]] = MethodParams

    def __init__(self, params: MethodParams | None = None, **overrides) -> None:
        base = params if params is not None else self.Params()
        self.params = base.model_copy(update=overrides) if overrides else base
        if overrides:
            self.params = self.Params.model_validate(self.params.model_dump())

    def preprocess(self, scan: Scan) -> Scan:
        """Per-scan preparation outside the timed call (downsampling, filtering)."""
        return scan

    @abstractmethod
    def register(
        self, source: Scan, target: Scan, init_T_target_source: np.ndarray
    ) -> RegistrationResult: ...

    def run(
        self, sequence: Sequence, seed: bool, on_frame: Callable[[int], None] | None = None
    ) -> OdometryResult:
        n = len(sequence)
        poses = np.empty((n, 4, 4))
        poses[0] = np.eye(4)
        stamps = np.empty(n)
        frames: list[FrameRecord] = []
        prev = None
        last_motion = np.eye(4)  # T_curr_prev of the previous step
        last_dt = None
        for i, raw in enumerate(sequence):
            scan = self.preprocess(raw)
            stamps[i] = raw.stamp
            if prev is None:
                frames.append(FrameRecord(i, raw.stamp, float("nan"), len(scan), 0, 0, True))
            else:
                dt = raw.stamp - stamps[i - 1]
                init = np.eye(4)
                if seed and self.uses_initial_guess and last_dt:
                    init = scale_motion(last_motion, dt / last_dt)
                with timed_section() as watch:
                    result = self.register(prev, scan, init)
                time_ms = watch.time_ms
                T = result.T_target_source
                if not np.all(np.isfinite(T)):
                    T = init
                    result = RegistrationResult(init, result.correspondences,
                                                result.iterations, False)
                poses[i] = poses[i - 1] @ inv_T(T)
                last_motion, last_dt = T, dt
                frames.append(FrameRecord(i, raw.stamp, time_ms, len(scan),
                                          result.correspondences, result.iterations,
                                          result.converged))
            prev = scan
            if on_frame:
                on_frame(i)
        return OdometryResult(stamps, poses, frames)
