"""From an experiment (or a single-run command line) to the planned jobs: every job resolved
against its store before anything runs (``plan``), so bad input is one clear error up front."""

from __future__ import annotations

import os
import warnings
from dataclasses import replace
from pathlib import Path

from rich.console import Console

from bench.data.synth import ensure_suite_with_progress
from bench.runs.experiment import Experiment, SequenceEntry
from bench.runs.folders import RunRecord, read_run
from bench.runs.job import Job, prepare, run_job, scored_ground_truth
from loaders.errors import DataError
from methods.registry import seed_option


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


def jobs_for_experiment(exp: Experiment, console: Console | None = None) -> list[Job]:
    sequences = list(exp.sequences)
    if exp.suite is not None:
        sequences += suite_sequences(exp.suite, exp.data_dir, console)
    if exp.synthetic:
        sequences += synthetic_sequences(exp, console)
    missing = [str(s.path) for s in sequences if not Path(s.path).exists()]
    if missing:
        raise DataError(f"experiment {exp.name!r}: stores not found: {', '.join(missing)}")
    known = set().union(*(_names(s) for s in sequences)) if sequences else set()
    for m in exp.methods:
        unknown = sorted(set(m.sequences or ()) - known)
        if unknown:
            raise DataError(f"experiment {exp.name!r}: method {m.name!r} names unknown "
                            f"sequences {', '.join(unknown)}")
    return [
        Job(store=Path(s.path), method=m.name, seed=seed, out_root=exp.out_dir,
            params=dict(v.params), lengths_m=tuple(exp.lengths_m), name=s.name,
            display_name=s.display_name, sensor_class=s.sensor_class, label=v.label,
            frame_range=s.frame_range)
        for s in sequences
        for m in exp.methods
        if m.sequences is None or _names(s) & set(m.sequences)
        for v in m.variants()  # one per sweep point (bench.runs.sweep)
        for seed in m.seed_options()
    ]


def single_job(method: str, data: Path, seed: bool, out: Path | None, params: dict) -> Job:
    """One run; ``out`` is the run folder itself (default results/runs/<store>/<method_seed>)."""
    return Job(store=Path(data), method=method, seed=seed_option(method, seed),
               out_root=Path("results/runs"), params=params, run_dir_override=out)


def plan(jobs: list[Job]) -> list[Job]:
    """Resolve every job before any runs: the stores open, the parameters are valid, the
    output folders are writable and no two jobs share a folder. Raises one DataError listing
    every problem; returns the jobs with their folders fixed."""
    problems, planned, owners, paths, warned = [], [], {}, {}, set()
    for job in jobs:
        try:
            prep = prepare(job)
        except DataError as err:
            problems.append(str(err))
            continue
        key = (job.store, job.frame_range)
        if key not in paths:
            paths[key] = _gt_path_length(prep)
        prep.sequence.close()
        problems += _lengths_problems(job, paths[key], warned)
        other = owners.get(prep.run_dir)
        if other is not None and other[1] != prep.key:
            problems.append(
                f"{prep.run_dir}: two runs would share this folder ({other[0].title} and "
                f"{job.title}); give the sequences distinct names or the method variants "
                "distinct 'label:'s")
            continue
        owners[prep.run_dir] = (job, prep.key)
        _check_writable(prep.run_dir)
        planned.append(replace(job, run_dir_override=prep.run_dir, run_key=prep.key,
                               store_sha256=prep.config["identity"]["store_sha256"]))
    if problems:
        raise DataError("\n".join(dict.fromkeys(problems)))
    # the same run asked for twice (e.g. by two tables) runs once
    return list({j.run_dir_override: j for j in planned}.values())


#: a segment of length L is accepted when its path length is within this fraction of L
#: (metrics.relative's tolerance)
SEGMENT_TOLERANCE = 0.2


def _gt_path_length(prep) -> float | None:
    """Length [m] of the scored ground truth's path (None without ground truth)."""
    gt = scored_ground_truth(prep.sequence)
    return None if gt is None or len(gt) < 2 else gt.path_length_m()


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
    return []


def _check_writable(run_dir: Path) -> None:
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
                           dict(params or {}))])[0]
    outcome = run_job(job, force)
    if outcome.status not in ("done", "skipped"):
        raise DataError(f"{method} on {store}: {outcome.message}")
    return read_run(outcome.run_dir)
