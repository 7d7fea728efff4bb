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

Two checks keep a reported time honest:
- ``process_ms``: the CPU time of the whole process over the same section, less that of the
  threads the harness names as its own (``harness_threads``: the Python threads alive when
  the run started, e.g. a dask worker's event loop or a progress display, whose work is not
  the method's). The thread's clock sees only the calling thread, so work handed to other
  threads (a BLAS or OpenMP pool, TBB, a thread the method starts) would vanish from it;
  ``cpu_leak`` compares the two over a run's timed sections, and a run whose process CPU
  exceeds its thread's by more than ``CPU_LEAK_LIMIT`` is not reported as one-thread CPU time
  (``bench.runs.timed`` times it again by wall clock under the lock).
- ``compiles``: numba compilations (or loads from its cache) inside the section, counted by a
  listener on numba's compiler lock. A compiled path the warm-up did not exercise shows there;
  ``timing_outliers`` lists such frames and frames far above the run's median.
"""

from __future__ import annotations

import fcntl
import os
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager

from loaders.errors import DataError

TIMING_LOCK_ENV = "DOPPLER_BENCH_TIMING_LOCK"
#: the lock the executors (and a run that falls back to wall time) name by default
DEFAULT_TIMING_LOCK = os.path.join(tempfile.gettempdir(), "doppler-bench-timing.lock")
#: process CPU above the thread's by more than this fraction: work left the timed thread
CPU_LEAK_LIMIT = 0.05
#: a timed frame above this many times the run's own median is flagged, at any speed (no floor
#: in milliseconds: a sub-millisecond method's 10x spike is as much an outlier as a slow one's)
OUTLIER_FACTOR = 10.0
_lock_files: dict[str, int] = {}
_compiles = [0]  # numba compilations and cache loads in this process (while listened to)
_harness_clocks: list[int] = []  # CPU clocks of the threads whose work is not the method's
_harness_last: dict[int, int] = {}  # each clock's last reading (ns): an ended thread's final time
_listening: list[bool] = []


def check_lock_path(path: str | None) -> None:
    """``DOPPLER_BENCH_TIMING_LOCK``'s value (None: unset) names a lock file that can be used:
    a file (new or existing, not a folder) in an existing folder we may write to or a file we
    may open; else a ``DataError`` naming the variable. Nothing is created."""
    if path is None:
        return
    where = f"{TIMING_LOCK_ENV}={path!r}"
    unset = f"or leave it unset: the executors use {DEFAULT_TIMING_LOCK}"
    if not path.strip() or "\0" in path:
        raise DataError(f"{where}: expected the path of a lock file ({unset})")
    folder = os.path.dirname(os.path.abspath(path))
    try:
        if os.path.isdir(path):
            raise DataError(f"{where}: is a folder; expected the path of a lock file in it, "
                            f"e.g. {os.path.join(path, 'timing.lock')} ({unset})")
        try:
            os.stat(path)
        except FileNotFoundError:
            pass
        except OSError as err:  # a name too long, a file where a folder should be
            raise DataError(f"{where}: not a usable path ({err.strerror or err}); {unset}"
                            ) from None
        if not os.path.isdir(folder):
            raise DataError(f"{where}: the folder {folder} does not exist; expected the path "
                            f"of a lock file in an existing folder ({unset})")
        usable = (os.access(path, os.R_OK | os.W_OK) or os.access(folder, os.W_OK)
                  if os.path.exists(path) else os.access(folder, os.W_OK))
    except DataError:
        raise
    except (OSError, ValueError) as err:
        raise DataError(f"{where}: not a usable path ({err}); {unset}") from None
    if not usable:
        raise DataError(f"{where}: cannot open or create the lock file (no write permission "
                        f"in {folder}); name a file in a folder of yours ({unset})")


def _lock_fd(path: str) -> int:
    fd = _lock_files.get(path)
    if fd is None:
        check_lock_path(path)
        try:
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
            except PermissionError:  # another user's lock file: one of our own
                fd = os.open(f"{path}.{os.getuid()}", os.O_RDWR | os.O_CREAT, 0o600)
        except OSError as err:
            raise DataError(f"{TIMING_LOCK_ENV}={path!r}: cannot open the lock file "
                            f"({err.strerror or err})") from None
        _lock_files[path] = fd
    return fd


def _watch_numba() -> None:
    """Count numba's compilations from now on (once numba is loaded: nothing compiles before)."""
    if _listening or "numba" not in sys.modules:
        return
    from numba.core import event

    class _Count(event.Listener):
        def on_start(self, ev) -> None:
            _compiles[0] += 1

        def on_end(self, ev) -> None:
            pass

    event.register("numba:compiler_lock", _Count())
    _listening.append(True)


def harness_threads(idents) -> None:
    """Name the threads (``threading`` idents) whose CPU time is the harness's, not the
    method's: it is left out of ``process_ms`` (an empty list: none)."""
    clocks = []
    for ident in idents:
        try:
            clocks.append(time.pthread_getcpuclockid(ident))
        except (OSError, AttributeError):
            pass
    _harness_clocks[:] = clocks
    _harness_last.clear()


def _harness_ns() -> int:
    """The named threads' CPU time (ns). A thread that has ended counts with its last reading:
    its time no longer grows, and dropping it would add its whole life to the method's time."""
    total = 0
    for clock in _harness_clocks:
        try:
            _harness_last[clock] = time.clock_gettime_ns(clock)
        except OSError:
            pass
        total += _harness_last.get(clock, 0)
    return total


class Stopwatch:
    """Milliseconds spent inside a ``timed_section`` or ``stopwatch``, by both clocks, the
    process's CPU time, and the numba compilations in it (set when it ends)."""

    wall_ms: float = float("nan")
    cpu_ms: float = float("nan")
    process_ms: float = float("nan")
    compiles: int = 0

    def ms(self, clock: str) -> float:
        """The time by ``clock`` ("cpu" or "wall")."""
        return self.cpu_ms if clock == "cpu" else self.wall_ms


@contextmanager
def stopwatch() -> Iterator[Stopwatch]:
    """Time a block by both clocks (e.g. the registration call inside a frame's work)."""
    _watch_numba()
    watch = Stopwatch()
    k0, h0 = _compiles[0], _harness_ns() if _harness_clocks else 0
    p0, c0, w0 = time.process_time_ns(), time.thread_time_ns(), time.perf_counter_ns()
    yield watch
    w1, c1, p1 = time.perf_counter_ns(), time.thread_time_ns(), time.process_time_ns()
    h1 = _harness_ns() if _harness_clocks else 0
    watch.wall_ms = (w1 - w0) / 1e6
    watch.cpu_ms = (c1 - c0) / 1e6
    watch.process_ms = (p1 - p0 - (h1 - h0)) / 1e6
    watch.compiles = _compiles[0] - k0


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


def cpu_leak(frames) -> float:
    """Process CPU over thread CPU, summed over the timed frames (``FrameRecord``s with
    ``process_ms`` and ``thread_ms``): 1.0 when all the work stayed on the calling thread; NaN
    when nothing was timed."""
    pairs = [(f.process_ms, f.thread_ms) for f in frames
             if f.process_ms == f.process_ms and f.thread_ms == f.thread_ms]
    thread = sum(t for _, t in pairs)
    return sum(p for p, _ in pairs) / thread if thread > 0 else float("nan")


def timing_outliers(frames) -> dict[int, str]:
    """Timed frames whose time is not the method's steady work: frame index -> why (a numba
    compilation inside it, or ``time_ms`` over ``OUTLIER_FACTOR`` x the run's own median,
    whatever the method's speed)."""
    timed = [f for f in frames if f.time_ms == f.time_ms]
    if not timed:
        return {}
    median = sorted(f.time_ms for f in timed)[len(timed) // 2]
    out = {}
    for f in timed:
        if getattr(f, "compiles", 0):
            out[f.index] = f"numba compiled {f.compiles}x inside it ({f.time_ms:.1f} ms)"
        elif median > 0 and f.time_ms > OUTLIER_FACTOR * median:
            out[f.index] = (f"{f.time_ms:.3g} ms, {f.time_ms / median:.0f}x the median "
                            f"({median:.3g} ms)")
    return out
