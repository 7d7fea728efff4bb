"""From an experiment (or a single-run command line) to the planned jobs: every job resolved
against its store before anything runs (``plan``), so bad input is one clear error up front."""

from __future__ import annotations

import fnmatch
import os
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml
from rich.console import Console

from bench import guard
from bench.data.advice import doppler_refusal
from bench.data.synth import ensure_suite_with_progress
from bench.runs.experiment import Experiment, SequenceEntry, expand_sequences
from bench.runs.folders import RunRecord, read_run, write_failure
from bench.runs.job import Job, calibration_frames, prepare, run_job
from bench.runs.ownership import foreign_run, run_identity
from bench.runs.reuse import rename_reused
from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.yamlio import read_yaml
from methods.registry import get_method, seed_option


def suite_sequences(suite: str, data_dir: Path, console: Console | None = None
                    ) -> list[SequenceEntry]:
    """Generate (or reuse) a synthetic suite and describe its stores."""
    from loaders.synthetic import suite_entries

    paths = ensure_suite_with_progress(suite, data_dir, console)
    entries = suite_entries(suite)
    return [SequenceEntry(path=p, name=e.name, display_name=e.display, sensor_class=e.klass)
            for p, e in zip(paths, entries, strict=True)]


def synthetic_sequences(exp: Experiment, console: Console | None = None
                        ) -> list[SequenceEntry]:
    """Generate (or reuse) the experiment's own synthetic sequences under
    ``data_dir/synthetic-entries/`` and describe their stores."""
    from bench.data.synth import ensure_entries_with_progress

    entries = [s.suite_entry() for s in exp.synthetic]
    paths = ensure_entries_with_progress(entries, exp.data_dir / "synthetic-entries",
                                         console)
    return [SequenceEntry(path=p, name=e.name, display_name=e.display, sensor_class=e.klass)
            for p, e in zip(paths, entries, strict=True)]


def _names(entry: SequenceEntry) -> set[str]:
    return {n for n in (entry.name, Path(entry.path).stem, entry.display_name) if n}


def _is_pattern(name: str) -> bool:
    return any(c in name for c in "*?[")


def _wanted(entry: SequenceEntry, patterns: list[str] | None) -> bool:
    """A method's ``sequences`` (names or glob patterns) select this sequence."""
    if patterns is None:
        return True
    names = _names(entry)
    return any(fnmatch.fnmatchcase(n, p) for p in patterns for n in names)


def jobs_for_experiment(exp: Experiment, console: Console | None = None) -> list[Job]:
    def say(text: str) -> None:
        if console is not None:
            console.print(f"{exp.name}: {text}", markup=False, soft_wrap=True)
        else:
            warnings.warn(f"{exp.name}: {text}", stacklevel=3)

    sequences = expand_sequences(list(exp.sequences), say)
    if exp.suite is not None:
        sequences += suite_sequences(exp.suite, exp.data_dir, console)
    if exp.synthetic:
        sequences += synthetic_sequences(exp, console)
    if not sequences:
        raise DataError(f"experiment {exp.name!r}: none of its stores exist (convert them "
                        "first: `bench datasets` lists the commands)")
    missing = [str(s.path) for s in sequences if not Path(s.path).exists()]
    if missing:
        raise DataError(f"experiment {exp.name!r}: stores not found: {', '.join(missing)}")
    known = set().union(*(_names(s) for s in sequences)) if sequences else set()
    optional = any(s.optional for s in exp.sequences)
    for m in exp.methods:
        unknown = sorted(n for n in set(m.sequences or ()) - known
                         if not _is_pattern(n) and not optional)
        if unknown:
            raise DataError(f"experiment {exp.name!r}: method {m.name!r} names unknown "
                            f"sequences {', '.join(unknown)}")
    return [
        Job(store=Path(s.path), method=m.name, seed=seed, out_root=exp.out_dir,
            params=dict(v.params), lengths_m=tuple(exp.lengths_m),
            kitti_lengths_m=tuple(exp.kitti_lengths_m), alignment=exp.alignment, name=s.name,
            display_name=s.display_name, sensor_class=s.sensor_class, label=v.label,
            frame_range=s.frame_range)
        for s in sequences
        for m in exp.methods
        if _wanted(s, m.sequences)
        for v in m.variants()  # one per sweep point (bench.runs.sweep)
        for seed in m.seed_options()
    ]


def single_job(method: str, data: Path, seed: bool, out: Path | None, params: dict,
               scoring: dict | None = None) -> Job:
    """One run; ``out`` is the run folder itself (default results/runs/<store>/<method_seed>);
    ``scoring``: lengths_m, kitti_lengths_m, alignment (Job fields) other than the defaults."""
    return Job(store=Path(data), method=method, seed=seed_option(method, seed),
               out_root=Path("results/runs"), params=params, run_dir_override=out,
               **{k: v for k, v in (scoring or {}).items() if v is not None})


def plan(jobs: list[Job], refused: list[str] | None = None, own_only: bool = False
         ) -> list[Job]:
    """Resolve every job before any runs: the stores open, the parameters are valid, the
    output folders are writable and no two jobs share a folder. Raises one DataError listing
    every problem; returns the jobs with their folders fixed.

    ``refused`` (an experiment): a method that cannot run on a store's Doppler (none, or
    ego-compensated) refuses only that pair: its reason (with the option that would make it
    run) is appended to ``refused`` and recorded in its run folder as a ``refused``
    failed.json (a failed row in every table), and the other pairs are planned.

    ``own_only`` (``bench run --method``: a folder named by the user or the default one): a
    folder holding a run of another method, seed option, parameters, frame range or store
    path is refused (``bench.guard.foreign_run``), ``--force`` included; an experiment's folders are
    its own layout (a changed parameter there runs again)."""
    problems, planned, owners, paths, warned = [], [], {}, {}, set()
    for job in jobs:
        try:
            prep = prepare(job)
        except DataError as err:
            problems.append(str(err))
            continue
        doppler = _doppler_problem(job, prep.sequence)
        if doppler:
            prep.sequence.close()
            if refused is None:
                problems.append(doppler)
            else:
                refused.append(f"{job.title}: {doppler}")
                _record_refusal(prep.run_dir, prep.config, doppler)
            continue
        key = (job.store, job.frame_range)
        if key not in paths:
            paths[key] = _gt_path_length(prep)
        prep.sequence.close()
        problems += _lengths_problems(job, paths[key], warned)
        other = owners.get(prep.run_dir)
        if other is not None and other[1] != prep.key:
            same = other[0].store.resolve() == job.store.resolve()
            what = (f"{other[0].title} and {job.title}" if same else
                    f"{other[0].title} of {other[0].store} and {job.title} of {job.store}: two "
                    "stores of different content under one sequence name")
            problems.append(
                f"{prep.run_dir}: two runs would share this folder ({what}); give the "
                "sequences distinct names (an experiment's sequences: name:) or the method "
                "variants distinct 'label:'s")
            continue
        owners[prep.run_dir] = (job, prep.key)
        _check_writable(prep.run_dir, job.store)
        if own_only:
            foreign_run(prep.run_dir, run_identity(prep.config), "bench run")
        other_store = _other_content(prep.run_dir, job.store,
                                     prep.config["identity"]["store_sha256"])
        if other_store:
            problems.append(other_store)
            continue
        renamed = rename_reused(prep.run_dir, prep.key, prep.config["sequence"])
        if renamed:
            warnings.warn(renamed, stacklevel=2)
        planned.append(replace(job, run_dir_override=prep.run_dir, run_key=prep.key,
                               store_sha256=prep.config["identity"]["store_sha256"],
                               code_sha256=prep.config["identity"]["code_sha256"]))
    if problems:
        raise DataError("\n".join(dict.fromkeys(problems)))
    # the same run asked for twice (e.g. by two tables) runs once
    return list({j.run_dir_override: j for j in planned}.values())


#: the status of a run an experiment did not start because its store cannot feed its method
REFUSED = "refused"


def _record_refusal(run_dir: Path, config: dict, reason: str) -> None:
    """A refused pair as a run that did not finish (its folder's failed.json), unless the
    folder holds a finished run (never lost)."""
    if not (run_dir / "metrics.json").exists():
        _check_writable(run_dir)
        write_failure(run_dir, config, reason, status=REFUSED)


def _doppler_problem(job: Job, seq) -> str | None:
    """Why ``job``'s method cannot run on its store's Doppler (None when it can): a method that
    declares ``needs_doppler`` on a store without Doppler, or with ego-compensated Doppler
    (``SensorInfo.doppler_kind``: static points read about 0 m/s, not the radial velocity)."""
    cls = get_method(job.method)
    if not getattr(cls, "needs_doppler", False):
        return None
    refusal = doppler_refusal(job.store, job.method, seq)
    if refusal is None:
        return None
    if "has no Doppler values" in refusal:
        return (f"{refusal}, or run a method that needs none (icp-p2p, gicp, kiss-icp, ...), or "
                f"leave this store out of {job.method} (the method's `sequences:` list in the "
                "experiment)")
    return (f"{refusal}, or run a method that needs no Doppler, or leave this store out of "
            f"{job.method} (the method's `sequences:` list in the experiment)")


#: a segment of length L is accepted when its path length is within this fraction of L
#: (metrics.relative's tolerance)
SEGMENT_TOLERANCE = 0.2


def _gt_path_length(prep) -> float | None:
    """Length [m] of the scored ground truth's path (None without ground truth)."""
    seq = prep.sequence
    gt, excluded = seq.ground_truth, calibration_frames(seq)
    if gt is None or len(gt) < 2:
        return None
    if excluded is None:
        return gt.path_length_m()
    poses, scored = gt_for_frames(gt, seq.stamps)
    xyz = poses[scored & ~excluded][:, :3, 3]
    return float(np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum()) if len(xyz) > 1 else None


def _lengths_problems(job: Job, path_m: float | None, warned: set[str]) -> list[str]:
    """An error when no requested segment length fits into the ground truth's path (the run
    would be unscorable); a warning, once per sequence (``warned``), for lengths that do not
    fit."""
    if path_m is None:
        return []
    fits = [L for L in job.lengths_m if (1 - SEGMENT_TOLERANCE) * L <= path_m]
    name = job.name or job.store.stem
    if not fits:
        return [f"{job.store}: the ground truth's path is {path_m:.1f} m long, too short for the "
                f"shortest segment length {min(job.lengths_m):g} m; choose lengths_m up to "
                f"{path_m / (1 - SEGMENT_TOLERANCE):.0f} m"]
    too_long = sorted(set(job.lengths_m) - set(fits))
    if too_long and name not in warned:
        warned.add(name)
        warnings.warn(f"{name}: the ground truth's path is {path_m:.1f} m long: no segments of "
                      f"{', '.join(f'{L:g}' for L in too_long)} m (their cells stay empty)",
                      stacklevel=3)
    kitti_short = [L for L in job.kitti_lengths_m if path_m <= L]
    if kitti_short and f"kitti:{name}" not in warned:
        warned.add(f"kitti:{name}")
        warnings.warn(f"{name}: the ground truth's path is {path_m:.1f} m long: "
                      + ("no KITTI drift (its shortest length is "
                         f"{min(job.kitti_lengths_m):g} m)" if len(kitti_short) ==
                         len(job.kitti_lengths_m) else "KITTI drift leaves out "
                         f"{', '.join(f'{L:g}' for L in kitti_short)} m"), stacklevel=3)
    return []


def _other_content(run_dir: Path, store: Path, sha256: str) -> str | None:
    """Why ``run_dir`` must not take a run of ``store``: it holds a run of another store (at
    another path, of other content) under the same sequence name, which a new run would
    silently replace (two stores named ``data1``: the bag in full and a cut of it). None when
    it holds no run, a run of this store (re-converted in place: it runs again), or of the
    same content."""
    try:
        config = read_yaml(run_dir / "config.yaml") or {}
    except (OSError, ValueError, yaml.YAMLError):
        return None
    if not isinstance(config, dict):
        return None
    seq = config.get("sequence") if isinstance(config.get("sequence"), dict) else {}
    identity = config.get("identity") if isinstance(config.get("identity"), dict) else {}
    old_store, old_sha = seq.get("store"), identity.get("store_sha256")
    if not old_store or not old_sha or old_sha == sha256:
        return None
    if Path(str(old_store)).resolve() == Path(store).resolve():
        return None
    return (f"{run_dir}: holds a run of sequence {seq.get('name')!r} from {old_store} (SHA-256 "
            f"{str(old_sha)[:12]}); {store} (SHA-256 {sha256[:12]}) is another store of that "
            "name and would replace it: name it apart (bench convert --name, an experiment's "
            "name:) or give the run another --out")


def _check_writable(run_dir: Path, store: Path | None = None) -> None:
    """The run folder can be written: its first existing folder is writable, and the output
    guard lets a harness run in (``bench.guard.run_folder``: no input inside it, not a folder
    of other files, not a run of ``bench score``)."""
    guard.run_folder(run_dir, guard.HARNESS, None, [store])
    parent = run_dir
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise DataError(f"{run_dir}: cannot write results here: {parent} is a file, "
                        "expected a folder")
    if not (parent / "metrics.json").exists() and not _writable(parent):
        raise DataError(f"{run_dir}: cannot write results here: {parent} is not writable")


def _writable(path: Path) -> bool:
    return os.access(path, os.W_OK | os.X_OK)


def run_single(method: str, store: Path, seed: bool = True, params: dict | None = None,
               out: Path | None = None, force: bool = False) -> RunRecord:
    """Plan and run one job in this process, exactly as ``bench run`` does (a finished run with
    the same key is reused); DataError when it fails."""
    job = plan([single_job(method, Path(store), seed, Path(out) if out is not None else None,
                           dict(params or {}))], own_only=True)[0]
    outcome = run_job(job, force)
    if outcome.status not in ("done", "skipped"):
        raise DataError(f"{method} on {store}: {outcome.message}")
    return read_run(outcome.run_dir)
