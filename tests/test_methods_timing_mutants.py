"""methods/timing.py, the parts the contract tests leave open: the named harness threads' clock
(a thread whose clock cannot be read counts 0), the lock file of our own beside another user's,
the open error naming the variable, numba compilations counted once each (one listener however
many sections), and the process CPU less the harness threads'."""

from __future__ import annotations

import os
import threading
import time

import pytest

from loaders.errors import DataError
from methods import timing


@pytest.fixture
def harness(monkeypatch):
    """The harness clocks and their last readings, restored after the test."""
    monkeypatch.setattr(timing, "_harness_clocks", [])
    monkeypatch.setattr(timing, "_harness_last", {})
    return timing


def test_no_named_thread_counts_nothing(harness):
    harness.harness_threads([])
    assert harness._harness_ns() == 0


def test_a_clock_never_read_counts_zero_and_a_read_one_its_last_reading(harness, monkeypatch):
    readings = {101: [OSError("gone")] * 2, 202: [5_000, OSError("ended")]}

    def clock_gettime_ns(clock):
        value = readings[clock].pop(0)
        if isinstance(value, Exception):
            raise value
        return value

    monkeypatch.setattr(timing.time, "clock_gettime_ns", clock_gettime_ns)
    harness._harness_clocks[:] = [101, 202]
    assert harness._harness_ns() == 5_000
    assert harness._harness_ns() == 5_000  # 202 ended: its last reading still counts


def test_harness_threads_names_the_threads_clocks(harness):
    done = threading.Event()
    worker = threading.Thread(target=done.wait)
    worker.start()
    try:
        harness._harness_last[1] = 7
        harness.harness_threads([worker.ident, threading.get_ident()])
        assert harness._harness_clocks == [time.pthread_getcpuclockid(worker.ident),
                                           time.pthread_getcpuclockid(threading.get_ident())]
        assert harness._harness_last == {}
    finally:
        done.set()
        worker.join()


def test_the_process_time_leaves_out_the_harness_threads(harness):
    """A named thread spinning 60 ms beside a section that sleeps: the process CPU of the
    section is about the caller's (near zero), not 60 ms."""
    go, stop, leave = threading.Event(), threading.Event(), threading.Event()

    def spin():
        go.wait()
        end = time.thread_time() + 0.06
        while time.thread_time() < end:
            pass
        stop.set()
        leave.wait(30)  # alive until the section has ended: its clock is read

    worker = threading.Thread(target=spin)
    worker.start()
    harness.harness_threads([worker.ident])
    with timing.stopwatch() as watch:
        go.set()
        stop.wait(30)
        time.sleep(0.01)
    leave.set()
    worker.join()
    assert watch.process_ms < 30, watch.process_ms
    assert watch.wall_ms >= 60 * 0.5


def test_another_users_lock_file_gives_one_of_our_own(tmp_path, monkeypatch):
    path = str(tmp_path / "shared.lock")
    real_open = os.open

    def deny(name, flags, mode=0o777):
        if name == path:
            raise PermissionError(13, "Permission denied")
        return real_open(name, flags, mode)

    monkeypatch.setattr(timing.os, "open", deny)
    monkeypatch.setattr(timing, "_lock_files", {})
    fd = timing._lock_fd(path)
    own = f"{path}.{os.getuid()}"
    assert os.fstat(fd).st_ino == os.stat(own).st_ino
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(own).st_mode & 0o777 == 0o600 & ~mask
    assert os.write(fd, b"x") == 1  # opened for writing
    assert timing._lock_files == {path: fd}
    os.close(fd)


def test_a_lock_file_that_cannot_be_opened_is_one_error(tmp_path, monkeypatch):
    path = str(tmp_path / "x.lock")

    def fail(name, flags, mode=0o777):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(timing.os, "open", fail)
    monkeypatch.setattr(timing, "_lock_files", {})
    with pytest.raises(DataError) as err:
        timing._lock_fd(path)
    assert str(err.value) == (f"{timing.TIMING_LOCK_ENV}={path!r}: cannot open the lock file "
                              "(Input/output error)")
    assert timing._lock_files == {}


def _compile_fresh():
    """Compile a new numba function (a new closure each call): one compilation."""
    import numba

    @numba.njit
    def f(x):
        return x + 1

    return f(1)


def test_the_listener_is_registered_once_and_counts_each_start(monkeypatch):
    import sys

    from numba.core import event

    registered = []
    monkeypatch.setattr(event, "register", lambda kind, listener: registered.append(
        (kind, listener)))
    monkeypatch.setattr(timing, "_listening", [])
    monkeypatch.setattr(timing, "_compiles", [5])
    with monkeypatch.context() as m:
        m.delitem(sys.modules, "numba")
        timing._watch_numba()  # numba not loaded: nothing compiles, nothing to listen to
        assert registered == [] and timing._listening == []
    timing._watch_numba()
    timing._watch_numba()
    (kind, listener), = registered
    assert kind == "numba:compiler_lock" and isinstance(listener, event.Listener)
    listener.on_start(None)
    listener.on_start(None)
    listener.on_end(None)
    assert timing._compiles == [7]


def test_each_numba_compilation_is_counted_once():
    _compile_fresh()  # numba loaded and its first-use costs paid
    counts = []
    for _ in range(2):
        with timing.stopwatch() as watch:
            _compile_fresh()
        counts.append(watch.compiles)
    assert counts[0] >= 1 and counts == [counts[0]] * 2
    with timing.stopwatch() as watch:
        pass
    assert watch.compiles == 0


def _permissions(monkeypatch, allowed):
    """``os.access`` as a user without root's rights: ``allowed`` path -> the modes granted."""

    def access(path, mode):
        return mode & ~allowed[os.path.abspath(path)] == 0

    monkeypatch.setattr(timing.os, "access", access)


RW, R, W, NONE = os.R_OK | os.W_OK, os.R_OK, os.W_OK, 0


@pytest.mark.parametrize("exists, file_mode, folder_mode, usable", [
    (True, RW, R, True),  # our own file in a folder we may not write to
    (True, R, RW, True),  # another user's file: ours beside it
    (True, R, R, False),
    (True, NONE, R, False),
    (False, NONE, RW, True),
    (False, NONE, R, False),
])
def test_a_lock_path_is_usable_when_we_can_open_or_create_it(tmp_path, monkeypatch, exists,
                                                             file_mode, folder_mode, usable):
    path = tmp_path / "timing.lock"
    if exists:
        path.write_text("")
    _permissions(monkeypatch, {str(path): file_mode, str(tmp_path): folder_mode})
    if usable:
        timing.check_lock_path(str(path))
        return
    with pytest.raises(DataError) as err:
        timing.check_lock_path(str(path))
    assert str(err.value) == (
        f"{timing.TIMING_LOCK_ENV}={str(path)!r}: cannot open or create the lock file (no "
        f"write permission in {tmp_path}); name a file in a folder of yours (or leave it "
        f"unset: the executors use {timing.DEFAULT_TIMING_LOCK})")


def test_a_path_the_system_refuses_to_check_is_one_error(tmp_path, monkeypatch):
    def refuse(path, mode):
        raise ValueError("path too strange")

    monkeypatch.setattr(timing.os, "access", refuse)
    path = str(tmp_path / "timing.lock")
    with pytest.raises(DataError) as err:
        timing.check_lock_path(path)
    assert str(err.value) == (f"{timing.TIMING_LOCK_ENV}={path!r}: not a usable path (path too "
                              f"strange); or leave it unset: the executors use "
                              f"{timing.DEFAULT_TIMING_LOCK}")
    assert err.value.__suppress_context__
