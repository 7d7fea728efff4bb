"""Run identity: a run is keyed by what determines it; labelled variants; no stale rows."""

import json
from pathlib import Path

import pytest
import yaml

from bench.report.tables.paper import runs
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


def test_a_same_size_same_mtime_store_replaced_by_rename_is_hashed_again(store, tmp_path,
                                                                         monkeypatch):
    """Only the inode tells this store from the one it replaced: same path, same size, same
    mtime (set back by os.utime), other bytes, moved in by os.replace. Neither the in-memory
    cache of this process nor the cache file may serve the old hash."""
    import hashlib
    import os

    from bench.runs import identity

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(identity, "_store_hashes", {})
    path = tmp_path / "twist.h5"
    data = bytearray(store.read_bytes())
    path.write_bytes(data)
    old = identity.store_identity(path)
    assert old == hashlib.sha256(data).hexdigest()
    before = path.stat()
    data[len(data) // 2] ^= 0xFF  # one byte changed, the size kept
    new = tmp_path / "twist.h5.tmp"
    new.write_bytes(data)
    os.utime(new, ns=(before.st_atime_ns, before.st_mtime_ns))
    os.replace(new, path)
    after = path.stat()
    assert (after.st_size, after.st_mtime_ns) == (before.st_size, before.st_mtime_ns)
    assert after.st_ino != before.st_ino
    expected = hashlib.sha256(data).hexdigest()
    assert identity.store_identity(path) == expected  # this process's memory cache
    monkeypatch.setattr(identity, "_store_hashes", {})
    assert identity.store_identity(path) == expected  # another process: the cache file


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
    docstring line, results unchanged) and the same job runs again.

    The copy keeps numba's on-disk cache of the compiled kernels (``__pycache__/*.nbi``,
    ``*.nbc``; not the bytecode): the copied files keep their times, so the copy loads the
    kernels instead of compiling them again in each child process. The run key covers the
    modules' sources, not these caches, as the reuse below shows."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    copy = tmp_path / "repo"
    for part in ("bench", "loaders", "methods", "metrics", "configs"):
        shutil.copytree(root / part, copy / part, ignore=shutil.ignore_patterns("*.pyc"))

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


# ---- what the run key covers (bench/runs/identity.py) ---------------------------------------

@pytest.fixture(scope="module")
def code_copy(tmp_path_factory):
    """A copy of the code whose identity the tests change file by file."""
    import shutil
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    copy = tmp_path_factory.mktemp("code")
    for part in ("bench", "loaders", "methods", "metrics"):
        shutil.copytree(root / part, copy / part, ignore=shutil.ignore_patterns("__pycache__"))
    return copy


def _scoring_files():
    """Every module of metrics/ and the scoring, listed from the folder (not from the key), and
    the rest of the path from the store to metrics.json: the job runner, the executors that
    call it, the folder writer, the store reader and a method."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    return sorted(str(p.relative_to(root)) for p in (root / "metrics").glob("*.py")) + [
        "bench/runs/evaluate.py", "bench/runs/timed.py", "bench/threads.py", "loaders/gt.py",
        "bench/runs/job.py", "bench/runs/executors.py", "bench/runs/folders.py",
        "bench/runs/result.py", "loaders/store.py", "methods/doppler.py",
        "methods/doppler_ego.py"]


@pytest.mark.parametrize("path", _scoring_files())
def test_editing_any_scoring_module_changes_the_key(code_copy, path):
    from bench.runs import identity

    before = identity.code_identity(code_copy)
    file = code_copy / path
    text = file.read_text()
    try:
        file.write_text(text + "\n# edited\n")
        assert identity.code_identity(code_copy) != before
    finally:
        file.write_text(text)
    assert identity.code_identity(code_copy) == before


def test_flipping_the_seed_handling_in_run_job_changes_the_key(code_copy):
    """The issue's case: run_job's own handling of the seed option changed and the old result
    was served as current. Every line of job.py is in the key, run_job's body included."""
    from bench.runs import identity

    before = identity.code_identity(code_copy)
    file = code_copy / "bench" / "runs" / "job.py"
    text = file.read_text()
    assert text.count("bool(job.seed)") == 1
    try:
        file.write_text(text.replace("bool(job.seed)", "not job.seed"))
        assert identity.code_identity(code_copy) != before
    finally:
        file.write_text(text)


def test_the_python_version_changes_the_key(code_copy, monkeypatch):
    from bench.runs import identity

    before = identity.code_identity(code_copy)
    monkeypatch.setattr(identity.platform, "python_version", lambda: "3.99.0")
    assert identity.code_identity(code_copy) != before


# ---- the libraries a run imported (bench/runs/libraries.py) ---------------------------------

_RUN_RECORDING = """
import ast, json, sys
from importlib import metadata
from pathlib import Path
import bench.cli  # the command line's own libraries (rich, typer) are loaded, not the run's
from bench.runs.job import Job, run_job
from bench.runs.plan import plan
job = plan([Job(store=Path(sys.argv[1]), method=sys.argv[3], seed=None,
                out_root=Path(sys.argv[2]))])[0]
outcome = run_job(job)
# independently of bench.runs.libraries: the installed distributions' file lists, and the
# import statements of the run path's files parsed by ast
provided = metadata.packages_distributions()
loaded = {name.partition(".")[0] for name in list(sys.modules)}
root = Path(sys.argv[4])
files = [*root.glob("loaders/**/*.py"), *root.glob("methods/*.py"), *root.glob("metrics/*.py"),
         *(root / "bench" / "runs" / f for f in ("job.py", "executors.py", "evaluate.py",
                                                  "result.py", "folders.py", "timed.py"))]
imported = set()
for f in files:
    for node in ast.walk(ast.parse(f.read_text())):
        if isinstance(node, ast.Import):
            imported |= {a.name.partition(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            imported.add(node.module.partition(".")[0])
print(json.dumps({"status": outcome.status, "message": outcome.message,
                  "loaded": sorted({d for m in loaded for d in provided.get(m, [])}),
                  "used": sorted({d for m in loaded & imported for d in provided.get(m, [])}),
                  "run_dir": str(outcome.run_dir)}))
"""


def _run_in_fresh_process(store, out, method="doppler", extra_path=()):
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    path = os.pathsep.join([*map(str, extra_path), str(root)])
    done = subprocess.run([sys.executable, "-c", _RUN_RECORDING, str(store), str(out), method,
                           str(root)],
                          capture_output=True, text=True, timeout=300, cwd=root,
                          env={**os.environ, "PYTHONPATH": path})
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.splitlines()[-1])


def _fake_distribution(folder, name, version, module=None):
    """A distribution as pip installs it, enough for importlib.metadata (and a module)."""
    info = folder / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    if module:
        (folder / module).mkdir()
        (folder / module / "__init__.py").write_text("")
    return folder


def _norm(name):
    return name.lower().replace("-", "_")


def test_a_run_records_every_library_it_imported_and_no_other(store, tmp_path):
    """Checked against reality in a fresh process that also loaded the command line: every
    loaded distribution whose modules the run path's code imports (found independently: the
    installed distributions' file lists, the files' import statements parsed by ast) is
    recorded with its version, and so are the loaded libraries those require (numba's
    llvmlite, pydantic's pydantic-core); the command line's rich and typer, loaded in the same
    process, are not, nor Open3D or kiss-icp, which other methods import."""
    from importlib import metadata

    result = _run_in_fresh_process(store, tmp_path / "runs")
    assert result["status"] == "done", result["message"]
    config = yaml.safe_load((Path(result["run_dir"]) / "config.yaml").read_text())
    recorded = {_norm(k): v for k, v in config["libraries"].items()}
    used = {_norm(d) for d in result["used"]} - {"doppler_bench"}
    assert {"numpy", "scipy", "numba", "h5py", "pydantic", "pyyaml"} <= used
    assert used <= set(recorded), used - set(recorded)
    assert {"llvmlite", "pydantic_core"} <= set(recorded)
    assert all(v == metadata.version(k) for k, v in config["libraries"].items() if k != "python")
    loaded = {_norm(d) for d in result["loaded"]}
    assert {"rich", "typer"} <= loaded and not {"rich", "typer"} & set(recorded)
    assert not {"open3d_cpu", "open3d", "kiss_icp"} & set(recorded)


def test_installing_an_unrelated_library_reruns_nothing_a_used_one_reruns(store, tmp_path):
    """A doppler run is reused when Open3D (another method's library) appears at another
    version, and runs again when the NumPy it imported is installed at another version."""
    out = tmp_path / "runs"
    assert _run_in_fresh_process(store, out)["status"] == "done"
    assert _run_in_fresh_process(store, out)["status"] == "skipped"
    extra = _fake_distribution(tmp_path / "extra", "open3d-cpu", "0.99.0", module="open3d")
    _fake_distribution(extra, "rerun-sdk", "0.99.0")
    assert _run_in_fresh_process(store, out, extra_path=[extra])["status"] == "skipped"
    numpy = _fake_distribution(tmp_path / "numpy", "numpy", "0.0.1")
    changed = _run_in_fresh_process(store, out, extra_path=[numpy])
    assert changed["status"] == "done"
    config = yaml.safe_load((Path(changed["run_dir"]) / "config.yaml").read_text())
    assert config["libraries"]["numpy"] == "0.0.1"
    assert _run_in_fresh_process(store, out)["status"] == "done"  # the real NumPy again


def test_libraries_current_compares_each_recorded_version():
    from importlib import metadata

    from bench.runs.libraries import changed_libraries, libraries_current

    real = metadata.version("numpy")
    assert libraries_current({"numpy": real}) and libraries_current(None)
    assert not libraries_current({"numpy": "0.0.1"})
    assert changed_libraries({"numpy": "0.0.1", "no-such-dist-xyz": None}) == {
        "numpy": ("0.0.1", real)}
    assert not libraries_current({"no-such-dist-xyz": "1.0"})


def test_another_cpu_or_thread_setting_reruns_the_job(store, tmp_path, monkeypatch):
    """The key covers the host: a time measured on another CPU model or with other library
    thread settings is not reused."""
    from bench.runs import identity

    job = Job(store=store, method="doppler", seed=None, out_root=tmp_path)
    assert run_job(job).status == "done"
    assert run_job(job).status == "skipped"
    config = yaml.safe_load(next(tmp_path.rglob("config.yaml")).read_text())
    assert config["identity"]["host"]["cpu"] == identity.cpu_model()
    assert config["identity"]["host"]["threads"]["OPENBLAS_NUM_THREADS"] == "1"
    monkeypatch.setattr(identity, "cpu_model", lambda: "Another CPU 9000")
    assert run_job(job).status == "done"
    assert run_job(job).status == "skipped"
    monkeypatch.setattr(identity, "thread_settings", lambda: {"OMP_NUM_THREADS": "4"})
    assert run_job(job).status == "done"
    assert run_job(job).status == "skipped"
    # the same model name with other instruction-set flags (numba compiles for them): rerun
    assert config["identity"]["host"]["cpu_flags"] == identity.cpu_flags_digest()
    monkeypatch.setattr(identity, "cpu_flags_digest", lambda: "another-flags-digest")
    assert run_job(job).status == "done"
    assert run_job(job).status == "skipped"


def test_a_table_of_times_from_two_cpus_says_so(store, tmp_path):
    from bench.report.tables.model import to_markdown
    from bench.report.tables.paper import relative_table, select

    for method in ("doppler", "icp-p2p"):
        assert run_job(Job(store=store, method=method, seed=None if method == "doppler"
                           else True, out_root=tmp_path)).status == "done"
    rows, lengths = select(tmp_path)
    assert len(rows) == 2 and "MIXED HOSTS" not in to_markdown(relative_table(rows, lengths))
    metrics_file = next(tmp_path.rglob("icp-p2p_seed/metrics.json"))
    metrics = json.loads(metrics_file.read_text())
    metrics_file.write_text(json.dumps({**metrics, "cpu": "Another CPU 9000"}))
    rows, lengths = select(tmp_path)
    text = to_markdown(relative_table(rows, lengths))
    assert "MIXED HOSTS" in text and "Another CPU 9000" in text and metrics["cpu"] in text


_CPUINFO = """processor\t: 0
vendor_id\t: AuthenticAMD
cpu family\t: {family}
model\t\t: {model}
model name\t: AMD EPYC
stepping\t: 1
flags\t\t: fpu sse2 avx2 {extra}

processor\t: 1
vendor_id\t: AuthenticAMD
model name\t: AMD EPYC
"""


def test_the_cpu_model_is_the_full_description_and_tells_generations_apart():
    """A virtual machine names two CPU generations "AMD EPYC"; the description keeps the full
    model name and adds vendor, family, model and stepping, and the flags digest tells
    instruction sets apart (numba compiles for them)."""
    from bench.runs.provenance import cpu_flags_digest, cpu_model

    zen3 = _CPUINFO.format(family=25, model=1, extra="")
    zen4 = _CPUINFO.format(family=25, model=17, extra="avx512f")
    assert cpu_model(zen3) == "AMD EPYC (AuthenticAMD family 25 model 1 stepping 1)"
    assert cpu_model(zen4) != cpu_model(zen3)
    assert cpu_flags_digest(zen4) != cpu_flags_digest(zen3)
    assert cpu_flags_digest("model name\t: X\n") is None
    long_name = "Intel(R) Xeon(R) Gold 6248R CPU @ 3.00GHz"
    assert cpu_model(f"model name\t: {long_name}\n") == long_name


def test_this_machines_cpu_model_holds_its_whole_model_name_line():
    """Read independently: the text after the first "model name" colon of /proc/cpuinfo."""
    from bench.runs.provenance import cpu_model

    lines = Path("/proc/cpuinfo").read_text().splitlines()
    name = next(x for x in lines if x.startswith("model name")).split(":", 1)[1].strip()
    family = next(x for x in lines if x.startswith("cpu family")).split(":", 1)[1].strip()
    assert cpu_model().startswith(name + " (") and f"family {family} " in cpu_model()


def test_renaming_a_module_changes_the_key(code_copy):
    """The key holds every file's path beside its content: the same bytes under another module
    name are other code (imports resolve by name)."""
    from bench.runs import identity

    before = identity.code_identity(code_copy)
    old = code_copy / "metrics" / "timing.py"
    new = code_copy / "metrics" / "timing_renamed.py"
    old.rename(new)
    try:
        assert identity.code_identity(code_copy) != before
    finally:
        new.rename(old)
    assert identity.code_identity(code_copy) == before


def test_a_librarys_requirements_leave_out_those_of_its_extras():
    """pydantic requires pydantic-core always, email-validator only for its ``email`` extra:
    a run that loaded pydantic records the one, never the other (even if something else loaded
    it)."""
    from bench.runs.libraries import _requirements

    required = _requirements("pydantic")
    assert "pydantic-core" in required and "annotated-types" in required
    assert "email-validator" not in required and "tzdata" not in required
    assert _requirements("no-such-dist-xyz") == []


def test_another_python_version_counts_as_a_changed_library():
    import platform

    from bench.runs.libraries import changed_libraries, libraries_current

    now = platform.python_version()
    assert libraries_current({"python": now})
    assert changed_libraries({"python": "2.7.18"}) == {"python": ("2.7.18", now)}


def test_library_lookups_are_read_once_per_process(monkeypatch):
    """After a run, the libraries it loaded are named and versioned from the installed
    distributions' metadata; within one process that is read once (a run of 50 frames spent
    about 55 ms re-reading it), and the second answer is the first."""
    from importlib import metadata

    from bench.runs.libraries import imported_libraries
    from bench.runs.provenance import installed_versions

    first = imported_libraries()
    packages = installed_versions(("numpy", "no-such-dist-xyz"))
    assert {"python", "numpy"} <= set(first) and packages["no-such-dist-xyz"] is None
    read = []
    for name in ("distribution", "requires", "version", "metadata", "packages_distributions"):
        real = getattr(metadata, name)
        monkeypatch.setattr(metadata, name, lambda *a, real=real, name=name, **k:
                            read.append(name) or real(*a, **k))
    assert imported_libraries() == first
    assert installed_versions(("numpy", "no-such-dist-xyz")) == packages
    assert read == []
