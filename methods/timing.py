"""How a frame's work is timed: the clock, and a lock for wall-clock timings.

Every timed section measures two clocks:
- ``cpu_ms``: the CPU time of the calling thread (``CLOCK_THREAD_CPUTIME_ID``). For a method
  that runs on one thread (the default of every method) it is exactly its work: time the thread
  spends waiting for a core, because other jobs or programs run on the machine, is not counted,
  so the same run gives the same time alone, beside other jobs or on a cluster.
- ``wall_ms``: the elapsed time. It is the latency of a method that runs on several threads
  (whose helper threads the calling thread's CPU time does not see); such a run is only
  meaningful alone.

``Odometry.clock`` picks ``cpu`` for one thread and ``wall`` otherwise. A wall-clock section
holds an exclusive ``flock`` on the file named by ``DOPPLER_BENCH_TIMING_LOCK`` (set by the
executors when jobs run in parallel), so no two wall-clock sections on this machine overlap;
waiting for the lock is not timed.
"""

from __future__ import annotations

import fcntl
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager

TIMING_LOCK_ENV = "DOPPLER_BENCH_TIMING_LOCK"
_lock_files: dict[str, int] = {}


def _lock_fd(path: str) -> int:
    fd = _lock_files.get(path)
    if fd is None:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except PermissionError:  # another user's lock file: one of our own
            fd = os.open(f"{path}.{os.getuid()}", os.O_RDWR | os.O_CREAT, 0o600)
        _lock_files[path] = fd
    return fd


class Stopwatch:
    """Milliseconds spent inside a ``timed_section`` or ``stopwatch``, by both clocks (set when
    it ends)."""

    wall_ms: float = float("nan")
    cpu_ms: float = float("nan")

    def ms(self, clock: str) -> float:
        """The time by ``clock`` ("cpu" or "wall")."""
        return self.cpu_ms if clock == "cpu" else self.wall_ms


@contextmanager
def stopwatch() -> Iterator[Stopwatch]:
    """Time a block by both clocks (e.g. the registration call inside a frame's work)."""
    watch = Stopwatch()
    c0, w0 = time.thread_time_ns(), time.perf_counter_ns()
    yield watch
    watch.wall_ms = (time.perf_counter_ns() - w0) / 1e6
    watch.cpu_ms = (time.thread_time_ns() - c0) / 1e6


@contextmanager
def timed_section(exclusive: bool = False) -> Iterator[Stopwatch]:
    """A frame's timed work: ``with timed_section(exclusive) as watch: ...``. ``exclusive``
    (wall-clock timing) holds the machine-wide lock when the executor named one."""
    path = os.environ.get(TIMING_LOCK_ENV) if exclusive else None
    fd = _lock_fd(path) if path else None
    if fd is not None:
        fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        with stopwatch() as watch:
            yield watch
    finally:
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_UN)
