"""Method interface: a registration step, the scan-to-scan odometry driver, seed / no seed and
the timing protocol every method follows.

A ``Registration`` aligns a source scan (previous) to a target scan (current) and returns
``T_target_source`` (maps source-frame points into the target frame, i.e. ``T_curr_prev``).
``Registration.run`` chains steps over a sequence:
``T_world_curr = T_world_prev @ inv(T_curr_prev)``.

Seed options: **with seed** a step starts from a motion prior: for a ``Registration`` the
previous step's estimate (constant-velocity model, scaled to the current time step); a method
with its own prior (``motion_prior`` names it: KISS-ICP's constant-velocity prediction)
uses that. **No seed**: every step starts from the identity and
every internal prior is reset. A method that takes no prior at all (``uses_initial_guess`` is
False: ``doppler``) runs once. Methods that keep their own state (a map) subclass ``Odometry``.

Timing protocol (the same for every method, ``FrameRecord``): ``time_ms`` is all per-frame work
from a scan in memory to its pose (downsampling, normals / covariances, kd-trees, voxel maps,
registration, map update), excluding file I/O; ``register_ms`` is the registration call alone.
The first frame has no registration and is not timed. Before the timed run, ``run_timed`` gives
every method the same warm-up (``Odometry.warm_up``: one untimed run on a separate pair), so no
compilation, import or first-call cost lands in a timed frame. Timed sections are exclusive of
other jobs' timed sections (``methods.timing``). Each timed frame also records the process's CPU
time and the numba compilations inside it (``FrameRecord.process_ms``, ``compiles``): the
harness (``bench.runs.timed``) checks that the work stayed on the timed thread and that no
compilation was left for a timed frame.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict
from scipy.spatial.transform import Rotation

from loaders.scan import MemorySequence, Scan, SensorInfo, Sequence
from loaders.se3 import inv_T, make_T
from methods.timing import stopwatch, timed_section


class MethodParams(BaseModel):
    """Base of every method's parameters: unknown keys are an error, not a silent default."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


@dataclass(frozen=True)
class RegistrationResult:
    T_target_source: np.ndarray
    correspondences: int
    iterations: int
    converged: bool


@dataclass
class FrameRecord:
    """One registered frame. ``time_ms``: all per-frame work from the scan in memory to its
    pose; ``register_ms``: the registration call alone; both by the method's clock
    (``Odometry.clock``: CPU time of a one-thread method, else wall time); ``wall_ms``: the
    elapsed time of the frame's work (beside ``time_ms``, it shows waiting for a core);
    ``thread_ms`` / ``process_ms``: the CPU time of the calling thread / the whole process over
    the frame's work (their ratio shows work that left the thread, ``methods.timing``);
    ``compiles``: numba compilations inside the frame (0 after a complete warm-up);
    ``replaced``: the registration gave no usable transform (non-finite, or too few pairs) and
    the step was replaced by the motion prior (the identity without a seed)."""

    index: int
    stamp: float
    time_ms: float
    points: int
    correspondences: int
    iterations: int
    converged: bool
    register_ms: float = float("nan")
    wall_ms: float = float("nan")
    thread_ms: float = float("nan")
    process_ms: float = float("nan")
    compiles: int = 0
    replaced: bool = False


@dataclass
class OdometryResult:
    """Estimated ``T_world_sensor`` per frame (first frame = identity), per-frame records and,
    for a method that measures it, its own velocity estimate."""

    stamps: np.ndarray
    poses: np.ndarray
    frames: list[FrameRecord] = field(default_factory=list)
    #: a method's own per-frame estimate of the sensor velocity (N, 3) [m/s, sensor frame]
    #: (a Doppler ego velocity; NaN rows where it had none), scored beside the trajectory's
    velocity_mps: np.ndarray | None = None


def uniform_downsample(scan: Scan, factor: int) -> Scan:
    """Keep every ``factor``-th point (all per-point arrays together)."""
    return scan if factor <= 1 else scan.select(slice(None, None, factor))


def scale_motion(T: np.ndarray, ratio: float) -> np.ndarray:
    """The constant-velocity motion ``T`` scaled to a time step ``ratio`` times as long."""
    if abs(ratio - 1.0) < 1e-6:
        return T.copy()
    rotvec = Rotation.from_matrix(T[:3, :3]).as_rotvec() * ratio
    return make_T(Rotation.from_rotvec(rotvec).as_matrix(), T[:3, 3] * ratio)


#: the harness's motion prior of a seeded ``Registration`` (the previous step's motion)
CONSTANT_VELOCITY = "constant velocity"


@dataclass(frozen=True)
class Presentation:
    """How a method is shown in every table and figure, declared with its class:
    ``display_name`` (None: its registry name), ``color`` (a matplotlib colour; None: a colour
    of its own is assigned, distinct from every other method's, ``methods.registry.color``)
    and ``order`` (its row position; the paper's baselines first; None: after the known
    ones)."""

    display_name: str | None = None
    color: str | None = None
    order: float | None = None


class Odometry(ABC):
    """Anything that turns a sequence into an estimated trajectory."""

    name: ClassVar[str]
    description: ClassVar[str]
    #: False for a method that takes no motion prior at all (it runs once, no seed options)
    uses_initial_guess: ClassVar[bool] = True
    #: what "with seed" starts from: ``CONSTANT_VELOCITY`` (the harness's guess) or the name of
    #: the method's own prior; None when ``uses_initial_guess`` is False
    motion_prior: ClassVar[str | None] = CONSTANT_VELOCITY
    #: True for a method that uses the sequence's sensor extrinsic (``T_body_sensor``) unless
    #: its parameter ``extrinsic_param`` is given: a run on a store whose extrinsic ``bench
    #: calibrate`` fitted to the GT is marked in every table
    uses_sensor_extrinsic: ClassVar[bool] = False
    extrinsic_param: ClassVar[str | None] = None
    #: True for a method that needs raw radial Doppler in every scan: the harness refuses it,
    #: before any job runs, on a store without Doppler or with ego-compensated Doppler
    needs_doppler: ClassVar[bool] = False
    #: the per-point arrays it reads besides the points: "doppler" and names of ``Scan.fields``
    #: (the store reads only these); None, the default for a method that does not say: all
    reads_fields: ClassVar[frozenset[str] | None] = None
    #: display name, colour and row order in tables and figures
    presentation: ClassVar[Presentation] = Presentation()

    @property
    def threads(self) -> int:
        """Threads the method computes with (its ``num_threads`` parameter; 1 without one)."""
        return int(getattr(getattr(self, "params", None), "num_threads", 1) or 1)

    @property
    def clock(self) -> str:
        """How its frames are timed (``methods.timing``): "cpu" (the thread's CPU time: the
        same alone or beside other jobs) on one thread, "wall" on several, or ``clock_override``
        when the harness set it (a run whose work left the thread is timed again by wall
        clock)."""
        return getattr(self, "clock_override", None) or ("cpu" if self.threads == 1 else "wall")

    def frame_record(self, index: int, stamp: float, total, register, points: int,
                     correspondences: int, iterations: int, converged: bool,
                     replaced: bool = False) -> FrameRecord:
        """A frame's record from its ``timed_section`` (``total``; None: not timed, as the
        first frame) and the stopwatch of its registration call (``register``; None: none);
        ``replaced``: its step was replaced by the motion prior (see ``FrameRecord``)."""
        nan = float("nan")
        if total is None:
            return FrameRecord(index, stamp, nan, points, correspondences, iterations,
                               converged, nan if register is None else register.ms(self.clock),
                               replaced=replaced)
        return FrameRecord(index, stamp, total.ms(self.clock), points, correspondences,
                           iterations, converged,
                           nan if register is None else register.ms(self.clock),
                           total.wall_ms, total.cpu_ms, total.process_ms, total.compiles,
                           replaced)

    def configured_for(self, sensor: SensorInfo) -> Odometry:
        """This method with the parameters that depend on the sensor resolved for ``sensor``
        (e.g. radar or LiDAR defaults, the vehicle-to-sensor extrinsic). Called once before a
        run; the resolved parameters are what a run records. Default: nothing to resolve."""
        return self

    def for_seed(self, seed: bool | None) -> Odometry:
        """This method with the defaults that are valid for the seed option: a value that
        needs the motion prior (e.g. a correspondence gate shorter than a frame's motion) is
        replaced for a no-seed run. Called before ``configured_for``; parameters set
        explicitly are kept. Default: nothing depends on the seed."""
        return self

    @abstractmethod
    def run(
        self, sequence: Sequence, seed: bool, on_frame: Callable[[int], None] | None = None
    ) -> OdometryResult: ...

    def warm_up(self, sequence: Sequence) -> None:
        """One untimed run on a separate pair of ``sequence``'s scans (its last two, or its
        first two when it is short), so that compilation, imports and first-call costs never
        land in a timed frame. The result is discarded; runs share no state."""
        n = len(sequence)
        if n < 2:
            return
        a, b = (n - 2, n - 1) if n >= 4 else (0, 1)
        pair = MemorySequence(sequence.name, sequence.sensor, [sequence[a], sequence[b]])
        self.run(pair, seed=True)


def run_timed(method: Odometry, sequence: Sequence, seed: bool,
              on_frame: Callable[[int], None] | None = None) -> OdometryResult:
    """How the harness runs a method: the common warm-up, then the timed run."""
    method.warm_up(sequence)
    return method.run(sequence, seed, on_frame)


class Registration(Odometry):
    """A pairwise registration step; ``run`` chains it over a sequence (scan to scan)."""

    Params: ClassVar[type[MethodParams]] = MethodParams

    def __init__(self, params: MethodParams | None = None, **overrides) -> None:
        base = params if params is not None else self.Params()
        self.params = base.model_copy(update=overrides) if overrides else base
        if overrides:
            self.params = self.Params.model_validate(self.params.model_dump())

    def preprocess(self, scan: Scan) -> Scan:
        """Per-scan preparation (downsampling, normals, kd-trees): part of the frame's
        ``time_ms``, not of ``register_ms``. Each scan is prepared once and serves as the
        target of one step and the source of the next."""
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
        exclusive = self.clock == "wall"
        for i, raw in enumerate(sequence):  # reading the scan (file I/O) is not timed
            stamps[i] = raw.stamp
            reg = None
            with timed_section(exclusive) as total:
                scan = self.preprocess(raw)
                if prev is not None:
                    dt = raw.stamp - stamps[i - 1]
                    init = np.eye(4)
                    if seed and self.uses_initial_guess and last_dt:
                        init = scale_motion(last_motion, dt / last_dt)
                    with stopwatch() as reg:
                        result = self.register(prev, scan, init)
                    T = result.T_target_source
                    replaced = not np.all(np.isfinite(T))
                    if replaced:  # counted and shown (RunResult.frames_replaced)
                        T = init
                        result = RegistrationResult(init, result.correspondences,
                                                    result.iterations, False)
                    poses[i] = poses[i - 1] @ inv_T(T)
                    last_motion, last_dt = T, dt
            if prev is None:  # the first frame: no registration, not timed
                frames.append(self.frame_record(i, raw.stamp, None, None, len(scan), 0, 0,
                                                True))
            else:
                frames.append(self.frame_record(i, raw.stamp, total, reg, len(scan),
                                                result.correspondences, result.iterations,
                                                result.converged, replaced))
            prev = scan
            if on_frame:
                on_frame(i)
        return OdometryResult(stamps, poses, frames)
