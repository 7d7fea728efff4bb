"""``bench speed``: every method timed on the same synthetic scan pairs at several sizes.

One consecutive pair of dense synthetic LiDAR scans (campus scene, exact motion, realistic
noise) is generated once; for each size N both scans are subsampled to N points with a fixed
random choice, so every method sees the same pairs. Each method then prepares the scans as in
a run (its own downsampling, untimed) and its registration call alone is timed: one warm-up,
then the median of ``repeats`` calls. With ``memory``, the peak resident memory of a whole
``bench run`` on a 120k-point LiDAR sequence is measured in a child process.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from loaders.fileio import atomic_path, atomic_write_text
from loaders.scan import Scan
from methods.registry import METHODS, make_method

PAIR_SCENE, PAIR_SENSOR = "campus", "lidar-dense"


def make_pair(max_points: int, seed: int = 0) -> tuple[Scan, Scan]:
    """Two consecutive dense scans with at least ``max_points`` points each (if possible)."""
    from loaders.synthetic import SyntheticSequence

    rays = int(max_points * 1.6)
    for _ in range(4):
        seq = SyntheticSequence(PAIR_SCENE, PAIR_SENSOR, frames=2, seed=seed, points=rays)
        pair = seq[0], seq[1]
        if min(len(s) for s in pair) >= max_points:
            return pair
        rays = int(rays * 1.5)
    return pair


def subsample(scan: Scan, n: int, seed: int) -> Scan:
    if len(scan) <= n:
        return scan
    idx = np.sort(np.random.default_rng(seed).choice(len(scan), n, replace=False))
    return scan.select(idx)


def time_method(name: str, source: Scan, target: Scan, repeats: int) -> dict:
    method = make_method(name)
    src, tgt = method.preprocess(source), method.preprocess(target)
    init = np.eye(4)
    t0 = time.perf_counter()
    result = method.register(src, tgt, init)  # warm-up
    warm_s = time.perf_counter() - t0
    # fast calls get many repeats (a stable median); calls over a second get three
    n_repeats = max(repeats, 51) if warm_s < 0.005 else repeats if warm_s < 1.0 else min(repeats, 3)
    times = []
    for _ in range(n_repeats):
        t0 = time.perf_counter_ns()
        method.register(src, tgt, init)
        times.append((time.perf_counter_ns() - t0) / 1e6)
    return {"median_ms": float(np.median(times)), "mean_ms": float(np.mean(times)),
            "p95_ms": float(np.percentile(times, 95)), "repeats": n_repeats,
            "correspondences": result.correspondences, "iterations": result.iterations}


def peak_memory_of_run(points: int = 120_000, frames: int = 20) -> tuple[float, str]:
    """Peak RSS [MB] of ``bench run --method doppler`` on a LiDAR store of ``points`` rays."""
    from loaders.store import write_store
    from loaders.synthetic import SyntheticSequence

    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "lidar.h5"
        seq = SyntheticSequence("tunnel", PAIR_SENSOR, frames=frames, seed=1, points=points)
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


def run_speed(sizes: list[int], methods: list[str] | None, repeats: int, out: Path,
              console: Console, memory: bool = True) -> list[dict]:
    names = methods or list(METHODS)
    if "doppler" not in names:
        names = ["doppler", *names]
    console.print(f"generating a synthetic {PAIR_SENSOR} scan pair ({max(sizes)} points)...")
    full_src, full_tgt = make_pair(max(sizes))
    rows = []
    for n in sizes:
        src, tgt = subsample(full_src, n, 1), subsample(full_tgt, n, 2)
        base = None
        for name in names:
            r = time_method(name, src, tgt, repeats)
            base = r["median_ms"] if name == "doppler" else base
            rows.append({"points": len(src), "method": name, **r,
                         "ratio_to_doppler": r["median_ms"] / base})
            console.print(f"  N={len(src):>7} {name:<10} {r['median_ms']:10.3f} ms "
                          f"({r['repeats']} repeats)", highlight=False)
    table = Table(title="Registration time per scan pair, median [ms] (x doppler)")
    table.add_column("points", justify="right")
    for name in names:
        table.add_column(name, justify="right")
    for n in sorted({r["points"] for r in rows}):
        cells = [f"{r['median_ms']:.3f} ({r['ratio_to_doppler']:.1f}x)"
                 for name in names for r in rows if r["points"] == n and r["method"] == name]
        table.add_row(f"{n}", *cells)
    console.print(table)
    out.mkdir(parents=True, exist_ok=True)
    buf = [",".join(rows[0])] + [",".join(f"{v:.6g}" if isinstance(v, float) else str(v)
                                          for v in r.values()) for r in rows]
    atomic_write_text(out / "speed.csv", "\n".join(buf) + "\n")
    _plot(rows, names, out / "speed.png")
    console.print(f"wrote {out}/speed.csv and speed.png")
    if memory:
        peak_mb, what = peak_memory_of_run()
        console.print(f"peak memory of `bench run --method doppler` on a LiDAR store "
                      f"({what}): {peak_mb:.0f} MB")
        atomic_write_text(out / "memory.csv", f"what,peak_rss_mb\n\"{what}\",{peak_mb:.1f}\n")
    return rows


def _plot(rows: list[dict], names: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for name in names:
        pts = [(r["points"], r["median_ms"]) for r in rows if r["method"] == name]
        ax.loglog(*zip(*pts, strict=True), marker="o", label=name)
    ax.set_xlabel("points per scan")
    ax.set_ylabel("registration time, median [ms]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)

