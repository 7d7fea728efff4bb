"""bench.runs.plan: what the mutation run (``tools/mutate.py``) found untested.

The planning helpers are called on jobs, folders and ground truths made here; the expected
lengths and messages are worked out by hand from the rule they state (a segment of length L
fits a path of P metres when 0.8 L <= P; a KITTI length L needs P > L)."""

from __future__ import annotations

import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from bench.runs import plan as planning
from bench.runs.experiment import SequenceEntry
from bench.runs.job import Job
from bench.runs.plan import (
    REFUSED,
    SEGMENT_TOLERANCE,
    _check_writable,
    _doppler_problem,
    _gt_path_length,
    _is_pattern,
    _lengths_problems,
    _names,
    _other_content,
    _wanted,
    single_job,
)
from loaders.errors import DataError
from loaders.trajectory import Trajectory
from metrics.kitti import KITTI_LENGTHS_M

# ---- which sequences a method runs on -------------------------------------------------------

def _entry(name="seq", path="/data/store-file.h5", display="Seq Display"):
    return SequenceEntry(path=Path(path), name=name, display_name=display)


def test_a_sequence_is_known_by_its_name_its_store_and_its_display_name():
    assert _names(_entry()) == {"seq", "store-file", "Seq Display"}
    assert _names(_entry(display=None)) == {"seq", "store-file"}


@pytest.mark.parametrize("name, pattern", [("seq*", True), ("seq?", True), ("[ab]", True),
                                           ("seq", False), ("a.b-c", False), ("SEQX", False)])
def test_a_pattern_has_a_wildcard(name, pattern):
    assert _is_pattern(name) is pattern


@pytest.mark.parametrize("patterns, wanted", [
    (None, True), (["seq"], True), (["store-*"], True), (["Seq Disp?ay"], True),
    (["SEQ"], False), (["other", "s*q"], True), (["other"], False), ([], False)])
def test_a_methods_sequences_select_by_any_name_case_sensitively(patterns, wanted):
    assert _wanted(_entry(), patterns) is wanted


# ---- single_job -----------------------------------------------------------------------------

def test_a_single_job_runs_into_the_folder_given_with_the_scoring_given():
    job = single_job("icp-p2p", Path("s.h5"), True, Path("out/run"), {"a": 1},
                     {"lengths_m": (5.0,), "alignment": None, "kitti_lengths_m": None})
    assert job.store == Path("s.h5") and job.method == "icp-p2p" and job.seed is True
    assert job.out_root == Path("results/runs") and job.run_dir_override == Path("out/run")
    assert job.params == {"a": 1} and job.lengths_m == (5.0,)
    assert job.alignment == "se3" and job.kitti_lengths_m == KITTI_LENGTHS_M
    default = single_job("doppler", Path("s.h5"), True, None, {})
    assert default.run_dir_override is None and default.seed is None  # no seed option


# ---- segment lengths against the ground truth's path ----------------------------------------

def _job(lengths=(10.0, 50.0, 70.0), kitti=KITTI_LENGTHS_M, name="seq"):
    return Job(store=Path("/data/store.h5"), method="doppler", seed=None, out_root=Path("r"),
               lengths_m=lengths, kitti_lengths_m=kitti, name=name)


def _said(call):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        out = call()
    return out, [str(w.message) for w in said]


def test_lengths_the_path_is_too_short_for_are_said_once_per_sequence():
    warned: set[str] = set()
    problems, said = _said(lambda: _lengths_problems(_job(), 50.0, warned))
    assert problems == []
    assert said == [
        "seq: the ground truth's path is 50.0 m long: no segments of 70 m (their cells stay "
        "empty)",
        "seq: the ground truth's path is 50.0 m long: no KITTI drift (its shortest length is "
        "100 m)"]
    assert warned == {"seq", "kitti:seq"}
    assert _said(lambda: _lengths_problems(_job(), 50.0, warned)) == ([], [])
    # another sequence is said again
    assert len(_said(lambda: _lengths_problems(_job(name="other"), 50.0, warned))[1]) == 2


def test_the_boundaries_of_a_fitting_length_are_inclusive_for_segments_only():
    # 0.8 x 62.5 = 50: the 62.5 m segment fits a 50 m path; a 50 m KITTI length does not
    problems, said = _said(lambda: _lengths_problems(_job((62.5,), (50.0, 40.0)), 50.0, set()))
    assert problems == [] and said == [
        "seq: the ground truth's path is 50.0 m long: KITTI drift leaves out 50 m"]
    assert SEGMENT_TOLERANCE == 0.2


def test_kitti_lengths_left_out_are_listed():
    _, said = _said(lambda: _lengths_problems(_job((10.0,)), 250.0, set()))
    assert said == ["seq: the ground truth's path is 250.0 m long: KITTI drift leaves out 300, "
                    "400, 500, 600, 700, 800 m"]
    assert _said(lambda: _lengths_problems(_job((10.0,)), 900.0, set())) == ([], [])


def test_no_fitting_length_is_an_error_saying_which_lengths_would_fit():
    problems, said = _said(lambda: _lengths_problems(_job((30.0, 40.0)), 20.0, set()))
    assert problems == ["/data/store.h5: the ground truth's path is 20.0 m long, too short for "
                        "the shortest segment length 30 m; choose lengths_m up to 25 m"]
    assert said == []


def test_without_ground_truth_or_name_the_lengths_are_not_checked_or_named_by_the_store():
    assert _lengths_problems(_job((1000.0,)), None, set()) == []
    _, said = _said(lambda: _lengths_problems(_job((10.0, 70.0), name=None), 50.0, set()))
    assert said[0].startswith("store: the ground truth's path is 50.0 m long")


# ---- the ground truth's path length ---------------------------------------------------------

class _Seq(SimpleNamespace):
    def __len__(self):
        return len(self.stamps)


def _straight(n=11, step=2.0):
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 3] = np.arange(n) * step
    return Trajectory(np.arange(n) * 0.1, poses)


def test_the_path_length_is_that_of_the_scored_ground_truth():
    gt = _straight()  # 10 steps of 2 m
    seq = _Seq(ground_truth=gt, stamps=gt.stamps, provenance={})
    assert _gt_path_length(SimpleNamespace(sequence=seq)) == pytest.approx(20.0)
    # frames 0-4 calibrated on: the path of frames 5-10 (5 steps)
    seq.provenance = {"calibration": {"frames": [0, 5]}}
    assert _gt_path_length(SimpleNamespace(sequence=seq)) == pytest.approx(10.0)
    seq.provenance = {"calibration": {"frames": [0, 10]}}  # one scored frame: no path
    assert _gt_path_length(SimpleNamespace(sequence=seq)) is None


def test_no_ground_truth_or_a_single_pose_has_no_path_length():
    one = _straight(1)
    for gt in (None, one):
        seq = _Seq(ground_truth=gt, stamps=np.array([0.0]), provenance={})
        assert _gt_path_length(SimpleNamespace(sequence=seq)) is None
    gt = _straight(2)
    seq = _Seq(ground_truth=gt, stamps=gt.stamps, provenance={})
    assert _gt_path_length(SimpleNamespace(sequence=seq)) == pytest.approx(2.0)


# ---- another store under the same name ------------------------------------------------------

def _run_config(folder: Path, store="/data/a.h5", sha="a" * 64, name="seq"):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "config.yaml").write_text(yaml.safe_dump(
        {"sequence": {"name": name, "store": store}, "identity": {"store_sha256": sha}}))


def test_a_folder_holding_a_run_of_another_store_is_refused(tmp_path):
    _run_config(tmp_path / "run")
    problem = _other_content(tmp_path / "run", Path("/data/b.h5"), "b" * 64)
    assert problem == (
        f"{tmp_path / 'run'}: holds a run of sequence 'seq' from /data/a.h5 (SHA-256 "
        f"{'a' * 12}); /data/b.h5 (SHA-256 {'b' * 12}) is another store of that name and would "
        "replace it: name it apart (bench convert --name, an experiment's name:) or give the "
        "run another --out")


def test_a_folder_of_the_same_store_or_content_or_of_no_run_is_taken(tmp_path):
    _run_config(tmp_path / "run")
    assert _other_content(tmp_path / "run", Path("/data/b.h5"), "a" * 64) is None  # content
    assert _other_content(tmp_path / "run", Path("/data/x/../a.h5"), "b" * 64) is None  # path
    assert _other_content(tmp_path / "empty", Path("/data/b.h5"), "b" * 64) is None
    for text in ("- a list\n", "sequence: [broken", "sequence: name\nidentity: 3\n",
                 "sequence: {store: /data/a.h5}\n", "identity: {store_sha256: abc}\n"):
        (tmp_path / "run" / "config.yaml").write_text(text)
        assert _other_content(tmp_path / "run", Path("/data/b.h5"), "b" * 64) is None, text


# ---- writable folders -----------------------------------------------------------------------

def test_a_run_folder_under_a_file_is_refused(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(DataError, match=r"is a file"):
        _check_writable(tmp_path / "file" / "seq" / "run")


def test_a_run_folder_under_an_unwritable_folder_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(planning, "_writable", lambda path: path != tmp_path / "locked")
    (tmp_path / "locked").mkdir()
    with pytest.raises(DataError, match=r"^.*/locked/seq/run: cannot write results here: "
                                        r".*/locked is not writable$"):
        _check_writable(tmp_path / "locked" / "seq" / "run")
    _check_writable(tmp_path / "open" / "seq" / "run")


def test_writable_is_the_operating_systems_answer(tmp_path):
    import os

    assert planning._writable(tmp_path) == os.access(tmp_path, os.W_OK | os.X_OK) is True
    assert planning._writable(tmp_path / "missing") is False


# ---- Doppler ---------------------------------------------------------------------------------

def test_a_method_needing_doppler_says_how_to_run_it(monkeypatch):
    monkeypatch.setattr(planning, "doppler_refusal",
                        lambda store, method, seq: "s.h5 has no Doppler values")
    job = Job(store=Path("s.h5"), method="doppler", seed=None, out_root=Path("r"))
    assert _doppler_problem(job, None) == (
        "s.h5 has no Doppler values, or run a method that needs none (icp-p2p, gicp, kiss-icp, "
        "...), or leave this store out of doppler (the method's `sequences:` list in the "
        "experiment)")
    monkeypatch.setattr(planning, "doppler_refusal",
                        lambda store, method, seq: "s.h5 has ego-compensated Doppler")
    assert _doppler_problem(job, None) == (
        "s.h5 has ego-compensated Doppler, or run a method that needs no Doppler, or leave this "
        "store out of doppler (the method's `sequences:` list in the experiment)")
    monkeypatch.setattr(planning, "doppler_refusal", lambda store, method, seq: None)
    assert _doppler_problem(job, None) is None


def test_a_method_needing_no_doppler_is_never_refused(monkeypatch):
    monkeypatch.setattr(planning, "doppler_refusal",
                        lambda *a: pytest.fail("asked about a method that needs no Doppler"))
    job = Job(store=Path("s.h5"), method="icp-p2p", seed=True, out_root=Path("r"))
    assert _doppler_problem(job, None) is None


def test_a_refused_pair_is_recorded_unless_the_folder_holds_a_finished_run(tmp_path):
    import json

    run_dir = tmp_path / "seq" / "doppler"
    planning._record_refusal(run_dir, {"run_key": "k"}, "no Doppler")
    info = json.loads((run_dir / "failed.json").read_text())
    assert info["status"] == REFUSED == "refused" and info["error"] == "no Doppler"
    assert yaml.safe_load((run_dir / "config.yaml").read_text()) == {"run_key": "k"}
    finished = tmp_path / "seq" / "done"
    finished.mkdir(parents=True)
    (finished / "metrics.json").write_text("{}")
    planning._record_refusal(finished, {"run_key": "k"}, "no Doppler")
    assert not (finished / "failed.json").exists()


# ---- jobs_for_experiment --------------------------------------------------------------------

def _experiment(tmp_path, sequences: str, methods: str, extra: str = ""):
    from bench.runs.experiment import load_experiment

    for name in ("a.h5", "b.h5"):
        (tmp_path / name).write_bytes(b"")  # only their existence is planned here
    path = tmp_path / "e.yaml"
    path.write_text(f"name: e\nsequences: {sequences}\nmethods: {methods}\n"
                    f"lengths_m: [8, 16]\nout: results\n{extra}")
    return load_experiment(path)


def test_every_sequence_method_variant_and_seed_option_is_a_job(tmp_path):
    exp = _experiment(
        tmp_path,
        f"[{{path: {tmp_path / 'a.h5'}, name: A, display_name: Aa, sensor_class: radar, "
        f"start: 2, frames: 5}}, {{path: {tmp_path / 'b.h5'}, name: B}}]",
        "[{name: doppler, sequences: [A]}, {name: icp-p2p, label: p, params: {max_iterations: 7}}]",
        "kitti_lengths_m: [50]\nalignment: sim3\n")
    jobs = planning.jobs_for_experiment(exp)
    assert [(j.name, j.method, j.seed) for j in jobs] == [
        ("A", "doppler", None), ("A", "icp-p2p", True), ("A", "icp-p2p", False),
        ("B", "icp-p2p", True), ("B", "icp-p2p", False)]
    first, icp = jobs[0], jobs[1]
    assert first.store == tmp_path / "a.h5" and first.out_root == tmp_path / "results"
    assert (first.display_name, first.sensor_class, first.frame_range) == ("Aa", "radar", (2, 5))
    assert first.lengths_m == (8.0, 16.0) and first.kitti_lengths_m == (50.0,)
    assert first.alignment == "sim3" and first.label is None and first.params == {}
    assert icp.label == "p" and icp.params == {"max_iterations": 7}
    assert jobs[3].frame_range is None and jobs[3].display_name is None


def test_an_experiment_without_stores_or_with_a_missing_one_is_one_error(tmp_path):
    missing = tmp_path / "missing.h5"
    exp = _experiment(tmp_path, f"[{{path: {missing}, optional: true}}]", "[{name: doppler}]")
    with pytest.raises(DataError, match=r"^experiment 'e': none of its stores exist \(convert "
                                        r"them first: `bench datasets` lists the commands\)$"):
        _said(lambda: planning.jobs_for_experiment(exp))
    exp = _experiment(tmp_path, f"[{{path: {tmp_path / 'a.h5'}}}, {{path: {missing}}}]",
                      "[{name: doppler}]")
    with pytest.raises(DataError, match=rf"^experiment 'e': stores not found: {missing}$"):
        planning.jobs_for_experiment(exp)


def test_a_method_naming_an_unknown_sequence_is_an_error_unless_a_pattern_or_optional(tmp_path):
    a = tmp_path / "a.h5"
    exp = _experiment(tmp_path, f"[{{path: {a}, name: A}}]",
                      "[{name: doppler, sequences: [A, zz, yy, 'x*']}]")
    with pytest.raises(DataError, match=r"^experiment 'e': method 'doppler' names unknown "
                                        r"sequences yy, zz$"):
        planning.jobs_for_experiment(exp)
    exp = _experiment(tmp_path, f"[{{path: {a}, name: A}}, {{path: {tmp_path / 'no.h5'}, "
                                "optional: true}]", "[{name: doppler, sequences: [A, zz]}]")
    (jobs, said) = _said(lambda: planning.jobs_for_experiment(exp))
    assert [j.name for j in jobs] == ["A"] and len(said) == 1 and said[0].startswith("e: ")


def test_what_the_planning_says_goes_to_the_console_when_there_is_one(tmp_path):
    from rich.console import Console

    exp = _experiment(tmp_path, f"[{{path: {tmp_path / 'a.h5'}}}, {{path: {tmp_path / 'n.h5'}, "
                                "optional: true, dataset: NTU}]", "[{name: doppler}]")
    exp = exp.model_copy(update={"sequences": [
        exp.sequences[0], exp.sequences[1].model_copy(update={"dataset": "[bold]NTU[/bold]"})]})
    console = Console(record=True, width=30)
    jobs, said = _said(lambda: planning.jobs_for_experiment(exp, console))
    assert len(jobs) == 1 and said == []
    text = console.export_text()
    # printed as it is (no markup) and on one line (no wrapping at the console's width)
    assert text.startswith("e: skipped [bold]NTU[/bold]: store ") and text.count("\n") == 1


def test_a_suite_and_synthetic_sequences_join_the_experiments_stores(tmp_path, monkeypatch):
    exp = _experiment(tmp_path, f"[{{path: {tmp_path / 'a.h5'}, name: A}}]", "[{name: doppler}]")
    exp = exp.model_copy(update={"suite": "mini", "synthetic": ["an entry"]})
    asked = []

    def suite(name, data_dir, console):
        asked.append(("suite", name, data_dir, console))
        return [_entry("S", tmp_path / "b.h5", None)]

    def synthetic(experiment, console):
        asked.append(("synthetic", experiment is exp, console))
        return [_entry("T", tmp_path / "b.h5", None)]

    monkeypatch.setattr(planning, "suite_sequences", suite)
    monkeypatch.setattr(planning, "synthetic_sequences", synthetic)
    jobs = planning.jobs_for_experiment(exp, "console")
    assert [j.name for j in jobs] == ["A", "S", "T"]
    assert asked == [("suite", "mini", exp.data_dir, "console"), ("synthetic", True, "console")]


# ---- synthetic sequences --------------------------------------------------------------------

def test_a_suite_is_generated_and_its_stores_described(tmp_path, monkeypatch):
    import loaders.synthetic

    asked = []
    entries = [SimpleNamespace(name="s1", display="Scene One", klass="4D Radar"),
               SimpleNamespace(name="s2", display="Scene Two", klass="Dense LiDAR")]

    def ensure(suite, data_dir, console):
        asked.append((suite, data_dir, console))
        return [data_dir / "s1.h5", data_dir / "s2.h5"]

    monkeypatch.setattr(planning, "ensure_suite_with_progress", ensure)
    monkeypatch.setattr(loaders.synthetic, "suite_entries",
                        lambda suite: entries if suite == "mini" else pytest.fail(suite))
    console = object()
    got = planning.suite_sequences("mini", tmp_path, console)
    assert asked == [("mini", tmp_path, console)]
    assert [(s.path, s.name, s.display_name, s.sensor_class) for s in got] == [
        (tmp_path / "s1.h5", "s1", "Scene One", "4D Radar"),
        (tmp_path / "s2.h5", "s2", "Scene Two", "Dense LiDAR")]


def test_a_suite_whose_stores_do_not_match_its_entries_is_an_error(tmp_path, monkeypatch):
    import bench.data.synth
    import loaders.synthetic

    one = [SimpleNamespace(name="s1", display="S", klass="4D Radar")]
    monkeypatch.setattr(planning, "ensure_suite_with_progress", lambda *a: [])
    monkeypatch.setattr(loaders.synthetic, "suite_entries", lambda suite: one)
    with pytest.raises(ValueError):
        planning.suite_sequences("mini", tmp_path)
    monkeypatch.setattr(bench.data.synth, "ensure_entries_with_progress", lambda *a: [])
    entry = SimpleNamespace(suite_entry=lambda: one[0])
    exp = SimpleNamespace(data_dir=tmp_path, synthetic=[entry])
    with pytest.raises(ValueError):
        planning.synthetic_sequences(exp)


def test_an_experiments_own_synthetic_sequences_are_written_under_its_data_folder(
        tmp_path, monkeypatch):
    import bench.data.synth

    asked = []

    def ensure(entries, out_dir, console):
        asked.append(([e.name for e in entries], out_dir, console))
        return [out_dir / f"{e.name}.h5" for e in entries]

    monkeypatch.setattr(bench.data.synth, "ensure_entries_with_progress", ensure)
    exp = SimpleNamespace(data_dir=tmp_path / "data", synthetic=[
        SimpleNamespace(suite_entry=lambda: SimpleNamespace(name="t1", display="T One",
                                                            klass="4D Radar"))])
    got = planning.synthetic_sequences(exp, "console")
    assert asked == [(["t1"], tmp_path / "data" / "synthetic-entries", "console")]
    assert [(s.path, s.name, s.display_name, s.sensor_class) for s in got] == [
        (tmp_path / "data" / "synthetic-entries" / "t1.h5", "t1", "T One", "4D Radar")]


# ---- run_single -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def small_store(tmp_path_factory):
    from conftest import constant_twist_sequence
    from loaders.store import write_store

    seq = constant_twist_sequence(n_frames=12, n_points=400, max_range_m=60)
    return write_store(seq, tmp_path_factory.mktemp("data") / "small.h5")


def test_run_single_runs_once_and_reuses_its_run(small_store, tmp_path):
    out = tmp_path / "run"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = planning.run_single("doppler", small_store, params={"tau_spatial_m": 2.0},
                                    out=out)
        assert first.dir == out and first.method == "doppler" and first.result.finished
        assert first.result.frames == 12
        mtime = (out / "metrics.json").stat().st_mtime_ns
        again = planning.run_single("doppler", small_store, params={"tau_spatial_m": 2.0},
                                    out=str(out))
        assert (out / "metrics.json").stat().st_mtime_ns == mtime  # reused, not run again
        assert again.result == first.result
        # a folder holding another method's run is never taken
        with pytest.raises(DataError, match="bench run"):
            planning.run_single("icp-p2p", small_store, out=out)


def test_run_single_raises_the_failure_of_its_run(small_store, tmp_path, monkeypatch):
    from bench.runs.job import JobOutcome

    seen = []

    def failing(job, force):
        seen.append((job.method, job.seed, force, job.run_key is not None))
        return JobOutcome(job, "failed", "it broke")

    monkeypatch.setattr(planning, "run_job", failing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(DataError, match=rf"^icp-p2p on {small_store}: it broke$"):
            planning.run_single("icp-p2p", small_store, seed=False, out=tmp_path / "r",
                                force=True)
    assert seen == [("icp-p2p", False, True, True)]
