"""Run folders: what one run (sequence x method x seed option) leaves on disk.

    <out>/<sequence>/<method>[_seed|_noseed]/
        est_tum.txt  est_kitti.txt  gt_tum.txt  gt_kitti.txt   (see below)
        est_all_tum.txt   (every frame's pose, when some frames have no ground truth)
        frames.csv  config.yaml  meta.json
        metrics.json   (written last: its presence means the run finished; a RunResult)
        failed.json    (instead of metrics.json when the run raised; retried on the next run)

With ground truth, the four trajectory files hold exactly the scored frames (those with GT),
row-aligned, so evo and the KITTI devkit read them directly: ``gt_kitti.txt`` / ``est_kitti.txt``
(3x4 row-major), ``gt_tum.txt`` / ``est_tum.txt`` (the same stamps). Numbers are written with 17
significant digits (they read back as the float64 values that were scored). Without ground
truth ``est_tum.txt`` / ``est_kitti.txt`` hold every frame.

Every file is written atomically (temporary file + rename). ``RunRecord`` is a run read back
(``read_run``, ``load_runs``): a thin view of its ``bench.runs.result.RunResult`` and
config.yaml. A metrics.json of an older version is re-scored from the run's trajectory files
on reading (methods not re-run), with one message saying so.
"""

from __future__ import annotations

import csv
import io
import json
import re
import sys
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np
import yaml
from pydantic import ValidationError

from bench import guard
from bench.runs.libraries import libraries_current
from bench.runs.provenance import run_meta
from bench.runs.result import RunResult
from bench.runs.sequence_identity import sequence_tags, tagged
from loaders.errors import DataError, validation_problems
from loaders.posefile import read_tum
from loaders.se3 import tum_from_T
from loaders.trajectory import Trajectory
from loaders.yamlio import load_yaml
from methods.base import OdometryResult
from methods.registry import Seed

FRAME_COLUMNS = ["index", "stamp", "time_ms", "register_ms", "wall_ms", "points",
                 "correspondences", "iterations", "converged", "replaced"]


RUN_RECORDS = ("metrics.json", "failed.json")


def run_dir_name(method: str, seed: bool | None | Seed, label: str | None = None) -> str:
    """``doppler`` (method without initial guess), ``icp-p2p_seed`` or ``icp-p2p_noseed``
    (``Seed.suffix``); a labelled variant uses its label (made file-name safe) instead of the
    method name."""
    base = re.sub(r"[^A-Za-z0-9._+-]+", "-", label).strip("-") if label else method
    return base + Seed.of(seed).suffix


def is_finished(run_dir: Path, key: str | None = None) -> bool:
    """The run in ``run_dir`` finished (and, given ``key``, was made from the same inputs, with
    the libraries it imported still installed at the versions it ran with
    (``bench.runs.libraries``), and its timing is clean: no compilation inside a timed frame,
    ``bench.runs.timed``). A broken metrics.json (``check_record``) is no finished run: it runs
    again."""
    if not (run_dir / "metrics.json").exists():
        return False
    if key is None:
        return check_record(run_dir / "metrics.json") is None
    try:
        config = load_yaml((run_dir / "config.yaml").read_text()) or {}
        # a run with a compilation inside a timed frame is no clean timing: it runs again
        clean = json.loads((run_dir / "metrics.json").read_text()).get("timing_clean", True)
    except (OSError, ValueError, AttributeError, yaml.YAMLError):
        return False
    return (isinstance(config, dict) and config.get("run_key") == key and clean is not False
            and libraries_current(config.get("libraries"))
            and check_record(run_dir / "metrics.json") is None)


def clear_run(run_dir: Path) -> None:
    """Remove a run folder's result records before it is run again, so a failed re-run never
    leaves the old metrics behind."""
    for name in RUN_RECORDS:
        guard.remove(run_dir / name, guard.in_a_run, "a run's record")


def _rows(values: np.ndarray) -> str:
    """Space-separated rows, 17 significant digits (exact), formatted by one ``%`` over the
    whole array (a third of the time of formatting number by number)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return ""
    line = " ".join(["%.17g"] * values.shape[1]) + "\n"
    return (line * len(values)) % tuple(values.ravel().tolist())


def write_trajectory(path: Path, traj: Trajectory, fmt: str) -> None:
    """TUM (``t x y z qx qy qz qw``) or KITTI (3x4 row-major) rows, 17 significant digits."""
    if fmt == "tum":
        xyz, quat = tum_from_T(np.asarray(traj.poses, dtype=np.float64))
        text = _rows(np.column_stack([traj.stamps, xyz, quat]))
    else:
        text = _rows(np.asarray(traj.poses, dtype=np.float64)[:, :3, :].reshape(-1, 12))
    _run_file(path, text)


def _run_file(path: Path, text: str) -> None:
    """Write a file of a run folder (new, or the run's own: ``guard.in_a_run``)."""
    guard.write_text(path, text, guard.in_a_run, "a run's file")


def frames_csv(result: OdometryResult) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(FRAME_COLUMNS)
    # attributes, not dataclasses.asdict (which deep-copies every field: it was the largest
    # per-frame cost of writing a run)
    writer.writerows([f.index, f"{f.stamp:.9f}", f"{f.time_ms:.6f}", f"{f.register_ms:.6f}",
                      f"{f.wall_ms:.6f}", f.points, f.correspondences, f.iterations,
                      int(f.converged), int(f.replaced)] for f in result.frames)
    return buf.getvalue()


def write_run(run_dir: Path, result: OdometryResult, gt: Trajectory | None,
              config: dict, metrics: dict, warnings: list[str] | None = None) -> None:
    """Write every file of a finished run; ``metrics.json`` (the ``RunResult`` of ``metrics``
    with the run's names from ``config``) last."""
    guard.make_folder(run_dir, "run folder")
    est = Trajectory(np.asarray(result.stamps, dtype=np.float64), result.poses)
    for stale in ("gt_tum.txt", "gt_kitti.txt", "est_all_tum.txt"):
        guard.remove(run_dir / stale, guard.in_a_run, "a run's file")
    if gt is not None:
        keep = np.isin(est.stamps, gt.stamps)
        if not keep.all():
            write_trajectory(run_dir / "est_all_tum.txt", est, "tum")
        est = Trajectory(est.stamps[keep], est.poses[keep])
        write_trajectory(run_dir / "gt_tum.txt", gt, "tum")
        write_trajectory(run_dir / "gt_kitti.txt", gt, "kitti")
    write_trajectory(run_dir / "est_tum.txt", est, "tum")
    write_trajectory(run_dir / "est_kitti.txt", est, "kitti")
    _run_file(run_dir / "frames.csv", frames_csv(result))
    _run_file(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    _run_file(run_dir / "meta.json",
              json.dumps({**run_meta(), "warnings": list(warnings or [])}, indent=2))
    guard.remove(run_dir / "failed.json", guard.in_a_run, "a run's record")
    seq = config.get("sequence") or {}
    record = RunResult.model_validate({
        **metrics, "label": config.get("label"), "display_name": seq.get("display_name"),
        "sensor_class": seq.get("sensor_class"), "notes": list(warnings or [])})
    _run_file(run_dir / "metrics.json", record.dump())


def write_failure(run_dir: Path, config: dict | None, error: str, trace: str = "",
                  status: str = "failed") -> None:
    """Record a run that did not finish (``status``: failed, interrupted, timeout, crashed)."""
    guard.make_folder(run_dir, "run folder")
    guard.remove(run_dir / "metrics.json", guard.in_a_run, "a run's record")
    if config is not None:
        _run_file(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    _run_file(run_dir / "failed.json", json.dumps(
        {"status": status, "error": error, "traceback": trace,
         "date": datetime.now(UTC).isoformat(timespec="seconds")}, indent=2))


@dataclass(frozen=True)
class RunRecord:
    """A run read back from its folder (``read_run`` / ``load_runs``): its typed ``result``
    (``bench.runs.result.RunResult``, the one record tables, figures, compare, regress,
    fidelity and the notebook API read), its config.yaml and its trajectory files."""

    dir: Path
    result: RunResult
    config: dict
    #: what tells this run's sequence content apart from another content under the same name
    #: ("frames 60-249"; ``bench.runs.sequence_identity``), "" when no other does
    sequence_tag: str = ""

    @property
    def sequence(self) -> str:
        """The sequence's name, with its content tag when another content has that name."""
        return tagged(self.result.sequence, self.sequence_tag)

    @property
    def base_display_name(self) -> str:
        """The display name recorded with the run (no content tag)."""
        return (self.result.display_name or (self.config.get("sequence") or {})
                .get("display_name") or self.result.sequence)

    @property
    def display_name(self) -> str:
        """The sequence's display name, with its content tag when another content of the runs
        read together has that name (``with_sequence_tags``)."""
        return tagged(self.base_display_name, self.sequence_tag)

    @property
    def sensor_class(self) -> str:
        return (self.result.sensor_class or (self.config.get("sequence") or {})
                .get("sensor_class") or "4D sensor")

    @property
    def doppler_kind(self) -> str:
        """The store's Doppler kind when the run was made (runs before it was recorded:
        radial)."""
        return (self.config.get("sequence") or {}).get("doppler_kind") or "radial"

    @property
    def method(self) -> str:
        return self.result.method

    @property
    def seed(self) -> Seed:
        return self.result.seed

    @property
    def label(self) -> str | None:
        return self.result.label or self.config.get("label")

    @property
    def diverged(self) -> bool | None:
        return self.result.diverged

    @property
    def has_gt(self) -> bool:
        return self.result.finished and (self.dir / "gt_tum.txt").exists()

    @cached_property
    def _paired(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        gt = read_run_tum(self.dir / "gt_tum.txt")
        est = read_run_tum(self.dir / "est_tum.txt")
        idx = np.searchsorted(est.stamps, gt.stamps).clip(0, len(est) - 1)
        keep = np.abs(est.stamps[idx] - gt.stamps) < 1e-6
        return gt.stamps[keep], gt.poses[keep], est.poses[idx[keep]]

    @property
    def stamps(self) -> np.ndarray:
        """Stamps [s] of the scored frames (those with ground truth)."""
        return self._paired[0]

    @property
    def gt(self) -> np.ndarray:
        """(N, 4, 4) ground truth T_world_sensor at ``stamps``."""
        return self._paired[1]

    @property
    def est(self) -> np.ndarray:
        """(N, 4, 4) estimated T_world_sensor at ``stamps``."""
        return self._paired[2]


#: a run's two files of two runs (a comparison): 4 x 5 MB at 40,000 poses
@lru_cache(maxsize=4)
def _tum_version(path: str, mtime_ns: int, size: int) -> Trajectory:
    return read_tum(path)


def read_run_tum(path: Path) -> Trajectory:
    """``read_tum`` of a run's trajectory file, parsed once per version of the file (its
    modification time and size) in a process: the report's readers (the file check, the
    tables' stability, every figure) read each run's files several times, 0.1 s each at
    40,000 poses. A copy: the caller may change it."""
    st = Path(path).stat()
    t = _tum_version(str(path), st.st_mtime_ns, st.st_size)
    return Trajectory(t.stamps.copy(), t.poses.copy())


#: results folders whose re-scoring was already announced (one message each)
_told: set[str] = set()


def _config(run_dir: Path) -> dict:
    path = run_dir / "config.yaml"
    try:
        config = (load_yaml(path.read_text()) or {}) if path.exists() else {}
    except (OSError, yaml.YAMLError):
        return {}  # bench report lists the folder's unreadable files
    if not isinstance(config, dict):
        return {}
    # the parts every reader looks into are mappings or absent
    return {k: v for k, v in config.items()
            if k not in ("sequence", "method", "identity") or isinstance(v, dict)}


def _rescored(run_dir: Path, raw: dict, config: dict) -> dict:
    """A metrics.json of schema 1 re-scored from the run's trajectory files (the methods are
    not re-run): every metric of today's ``RunResult`` from est_tum.txt / gt_tum.txt, with the
    lengths in its config.yaml and the default KITTI lengths, alignment and velocity window."""
    from bench.runs.evaluate import Scoring, score

    if raw.get("diverged") is None or not (run_dir / "gt_tum.txt").exists() or \
            not (run_dir / "est_tum.txt").exists():
        return raw
    gt = read_tum(run_dir / "gt_tum.txt")
    est = read_tum(run_dir / "est_tum.txt")
    idx = np.searchsorted(est.stamps, gt.stamps).clip(0, len(est) - 1)
    keep = np.abs(est.stamps[idx] - gt.stamps) < 1e-6
    lengths = config.get("lengths_m") or [float(k) for k in (raw.get("relative_error") or {})]
    timings = {k: raw[k] for k in ("time_ms", "register_ms", "wall_ms") if raw.get(k)}
    part = score(gt.poses[keep], est.poses[idx[keep]], np.zeros(0), name=str(run_dir),
                 scoring=Scoring(tuple(lengths)), stamps=gt.stamps[keep], timings=timings)
    part["diverged"] = raw["diverged"]  # it looked at every frame, est_tum.txt only at some
    return {**raw, **part, "schema": 2, "frames_scored": raw.get("frames_scored",
                                                                  int(keep.sum()))}


def _failed(run_dir: Path, config: dict, info: dict | None = None) -> RunResult:
    """A run that did not finish, from its failed.json (or ``info``) and config.yaml (or its
    folder names)."""
    if info is None:
        try:
            info = json.loads((run_dir / "failed.json").read_text())
        except (OSError, ValueError):
            info = None
        if not isinstance(info, dict):
            info = {"status": "failed", "error": f"{run_dir / 'failed.json'}: unreadable"}
    seq = config.get("sequence") or {}
    name = run_dir.name
    seed = config.get("seed", False if name.endswith("_noseed") else
                      (True if name.endswith("_seed") else None))
    method = (config.get("method") or {}).get("name") or re.sub(r"_(no)?seed$", "", name)
    status = str(info.get("status") or "failed")
    # a failure record never reads as a finished run
    status = "failed" if status == "done" else status
    return RunResult(status=status, error=str(info.get("error") or ""),
                     sequence=seq.get("name") or run_dir.parent.name, method=method, seed=seed,
                     label=config.get("label"), display_name=seq.get("display_name"),
                     sensor_class=seq.get("sensor_class"))


class BrokenRecord(DataError):
    """A run's metrics.json that cannot be read as its record (truncated, not JSON, or a
    field of the wrong type); the message names the file and what was expected."""


#: the status of a run whose metrics.json is broken (shown as a failed row, never as a result)
BROKEN = "broken"


def metrics_raw(path: Path) -> dict:
    """The JSON object of a run's metrics.json; BrokenRecord naming the file when it is not
    valid JSON or not an object."""
    try:
        raw = json.loads(Path(path).read_text())
    except OSError as err:
        raise BrokenRecord(f"{path}: cannot be read ({err.strerror or err})") from None
    except ValueError as err:
        raise BrokenRecord(f"{path}: not valid JSON ({err}); expected the record a finished "
                           "run writes (`bench run` runs it again)") from None
    if not isinstance(raw, dict):
        raise BrokenRecord(f"{path}: expected a JSON object (a run's record), found "
                           f"{type(raw).__name__}")
    schema = raw.get("schema", 1)
    if isinstance(schema, bool) or not isinstance(schema, int):
        raise BrokenRecord(f"{path}: not a valid run record: field schema: should be an "
                           f"integer (got {schema!r})")
    return raw


def check_record(path: Path) -> str | None:
    """Why the metrics.json at ``path`` is broken (its message, naming the file), or None when
    it reads as a ``RunResult`` (an older record: once re-scored, as ``read_run`` reads it)."""
    try:
        read_run(Path(path).parent, _stale=[])
    except BrokenRecord as err:
        return str(err)
    return None


def _broken(run_dir: Path, config: dict, problem: str) -> RunResult:
    """A run whose metrics.json is broken, as a run that did not finish (status ``BROKEN``)."""
    return _failed(run_dir, config, {"status": BROKEN, "error": problem})


def read_run(run_dir: Path, failed: bool = False, _stale: list | None = None
             ) -> RunRecord | None:
    """The finished run in ``run_dir`` (None when it has no metrics.json; with ``failed``, a
    run that did not finish is returned too, its ``result.status`` saying how it ended)."""
    run_dir = Path(run_dir)
    metrics_path = run_dir / "metrics.json"
    config = _config(run_dir)
    if not metrics_path.exists():
        if failed and (run_dir / "failed.json").exists():
            return RunRecord(run_dir, _failed(run_dir, config), config)
        return None
    try:
        raw = metrics_raw(metrics_path)
    except BrokenRecord as err:
        if not failed:
            raise
        return RunRecord(run_dir, _broken(run_dir, config, str(err)), config)
    if raw.get("schema", 1) < 2:
        try:
            new = _rescored(run_dir, raw, config)
        except (ArithmeticError, LookupError, TypeError, ValueError, OSError) as err:
            # the message's first line (a conversion inside the f-string field would quote it)
            detail = str(err).splitlines()[0] if str(err) else repr(err)
            problem = BrokenRecord(f"{metrics_path}: an older record that cannot be re-scored "
                                   f"({detail})")
            if not failed:
                raise problem from None
            return RunRecord(run_dir, _broken(run_dir, config, str(problem)), config)
        stale = [(run_dir, new is not raw)]
        raw = new
        if _stale is not None:
            _stale += stale
        else:
            _announce(stale, run_dir)
    try:
        result = RunResult.model_validate(raw)
    except ValidationError as err:
        problem = BrokenRecord(f"{metrics_path}: not a valid run record: "
                               + "; ".join(f"field {line}" for line in validation_problems(err)))
        if not failed:
            raise problem from None
        return RunRecord(run_dir, _broken(run_dir, config, str(problem)), config)
    return RunRecord(run_dir, result, config)


def _announce(stale: list[tuple[Path, bool]], where: Path) -> None:
    """One message per results folder about its run folders of an older version: how many
    were re-scored from their trajectory files, how many read as they are."""
    key = str(Path(where).resolve())
    if not stale or key in _told:
        return
    _told.add(key)
    rescored = sum(done for _, done in stale)
    parts = []
    if rescored:
        parts.append(f"{rescored} re-scored from their trajectory files (methods not re-run)")
    if len(stale) - rescored:
        parts.append(f"{len(stale) - rescored} read as they are (no trajectory files to "
                     "re-score: no KITTI drift or velocity error)")
    sys.stderr.write(f"note: {len(stale)} run folder(s) under {where} were written by an older "
                     f"version of the harness: {'; '.join(parts)}; `bench run` re-runs them\n")


def load_runs(results_dir: Path, only: set[Path] | None = None,
              failed: bool = False) -> list[RunRecord]:
    """Every finished run under ``results_dir`` (or only the folders in ``only``), in path
    order; with ``failed`` also the runs that did not finish (failed.json)."""
    wanted = None if only is None else {Path(p).resolve() for p in only}
    names = ("metrics.json", "failed.json") if failed else ("metrics.json",)
    folders = sorted({p.parent for n in names for p in Path(results_dir).rglob(n)})
    runs, stale = [], []
    for folder in folders:
        if wanted is None or folder.resolve() in wanted:
            run = read_run(folder, failed, stale)
            if run is not None:
                runs.append(run)
    _announce(stale, Path(results_dir))
    return with_sequence_tags(runs)


def with_sequence_tags(runs: list[RunRecord]) -> list[RunRecord]:
    """``runs`` read together, each whose sequence name another content shares tagged with
    what tells its content apart (``bench.runs.sequence_identity``), so no table, figure or
    summary pairs different content as one sequence."""
    tags = sequence_tags([r.base_display_name for r in runs], [r.config for r in runs])
    return [r if r.sequence_tag == tag else replace(r, sequence_tag=tag)
            for r, tag in zip(runs, tags, strict=True)]
