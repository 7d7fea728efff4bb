"""Timed sections that no other job of the same experiment can disturb.

When jobs run in parallel, the executor names a lock file in ``DOPPLER_BENCH_TIMING_LOCK``;
every timed section (a method's registration work for one frame) then holds an exclusive
``flock`` on it, so no two timed sections on this machine overlap and a reported time is the
method's own. Without the variable (serial runs) the guard costs nothing. Only the work inside
the ``with`` block is timed; waiting for the lock is not.
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
    """Milliseconds spent inside a ``timed_section`` (``time_ms`` is set when it ends)."""

    time_ms: float = float("nan")


@contextmanager
def timed_section() -> Iterator[Stopwatch]:
    """``with timed_section() as watch: ...`` then ``watch.time_ms``; exclusive when asked."""
    watch = Stopwatch()
    path = os.environ.get(TIMING_LOCK_ENV)
    fd = _lock_fd(path) if path else None
    if fd is not None:
        fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        t0 = time.perf_counter_ns()
        yield watch
        watch.time_ms = (time.perf_counter_ns() - t0) / 1e6
    finally:
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_UN)
