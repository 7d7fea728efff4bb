"""The ``bench`` command line: list, datasets, synth, convert, inspect, calibrate,
calibrate-coverage, run, score, export, table, figures, speed, reproduce.

Exit codes: 0 when everything asked for succeeded, 1 when any run failed (the summary lists
them), 2 for a user error (bad input, option or YAML; one message, no traceback), 130 after
Ctrl-C.
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

# importing the ``bench`` package pinned the library thread counts before numpy & co. loaded
# (bench/__init__.py, bench.threads), the same in every executor mode
from bench.console import make_console
from bench.data.convert import convert_app
from bench.runs.external import DEFAULT_MIN_COVERAGE, DEFAULT_TOLERANCE_S
from loaders.errors import DataError

app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="Benchmark harness for Doppler-based scan matching (4D radar, FMCW LiDAR).")
app.add_typer(convert_app, name="convert", short_help="a dataset to an HDF5 store")
console = make_console()
status = make_console(stderr=True)  # status lines beside data written to stdout


@app.command("list", short_help="methods, loaders, scenes and sensors")
def list_cmd() -> None:
    """List the registered methods, loaders, synthetic scenes and sensors."""
    from bench.report.listing import print_registries

    print_registries(console)


@app.command(short_help="the public datasets and how to convert each")
def datasets(
    markdown: Annotated[bool, typer.Option(
        "--markdown", help="print the datasets page's markdown table instead")] = False,
) -> None:
    """Every supported dataset: sensor, sensor class, Doppler kind, licence, where its owners
    publish it, the layout the loader expects and the exact `bench convert` command."""
    from bench.data.catalogue import print_catalogue

    print_catalogue(console, markdown)


@app.command(short_help="generate synthetic sequences (or check the suite)")
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
    from bench.commands import synth_dispatch

    raise typer.Exit(synth_dispatch(
        console, fidelity, fidelity_out, realism, data_dir, scene=scene,
        sensor=sensor, frames=frames, seed=seed, out=out, noise=noise,
        options=_parse_params(option, "--option"), list_=list_, suite=suite))


@app.command(short_help="what is in a store or frame folder")
def inspect(
    path: Annotated[Path, typer.Argument(help="a store (.h5) or a NumPy frame folder")],
    period: Annotated[float | None, typer.Option(help="scan period [s] for frame folders")] = None,
    plot: Annotated[Path | None, typer.Option(
        help="PNG of the speed from Doppler against GT speed (default: NAME_speed.png next "
             "to the store or folder; '-' for none)")] = None,
) -> None:
    """Print frames, points per frame, period, duration, GT figures, a Doppler-sign check and
    a sensor-to-GT rotation check; plot the speed from Doppler against the GT speed."""
    from bench.data.inspection import default_plot, inspect_path

    if plot is None:
        plot = default_plot(path)
    inspect_path(path, period, console, None if str(plot) == "-" else plot)


@app.command(short_help="sensor-to-GT rotation of a store")
def calibrate(
    store: Annotated[Path, typer.Argument(help="store (.h5) with Doppler and ground truth")],
    start: Annotated[int, typer.Option(min=0, help="first frame to estimate on")] = 0,
    frames: Annotated[int | None, typer.Option(
        min=5, help="frames to estimate on (default: the first half of the store)")] = None,
    write: Annotated[Path | None, typer.Option(
        "--write", help="write a store with the corrected GT and extrinsic to this path; runs "
        "on it score only the frames not used here")] = None,
    apply: Annotated[str, typer.Option(
        help="the estimate --write applies: doppler or hand-eye")] = "doppler",
    min_speed: Annotated[float, typer.Option(help="use frames faster than this [m/s]")] = 2.0,
    bootstrap: Annotated[int, typer.Option(min=10, help="bootstrap resamples")] = 200,
    max_width: Annotated[float, typer.Option(
        help="--write applies only the angles whose 95 % interval is narrower than this "
        "[deg]; it names the others and leaves them alone")] = 2.0,
    force: Annotated[bool, typer.Option(
        help="let --write replace a store bench calibrate wrote (never the input store, "
        "never another file)")] = False,
) -> None:
    """Estimate the rotation between the sensor frame and the ground truth's body frame on a
    range of frames, twice: from the Doppler ego velocity (and road plane), and without Doppler
    by hand-eye alignment of KISS-ICP's trajectory; print both, their difference, and the
    Doppler estimate of pieces of the range (and whether they agree)."""
    from bench.data.calibration.calibrate import calibrate_store

    calibrate_store(store, write, console, min_speed, bootstrap, start, frames, apply,
                    max_width_deg=max_width, force=force)


@app.command("calibrate-coverage", short_help="how often bench calibrate's intervals cover a "
             "known rotation (synthetic)")
def calibrate_coverage(
    seeds: Annotated[int, typer.Option(min=1, help="synthetic sequences (one per seed)")] = 20,
    first_seed: Annotated[int, typer.Option(help="the first seed")] = 100,
    frames: Annotated[int, typer.Option(min=10, help="frames per sequence")] = 125,
    scene: Annotated[str, typer.Option(help="synthetic scene (bench list)")] = "loop",
    sensor: Annotated[str, typer.Option(help="synthetic sensor (bench list)")]
    = "radar-semidense",
    bootstrap: Annotated[int, typer.Option(min=10, help="bootstrap resamples")] = 200,
) -> None:
    """Rotate the GT of synthetic sequences by a known R_gt_sensor (roll 1, pitch 2, yaw -1.5
    deg), run the Doppler calibration on each and print, per angle, how often its stated 95 %
    interval covers the truth, the mean error and the mean stated sd."""
    from bench.studies.calibration_coverage import TRUTH_DEG, calibration_coverage

    def progress(seed, cal) -> None:
        status.print(f"seed {seed}: " + ", ".join(
            f"{ax} {cal.angles_deg[ax] - TRUTH_DEG[ax]:+.3f} (sd {cal.std_deg[ax]:.3f})"
            for ax in cal.angles_deg) + " deg off", highlight=False)

    cov = calibration_coverage(range(first_seed, first_seed + seeds), frames, scene, sensor,
                               bootstrap, progress=progress)
    console.print(f"calibration coverage: {seeds} {scene} / {sensor} sequences of {frames} "
                  f"frames (seeds {first_seed}-{first_seed + seeds - 1}), truth roll "
                  f"{TRUTH_DEG['roll']:+g}, pitch {TRUTH_DEG['pitch']:+g}, yaw "
                  f"{TRUTH_DEG['yaw']:+g} deg, {100 * cov.level:.0f} % intervals:",
                  highlight=False)
    for line in cov.lines():
        console.print(line, highlight=False)


@app.command(short_help="one run, or every run of an experiment")
def run(
    experiment: Annotated[Path | None, typer.Argument(help="experiment YAML")] = None,
    method: Annotated[str | None, typer.Option(help="method name (see bench list)")] = None,
    data: Annotated[Path | None, typer.Option(help="store (.h5) for a single run")] = None,
    out: Annotated[Path | None, typer.Option(help="run folder (single run) or results root")]
    = None,
    seed: Annotated[bool | None, typer.Option(
        "--seed/--no-seed", help="single run: start from a motion prior (default) or from the "
        "identity")] = None,
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
    lengths: Annotated[str | None, typer.Option(
        help="relative-error segment lengths [m], comma separated (default 8,16,...,48; an "
        "experiment's lengths_m)")] = None,
    kitti_lengths: Annotated[str | None, typer.Option(
        help="KITTI drift segment lengths [m] (default 100,200,...,800)")] = None,
    alignment: Annotated[str | None, typer.Option(
        help="APE alignment: none, origin, se3 (default), sim3, first-N, sim3-first-N")] = None,
) -> None:
    """Run one method on one store, or every run of an experiment YAML."""
    from bench.commands import run_command, scoring_options

    raise typer.Exit(run_command(console, experiment, method, data, out, seed,
                                 _parse_params(param), jobs, force, executor, scheduler,
                                 job_timeout, scoring_options(lengths, kitti_lengths,
                                                              alignment)))


@app.command(short_help="score a trajectory made elsewhere as a run")
def score(
    trajectory: Annotated[Path, typer.Argument(
        help="TUM file (t x y z qx qy qz qw [time_ms]), KITTI pose file (with --stamps), Boreas "
        "odometry submission (13 columns: stamp [us], T_k_i 3x4) or a bag (ROS1 .bag, ROS2 "
        "folder, .db3, .mcap) with an Odometry / PoseStamped topic")],
    store: Annotated[Path, typer.Option(help="the store whose ground truth it is scored "
                                             "against")],
    name: Annotated[str, typer.Option(help="the run's name: its folder (one path component) and "
                                           "row label")],
    out: Annotated[Path, typer.Option(
        metavar="RESULTS_DIR", help="results root: the run goes to RESULTS_DIR/SEQUENCE/NAME")]
    = Path("results/external"),
    format: Annotated[str, typer.Option(
        "--format", metavar="auto|tum|kitti|boreas|bag", help="the trajectory's format (auto: "
        "a bag by its suffix or folder, else by the first row's width: 12 kitti, 13 boreas, "
        "else tum)")] = "auto",
    stamps: Annotated[Path | None, typer.Option(
        help="KITTI: the stamps file, one stamp [s] per pose row")] = None,
    topic: Annotated[str | None, typer.Option(
        help="bag: the pose topic (default: its only Odometry / PoseStamped topic)")] = None,
    frame_times: Annotated[Path | None, typer.Option(
        help="the method's own time of each pose row [ms], one a line (shown as reported by "
        "the method; without it the run is not timed)")] = None,
    time_offset: Annotated[float, typer.Option(
        help="est_stamp + offset = the store's scan clock [s]")] = 0.0,
    stamp_unit: Annotated[str | None, typer.Option(
        metavar="s|ms|us|ns", help="the unit of the trajectory's stamps (default: s; boreas: "
        "us)")] = None,
    tolerance: Annotated[float, typer.Option(
        metavar="SECONDS", help="a scan within this (<=) of an estimated pose takes that pose, "
        "one scan a pose (as evo's --t_max_diff) [s]")] = DEFAULT_TOLERANCE_S,
    max_gap: Annotated[float | None, typer.Option(
        metavar="SECONDS", help="interpolate the scans between two poses at most this far "
        "apart [s] (default: no interpolation)")] = None,
    min_coverage: Annotated[float, typer.Option(
        metavar="SHARE", help="refuse an estimate covering less than this share of the scans "
        "with ground truth (0 to 1)")] = DEFAULT_MIN_COVERAGE,
    trust_clock: Annotated[bool, typer.Option(
        "--trust-clock", help="skip the clock checks (index stamps, units, the motion profile)")]
    = False,
    pose_frame: Annotated[str, typer.Option(
        help="the frame the poses are given in: sensor, or body (the store's T_body_sensor "
        "moves them to the sensor)")] = "sensor",
    extrinsic: Annotated[str | None, typer.Option(
        help="T_frame_sensor: the sensor in the frame of the poses, 'x y z qx qy qz qw' or 16 "
        "numbers (overrides --pose-frame)")] = None,
    force: Annotated[bool, typer.Option(help="score again even when unchanged")] = False,
    replace_run: Annotated[bool, typer.Option(
        "--replace-run", help="replace a harness run of the same name in "
        "RESULTS_DIR/SEQUENCE/NAME (refused without it; replaced with a warning)")] = False,
    lengths: Annotated[str | None, typer.Option(
        help="relative-error segment lengths [m], comma separated (default 8,16,...,48)")] = None,
    kitti_lengths: Annotated[str | None, typer.Option(
        help="KITTI drift segment lengths [m] (default 100,200,...,800)")] = None,
    alignment: Annotated[str | None, typer.Option(
        help="APE alignment: none, origin, se3 (default), sim3, first-N, sim3-first-N")] = None,
) -> None:
    """Score a trajectory estimated elsewhere (another odometry, a ROS node) against a store's
    ground truth, as a run of its own: the same metrics as `bench run`, in an ordinary run
    folder that every table, figure, compare, regress and report shows. Refused (exit 2), each
    only on evidence the data give: a clock that does not fit the scans (no pose within
    --tolerance; stamps or positions in another unit, the path length saying which; frame
    indices as stamps; a speed and turn-rate profile whose bootstrap interval leaves out no
    shift: the message lists every --time-offset that fits alike), a convention that does not
    fit (w x y z quaternions, inverse poses), a rotation block that is no rotation, a coverage
    below --min-coverage. Stamps that are the scans' own are on the store's clock; where the
    data cannot tell, it is scored as given and the clock check says so."""
    from bench.commands import score_command, scoring_options
    from bench.runs.external.score import ExternalSpec

    spec = ExternalSpec(trajectory, name, format, stamps, topic, frame_times, time_offset,
                        tolerance, max_gap, pose_frame, extrinsic, stamp_unit, min_coverage,
                        trust_clock, replace_run)
    raise typer.Exit(score_command(console, store, spec, out, force,
                                   scoring_options(lengths, kitti_lengths, alignment)))


@app.command(short_help="a store as a ROS bag (ros1, ros2, mcap)")
def export(
    store: Annotated[Path, typer.Argument(help="store (.h5)")],
    format: Annotated[str, typer.Option(
        "--format", metavar="ros1|ros2|mcap", help="ros1 (.bag), ros2 (rosbag2 folder, sqlite3) "
        "or mcap (rosbag2 folder, mcap)")] = "mcap",
    out: Annotated[Path | None, typer.Option(
        metavar="BAG", help="bag to write (default: STORE.bag, STORE_ros2/ or STORE_mcap/)")]
    = None,
    force: Annotated[bool, typer.Option(help="replace an existing bag")] = False,
) -> None:
    """Write a store as a ROS bag: /points (PointCloud2 in the frame radar or lidar: x y z
    doppler and the stored fields; doppler positive when the point recedes), /ground_truth
    (nav_msgs/Odometry of the body the GT poses are of: base_link, camera for View-of-Delft),
    /tf_static (body -> radar|lidar) and /doppler_bench/description; the store's stamps; one
    scan at a time."""
    from bench.data.export import export_command

    export_command(console, store, format, out, force)


def _parse_params(items: list[str] | None, option: str = "--param") -> dict:
    """``key=value`` strings -> dict (values parsed as YAML: 3, 0.5, true, [1, 2])."""
    import yaml

    params = {}
    for item in items or []:
        if "=" not in item or not item.split("=", 1)[0].strip():
            raise DataError(f"{option} expects key=value, got {item!r}")
        key, value = item.split("=", 1)
        try:
            params[key.strip()] = yaml.safe_load(value)
        except yaml.YAMLError as err:
            raise DataError(f"{option} {item!r}: the value is not a YAML value "
                            f"({str(err).splitlines()[0]})") from None
        if not _finite(params[key.strip()]):
            raise DataError(f"{option} {item!r}: expected finite numbers (not nan or inf)")
    return params


def _finite(value) -> bool:
    """No NaN or infinity anywhere in a parsed parameter value."""
    if isinstance(value, float):
        return value == value and abs(value) != float("inf")
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, list):
        return all(_finite(v) for v in value)
    return True


@app.command(short_help="the paper's Table III from results")
def table(
    results_dirs: Annotated[list[Path], typer.Argument(
        help="results folder(s), searched recursively; several: rows labelled by folder")],
    format: Annotated[str, typer.Option("--format", "-f", help="md, tex or csv")] = "md",
    metric: Annotated[str, typer.Option(
        help="relative (Table III: error per segment length), kitti (drift in % and deg/100 m "
        "over 100-800 m), ape (methods x sequences, Tables IV/V) or velocity (ego-velocity "
        "error)")] = "relative",
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
    sweep: Annotated[bool, typer.Option(
        help="the experiment's parameter sweeps: one row per point, the best per length in "
        "bold, the criterion's choice beside the default")] = False,
    marks: Annotated[str, typer.Option(
        help="intervals (default: bold = every figure at or below the smallest upper end of "
        "the printed 95 % intervals in its column, so a reader can check each mark) or value "
        "(the paper's plain by-value style)")] = "intervals",
    ci: Annotated[bool, typer.Option(
        "--ci/--no-ci", help="show each figure's 95 % confidence interval [low, high] in the "
        "cells (the CSV always has them)")] = False,
    stability: Annotated[bool, typer.Option(
        help="score each half of every sequence on its own and say how many marks hold on "
        "both halves; a cell whose mark differs on a half is flagged with a dagger (relative "
        "error only)")] = False,
) -> None:
    """Print a table (by default the paper-shaped Table III) and write table.md / .tex / .csv
    (table_<metric>.* for another metric)."""
    from bench.report.commands import table_command

    if sweep:
        from bench.report.tables.sweep import sweep_markdown

        if len(results_dirs) != 1:
            raise DataError("--sweep reads one results folder (the sweep experiment's out)")
        sys.stdout.write(sweep_markdown(results_dirs[0]))
        raise typer.Exit(0)

    raise typer.Exit(table_command(console, status, list(results_dirs), format, out, lengths,
                                   pivot, methods, variants, metric, marks, ci, stability))


@app.command(short_help="two result folders side by side")
def compare(
    a: Annotated[Path, typer.Argument(help="results folder or run folder A (the baseline)")],
    b: Annotated[Path, typer.Argument(help="results folder or run folder B")],
    threshold: Annotated[float, typer.Option(help="relative growth marked as a regression")]
    = 0.10,
    fail_on_regression: Annotated[bool, typer.Option(help="exit 1 when B regresses")] = False,
) -> None:
    """Two result folders side by side: A -> B and the change per sequence, method, seed and
    segment length; regressions marked with '!'."""
    from bench.report.commands import compare_command

    raise typer.Exit(compare_command(console, a, b, threshold, fail_on_regression))


@app.command(short_help="CI regression against the baseline")
def regress(
    update: Annotated[bool, typer.Option(help="accept the current results as the new baseline "
                                              "and print what changed")] = False,
    tolerance: Annotated[float, typer.Option(help="relative growth that fails")] = 0.10,
    jobs: Annotated[int, typer.Option(min=1, help="parallel workers")] = 2,
    data_dir: Annotated[Path | None, typer.Option(
        help="where the CI suite is generated (default: the experiment's, data/)")] = None,
    out: Annotated[Path | None, typer.Option(
        help="where its runs go (default: the experiment's, results/ci)")] = None,
    accept_improvements: Annotated[bool, typer.Option(
        help="let errors that dropped by more than the tolerance pass (printed, baseline "
             "unchanged)")] = False,
) -> None:
    """CI regression: run configs/experiments/ci.yaml (unchanged runs are reused) and compare
    with configs/ci/baseline.json; exit 1 when a method's error grows by more than the
    tolerance or it newly diverges, when an error drops by more than the tolerance ("!
    improved: review", unless --accept-improvements) and when a run is not in the baseline."""
    from bench.studies.regress import regress_command

    raise typer.Exit(regress_command(console, update, tolerance, jobs, data_dir, out,
                                     accept_improvements))


@app.command(short_help="paper figures from results")
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
    from bench.report.commands import figures_command

    raise typer.Exit(figures_command(console, results_dir, out, speed_csv, pair))


@app.command(short_help="one HTML page of a results folder")
def report(
    results_dir: Annotated[Path, typer.Argument(help="results folder")],
    out: Annotated[Path | None, typer.Option(help="page to write (default "
                                             "RESULTS_DIR/report.html)")] = None,
    figures: Annotated[bool, typer.Option(
        "--figures/--no-figures", help="draw the figures into RESULTS_DIR/figures first "
        "(as `bench figures`, PNG for the page: a PDF only where one exists), unless they are "
        "newer than every run record")] = True,
) -> None:
    """One self-contained HTML page of a results folder: its tables (every metric's, made for
    the page with intervals and significance marks, then every *.md table the folder holds),
    its figures embedded (drawn first when missing or older than a run record), the failed
    runs (broken run records and unreadable files named) and missing data, and the
    provenance (code version, store hashes, machine, how times were taken). Readable
    offline; it loads nothing from the network. Exit 0; 1 when a run record is broken or a
    run folder holds unreadable files (the page is written and lists them); 2 when the folder
    holds no run."""
    from bench.report.commands import report_command

    raise typer.Exit(report_command(console, results_dir, out, figures))


@app.command(short_help="a rerun recording of a store and a run")
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
    from bench.report.view import write_recording

    out = out or Path("results/view") / f"{store.stem}.rrd"
    path = write_recording(store, out, run, pair, stride)
    console.print(f"wrote {path}; open it with: rerun {path}", markup=False)


@app.command(short_help="time and memory of every method")
def speed(
    sizes: Annotated[str, typer.Option(help="point counts, comma separated")]
    = "1000,4000,16000,64000,128000",
    methods: Annotated[str | None, typer.Option(help="methods (default: all registered)")]
    = None,
    repeats: Annotated[int, typer.Option(min=1, help="timed frames per size (distinct "
                                                    "consecutive pairs)")] = 7,
    out: Annotated[Path, typer.Option(help="output folder")] = Path("results/speed"),
    memory: Annotated[bool, typer.Option(help="also measure each method's peak memory on a "
                                              "64k-point LiDAR run")] = True,
    threads: Annotated[int, typer.Option(min=1, help="also time the methods that take a "
                                                    "thread count on N threads (beside 1)")] = 1,
    reference: Annotated[bool, typer.Option(
        "--reference", help="also time Open3D's and small_gicp's own pipelines doing the same "
        "work on the same pairs (speed_reference.csv)")] = False,
    vs_run: Annotated[bool, typer.Option(
        "--vs-run", help="also run each method with `bench run` on the first scenario's scans "
        "and print both median times (the two protocols agree)")] = False,
    harness: Annotated[bool, typer.Option(
        "--harness", help="only the harness's own per-frame cost (reading a scan, the driver, "
        "evaluating, writing) beside doppler's time (harness.csv)")] = False,
    store: Annotated[Path | None, typer.Option(
        help="with --harness: measure on this store, and time a whole `bench run` on it")]
    = None,
    scale: Annotated[bool, typer.Option(
        "--scale", help="only the harness at dataset scale: scoring, table and report per pose "
        "and their peak memory at --poses, and an experiment's cost per frame on the process "
        "and dask executors, beside doppler's time on the real sample (scale.csv)")] = False,
    poses: Annotated[str, typer.Option(help="with --scale: drive lengths in poses, comma "
                                            "separated")] = "2500,10000,40000",
    scale_frames: Annotated[int, typer.Option(
        min=2, help="with --scale: frames of each of the experiment's 3 sequences")] = 2000,
) -> None:
    """Time every method on the same synthetic scan pairs (total per-frame work and the
    registration call); print ratios to `doppler`, each method's peak memory and the harness's
    own cost per frame."""
    from bench.studies.speed import check_outputs, run_speed

    check_outputs(out, inputs=[store])  # a folder of its own CSVs and plots, before timing
    if scale:
        from bench.studies.scale import MIN_POSES, run_scale

        try:
            counts = tuple(int(x) for x in poses.split(","))
        except ValueError:
            counts = ()
        if not counts or min(counts) < MIN_POSES:
            raise DataError(f"--poses {poses!r}: expected pose counts of at least {MIN_POSES} "
                            "(a drive with 48 m segments), comma separated, e.g. 2500,40000")
        run_scale(out, console, counts, scale_frames)
        return
    if harness:
        from bench.studies.harness import run_harness

        run_harness(out, console, store)
        return
    try:
        counts = [int(s) for s in sizes.split(",")]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1:
        raise DataError(f"--sizes {sizes!r}: expected point counts of at least 1, comma "
                        "separated, e.g. 1000,64000")
    names = [m.strip() for m in methods.split(",")] if methods else None
    if names is not None:
        from methods.registry import get_method

        for name in names:
            get_method(name)  # an unknown name: one message naming it and the registered ones
    run_speed(counts, names, repeats, out, console, memory, threads=threads,
              reference=reference, vs_run=vs_run)


@app.command(short_help="the paper's Tables III-V")
def reproduce(
    out: Annotated[Path, typer.Option(help="results folder")] = Path("results/paper-synthetic"),
    data_dir: Annotated[Path, typer.Option(help="data folder (synthetic cache, real stores)")]
    = Path("data"),
    jobs: Annotated[int, typer.Option(min=1, help="parallel workers")] = 2,
    force: Annotated[bool, typer.Option(help="rerun finished runs")] = False,
    synthetic_only: Annotated[bool, typer.Option(help="ignore real stores")] = False,
    executor: Annotated[str, typer.Option(help="local, process or dask")] = "process",
    scheduler: Annotated[str | None, typer.Option(
        help="dask scheduler address (default: a LocalCluster)")] = None,
    job_timeout: Annotated[float | None, typer.Option(
        help="end a job that runs longer than this [s]")] = None,
    lengths: Annotated[str | None, typer.Option(
        help="Table III's segment lengths [m], comma separated (default 8,16,...,48)")] = None,
    kitti_lengths: Annotated[str | None, typer.Option(
        help="KITTI drift segment lengths [m] (default 100,200,...,800)")] = None,
    alignment: Annotated[str | None, typer.Option(
        help="APE alignment of Tables IV/V (default se3)")] = None,
    marks: Annotated[str, typer.Option(
        help="intervals (default: bold = every figure at or below the smallest upper end of "
        "the printed 95 % intervals in its column) or value (the paper's by-value style)")
    ] = "intervals",
    ci: Annotated[bool, typer.Option(
        "--ci/--no-ci", help="show each figure's 95 % confidence interval [low, high] in the "
        "tables' cells, as `bench table --ci` (without: the caption names the CSV columns "
        "that hold them)")] = False,
) -> None:
    """Reproduce the paper's Tables III, IV and V (configs/experiments/table3-5.yaml) on the
    paper's sequences: real stores under DATA_DIR/real when present, else the synthetic suite."""
    from bench.commands import scoring_options
    from bench.report.tables.model import MARK_RULES, rule_name
    from bench.studies.reproduce import reproduce_table

    try:
        marks = rule_name(marks)
    except ValueError:
        raise DataError(f"--marks {marks!r}: choose from {', '.join(MARK_RULES)}") from None
    if reproduce_table(out, data_dir, jobs, force, synthetic_only, console, executor,
                       scheduler, job_timeout,
                       scoring_options(lengths, kitti_lengths, alignment), marks, ci):
        raise typer.Exit(1)


#: metavars where the option's name in capitals does not say enough
METAVARS = {"param": "KEY=VALUE", "option": "KEY=VALUE", "experiment": "EXPERIMENT.yaml",
            "data": "STORE.h5", "store": "STORE.h5", "write": "STORE.h5", "pair": "STORE FRAME",
            "path": "STORE_OR_FOLDER", "results_dirs": "RESULTS_DIR", "results_dir": "RESULTS_DIR",
            "jobs": "N",
            "frames": "N", "start": "FRAME", "repeats": "N", "threads": "N", "stride": "K",
            "bootstrap": "N", "seed": "N", "period": "SECONDS", "job_timeout": "SECONDS",
            "lengths": "8,48,...", "methods": "METHOD,...", "sizes": "N,...",
            "format": "md|tex|csv", "executor": "local|process|dask", "apply": "doppler|hand-eye",
            "min_speed": "M_PER_S", "threshold": "FRACTION", "tolerance": "FRACTION",
            "run": "RUN_DIR", "a": "A", "b": "B", "trajectory": "TRAJECTORY",
            "name": "NAME", "topic": "TOPIC", "frame_times": "TIMES.txt", "stamps": "STAMPS.txt",
            "time_offset": "SECONDS", "max_gap": "SECONDS",
            "pose_frame": "sensor|body", "extrinsic": "'X Y Z QX QY QZ QW'"}


def tidy_help(command) -> None:
    """Usage lines that read like a Unix tool's: a metavar in capitals for every value (not
    Python types such as <list[str]>), recursively through the command groups."""
    for sub in getattr(command, "commands", {}).values():
        tidy_help(sub)
    for param in command.params:
        if getattr(param, "is_flag", False) or param.name == "help":
            continue
        if param.metavar is None:
            param.metavar = METAVARS.get(param.name, param.name.upper())
        if param.param_type_name == "argument":
            param.display_type_rich = lambda ctx: None  # the metavar says it


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        console.print(f"doppler-bench {version('doppler-bench')}", markup=False)
        raise typer.Exit(0)


@app.callback()
def _options(ctx: typer.Context, version: Annotated[bool, typer.Option(
        "--version", callback=_version, is_eager=True, help="print the version and exit")]
        = False) -> None:
    """Benchmark harness for Doppler-based scan matching (4D radar, FMCW LiDAR)."""
    # before the command's own options are read: each is checked as it is (bench/options.py),
    # and the environment variables the harness reads, once
    from bench import options

    options.attach(ctx.command)
    options.check_environment()


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    status.print(f"[yellow]warning:[/] {escape(str(message))}")


#: the options that name a file or folder to write, and those that name a folder to make
PATH_OPTIONS = ("--out", "--write", "--fidelity-out", "--plot", "--data-dir")
NAME_OPTIONS = ("--name",)


def check_names(args: list[str]) -> None:
    """Every --out / --name of the command line through one name check before anything runs
    (``bench.guard.check_out`` / ``check_name``: empty, too long, separators in a name): one
    message and exit 2, never an OSError "File name too long" after the work."""
    from bench import guard

    for i, arg in enumerate(args):
        if arg == "--":
            break
        option, eq, value = arg.partition("=")
        if option not in PATH_OPTIONS + NAME_OPTIONS:
            continue
        if not eq:
            if i + 1 >= len(args):
                continue  # the parser says the value is missing
            value = args[i + 1]
        if option in NAME_OPTIONS:
            guard.check_name(value, option)
        else:
            guard.check_out(value, option)


@functools.cache
def _command():
    """The click command tree of ``app``, its help tidied (built once a process: main() may be
    called many times in one, as the property tests do)."""
    command = typer.main.get_command(app)
    tidy_help(command)
    return command


def main() -> None:
    """Console entry point: bad input ends with one clear message, not a traceback."""
    import warnings

    warnings.showwarning = _show_warning
    try:
        check_names(sys.argv[1:])
        code = _command().main(prog_name="bench", standalone_mode=False)
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
            if type(err).__name__ == "NoArgsIsHelpError" or not hasattr(err, "ctx"):
                err.show()  # the help of a group called without a command
            else:  # a usage error (unknown option, missing argument): one line, as every error
                where = getattr(err.ctx, "command_path", "") if err.ctx is not None else ""
                status.print(f"[bold red]error:[/] {escape(err.format_message())}"
                             + (f" (see {escape(where)} --help)" if where else ""),
                             soft_wrap=True)
            sys.exit(err.exit_code)
        raise
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
