"""``bench speed``: every method timed on the same synthetic scans at the same input size, with
the harness's timing protocol (``methods.base``).

Two scenarios, each generated once so that every method sees exactly the same points:
- ``lidar``: a short dense FMCW-LiDAR sequence (campus scene); for each size N every scan is
  subsampled to N points with a fixed random choice (the scaling curve, 1k-128k points);
- ``radar``: a semi-dense 4D-radar sequence (loop scene) at its own density (about 4k
  points, the paper's Loop sequences).

N is always the number of points handed to the method (its input). Two figures per method:
``time_ms``, the total per-frame work (a pairwise method: preparing the new scan, i.e. its own
downsampling, normals, kd-tree or voxel map, plus the registration call), and ``register_ms``,
the registration call alone (what is inside it for each method: README, Metrics, Timing).
Every method is timed exactly as a run times it (``bench.runs.timed.timed_run``: the library
threads limited, the common warm-up ``Odometry.warm_up`` on the sequence's last pair, then one
seeded run over the sequence's distinct consecutive frames, no pair repeated), and a figure is
the median over all its registered frames, so it equals the ``time_ms`` of a ``bench run`` on
the same scans within noise (``compare_with_run`` / ``--vs-run`` shows both). The sequence has
``repeats`` + 1 frames (``repeats`` timed frames). Methods are configured for the scenario's
sensor kind (radar or LiDAR parameter sets); every method runs on 1 thread and, with
``threads`` > 1, again on ``threads`` where it takes a thread count (both figures side by side,
the ``threads_setting`` column of speed.csv; kiss-icp's N-thread run is made in a fresh process,
``methods.kiss``); the clock is the harness's (CPU time on one thread, wall time on several).
With ``memory``, the peak resident memory of a
whole ``bench run`` of each method on a 64k-point LiDAR store is measured in a child process,
beside the memory its imports alone take (``RUN_IMPORTS``, about 156 MB, the same for every
method); a run that fails is an error (the probe once passed ``-p=num_threads=1``, which every
run rejected, and reported the imports' footprint as every method's peak). With ``reference``,
Open3D's and small_gicp's own pipelines doing the same work are timed on each pair right after
the methods (``bench.studies.speed_reference``)."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from bench import guard
from bench.studies.speed_timing import method_params, time_frames
from loaders.scan import MemorySequence, Scan, SensorInfo
from methods.registry import METHODS, make_method

LIDAR_SCENE, RADAR_SCENE = "campus", "loop"


def make_sequence(scene: str, sensor: str, frames: int, min_points: int | None = None,
                  seed: int = 0) -> MemorySequence:
    """A short synthetic sequence held in memory; with ``min_points``, dense enough that each
    scan has at least that many points (when the generator can)."""
    from loaders.synthetic import SyntheticSequence

    options = {}
    rays = int(min_points * 1.6) if min_points else None
    for _ in range(4):
        if rays:
            options["points"] = rays
        seq = SyntheticSequence(scene, sensor, frames=frames, seed=seed, **options)
        scans = list(seq)
        if not min_points or min(len(s) for s in scans) >= min_points:
            break
        rays = int(rays * 1.5)
    return MemorySequence(seq.name, seq.sensor, scans, seq.ground_truth)


def subsample(scan: Scan, n: int, seed: int) -> Scan:
    if len(scan) <= n:
        return scan
    idx = np.sort(np.random.default_rng(seed).choice(len(scan), n, replace=False))
    return scan.select(idx)


def _prep_note(method) -> str:
    """How the method thins its input (its own stride, voxel grid, VGICP voxels)."""
    params = getattr(method, "params", None)
    factor = getattr(params, "downsample", None)
    grid = getattr(params, "voxel_downsample_m", None) or getattr(params, "voxel_m", None)
    notes = [f"1 in {factor} points" if factor and factor > 1 else
             f"voxel grid {grid:g} m" if grid else "all points"]
    voxel = getattr(params, "voxel_size_m", None)
    if voxel and "vgicp" in getattr(method, "name", ""):
        notes.append(f"VGICP voxels {voxel:g} m")
    return ", ".join(notes)


def time_method(name: str, sequence, threads: int = 1) -> dict:
    """Timing figures of method ``name`` over ``sequence`` (every frame), as a run times them
    (``time_frames``)."""
    method = make_method(name, method_params(name, threads), sequence.sensor)
    r = time_frames(method, sequence)
    return {**r, "prep": _prep_note(method), "threads": method.threads}


def compare_with_run(name: str, sequence, folder: Path) -> tuple[float, float]:
    """(median ``time_ms`` of ``bench speed``, of a ``bench run`` job) of method ``name`` on
    the same scans (``sequence`` written as a store into ``folder``): the two protocols agree
    when these are equal within noise."""
    from bench.runs.plan import run_single

    # without ground truth: the run is timed, not scored (the scans are a few metres of path)
    scans = MemorySequence(sequence.name, sequence.sensor, list(sequence))
    store = guard.write_store(scans, folder / f"{name}.h5", guard.is_store, "a scratch store")
    ours = time_method(name, sequence)["median_ms"]
    run = run_single(name, store, True, {}, folder / name, force=True).result
    return ours, run.time_ms.median


#: what every `bench run` imports before it reads a scan (the CLI, every method's module and
#: library, the job runner, the store reader): the baseline of the memory figures
RUN_IMPORTS = ("bench.cli", "methods.registry", "bench.commands", "bench.runs.job",
               "loaders.store")


def peak_memory_of_run(method: str, store: Path, threads: int = 1) -> tuple[float, float]:
    """(peak RSS, RSS after the imports alone) [MB] of ``bench run --method METHOD`` on
    ``store``, in a child process; a failed run is an error, not a figure."""
    params = [arg for v in method_params(method, threads).values()
              for arg in ("-p", f"num_threads={v}")]
    with tempfile.TemporaryDirectory() as tmp:
        # VmHWM: the peak RSS of this process image (ru_maxrss would carry the parent's peak
        # over the fork and exec that start the child); read once after the imports (the
        # baseline) and once after the run
        code = (f"import sys, {', '.join(RUN_IMPORTS)}\n"
                "def hwm():\n"
                "    return next(ln.split()[1] for ln in open('/proc/self/status')\n"
                "                if ln.startswith('VmHWM'))\n"
                "print('BASE_KB', hwm())\n"
                "sys.argv=['bench','run',"
                f"'--method',{method!r},'--data',{str(store)!r},'--out',{tmp + '/run'!r},"
                f"'--executor','local',*{params!r}]\n"
                "try:\n    bench.cli.main()\nexcept SystemExit as e:\n"
                "    print('EXIT', e.code or 0)\n"
                "print('PEAK_KB', hwm())")
        # the child imports this checkout's code (not another install of the package)
        root = str(Path(__file__).resolve().parents[2])
        path = os.pathsep.join(filter(None, (root, os.environ.get("PYTHONPATH"))))
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=1800, env={**os.environ, "PYTHONPATH": path})
    found = dict(line.split()[:2] for line in out.stdout.splitlines()
                 if line.startswith(("BASE_KB", "PEAK_KB", "EXIT")))
    if out.returncode or found.get("EXIT", "0") != "0" or "PEAK_KB" not in found:
        raise RuntimeError(f"memory probe of {method}: `bench run` failed (exit "
                           f"{found.get('EXIT', out.returncode)}):\n{out.stderr[-2000:]}")
    return int(found["PEAK_KB"]) / 1024, int(found["BASE_KB"]) / 1024


def memory_store(path: Path, points: int = 64_000, frames: int = 20) -> tuple[Path, str]:
    """A LiDAR store of ``frames`` scans of ``points`` points each (tunnel scene)."""
    seq = make_sequence("tunnel", "lidar-dense", frames, points, seed=1)
    scans = [subsample(s, points, k) for k, s in enumerate(seq)]
    guard.write_store(MemorySequence(seq.name, seq.sensor, scans, seq.ground_truth), path,
                      guard.is_store, "a scratch store")
    return path, f"{frames} frames of {int(np.median([len(s) for s in scans]))} points"


def _scenarios(sizes: list[int], radar: bool, frames: int, folder: Path):
    """(scenario, input points, sequence of ``frames`` scans) in the order they are timed. Each
    sequence is read from a store written into ``folder``, one scan at a time as a run reads
    it (float32 per-point values; the read between frames is untimed but, as in a run, it
    leaves the caches to the next frame)."""
    from loaders.store import StoreSequence

    def stored(seq: MemorySequence, name: str) -> StoreSequence:
        return StoreSequence(guard.write_store(seq, folder / f"{name}.h5", guard.is_store,
                                               "a scratch store"))

    if radar:
        seq = stored(make_sequence(RADAR_SCENE, "radar-semidense", frames), "radar")
        yield "radar", int(np.median([len(s) for s in seq])), seq
        seq.close()
    full = make_sequence(LIDAR_SCENE, "lidar-dense", frames, max(sizes))
    for n in sizes:
        scans = [subsample(s, n, k) for k, s in enumerate(full)]
        seq = stored(MemorySequence(full.name, SensorInfo("lidar", full.sensor.period_s),
                                    scans, full.ground_truth), f"lidar-{n}")
        yield "lidar", n, seq
        seq.close()


def run_speed(sizes: list[int], methods: list[str] | None, repeats: int, out: Path,
              console: Console, memory: bool = True, radar: bool = True,
              threads: int = 1, reference: bool = False, vs_run: bool = False,
              harness: bool = True) -> list[dict]:
    """Time the methods; with ``reference``, also the libraries' own pipelines beside them
    on each pair (``bench.studies.speed_reference``, written to speed_reference.csv); with
    ``vs_run``, each method's figure on the first scenario beside a ``bench run`` of the same
    scans (``compare_with_run``); with ``harness``, the harness's own per-frame cost beside
    doppler's (``bench.studies.harness``, harness.csv)."""
    from bench.studies import harness as harness_study

    harness_rows = []
    # doppler first: the base of every ratio
    names = ["doppler", *[name for name in methods or list(METHODS) if name != "doppler"]]
    if reference:
        from bench.studies import speed_reference

        libraries = speed_reference.available_libraries(console)
    console.print(f"generating synthetic radar and LiDAR sequences (up to {max(sizes)} points)")
    # with --threads N, every method is timed on 1 thread and on N (a method without a thread
    # count only on 1: its figure stands for both)
    settings = [1, threads] if threads > 1 else [1]
    rows, reference_rows = [], []
    # ``repeats`` timed frames: distinct consecutive pairs, no pair timed twice
    folder = tempfile.TemporaryDirectory()
    for scenario, n, seq in _scenarios(sizes, radar, max(repeats, 2) + 1, Path(folder.name)):
        for setting in settings:
            base = None
            for name in names:
                if setting > 1 and not method_params(name, setting):
                    continue
                r = time_method(name, seq, threads=setting)
                base = r["median_ms"] if name == "doppler" else base
                rows.append({"scenario": scenario, "points": n, "method": name,
                             "threads_setting": setting, **r,
                             "ratio_to_doppler": r["median_ms"] / base})
                console.print(f"  {scenario:<5} N={n:>7} {name:<12} {r['median_ms']:10.3f} ms "
                              f"(registration {r['register_median_ms']:.3f} ms; {r['repeats']} "
                              f"frames, {r['iterations']} it, {r['prep']}, {r['threads']} "
                              f"thr., {r['clock']} time)", highlight=False, markup=False)
        if harness and harness_study.wanted(scenario, n, sizes):  # reading, scoring, writing
            harness_rows.append(harness_study.scenario_row(
                scenario, seq, harness_study.TILED_FRAMES[scenario]))
        if reference:  # the same pair, right after ours, at the requested thread count
            reference_rows += speed_reference.reference_rows(
                scenario, n, seq, [r for r in rows if r["points"] == n
                                   and r["scenario"] == scenario
                                   and r["threads_setting"] == threads],
                threads, libraries)
    _print_table(rows, names, console)
    if harness_rows:
        harness_study.report(harness_rows, out, console)
    guard.make_folder(out)
    write_csv(rows, out / "speed.csv")
    _plot(rows, names, out / "speed.png")
    console.print(f"wrote {out}/speed.csv and speed.png")
    if reference_rows:
        speed_reference.print_reference_table(reference_rows, libraries, console)
        write_csv(reference_rows, out / "speed_reference.csv")
        console.print(f"wrote {out}/speed_reference.csv")
    elif reference:
        console.print("--reference: none of these methods has a library counterpart ("
                      f"{', '.join(speed_reference.COUNTERPARTS)})", markup=False)
    if vs_run:
        scenarios = _scenarios(sizes, radar, max(repeats, 2) + 1, Path(folder.name))
        scenario, n, seq = next(scenarios)
        _print_vs_run(names, seq, f"{scenario}, {n} points, {len(seq) - 1} frames", console)
        scenarios.close()
    folder.cleanup()
    if memory:
        _memory(names, out, console, threads)
    return rows


def _print_vs_run(names: list[str], sequence: MemorySequence, what: str,
                  console: Console) -> None:
    table = Table(title=escape(f"bench speed against bench run on the same scans ({what}): "
                               "median time_ms [ms]"))
    for col in ("method", "bench speed", "bench run", "speed / run"):
        table.add_column(col, justify="left" if col == "method" else "right")
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            ours, run = compare_with_run(name, sequence, Path(tmp))
            table.add_row(name, f"{ours:.3f}", f"{run:.3f}", f"{ours / run:.2f}")
    console.print(table)


#: every file ``bench speed`` may write into its --out folder
OUTPUTS = ("speed.csv", "speed.png", "speed_reference.csv", "memory.csv", "harness.csv",
           "scale.csv", "scale_executors.csv")


def check_outputs(out: Path, inputs=()) -> None:
    """Before any timing: ``out`` a folder (not a run's) whose files of ``OUTPUTS``, where they
    exist, the harness wrote (``bench.guard``)."""
    guard.output_folder(out, inputs=inputs)
    for name in OUTPUTS:
        guard.regenerated_file(Path(out) / name, guard.derived, "a speed table or plot")


def write_csv(rows: list[dict], path: Path) -> None:
    """``rows`` (the same keys each) as CSV, written atomically."""
    header = list(rows[0])
    lines = [",".join(header)] + [",".join(_csv_value(r[k]) for k in header) for r in rows]
    guard.write_text(path, "\n".join(lines) + "\n", guard.derived, "a table of times")


def _memory(names: list[str], out: Path, console: Console, threads: int) -> None:
    """Peak RSS of a `bench run` of every method on the same 64k-point LiDAR store, and how
    much of it the run added to the imports every run makes."""
    with tempfile.TemporaryDirectory() as tmp:
        store, what = memory_store(Path(tmp) / "lidar64k.h5")
        lines = ["method,peak_rss_mb,imports_rss_mb,run_mb,store"]
        table = Table(title=escape(f"Peak memory of `bench run` [MB], LiDAR store ({what})"))
        table.add_column("method")
        table.add_column("peak RSS", justify="right")
        table.add_column("above the imports", justify="right")
        bases = []
        for name in names:
            peak_mb, base_mb = peak_memory_of_run(name, store, threads)
            bases.append(base_mb)
            lines.append(f"{name},{peak_mb:.1f},{base_mb:.1f},{peak_mb - base_mb:.1f},"
                         f"\"{what}\"")
            table.add_row(name, f"{peak_mb:.0f}", f"{peak_mb - base_mb:.0f}")
    table.caption = escape(f"the imports of every run ({', '.join(RUN_IMPORTS)}: Python, "
                           "NumPy, SciPy, numba, small_gicp, h5py, ...) take "
                           f"{min(bases):.0f}-{max(bases):.0f} MB before a scan is read")
    console.print(table)
    guard.write_text(out / "memory.csv", "\n".join(lines) + "\n", guard.derived,
                     "a table of memory")


def _csv_value(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    text = str(v)
    return f'"{text}"' if "," in text else text


def _print_table(rows: list[dict], names: list[str], console: Console) -> None:
    table = Table(title=escape("Time per frame, median [ms]: total (all per-frame work) / "
                               "registration call, and total x doppler; input points per "
                               "scan, before each method's own downsampling"))
    table.add_column("scan")
    table.add_column("input points", justify="right")
    table.add_column("threads", justify="right")
    for name in names:
        table.add_column(name, justify="right")
    keys = list(dict.fromkeys((r["scenario"], r["points"], r["threads_setting"]) for r in rows))
    for scenario, n, setting in keys:
        cells = {r["method"]: f"{r['median_ms']:.2f} / {r['register_median_ms']:.2f} "
                              f"({r['ratio_to_doppler']:.1f}x)"
                 for r in rows if (r["scenario"], r["points"], r["threads_setting"])
                 == (scenario, n, setting)}
        # "-": a method without a thread count (its 1-thread figure above stands)
        table.add_row(scenario, f"{n}", f"{setting}", *[cells.get(name, "-") for name in names])
    preps = {r["method"]: r["prep"] for r in rows}
    table.caption = escape("clock: CPU time on 1 thread, wall time on more (threads: the "
                           "count asked for; a method without a thread count runs on 1); "
                           "preparation "
                           "(timed in the total): "
                           + "; ".join(f"{k}: {v}" for k, v in preps.items()))
    console.print(table)


def _plot(rows: list[dict], names: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench.report.names import display_name

    fig, ax = plt.subplots(figsize=(6, 4))
    for name in names:
        pts = sorted((r["points"], r["median_ms"], r["p5_ms"], r["p95_ms"]) for r in rows
                     if r["method"] == name and r["scenario"] == "lidar"
                     and r["threads_setting"] == 1)
        if not pts:
            continue
        n, med, lo, hi = (np.array(v) for v in zip(*pts, strict=True))
        (line,) = ax.loglog(n, med, marker="o", label=display_name(name))
        ax.fill_between(n, lo, hi, color=line.get_color(), alpha=0.2, linewidth=0)
    ax.set_xlabel("input points per scan")
    ax.set_ylabel("time per frame, all per-frame work [ms]")
    ax.set_title("median with p5-p95 band, 1 thread (synthetic FMCW LiDAR)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    guard.savefig(fig, path, "png", guard.derived, "a speed plot", dpi=120)
    plt.close(fig)
