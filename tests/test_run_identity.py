"""Run identity: a run is keyed by what determines it; labelled variants; no stale rows."""

import json

import pytest
import yaml

from bench.report.tables import runs
from bench.runs.experiment import load_experiment
from bench.runs.job import Job, run_job
from bench.runs.plan import jobs_for_experiment, plan
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import write_store


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=40, n_points=1500, noise_m=0.01, max_range_m=70)
    return write_store(seq, tmp_path_factory.mktemp("data") / "twist.h5")


def test_a_parameter_or_length_change_reruns_and_an_unchanged_job_is_skipped(store, tmp_path):
    job = Job(store=store, method="doppler", seed=None, out_root=tmp_path)
    assert run_job(job).status == "done"
    assert run_job(job).status == "skipped"
    changed = Job(store=store, method="doppler", seed=None, out_root=tmp_path,
                  params={"tau_spatial_m": 2.0})
    assert run_job(changed).status == "done"
    config = yaml.safe_load((tmp_path / "twist" / "doppler" / "config.yaml").read_text())
    assert config["method"]["params"]["tau_spatial_m"] == 2.0
    shorter = Job(store=store, method="doppler", seed=None, out_root=tmp_path,
                  params={"tau_spatial_m": 2.0}, lengths_m=(8.0,))
    assert run_job(shorter).status == "done"
    assert run_job(shorter).status == "skipped"


def test_a_changed_store_reruns(store, tmp_path):
    copy = tmp_path / "twist.h5"
    copy.write_bytes(store.read_bytes())
    job = Job(store=copy, method="doppler", seed=None, out_root=tmp_path / "r")
    assert run_job(job).status == "done"
    other = constant_twist_sequence(n_frames=40, n_points=1500, noise_m=0.01, seed=5)
    write_store(other, copy)
    assert run_job(job).status == "done"


def test_a_failing_forced_rerun_leaves_no_stale_metrics(store, tmp_path):
    job = Job(store=store, method="doppler", seed=None, out_root=tmp_path)
    assert run_job(job).status == "done"
    run_dir = tmp_path / "twist" / "doppler"
    assert (run_dir / "metrics.json").exists()
    broken = Job(store=store, method="doppler", seed=None, out_root=tmp_path,
                 params={"tau_spatial_m": -1.0})
    assert run_job(broken, force=True).status == "failed"
    assert not (run_dir / "metrics.json").exists()
    assert json.loads((run_dir / "failed.json").read_text())["status"] == "failed"
    # the table shows it as a failed row, never with the old metrics
    assert [(r.failed, r.result.relative_error) for r in runs(tmp_path)] == [(True, [])]


def _experiment(tmp_path, store, methods: str):
    exp = tmp_path / "exp" / "e.yaml"
    exp.parent.mkdir(parents=True)
    exp.write_text(f"name: e\nsequences: [{{path: {store}, name: twist}}]\n"
                   f"methods: {methods}\nlengths_m: [8, 16]\nout: results\n")
    return exp


def test_labelled_variants_get_two_rows_and_yaml_paths_are_relative(store, tmp_path):
    exp_path = _experiment(tmp_path, store, "[{name: doppler, label: tau3}, "
                           "{name: doppler, label: tau1, params: {tau_spatial_m: 1.0}}]")
    exp = load_experiment(exp_path)
    assert exp.out_dir == exp_path.parent / "results"
    outcomes = run_jobs(plan(jobs_for_experiment(exp)), executor="local")
    assert [o.status for o in outcomes] == ["done", "done"]
    rows = runs(exp.out_dir)
    assert sorted(r.label for r in rows) == ["(No initial guess) tau1", "(No initial guess) tau3"]
    assert rows[0].result.relative_error != rows[1].result.relative_error


def test_two_unlabelled_variants_and_folder_collisions_are_user_errors(store, tmp_path):
    exp_path = _experiment(tmp_path, store, "[{name: doppler}, {name: doppler, "
                           "params: {tau_spatial_m: 1.0}}]")
    with pytest.raises(DataError, match="label"):
        load_experiment(exp_path)
    copy = tmp_path / "copy.h5"
    write_store(constant_twist_sequence(n_frames=10, seed=3), copy)  # same internal name
    jobs = [Job(store=s, method="doppler", seed=None, out_root=tmp_path / "c")
            for s in (store, copy)]
    with pytest.raises(DataError, match="share this folder"):
        plan(jobs)


def test_method_sequence_filter(store, tmp_path):
    exp_path = _experiment(tmp_path, store, "[{name: doppler, sequences: [twist]}, "
                           "{name: icp-p2p, sequences: [elsewhere]}]")
    with pytest.raises(DataError, match="unknown sequences elsewhere"):
        jobs_for_experiment(load_experiment(exp_path))


def test_store_hashes_are_cached_by_path_size_mtime_and_inode(store, tmp_path, monkeypatch):
    import hashlib

    from bench.runs import identity as results

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(results, "_store_hashes", {})
    copy = tmp_path / "twist.h5"
    copy.write_bytes(store.read_bytes())
    true_hash = hashlib.sha256(copy.read_bytes()).hexdigest()
    assert results.store_identity(copy) == true_hash
    cache_file = tmp_path / "cache" / "doppler-bench" / "store-sha256.json"
    cached = json.loads(cache_file.read_text())
    assert list(cached.values()) == [true_hash]
    # another process (empty memory cache) takes the hash from the file, without reading
    # the store: a planted value proves it
    cache_file.write_text(json.dumps({k: "planted" for k in cached}))
    monkeypatch.setattr(results, "_store_hashes", {})
    assert results.store_identity(copy) == "planted"
    # a rewritten store (new inode, size or mtime) is hashed again
    write_store(constant_twist_sequence(n_frames=12, seed=7), copy)
    monkeypatch.setattr(results, "_store_hashes", {})
    assert results.store_identity(copy) == hashlib.sha256(copy.read_bytes()).hexdigest()


def test_part_of_a_store_runs_as_its_own_keyed_run(store, tmp_path):
    """An experiment may run frames start .. start + frames - 1 of a store (e.g. a validation
    split); the range is part of the run's identity and recorded in its config."""
    exp = tmp_path / "exp.yaml"
    exp.write_text(yaml.safe_dump({
        "name": "part", "out": str(tmp_path / "out"), "lengths_m": [2.0],
        "sequences": [{"path": str(store), "name": "tail", "start": 10, "frames": 25}],
        "methods": [{"name": "doppler"}]}))
    (job,) = plan(jobs_for_experiment(load_experiment(exp)))
    outcome = run_job(job)
    assert outcome.status == "done", outcome.message
    metrics = json.loads((outcome.run_dir / "metrics.json").read_text())
    config = yaml.safe_load((outcome.run_dir / "config.yaml").read_text())
    assert metrics["frames"] == 25 and config["sequence"]["frame_range"] == [10, 25]
    exp.write_text(exp.read_text().replace("start: 10", "start: 12"))
    (moved,) = plan(jobs_for_experiment(load_experiment(exp)))
    assert moved.run_key != job.run_key
    assert run_job(moved).status == "done"


_RUN_IN_COPY = """
import sys
from pathlib import Path
from bench.runs.job import Job, run_job
from bench.runs.plan import plan
job = plan([Job(store=Path(sys.argv[1]), method="doppler", seed=None,
                out_root=Path(sys.argv[2]))])[0]
print(run_job(job).status)
"""


def test_editing_a_loader_helper_re_runs_the_run(store, tmp_path):
    """The run key covers the content of every module that can change a result: a copy of the
    code runs a job, the job is reused, then a helper in loaders/se3.py is edited (a new
    docstring line, results unchanged) and the same job runs again."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    copy = tmp_path / "repo"
    for part in ("bench", "loaders", "methods", "metrics", "configs"):
        shutil.copytree(root / part, copy / part,
                        ignore=shutil.ignore_patterns("__pycache__"))

    def run() -> str:
        out = subprocess.run([sys.executable, "-c", _RUN_IN_COPY, str(store),
                              str(tmp_path / "results")], cwd=copy, capture_output=True,
                             text=True, timeout=300,
                             env={**os.environ, "PYTHONPATH": str(copy)})
        assert out.returncode == 0, out.stderr[-2000:]
        return out.stdout.split()[-1]

    assert run() == "done"
    assert run() == "skipped"
    se3 = copy / "loaders" / "se3.py"
    text = se3.read_text()
    assert '    """Inverse of (..., 4, 4) rigid transforms' in text
    se3.write_text(text.replace('    """Inverse of (..., 4, 4) rigid transforms',
                                '    """(edited) Inverse of (..., 4, 4) rigid transforms', 1))
    assert run() == "done"
