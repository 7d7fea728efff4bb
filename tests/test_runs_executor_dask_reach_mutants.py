"""bench/runs/executor_dask.py's ``run_dask`` in process: on a dask.distributed cluster of
worker threads (``processes=False``: it starts in a fraction of a second, where the LocalCluster
of worker processes ``run_dask`` asks for takes seconds), with a stand-in for ``run_job`` so
that each job's work, progress and failure is the test's. What it pins: every job's outcome
returned in the jobs' order, a job that raises reported as a failure and recorded, progress
reported per job, the ``force`` flag and the environment handed to the tasks, the cluster
closed at the end (no orphan workers), a job over its timeout ended and recorded, and Ctrl-C
recording every unfinished job (the mutation run of tools/mutate.py over ``run_dask``, which
the CLI tests reach only in a subprocess)."""

from __future__ import annotations

import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import dask
import distributed
import pytest

from bench.runs import executor_dask as ex
from bench.runs.job import Job, JobOutcome
from loaders.errors import DataError
from methods.timing import TIMING_LOCK_ENV

#: the real LocalCluster (the tests replace distributed's with ``Clusters``)
LOCAL_CLUSTER = distributed.LocalCluster
#: what the stand-in for ``_exit_worker`` did, and the event it sets (module level: dask
#: pickles the function it runs on the workers)
ENDED: list = []
RELEASE = threading.Event()


def _end_worker() -> None:
    """Stands in for os._exit on a worker: records it and releases a hanging job."""
    ENDED.append(True)
    RELEASE.set()


def _jobs(tmp_path: Path, names) -> list[Job]:
    return [Job(tmp_path / "s.h5", "doppler", None, tmp_path, label=n,
                run_dir_override=tmp_path / n) for n in names]


def _failed(tmp_path: Path, name: str) -> dict:
    return json.loads((tmp_path / name / "failed.json").read_text())


class Clusters:
    """Stands in for distributed.LocalCluster: records what ``run_dask`` asked for (and the
    scheduler's allowed failures at that moment), starts ``n_workers`` worker threads instead
    of processes, and keeps the clusters to check they were closed."""

    def __init__(self, n_workers: int):
        self.n_workers, self.asked, self.made = n_workers, [], []

    def __call__(self, **kw):
        self.asked.append((kw, dask.config.get("distributed.scheduler.allowed-failures")))
        cluster = LOCAL_CLUSTER(n_workers=self.n_workers, threads_per_worker=1,
                                           processes=False, dashboard_address=None)
        self.made.append(cluster)
        return cluster


class Work:
    """Stands in for ``run_job`` on the workers: ``plan[label]`` says what a job does
    ("ok": two progress reports then done; "slow-ok": the same after a pause; "raise": fails
    with an error; "hang": waits until released), and it records the jobs, the ``force``
    flag and the environment the task set."""

    def __init__(self, plan: dict[str, str]):
        self.plan, self.calls, self.env = plan, [], []
        self.lock = threading.Lock()

    def __call__(self, job, force, progress):
        import os

        with self.lock:
            self.calls.append((job.label, force))
            self.env.append(os.environ.get("MREACH_TASK_VAR"))
        what = self.plan[job.label]
        if what == "hang":
            RELEASE.wait(10.0)
            return JobOutcome(job, "done", "released")
        if what == "slow-ok":
            time.sleep(0.4)
        if what == "raise":
            raise RuntimeError(f"boom in {job.label}")
        progress(1, 2)
        progress(2, 2)
        time.sleep(0.15)  # the progress events reach the client before the result
        return JobOutcome(job, "done", f"ran {job.label}", frames=2)


@pytest.fixture(autouse=True)
def offload_pool(monkeypatch):
    """A fresh pool for dask's offload thread (a module global of distributed.utils): in a
    process forked after dask ran (mutmut forks each mutant's test run from one that ran the
    tests), the global pool counts a thread that does not exist there, and a cluster started
    in it waits forever for work sent to that thread."""
    import distributed.utils

    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="Dask-Offload")
    monkeypatch.setattr(distributed.utils, "_offload_executor", pool)
    yield
    pool.shutdown(wait=True)


@pytest.fixture()
def lock_env(monkeypatch, tmp_path):
    monkeypatch.setenv(TIMING_LOCK_ENV, str(tmp_path / "timing.lock"))
    monkeypatch.delenv("MREACH_TASK_VAR", raising=False)
    monkeypatch.setattr(ex, "_exit_worker", _end_worker)
    ENDED.clear()
    RELEASE.clear()
    yield
    RELEASE.set()  # no worker thread left waiting


class Flight:
    """Counts the jobs in flight (submitted to dask and not yet handed to ``finish``) and
    records how long each wait for a finished job may last."""

    def __init__(self, monkeypatch):
        self.submitted, self.finished, self.most, self.waits = 0, [], 0, []
        submit, wait = distributed.Client.submit, distributed.wait

        def counting(client, *args, **kw):
            self.submitted += 1
            self.most = max(self.most, self.submitted - len(self.finished))
            return submit(client, *args, **kw)

        def timed_wait(futures, timeout=None, return_when="ALL_COMPLETED"):
            self.waits.append(timeout)
            return wait(futures, timeout=timeout, return_when=return_when)

        monkeypatch.setattr(distributed.Client, "submit", counting)
        monkeypatch.setattr(distributed, "wait", timed_wait)


def _run(jobs, work, monkeypatch, workers=2, force=False, timeout=None, scheduler=None,
         report=None):
    monkeypatch.setattr(ex, "run_job", work)
    flight = Flight(monkeypatch)
    reports = []
    report = report or (lambda job, done, total: reports.append((job.label, done, total)))
    outcomes = ex.run_dask(jobs, workers, force, report, flight.finished.append, timeout,
                           scheduler, {"MREACH_TASK_VAR": "set-by-the-task"})
    _run.most, _run.waits = flight.most, flight.waits
    # it polls at least every half second: progress, timeouts and Ctrl-C are seen that soon
    assert all(w is not None and w <= 0.5 for w in flight.waits), flight.waits
    return outcomes, reports, flight.finished


def test_every_job_is_returned_in_order_a_raising_job_fails_and_the_cluster_is_closed(
        monkeypatch, tmp_path, lock_env):
    clusters = Clusters(n_workers=2)
    monkeypatch.setattr(distributed, "LocalCluster", clusters)
    # the first job finishes last: the outcomes still come back in the jobs' order
    jobs = _jobs(tmp_path, ["a", "b", "c"])
    work = Work({"a": "slow-ok", "b": "raise", "c": "ok"})
    outcomes, reports, finished = _run(jobs, work, monkeypatch, workers=3, force=True)
    assert [o.job for o in outcomes] == jobs
    assert [o.status for o in outcomes] == ["done", "failed", "done"]
    assert outcomes[0].message == "ran a" and outcomes[2].message == "ran c"
    assert outcomes[1].message == "dask: RuntimeError: boom in b"
    failed = _failed(tmp_path, "b")
    assert (failed["status"], failed["error"]) == ("crashed", "dask: RuntimeError: boom in b")
    assert not (tmp_path / "a").exists() and not (tmp_path / "c").exists()
    # each outcome handed to ``finish`` once, as it came
    assert sorted(o.job.label for o in finished) == ["a", "b", "c"]
    assert {o.job.label: o for o in finished} == {o.job.label: o for o in outcomes}
    # every job ran once, with the force flag and the environment given
    assert sorted(work.calls) == [("a", True), ("b", True), ("c", True)]
    assert work.env == ["set-by-the-task"] * 3
    # progress: the frames of each job that reported any (the start event is no report)
    for label in ("a", "c"):
        assert [(d, t) for n, d, t in reports if n == label] == [(1, 2), (2, 2)]
    assert all(t > 0 for _, _, t in reports) and "b" not in {n for n, _, _ in reports}
    # a LocalCluster of the asked workers, one thread each, worker processes, no dashboard,
    # quiet logs, a scheduler that does not retry a job whose worker died; closed at the end
    assert len(clusters.asked) == 1
    kw, allowed = clusters.asked[0]
    import logging
    assert kw == {"n_workers": 3, "threads_per_worker": 1, "processes": True,
                  "dashboard_address": None, "silence_logs": logging.CRITICAL}
    assert allowed == 0
    assert clusters.made[0].status.name == "closed"
    assert _run.most == 2  # no more jobs in flight than worker threads
    assert _run.waits  # it waited for the jobs through distributed.wait


def test_no_worker_asked_is_still_one_worker(monkeypatch, tmp_path,
                                                                     lock_env):
    clusters = Clusters(n_workers=1)
    monkeypatch.setattr(distributed, "LocalCluster", clusters)
    jobs = _jobs(tmp_path, ["a", "b"])
    work = Work({"a": "ok", "b": "ok"})
    outcomes, _, finished = _run(jobs, work, monkeypatch, workers=0)
    assert clusters.asked[0][0]["n_workers"] == 1
    assert [o.status for o in outcomes] == ["done", "done"] and len(finished) == 2
    assert sorted(work.calls) == [("a", False), ("b", False)]
    assert _run.most == 1  # one worker thread: one job in flight
    assert clusters.made[0].status.name == "closed"


def test_no_job_is_an_empty_list(monkeypatch, tmp_path, lock_env):
    clusters = Clusters(n_workers=1)
    monkeypatch.setattr(distributed, "LocalCluster", clusters)
    outcomes, reports, finished = _run([], Work({}), monkeypatch)
    assert outcomes == [] and reports == [] and finished == []
    assert clusters.made[0].status.name == "closed"


@pytest.fixture()
def cluster():
    """An existing cluster (``--scheduler``): two worker threads."""
    with LOCAL_CLUSTER(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as c:
        yield c


def test_a_job_over_its_timeout_is_ended_and_the_others_finish(monkeypatch, tmp_path,
                                                               lock_env, cluster):
    monkeypatch.setattr(distributed, "LocalCluster", _no_local_cluster)
    jobs = _jobs(tmp_path, ["stuck", "a", "b"])
    work = Work({"stuck": "hang", "a": "ok", "b": "ok"})
    t0 = time.monotonic()
    outcomes, reports, _ = _run(jobs, work, monkeypatch, timeout=1.0,
                                scheduler=cluster.scheduler_address)
    assert time.monotonic() - t0 < 8.0
    message = "timeout: ended after 1 s (--job-timeout)"
    assert [(o.status, o.message) for o in outcomes] == [
        ("failed", message), ("done", "ran a"), ("done", "ran b")]
    assert ENDED == [True]  # its worker was ended
    failed = _failed(tmp_path, "stuck")
    assert (failed["status"], failed["error"]) == ("timeout", message)
    assert {n for n, _, _ in reports} == {"a", "b"}


def _no_local_cluster(**kw):
    raise AssertionError("no LocalCluster with --scheduler")


def test_without_a_timeout_a_slow_job_is_waited_for(monkeypatch, tmp_path, lock_env,
                                                    cluster):
    monkeypatch.setattr(distributed, "LocalCluster", _no_local_cluster)
    jobs = _jobs(tmp_path, ["slow"])
    outcomes, reports, _ = _run(jobs, Work({"slow": "slow-ok"}), monkeypatch,
                                scheduler=cluster.scheduler_address)
    assert [(o.status, o.message) for o in outcomes] == [("done", "ran slow")]
    assert reports == [("slow", 1, 2), ("slow", 2, 2)]


def _interrupt_on_second_job(job, done, total):
    if job.label == "b":
        raise KeyboardInterrupt


def test_ctrl_c_records_every_unfinished_job_and_closes_the_local_cluster(monkeypatch,
                                                                         tmp_path, lock_env):
    clusters = Clusters(n_workers=1)
    monkeypatch.setattr(distributed, "LocalCluster", clusters)
    jobs = _jobs(tmp_path, ["a", "b", "c"])
    work = Work({"a": "ok", "b": "ok", "c": "ok"})
    with pytest.raises(KeyboardInterrupt):
        _run(jobs, work, monkeypatch, workers=1, report=_interrupt_on_second_job)
    assert clusters.made[0].status.name == "closed"
    assert ENDED == []  # the LocalCluster's workers end with it: none is ended one by one
    assert not (tmp_path / "a").exists()  # it finished before Ctrl-C
    for label in ("b", "c"):
        failed = _failed(tmp_path, label)
        assert (failed["status"], failed["error"]) == ("interrupted", ex.INTERRUPTED)


def test_ctrl_c_on_a_scheduler_ends_the_running_jobs_workers(monkeypatch, tmp_path, lock_env,
                                                             cluster):
    monkeypatch.setattr(distributed, "LocalCluster", _no_local_cluster)
    jobs = _jobs(tmp_path, ["a", "b"])
    work = Work({"a": "ok", "b": "hang"})

    def report(job, done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _run(jobs, work, monkeypatch, report=report, scheduler=cluster.scheduler_address)
    assert ENDED  # the worker running the unfinished job was ended
    for label in ("a", "b"):
        failed = _failed(tmp_path, label)
        assert (failed["status"], failed["error"]) == ("interrupted", ex.INTERRUPTED)


def test_without_dask_distributed_one_error_says_what_to_install(monkeypatch, tmp_path):
    monkeypatch.setitem(__import__("sys").modules, "distributed", None)
    with pytest.raises(DataError) as caught:
        ex.run_dask(_jobs(tmp_path, ["a"]), 1, False, print, print, None, None, {})
    assert str(caught.value) == ("the dask executor needs dask.distributed: "
                                 "pip install 'doppler-bench[dask]'")
    assert caught.value.__cause__ is None and caught.value.__suppress_context__
