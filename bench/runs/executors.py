"""Executors: where jobs run. Metrics are the same whichever runs them (timing apart).

- ``local``: in this process, one after another (for debugging; a crash in a native library
  ends the command).
- ``process`` (default): every job in its own worker process, at most ``workers`` at once, so a
  segfault or abort inside a native library fails that job only. A worker is forked from the
  main process, which has imported the harness, the methods and their libraries while planning,
  so it starts at once (a spawned worker imported them again: about 1.2 s of CPU before its
  first frame); it is spawned instead where forking is unsafe (``start_method``).
  Workers die with the main process (PR_SET_PDEATHSIG and a parent watchdog), ignore Ctrl-C
  (the main process ends them and records their runs as interrupted), and a job that runs
  longer than ``job_timeout_s`` is killed and recorded as failed.
- ``dask``: dask.distributed, on an existing cluster (``scheduler`` address) or a LocalCluster
  of ``workers`` single-threaded worker processes (``bench.runs.executor_dask``).

In every mode the BLAS/OpenMP/numba thread counts are pinned (``job_environment``) and every timed
section holds a machine-wide lock (``methods.timing``), so no two timed sections overlap and a
reported time is the method's own.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from multiprocessing import get_all_start_methods, get_context
from multiprocessing.connection import wait as wait_for

from bench.runs.folders import is_finished
from bench.runs.job import Job, JobOutcome, expected_cost, record_unfinished, run_job
from bench.threads import numba_pool_launched, pin_threads
from loaders.errors import DataError
from methods.timing import DEFAULT_TIMING_LOCK, TIMING_LOCK_ENV

EXECUTORS = ("local", "process", "dask")
TIMING_LOCK = DEFAULT_TIMING_LOCK

Report = Callable[[Job, int, int], None]   # (job, frames done, frames total)
Finish = Callable[[JobOutcome], None]


def job_environment() -> dict[str, str]:
    """Pin library thread counts (``bench.threads``) and name the timing lock; the values are
    inherited by worker processes and recorded in each run's meta.json."""
    threads = pin_threads()
    os.environ.setdefault(TIMING_LOCK_ENV, TIMING_LOCK)
    return threads


def execute(jobs: list[Job], executor: str, workers: int, force: bool, report: Report,
            finish: Finish, job_timeout_s: float | None = None,
            scheduler: str | None = None) -> list[JobOutcome]:
    """Run ``jobs`` with ``executor``; ``finish`` is called once per job as it ends. Ctrl-C
    ends the workers, records the runs in flight as interrupted and re-raises."""
    job_environment()
    if not force:  # planned runs already finished with the same inputs: no worker needed
        done = {i for i, j in enumerate(jobs) if j.run_key and j.run_dir_override
                and is_finished(j.run_dir_override, j.run_key)}
        if done:
            skipped = {i: JobOutcome(jobs[i], "skipped", str(jobs[i].run_dir_override),
                                     run_dir=jobs[i].run_dir_override) for i in done}
            for outcome in skipped.values():
                finish(outcome)
            rest = [j for i, j in enumerate(jobs) if i not in done]
            ran = iter(execute(rest, executor, workers, force, report, finish,
                               job_timeout_s, scheduler) if rest else [])
            return [skipped[i] if i in done else next(ran) for i in range(len(jobs))]
    if executor == "local":
        return _run_local(jobs, force, report, finish)
    if executor == "process":
        return _run_processes(jobs, workers, force, report, finish, job_timeout_s)
    if executor == "dask":
        from bench.runs.executor_dask import run_dask

        return run_dask(jobs, workers, force, report, finish, job_timeout_s, scheduler,
                        job_environment())
    raise DataError(f"unknown executor {executor!r}; choose from {', '.join(EXECUTORS)}")


def _run_local(jobs, force, report, finish) -> list[JobOutcome]:
    outcomes = []
    for job in jobs:
        try:
            outcome = run_job(job, force, lambda d, t, j=job: report(j, d, t))
        except KeyboardInterrupt:
            record_unfinished(job, "interrupted by the user (Ctrl-C)", "interrupted")
            finish(JobOutcome(job, "interrupted", "interrupted by the user (Ctrl-C)"))
            raise
        outcomes.append(outcome)
        finish(outcome)
    return outcomes


# ---- process executor ---------------------------------------------------------------------

def _die_with_parent(parent_pid: int) -> None:
    """End this worker when the main process dies, even by SIGKILL."""
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG

    def watch() -> None:
        while True:
            if os.getppid() != parent_pid:
                os._exit(1)
            time.sleep(0.5)

    threading.Thread(target=watch, daemon=True).start()
    if os.getppid() != parent_pid:  # died before the guard was set
        os._exit(1)


def start_method() -> str:
    """How a worker process starts: "fork" (the worker has everything the main process
    imported), unless this platform cannot fork or numba's thread pool already runs in this
    process (a notebook that ran parallel numba code: its OpenMP / TBB layers do not survive a
    fork), then "spawn" (a fresh interpreter that imports what the job needs)."""
    if "fork" in get_all_start_methods() and not numba_pool_launched():
        return "fork"
    return "spawn"


def _worker(job: Job, force: bool, conn, parent_pid: int, forked: bool = False) -> None:
    """One job in its own process; reports on its own pipe (no lock shared with other workers,
    so a worker that crashes mid-message cannot block the others)."""
    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the main process decides what Ctrl-C ends
    last = [0.0]

    def progress(done: int, total: int) -> None:
        now = time.monotonic()
        if done == total or now - last[0] > 0.2:
            last[0] = now
            conn.send(("progress", done, total))

    conn.send(("outcome", run_job(job, force, progress)))
    conn.close()
    # the run is written and reported: skip the interpreter's teardown of numba, LLVM and
    # h5py (about 0.4 s a job), which only frees memory the exit frees anyway. A forked
    # worker's output buffers are copies of the main process's (its unflushed progress
    # display): flushing them would print that twice, and the worker prints nothing itself
    if not forked:
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(0)


def _exit_reason(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"worker killed by signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"worker killed by signal {-exitcode}"
    return f"worker exited with code {exitcode} before reporting"


def _run_processes(jobs, workers, force, report, finish, job_timeout_s) -> list[JobOutcome]:
    method = start_method()
    ctx = get_context(method)
    if method == "fork":  # nothing of this process's pending output is copied into a worker
        sys.stdout.flush()
        sys.stderr.flush()
    # longest jobs first (iterative methods on large stores), so workers finish together
    pending = sorted(range(len(jobs)), key=lambda i: expected_cost(jobs[i]), reverse=True)
    running: dict[int, tuple] = {}   # index -> (process, start time, receiving end)
    results: dict[int, JobOutcome] = {}

    def done(index: int, outcome: JobOutcome) -> None:
        results[index] = outcome
        finish(outcome)

    def drain(timeout: float) -> None:
        conns = {entry[2]: index for index, entry in running.items()}
        for conn in wait_for(list(conns), timeout=timeout):
            index = conns[conn]
            try:
                while conn.poll():
                    kind, *rest = conn.recv()
                    if kind == "progress":
                        report(jobs[index], *rest)
                    elif index not in results:
                        done(index, rest[0])
            except (EOFError, OSError):
                pass  # the worker ended; its exit is handled below

    try:
        while pending or running:
            while pending and len(running) < max(1, workers):
                index = pending.pop(0)
                receiver, sender = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_worker, daemon=True,
                                   args=(jobs[index], force, sender, os.getpid(),
                                         method == "fork"))
                # the worker starts with SIGINT blocked (inherited through fork or exec), so a
                # Ctrl-C during its start-up cannot print a traceback there; here it is only
                # deferred until the worker is registered, never lost
                mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
                try:
                    proc.start()
                    running[index] = (proc, time.monotonic(), receiver)
                finally:
                    signal.pthread_sigmask(signal.SIG_SETMASK, mask)
                sender.close()
            drain(0.1)
            for index, (proc, start, receiver) in list(running.items()):
                if proc.is_alive():
                    if job_timeout_s and time.monotonic() - start > job_timeout_s:
                        proc.kill()
                        proc.join()
                        message = f"timeout: ended after {job_timeout_s:g} s (--job-timeout)"
                        record_unfinished(jobs[index], message, "timeout")
                        done(index, JobOutcome(jobs[index], "failed", message))
                        receiver.close()
                        del running[index]
                    continue
                proc.join()
                drain(0.0)
                if index not in results:
                    message = _exit_reason(proc.exitcode)
                    record_unfinished(jobs[index], message, "crashed")
                    done(index, JobOutcome(jobs[index], "failed", message))
                receiver.close()
                del running[index]
    except KeyboardInterrupt:
        for proc, _, _ in running.values():
            proc.kill()
        for index, (proc, _, _) in running.items():
            proc.join(timeout=5)
            message = "interrupted by the user (Ctrl-C)"
            record_unfinished(jobs[index], message, "interrupted")
            results[index] = JobOutcome(jobs[index], "interrupted", message)
        raise
    return [results[i] for i in range(len(jobs)) if i in results]
