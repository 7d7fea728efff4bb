"""What a job is (one sequence x method x seed option) and how one job runs.

A job's folder is ``<out>/<sequence>/<method or label>[_seed|_noseed]``; its ``config.yaml``
holds a ``run_key``: a hash of everything that determines the result (the store's content
hash, the method, its resolved parameters, the seed option, the evaluation lengths, the host
and the hash of the code that runs between the store and metrics.json, this module included:
``bench.runs.identity``), and ``libraries``: the third-party libraries the run imported, with
their versions (``bench.runs.libraries``). A job is skipped only when its folder holds a
finished run with the same key whose libraries are installed at the same versions; otherwise
the old records are removed first and it runs again, so a failed re-run never leaves stale
metrics behind.
``bench.runs.plan`` resolves every job before anything runs (stores, parameters, folders), so
bad input is one clear error up front; executors (``bench.runs.executors``) run the planned
jobs through ``run_job``.
"""

from __future__ import annotations

import sys
import time
import traceback
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from bench.paths import ROOT
from bench.runs.evaluate import Scoring, evaluate_run
from bench.runs.folders import clear_run, is_finished, run_dir_name, write_failure, write_run
from bench.runs.identity import code_identity, host_identity, run_key, store_identity
from bench.runs.libraries import imported_libraries
from bench.runs.sequence_identity import content_or_none
from bench.runs.timed import timed_run
from loaders.errors import DataError, validation_problems
from loaders.scan import FrameRange, Sequence
from loaders.sensor_classes import SYNTHETIC_MARK, is_synthetic, sensor_class
from loaders.store import StoreSequence
from methods.base import Odometry
from methods.registry import display_name, get_method, make_method
from metrics.kitti import KITTI_LENGTHS_M
from metrics.relative import DEFAULT_LENGTHS_M


@dataclass(frozen=True)
class Job:
    store: Path
    method: str
    seed: bool | None
    out_root: Path
    params: dict = field(default_factory=dict)
    lengths_m: tuple[float, ...] = DEFAULT_LENGTHS_M
    name: str | None = None
    display_name: str | None = None
    sensor_class: str | None = None
    run_dir_override: Path | None = None
    label: str | None = None
    frame_range: tuple[int, int | None] | None = None  # (start, frames) of the store, or all
    run_key: str | None = None  # set by ``plan``
    store_sha256: str | None = None  # set by ``plan``, so workers do not hash the store again
    code_sha256: str | None = None  # set by ``plan``, so workers do not hash the code again
    alignment: str = "se3"  # APE alignment (metrics.Alignment spec)
    kitti_lengths_m: tuple[float, ...] = KITTI_LENGTHS_M

    @property
    def scoring(self) -> Scoring:
        """How the run is scored (bench.runs.evaluate.Scoring)."""
        return Scoring(self.lengths_m, self.kitti_lengths_m, self.alignment)

    @property
    def title(self) -> str:
        folder = run_dir_name(self.method, self.seed, self.label)
        return f"{self.name or self.store.stem} / {folder}"

    def run_dir(self, sequence_name: str) -> Path:
        if self.run_dir_override is not None:
            return self.run_dir_override
        return (self.out_root / sequence_folder(sequence_name)
                / run_dir_name(self.method, self.seed, self.label))


def sequence_folder(name: str) -> str:
    """A sequence name as one folder name: path separators replaced, and a name of dots only
    ("..") prefixed, so no name leaves the results folder or nests folders."""
    folder = name.replace("/", "_").replace("\\", "_")
    return folder if folder.strip(".") else f"_{folder}"


@dataclass
class JobOutcome:
    job: Job
    status: str  # "done", "skipped", "failed", "interrupted"
    message: str = ""
    frames: int = 0
    wall_s: float = 0.0
    run_dir: Path | None = None
    warnings: list[str] = field(default_factory=list)  # said while the job ran


@dataclass
class Prepared:
    """A job resolved against its store: the open sequence, the configured method, the folder,
    the run key and the configuration to record."""

    sequence: Sequence
    method: Odometry
    run_dir: Path
    key: str
    config: dict


def sequence_labels(seq: Sequence, job: Job) -> tuple[str, str, str]:
    """(name, display name, sensor class) from the job, else the store's provenance. A store
    whose ground truth ``bench calibrate`` corrected says so in its display name."""
    prov = seq.provenance
    name = job.name or seq.name
    display = job.display_name or prov.get("display_name") or name
    frames = (prov.get("calibration") or {}).get("frames")
    if frames:
        display += f" (GT calibrated on frames {frames[0]}-{frames[1] - 1}, not scored)"
    if is_synthetic(prov) and SYNTHETIC_MARK not in display:
        display += f" {SYNTHETIC_MARK}"  # never mistaken for the real sequence it imitates
    klass = (job.sensor_class or prov.get("sensor_class") or prov.get("class")
             or sensor_class(seq.sensor))
    return name, display, klass


def calibration_frames(seq: Sequence) -> np.ndarray | None:
    """Bool per frame of ``seq``: the store frames [first, stop) ``bench calibrate`` estimated
    the GT correction on (its provenance), by index (a frame range maps to its store frames);
    those frames are registered but not scored. None when the store was not calibrated."""
    frames = (seq.provenance.get("calibration") or {}).get("frames")
    if not frames:
        return None
    index = seq.indices if isinstance(seq, FrameRange) else np.arange(len(seq))
    return (index >= frames[0]) & (index < frames[1])


#: the label mark of a run whose method used an extrinsic ``bench calibrate`` fitted to the GT
GT_EXTRINSIC_MARK = "(extrinsic fitted to GT)"


def extrinsic_from_gt(seq: Sequence, cls: type[Odometry], params: dict | None) -> bool:
    """True when ``cls`` takes the store's sensor extrinsic (``uses_sensor_extrinsic``, none
    given in ``params``) and ``bench calibrate`` corrected that extrinsic with a rotation fitted
    to the ground truth: the run is then not independent of the GT it is scored against."""
    calibrated = bool((seq.provenance.get("calibration") or {}).get("frames"))
    given = getattr(cls, "extrinsic_param", None)
    return (calibrated and bool(getattr(cls, "uses_sensor_extrinsic", False))
            and not (given and (params or {}).get(given) is not None))


def _method_error(job: Job, err: Exception) -> DataError:
    if isinstance(err, ValidationError):
        params = list(get_method(job.method).Params.model_fields)
        problems = "; ".join(validation_problems(err, lambda loc: params, "parameter"))
        return DataError(f"method {job.method!r}: invalid parameters {job.params}: {problems}")
    return DataError(f"method {job.method!r}: {err}")


def prepare(job: Job) -> Prepared:
    """Open the store and configure the method; DataError on bad input (store or parameters).
    A method configuration error names the run folder it belongs to (``err.run_dir``)."""
    # the store reads only the per-point arrays the method uses (all for one that does not say)
    store = StoreSequence(job.store, fields=get_method(job.method).reads_fields)
    seq = store if job.frame_range is None else FrameRange(store, *job.frame_range)
    try:
        name, display, klass = sequence_labels(seq, job)
        run_dir = job.run_dir(name)
        cls = get_method(job.method)
        config = {
            "sequence": {"name": name, "display_name": display, "sensor_class": klass,
                         "store": str(job.store), "frames": len(seq),
                         # its numbers, whatever its name (two names, one content: one sequence)
                         "content_sha256": content_or_none(job.store),
                         "frame_range": list(job.frame_range) if job.frame_range else None,
                         # the frames of its source the store holds (bench convert --start ...)
                         "store_frame_range": store.provenance.get("frame_range"),
                         "sensor_kind": seq.sensor.kind, "sensor_model": seq.sensor.model,
                         "period_s": seq.sensor.period_s,
                         # gt-reconstructed: every table / figure row is marked GT-assisted
                         "doppler_kind": seq.sensor.doppler_kind},
            "method": {"name": job.method, "description": cls.description,
                       "uses_initial_guess": cls.uses_initial_guess},
            "label": job.label,
            "seed": job.seed,
            "lengths_m": list(job.lengths_m),
            "kitti_lengths_m": list(job.kitti_lengths_m),
            "alignment": job.scoring.alignment,
        }
        try:
            method = make_method(job.method, job.params, seq.sensor, job.seed)
        except (ValidationError, ValueError, TypeError) as err:
            error = _method_error(job, err)
            error.run_dir, error.config = run_dir, config  # type: ignore[attr-defined]
            raise error from None
        params = getattr(method, "params", None)
        config["method"]["params"] = params.model_dump(mode="json") if params is not None else {}
        # the parameters asked for (bench run -p, an experiment's params:), as given: a row
        # label names them (bench.report.names.overrides_note)
        config["method"]["given"] = {str(k): v for k, v in (job.params or {}).items()}
        if extrinsic_from_gt(seq, cls, job.params):
            # the method consumes the store's extrinsic, which bench calibrate fitted to the GT
            config["method"]["extrinsic_from_gt"] = True
            config["label"] = f"{job.label or display_name(job.method)} {GT_EXTRINSIC_MARK}"
        identity = {"store_sha256": job.store_sha256 or store_identity(job.store),
                    "method": job.method, "frame_range": job.frame_range,
                    "params": config["method"]["params"], "seed": job.seed,
                    "lengths_m": [float(x) for x in job.lengths_m],
                    "scoring": {"kitti_lengths_m": [float(x) for x in job.kitti_lengths_m],
                                "alignment": job.scoring.alignment},
                    "code_sha256": job.code_sha256 or code_identity(),
                    "host": host_identity()}
        config["run_key"] = run_key(identity)
        config["identity"] = identity
        return Prepared(seq, method, run_dir, config["run_key"], config)
    except BaseException:
        store.close()
        raise


def run_job(job: Job, force: bool = False,
            on_frame: Callable[[int, int], None] | None = None) -> JobOutcome:
    """Run one job and write its folder. ``on_frame(done, total)`` reports progress. Never
    raises for a failing run: the failure is recorded in ``failed.json`` and returned."""
    t0 = time.perf_counter()
    try:
        prep = prepare(job)
    except DataError as err:
        run_dir = getattr(err, "run_dir", None)
        if run_dir is not None:
            _record_failure(run_dir, getattr(err, "config", None), str(err), "")
        return JobOutcome(job, "failed", str(err), run_dir=run_dir)
    seq, run_dir = prep.sequence, prep.run_dir
    try:
        if is_finished(run_dir, prep.key) and not force:
            return JobOutcome(job, "skipped", str(run_dir), run_dir=run_dir)
        clear_run(run_dir)
        total = len(seq)
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            result, timing = timed_run(prep.method, seq, bool(job.seed),
                                       (lambda i: on_frame(i + 1, total)) if on_frame else None)
            warn_few_points(result, job)
            evaluation = evaluate_run(seq.ground_truth, result, name=str(job.store),
                                      scoring=job.scoring, excluded=calibration_frames(seq))
        notes = list(dict.fromkeys(str(w.message) for w in said))
        # the libraries this run imported, at their versions: it is reused only while they
        # are installed as they were (bench.runs.libraries, bench.runs.folders.is_finished)
        prep.config["libraries"] = imported_libraries(_outside_files(prep.method))
        metrics = {"sequence": prep.config["sequence"]["name"], "method": job.method,
                   "seed": job.seed, "frames": len(seq), **evaluation.metrics, **timing}
        write_run(run_dir, result, evaluation.gt, prep.config, metrics, notes)
        return JobOutcome(job, "done", str(run_dir), len(seq), time.perf_counter() - t0,
                          run_dir=run_dir, warnings=notes)
    except Exception as err:  # noqa: BLE001 - record any failure and carry on
        message = f"{type(err).__name__}: {err}" if not isinstance(err, DataError) else str(err)
        _record_failure(run_dir, prep.config, message, traceback.format_exc())
        return JobOutcome(job, "failed", message, wall_s=time.perf_counter() - t0,
                          run_dir=run_dir)
    finally:
        seq.close()


def _outside_files(method: Odometry) -> list[Path]:
    """The method's module when it lives outside the repository (a plugin): its imports
    count among the run's libraries too."""
    module = sys.modules.get(type(method).__module__)
    file = getattr(module, "__file__", None)
    if file and not Path(file).resolve().is_relative_to(ROOT):
        return [Path(file)]
    return []


#: fewer points than this after a method's own preparation leave nothing to register
MIN_POINTS = 3


class FewPointsWarning(UserWarning):
    """A frame had too few points to register: its step kept the motion prior."""


def warn_few_points(result, job: Job) -> None:
    """A named warning when frames had fewer than ``MIN_POINTS`` points to register (after the
    method's own downsampling): their pose is the motion prior, not a measurement."""
    few = [f for f in result.frames if f.points < MIN_POINTS]
    if few:
        warnings.warn(f"{job.store}, frame {few[0].index}: {few[0].points} point(s) to register "
                      f"after {job.method}'s preparation (at least {MIN_POINTS} needed); "
                      f"{len(few)} such frame(s) kept their motion prior", FewPointsWarning,
                      stacklevel=2)


def _record_failure(run_dir: Path, config: dict | None, message: str, trace: str,
                    status: str = "failed") -> None:
    try:
        write_failure(run_dir, config, message, trace, status)
    except (OSError, DataError):
        pass  # the outcome still carries the message; the folder itself is the problem


def record_unfinished(job: Job, message: str, status: str) -> None:
    """Record a job that an executor ended (interrupted, timed out, crashed worker)."""
    if job.run_dir_override is not None:
        _record_failure(job.run_dir_override, None, message, "", status)


def expected_cost(job: Job) -> float:
    size = job.store.stat().st_size if job.store.exists() else 0
    return size * (20.0 if get_method(job.method).uses_initial_guess else 1.0)


def summarize(outcomes: list[JobOutcome]) -> str:
    statuses = ("done", "skipped", "failed", "interrupted")
    counts = {s: sum(o.status == s for o in outcomes) for s in statuses}
    text = ", ".join(f"{v} {k}" for k, v in counts.items() if v or k == "failed")
    from loaders.store import store_has_ground_truth

    unscored = [o for o in outcomes if o.status == "done" and o.job.store.suffix == ".h5"
                and store_has_ground_truth(o.job.store) is False]
    for o in unscored:  # a trajectory without errors must not pass for a scored run
        text += (f"\n  not scored: {o.job.title}: {o.job.store} has no ground truth (the "
                 "trajectory is written, no error is computed)")
    failed = [o for o in outcomes if o.status in ("failed", "interrupted")]
    for o in failed:
        first_line = o.message.splitlines()[0] if o.message else ""
        text += f"\n  {o.status}: {o.job.title}: {first_line}"
    return text
