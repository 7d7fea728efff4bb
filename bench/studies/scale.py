"""``bench speed --scale``: what the harness costs at dataset scale, beside a method's own time.

Two parts, each case in a fresh child process (``bench`` itself, as a user runs it), measured
by the child's CPU time (its own and that of every process it waited for: the load of other
programs on the machine does not inflate it; wall time beside it) and its peak resident memory
(``VmHWM`` of the child, read after the command):

- **Scoring, table and report at N poses** (default 2,500 / 10,000 / 40,000): a synthetic 10 Hz
  drive of N poses at 5 m/s (``bench.studies.coverage``: a smooth planar path, odometry-like
  estimates whose errors drift) as a store of N tiny scans with its ground truth, and two
  estimates of it as TUM files. ``bench score`` scores each (every metric with its intervals),
  then ``bench table`` and ``bench report`` read the two runs. Per pose: a command's CPU time
  over the poses it covers (2N for the table and report, N per scoring, the two scorings
  summed over 2N), start-up included; the marginal cost per pose between the smallest and the
  largest N leaves the start-up out. ``x scorings``: the command's time over the two
  scorings' time (the issue's limit: at most 1).
- **An experiment's whole cost per frame on each executor** (``process``, ``dask``): ``bench
  run`` of an experiment of ``SEQUENCES`` long synthetic radar sequences (the radar scans of
  ``bench speed`` thinned to ``POINTS`` points and tiled to ``frames`` frames along a straight
  ground truth) with the cheapest method (``doppler``), 2 workers. Per frame: the whole
  command's CPU time (planning, workers, reading, the method, scoring, writing) less the
  method's own ``time_ms``, over every frame; and its wall time per frame.

Beside both: ``doppler``'s median per-frame time on the real radar sample
(``samples/ntu4dradlm-loop1.h5``, 250 Oculii Eagle frames), measured in the same command the
way ``bench speed`` times a method. Writes ``scale.csv`` and ``scale_executors.csv``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.markup import escape
from rich.table import Table

from bench import guard
from bench.studies.speed import write_csv

POSES = (2500, 10_000, 40_000)
#: the shortest drive (50 m at 5 m/s and 10 Hz: segments up to 48 m)
MIN_POSES = 100
#: the real radar sample doppler is timed on
SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "ntu4dradlm-loop1.h5"
#: the executor experiment: sequences, frames each, points a scan, its method
SEQUENCES, FRAMES, POINTS, METHOD = 3, 2000, 1000, "doppler"
EXECUTORS = ("process", "dask")
WORKERS = 2


def child(argv: list[str], timeout_s: float = 3600, entry: str = "bench.cli") -> dict:
    """``bench ARGV`` in a child process: wall and CPU time [s] (the child's own and its
    waited-for children's: worker processes) and peak RSS [MB]; a failing command is an
    error naming it. ``entry``: the module whose ``main()`` is the command."""
    code = ("import resource, sys\n"
            f"import {entry}\n"
            f"sys.argv = ['bench', *{argv!r}]\n"
            "status = 0\n"
            f"try:\n    {entry}.main()\n"
            "except SystemExit as e:\n    status = e.code or 0\n"
            "own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF,\n"
            "                                              resource.RUSAGE_CHILDREN))\n"
            "cpu = own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime\n"
            "hwm = next(ln.split()[1] for ln in open('/proc/self/status')\n"
            "           if ln.startswith('VmHWM'))\n"
            "print('SCALE_PROBE', status, cpu, hwm)\n")
    # the child imports this checkout's code (not another install of the package)
    root = str(Path(__file__).resolve().parents[2])
    env = {**os.environ,
           "PYTHONPATH": os.pathsep.join(filter(None, (root, os.environ.get("PYTHONPATH"))))}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=timeout_s)
    wall = time.perf_counter() - t0
    probe = [ln.split() for ln in done.stdout.splitlines() if ln.startswith("SCALE_PROBE")]
    if done.returncode or not probe or probe[-1][1] != "0":
        raise RuntimeError(f"`bench {' '.join(argv)}` failed (exit "
                           f"{probe[-1][1] if probe else done.returncode}):\n"
                           f"{done.stdout[-1500:]}{done.stderr[-1500:]}")
    return {"wall_s": wall, "cpu_s": float(probe[-1][2]), "peak_mb": int(probe[-1][3]) / 1024}


def drive(poses: int, folder: Path) -> tuple[Path, list[Path]]:
    """A store of ``poses`` 10 Hz scans (3 points each: the scans are not read by scoring)
    with the ground truth of a smooth 5 m/s drive, and two estimates of it with different
    noise as TUM files."""
    from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
    from loaders.posefile import tum_text
    from loaders.scan import MemorySequence, Scan, SensorInfo
    from loaders.trajectory import Trajectory

    gt = ground_truth(poses)
    stamps = np.arange(poses) * 0.1
    points = np.array([[5.0, 0.0, 0.0], [0.0, 5.0, 0.0], [5.0, 5.0, 1.0]])
    seq = MemorySequence(f"drive-{poses}", SensorInfo("radar", 0.1),
                         [Scan(float(t), points) for t in stamps], Trajectory(stamps, gt))
    store = guard.write_store(seq, folder / f"drive-{poses}.h5", guard.is_store, "a scratch store")
    estimates = []
    for k, noise in enumerate((NoiseModel(), NoiseModel(0.08, 0.02))):
        path = folder / f"drive-{poses}-estimate-{k}.txt"
        guard.write_text(path, tum_text(Trajectory(stamps, noisy_estimate(gt, noise, 100 + k))),
                         guard.derived, "a scratch estimate")
        estimates.append(path)
    return store, estimates


def scale_row(poses: int, folder: Path) -> dict:
    """Scoring two estimates of a ``poses``-pose drive, then the table and the report of the
    two runs, each in a child process (see the module docstring)."""
    store, estimates = drive(poses, folder)
    results = folder / f"results-{poses}"
    scores = [child(["score", str(est), "--store", str(store), "--name", f"estimate-{k}",
                     "--out", str(results)]) for k, est in enumerate(estimates)]
    table = child(["table", str(results)])
    report = child(["report", str(results)])
    score_cpu = sum(s["cpu_s"] for s in scores)
    row = {"poses": poses,
           "score_ms": 1e3 * score_cpu / (2 * poses),
           "score_wall_ms": 1e3 * sum(s["wall_s"] for s in scores) / (2 * poses),
           "score_mb": max(s["peak_mb"] for s in scores)}
    for name, r in (("table", table), ("report", report)):
        row |= {f"{name}_ms": 1e3 * r["cpu_s"] / (2 * poses),
                f"{name}_wall_ms": 1e3 * r["wall_s"] / (2 * poses),
                f"{name}_mb": r["peak_mb"], f"{name}_x_scorings": r["cpu_s"] / score_cpu}
    return row


def marginal(rows: list[dict], key: str) -> float:
    """The cost per pose [ms] of ``key`` between the smallest and the largest drive (the
    start-up left out)."""
    a, b = rows[0], rows[-1]
    return (b[key] * b["poses"] - a[key] * a["poses"]) / (b["poses"] - a["poses"])


def doppler_on_sample(sample: Path) -> float:
    """``doppler``'s median per-frame time [ms] on ``sample``, as ``bench speed`` times it."""
    from bench.studies.speed import time_method
    from loaders.store import StoreSequence

    if not Path(sample).exists():
        from loaders.errors import DataError

        raise DataError(f"{sample}: no such store; the scale benchmark times doppler on the "
                        "real radar sample (samples/ntu4dradlm-loop1.h5)")
    seq = StoreSequence(sample)
    try:
        return float(time_method(METHOD, seq)["median_ms"])
    finally:
        seq.close()


def long_stores(folder: Path, sequences: int, frames: int) -> list[Path]:
    """``sequences`` stores of ``frames`` synthetic radar scans of at most ``POINTS`` points,
    tiled along a straight ground truth (``bench.studies.harness.tiled_store``)."""
    from bench.studies.harness import synthetic_scenarios, tiled_store
    from loaders.scan import MemorySequence

    radar = next(synthetic_scenarios())[1]
    rng = np.random.default_rng(0)
    scans = [s if len(s) <= POINTS else s.select(np.sort(rng.choice(len(s), POINTS, False)))
             for s in radar]
    # each its own name and scan order: stores of different content, sequences of their own
    return [tiled_store(MemorySequence(f"long-{k}", radar.sensor, scans[k:] + scans[:k]),
                        frames, folder / f"long-{k}.h5") for k in range(sequences)]


def executor_rows(folder: Path, sequences: int, frames: int,
                  executors: tuple[str, ...] = EXECUTORS) -> list[dict]:
    """``bench run`` of one experiment over the long stores on each executor (see the module
    docstring)."""
    import pandas as pd
    import yaml

    stores = long_stores(folder, sequences, frames)
    rows = []
    for executor in executors:
        out = folder / f"experiment-{executor}"
        spec = {"name": f"scale-{executor}", "methods": [{"name": METHOD}], "jobs": WORKERS,
                "out": str(out), "sequences": [{"path": str(s)} for s in stores]}
        config = folder / f"experiment-{executor}.yaml"
        guard.write_text(config, yaml.safe_dump(spec), guard.derived, "a scratch experiment")
        r = child(["run", str(config), "--executor", executor, "--jobs", str(WORKERS)])
        times = np.concatenate([pd.read_csv(p)["time_ms"].to_numpy(float)
                                for p in sorted(out.rglob("frames.csv"))])
        n = len(times)
        if n != sequences * frames:
            raise RuntimeError(f"{executor}: {n} frames recorded, expected "
                               f"{sequences * frames}")
        method_ms = float(np.nanmean(times))
        rows.append({"executor": executor, "sequences": sequences, "frames": n,
                     "timed_frames": int(np.isfinite(times).sum()), "method_ms": method_ms,
                     "method_median_ms": float(np.nanmedian(times)),
                     "harness_ms": (1e3 * r["cpu_s"] - float(np.nansum(times))) / n,
                     "cpu_ms": 1e3 * r["cpu_s"] / n, "wall_ms": 1e3 * r["wall_s"] / n,
                     "main_peak_mb": r["peak_mb"]})
    return rows


def print_scale(rows: list[dict], doppler_ms: float, console) -> None:
    table = Table(title=escape("The harness at dataset scale: CPU time per pose [ms] (wall in "
                               "brackets), peak memory [MB], and the table / report against "
                               "the scorings that made them"))
    for col in ("poses", "score", "score peak", "table", "table peak", "table x scorings",
                "report", "report peak", "report x scorings", "doppler / frame"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(f"{r['poses']:,}",
                      *[v for k in ("score", "table", "report") for v in
                        (f"{r[k + '_ms']:.3f} ({r[k + '_wall_ms']:.3f})",
                         f"{r[k + '_mb']:.0f}")
                        + ((f"{r[k + '_x_scorings']:.2f}x",) if k != "score" else ())],
                      f"{doppler_ms:.3f}")
    if len(rows) > 1:
        m = {k: marginal(rows, f"{k}_ms") for k in ("score", "table", "report")}
        table.caption = escape(
            f"marginal per pose {rows[0]['poses']:,} -> {rows[-1]['poses']:,}: scoring "
            f"{m['score']:.3f} ms ({m['score'] / doppler_ms:.2f}x doppler's per-frame time), "
            f"table {m['table']:.3f} ms, report {m['report']:.3f} ms. Per pose: the command's "
            "CPU time (start-up included) over the poses it covers (two runs: 2N; scoring: the "
            "two scorings over 2N); doppler: median per-frame time on the real radar sample "
            f"({SAMPLE.name}), measured in this command")
    console.print(table)


def print_executors(rows: list[dict], doppler_ms: float, console) -> None:
    table = Table(title=escape(f"An experiment's whole cost per frame: `bench run` of "
                               f"{rows[0]['sequences']} long synthetic radar sequences with "
                               f"{METHOD}, {WORKERS} workers [ms per frame]"))
    for col in ("executor", "frames", "method (mean)", "harness CPU", "harness / method",
                "all CPU", "wall", "main peak [MB]", "doppler on the sample"):
        table.add_column(col, justify="left" if col == "executor" else "right")
    for r in rows:
        table.add_row(r["executor"], f"{r['frames']:,}", f"{r['method_ms']:.3f}",
                      f"{r['harness_ms']:.3f}", f"{r['harness_ms'] / r['method_ms']:.2f}x",
                      f"{r['cpu_ms']:.3f}", f"{r['wall_ms']:.3f}", f"{r['main_peak_mb']:.0f}",
                      f"{doppler_ms:.3f}")
    table.caption = escape(
        "harness CPU: the whole command's CPU time (planning, start-up, workers, reading, "
        "scoring, writing) less the method's own time_ms, over every frame; all CPU: the "
        f"whole command's CPU time per frame; wall: its wall time per frame on {WORKERS} "
        f"workers; scans thinned to {POINTS} points, tiled along a straight path")
    console.print(table)


def run_scale(out: Path, console, poses: tuple[int, ...] = POSES, frames: int = FRAMES,
              sequences: int = SEQUENCES, sample: Path = SAMPLE,
              executors: tuple[str, ...] = EXECUTORS) -> tuple[list[dict], list[dict]]:
    """``bench speed --scale``: print both tables and write ``scale.csv`` and
    ``scale_executors.csv`` into ``out``."""
    console.print(f"timing {METHOD} on {sample}", markup=False)
    doppler_ms = doppler_on_sample(sample)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sorted(poses):
            console.print(f"scoring, table and report at {n:,} poses", markup=False)
            rows.append(scale_row(n, Path(tmp)))
        console.print(f"`bench run` of {sequences} x {frames} frames on "
                      f"{', '.join(executors)}", markup=False)
        ex_rows = executor_rows(Path(tmp), sequences, frames, executors)
    for r in rows + ex_rows:
        r["doppler_sample_ms"] = doppler_ms
    print_scale(rows, doppler_ms, console)
    print_executors(ex_rows, doppler_ms, console)
    guard.make_folder(out)
    write_csv(rows, out / "scale.csv")
    write_csv(ex_rows, out / "scale_executors.csv")
    console.print(f"wrote {out}/scale.csv and scale_executors.csv", markup=False)
    return rows, ex_rows
