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
the registration call alone. A pairwise method is timed on one consecutive pair: the same
warm-up as in a run, then ``repeats`` timed frames (at least 51 for sub-5 ms frames, at most 3
for frames over a second). A stateful method (its own map: KISS-ICP, doppler-ego) runs over the
short sequence after the warm-up and its frames after the second are used. Methods are
configured for the scenario's sensor kind (radar or LiDAR parameter sets); every method runs on
1 thread and, with ``threads`` > 1, again on ``threads`` where it takes a thread count (both
figures side by side, the ``threads_setting`` column of speed.csv); the clock is the harness's
(CPU time on one thread, wall time on several). With ``memory``, the peak resident memory of a
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
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from loaders.fileio import atomic_path, atomic_write_text
from loaders.scan import MemorySequence, Scan, SensorInfo
from methods.base import Registration, run_timed
from methods.registry import METHODS, make_method
from methods.timing import stopwatch

LIDAR_SCENE, RADAR_SCENE = "campus", "loop"
SEQUENCE_FRAMES = 8  # frames of the short sequence a stateful method runs over


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


def _stats(total_ms: list[float], register_ms: list[float]) -> dict:
    t, r = np.asarray(total_ms), np.asarray(register_ms)
    return {"median_ms": float(np.median(t)), "mean_ms": float(t.mean()),
            "p5_ms": float(np.percentile(t, 5)), "p95_ms": float(np.percentile(t, 95)),
            "register_median_ms": float(np.nanmedian(r)) if np.isfinite(r).any() else np.nan,
            "repeats": len(t)}


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


def time_pair(method: Registration, source: Scan, target: Scan, repeats: int) -> dict:
    """Frame times of registering ``target`` to ``source``: preparing the target (the new scan)
    plus the registration call, and the call alone; by the method's clock."""
    src = method.preprocess(source)
    init = np.eye(4)
    t0 = time.perf_counter()
    result = method.register(src, method.preprocess(target), init)  # the warm-up
    warm_s = time.perf_counter() - t0
    n = max(repeats, 51) if warm_s < 0.005 else repeats if warm_s < 1.0 else min(repeats, 3)
    total, register = [], []
    for _ in range(n):
        with stopwatch() as frame:
            tgt = method.preprocess(target)
            with stopwatch() as reg:
                method.register(src, tgt, init)
        total.append(frame.ms(method.clock))
        register.append(reg.ms(method.clock))
    return {**_stats(total, register), "correspondences": result.correspondences,
            "iterations": result.iterations}


def time_sequence(method, sequence: MemorySequence) -> dict:
    result = run_timed(method, sequence, seed=True)
    frames = result.frames[2:] or result.frames[1:]
    return {**_stats([f.time_ms for f in frames], [f.register_ms for f in frames]),
            "correspondences": int(np.median([f.correspondences for f in frames])),
            "iterations": int(np.median([f.iterations for f in frames]))}


def method_params(name: str, threads: int) -> dict:
    """The parameters that set ``threads`` threads for ``name`` (none when it has no thread
    count: it computes on one)."""
    fields = getattr(METHODS[name], "Params", None)
    has = fields is not None and "num_threads" in getattr(fields, "model_fields", {})
    return {"num_threads": threads} if has else {}


def time_method(name: str, sequence: MemorySequence, repeats: int, threads: int = 1) -> dict:
    """Timing figures of method ``name`` on ``sequence`` (pair 0 -> 1, or the sequence)."""
    method = make_method(name, method_params(name, threads), sequence.sensor)
    if isinstance(method, Registration):
        r = time_pair(method, sequence[0], sequence[1], repeats)
    else:
        r = time_sequence(method, sequence)
    return {**r, "prep": _prep_note(method), "threads": method.threads, "clock": method.clock}


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
    from loaders.store import write_store

    seq = make_sequence("tunnel", "lidar-dense", frames, points, seed=1)
    scans = [subsample(s, points, k) for k, s in enumerate(seq)]
    write_store(MemorySequence(seq.name, seq.sensor, scans, seq.ground_truth), path)
    return path, f"{frames} frames of {int(np.median([len(s) for s in scans]))} points"


def _scenarios(sizes: list[int], radar: bool):
    """(scenario, input points, sequence) in the order they are timed."""
    if radar:
        seq = make_sequence(RADAR_SCENE, "radar-semidense", SEQUENCE_FRAMES)
        yield "radar", int(np.median([len(s) for s in seq])), seq
    full = make_sequence(LIDAR_SCENE, "lidar-dense", SEQUENCE_FRAMES, max(sizes))
    for n in sizes:
        scans = [subsample(s, n, k) for k, s in enumerate(full)]
        seq = MemorySequence(full.name, SensorInfo("lidar", full.sensor.period_s),
                             scans, full.ground_truth)
        yield "lidar", n, seq


def run_speed(sizes: list[int], methods: list[str] | None, repeats: int, out: Path,
              console: Console, memory: bool = True, radar: bool = True,
              threads: int = 1, reference: bool = False, harness: bool = True) -> list[dict]:
    """Time the methods; with ``reference``, also the libraries' own pipelines beside them
    on each pair (``bench.studies.speed_reference``, written to speed_reference.csv); with
    ``harness``, the harness's own per-frame cost beside doppler's (``bench.studies.harness``,
    harness.csv)."""
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
    for scenario, n, seq in _scenarios(sizes, radar):
        for setting in settings:
            base = None
            for name in names:
                if setting > 1 and not method_params(name, setting):
                    continue
                r = time_method(name, seq, repeats, setting)
                base = r["median_ms"] if name == "doppler" else base
                rows.append({"scenario": scenario, "points": n, "method": name,
                             "threads_setting": setting, **r,
                             "ratio_to_doppler": r["median_ms"] / base})
                console.print(f"  {scenario:<5} N={n:>7} {name:<12} {r['median_ms']:10.3f} ms "
                              f"(registration {r['register_median_ms']:.3f} ms; {r['repeats']} "
                              f"repeats, {r['iterations']} it, {r['prep']}, {r['threads']} "
                              f"thr., {r['clock']} time)", highlight=False, markup=False)
        if harness and harness_study.wanted(scenario, n, sizes):  # reading, scoring, writing
            harness_rows.append(harness_study.scenario_row(
                scenario, seq, harness_study.TILED_FRAMES[scenario]))
        if reference:  # the same pair, right after ours, at the requested thread count
            reference_rows += speed_reference.reference_rows(
                scenario, n, seq, [r for r in rows if r["points"] == n
                                   and r["scenario"] == scenario
                                   and r["threads_setting"] == threads],
                repeats, threads, libraries)
    _print_table(rows, names, console)
    if harness_rows:
        harness_study.report(harness_rows, out, console)
    out.mkdir(parents=True, exist_ok=True)
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
    if memory:
        _memory(names, out, console, threads)
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    """``rows`` (the same keys each) as CSV, written atomically."""
    header = list(rows[0])
    lines = [",".join(header)] + [",".join(_csv_value(r[k]) for k in header) for r in rows]
    atomic_write_text(path, "\n".join(lines) + "\n")


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
    atomic_write_text(out / "memory.csv", "\n".join(lines) + "\n")


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
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)
