"""The harness's own cost per frame, beside the method's (``bench speed``, ``bench speed
--harness``).

A run (``bench.runs.job.run_job``) spends, besides its method's ``time_ms``: a fixed start-up
(imports, planning, hashing the store once, opening it, building the method, its warm-up) and,
per frame, reading the scan from the store (``read``), the driver around the method
(``driver``: the loop, its records, progress), scoring the run (``evaluate``) and writing its
folder (``write``). ``phases`` runs one job phase by phase, as ``run_job`` does, and measures
each: by CPU time (``time.process_time``: the same on a loaded machine; the method's
``time_ms`` is CPU time too) and by the wall clock. ``whole_run`` times ``bench run`` itself in
a child process on the store and on its first ``SHORT_FRAMES`` frames: the difference per
added frame is the marginal cost of a frame, whatever the start-up.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from bench import guard
from loaders.scan import FrameRange, MemorySequence, Scan, Sequence
from loaders.se3 import make_T
from loaders.store import StoreSequence
from loaders.trajectory import Trajectory
from methods.base import OdometryResult

#: frames of the short store ``whole_run`` subtracts (its start-up and warm-up)
SHORT_FRAMES = 50
#: the issue's allowance: the harness may cost this many times the method per frame
OVERHEAD_LIMIT = 1.5
#: and a scan read this many times the method's time
READ_LIMIT = 2.0


class _Clock:
    cpu_s = wall_s = 0.0


@contextmanager
def _clock():
    c = _Clock()
    cpu, wall = time.process_time(), time.perf_counter()
    yield c
    c.cpu_s, c.wall_s = time.process_time() - cpu, time.perf_counter() - wall


def read_cost(store: Path, fields, frames: int | None = None) -> dict:
    """Reading the scans of ``store`` in order, as a run does (the arrays ``fields``), per
    scan [ms]: CPU time and wall time; ``points``: the median scan's size."""
    seq = StoreSequence(store, fields=fields)
    n = len(seq) if frames is None else min(frames, len(seq))
    try:
        with _clock() as c:
            for i in range(n):
                seq.scan(i)
    finally:
        seq.close()
    return {"read_ms": 1e3 * c.cpu_s / n, "read_wall_ms": 1e3 * c.wall_s / n,
            "points": int(np.median(seq.points_per_frame()[:n]))}


def phases(store: Path, method: str = "doppler", params: dict | None = None) -> dict:
    """One run of ``method`` on ``store``, as ``run_job`` runs it, phase by phase: the fixed
    cost (``startup_s``: prepare, warm-up, loading the compiled scoring kernels (the first of
    two evaluations' excess over the second) and the part of writing the folder that does not grow
    with the frames) [s], and per frame [ms]: the method (mean ``time_ms``), the scan read, the
    driver, evaluate, write and their sum (``harness_ms``); CPU time, ``*_wall_ms`` wall."""
    from bench.runs.evaluate import evaluate_run
    from bench.runs.folders import write_run
    from bench.runs.job import calibration_frames, prepare
    from bench.runs.plan import plan, single_job
    from methods.registry import get_method

    with tempfile.TemporaryDirectory() as tmp:
        job = plan([single_job(method, Path(store), True, Path(tmp) / "run",
                               dict(params or {}))])[0]
        seed = bool(job.seed)
        with _clock() as start:
            prep = prepare(job)
            prep.method.warm_up(prep.sequence)  # run_timed's warm-up
        seq = prep.sequence
        try:
            with _clock() as loop:
                result = prep.method.run(seq, seed, lambda i: None)
            # scored twice: the first also loads the compiled scoring kernels (numba's cache,
            # once per process: a fixed cost, its excess over the second), the second is timed
            clocks = []
            for _ in range(2):
                with _clock() as evaluate:
                    evaluation = evaluate_run(seq.ground_truth, result, job.lengths_m,
                                              excluded=calibration_frames(seq))
                clocks.append(evaluate)
            metrics = {"sequence": seq.name, "method": method, "seed": job.seed,
                       "frames": len(seq), **evaluation.metrics}
            with _clock() as write:
                write_run(prep.run_dir, result, evaluation.gt, prep.config, metrics, [])
            # the part of writing that does not grow with the frames (meta.json's versions
            # and git state, config.yaml, opening and syncing the files): a 2-frame folder
            first = OdometryResult(result.stamps[:2], result.poses[:2], result.frames[:2])
            with _clock() as write_fixed:
                write_run(Path(tmp) / "fixed", first, None, prep.config, metrics, [])
        finally:
            seq.close()
    n = len(result.frames)
    times = np.array([f.time_ms for f in result.frames])
    method_ms = float(np.nanmean(times))
    timed = np.isfinite(times).sum()
    read = read_cost(Path(store), get_method(method).reads_fields)
    out = {"method": method, "frames": n, "points": read["points"], "method_ms": method_ms,
           "startup_s": start.cpu_s, "startup_wall_s": start.wall_s,
           "read_ms": read["read_ms"], "read_wall_ms": read["read_wall_ms"]}
    for name, c, unit in (("loop", loop, n), ("evaluate", evaluate, n)):
        out[f"{name}_ms"], out[f"{name}_wall_ms"] = 1e3 * c.cpu_s / unit, 1e3 * c.wall_s / unit
    out["write_ms"] = 1e3 * max(0.0, write.cpu_s - write_fixed.cpu_s) / n
    out["write_wall_ms"] = 1e3 * max(0.0, write.wall_s - write_fixed.wall_s) / n
    out["startup_s"] += write_fixed.cpu_s + max(0.0, clocks[0].cpu_s - clocks[1].cpu_s)
    out["startup_wall_s"] += write_fixed.wall_s + max(0.0, clocks[0].wall_s - clocks[1].wall_s)
    # the loop's time besides the method's timed frames: reading and driving
    for suffix in ("", "_wall"):
        rest = out[f"loop{suffix}_ms"] - method_ms * timed / n
        out[f"driver{suffix}_ms"] = rest - out[f"read{suffix}_ms"]
        out[f"harness{suffix}_ms"] = (rest + out[f"evaluate{suffix}_ms"]
                                      + out[f"write{suffix}_ms"])
    return out


def _bench_run(store: Path, method: str, out: Path) -> tuple[float, float]:
    """(wall, CPU) [s] of ``bench run --method METHOD --data STORE`` in a child process (the
    default process executor: its worker's CPU time counted)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    root = str(Path(__file__).resolve().parents[2])
    env = {**os.environ,
           "PYTHONPATH": os.pathsep.join(filter(None, (root, os.environ.get("PYTHONPATH"))))}
    done = subprocess.run([sys.executable, "-m", "bench.cli", "run", "--method", method,
                           "--data", str(store), "--out", str(out), "--force"],
                          capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        raise RuntimeError(f"bench run --method {method} --data {store} failed:\n"
                           f"{done.stdout[-1500:]}{done.stderr[-1500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def whole_run(store: Path, method: str = "doppler") -> dict:
    """``bench run`` on ``store`` and on its first ``SHORT_FRAMES`` frames (child processes):
    wall and CPU [s] of each, the method's mean ``time_ms``, and per frame [ms] what the run
    spent besides the method: ``marginal_*`` = (full - short) / (frames - SHORT_FRAMES) - mean
    ``time_ms``; ``issue_*`` = (full - 3 s) / frames - mean ``time_ms`` (issue 29's check)."""
    import pandas as pd

    with tempfile.TemporaryDirectory() as tmp:
        full = StoreSequence(store)
        n = len(full)
        k = min(SHORT_FRAMES, n // 2)
        short = guard.write_store(FrameRange(full, 0, k), Path(tmp) / "short.h5", None,
                                  "a scratch store")
        full.close()
        wall_s, cpu_s = _bench_run(short, method, Path(tmp) / "short")
        wall, cpu = _bench_run(Path(store), method, Path(tmp) / "full")
        method_ms = float(pd.read_csv(Path(tmp) / "full" / "frames.csv")["time_ms"].mean())
    out = {"method": method, "frames": n, "method_ms": method_ms, "wall_s": wall, "cpu_s": cpu,
           "short_frames": k, "short_wall_s": wall_s, "short_cpu_s": cpu_s}
    for kind, total, first in (("wall", wall, wall_s), ("cpu", cpu, cpu_s)):
        out[f"marginal_{kind}_ms"] = 1e3 * (total - first) / (n - k) - method_ms
        out[f"issue_{kind}_ms"] = 1e3 * (total - 3.0) / n - method_ms
    return out


def tiled_store(seq: Sequence, frames: int, path: Path) -> Path:
    """A store of ``frames`` scans cycling through ``seq``'s at its period, with a
    ground truth along a straight line at 10 m/s: a long sequence for timing the harness
    (evaluation and writing cost the same whatever the motion)."""
    scans = [seq[i % len(seq)] for i in range(frames)]
    dt = seq.sensor.period_s
    stamps = np.arange(frames) * dt
    scans = [Scan(t, s.points, s.doppler, s.fields) for t, s in zip(stamps, scans, strict=True)]
    gt = Trajectory(stamps, np.array([make_T(np.eye(3), [10.0 * t, 0, 0]) for t in stamps]))
    guard.write_store(MemorySequence(f"{seq.name}-tiled", seq.sensor, scans, gt), path,
                      guard.is_store, "a scratch store")
    return path


def scenario_row(scenario: str, seq: Sequence, frames: int = 300,
                 method: str = "doppler") -> dict:
    """``phases`` of ``method`` on ``seq``'s scans tiled to ``frames`` frames."""
    with tempfile.TemporaryDirectory() as tmp:
        store = tiled_store(seq, frames, Path(tmp) / "tiled.h5")
        return {"scenario": scenario, **phases(store, method)}


def print_rows(rows: list[dict], console) -> None:
    """The per-frame table: method, read, driver, evaluate, write, harness total and ratios."""
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=escape("The harness's own cost per frame beside the method's [ms, CPU "
                               "time] (wall time in brackets)"))
    for col in ("scan", "points", "frames", "method", "read", "driver", "evaluate", "write",
                "harness", "harness / method", "read / method", "fixed [s]"):
        # escaped: "[s]" would be read as rich markup (strike-through) and vanish
        table.add_column(escape(col), justify="left" if col == "scan" else "right")
    for r in rows:
        m = r["method_ms"]
        table.add_row(
            f"{r['scenario']} ({r['method']})", f"{r['points']}", f"{r['frames']}", f"{m:.3f}",
            *[f"{r[k + '_ms']:.3f} ({r[k + '_wall_ms']:.3f})"
              for k in ("read", "driver", "evaluate", "write", "harness")],
            f"{r['harness_ms'] / m:.2f}x", f"{r['read_ms'] / m:.2f}x",
            f"{r['startup_s']:.2f} ({r['startup_wall_s']:.2f})")
    table.caption = escape(
        "read: a scan from the store (the arrays the method reads); driver: the loop around "
        "the method; fixed: start-up (store, method, warm-up) and the part of writing the run "
        f"folder that does not grow with the frames; limits (issue 29): harness <= "
        f"{OVERHEAD_LIMIT}x and read <= {READ_LIMIT}x the method")
    console.print(table)


def print_whole_run(r: dict, console) -> None:
    m = r["method_ms"]
    console.print(
        f"bench run --method {r['method']}: {r['frames']} frames in {r['wall_s']:.1f} s wall / "
        f"{r['cpu_s']:.1f} s CPU ({r['short_frames']} frames: {r['short_wall_s']:.1f} s / "
        f"{r['short_cpu_s']:.1f} s); method {m:.3f} ms/frame; besides it per frame: "
        f"marginal {r['marginal_cpu_ms']:.3f} ms CPU ({r['marginal_cpu_ms'] / m:.2f}x), "
        f"{r['marginal_wall_ms']:.3f} ms wall ({r['marginal_wall_ms'] / m:.2f}x); "
        f"(total - 3 s) / frames - method: {r['issue_cpu_ms']:.3f} ms CPU "
        f"({r['issue_cpu_ms'] / m:.2f}x), {r['issue_wall_ms']:.3f} ms wall "
        f"({r['issue_wall_ms'] / m:.2f}x); limit {OVERHEAD_LIMIT}x", highlight=False,
        markup=False)


#: LiDAR scan size of the harness figures (issue 29: a 64k-point scan read in at most 2 ms)
LIDAR_POINTS = 64000
#: frames of the tiled stores (radar, LiDAR)
TILED_FRAMES = {"radar": 300, "lidar": 40}


def wanted(scenario: str, points: int, sizes: list[int]) -> bool:
    """The scenarios ``bench speed`` adds harness figures to: the radar scan and the LiDAR
    scan of ``LIDAR_POINTS`` points (else the largest size asked for)."""
    lidar = LIDAR_POINTS if LIDAR_POINTS in sizes else max(sizes)
    return scenario == "radar" or points == lidar


def report(rows: list[dict], out: Path, console) -> None:
    """Print the harness table and write ``harness.csv``."""
    print_rows(rows, console)
    guard.make_folder(out)
    header = list(rows[0])
    lines = [",".join(header)] + [",".join(f"{r[k]:.6g}" if isinstance(r[k], float)
                                           else str(r[k]) for k in header) for r in rows]
    guard.write_text(out / "harness.csv", "\n".join(lines) + "\n", guard.derived,
                     "a harness table")
    console.print(f"wrote {out}/harness.csv")


def synthetic_scenarios(lidar_points: int = LIDAR_POINTS, frames: int = 8):
    """(scenario, sequence): the scenes ``bench speed`` times the methods on: a semi-dense
    radar sequence (loop scene) at its own density, and a dense LiDAR sequence (campus scene)
    subsampled to ``lidar_points`` points a scan."""
    from loaders.synthetic import SyntheticSequence

    radar = SyntheticSequence("loop", "radar-semidense", frames=frames, seed=0)
    yield "radar", MemorySequence(radar.name, radar.sensor, list(radar), radar.ground_truth)
    lidar = SyntheticSequence("campus", "lidar-dense", frames=frames, seed=0,
                              points=int(lidar_points * 1.6))
    rng = np.random.default_rng(0)
    scans = [s if len(s) <= lidar_points else
             s.select(np.sort(rng.choice(len(s), lidar_points, replace=False))) for s in lidar]
    yield "lidar", MemorySequence(lidar.name, lidar.sensor, scans, lidar.ground_truth)


def run_harness(out: Path, console, store: Path | None = None, method: str = "doppler",
                lidar_points: int = LIDAR_POINTS) -> list[dict]:
    """``bench speed --harness``: the harness's per-frame cost beside ``method``'s on the
    synthetic radar scan and a ``lidar_points``-point LiDAR scan (tiled stores); with
    ``store``, on it too, and a whole ``bench run`` on it (``whole_run``)."""
    rows = []
    if store is not None:
        rows.append({"scenario": Path(store).name, **phases(Path(store), method)})
    else:
        console.print(f"generating synthetic radar and {lidar_points}-point LiDAR scans")
        for scenario, seq in synthetic_scenarios(lidar_points):
            rows.append(scenario_row(scenario, seq, TILED_FRAMES[scenario], method))
    report(rows, out, console)
    if store is not None:
        console.print(f"timing `bench run --method {method}` on {store} and on its first "
                      f"{SHORT_FRAMES} frames (child processes)", markup=False)
        print_whole_run(whole_run(Path(store), method), console)
    return rows
