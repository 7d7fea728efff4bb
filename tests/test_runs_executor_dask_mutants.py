"""bench/runs/executor_dask.py's helpers, in process with stand-ins for dask's client and
worker (a LocalCluster takes far longer to start than a unit test may; ``run_dask`` itself is
exercised through the CLI by tests/test_executors.py): the client of --scheduler and its one
error, the failure message of a task, the task's progress events, ending the tasks of a timeout
(the mutation run of tools/mutate.py over bench/runs/executor_dask.py)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from types import SimpleNamespace

import pytest

from bench.runs import executor_dask as ex
from bench.runs.job import Job, JobOutcome
from loaders.errors import DataError


class FakeClient:
    """Records how it was made; raises ``error`` when given one."""

    def __init__(self, target, timeout=None, error=None):
        if error is not None:
            raise error
        self.target, self.timeout = target, timeout


def test_a_local_cluster_is_joined_without_a_timeout():
    cluster = object()
    client = ex._client(FakeClient, None, cluster)
    assert client.target is cluster and client.timeout is None


def test_a_scheduler_is_joined_with_a_timeout():
    client = ex._client(FakeClient, "tcp://host:8786", object())
    assert client.target == "tcp://host:8786" and client.timeout == "10s"


@pytest.mark.parametrize("error", [ValueError("bad address"), OSError("refused"),
                                   TimeoutError("no answer")])
def test_a_scheduler_nobody_answers_at_is_one_error_naming_the_option(error):
    def failing(target, timeout=None):
        return FakeClient(target, timeout, error)

    with pytest.raises(DataError) as caught:
        ex._client(failing, "tcp://nowhere:1", None)
    assert str(caught.value) == (
        f"--scheduler 'tcp://nowhere:1': no dask scheduler answers there "
        f"({type(error).__name__}: {error}); expected the address of a running "
        "`dask scheduler`, e.g. tcp://HOST:8786")
    assert caught.value.__cause__ is None and caught.value.__suppress_context__


def test_another_error_of_the_client_is_not_hidden():
    def failing(target, timeout=None):
        raise KeyError("x")

    with pytest.raises(KeyError):
        ex._client(failing, "tcp://h:1", None)


def test_the_failure_message_of_a_task():
    class KilledWorker(Exception):
        pass

    assert ex._failure_message(KilledWorker("w")) == (
        "crashed: the dask worker died while running this job (a crash inside a native "
        "library?)")
    assert ex._failure_message(ValueError("bad")) == "dask: ValueError: bad"
    assert ex.INTERRUPTED == "interrupted by the user (Ctrl-C)"


class FakeWorker:
    def __init__(self):
        self.events = []

    def log_event(self, topic, event):
        self.events.append((topic, event))


def test_a_task_reports_its_start_and_progress_and_runs_the_job(monkeypatch, tmp_path):
    import distributed

    worker = FakeWorker()
    monkeypatch.setattr(distributed, "get_worker", lambda: worker)
    clock = iter([100.0, 100.1, 100.7, 100.8, 101.0])
    monkeypatch.setattr(ex, "time", SimpleNamespace(monotonic=lambda: next(clock)))
    calls = []

    def fake_run(job, force, progress):
        calls.append((job, force))
        for done in (1, 2, 3, 4, 5):
            progress(done, 5)
        return "outcome"

    monkeypatch.setattr(ex, "run_job", fake_run)
    monkeypatch.delenv("MRUNS_TEST_VAR", raising=False)
    monkeypatch.setenv("MRUNS_KEPT", "mine")
    job = Job(tmp_path / "s.h5", "doppler", None, tmp_path)
    got = ex._dask_task(3, job, True, {"MRUNS_TEST_VAR": "1", "MRUNS_KEPT": "theirs"}, "t")
    assert got == "outcome" and calls == [(job, True)]
    assert os.environ["MRUNS_TEST_VAR"] == "1" and os.environ["MRUNS_KEPT"] == "mine"
    # the start, then at most one event per half second, and always the last frame
    assert worker.events == [("t", (3, 0, 0)), ("t", (3, 1, 5)), ("t", (3, 3, 5)),
                             ("t", (3, 5, 5))]
    # exactly half a second after the last event is not yet more than half a second
    worker.events.clear()
    clock = iter([200.0, 200.5, 200.75, 201.0, 201.1])
    ex._dask_task(1, job, False, {}, "u")
    assert worker.events == [("u", (1, 0, 0)), ("u", (1, 1, 5)), ("u", (1, 3, 5)),
                             ("u", (1, 5, 5))]


class FakeFuture:
    def __init__(self, key):
        self.key, self.cancelled = key, False

    def cancel(self):
        self.cancelled = True

    def __hash__(self):
        return hash(self.key)


class FakeDaskClient:
    def __init__(self, processing, fail=False):
        self._processing, self.fail, self.ran = processing, fail, []

    def processing(self):
        if self.fail:
            raise OSError("scheduler gone")
        return self._processing

    def run(self, fn, workers):
        self.ran.append((fn, workers))
        raise OSError("the connection breaks as the worker exits")


def test_ending_tasks_ends_only_the_workers_running_them():
    a, b = FakeFuture("a"), FakeFuture("b")
    client = FakeDaskClient({"w1": ["a"], "w2": ["c"], "w3": ["b", "d"]})
    ex._end_tasks(client, [a, b])
    assert a.cancelled and b.cancelled
    assert client.ran == [(ex._exit_worker, ["w1", "w3"])]
    idle = FakeDaskClient({"w2": ["c"]})
    ex._end_tasks(idle, [FakeFuture("a")])
    assert idle.ran == []
    gone = FakeDaskClient({}, fail=True)
    f = FakeFuture("a")
    ex._end_tasks(gone, [f])  # the scheduler is gone: still cancelled, nothing raised
    assert f.cancelled and gone.ran == []


def test_a_job_over_its_timeout_is_ended_and_recorded(monkeypatch, tmp_path):
    monkeypatch.setattr(ex, "time", SimpleNamespace(monotonic=lambda: 1000.0))
    jobs = [Job(tmp_path / "s.h5", "doppler", None, tmp_path, run_dir_override=tmp_path / n)
            for n in ("late", "early", "queued")]
    futs = [FakeFuture(str(i)) for i in range(3)]
    futures = {f: i for i, f in enumerate(futs)}
    started = {0: 1000.0 - 30.5, 1: 1000.0 - 29.0}  # the third has not started
    done = []
    client = FakeDaskClient({"w": ["0"]})
    late = ex._timeouts(client, futures, set(futs), started, 30.0, jobs,
                        lambda i, o: done.append((i, o)))
    assert late == {futs[0]} and futs[0].cancelled and not futs[1].cancelled
    message = "timeout: ended after 30 s (--job-timeout)"
    assert done == [(0, JobOutcome(jobs[0], "failed", message))]
    assert client.ran == [(ex._exit_worker, ["w"])]  # its worker ended
    failed = json.loads(Path(tmp_path / "late" / "failed.json").read_text())
    assert (failed["status"], failed["error"]) == ("timeout", message)
    assert not (tmp_path / "early").exists()
    # exactly the timeout is not over it
    assert ex._timeouts(client, futures, {futs[1]}, {1: 970.0}, 30.0, jobs,
                        lambda i, o: done.append(i)) == set()
    assert len(done) == 1
