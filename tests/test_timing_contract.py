"""methods/timing.py's contract, checked directly and fast: the lock path check's answers, the
machine-wide lock held exactly while an exclusive section runs (another open file description
cannot take it then, and can before and after), the lock file kept open once per path, and the
leak ratio's definition."""

from __future__ import annotations

import fcntl
import os
import threading
import time
from types import SimpleNamespace

import pytest

from loaders.errors import DataError
from methods import timing


def _can_lock(path) -> bool:
    """Whether a new open file description of ``path`` gets the exclusive lock now."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    finally:
        os.close(fd)
    return True


def test_an_exclusive_section_holds_the_named_lock_only_while_it_runs(monkeypatch, tmp_path):
    lock = str(tmp_path / "timing.lock")
    monkeypatch.setenv(timing.TIMING_LOCK_ENV, lock)
    with timing.timed_section(exclusive=True) as watch:
        assert not _can_lock(lock)
    assert _can_lock(lock)
    assert watch.wall_ms >= 0 and watch.cpu_ms >= 0
    with pytest.raises(RuntimeError), timing.timed_section(exclusive=True):
        raise RuntimeError("the work failed")
    assert _can_lock(lock)  # released on an error too
    with timing.timed_section(exclusive=False):  # a CPU-timed section takes no lock
        assert _can_lock(lock)


def test_an_exclusive_section_waits_while_another_holder_has_the_lock(monkeypatch, tmp_path):
    """A holder (another open file description, as another process's) blocks the section;
    once it lets go, the section runs."""
    import threading

    lock = str(tmp_path / "timing.lock")
    monkeypatch.setenv(timing.TIMING_LOCK_ENV, lock)
    fd = os.open(lock, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    entered = threading.Event()

    def section():
        with timing.timed_section(exclusive=True):
            entered.set()

    worker = threading.Thread(target=section)
    worker.start()
    try:
        assert not entered.wait(0.3)  # blocked by the holder
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
    assert entered.wait(10)
    worker.join(10)


def test_no_lock_is_taken_when_the_variable_is_unset(monkeypatch, tmp_path):
    monkeypatch.delenv(timing.TIMING_LOCK_ENV, raising=False)
    before = dict(timing._lock_files)
    with timing.timed_section(exclusive=True):
        assert _can_lock(timing.DEFAULT_TIMING_LOCK.replace(
            os.path.dirname(timing.DEFAULT_TIMING_LOCK), str(tmp_path)))
    assert timing._lock_files == before  # nothing opened


def test_the_lock_file_is_opened_once_per_path(tmp_path):
    a, b = str(tmp_path / "a.lock"), str(tmp_path / "b.lock")
    fd = timing._lock_fd(a)
    assert timing._lock_fd(a) == fd and timing._lock_fd(b) != fd
    assert os.path.exists(a) and os.fstat(fd).st_ino == os.stat(a).st_ino
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(a).st_mode & 0o777 == 0o666 & ~mask  # any user may take the lock
    with pytest.raises(DataError, match=timing.TIMING_LOCK_ENV) as err:
        timing._lock_fd(str(tmp_path / "missing" / "c.lock"))
    assert "does not exist" in str(err.value)  # checked before opening


@pytest.mark.parametrize("bad, says", [
    ("   ", "expected the path of a lock file"),
    ("a\0b", "expected the path of a lock file"),
    ("{tmp}", "is a folder"),
    ("{tmp}/no/x.lock", "does not exist"),
    ("{tmp}/f/x.lock", "not a usable path"),  # f is a file, not a folder
    ("{tmp}/" + "x" * 300, "not a usable path"),  # a name too long
])
def test_a_bad_lock_path_is_one_error_naming_the_variable_and_the_default(bad, says, tmp_path):
    (tmp_path / "f").write_text("")
    path = bad.replace("{tmp}", str(tmp_path))
    with pytest.raises(DataError) as err:
        timing.check_lock_path(path)
    text = str(err.value)
    assert text.startswith(f"{timing.TIMING_LOCK_ENV}={path!r}: ")
    assert says in text and timing.DEFAULT_TIMING_LOCK in text
    assert "[Errno" not in text  # the system's reason in words
    if says == "is a folder":
        assert os.path.join(path, "timing.lock") in text  # the suggested file


def test_a_usable_lock_path_passes_and_creates_nothing(tmp_path):
    timing.check_lock_path(None)  # unset
    timing.check_lock_path(str(tmp_path / "new.lock"))
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "old.lock").write_text("")
    timing.check_lock_path(str(tmp_path / "old.lock"))  # an existing file


def _frame(process_ms, thread_ms):
    return SimpleNamespace(process_ms=process_ms, thread_ms=thread_ms)


def test_the_cpu_leak_is_the_ratio_of_the_sums_over_timed_frames():
    nan = float("nan")
    assert timing.cpu_leak([_frame(2.0, 1.0), _frame(4.0, 3.0)]) == pytest.approx(6.0 / 4.0)
    # untimed frames (NaN in either clock) are left out of both sums
    frames = [_frame(2.0, 1.0), _frame(nan, 5.0), _frame(7.0, nan), _frame(1.0, 1.0)]
    assert timing.cpu_leak(frames) == pytest.approx(3.0 / 2.0)
    assert timing.cpu_leak([_frame(0.3, 0.2), _frame(0.4, 0.3)]) == pytest.approx(1.4)
    for nothing in ([], [_frame(nan, nan)], [_frame(1.0, 0.0)]):
        assert timing.cpu_leak(nothing) != timing.cpu_leak(nothing)  # NaN


def test_the_median_is_the_runs_own_and_a_zero_median_flags_nothing():
    def frame(i, ms, compiles=0):
        return SimpleNamespace(index=i, time_ms=ms, compiles=compiles)

    # the median of 1, 2, 3, 100: the upper middle value (3); 100 > 10 * 3 is flagged, and a
    # frame exactly at 10x the median is not
    flagged = timing.timing_outliers([frame(0, 1.0), frame(1, 2.0), frame(2, 100.0),
                                      frame(3, 3.0)])
    assert list(flagged) == [2]
    assert "33x the median (3 ms)" in flagged[2]
    assert timing.timing_outliers([frame(0, 3.0), frame(1, 3.0), frame(2, 30.0)]) == {}
    assert timing.timing_outliers([frame(0, 0.0), frame(1, 0.0), frame(2, 5.0)]) == {}
    assert timing.timing_outliers([]) == {}
    # a sub-millisecond median counts too; a frame without a compile count has none
    bare = [SimpleNamespace(index=i, time_ms=ms) for i, ms in enumerate([0.4, 0.5, 0.6, 9.0])]
    assert list(timing.timing_outliers(bare)) == [3]
    assert "x the median" in timing.timing_outliers(bare)[3]
    assert timing.timing_outliers([frame(0, float("nan"), compiles=2)]) == {}
    got = timing.timing_outliers([frame(0, 1.0), frame(1, 1.5, compiles=2)])
    assert got == {1: "numba compiled 2x inside it (1.5 ms)"}


def _spin(seconds: float) -> None:
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def test_the_harness_threads_work_is_left_out_of_the_process_time():
    """A named harness thread's 60 ms of CPU during a section is not the method's: out of
    ``process_ms``; the same work by an unnamed thread is in it. All clocks in milliseconds."""
    def section(name_it: bool):
        ready, go, done, stop = (threading.Event() for _ in range(4))

        def harness():  # works 60 ms in the section, then lives on until it ends
            ready.set()
            go.wait()
            _spin(0.06)
            done.set()
            stop.wait()

        worker = threading.Thread(target=harness)
        worker.start()
        ready.wait()
        timing.harness_threads([worker.ident] if name_it else [])
        try:
            with timing.stopwatch() as watch:
                go.set()
                done.wait()
                _spin(0.02)  # the calling thread's own 20 ms
        finally:
            stop.set()
            worker.join()
            timing.harness_threads([])
        return watch

    named = section(True)
    assert 15 < named.cpu_ms < 45 and 15 < named.process_ms < 45, vars(named)
    assert named.wall_ms >= named.cpu_ms and named.ms("wall") == named.wall_ms
    assert named.ms("cpu") == named.cpu_ms != named.wall_ms
    unnamed = section(False)
    assert unnamed.process_ms > 70, vars(unnamed)


def test_a_harness_thread_that_ends_inside_a_section_keeps_its_time_out():
    """A named thread with 60 ms of CPU before the section that ends inside it: its clock can
    no longer be read at the end, and its earlier time must not come back as the method's
    (``process_ms`` near the caller's own 20 ms, not 80 ms)."""
    spun, go = threading.Event(), threading.Event()

    def harness():
        _spin(0.06)  # before the section
        spun.set()
        go.wait()  # ends inside it

    worker = threading.Thread(target=harness)
    worker.start()
    spun.wait()
    timing.harness_threads([worker.ident])
    try:
        with timing.stopwatch() as watch:
            go.set()
            worker.join()
            _spin(0.02)
    finally:
        timing.harness_threads([])
    assert 15 < watch.cpu_ms < 45, vars(watch)
    assert watch.process_ms < 45, vars(watch)


def test_every_named_harness_thread_is_left_out():
    """Two named threads (a helper and the calling one): the work of both is out of the
    process time, while the thread clock still sees the caller's."""
    stop = threading.Event()
    helper = threading.Thread(target=stop.wait)
    helper.start()
    timing.harness_threads([threading.get_ident(), helper.ident])  # summed, in any order
    try:
        with timing.stopwatch() as watch:
            _spin(0.03)
        assert watch.cpu_ms > 25 and watch.process_ms < watch.cpu_ms / 2, vars(watch)
    finally:
        timing.harness_threads([])
        stop.set()
        helper.join()


def test_a_numba_compilation_inside_a_section_is_counted():
    import numba

    with timing.stopwatch() as warm:
        pass

    @numba.njit(cache=False)
    def fresh(x):  # a new function: compiled on its first call
        return x * 2 + 1

    with timing.stopwatch() as watch:
        assert fresh(3) == 7
    assert watch.compiles >= 1
    with timing.stopwatch() as again:
        assert fresh(4) == 9  # compiled already
    assert again.compiles == 0 and warm.compiles == 0
