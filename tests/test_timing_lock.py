"""The two clocks of a timed section, and exclusive (wall-clock) sections never overlapping
across processes when the executor names a lock."""

import multiprocessing as mp
import time

from methods import timing


def _hold(path: str, q) -> None:
    import os

    os.environ[timing.TIMING_LOCK_ENV] = path
    with timing.timed_section(exclusive=True):
        q.put(("in", time.monotonic()))
        time.sleep(0.3)
        q.put(("out", time.monotonic()))


def test_timed_sections_of_two_processes_do_not_overlap(tmp_path):
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    procs = [ctx.Process(target=_hold, args=(str(tmp_path / "lock"), q)) for _ in range(2)]
    for p in procs:
        p.start()
    events = sorted((q.get(timeout=30) for _ in range(4)), key=lambda e: e[1])
    for p in procs:
        p.join(timeout=30)
    assert [e[0] for e in events] == ["in", "out", "in", "out"]


def test_the_stopwatch_measures_only_the_section(monkeypatch):
    monkeypatch.delenv(timing.TIMING_LOCK_ENV, raising=False)
    with timing.timed_section() as watch:
        time.sleep(0.02)
    assert 15 < watch.wall_ms < 500
    # waiting (here: sleeping, as when another job holds the core) costs no CPU time
    assert watch.cpu_ms < 5 and watch.ms("cpu") == watch.cpu_ms


def test_cpu_time_counts_the_threads_own_work():
    with timing.stopwatch() as watch:
        t_end = time.thread_time() + 0.03
        while time.thread_time() < t_end:  # 30 ms of this thread's own CPU work
            pass
    assert 29 < watch.cpu_ms <= watch.wall_ms + 1
