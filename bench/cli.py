"""The ``bench`` command line: list, synth, convert, inspect, calibrate, run, table, figures,
speed, reproduce.

Exit codes: 0 when everything asked for succeeded, 1 when any run failed (the summary lists
them), 2 for a user error (bad input, option or YAML; one message, no traceback), 130 after
Ctrl-C.
"""

from __future__ import annotations

import os
import sys

# library thread counts are pinned before numpy & co. load, the same in every executor mode
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from pathlib import Path  # noqa: E402
from typing import Annotated  # noqa: E402

import typer  # noqa: E402
from rich.markup import escape  # noqa: E402

from bench.console import make_console  # noqa: E402
from bench.convert import convert_app  # noqa: E402
from loaders.errors import DataError  # noqa: E402

app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="Benchmark harness for Doppler-based scan matching (4D radar, FMCW LiDAR).")
app.add_typer(convert_app, name="convert")
console = make_console()
status = make_console(stderr=True)  # status lines beside data written to stdout


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
    fidelity: Annotated[bool, typer.Option(
        "--fidelity", help="the fidelity report: synthetic-paper's runs of the paper's tables "
        "(run when missing, as `bench reproduce --synthetic-only`) next to the paper's Table "
        "III with ratios, and the paper's findings checked; writes fidelity.md / .csv into "
        "--fidelity-out")] = False,
    fidelity_out: Annotated[Path, typer.Option(help="results folder of --fidelity")] = Path(
        "results/paper-synthetic"),
    realism: Annotated[bool, typer.Option(
        "--realism", help="the real NTU4DRadLM sample's statistics next to the synthetic "
        "semi-dense radar, with ratios (exit 1 while one is off by more than 20 %)")] = False,
) -> None:
    """Generate a synthetic 4D-sensor sequence (exact Doppler and ground truth) into a store."""
    from bench.convert import write_with_progress
    from loaders import synthetic

    if fidelity:
        from bench.reproduce import reproduce_table

        if reproduce_table(fidelity_out, data_dir, 2, False, True, console):
            raise typer.Exit(1)
        return
    if realism:
        from bench.studies.realism import main as realism_main

        raise typer.Exit(realism_main([]))

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
        from bench.progress import ensure_suite_with_progress

        paths = ensure_suite_with_progress(suite, data_dir, console)
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


@app.command()
def inspect(
    path: Annotated[Path, typer.Argument(help="a store (.h5) or a NumPy frame folder")],
    period: Annotated[float | None, typer.Option(help="scan period [s] for frame folders")] = None,
    plot: Annotated[Path | None, typer.Option(
        help="PNG of the speed from Doppler against GT speed (default: "
             "results/inspect/NAME_speed.png; '-' for none)")] = None,
) -> None:
    """Print frames, points per frame, period, duration, GT figures, a Doppler-sign check and
    a sensor-to-GT rotation check; plot the speed from Doppler against the GT speed."""
    from bench.inspect import inspect_path

    if plot is None:
        plot = Path("results/inspect") / f"{path.stem}_speed.png"
    inspect_path(path, period, console, None if str(plot) == "-" else plot)


@app.command()
def calibrate(
    store: Annotated[Path, typer.Argument(help="store (.h5) with Doppler and ground truth")],
    write: Annotated[Path | None, typer.Option(
        "--write", help="write a store with the corrected GT and extrinsic to this path")] = None,
    min_speed: Annotated[float, typer.Option(help="use frames faster than this [m/s]")] = 2.0,
    bootstrap: Annotated[int, typer.Option(min=10, help="bootstrap resamples")] = 200,
) -> None:
    """Estimate the rotation between the sensor frame and the ground truth's body frame from
    the Doppler ego velocity (roll / pitch / yaw with uncertainty, road-plane check)."""
    from bench.calibrate import calibrate_store

    calibrate_store(store, write, console, min_speed, bootstrap)


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
    jobs: Annotated[int | None, typer.Option(min=1, help="parallel workers")] = None,
    force: Annotated[bool, typer.Option(help="rerun finished runs")] = False,
    executor: Annotated[str, typer.Option(help="local (in-process), process (one worker "
                                                "process per job) or dask")] = "process",
    scheduler: Annotated[str | None, typer.Option(
        help="dask scheduler address (default: a LocalCluster)")] = None,
    job_timeout: Annotated[float | None, typer.Option(
        help="end a job that runs longer than this [s]")] = None,
) -> None:
    """Run one method on one store, or every run of an experiment YAML."""
    from bench.executors import EXECUTORS
    from bench.experiment import load_experiment
    from bench.progress import run_jobs
    from bench.run import plan, summarize
    from bench.runplan import jobs_for_experiment, single_job

    if executor not in EXECUTORS:
        raise DataError(f"unknown executor {executor!r}; choose from {', '.join(EXECUTORS)}")
    if experiment is not None:
        exp = load_experiment(experiment)
        if out is not None:
            exp.out = out
        job_list = plan(jobs_for_experiment(exp, console))
        workers, results_dir = jobs or exp.jobs, exp.out_dir
    else:
        if method is None or data is None:
            raise DataError("give an EXPERIMENT.yaml, or --method M --data PATH.h5 [--out DIR]")
        job_list = plan([single_job(method, data, seed, out, _parse_params(param))])
        workers, results_dir = 1, None
    outcomes = run_jobs(job_list, console, workers, force, executor, job_timeout, scheduler)
    console.print(summarize(outcomes), markup=False)
    if results_dir is not None and any(o.status in ("done", "skipped") for o in outcomes):
        from bench.tables import write_tables

        console.print(write_tables(results_dir)["md"], markup=False)
    elif results_dir is None and outcomes and outcomes[0].run_dir is not None:
        _print_run(outcomes[0].run_dir)
    if any(o.status != "done" and o.status != "skipped" for o in outcomes):
        raise typer.Exit(1)


def _print_run(run_dir: Path) -> None:
    """Key metrics of a finished single run, and its folder."""
    import json

    metrics_path = run_dir / "metrics.json"
    if metrics_path.exists():
        m = json.loads(metrics_path.read_text())
        rel = m.get("relative_error") or {}
        scored = [k for k, r in rel.items() if r.get("n")]  # lengths with segments
        parts = []
        for length in dict.fromkeys(scored[:1] + scored[-1:]):  # the shortest and longest
            r = rel[length]
            parts.append(f"{length} m: {r['rot_deg_mean']:.3f} deg / "
                         f"{r['trans_m_mean']:.3f} m")
        ape = m.get("ape") or {}
        if ape.get("trans_rmse_m") is not None:
            parts.append(f"APE {ape['trans_rmse_m']:.3f} m")
        t = m.get("time_ms") or {}
        if t.get("mean") is not None:
            parts.append(f"time {t['mean']:.2f} ms/frame")
        if m.get("diverged"):
            parts.append("DIVERGED")
        console.print("; ".join(parts) or "no ground truth: no errors", markup=False)
    console.print(f"run folder: {run_dir}", markup=False)


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
    results_dirs: Annotated[list[Path], typer.Argument(
        help="results folder(s), searched recursively; several: rows labelled by folder")],
    format: Annotated[str, typer.Option("--format", "-f", help="md, tex or csv")] = "md",
    out: Annotated[Path | None, typer.Option(help="folder for table.{md,tex,csv}")] = None,
    lengths: Annotated[str | None, typer.Option(
        help="only these segment lengths [m], comma separated (e.g. 8,48)")] = None,
    pivot: Annotated[bool, typer.Option(
        help="methods x sequences, one markdown table per length (writes pivot.md)")] = False,
    methods: Annotated[str | None, typer.Option(
        help="only these methods (registry names, comma separated), with their variants")] = None,
    variants: Annotated[bool, typer.Option(
        help="include labelled variants (e.g. ablations); --no-variants: plain methods only")]
    = True,
) -> None:
    """Print the paper-shaped table (Table III) and write table.md / .tex / .csv."""
    from bench.tables import FORMATS, is_variant, save_formats, select_rows, write_tables
    from bench.tables_pivot import to_pivot_markdown

    wanted = None if methods is None else {m.strip() for m in methods.split(",")}

    def keep(row) -> bool:
        return (wanted is None or row.method in wanted) and (variants or not is_variant(row))

    if format not in FORMATS:
        raise DataError(f"unknown table format {format!r}; choose from {', '.join(FORMATS)}")
    try:
        lengths_m = None if lengths is None else [float(x) for x in lengths.split(",")]
    except ValueError:
        raise DataError(f"--lengths {lengths!r}: expected numbers in metres, e.g. 8,48") from None
    try:
        rows, chosen = select_rows(list(results_dirs), lengths_m=lengths_m, keep=keep)
    except ValueError as e:
        raise DataError(str(e)) from None
    texts = write_tables(list(results_dirs), out, rows_lengths=(rows, chosen))
    if pivot:
        text = "\n".join(to_pivot_markdown(rows, x) for x in chosen)
        save_formats(out or results_dirs[0], "pivot", {"md": text})
        sys.stdout.write(text)
        status.print(f"wrote {(out or results_dirs[0])}/pivot.md and table.{{md,tex,csv}}",
                     style="dim", markup=False)
        return
    sys.stdout.write(texts[format])  # plain text, unwrapped (a pipe gets valid CSV)
    status.print(f"wrote {(out or results_dirs[0])}/table.{{md,tex,csv}}", style="dim",
                 markup=False)


@app.command()
def compare(
    a: Annotated[Path, typer.Argument(help="results folder or run folder A (the baseline)")],
    b: Annotated[Path, typer.Argument(help="results folder or run folder B")],
    threshold: Annotated[float, typer.Option(help="relative growth marked as a regression")]
    = 0.10,
    fail_on_regression: Annotated[bool, typer.Option(help="exit 1 when B regresses")] = False,
) -> None:
    """Two result folders side by side: A -> B and the change per sequence, method, seed and
    segment length; regressions marked with '!'."""
    from bench.compare import compare as compare_runs
    from bench.compare import to_text

    df = compare_runs(a, b, threshold)
    console.print(to_text(df), markup=False, highlight=False)
    n = int(df["regression"].sum())
    console.print(f"{len(df)} cells, {n} regressions (> {threshold:.0%} growth or newly "
                  "diverged)", markup=False)
    if fail_on_regression and n:
        raise typer.Exit(1)


@app.command()
def regress(
    update: Annotated[bool, typer.Option(help="accept the current results as the new baseline "
                                              "and print what changed")] = False,
    tolerance: Annotated[float, typer.Option(help="relative growth that fails")] = 0.10,
    jobs: Annotated[int, typer.Option(min=1, help="parallel workers")] = 2,
) -> None:
    """CI regression: run configs/experiments/ci.yaml (unchanged runs are reused) and compare
    with configs/ci/baseline.json; exit 1 when a method's error grows by more than the
    tolerance or it newly diverges."""
    from bench import regress as rg
    from bench.experiment import load_experiment
    from bench.progress import run_jobs
    from bench.run import plan, summarize
    from bench.runplan import jobs_for_experiment

    exp = load_experiment(rg.CI_EXPERIMENT)
    outcomes = run_jobs(plan(jobs_for_experiment(exp, console)), console, jobs)
    if any(o.status not in ("done", "skipped") for o in outcomes):
        console.print(summarize(outcomes), markup=False)
        raise typer.Exit(1)
    only = {o.run_dir for o in outcomes}
    current = rg.snapshot(exp.out_dir, only)
    baseline = {} if update and not rg.BASELINE.exists() else rg.read_baseline(rg.BASELINE)
    findings = rg.check(baseline, current, tolerance)
    for f in findings:
        console.print(str(f), markup=False)
    if update:
        rg.write_baseline(current, rg.BASELINE)
        console.print(f"baseline updated: {rg.BASELINE} ({len(findings)} changes)",
                      markup=False)
        return
    bad = [f for f in findings if f.regression]
    console.print(f"{len(current)} runs, {len(findings)} changes, {len(bad)} regressions",
                  markup=False)
    if bad:
        raise typer.Exit(1)


@app.command()
def figures(
    results_dir: Annotated[Path | None, typer.Argument(
        help="results folder (searched recursively)")] = None,
    out: Annotated[Path | None, typer.Option(help="output folder (default RESULTS_DIR/figures)")]
    = None,
    speed_csv: Annotated[Path | None, typer.Option(
        help="a `bench speed` CSV to plot (default results/speed/speed.csv when present)")]
    = None,
    pair: Annotated[tuple[Path, int] | None, typer.Option(
        help="STORE FRAME: closest-point vs Doppler correspondences of one scan pair")] = None,
) -> None:
    """Paper figures (PDF and PNG): trajectories, relative-error box plots, error along the
    path, per-frame time and correspondences, speed scaling; or one scan pair's
    correspondences (--pair STORE FRAME)."""
    from bench.figures import make_figures
    from bench.figures_pair import plot_pair

    paths = []
    if pair is not None:
        paths += plot_pair(pair[0], pair[1], out or Path("results/figures"))
    if results_dir is not None:
        default_csv = Path("results/speed/speed.csv")
        paths += make_figures(results_dir, out, speed_csv or
                              (default_csv if default_csv.exists() else None))
    if not paths:
        raise DataError("give a RESULTS_DIR with finished runs, or --pair STORE FRAME")
    for p in paths:
        if p.suffix == ".png":
            console.print(f"wrote {p} (+ .pdf)", markup=False)


@app.command()
def view(
    store: Annotated[Path, typer.Argument(help="store (.h5)")],
    run: Annotated[Path | None, typer.Option(help="a run folder: its estimated trajectory")]
    = None,
    out: Annotated[Path | None, typer.Option(help="recording to write (default "
                                             "results/view/STORE.rrd)")] = None,
    pair: Annotated[int | None, typer.Option(help="FRAME: log this pair's correspondences")]
    = None,
    stride: Annotated[int, typer.Option(min=1, help="log every k-th scan")] = 1,
) -> None:
    """Write a rerun recording: scans coloured by Doppler, GT and estimated trajectories, one
    pair's correspondences (open it with `rerun FILE.rrd`)."""
    from bench.view import write_recording

    out = out or Path("results/view") / f"{store.stem}.rrd"
    path = write_recording(store, out, run, pair, stride)
    console.print(f"wrote {path}; open it with: rerun {path}", markup=False)


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
    jobs: Annotated[int, typer.Option(min=1, help="parallel workers")] = 2,
    force: Annotated[bool, typer.Option(help="rerun finished runs")] = False,
    synthetic_only: Annotated[bool, typer.Option(help="ignore real stores")] = False,
    executor: Annotated[str, typer.Option(help="local, process or dask")] = "process",
) -> None:
    """Reproduce the paper's Tables III, IV and V (configs/experiments/table3-5.yaml) on the
    paper's sequences: real stores under DATA_DIR/real when present, else the synthetic suite."""
    from bench.reproduce import reproduce_table

    if reproduce_table(out, data_dir, jobs, force, synthetic_only, console, executor):
        raise typer.Exit(1)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    status.print(f"[yellow]warning:[/] {escape(str(message))}")


def main() -> None:
    """Console entry point: bad input ends with one clear message, not a traceback."""
    import warnings

    warnings.showwarning = _show_warning
    try:
        code = app(standalone_mode=False)
    except DataError as err:  # errors and warnings on stderr: stdout may be data (a CSV)
        status.print(f"[bold red]error:[/] {escape(str(err))}")
        sys.exit(2)
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError) as err:
        status.print(f"[bold red]error:[/] {escape(str(err))}")
        sys.exit(2)
    except typer.Exit as e:
        sys.exit(e.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        status.print("[red]aborted (Ctrl-C)[/]")
        sys.exit(130)
    except Exception as err:
        if callable(getattr(err, "show", None)) and hasattr(err, "exit_code"):
            err.show()  # a usage error (unknown option, missing argument)
            sys.exit(err.exit_code)
        raise
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
