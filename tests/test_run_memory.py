"""A run's memory is bounded by a few scans (and a method's map), whatever the sequence length:
its peak grows with the frames only by their records (a pose and a row of timings each)."""

from __future__ import annotations

import gc
import tracemalloc

from bench.runs.job import run_job
from bench.runs.plan import plan, single_job
from bench.studies.harness import tiled_store
from conftest import constant_twist_sequence


def _peak_bytes(store, out) -> int:
    job = plan([single_job("doppler", store, True, out, {})])[0]
    gc.collect()
    tracemalloc.start()
    try:
        outcome = run_job(job, force=True)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert outcome.status == "done", outcome.message
    return peak


def test_peak_memory_of_a_run_does_not_grow_with_the_sequence(tmp_path):
    base = constant_twist_sequence(n_frames=10, n_points=4000)
    scan_bytes = max(s.points.nbytes + s.doppler.nbytes for s in base)  # float64, as read
    n = 100
    short = tiled_store(base, n, tmp_path / "short.h5")
    long = tiled_store(base, 4 * n, tmp_path / "long.h5")
    _peak_bytes(short, tmp_path / "warm")  # first-call allocations (imports, caches) once
    peak_short = _peak_bytes(short, tmp_path / "short")
    peak_long = _peak_bytes(long, tmp_path / "long")
    per_frame = (peak_long - peak_short) / (3 * n)
    # holding the scans adds a scan per frame (measured: 130 kB a frame when the method keeps
    # them); the records add about 3 % of one (4 kB: pose, timings, rows of the written files)
    assert per_frame < 0.1 * scan_bytes, (peak_short, peak_long, scan_bytes)
