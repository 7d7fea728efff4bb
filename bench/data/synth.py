"""``bench synth``: one synthetic sequence into a store, a named suite (with a progress bar per
sequence), or the list of scenes, sensors, options and suites."""

from __future__ import annotations

from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from bench import guard
from loaders.errors import DataError


def synth_command(console: Console, scene: str | None, sensor: str, frames: int, seed: int,
                  out: Path | None, noise: bool, options: dict, list_: bool, suite: str | None,
                  data_dir: Path) -> int:
    """Do what the options ask for; returns the exit code."""
    from loaders import synthetic

    if list_:
        for title, items in (("scenes", synthetic.list_scenes()),
                             ("sensors", synthetic.list_sensors()),
                             ("options (-o key=value)", synthetic.OPTIONS),
                             ("suites", {k: f"{len(v)} sequences"
                                         for k, v in synthetic.SUITES.items()})):
            console.print(f"[bold]{title}[/]")
            for name, text in items.items():
                console.print(f"  {name:<18} {text}", markup=False)  # units: "[m/s]"
        return 0
    if suite is not None:
        paths = ensure_suite_with_progress(suite, data_dir, console)
        console.print(f"[green]{len(paths)} stores[/] under {data_dir / suite}")
        return 0
    if scene is None or out is None:
        raise DataError("give a SCENE and --out PATH.h5 (or --list, or --suite NAME)")
    try:
        from loaders.synthetic_options import check_options

        check_options(options)
        seq = synthetic.SyntheticSequence(scene, sensor, frames=frames, seed=seed, noise=noise,
                                          **options)
    except (ValueError, KeyError) as err:
        raise DataError(f"bench synth: {err}") from err
    from bench.data.convert import write_with_progress

    # a synthetic store is made again; a converted store (real data) or any other file never
    guard.regenerated_file(out, guard.is_synthetic_store, "a synthetic store")
    write_with_progress(seq, out, guard.is_synthetic_store, "a synthetic store")
    return 0


def ensure_suite_with_progress(suite: str, data_dir: Path,
                               console: Console | None = None) -> list[Path]:
    """Generate (or reuse) a synthetic suite with a progress bar per sequence."""
    from loaders import synthetic

    tasks: dict[str, int] = {}
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console or Console()) as progress:

        def report(name: str, done: int, total: int) -> None:
            if name not in tasks:
                tasks[name] = progress.add_task(escape(f"{suite}/{name}"), total=total)
            progress.update(tasks[name], completed=done)

        def write(seq, path: Path, cb) -> Path:  # a stale synthetic store only, never a file
            return guard.write_store(seq, path, guard.is_synthetic_store,  # of another kind
                                     "a synthetic store", progress=cb)

        return synthetic.ensure_suite(suite, data_dir, progress=report, writer=write)


def ensure_entries_with_progress(entries: list, out_dir: Path,
                                 console: Console | None = None) -> list[Path]:
    """Write the stores of synthetic ``entries`` (``loaders.synthetic.SuiteEntry``; an
    experiment's own ``synthetic:`` sequences, e.g. the tuning seeds of configs/tuning/) under
    ``out_dir`` as ``<name>-<entry hash>.h5`` (so experiments that list the same sequence
    share its store), only missing ones, with a progress bar each."""
    from loaders.synthetic.suite import store_is_current

    paths = []
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console or Console()) as progress:
        for entry in entries:
            path = Path(out_dir) / f"{entry.name}-{entry.entry_hash()}.h5"
            if not store_is_current(path, entry):
                task = progress.add_task(escape(f"{out_dir.name}/{entry.name}"),
                                         total=entry.frames)
                # a store of an older entry hash is the harness's synthetic store: made again
                guard.write_store(entry.sequence(out_dir.name), path, guard.is_synthetic_store,
                                  "a synthetic store",
                                  progress=lambda i, _t=task: progress.update(_t,
                                                                              completed=i + 1))
            paths.append(path)
    return paths
