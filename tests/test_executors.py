"""Executors and the command line's exit codes: crashes fail alone, Ctrl-C and the death of
the main process leave no worker, and every executor gives the same metrics."""

import csv
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from bench.runs.executors import execute
from bench.runs.job import Job
from bench.runs.plan import plan
from conftest import constant_twist_sequence
from loaders.store import write_store

TESTS = Path(__file__).resolve().parent
ENV = {**os.environ, "DOPPLER_BENCH_METHODS": "bench_test_methods",
       "PYTHONPATH": os.pathsep.join([str(TESTS / "plugins"), str(TESTS.parent)])}


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=40, n_points=1500, noise_m=0.01, max_range_m=70)
    return write_store(seq, tmp_path_factory.mktemp("data") / "twist.h5")


def _metrics(run_dir: Path) -> dict:
    m = json.loads((run_dir / "metrics.json").read_text())
    # every executor pins the library threads: the work stayed on the timed thread
    assert m["clock"] == "cpu" and m["cpu_process_to_thread"] <= 1.05, m
    assert m["timing_clean"] is True
    for timing in ("time_ms", "register_ms", "wall_ms", "cpu_process_to_thread",
                   "timing_outliers"):  # only the timing may differ
        m.pop(timing)
    return m


def test_every_executor_gives_the_same_metrics_and_reports_progress(store, tmp_path):
    results = {}
    for executor in ("local", "process", "dask"):
        jobs = plan([Job(store=store, method=m, seed=s, out_root=tmp_path / executor)
                     for m, s in (("doppler", None), ("icp-p2p", True))])
        progress, finished = {}, []
        outcomes = execute(jobs, executor, 2, False,
                           lambda job, done, total, p=progress: p.setdefault(job.title, [])
                           .append((done, total)), finished.append)
        assert [o.status for o in outcomes] == ["done", "done"], [o.message for o in outcomes]
        assert len(finished) == 2
        # every run reported frames as it went (the bars' frames/s), ending with all of them
        assert {title: reports[-1] for title, reports in progress.items()} == {
            j.title: (40, 40) for j in jobs}, executor
        results[executor] = [_metrics(j.run_dir_override) for j in jobs]
    assert results["local"] == results["process"] == results["dask"]


def _bench(args, **kw):
    return subprocess.Popen([sys.executable, "-m", "bench.cli", *args], env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)


def _experiment(tmp_path, store, methods):
    exp = tmp_path / "e.yaml"
    exp.write_text(f"name: e\nsequences: [{{path: {store}, name: twist}}]\n"
                   f"methods: {methods}\nlengths_m: [8]\nout: results\njobs: 2\n")
    return exp


def test_a_job_that_aborts_fails_alone(store, tmp_path):
    exp = _experiment(tmp_path, store, "[{name: test-abort}, {name: doppler}]")
    proc = _bench(["run", str(exp)])
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 1, out
    assert "SIGABRT" in out and "Traceback" not in out
    failed = json.loads((tmp_path / "results/twist/test-abort/failed.json").read_text())
    assert "SIGABRT" in failed["error"] and failed["status"] == "crashed"
    assert (tmp_path / "results/twist/doppler/metrics.json").exists()


def _workers_of(pid: int) -> list[psutil.Process]:
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _wait_for_workers(proc, n, timeout_s=60.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        workers = [w for w in _workers_of(proc.pid) if "python" in w.name().lower()]
        if len(workers) >= n:
            return workers
        time.sleep(0.2)
    raise AssertionError("workers did not start")


def _slow_experiment(tmp_path, store):
    variants = ", ".join(f"{{name: test-sleep, label: s{k}, params: {{sleep_s: 0.5}}}}"
                         for k in range(4))
    return _experiment(tmp_path, store, f"[{variants}]")


def test_ctrl_c_exits_130_within_seconds_and_leaves_no_worker(store, tmp_path):
    log = tmp_path / "out.log"
    with log.open("w") as sink:  # a file, not a pipe: nothing can block on a full pipe
        # a background job (nohup, CI) inherits SIGINT ignored, and Python then keeps it
        # ignored: give the child the default disposition a terminal's Ctrl-C meets
        proc = subprocess.Popen([sys.executable, "-m", "bench.cli", "run",
                                 str(_slow_experiment(tmp_path, store))], env=ENV,
                                stdout=sink, stderr=subprocess.STDOUT, text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        workers = _wait_for_workers(proc, 2)  # the two workers (forked: no resource tracker)
        time.sleep(2.0)  # inside the runs
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
    out = log.read_text()
    assert proc.returncode == 130, out
    assert time.monotonic() - t0 < 10
    assert "interrupted" in out and "Traceback" not in out
    time.sleep(0.5)
    assert not [w for w in workers if w.is_running() and w.status() != psutil.STATUS_ZOMBIE]
    records = [json.loads(p.read_text()) for p in (tmp_path / "results").rglob("failed.json")]
    assert records and all(r["status"] == "interrupted" for r in records)


def test_sigkill_of_the_main_process_leaves_no_worker(store, tmp_path):
    proc = _bench(["run", str(_slow_experiment(tmp_path, store))])
    workers = _wait_for_workers(proc, 2)
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(w.is_running() for w in workers):
        time.sleep(0.2)
    assert not [w for w in workers if w.is_running() and w.status() != psutil.STATUS_ZOMBIE]


def test_a_job_timeout_ends_the_job(store, tmp_path):
    exp = _experiment(tmp_path, store, "[{name: test-sleep, params: {sleep_s: 1.0}}]")
    proc = _bench(["run", str(exp), "--job-timeout", "3"])
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 1, out
    assert "timeout" in out


def test_dask_job_timeout_ends_that_job_only(store, tmp_path):
    # more jobs than workers, each ~1 s: the timeout counts from a job's start (not its
    # submission: the last ones start ~4 s after it), and the jobs queued behind the slow one
    # must not die with it
    quick = ", ".join(f"{{name: test-sleep, label: q{k}, params: {{sleep_s: 0, "
                      "untimed_sleep_s: 0.025}}" for k in range(5))
    # the slow job sleeps outside the timed section, so it does not hold the timing lock
    slow = "{name: test-sleep, label: slow, params: {sleep_s: 0, untimed_sleep_s: 0.3}}"
    exp = _experiment(tmp_path, store, f"[{slow}, {quick}]")
    proc = _bench(["run", str(exp), "--executor", "dask", "--job-timeout", "5"])
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 1, out
    slow = tmp_path / "results/twist/slow"
    assert json.loads((slow / "failed.json").read_text())["status"] == "timeout"
    assert not (slow / "metrics.json").exists()
    for k in range(5):
        assert (tmp_path / f"results/twist/q{k}/metrics.json").exists(), out


@pytest.mark.parametrize("args, code", [
    (["run", "--method", "doppler", "--data", "STORE", "-p", "tau_spatial_m=abc"], 2),
    (["run", "--method", "doppler", "--data", "STORE", "-p", "nonsense=1"], 2),
    (["run", "--method", "nope", "--data", "STORE"], 2),
    (["run", "--method", "doppler", "--data", "STORE", "--executor", "cloud"], 2),
    (["run", "--method", "doppler", "--data", "STORE", "--out", "OUT"], 0),
    (["run", "--method", "test-abort", "--data", "STORE", "--out", "OUT2"], 1),
    (["run", "BADYAML"], 2),
])
def test_exit_codes(store, tmp_path, args, code):
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("name: e\nmethods: [{name: doppler\n")  # unclosed flow sequence
    args = [a.replace("STORE", str(store)).replace("OUT", str(tmp_path / "o"))
            .replace("BADYAML", str(bad_yaml)) for a in args]
    proc = _bench(args)
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == code, out
    assert "Traceback" not in out
    if code == 0:
        assert "run folder:" in out and "8 m:" in out and "APE" in out
    if code == 1:
        assert "1 failed" in out and "SIGABRT" in out  # the summary names the failed run
    if args[-1] == str(bad_yaml):
        assert "bad.yaml" in out  # the message names the file


def test_piped_output_is_plain_and_keeps_units(store, tmp_path):
    out_dir = tmp_path / "runs"
    assert _bench(["run", "--method", "doppler", "--data", str(store), "--out",
                   str(out_dir / "twist" / "doppler")]).wait(timeout=120) == 0
    proc = subprocess.Popen([sys.executable, "-m", "bench.cli", "table", str(out_dir), "-f",
                             "csv"], env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    out, err = proc.communicate(timeout=60)
    header = out.splitlines()[0]
    assert header.startswith("sequence,sensor_class,method") and "\x1b[" not in out
    assert len(out.splitlines()[1]) > 80  # not wrapped at 80 columns
    rows = list(csv.reader(io.StringIO(out)))  # stdout is the CSV alone: status on stderr
    # long format: one line per value (per length: rotation, translation, segments,
    # independent segments and both intervals' ends; the time)
    assert len(rows) == 1 + 6 * 8 + 1 and {len(r) for r in rows} == {len(header.split(","))}
    assert "wrote" in err
    proc = _bench(["run", "--help"])
    help_text, _ = proc.communicate(timeout=60)
    assert "[s]" in help_text


def test_workers_are_forked_from_a_process_without_a_running_numba_pool():
    """The main process of `bench run` has imported the harness and the methods while
    planning; its workers are forked from it (no second import before the first frame)."""
    code = ("import bench.runs.job, bench.runs.executors as e; import numba; "
            "print(e.start_method())")
    done = subprocess.run([sys.executable, "-c", code], env=ENV, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-1] == "fork"
