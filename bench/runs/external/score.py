"""A trajectory made elsewhere, scored as a run of its own (``bench score``).

The estimate (``loaders.estimate``: TUM, KITTI + stamps, Boreas, or a bag's pose topic) is
brought to the store's scan stamps (``bench.runs.external.match``) and scored by the one scoring
path
(``bench.runs.evaluate.evaluate_run``) against the store's ground truth: the same relative
errors, KITTI drift, APE and velocity error as a run of the harness, over the scans that have
both ground truth and an estimate. Its run folder is an ordinary one
(``<out>/<sequence>/<name>/``, ``bench.runs.folders.write_run``), so every table, figure,
``compare``, ``regress`` and the report show it; its label is "<name> (external)".

The contract (each breach one ``DataError`` naming the estimate, exit 2 on the command line):

- the options are finite (``match.check_options``; ``min_coverage`` in [0, 1]);
- its clock fits the scans' (unless ``trust_clock``; ``bench.runs.external.clock_check``):
  stamps that are the scans' own are on the store's clock; frame indices as stamps are
  refused as such; a speed a power of 1000 off names stamps or positions in another unit, the
  path length settling which; a motion profile that fits decisively elsewhere (a block
  bootstrap interval of the shift that leaves out none, a correlation gain above 0) is refused
  naming every ``--time-offset`` that fits alike, even when every stamp matches; where the data
  cannot tell, it is scored as given and the check says so;
- its convention fits (``bench.runs.external.conventions``): quaternions in w x y z order and
  inverse poses (Boreas ``T_i_k``) are refused when the other reading's relative motions
  decisively agree with the ground truth's;
- no scan within the tolerance: refused with the offset that fits (the motion profile's, or
  ``loaders.gt.offset_hint``'s guess);
- it covers at least ``min_coverage`` (``DEFAULT_MIN_COVERAGE``) of the scans that have ground
  truth (and are not calibration frames); too short to score at all is said of the estimate;
- its ``name`` is one path component, not a harness method's name nor a harness run folder's
  (``icp-p2p_seed``), and an existing folder of that name that holds another kind of run (a
  harness run) is replaced only with ``replace_run``, and then with a warning; a folder that
  holds no run is never written into (``bench.runs.external.names``).

Timing: "not timed" (``time_ms`` empty, ``clock_note`` says so) unless the method reported its
per-frame times (a 9th TUM column or a file), which are then recorded with ``clock`` "reported
by the method" and never ranked against the harness's own clock.

Identity (``config.yaml``'s ``run_key``): the SHA-256 of the trajectory file (of every file of
a bag folder), of its stamps / times files, the store's content, the association and scoring
settings and the scoring code (``bench.runs.identity.code_identity`` and the sources of the
``bench.runs.external.score*`` modules).
"""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from bench import guard
from bench.runs.evaluate import Scoring, evaluate_run, timing_part
from bench.runs.external import DEFAULT_MIN_COVERAGE, DEFAULT_TOLERANCE_S
from bench.runs.external.checks import check_estimate
from bench.runs.external.match import check_options
from bench.runs.external.names import EXTERNAL, check_name, check_run_folder
from bench.runs.folders import clear_run, is_finished, run_dir_name, write_run
from bench.runs.identity import code_identity, run_key, store_identity
from bench.runs.job import sequence_folder, sequence_labels
from bench.runs.ownership import foreign_run
from bench.runs.result import EXTERNAL_MARK, REPORTED_CLOCK
from loaders.errors import DataError
from loaders.estimate import read_estimate
from loaders.posefile import parse_extrinsic
from loaders.store import StoreSequence
from methods.base import FrameRecord, OdometryResult

#: the clock note of an external run without per-frame times
NOT_TIMED = ("not timed: the trajectory was made outside the harness and came without "
             "per-frame times")
DEFAULT_OUT = Path("results/external")


@dataclass(frozen=True)
class ExternalSpec:
    """What to score: the trajectory (``fmt`` auto / tum / kitti / boreas / bag; KITTI
    ``stamps``; a bag's ``topic``; per-row ``frame_times`` [ms]), its run ``name``, the clock
    offset (``est_stamp + time_offset_s = sensor clock``), the association ``tolerance_s`` and
    ``max_gap_s`` (None: no interpolation), the frame of its poses: ``pose_frame`` "sensor" or
    "body" (the store's ``T_body_sensor`` applies), or an explicit ``extrinsic`` T_frame_sensor
    ("x y z qx qy qz qw" or 16 numbers); ``stamp_unit`` (s, ms, us, ns; None: the format's),
    ``min_coverage``, ``trust_clock`` (skip the clock checks) and ``replace_run`` (replace a
    run of another kind of the same name: see the module docstring)."""

    trajectory: Path
    name: str
    fmt: str = "auto"
    stamps: Path | None = None
    topic: str | None = None
    frame_times: Path | None = None
    time_offset_s: float = 0.0
    tolerance_s: float = DEFAULT_TOLERANCE_S
    max_gap_s: float | None = None
    pose_frame: str = "sensor"
    extrinsic: str | None = None
    stamp_unit: str | None = None
    min_coverage: float = DEFAULT_MIN_COVERAGE
    trust_clock: bool = False
    replace_run: bool = False


@dataclass
class ExternalOutcome:
    run_dir: Path
    status: str  # "done" or "skipped" (same run key)
    coverage: dict = field(default_factory=dict)
    frame: str = ""  # how the poses were moved to the sensor (T_frame_sensor)
    clock: str = ""  # what the clock check found
    warnings: list[str] = field(default_factory=list)  # scored anyway
    convention: str = ""  # what the convention check found


def file_sha256(path: Path | None) -> str | None:
    """SHA-256 of a file, or of every file of a folder (a ROS2 bag) with its relative path."""
    if path is None:
        return None
    path = Path(path)
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for p in files:
        if path.is_dir():
            h.update(str(p.relative_to(path)).encode() + b"\0")
        with open(p, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def _own_code() -> str:
    h = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def check_options_of(spec: ExternalSpec) -> None:
    """The association options (``match.check_options``) and ``min_coverage``."""
    check_options(spec.time_offset_s, spec.tolerance_s, spec.max_gap_s)
    if not (np.isfinite(spec.min_coverage) and 0 <= spec.min_coverage <= 1):
        raise DataError(f"--min-coverage {spec.min_coverage:g}: expected a share in [0, 1] of the "
                        "scans with ground truth")


def frame_transform(spec: ExternalSpec, T_body_sensor: np.ndarray) -> tuple[np.ndarray, str]:
    """T_frame_sensor of the estimate's poses and how it was chosen."""
    if spec.extrinsic is not None:
        return parse_extrinsic(spec.extrinsic), "given (--extrinsic)"
    if spec.pose_frame == "body":
        return np.asarray(T_body_sensor, dtype=np.float64), "the store's T_body_sensor"
    if spec.pose_frame != "sensor":
        raise DataError(f"--pose-frame {spec.pose_frame!r}: expected sensor or body")
    return np.eye(4), "identity (poses of the sensor)"


def score_external(store: Path, spec: ExternalSpec, out: Path | None = None,
                   scoring: Scoring | None = None, force: bool = False,
                   names: dict | None = None) -> ExternalOutcome:
    """Score ``spec``'s trajectory against ``store``'s ground truth into a run folder
    (``out``/<sequence>/<name>; ``out`` default results/external). ``names``: the sequence's
    name, display_name and sensor_class in an experiment (default: the store's). The contract
    (what is refused and how) is the module docstring's."""
    name = check_name(spec.name)
    check_options_of(spec)
    scoring = scoring or Scoring()
    seq = StoreSequence(store, fields=())
    try:
        if seq.ground_truth is None:
            raise DataError(f"{store}: the store has no ground truth; nothing to score "
                            f"{spec.trajectory} against")
        given = {"name": None, "display_name": None, "sensor_class": None, **(names or {})}
        seq_name, display, klass = sequence_labels(seq, SimpleNamespace(**given))
        run_dir = Path(out or DEFAULT_OUT) / sequence_folder(seq_name) / run_dir_name(name, None)
        # the output before any matching (bench.guard): a new folder, this command's own run
        # (same trajectory file and store), or a harness run only with --replace-run
        check_run_folder(run_dir, spec.replace_run)
        guard.run_folder(run_dir, guard.EXTERNAL, spec.replace_run, [
            spec.trajectory, spec.stamps, spec.frame_times, store], root=Path(out or DEFAULT_OUT),
            ask="--replace-run")
        foreign_run(run_dir, {"trajectory": str(guard.resolved(spec.trajectory)),
                              "topic": spec.topic, "store": str(guard.resolved(store))},
                    "bench score")
        est = read_estimate(spec.trajectory, spec.fmt, spec.stamps, spec.topic, spec.frame_times,
                            spec.stamp_unit)
        T_frame_sensor, how = frame_transform(spec, seq.sensor.T_body_sensor)
        stamps = seq.stamps
        where = f"{spec.trajectory}" + (f":{spec.topic}" if spec.topic else "")
        checked = check_estimate(seq, est, spec, T_frame_sensor, where, str(store))
        m, coverage, with_gt = checked.matched, checked.coverage, checked.with_gt
        clock, convention, warned = checked.clock, checked.convention, checked.warnings
        identity = {
            "kind": EXTERNAL, "store_sha256": store_identity(store),
            "trajectory_sha256": file_sha256(spec.trajectory),
            "stamps_sha256": file_sha256(spec.stamps),
            "frame_times_sha256": file_sha256(spec.frame_times),
            "format": spec.fmt, "topic": spec.topic, "T_frame_sensor": T_frame_sensor.tolist(),
            "stamp_unit": spec.stamp_unit,
            "association": {k: m.report[k] for k in ("time_offset_s", "tolerance_s",
                                                     "max_gap_s")},
            "lengths_m": list(scoring.lengths_m),
            "scoring": {"kitti_lengths_m": list(scoring.kitti_lengths_m),
                        "alignment": scoring.alignment,
                        "velocity_window_s": scoring.velocity_window_s},
            "code_sha256": code_identity(), "external_code_sha256": _own_code()}
        key = run_key(identity)
        replaced = check_run_folder(run_dir, spec.replace_run)
        guard.run_folder(run_dir, guard.EXTERNAL, spec.replace_run, [
            spec.trajectory, spec.stamps, spec.frame_times, store], root=Path(out or DEFAULT_OUT),
            ask="--replace-run")
        if is_finished(run_dir, key) and not force and not replaced:
            return ExternalOutcome(run_dir, "skipped", coverage, how, clock, warned, convention)
        idx = np.flatnonzero(m.covered)
        row_times = _frame_times(est.frame_times_ms, len(stamps), m)
        # positional arguments from plain lists: half the time at 40,000 frames
        frames = [FrameRecord(i, t, ms, 0, 0, 0, True) for i, t, ms in
                  zip(idx.tolist(), stamps[idx].tolist(), row_times[idx].tolist(), strict=True)]
        result = OdometryResult(stamps[idx], m.poses[idx], frames)
        evaluation = _evaluate(seq.ground_truth, result, scoring, with_gt, idx, coverage, where,
                               str(store))
        reported = est.frame_times_ms is not None
        timings = {"time_ms": timing_part(est.frame_times_ms if reported else np.zeros(0)),
                   "register_ms": {}, "wall_ms": {}}
        notes = _notes(coverage, reported) + [f"warning: {w}" for w in warned]
        metrics = {"sequence": seq_name, "method": name, "seed": None, "frames": len(seq),
                   **evaluation.metrics, **timings,
                   "clock": REPORTED_CLOCK if reported else None,
                   "clock_note": (f"{REPORTED_CLOCK}: per-frame times from "
                                  f"{spec.frame_times or spec.trajectory}, not measured by the "
                                  "harness" if reported else NOT_TIMED)}
        config = {
            "sequence": {"name": seq_name, "display_name": display, "sensor_class": klass,
                         "store": str(store), "frames": len(seq), "frame_range": None,
                         "sensor_kind": seq.sensor.kind, "sensor_model": seq.sensor.model,
                         "period_s": seq.sensor.period_s,
                         "doppler_kind": seq.sensor.doppler_kind},
            "method": {"name": name, "description": f"external trajectory {where}",
                       "uses_initial_guess": False, "params": {}},
            "label": f"{name} {EXTERNAL_MARK}", "seed": None,
            "lengths_m": list(scoring.lengths_m),
            "kitti_lengths_m": list(scoring.kitti_lengths_m), "alignment": scoring.alignment,
            "external": {"trajectory": str(spec.trajectory), "format": spec.fmt,
                         "topic": spec.topic, "stamps": _str(spec.stamps),
                         "frame_times": _str(spec.frame_times), "pose_frame": spec.pose_frame,
                         "stamp_unit": spec.stamp_unit,
                         "T_frame_sensor": T_frame_sensor.tolist(), "T_frame_sensor_from": how,
                         "timing": REPORTED_CLOCK if reported else "not timed",
                         "clock_check": clock, "convention_check": convention,
                         "coverage": coverage},
            "run_key": key, "identity": identity}
        if replaced:
            clear_run(run_dir)
            warnings.warn(f"{run_dir}: replaced {replaced} by the external run {name} "
                          "(--replace-run)", stacklevel=2)
        write_run(run_dir, result, evaluation.gt, config, metrics, notes)
        return ExternalOutcome(run_dir, "done", coverage, how, clock, warned, convention)
    finally:
        seq.close()


def _evaluate(gt, result, scoring: Scoring, with_gt: np.ndarray, idx: np.ndarray,
              coverage: dict, where: str, store: str):
    """``evaluate_run``; an estimate too short for any segment is said of the estimate (how
    much of the ground truth it covers), not of the store's ground truth."""
    try:
        return evaluate_run(gt, result, name=store, scoring=scoring, excluded=~with_gt[idx])
    except DataError as err:
        if "no relative-error segment" not in str(err):
            raise
        poses = result.poses[with_gt[idx]]
        path = float(np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1).sum()) \
            if len(poses) > 1 else 0.0
        raise DataError(
            f"{where} is too short to score: it covers {coverage['scored']} of the "
            f"{coverage['scans_with_gt']} scans with ground truth "
            f"({100 * coverage['share_scored']:.1f} %), about {path:.3f} m of path, shorter "
            f"than the shortest segment ({min(scoring.lengths_m):g} m)") from None


def _str(path: Path | None) -> str | None:
    return None if path is None else str(path)


def _frame_times(times_ms: np.ndarray | None, n_scans: int, m) -> np.ndarray:
    """Per scan: the reported time of the pose it matched [ms] (NaN when interpolated or not
    reported)."""
    out = np.full(n_scans, np.nan)
    if times_ms is not None and m.matched.any():
        out[m.matched] = times_ms[m.pose_index[m.matched]]
    return out


def _notes(coverage: dict, reported: bool) -> list[str]:
    share = coverage["share_scored"]
    gap = coverage["max_gap_s"]
    notes = [f"external trajectory: {coverage['scored']} of the {coverage['scans_with_gt']} "
             f"scans with ground truth scored ({100 * share:.1f} %): {coverage['matched']} "
             f"matched within {coverage['tolerance_s']:g} s, {coverage['interpolated']} "
             + ("interpolated (no --max-gap: no interpolation)" if gap is None else
                f"interpolated (--max-gap {gap:g} s; the widest gap bridged "
                f"{coverage.get('widest_bridged_s', 0.0):.3g} s)")]
    if not reported:
        notes.append(NOT_TIMED)
    return notes


def score_experiment_external(exp, force: bool = False) -> list[tuple[str, str, str]]:
    """Score every ``external`` entry of an experiment (``bench.runs.experiment``) into its
    results folder with its scoring settings, filed under the sequence entry of the same
    store; returns (name, status "done" / "skipped" / "failed", message) per entry: a failing
    entry is reported, the others carry on."""
    from bench.runs.experiment import expand_sequences

    entries = {Path(s.path).resolve(): s for s in expand_sequences(exp.sequences, lambda t: None)}
    scoring = Scoring(tuple(exp.lengths_m), tuple(exp.kitti_lengths_m), exp.alignment)
    done = []
    for e in exp.external:
        seq = entries.get(Path(e.store).resolve())
        names = None if seq is None else {"name": seq.name, "display_name": seq.display_name,
                                          "sensor_class": seq.sensor_class}
        spec = ExternalSpec(e.trajectory, e.name, e.format, e.stamps, e.topic, e.frame_times,
                            e.time_offset_s, e.tolerance_s, e.max_gap_s, e.pose_frame,
                            e.extrinsic, e.stamp_unit, e.min_coverage, e.trust_clock)
        try:
            o = score_external(e.store, spec, exp.out_dir, scoring, force, names)
        except DataError as err:
            done.append((e.name, "failed", str(err)))
            continue
        c = o.coverage
        done.append((e.name, o.status, f"{o.run_dir}: {c['scored']} of the "
                     f"{c['scans_with_gt']} scans with ground truth scored "
                     f"({100 * c['share_scored']:.1f} %)"
                     + "".join(f"; warning: {w}" for w in o.warnings)))
    return done
