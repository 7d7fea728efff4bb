"""From an experiment (or a single-run command line) to the list of jobs to execute."""

from __future__ import annotations

from pathlib import Path

from rich.console import Console

from bench.experiment import Experiment, SequenceEntry
from bench.progress import ensure_suite_with_progress
from bench.run import Job
from loaders.errors import DataError
from methods.registry import get_method


def suite_sequences(suite: str, data_dir: Path, console: Console | None = None
                    ) -> list[SequenceEntry]:
    """Generate (or reuse) a synthetic suite and describe its stores."""
    from loaders.synthetic import suite_entries

    paths = ensure_suite_with_progress(suite, data_dir, console)
    entries = suite_entries(suite)
    return [SequenceEntry(path=p, name=e.name, display_name=e.display, sensor_class=e.klass)
            for p, e in zip(paths, entries, strict=True)]


def _names(entry: SequenceEntry) -> set[str]:
    return {n for n in (entry.name, Path(entry.path).stem, entry.display_name) if n}


def jobs_for_experiment(exp: Experiment, console: Console | None = None) -> list[Job]:
    sequences = list(exp.sequences)
    if exp.suite is not None:
        sequences += suite_sequences(exp.suite, exp.data_dir, console)
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
            params=dict(m.params), lengths_m=tuple(exp.lengths_m), name=s.name,
            display_name=s.display_name, sensor_class=s.sensor_class, label=m.label)
        for s in sequences
        for m in exp.methods
        if m.sequences is None or _names(s) & set(m.sequences)
        for seed in m.seed_options()
    ]


def single_job(method: str, data: Path, seed: bool, out: Path | None, params: dict) -> Job:
    """One run; ``out`` is the run folder itself (default results/runs/<store>/<method_seed>)."""
    cls = get_method(method)
    seed_opt = seed if cls.uses_initial_guess else None
    return Job(store=Path(data), method=method, seed=seed_opt,
               out_root=Path("results/runs"), params=params, run_dir_override=out)
