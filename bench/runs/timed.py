"""How the harness times a method, the one place every timed path goes through (``bench run``
in every executor, ``bench.api``, ``bench speed``): the library thread counts limited to one
(``bench.threads``), the common warm-up and the timed run (``methods.base.run_timed``), then
the two checks of ``methods.timing``:

- work that left the timed thread: a one-thread (CPU-clock) run whose process CPU exceeds its
  thread's by more than ``CPU_LEAK_LIMIT`` is not reported as one-thread CPU time: it is timed
  again by wall clock under the machine-wide timing lock, and says so (a warning naming the
  thread settings, ``clock`` "wall" and ``clock_note`` in metrics.json);
- frames that are not the method's steady work (``timing_outliers``: a numba compilation inside
  a frame, or a frame far above the run's median) are listed in the run; a run with a
  compilation in a timed frame is marked ``timing_clean: false`` and is not reused as a clean
  timing (``bench.runs.folders.is_finished``): it runs again next time.

The process-to-thread CPU ratio is recorded in every run (``cpu_process_to_thread``); the
Python threads alive when the run starts (a dask worker's event loop and heartbeats, the
progress display of ``--executor local``) are the harness's and left out of it
(``methods.timing.harness_threads``): their work is not the method's, and a dask worker's
threads alone once made 1.06-1.40x on millisecond frames. A thread the method starts, and
every native pool (BLAS, OpenMP, TBB), counts.
"""

from __future__ import annotations

import os
import threading
import warnings
from collections.abc import Callable

from bench.runs.provenance import cpu_model
from bench.threads import leak_hint, limit_threads
from methods.base import Odometry, OdometryResult, run_timed
from methods.timing import (
    CPU_LEAK_LIMIT,
    DEFAULT_TIMING_LOCK,
    TIMING_LOCK_ENV,
    cpu_leak,
    harness_threads,
    timing_outliers,
)


class CpuLeakWarning(UserWarning):
    """A one-thread run's work left its thread: it was timed again by wall clock."""


class TimingOutlierWarning(UserWarning):
    """A timed frame was not the method's steady work (a compilation, a far outlier)."""


def timed_run(method: Odometry, sequence, seed: bool,
              on_frame: Callable[[int], None] | None = None) -> tuple[OdometryResult, dict]:
    """The warm-up and the timed run of ``method``, checked; returns the result and the timing
    record for metrics.json (clock, threads, the CPU model, cpu_process_to_thread,
    timing_outliers, timing_clean and, after a fall-back, clock_note)."""
    limit_threads(1)
    # the Python threads already running (a dask worker's event loop, a progress display)
    # are the harness's: their CPU time is not the method's work
    here = threading.current_thread()
    harness_threads([t.ident for t in threading.enumerate() if t is not here])
    try:
        return _checked_run(method, sequence, seed, on_frame)
    finally:
        harness_threads([])


def _checked_run(method: Odometry, sequence, seed: bool,
                 on_frame: Callable[[int], None] | None) -> tuple[OdometryResult, dict]:
    result = run_timed(method, sequence, seed, on_frame)
    ratio = cpu_leak(result.frames)
    record: dict = {}
    if method.clock == "cpu" and ratio > 1 + CPU_LEAK_LIMIT:
        note = (f"process CPU time was {ratio:.2f}x the timed thread's (limit "
                f"{1 + CPU_LEAK_LIMIT:.2f}): work left the thread ({leak_hint()}), so its CPU "
                "time would undercount; timed again by wall clock under the timing lock")
        warnings.warn(f"{method.name}: {note}", CpuLeakWarning, stacklevel=2)
        os.environ.setdefault(TIMING_LOCK_ENV, DEFAULT_TIMING_LOCK)
        method.clock_override = "wall"
        try:
            result = run_timed(method, sequence, seed, on_frame)
        finally:
            del method.clock_override
        record["clock_note"] = note
        record["clock"] = "wall"
        record["cpu_process_to_thread_first"] = ratio
        ratio = cpu_leak(result.frames)
    outliers = timing_outliers(result.frames)
    if outliers:
        listed = "; ".join(f"frame {k}: {v}" for k, v in list(outliers.items())[:5])
        warnings.warn(f"{method.name}: {len(outliers)} timed frame(s) not steady work: "
                      f"{listed}", TimingOutlierWarning, stacklevel=2)
    compiled = any(f.compiles for f in result.frames)
    return result, {"clock": record.pop("clock", method.clock), "threads": method.threads,
                    "cpu": cpu_model(),
                    "cpu_process_to_thread": ratio if ratio == ratio else None, **record,
                    "timing_outliers": {str(k): v for k, v in outliers.items()},
                    "timing_clean": not compiled}
