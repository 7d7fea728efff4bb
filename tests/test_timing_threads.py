"""Timing that cannot undercount (bench/threads.py, methods/timing.py, bench/runs/timed.py): the
thread clock is the thread's, library threads are pinned on every timed path even when the
user asked for more, work that leaves the thread is caught, kiss-icp's thread count is
honoured per run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from bench.runs.timed import CpuLeakWarning, timed_run
from conftest import constant_twist_sequence
from methods import timing
from methods.base import Registration, RegistrationResult

ROOT = Path(__file__).resolve().parents[1]
USER_THREADS = {"OPENBLAS_NUM_THREADS": "4", "OMP_NUM_THREADS": "4"}


def _spin(seconds: float) -> None:
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def test_the_cpu_clock_is_the_threads_not_the_processes():
    """Another thread's work during a section is in ``process_ms`` only, never in ``cpu_ms``
    (a clock that read the process's CPU time would count it)."""
    with timing.stopwatch() as watch:
        other = threading.Thread(target=_spin, args=(0.08,))
        other.start()
        other.join()  # this thread waits (no CPU), the other one works 80 ms
    assert watch.cpu_ms < 20, watch.cpu_ms
    assert watch.process_ms > 60, watch.process_ms
    assert watch.ms("cpu") == watch.cpu_ms


class _Helper(Registration):
    """A 'one-thread' method whose registration hands its work to another thread."""

    name = "test-helper-thread"
    description = "work on a helper thread"

    def register(self, source, target, init):
        worker = threading.Thread(target=_spin, args=(0.01,))
        worker.start()
        worker.join()
        return RegistrationResult(np.eye(4), len(source), 1, True)


def test_a_run_whose_work_leaves_the_thread_is_timed_by_the_wall_clock(monkeypatch, tmp_path):
    monkeypatch.setenv(timing.TIMING_LOCK_ENV, str(tmp_path / "lock"))
    seq = constant_twist_sequence(n_frames=6, n_points=200)
    method = _Helper()
    with pytest.warns(CpuLeakWarning, match="OPENBLAS_NUM_THREADS=1"):
        result, record = timed_run(method, seq, seed=True)
    assert record["clock"] == "wall" and "wall clock" in record["clock_note"]
    assert record["cpu_process_to_thread_first"] > 1.05
    times = np.array([f.time_ms for f in result.frames[1:]])
    walls = np.array([f.wall_ms for f in result.frames[1:]])
    np.testing.assert_array_equal(times, walls)  # the reported time is the wall time
    assert np.all(times >= 9.0)  # the helper's 10 ms are in it, not lost
    assert method.clock == "cpu"  # the fall-back was for that run only


def test_pinning_overrides_the_users_setting_and_limits_loaded_blas():
    """In a process that loaded NumPy with OPENBLAS_NUM_THREADS=4 before ``bench``: the
    environment is pinned to 1 (the user's value remembered) and ``limit_threads`` sets the
    loaded OpenBLAS to 1 thread."""
    code = """
import ctypes, json, os, numpy
def blas_threads():
    lib = next(p for p in (l.split()[-1] for l in open('/proc/self/maps'))
               if 'openblas' in p.lower() and p.endswith('.so'))
    lib = ctypes.CDLL(lib, mode=os.RTLD_NOLOAD)
    for sym in ('scipy_openblas_get_num_threads64_', 'openblas_get_num_threads64_',
                'scipy_openblas_get_num_threads', 'openblas_get_num_threads'):
        if hasattr(lib, sym):
            return getattr(lib, sym)()
before = blas_threads()
import bench.threads as t
env = dict(os.environ)
limited = t.limit_threads(1)
print(json.dumps([before, blas_threads(), env['OPENBLAS_NUM_THREADS'],
                  t.overridden_settings, limited]))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=ROOT, env={**os.environ, **USER_THREADS})
    assert out.returncode == 0, out.stderr[-2000:]
    before, after, env, overridden, limited = json.loads(out.stdout.splitlines()[-1])
    assert before == min(4, os.cpu_count()) > 1, before  # OpenBLAS caps it at the cores
    assert after == 1, (after, limited)
    assert env == "1"
    assert overridden == USER_THREADS


# Every registered method through the notebook API, in a process that loaded NumPy first with
# the user's OPENBLAS_NUM_THREADS=4 / OMP_NUM_THREADS=4 (so only the run-start limit can pin
# BLAS), on 30k-point LiDAR scans (large enough for OpenBLAS to use its threads: unpinned,
# doppler-ego's process CPU was 1.22x its thread's here).
_API_RUN = """
import json, sys
import numpy
from bench.studies.speed import make_sequence, subsample
from loaders.scan import MemorySequence
from loaders.store import write_store
from methods.registry import METHODS
seq = make_sequence("campus", "lidar-dense", 5, 30000, seed=1)
scans = [subsample(s, 30000, k) for k, s in enumerate(seq)]
store = write_store(MemorySequence(seq.name, seq.sensor, scans), sys.argv[1] + "/lidar.h5")
from bench.api import run_method
out = {}
for name in METHODS:
    m = run_method(name, store, out=sys.argv[1] + "/" + name)
    out[name] = [m.clock, m.cpu_process_to_thread, m.cpu_process_to_thread_first]
print(json.dumps(out))
"""


def test_every_method_through_the_api_keeps_its_work_on_the_timed_thread(tmp_path):
    out = subprocess.run([sys.executable, "-c", _API_RUN, str(tmp_path)], capture_output=True,
                         text=True, timeout=900, cwd=ROOT, env={**os.environ, **USER_THREADS})
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.splitlines()[-1])
    from methods.registry import METHODS

    assert set(got) == set(METHODS)
    for name, (clock, ratio, first) in got.items():
        assert clock == "cpu" and first is None, (name, clock, first)  # no fall-back needed
        assert 0.99 < ratio <= 1.05, (name, ratio)


_KISS_TWICE = """
import json
from bench.runs.timed import timed_run
from conftest import constant_twist_sequence
from methods.registry import make_method
seq = constant_twist_sequence(n_frames=8, n_points=20000, max_range_m=60)
out = []
for threads in (2, 1):
    method = make_method("kiss-icp", {"num_threads": threads}, seq.sensor)
    fresh = method.needs_fresh_process
    result, record = timed_run(method, seq, seed=True)
    out.append([threads, fresh, record["clock"], record["cpu_process_to_thread"],
                len(result.frames)])
print(json.dumps(out))
"""


def test_kiss_icp_honours_each_runs_thread_count():
    """A one-thread kiss-icp run after a two-thread one in the same process runs in a fresh
    process (kiss-icp's first instance fixes its TBB thread count process-wide) and its work
    stays on the timed thread."""
    out = subprocess.run([sys.executable, "-c", _KISS_TWICE], capture_output=True, text=True,
                         timeout=600, cwd=ROOT / "tests",
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(
                             filter(None, (str(ROOT), str(ROOT / "tests"),
                                           os.environ.get("PYTHONPATH"))))})
    assert out.returncode == 0, out.stderr[-3000:]
    (t2, fresh2, clock2, _, n2), (t1, fresh1, clock1, ratio1, n1) = json.loads(
        out.stdout.splitlines()[-1])
    assert (t2, fresh2, clock2) == (2, False, "wall")
    assert (t1, fresh1, clock1) == (1, True, "cpu")
    assert ratio1 <= 1.05 and n1 == n2 == 8


_NUMBA_FIRST = """
import json, sys
import numpy as np  # NumPy (and its BLAS) and kiss-icp loaded before bench, too
import kiss_icp.pipeline
import numba


@numba.njit(parallel=True)
def total(x):
    s = 0.0
    for i in numba.prange(x.shape[0]):
        s += x[i]
    return s


assert total(np.ones(1000)) == 1000.0  # numba's thread pool now runs, at its default size
pool = numba.config.NUMBA_NUM_THREADS
from bench.api import run_method
from bench.runs.folders import read_run
out = {}
for method in ("doppler", "doppler-ego"):
    run_dir = f"{sys.argv[2]}/{method}"
    run_method(method, sys.argv[1], seed=False, out=run_dir, params={})
    record = read_run(__import__("pathlib").Path(run_dir))
    out[method] = {"frames": record.result.frames, "threads": numba.get_num_threads()}
@numba.njit
def late(x):  # numba reads its configuration again at every compilation
    return x + 1
out["late"] = late(1)
# the process executor spawns its workers here (a fork would copy the running pool)
from bench.runs.executors import execute, start_method
from bench.runs.job import Job
from bench.runs.plan import plan
jobs = plan([Job(store=__import__("pathlib").Path(sys.argv[1]), method="doppler", seed=None,
                 out_root=__import__("pathlib").Path(sys.argv[2]) / "process")])
outcomes = execute(jobs, "process", 1, True, lambda *a: None, lambda o: None)
out["start"] = start_method()
out["process"] = [o.status for o in outcomes]
out["pool"] = pool
out["env"] = __import__("os").environ.get("NUMBA_NUM_THREADS")
print(json.dumps(out))
"""


def test_numba_imported_and_running_before_bench_is_limited_at_run_time(tmp_path):
    """A notebook that imported NumPy, kiss-icp and numba, compiled and ran a parallel numba
    function before importing ``bench``: ``doppler`` and ``doppler-ego`` run through the API
    (no "Cannot set NUMBA_NUM_THREADS ... once the threads have been launched"), numba is
    limited to one thread at run time, and a later compilation still works; the process
    executor spawns its worker instead of forking the running pool. In a fresh interpreter."""
    from loaders.store import write_store

    store = write_store(constant_twist_sequence(n_frames=12, n_points=800),
                        tmp_path / "twelve.h5")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    done = subprocess.run([sys.executable, "-c", _NUMBA_FIRST, str(store), str(tmp_path)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env={**env, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.splitlines()[-1])
    assert out["pool"] == (os.cpu_count() or 1) and out["env"] is None  # left as launched
    for method in ("doppler", "doppler-ego"):
        assert out[method] == {"frames": 12, "threads": 1}
    assert out["late"] == 2
    assert out["start"] == "spawn" and out["process"] == ["done"]


def test_a_users_setting_of_one_is_no_override_and_a_numba_limited_at_run_time_records_one(
        monkeypatch):
    """``overridden_settings`` keeps only values the pinning changed (a user's 1 is not one);
    with numba's pool found running (limited at run time, its variable left alone) the thread
    settings still say numba runs one thread."""
    from bench import threads

    monkeypatch.setattr(threads, "overridden_settings", {})
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    threads.pin_threads()
    assert threads.overridden_settings == {"MKL_NUM_THREADS": "3"}
    assert os.environ["MKL_NUM_THREADS"] == "1"
    monkeypatch.setattr(threads, "_numba_limited_at_run_time", [True])
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    assert threads.thread_settings()["NUMBA_NUM_THREADS"] == "1"
