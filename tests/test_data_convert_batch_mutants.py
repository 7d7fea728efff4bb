"""`bench convert dataset` in this process (the local executor): what is planned, skipped,
refused and reported, the progress each job sends, and one job's failure. Written against the
surviving mutants of ``make mutate`` on bench/data/convert_batch.py."""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import queue
import re
import signal
import time
import types
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import yaml
from rich.console import Console

from bench.data import convert_batch
from bench.data.convert_batch import (
    ConvertJob,
    convert_datasets,
    convert_one,
    plan_conversions,
    run_conversions,
    stored_key,
)
from bench.data.datasets import DatasetConfig
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import StoreSequence, write_store


def _frames(folder, n=4, points=20, seed=0):
    """Raw npy frames (points and Doppler) and a GT file of ``n`` poses 1 m apart in x."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    pts = []
    for i in range(n):
        pts.append(rng.uniform(-20, 20, (points, 3)))
        np.save(folder / f"frame_{i:03d}.npy", pts[-1])
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(0, 2, points))
    (folder / "gt.txt").write_text("".join(f"{0.1 * i:.1f} {i} 0 0 0 0 0 1\n" for i in range(n)))
    return pts


def _config(tmp_path, name, raw, gt=True) -> str:
    options = {"period_s": 0.1, **({"gt": "gt.txt"} if gt else {})}
    cfg = {"name": name, "display_name": name, "sensor_class": "Sparse 4D Radar",
           "loader": "npy-frames", "raw_dir": str(raw), "raw_files": ["frame_000.npy"],
           "options": options, "store": f"{name}.h5"}
    path = tmp_path / "configs" / f"{name}.yaml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(yaml.safe_dump(cfg))
    return str(path)


def _console():
    return Console(record=True, width=300, force_terminal=False)


def _text(console) -> str:
    return " ".join(console.export_text().split())


def test_one_sequence_is_converted_in_this_process_and_then_up_to_date(tmp_path, monkeypatch):
    pts = _frames(tmp_path / "raw")
    cfg = _config(tmp_path, "SeqA", tmp_path / "raw")

    def no_processes(*args):
        raise AssertionError("one sequence needs no worker process")

    monkeypatch.setattr(convert_batch, "_run_processes", no_processes)
    console = _console()
    assert convert_datasets([cfg], tmp_path / "data", None, None, 2, "process", False,
                            console) == 0
    store = tmp_path / "data" / "real" / "SeqA.h5"
    text = _text(console)
    assert re.search(rf"wrote {re.escape(str(store))}: 4 frames in \d+\.\d s \(\d+ frames/s\)",
                     text), text
    assert "no ground truth" not in text
    assert text.endswith("1 converted, 0 up to date, 0 failed"), text
    st = StoreSequence(store)
    try:
        assert len(st) == 4 and st.name == "SeqA"
        np.testing.assert_allclose(st.scan(2).points, pts[2], atol=1e-5)
        key = st.provenance["conversion"]["key"]
        assert st.provenance["conversion"]["config"] == "SeqA"
    finally:
        st.close()
    assert key == DatasetConfig.model_validate(yaml.safe_load(open(cfg))).conversion_key()
    assert stored_key(store) == key
    # again: nothing to do, said once, exit 0
    console = _console()
    assert convert_datasets([cfg], tmp_path / "data", None, None, 1, "local", False,
                            console) == 0
    assert _text(console) == (f"SeqA: {store} is up to date (inputs and options unchanged; "
                              "--force converts again)")


def test_out_and_raw_dir_apply_to_one_sequence(tmp_path):
    _frames(tmp_path / "elsewhere")
    cfg = _config(tmp_path, "SeqA", tmp_path / "raw_not_here")
    out = tmp_path / "mine" / "a.h5"
    console = _console()
    assert convert_datasets([cfg], tmp_path / "data", tmp_path / "elsewhere", out, 1, "local",
                            False, console) == 0
    assert out.is_file() and not (tmp_path / "data").exists()


def test_a_store_without_ground_truth_is_said_to_be_unscored(tmp_path):
    _frames(tmp_path / "raw")
    (tmp_path / "raw" / "gt.txt").unlink()
    cfg = _config(tmp_path, "NoGT", tmp_path / "raw", gt=False)
    console = _console()
    assert convert_datasets([cfg], tmp_path / "data", None, None, 1, "local", False,
                            console) == 0
    assert "NoGT.h5 (no ground truth: runs on this store are not scored): 4 frames" in \
        _text(console)


@pytest.mark.parametrize("executor", ["threads", "Local", ""])
def test_an_unknown_executor_is_refused_naming_the_choices(tmp_path, executor):
    with pytest.raises(DataError) as err:
        convert_datasets(["x"], tmp_path, None, None, 1, executor, False, _console())
    assert str(err.value) == (f"unknown executor {executor!r}; choose from local, process, "
                              "dask")


@pytest.mark.parametrize("which", ["out", "raw_dir"])
def test_out_or_raw_dir_with_several_sequences_is_refused(tmp_path, which):
    a = _config(tmp_path, "A", tmp_path / "a")
    b = _config(tmp_path, "B", tmp_path / "b")
    given = {"out": None, "raw_dir": None, which: tmp_path / "x"}
    with pytest.raises(DataError, match="^--out and --raw-dir name one sequence's files: give one "
                                        "NAME, or set each config's raw_dir$"):
        convert_datasets([a, b], tmp_path / "data", given["raw_dir"], given["out"], 1, "local",
                         False, _console())
    assert not (tmp_path / "data").exists()


def test_absent_and_incomplete_raw_data_are_skipped_with_one_line_each(tmp_path):
    _frames(tmp_path / "ok")
    _frames(tmp_path / "half")
    (tmp_path / "half" / "frame_000.npy").unlink()
    names = [_config(tmp_path, "Ok", tmp_path / "ok"), _config(tmp_path, "Half", tmp_path / "half"),
             _config(tmp_path, "Gone", tmp_path / "gone")]
    console = _console()
    assert convert_datasets(names, tmp_path / "data", None, None, 1, "local", False,
                            console) == 0
    lines = console.export_text().splitlines()
    assert f"skipped Half: raw data {tmp_path / 'half'} incomplete (missing frame_000.npy)" \
        in lines
    assert f"skipped Gone: raw data {tmp_path / 'gone'} not found" in lines
    assert lines[-1] == "1 converted, 0 up to date, 0 failed"


def test_nothing_to_convert_is_an_error_naming_the_sequences(tmp_path):
    names = [_config(tmp_path, "A", tmp_path / "a"), _config(tmp_path, "B", tmp_path / "b")]
    with pytest.raises(DataError) as err:
        convert_datasets(names, tmp_path / "data", None, None, 1, "local", False, _console())
    assert str(err.value) == ("nothing to convert: no raw data found for A, B (see `bench "
                              "datasets`)")
    # one sequence: its missing data is an error, not a skip
    with pytest.raises(DataError, match="not found"):
        convert_datasets(names[:1], tmp_path / "data", None, None, 1, "local", False,
                         _console())


def test_a_failed_sequence_fails_the_batch_and_is_named(tmp_path):
    _frames(tmp_path / "ok")
    _frames(tmp_path / "bad")
    np.save(tmp_path / "bad" / "frame_002_dop.npy", np.zeros(3))  # wrong length
    names = [_config(tmp_path, "Ok", tmp_path / "ok"), _config(tmp_path, "Bad", tmp_path / "bad")]
    console = _console()
    assert convert_datasets(names, tmp_path / "data", None, None, 1, "local", False,
                            console) == 1
    text = _text(console)
    assert re.search(r"failed Bad: .*frame_002", text), text
    assert text.endswith("1 converted, 0 up to date, 1 failed")


def test_convert_one_reports_progress_from_0_to_all_frames(tmp_path):
    _frames(tmp_path / "raw", n=5)
    cfg = DatasetConfig.model_validate(yaml.safe_load(open(_config(tmp_path, "P",
                                                                   tmp_path / "raw"))))
    out = tmp_path / "p.h5"
    job = ConvertJob(cfg.model_dump(mode="json"), None, out, "KEY")
    assert job.name == "P"

    class Queue(list):
        put = list.append

    queue = Queue()
    name, status, message, frames, wall = convert_one(job, queue)
    assert (name, status, message, frames) == ("P", "done", str(out), 5) and wall >= 0
    assert queue[0] == ("P", 0, 5) and queue[-1] == ("P", 5, 5)
    assert all(q[0] == "P" and q[2] == 5 for q in queue)
    done = [q[1] for q in queue]
    assert done == sorted(done)
    assert stored_key(out) == "KEY"
    # without a queue: the same store, no progress
    out.unlink()
    assert convert_one(ConvertJob(job.config, None, out, "K2"), None)[:4] == ("P", "done",
                                                                             str(out), 5)


def test_convert_one_turns_any_error_into_a_failed_result(tmp_path):
    job = ConvertJob({"name": "Broken"}, None, tmp_path / "b.h5", "k")
    name, status, message, frames, wall = convert_one(job)
    assert (name, status, frames) == ("Broken", "failed", 0) and wall >= 0
    assert message.startswith("unexpected error: ") and "ValidationError" in message, message
    cfg = {"name": "Gone", "display_name": "Gone", "sensor_class": "Sparse 4D Radar",
           "loader": "npy-frames", "raw_dir": str(tmp_path / "gone"),
           "raw_files": ["frame_000.npy"], "store": "Gone.h5"}
    name, status, message, frames, _ = convert_one(ConvertJob(cfg, None, tmp_path / "g.h5", "k"))
    assert (name, status, frames) == ("Gone", "failed", 0)
    assert "not found" in message and not message.startswith("unexpected")


def test_stored_key_is_none_unless_a_converted_store(tmp_path):
    assert stored_key(tmp_path / "absent.h5") is None
    (tmp_path / "junk.h5").write_bytes(b"not a store")
    assert stored_key(tmp_path / "junk.h5") is None
    plain = write_store(constant_twist_sequence(n_frames=3, n_points=20), tmp_path / "p.h5")
    assert stored_key(plain) is None


def _plan(tmp_path, names, force, out=None):
    from bench.data.datasets import select_configs

    console = _console()
    jobs, current = plan_conversions(select_configs(names), tmp_path / "data", None, out,
                                     force, console)
    return jobs, current, _text(console)


def test_plan_replaces_its_own_stores_and_refuses_other_files(tmp_path):
    _frames(tmp_path / "raw")
    cfg = _config(tmp_path, "S", tmp_path / "raw")
    dest = tmp_path / "data" / "real" / "S.h5"
    jobs, current, _ = _plan(tmp_path, [cfg], False)
    assert current == 0 and [(j.name, j.out) for j in jobs] == [("S", dest)]
    assert json.loads(json.dumps(jobs[0].config)) == jobs[0].config  # plain values: any executor
    key = jobs[0].key
    convert_one(jobs[0])
    jobs, current, text = _plan(tmp_path, [cfg], False)
    assert (jobs, current) == ([], 1) and "is up to date" in text
    jobs, current, _ = _plan(tmp_path, [cfg], True)  # --force: converted again
    assert current == 0 and [(j.out, j.key) for j in jobs] == [(dest, key)]
    # a store of its own with another key (an option changed) is replaced without --force
    convert_one(ConvertJob(jobs[0].config, None, dest, "an older key"))
    jobs, current, _ = _plan(tmp_path, [cfg], False)
    assert [j.out for j in jobs] == [dest] and current == 0
    # a store this command did not convert: only with --force
    dest.unlink()
    write_store(constant_twist_sequence(n_frames=3, n_points=20), dest)
    with pytest.raises(DataError, match="^--out .*exists \\(a store\\); give another --out or "
                                        "--force"):
        _plan(tmp_path, [cfg], False)
    assert [j.out for j in _plan(tmp_path, [cfg], True)[0]] == [dest]
    # any other file: never
    other = tmp_path / "notes.h5"
    other.write_text("mine")
    with pytest.raises(DataError, match="^--out .*is a file that is not a store"):
        _plan(tmp_path, [cfg], True, out=other)
    assert other.read_text() == "mine"
    # the raw data is an input: never written over
    with pytest.raises(DataError, match="--out"):
        _plan(tmp_path, [cfg], True, out=tmp_path / "raw" / "frame_000.npy")


def test_run_conversions_keeps_the_jobs_order_and_shows_each_bar_full(tmp_path):
    jobs = []
    for name in ("B", "A"):
        _frames(tmp_path / name, n=3)
        cfg = DatasetConfig.model_validate(yaml.safe_load(open(_config(tmp_path, name,
                                                                       tmp_path / name))))
        jobs.append(ConvertJob(cfg.model_dump(mode="json"), None, tmp_path / f"{name}.h5", name))
    console = _console()
    results = run_conversions(jobs, "local", 1, console)
    assert [(r[0], r[1], r[3]) for r in results] == [("B", "done", 3), ("A", "done", 3)]
    text = console.export_text()
    for name in ("B", "A"):  # description, bar, frames done of all, elapsed
        assert re.search(rf"^{name} -> {name}\.h5 ━+ 3/3 \d:\d\d:\d\d$", text, re.M), text


# -- the executors' plumbing, with stand-ins for the worker processes and dask ------------------


def _jobs(tmp_path, names=("B", "A")):
    jobs = []
    for name in names:
        _frames(tmp_path / name, n=3)
        cfg = DatasetConfig.model_validate(yaml.safe_load(open(_config(tmp_path, name,
                                                                       tmp_path / name))))
        jobs.append(ConvertJob(cfg.model_dump(mode="json"), None, tmp_path / f"{name}.h5", name))
    return jobs


class _Pool(ThreadPoolExecutor):
    """ProcessPoolExecutor's stand-in: threads, its arguments kept."""

    made: list = []

    def __init__(self, max_workers, mp_context, initializer, initargs):
        super().__init__(max_workers=max_workers)
        _Pool.made.append({"max_workers": max_workers, "mp_context": mp_context,
                           "initializer": initializer, "initargs": initargs})


class _Context:
    """multiprocessing's spawn context's stand-in: a Manager whose Queue is a plain queue."""

    def __init__(self, method):
        self.method = method

    @contextlib.contextmanager
    def Manager(self):  # noqa: N802 - multiprocessing's name
        yield types.SimpleNamespace(Queue=queue.Queue)


@pytest.fixture
def threads(monkeypatch):
    import concurrent.futures
    import multiprocessing

    _Pool.made = []
    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", _Pool)
    monkeypatch.setattr(multiprocessing, "get_context", _Context)
    return _Pool.made


@pytest.mark.parametrize("workers, pool_size", [(0, 1), (1, 1), (3, 3)])
def test_the_process_executor_runs_every_job_and_keeps_their_order(tmp_path, threads, workers,
                                                                   pool_size):
    jobs = _jobs(tmp_path)
    seen = []
    results = convert_batch._run_processes(jobs, workers, lambda *a: seen.append(a))
    assert [(r[0], r[1], r[3]) for r in results] == [("B", "done", 3), ("A", "done", 3)]
    (made,) = threads
    assert made["max_workers"] == pool_size
    assert made["mp_context"].method == "spawn"
    assert made["initializer"] is convert_batch._worker_init
    assert made["initargs"] == (os.getpid(),)
    for name in ("A", "B"):  # every progress message reached the bar: from 0 to all 3 frames
        assert (name, 0, 3) in seen and (name, 3, 3) in seen, seen


def test_a_worker_that_dies_fails_its_job_only(tmp_path, threads, monkeypatch):
    jobs = _jobs(tmp_path)

    def convert(job, queue=None):
        if job.name == "A":
            raise RuntimeError("killed by the OOM killer")
        return (job.name, "done", "ok", 3, 0.5)

    monkeypatch.setattr(convert_batch, "convert_one", convert)
    results = convert_batch._run_processes(jobs, 2, lambda *a: None)
    assert results == [("B", "done", "ok", 3, 0.5),
                       ("A", "failed", "worker died: killed by the OOM killer", 0, 0.0)]


def test_run_conversions_dispatches_by_executor(tmp_path, monkeypatch):
    jobs = _jobs(tmp_path, names=("C",))
    calls = []

    def processes(jobs, workers, update):
        update("C", 2, 3)  # the bar of the job named
        calls.append(("process", [j.name for j in jobs], workers))
        return ["p"]

    def dask(jobs, workers, scheduler, update):
        update("C", 1, 3)
        calls.append(("dask", [j.name for j in jobs], workers, scheduler))
        return ["d"]

    monkeypatch.setattr(convert_batch, "_run_processes", processes)
    monkeypatch.setattr(convert_batch, "_run_dask", dask)
    console = _console()
    assert run_conversions(jobs, "process", 4, console) == ["p"]
    assert re.search(r"^C -> C\.h5 [━╸ ]+ 2/3 ", console.export_text(), re.M)
    assert run_conversions(jobs, "dask", 2, _console(), "tcp://h:1") == ["d"]
    assert calls == [("process", ["C"], 4), ("dask", ["C"], 2, "tcp://h:1")]


class _Future:
    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


class _Dask:
    """dask.distributed's stand-in: a client that runs each job at once; what was made and
    closed kept."""

    def __init__(self):
        self.events = []
        dask = self

        class LocalCluster:
            def __init__(self, **kwargs):
                dask.events.append(("cluster", kwargs))

            def close(self):
                dask.events.append(("cluster closed",))

        class Client:
            def __init__(self, address):
                dask.events.append(("client", address if isinstance(address, str) else
                                    type(address).__name__))

            def submit(self, fn, *args, pure=True):
                dask.events.append(("submit", args[0].name, args[1:], pure))
                return _Future(fn(*args))

            def close(self):
                dask.events.append(("client closed",))

        self.LocalCluster, self.Client = LocalCluster, Client

    @staticmethod
    def as_completed(futures):
        return list(futures)[::-1]  # finished in another order than submitted


@pytest.fixture
def dask(monkeypatch):
    import dask.distributed

    fake = _Dask()
    for name in ("LocalCluster", "Client", "as_completed"):
        monkeypatch.setattr(dask.distributed, name, getattr(fake, name))
    return fake


def test_dask_runs_on_a_local_cluster_of_single_threaded_processes(tmp_path, dask):
    jobs = _jobs(tmp_path)
    seen = []
    results = convert_batch._run_dask(jobs, 0, None, lambda *a: seen.append(a))
    assert [(r[0], r[1], r[3]) for r in results] == [("B", "done", 3), ("A", "done", 3)]
    assert dask.events[0] == ("cluster", {"n_workers": 1, "threads_per_worker": 1,
                                          "processes": True})
    assert dask.events[1] == ("client", "LocalCluster")
    assert [e[1:] for e in dask.events if e[0] == "submit"] == [("B", (None,), False),
                                                                ("A", (None,), False)]
    assert dask.events[-2:] == [("client closed",), ("cluster closed",)]
    assert sorted(seen) == [("A", 3, 3), ("B", 3, 3)]


def test_dask_on_a_scheduler_makes_no_cluster(tmp_path, dask, monkeypatch):
    jobs = _jobs(tmp_path, names=("C",))
    monkeypatch.setattr(convert_batch, "convert_one",
                        lambda job, queue=None: (job.name, "failed", "x", 0, 0.0))
    seen = []
    assert convert_batch._run_dask(jobs, 3, "tcp://h:8786", lambda *a: seen.append(a)) == [
        ("C", "failed", "x", 0, 0.0)]
    assert [e[0] for e in dask.events] == ["client", "submit", "client closed"]
    assert dask.events[0] == ("client", "tcp://h:8786")
    assert seen == [("C", 0, 1)]  # a bar of at least one step


def test_a_worker_ignores_ctrl_c_and_dies_with_its_parent(monkeypatch):
    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    before = signal.getsignal(signal.SIGINT)
    try:
        convert_batch._worker_init(os.getppid())
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        death = ctypes.c_int(-1)
        assert libc.prctl(2, ctypes.byref(death)) == 0  # PR_GET_PDEATHSIG
        assert death.value == signal.SIGKILL
    finally:
        signal.signal(signal.SIGINT, before)
        libc.prctl(1, 0)  # PR_SET_PDEATHSIG: none, as before


def test_a_worker_whose_parent_is_gone_exits_at_once(monkeypatch):
    exits = []

    def exit_(code):
        exits.append(code)

    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(convert_batch.os, "_exit", exit_)
    try:
        convert_batch._worker_init(os.getppid() + 1)
        convert_batch._worker_init(os.getppid())
    finally:
        signal.signal(signal.SIGINT, before)
        libc.prctl(1, 0)
    assert exits == [1]


@pytest.mark.parametrize("has_processes", [True, False])
def test_ctrl_c_kills_the_workers_and_cancels_what_is_left(tmp_path, threads, monkeypatch,
                                                          has_processes):
    import concurrent.futures

    killed, shutdowns = [], []

    class Interrupted(_Pool):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            if has_processes:  # the pool's own (private) table of its worker processes
                self._processes = {1: types.SimpleNamespace(kill=lambda: killed.append(1)),
                                   2: types.SimpleNamespace(kill=lambda: killed.append(2))}

        def submit(self, *args, **kwargs):
            raise KeyboardInterrupt

        def shutdown(self, wait=True, cancel_futures=False):
            shutdowns.append((wait, cancel_futures))
            super().shutdown(wait=wait, cancel_futures=cancel_futures)

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", Interrupted)
    with pytest.raises(KeyboardInterrupt):
        convert_batch._run_processes(_jobs(tmp_path, names=("C",)), 1, lambda *a: None)
    assert sorted(killed) == ([1, 2] if has_processes else []) and shutdowns == [(False, True)]


@pytest.mark.parametrize("error", [OSError("no libc.so.6 here"), AttributeError("no prctl")])
def test_a_worker_without_prctl_still_starts(monkeypatch, error):
    def cdll(*args, **kwargs):
        raise error

    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(ctypes, "CDLL", cdll)
    try:
        convert_batch._worker_init(os.getppid())
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


def _stand_in_executors(monkeypatch):
    calls = []

    def processes(jobs, workers, update):
        calls.append(("process", [j.name for j in jobs], workers))
        return [(j.name, "done", str(j.out), 3, 1.0) for j in jobs]

    def dask(jobs, workers, scheduler, update):
        calls.append(("dask", [j.name for j in jobs], workers, scheduler))
        return [(j.name, "done", str(j.out), 3, 1.0) for j in jobs]

    monkeypatch.setattr(convert_batch, "_run_processes", processes)
    monkeypatch.setattr(convert_batch, "_run_dask", dask)
    return calls


def test_several_sequences_go_to_the_executor_asked_for(tmp_path, monkeypatch):
    calls = _stand_in_executors(monkeypatch)
    for name in ("A", "B"):
        _frames(tmp_path / name)
    names = [_config(tmp_path, "A", tmp_path / "A"), _config(tmp_path, "B", tmp_path / "B")]
    console = _console()
    assert convert_datasets(names, tmp_path / "data", None, None, 3, "process", False,
                            console) == 0
    assert convert_datasets(names, tmp_path / "data", None, None, 2, "dask", False, _console(),
                            "tcp://h:1") == 0
    assert calls == [("process", ["A", "B"], 3), ("dask", ["A", "B"], 2, "tcp://h:1")]
    text = _text(console)
    assert "A -> A.h5" in text and "B -> B.h5" in text  # the bars on the console given
    assert "wrote" in text and text.endswith("2 converted, 0 up to date, 0 failed")


def test_one_sequence_stays_on_dask_when_asked(tmp_path, monkeypatch):
    calls = _stand_in_executors(monkeypatch)
    _frames(tmp_path / "A")
    assert convert_datasets([_config(tmp_path, "A", tmp_path / "A")], tmp_path / "data", None,
                            None, 1, "dask", False, _console(), "tcp://h:2") == 0
    assert calls == [("dask", ["A"], 1, "tcp://h:2")]


def test_force_converts_an_up_to_date_store_again(tmp_path):
    _frames(tmp_path / "raw")
    cfg = _config(tmp_path, "S", tmp_path / "raw")
    assert convert_datasets([cfg], tmp_path / "data", None, None, 1, "local", False,
                            _console()) == 0
    console = _console()
    assert convert_datasets([cfg], tmp_path / "data", None, None, 1, "local", True,
                            console) == 0
    assert _text(console).endswith("1 converted, 0 up to date, 0 failed")


def test_progress_is_sent_for_the_first_frame_then_at_most_every_quarter_second(tmp_path,
                                                                                monkeypatch):
    """A clock of our own: 1.125 s at the first frame, a quarter second more at each."""
    _frames(tmp_path / "raw", n=8)
    cfg = DatasetConfig.model_validate(yaml.safe_load(open(_config(tmp_path, "P",
                                                                   tmp_path / "raw"))))
    ticks = iter(1.125 + 0.25 * k for k in range(100))
    monkeypatch.setattr(convert_batch, "time", types.SimpleNamespace(
        monotonic=lambda: next(ticks), perf_counter=time.perf_counter))

    class Queue(list):
        put = list.append

    queue = Queue()
    job = ConvertJob(cfg.model_dump(mode="json"), None, tmp_path / "p.h5", "K")
    assert convert_one(job, queue)[1] == "done"
    # frames 1, 3, 5, 7 (more than 0.25 s after the last message) and the last, 8
    assert queue == [("P", 0, 8), ("P", 1, 8), ("P", 3, 8), ("P", 5, 8), ("P", 7, 8),
                     ("P", 8, 8)]


def test_skips_and_up_to_date_lines_are_plain_text_on_one_line(tmp_path):
    """Paths with square brackets (no markup) on a narrow console (no wrapping)."""
    _frames(tmp_path / "raw")
    data = tmp_path / "data[b]"
    ok = _config(tmp_path, "Ok", tmp_path / "raw")
    convert_datasets([ok], data, None, None, 1, "local", False, _console())
    gone = _config(tmp_path, "Gone", tmp_path / "gone[b]")
    console = Console(record=True, width=40, force_terminal=False)
    convert_datasets([ok, gone], data, None, None, 1, "local", False, console)
    lines = console.export_text().splitlines()
    assert f"skipped Gone: raw data {tmp_path / 'gone[b]'} not found" in lines
    assert (f"Ok: {data / 'real' / 'Ok.h5'} is up to date (inputs and options unchanged; "
            "--force converts again)") in lines


def test_every_missing_raw_file_is_named(tmp_path):
    (tmp_path / "half").mkdir()
    cfg = {"name": "Half", "display_name": "Half", "sensor_class": "Sparse 4D Radar",
           "loader": "npy-frames", "raw_dir": str(tmp_path / "half"),
           "raw_files": ["frame_000.npy", "gt.txt"], "store": "Half.h5"}
    path = tmp_path / "Half.yaml"
    path.write_text(yaml.safe_dump(cfg))
    _frames(tmp_path / "ok")
    console = _console()
    convert_datasets([str(path), _config(tmp_path, "Ok", tmp_path / "ok")], tmp_path / "data",
                     None, None, 1, "local", False, console)
    assert (f"skipped Half: raw data {tmp_path / 'half'} incomplete (missing frame_000.npy, "
            "gt.txt)") in console.export_text().splitlines()


def test_plan_counts_every_up_to_date_store_and_goes_on_after_one(tmp_path):
    for name in ("A", "B", "C"):
        _frames(tmp_path / name)
    a, b, c = (_config(tmp_path, n, tmp_path / n) for n in ("A", "B", "C"))
    convert_datasets([a, b], tmp_path / "data", None, None, 1, "local", False, _console())
    jobs, current, _ = _plan(tmp_path, [a, b, c], False)
    assert current == 2 and [j.name for j in jobs] == ["C"]


def test_plan_reads_and_protects_the_raw_folder_given(tmp_path):
    from bench.data.datasets import select_configs

    _frames(tmp_path / "other")
    configs = select_configs([_config(tmp_path, "X", tmp_path / "nowhere"),
                              _config(tmp_path, "Y", tmp_path / "nowhere2")])
    jobs, _ = plan_conversions(configs, tmp_path / "data", tmp_path / "other", None, False,
                               _console())
    assert [j.name for j in jobs] == ["X", "Y"]  # both found in the raw folder given
    with pytest.raises(DataError, match="is an input of this command"):
        plan_conversions(configs[:1], tmp_path / "data", tmp_path / "other",
                         tmp_path / "other", True, _console())
    with pytest.raises(DataError, match="is an input of this command"):
        _plan(tmp_path, [_config(tmp_path, "Z", tmp_path / "other")], True,
              out=tmp_path / "other")


def test_each_result_is_one_line_with_its_rate(tmp_path, monkeypatch):
    for name in ("A", "B"):
        _frames(tmp_path / name)
    long = ("frame_002: " + "a very long reason " * 10).rstrip()

    def processes(jobs, workers, update):
        return [("A", "done", "/x/A.h5", 3, 0.5), ("B", "failed", long, 0, 0.25)]

    monkeypatch.setattr(convert_batch, "_run_processes", processes)
    console = Console(record=True, width=120, force_terminal=False)  # narrower than `long`
    names = [_config(tmp_path, "A", tmp_path / "A"), _config(tmp_path, "B", tmp_path / "B")]
    assert convert_datasets(names, tmp_path / "data", None, None, 2, "process", False,
                            console) == 1
    lines = console.export_text().splitlines()
    assert "wrote /x/A.h5: 3 frames in 0.5 s (6 frames/s)" in lines
    assert f"failed B: {long}" in lines
    assert lines[-1] == "1 converted, 0 up to date, 1 failed"


def test_a_file_put_in_place_after_planning_is_left_alone_and_timed(tmp_path):
    _frames(tmp_path / "raw")
    cfg = DatasetConfig.model_validate(yaml.safe_load(open(_config(tmp_path, "S",
                                                                   tmp_path / "raw"))))
    out = tmp_path / "s.h5"
    out.write_text("someone's notes")
    t0 = time.perf_counter()
    name, status, message, frames, wall = convert_one(
        ConvertJob(cfg.model_dump(mode="json"), None, out, "k"))
    took = time.perf_counter() - t0
    assert (name, status, frames) == ("S", "failed", 0)
    assert "is not a store the harness wrote" in message
    assert out.read_text() == "someone's notes"
    assert 0 <= wall <= took
    t0 = time.perf_counter()
    out.unlink()
    result = convert_one(ConvertJob(cfg.model_dump(mode="json"), None, out, "k"))
    assert result[1] == "done" and 0 <= result[4] <= time.perf_counter() - t0
    t0 = time.perf_counter()
    broken = convert_one(ConvertJob({"name": "B"}, None, out, "k"))
    assert broken[1] == "failed" and 0 <= broken[4] <= time.perf_counter() - t0
