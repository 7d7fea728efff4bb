"""The ``bench`` command line: list, synth, convert, inspect, run, table, speed, reproduce."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from bench.convert import convert_app
from loaders.errors import DataError

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Benchmark harness for Doppler-based scan matching (4D radar, FMCW LiDAR).")
app.add_typer(convert_app, name="convert")
console = Console()


@app.command("list")
def list_cmd() -> None:
    """List the registered methods, loaders, synthetic scenes and sensors."""
    from rich.table import Table

    from bench.convert import LOADERS
    from loaders.synthetic import list_scenes, list_sensors
    from methods.registry import METHODS

    for title, items in (
        ("Methods", {name: cls.description for name, cls in METHODS.items()}),
        ("Loaders (bench convert LOADER)", LOADERS),
        ("Synthetic scenes (bench synth SCENE)", list_scenes()),
        ("Synthetic sensors (--sensor)", list_sensors()),
    ):
        table = Table(title=title, title_justify="left", show_header=False)
        for name, text in items.items():
            table.add_row(f"[bold]{name}[/]", text)
        console.print(table)


@app.command()
def synth(
    scene: Annotated[str | None, typer.Argument(help="scene name (see --list)")] = None,
    sensor: Annotated[str, typer.Option(help="sensor model")] = "radar-semidense",
    frames: Annotated[int, typer.Option(min=2, help="number of scans")] = 120,
    seed: Annotated[int, typer.Option(help="random seed")] = 0,
    out: Annotated[Path | None, typer.Option(help="store to write (.h5)")] = None,
    noise: Annotated[bool, typer.Option(help="add sensor noise")] = True,
    option: Annotated[list[str] | None, typer.Option(
        "--option", "-o", help="generator option key=value (points, uturn, speed, ...)")] = None,
    list_: Annotated[bool, typer.Option("--list", help="list scenes, sensors and suites")] = False,
    suite: Annotated[str | None, typer.Option(help="generate a named suite instead")] = None,
    data_dir: Annotated[Path, typer.Option(help="cache folder of suites")] = Path("data"),
) -> None:
    """Generate a synthetic 4D-sensor sequence (exact Doppler and ground truth) into a store."""
    from bench.convert import write_with_progress
    from loaders import synthetic

    if list_:
        for title, items in (("scenes", synthetic.list_scenes()),
                             ("sensors", synthetic.list_sensors()),
                             ("options (-o key=value)", synthetic.OPTIONS),
                             ("suites", {k: f"{len(v)} sequences"
                                         for k, v in synthetic.SUITES.items()})):
            console.print(f"[bold]{title}[/]")
            for name, text in items.items():
                console.print(f"  {name:<18} {text}")
        return
    if suite is not None:
        paths = ensure_suite_with_progress(suite, data_dir)
        console.print(f"[green]{len(paths)} stores[/] under {data_dir / suite}")
        return
    if scene is None or out is None:
        raise DataError("give a SCENE and --out PATH.h5 (or --list, or --suite NAME)")
    options = _parse_params(option)
    try:
        seq = synthetic.SyntheticSequence(scene, sensor, frames=frames, seed=seed, noise=noise,
                                          **options)
    except (ValueError, KeyError) as err:
        raise DataError(f"bench synth: {err}") from err
    write_with_progress(seq, out)


def ensure_suite_with_progress(suite: str, data_dir: Path) -> list[Path]:
    """Generate (or reuse) a synthetic suite with a progress bar per sequence."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from loaders import synthetic

    tasks: dict[str, int] = {}
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console) as progress:

        def report(name: str, done: int, total: int) -> None:
            if name not in tasks:
                tasks[name] = progress.add_task(f"{suite}/{name}", total=total)
            progress.update(tasks[name], completed=done)

        return synthetic.ensure_suite(suite, data_dir, progress=report)


@app.command()
def inspect(
    path: Annotated[Path, typer.Argument(help="a store (.h5) or a NumPy frame folder")],
    period: Annotated[float | None, typer.Option(help="scan period [s] for frame folders")] = None,
) -> None:
    """Print frames, points per frame, period, duration, GT figures and a Doppler-sign check."""
    from bench.inspect import inspect_path

    inspect_path(path, period, console)


@app.command()
def run(
    experiment: Annotated[Path | None, typer.Argument(help="experiment YAML")] = None,
    method: Annotated[str | None, typer.Option(help="method name (see bench list)")] = None,
    data: Annotated[Path | None, typer.Option(help="store (.h5) for a single run")] = None,
    out: Annotated[Path | None, typer.Option(help="run folder (single run) or results root")]
    = None,
    seed: Annotated[bool, typer.Option("--seed/--no-seed",
                                       help="constant-velocity initial guess or identity")] = True,
    param: Annotated[list[str] | None, typer.Option("--param", "-p",
                                                    help="method parameter key=value")] = None,
    jobs: Annotated[int | None, typer.Option(help="parallel worker processes")] = None,
    force: Annotated[bool, typer.Option(help="rerun finished runs")] = False,
) -> None:
    """Run one method on one store, or every run of an experiment YAML."""
    from bench.experiment import load_experiment
    from bench.run import execute, summarize
    from bench.runplan import jobs_for_experiment, single_job

    if experiment is not None:
        exp = load_experiment(experiment)
        if out is not None:
            exp.out = out
        job_list = jobs_for_experiment(exp, console)
        outcomes = execute(job_list, jobs or exp.jobs, force, console)
        results_dir = exp.out_dir
    else:
        if method is None or data is None:
            raise DataError("give an EXPERIMENT.yaml, or --method M --data PATH.h5 [--out DIR]")
        job = single_job(method, data, seed, out, _parse_params(param))
        outcomes = execute([job], 1, force, console)
        results_dir = None
    console.print(f"[bold]{summarize(outcomes)}[/]")
    if results_dir is not None and any(o.status != "failed" for o in outcomes):
        from bench.tables import write_tables

        console.print(write_tables(results_dir)["md"])
    if any(o.status == "failed" for o in outcomes):
        raise typer.Exit(1)


def _parse_params(items: list[str] | None) -> dict:
    """``key=value`` strings -> dict (values parsed as YAML: 3, 0.5, true, [1, 2])."""
    import yaml

    params = {}
    for item in items or []:
        if "=" not in item:
            raise DataError(f"--param expects key=value, got {item!r}")
        key, value = item.split("=", 1)
        params[key.strip()] = yaml.safe_load(value)
    return params


@app.command()
def table(
    results_dir: Annotated[Path, typer.Argument(help="results folder (searched recursively)")],
    format: Annotated[str, typer.Option("--format", "-f", help="md, tex or csv")] = "md",
    out: Annotated[Path | None, typer.Option(help="folder for table.{md,tex,csv}")] = None,
) -> None:
    """Print the paper-shaped table (Table III) and write table.md / .tex / .csv."""
    from bench.tables import FORMATS, write_tables

    if format not in FORMATS:
        raise DataError(f"unknown table format {format!r}; choose from {', '.join(FORMATS)}")
    texts = write_tables(results_dir, out)
    console.print(texts[format], markup=False, highlight=False)
    console.print(f"[dim]wrote {(out or results_dir)}/table.{{md,tex,csv}}[/]")


@app.command()
def figures(
    results_dir: Annotated[Path, typer.Argument(help="results folder (searched recursively)")],
    out: Annotated[Path | None, typer.Option(help="output folder (default RESULTS_DIR/figures)")]
    = None,
) -> None:
    """Top-view trajectory plots per sequence (estimates aligned at the first pose)."""
    from bench.figures import plot_trajectories

    paths = plot_trajectories(results_dir, out)
    if not paths:
        raise DataError(f"{results_dir}: no finished runs with ground truth to plot")
    console.print(f"wrote {len(paths)} figures to {paths[0].parent}/")


@app.command()
def speed(
    sizes: Annotated[str, typer.Option(help="point counts, comma separated")]
    = "1000,4000,16000,64000,128000",
    methods: Annotated[str | None, typer.Option(help="methods (default: all registered)")]
    = None,
    repeats: Annotated[int, typer.Option(min=1, help="timed repeats per size")] = 7,
    out: Annotated[Path, typer.Option(help="output folder")] = Path("results/speed"),
    memory: Annotated[bool, typer.Option(help="also measure the peak memory of a LiDAR run")]
    = True,
) -> None:
    """Time every method on the same synthetic scan pairs; print ratios to `doppler`."""
    from bench.speed import run_speed

    run_speed([int(s) for s in sizes.split(",")],
              methods.split(",") if methods else None, repeats, out, console, memory)


@app.command()
def reproduce(
    out: Annotated[Path, typer.Option(help="results folder")] = Path("results/paper-synthetic"),
    data_dir: Annotated[Path, typer.Option(help="data folder (synthetic cache, real stores)")]
    = Path("data"),
    jobs: Annotated[int, typer.Option(help="parallel worker processes")] = 2,
    force: Annotated[bool, typer.Option(help="rerun finished runs")] = False,
    synthetic_only: Annotated[bool, typer.Option(help="ignore real stores")] = False,
) -> None:
    """Reproduce the paper's Table III: every method, both seed options, on the paper's
    sequences (real stores under DATA_DIR/real when present, else the synthetic suite)."""
    from bench.reproduce import reproduce_table

    reproduce_table(out, data_dir, jobs, force, synthetic_only, console)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    console.print(f"[yellow]warning:[/] {message}", highlight=False)


def main() -> None:
    """Console entry point: bad input ends with one clear message, not a traceback."""
    import warnings

    warnings.showwarning = _show_warning
    try:
        app(standalone_mode=False)
    except DataError as err:
        console.print(f"[bold red]error:[/] {err}", markup=True, highlight=False)
        sys.exit(2)
    except FileNotFoundError as err:
        console.print(f"[bold red]error:[/] {err}", highlight=False)
        sys.exit(2)
    except typer.Exit as e:
        sys.exit(e.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        console.print("[red]aborted[/]")
        sys.exit(130)
    except Exception as err:
        if callable(getattr(err, "show", None)) and hasattr(err, "exit_code"):
            err.show()  # a usage error (unknown option, missing argument)
            sys.exit(err.exit_code)
        raise


if __name__ == "__main__":
    main()
