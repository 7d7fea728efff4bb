"""``bench speed``: every method timed on the same synthetic scans at the same input size.

Two scenarios, each generated once so that every method sees exactly the same points:
- ``lidar``: a short dense FMCW-LiDAR sequence (campus scene); for each size N every scan is
  subsampled to N points with a fixed random choice (the scaling curve, 1k-128k points);
- ``radar``: a semi-dense 4D-radar sequence (loop scene) at its own density (about 4k
  points, the paper's Loop sequences).

N is always the number of points handed to the method (its input); each method then prepares
the scans as in a run (its own downsampling, normals, layout: untimed, stated in the table's
``prep`` column) and only its registration call is timed. A pairwise method is timed on one
consecutive pair: one warm-up call, then ``repeats`` calls (at least 51 for sub-5 ms calls, at
most 3 for calls over a second). A stateful method (its own map, e.g. KISS-ICP) runs over the
short sequence and its per-frame registration times after the first two frames are used.
Methods are configured for the scenario's sensor kind (radar or LiDAR parameter sets). With
``memory``, the peak resident memory of a whole ``bench run`` on a 120k-point LiDAR sequence
is measured in a child process.
"""

from __future__ import annotations

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
from methods.base import Registration
from methods.registry import METHODS, make_method

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


def _stats(times_ms: list[float]) -> dict:
    t = np.asarray(times_ms)
    return {"median_ms": float(np.median(t)), "mean_ms": float(t.mean()),
            "p5_ms": float(np.percentile(t, 5)), "p95_ms": float(np.percentile(t, 95)),
            "repeats": len(t)}


def _prep_note(method) -> str:
    params = getattr(method, "params", None)
    factor = getattr(params, "downsample", None)
    notes = [f"1 in {factor} points" if factor and factor > 1 else "all points"]
    voxel = getattr(params, "voxel_size_m", None)
    if voxel and "vgicp" in getattr(method, "name", ""):
        notes.append(f"voxel {voxel:g} m")
    return ", ".join(notes)


def time_pair(method: Registration, source: Scan, target: Scan, repeats: int) -> dict:
    src, tgt = method.preprocess(source), method.preprocess(target)
    init = np.eye(4)
    t0 = time.perf_counter()
    result = method.register(src, tgt, init)  # warm-up (compilation, caches)
    warm_s = time.perf_counter() - t0
    n = max(repeats, 51) if warm_s < 0.005 else repeats if warm_s < 1.0 else min(repeats, 3)
    times = []
    for _ in range(n):
        t0 = time.perf_counter_ns()
        method.register(src, tgt, init)
        times.append((time.perf_counter_ns() - t0) / 1e6)
    return {**_stats(times), "correspondences": result.correspondences,
            "iterations": result.iterations}


def time_sequence(method, sequence: MemorySequence) -> dict:
    result = method.run(sequence, seed=True)
    frames = result.frames[2:] or result.frames[1:]
    return {**_stats([f.time_ms for f in frames]),
            "correspondences": int(np.median([f.correspondences for f in frames])),
            "iterations": int(np.median([f.iterations for f in frames]))}


def time_method(name: str, sequence: MemorySequence, repeats: int) -> dict:
    """Timing figures of method ``name`` on ``sequence`` (pair 0 -> 1, or the sequence)."""
    method = make_method(name, {}, sequence.sensor)
    if isinstance(method, Registration):
        r = time_pair(method, sequence[0], sequence[1], repeats)
    else:
        r = time_sequence(method, sequence)
    return {**r, "prep": _prep_note(method)}


def peak_memory_of_run(points: int = 120_000, frames: int = 20) -> tuple[float, str]:
    """Peak RSS [MB] of ``bench run --method doppler`` on a LiDAR store of ``points`` rays."""
    from loaders.store import write_store
    from loaders.synthetic import SyntheticSequence

    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "lidar.h5"
        seq = SyntheticSequence("tunnel", "lidar-dense", frames=frames, seed=1, points=points)
        write_store(seq, store)
        median_points = int(np.median([len(s) for s in seq]))
        code = ("import resource, sys; from bench.cli import main; sys.argv=['bench','run',"
                f"'--method','doppler','--data',{str(store)!r},'--out',{tmp + '/run'!r}]\n"
                "try:\n    main()\nexcept SystemExit:\n    pass\n"
                "print('PEAK_KB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=900)
        peak_kb = next((int(line.split()[1]) for line in out.stdout.splitlines()
                        if line.startswith("PEAK_KB")), -1)
        if peak_kb < 0:
            raise RuntimeError(f"memory probe failed:\n{out.stderr[-2000:]}")
    return peak_kb / 1024, f"{frames} frames, median {median_points} points/frame"


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
              console: Console, memory: bool = True, radar: bool = True) -> list[dict]:
    names = methods or list(METHODS)
    if "doppler" not in names:
        names = ["doppler", *names]
    console.print(f"generating synthetic radar and LiDAR sequences (up to {max(sizes)} points)")
    rows = []
    for scenario, n, seq in _scenarios(sizes, radar):
        base = None
        for name in names:
            r = time_method(name, seq, repeats)
            base = r["median_ms"] if name == "doppler" else base
            rows.append({"scenario": scenario, "points": n, "method": name, **r,
                         "ratio_to_doppler": r["median_ms"] / base})
            console.print(f"  {scenario:<5} N={n:>7} {name:<12} {r['median_ms']:10.3f} ms "
                          f"({r['repeats']} repeats, {r['iterations']} it, {r['prep']})",
                          highlight=False, markup=False)
    _print_table(rows, names, console)
    out.mkdir(parents=True, exist_ok=True)
    header = list(rows[0])
    lines = [",".join(header)] + [",".join(_csv_value(r[k]) for k in header) for r in rows]
    atomic_write_text(out / "speed.csv", "\n".join(lines) + "\n")
    _plot(rows, names, out / "speed.png")
    console.print(f"wrote {out}/speed.csv and speed.png")
    if memory:
        peak_mb, what = peak_memory_of_run()
        console.print(f"peak memory of `bench run --method doppler` on a LiDAR store "
                      f"({what}): {peak_mb:.0f} MB", markup=False)
        atomic_write_text(out / "memory.csv", f"what,peak_rss_mb\n\"{what}\",{peak_mb:.1f}\n")
    return rows


def _csv_value(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    text = str(v)
    return f'"{text}"' if "," in text else text


def _print_table(rows: list[dict], names: list[str], console: Console) -> None:
    table = Table(title=escape("Registration time per frame, median [ms] (x doppler); input "
                               "points per scan, before each method's own downsampling"))
    table.add_column("scan")
    table.add_column("input points", justify="right")
    for name in names:
        table.add_column(name, justify="right")
    keys = list(dict.fromkeys((r["scenario"], r["points"]) for r in rows))
    for scenario, n in keys:
        cells = {r["method"]: f"{r['median_ms']:.2f} ({r['ratio_to_doppler']:.1f}x)"
                 for r in rows if (r["scenario"], r["points"]) == (scenario, n)}
        table.add_row(scenario, f"{n}", *[cells.get(name, "-") for name in names])
    preps = {r["method"]: r["prep"] for r in rows}
    table.caption = escape("prep (untimed): "
                           + "; ".join(f"{k}: {v}" for k, v in preps.items()))
    console.print(table)


def _plot(rows: list[dict], names: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench.report.names import long_name

    fig, ax = plt.subplots(figsize=(6, 4))
    for name in names:
        pts = sorted((r["points"], r["median_ms"], r["p5_ms"], r["p95_ms"]) for r in rows
                     if r["method"] == name and r["scenario"] == "lidar")
        if not pts:
            continue
        n, med, lo, hi = (np.array(v) for v in zip(*pts, strict=True))
        (line,) = ax.loglog(n, med, marker="o", label=long_name(name))
        ax.fill_between(n, lo, hi, color=line.get_color(), alpha=0.2, linewidth=0)
    ax.set_xlabel("input points per scan")
    ax.set_ylabel("registration time per frame [ms]")
    ax.set_title("median with p5-p95 band (synthetic FMCW LiDAR)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)
