"""The dask executor: jobs on dask.distributed workers (a LocalCluster or an existing cluster).

- Each job is one task; workers are expected to run one task at a time (``--nthreads 1``),
  so a job's timing is not disturbed by another task in the same process.
- Progress: a task reports (frames done, total) as worker events on a topic unique to this
  call; the main thread drains them and updates the bars (per-run frames/s).
- ``job_timeout_s`` counts from the moment the task reports its start on a worker (not from
  submission, so queued jobs are not charged for waiting). A job that runs too long, or that is
  running when Ctrl-C arrives, has its worker process ended (its nanny starts a fresh one): a
  cancelled dask task would otherwise keep computing and write its folder after being
  recorded as timed out or interrupted. At most as many jobs as worker threads are submitted
  at a time, so ending a worker ends no other job.
- A worker that dies inside a job (a segfault or abort in native code) fails that job; a
  LocalCluster does not retry it on other workers.
"""

from __future__ import annotations

import contextlib
import logging
import os
import queue
import time
import uuid

from bench.runs.job import Job, JobOutcome, record_unfinished, run_job
from loaders.errors import DataError
from methods.timing import TIMING_LOCK_ENV

INTERRUPTED = "interrupted by the user (Ctrl-C)"


def _dask_task(index: int, job: Job, force: bool, env: dict[str, str], topic: str
               ) -> JobOutcome:
    """Runs on a dask worker. ``env``: the pinned thread counts and the timing lock (a dask
    nanny already starts workers with OMP/MKL/OPENBLAS at 1; these fill in the rest)."""
    for var, value in env.items():
        os.environ.setdefault(var, value)
    from distributed import get_worker

    worker = get_worker()
    last = [0.0]

    def progress(done: int, total: int) -> None:
        now = time.monotonic()
        if done == total or now - last[0] > 0.5:
            last[0] = now
            worker.log_event(topic, (index, done, total))

    worker.log_event(topic, (index, 0, 0))  # started: the timeout counts from here
    return run_job(job, force, progress)


def _exit_worker() -> None:
    os._exit(1)  # runs on a worker: its nanny starts a fresh one


def _end_tasks(client, futures) -> None:
    """Cancel ``futures`` and end the worker processes running them (a cancelled task that is
    already running would otherwise go on computing and write its folder)."""
    keys = {f.key for f in futures}
    addresses = []
    with contextlib.suppress(Exception):  # best effort: the scheduler may be gone
        addresses = [addr for addr, running in client.processing().items()
                     if keys & set(running)]
    for fut in futures:
        fut.cancel()
    if addresses:
        with contextlib.suppress(Exception):  # the connection breaks as the worker exits
            client.run(_exit_worker, workers=addresses)


def _failure_message(err: BaseException) -> str:
    if type(err).__name__ == "KilledWorker":
        return ("crashed: the dask worker died while running this job (a crash inside a "
                "native library?)")
    return f"dask: {type(err).__name__}: {err}"


def _client(Client, scheduler: str | None, cluster):
    """A client of the LocalCluster, or of the scheduler at ``scheduler`` (a bad address or
    one nobody answers at: one DataError naming --scheduler)."""
    if scheduler is None:
        return Client(cluster)
    try:
        return Client(scheduler, timeout="10s")
    except (ValueError, OSError, TimeoutError) as err:
        raise DataError(f"--scheduler {scheduler!r}: no dask scheduler answers there "
                        f"({type(err).__name__}: {err}); expected the address of a running "
                        "`dask scheduler`, e.g. tcp://HOST:8786") from None


def run_dask(jobs: list[Job], workers: int, force: bool, report, finish,
             job_timeout_s: float | None, scheduler: str | None, env: dict[str, str]
             ) -> list[JobOutcome]:
    try:
        import dask
        from distributed import Client, LocalCluster, wait
    except ImportError:
        raise DataError("the dask executor needs dask.distributed: "
                        "pip install 'doppler-bench[dask]'") from None
    env = {**env, TIMING_LOCK_ENV: os.environ[TIMING_LOCK_ENV]}
    cluster = None
    if scheduler is None:
        # the scheduler runs in this process: a job whose worker dies fails at once
        with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
            cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1,
                                   processes=True, dashboard_address=None,
                                   silence_logs=logging.CRITICAL)
    results: dict[int, JobOutcome] = {}
    events: queue.SimpleQueue = queue.SimpleQueue()
    topic = f"doppler-bench-progress-{uuid.uuid4().hex}"

    def done(index: int, outcome: JobOutcome) -> None:
        results[index] = outcome
        finish(outcome)

    try:
        with _client(Client, scheduler, cluster) as client:
            client.subscribe_topic(topic, lambda event: events.put(event[1]))
            # no more jobs in flight than worker threads: a worker holds only the job it runs,
            # so ending it for a timeout or Ctrl-C ends no other job
            capacity = max(1, sum(client.nthreads().values()))
            pending = list(range(len(jobs)))
            futures: dict = {}
            started: dict[int, float] = {}
            remaining: set = set()
            try:
                while pending or remaining:
                    while pending and len(remaining) < capacity:
                        index = pending.pop(0)
                        fut = client.submit(_dask_task, index, jobs[index], force, env, topic,
                                            pure=False)
                        futures[fut] = index
                        remaining.add(fut)
                    try:
                        finished, remaining = wait(list(remaining), timeout=0.5,
                                                   return_when="FIRST_COMPLETED")
                    except TimeoutError:  # nothing finished within the poll interval
                        finished = set()
                    while not events.empty():
                        index, n_done, total = events.get()
                        started.setdefault(index, time.monotonic())
                        if total and index not in results:
                            report(jobs[index], n_done, total)
                    for fut in finished:
                        index = futures[fut]
                        try:
                            outcome = fut.result()
                        except Exception as err:  # noqa: BLE001 - a worker died or raised
                            outcome = JobOutcome(jobs[index], "failed", _failure_message(err))
                            record_unfinished(jobs[index], outcome.message, "crashed")
                        done(index, outcome)
                    if job_timeout_s and remaining:
                        remaining -= _timeouts(client, futures, remaining, started,
                                               job_timeout_s, jobs, done)
            except KeyboardInterrupt:
                if cluster is None:  # a LocalCluster's workers end with it below
                    _end_tasks(client, [f for f in futures if futures[f] not in results])
                raise
    except KeyboardInterrupt:
        if cluster is not None:
            cluster.close()
        for index, job in enumerate(jobs):  # recorded once no worker can write any more
            if index not in results:
                record_unfinished(job, INTERRUPTED, "interrupted")
                results[index] = JobOutcome(job, "interrupted", INTERRUPTED)
        raise
    finally:
        if cluster is not None:
            cluster.close()
    return [results[i] for i in range(len(jobs)) if i in results]


def _timeouts(client, futures, remaining, started, job_timeout_s, jobs, done) -> set:
    """End and record the jobs that have run longer than the timeout (``started``: when each
    job's task reported its start)."""
    now = time.monotonic()
    late = {f for f in remaining
            if futures[f] in started and now - started[futures[f]] > job_timeout_s}
    if late:
        _end_tasks(client, late)
        for fut in late:
            index = futures[fut]
            message = f"timeout: ended after {job_timeout_s:g} s (--job-timeout)"
            record_unfinished(jobs[index], message, "timeout")
            done(index, JobOutcome(jobs[index], "failed", message))
    return late
