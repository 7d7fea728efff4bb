"""bench.runs.plan's ``plan``: what the mutation run (``tools/mutate.py``) found untested.

``plan`` is called in this process on jobs over tiny stores written here (8 frames of a
constant twist, a few hundred points: no method runs). Expected folders, keys and messages
come from the rules ``plan`` states (a folder per sequence and method, one run per folder,
every problem in one error) and from the job module's own resolution (``prepare``), which
``plan`` only collects."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import warnings
from pathlib import Path

import pytest
import yaml

from bench.runs import plan as planning
from bench.runs.job import Job, prepare
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import write_store


def _store(path: Path, name: str, doppler_kind: str = "radial", v=(8.0, 0.0, 0.0)) -> Path:
    seq = constant_twist_sequence(n_frames=8, n_points=300, v=v, max_range_m=60)
    seq.name = name
    seq.sensor = dataclasses.replace(seq.sensor, doppler_kind=doppler_kind)
    return write_store(seq, path)


@pytest.fixture(scope="module")
def stores(tmp_path_factory) -> dict[str, Path]:
    """Two stores of one sequence name and different content (a 5.6 m path each: 7 steps of
    0.8 m), one with ego-compensated Doppler and one of a 14 m path (for the default
    lengths)."""
    folder = tmp_path_factory.mktemp("plan-stores")
    return {"a": _store(folder / "a.h5", "loop"),
            "b": _store(folder / "b" / "a.h5", "loop", v=(7.0, 0.0, 0.0)),
            "ego": _store(folder / "ego.h5", "ego", doppler_kind="ego-compensated"),
            "long": _store(folder / "long.h5", "long", v=(20.0, 0.0, 0.0))}


def _job(store: Path, out: Path, method: str = "icp-p2p", seed=True, **fields) -> Job:
    fields.setdefault("lengths_m", (2.0,))
    fields.setdefault("kitti_lengths_m", (1.0,))
    return Job(store=store, method=method, seed=seed, out_root=out, **fields)


def _quiet(call):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        out = call()
    return out, [str(w.message) for w in said]


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# ---- the planned jobs -----------------------------------------------------------------------

def test_each_job_is_planned_with_its_folder_key_and_identities(stores, tmp_path):
    jobs = [_job(stores["a"], tmp_path), _job(stores["a"], tmp_path, seed=False),
            _job(stores["a"], tmp_path, method="doppler", seed=None, label="tau 2",
                 params={"tau_spatial_m": 2.0})]
    planned, said = _quiet(lambda: planning.plan(jobs))
    assert said == []
    assert [j.run_dir_override for j in planned] == [
        tmp_path / "loop" / "icp-p2p_seed", tmp_path / "loop" / "icp-p2p_noseed",
        tmp_path / "loop" / "tau-2"]
    for job, got in zip(jobs, planned, strict=True):
        prep = prepare(job)
        prep.sequence.close()
        assert got.run_key == prep.key and len(got.run_key) > 8
        assert got.store_sha256 == _sha256(stores["a"])
        assert got.code_sha256 == prep.config["identity"]["code_sha256"]
        assert dataclasses.replace(got, run_dir_override=None, run_key=None,
                                   store_sha256=None, code_sha256=None) == job
    assert len({j.run_key for j in planned}) == 3
    assert not any(p.exists() for p in (tmp_path / "loop").glob("*"))  # nothing written


def test_the_same_run_asked_for_twice_is_planned_once(stores, tmp_path):
    job = _job(stores["a"], tmp_path)
    other = _job(stores["a"], tmp_path, seed=False)
    planned = planning.plan([job, other, job])
    assert [j.run_dir_override.name for j in planned] == ["icp-p2p_seed", "icp-p2p_noseed"]


def test_every_store_is_closed_once_planned(stores, tmp_path, monkeypatch):
    opened = []

    def spy(job):
        prep = prepare(job)
        opened.append(prep.sequence)
        return prep

    monkeypatch.setattr(planning, "prepare", spy)
    planning.plan([_job(stores["a"], tmp_path), _job(stores["a"], tmp_path, seed=False)])
    refused: list[str] = []
    planning.plan([_job(stores["ego"], tmp_path, method="doppler", seed=None)], refused)
    assert len(opened) == 3 and all(s._h5 is None for s in opened)


# ---- every problem in one error -------------------------------------------------------------

def test_every_problem_is_listed_once_in_one_error(stores, tmp_path):
    bad = _job(stores["a"], tmp_path, params={"no_such_parameter": 1})
    missing = _job(tmp_path / "missing.h5", tmp_path)
    with pytest.raises(DataError) as raised:
        planning.plan([bad, missing, bad, _job(stores["a"], tmp_path, seed=False)])
    lines = str(raised.value).split("\n")
    assert len(lines) == 2 and "no_such_parameter" in lines[0]
    assert lines[1] == f"{tmp_path / 'missing.h5'}: store not found"


def test_a_store_whose_doppler_the_method_cannot_use_is_a_problem_or_a_refused_pair(
        stores, tmp_path):
    refusing = _job(stores["ego"], tmp_path, method="doppler", seed=None)
    fine = _job(stores["ego"], tmp_path)
    with pytest.raises(DataError, match=r"ego-compensated.*or run a method that needs no "
                                        r"Doppler") as raised:
        planning.plan([refusing, fine])
    assert "\n" not in str(raised.value)  # the other job is no problem
    assert not (tmp_path / "ego").exists()  # nothing recorded without a list of refusals
    refused: list[str] = []
    planned = planning.plan([refusing, fine], refused)
    assert [j.method for j in planned] == ["icp-p2p"]
    assert len(refused) == 1 and refused[0].startswith(
        f"ego / doppler: {stores['ego']}: doppler needs the raw radial Doppler velocity, but "
        "the store's Doppler is ")
    assert "or run a method that needs no Doppler" in refused[0]
    info = json.loads((tmp_path / "ego" / "doppler" / "failed.json").read_text())
    assert info["status"] == "refused" and refused[0] == f"ego / doppler: {info['error']}"
    config = yaml.safe_load((tmp_path / "ego" / "doppler" / "config.yaml").read_text())
    assert config["method"]["name"] == "doppler" and config["sequence"]["name"] == "ego"


# ---- segment lengths against the ground truth -----------------------------------------------

def test_lengths_are_checked_against_each_stores_path_once_per_sequence(stores, tmp_path,
                                                                       monkeypatch):
    # each store's path: 7 steps of 0.1 s at 8 m/s = 5.6 m (a 50 m segment cannot fit)
    measured = []
    original = planning._gt_path_length

    def spy(prep):
        measured.append(prep.sequence.path)
        return original(prep)

    monkeypatch.setattr(planning, "_gt_path_length", spy)
    jobs = [_job(stores["a"], tmp_path, lengths_m=(2.0, 50.0)),
            _job(stores["a"], tmp_path, seed=False, lengths_m=(2.0, 50.0))]
    planned, said = _quiet(lambda: planning.plan(jobs))
    assert len(planned) == 2 and measured == [stores["a"]]  # one store: measured once
    assert said == ["a: the ground truth's path is 5.6 m long: no segments of 50 m (their "
                    "cells stay empty)"]  # one sequence (the store's stem): said once
    with pytest.raises(DataError, match=r"^.*a\.h5: the ground truth's path is 5\.6 m long, "
                                        r"too short for the shortest segment length 50 m"):
        _quiet(lambda: planning.plan([_job(stores["a"], tmp_path, lengths_m=(50.0,))]))


def test_a_frame_range_is_its_own_path(stores, tmp_path):
    # frames 0-2: 2 steps of 0.8 m = 1.6 m, too short for a 2 m segment (0.8 x 2 = 1.6 fits)
    # and for 2.5 m (0.8 x 2.5 = 2.0 > 1.6)
    whole = _job(stores["a"], tmp_path, lengths_m=(2.5,))
    part = _job(stores["a"], tmp_path, seed=False, lengths_m=(2.5,), frame_range=(0, 3),
                name="first")
    with pytest.raises(DataError) as raised:
        _quiet(lambda: planning.plan([whole, part]))
    assert str(raised.value).startswith(f"{stores['a']}: the ground truth's path is 1.6 m")


# ---- one run per folder ---------------------------------------------------------------------

def test_two_runs_in_one_folder_are_a_problem_naming_both(stores, tmp_path):
    first = _job(stores["a"], tmp_path)
    other_params = _job(stores["a"], tmp_path, params={"max_iterations": 3})
    other_store = _job(stores["b"], tmp_path)
    missing = _job(tmp_path / "missing.h5", tmp_path)
    folder = tmp_path / "loop" / "icp-p2p_seed"
    advice = ("give the sequences distinct names (an experiment's sequences: name:) or the "
              "method variants distinct 'label:'s")
    with pytest.raises(DataError) as raised:
        planning.plan([first, other_params, other_store, missing])
    assert str(raised.value).split("\n") == [
        f"{folder}: two runs would share this folder (a / icp-p2p_seed and a / icp-p2p_seed); "
        + advice,
        f"{folder}: two runs would share this folder (a / icp-p2p_seed of {stores['a']} and "
        f"a / icp-p2p_seed of {stores['b']}: two stores of different content under one "
        "sequence name); " + advice,
        f"{tmp_path / 'missing.h5'}: store not found"]


def test_a_job_of_another_path_to_the_same_store_shares_its_folder_as_the_same_store(
        stores, tmp_path):
    first = _job(stores["a"], tmp_path)
    again = _job(stores["a"].parent / "b" / ".." / "a.h5", tmp_path, params={"max_iterations": 3})
    with pytest.raises(DataError) as raised:
        planning.plan([first, again])
    assert "(a / icp-p2p_seed and a / icp-p2p_seed)" in str(raised.value)


# ---- what a folder already holds ------------------------------------------------------------

def _config_of(job: Job) -> dict:
    prep = prepare(job)
    prep.sequence.close()
    return prep.config


def test_a_folder_holding_the_store_itself_is_refused(stores, tmp_path):
    import shutil

    from bench.guard import Refused

    folder = tmp_path / "run"
    folder.mkdir()
    store = Path(shutil.copy2(stores["a"], folder / "s.h5"))
    job = _job(store, tmp_path, run_dir_override=folder)
    (folder / "config.yaml").write_text(yaml.safe_dump(_config_of(job)))
    with pytest.raises(Refused, match=r"holds an input of this command"):
        planning.plan([job])


def test_a_folder_holding_a_run_of_bench_score_is_refused_without_offering_force(
        stores, tmp_path):
    from bench.guard import Refused

    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "config.yaml").write_text(yaml.safe_dump({"external": {"file": "x.txt"},
                                                        "run_key": "k"}))
    with pytest.raises(Refused) as raised:
        planning.plan([_job(stores["a"], tmp_path, run_dir_override=folder)])
    assert str(raised.value).endswith("bench run does not replace it: choose another name")


def test_a_folder_of_another_methods_run_is_refused_only_for_its_own_runs(stores, tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "config.yaml").write_text(yaml.safe_dump(
        _config_of(_job(stores["a"], tmp_path, method="doppler", seed=None))))
    job = _job(stores["a"], tmp_path, run_dir_override=folder)
    with pytest.raises(DataError, match=r": holds another run \(method 'doppler'.*\); bench run "
                                        r"would replace it with method 'icp-p2p'"):
        planning.plan([job], own_only=True)
    (planned,) = planning.plan([job])  # an experiment's folder: its own layout
    assert planned.run_dir_override == folder


def test_a_folder_holding_a_run_of_another_store_is_a_problem(stores, tmp_path):
    config = _config_of(_job(stores["b"], tmp_path))
    folder = tmp_path / "loop" / "icp-p2p_seed"
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(yaml.safe_dump(config))
    with pytest.raises(DataError) as raised:
        planning.plan([_job(stores["a"], tmp_path), _job(tmp_path / "missing.h5", tmp_path)])
    lines = str(raised.value).split("\n")
    assert len(lines) == 2 and lines[0].startswith(
        f"{folder}: holds a run of sequence 'loop' from {stores['b']} (SHA-256 "
        f"{_sha256(stores['b'])[:12]}); {stores['a']} (SHA-256 {_sha256(stores['a'])[:12]}) "
        "is another store of that name")


def test_a_finished_run_made_under_another_name_is_reused_saying_so(stores, tmp_path):
    import numpy as np

    from bench.runs.folders import write_run
    from methods.base import OdometryResult

    by_hand = _job(stores["a"], tmp_path, method="doppler", seed=None,
                   params={"tau_spatial_m": 2.0}, run_dir_override=tmp_path / "made")
    (planned,), _ = _quiet(lambda: planning.plan([by_hand]))
    # the run's records as a finished run writes them (no method runs here)
    poses = np.tile(np.eye(4), (3, 1, 1))
    write_run(tmp_path / "made", OdometryResult(np.arange(3) * 0.1, poses, []), None,
              _config_of(planned), {"sequence": "loop", "method": "doppler", "seed": None,
                                    "frames": 3, "diverged": False})
    named = dataclasses.replace(by_hand, name="Named", display_name="Named loop")
    (again,), said = _quiet(lambda: planning.plan([named]))
    assert again.run_key == planned.run_key
    assert len(said) == 1 and said[0].startswith(
        f"reused {tmp_path / 'made'} (made as sequence 'loop'")
    assert "under the name 'Named loop'" in said[0]
    config = yaml.safe_load((tmp_path / "made" / "config.yaml").read_text())
    assert config["sequence"]["display_name"] == "Named loop"
    assert _quiet(lambda: planning.plan([named]))[1] == []  # renamed once


# ---- run_single and jobs_for_experiment -----------------------------------------------------

def _run_single_job(monkeypatch, *args, **kwargs) -> Job:
    """The job ``run_single`` hands to ``run_job`` (which fails here: no method runs)."""
    from bench.runs.job import JobOutcome

    seen = []

    def failing(job, force):
        seen.append(job)
        return JobOutcome(job, "failed", "stopped here")

    monkeypatch.setattr(planning, "run_job", failing)
    with pytest.raises(DataError, match="stopped here$"):
        _quiet(lambda: planning.run_single(*args, **kwargs))
    (job,) = seen
    return job


def test_run_single_seeds_by_default_into_the_default_folder_with_no_parameters(
        stores, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    job = _run_single_job(monkeypatch, "icp-p2p", stores["long"])
    assert job.seed is True and job.params == {}
    assert job.run_dir_override == Path("results/runs") / "long" / "icp-p2p_seed"
    job = _run_single_job(monkeypatch, "icp-p2p", str(stores["long"]), seed=False,
                          params={"max_iterations": 3}, out=str(tmp_path / "mine"))
    assert job.seed is False and job.params == {"max_iterations": 3}
    assert job.run_dir_override == tmp_path / "mine"


def test_an_experiment_missing_two_stores_names_both(tmp_path):
    from bench.runs.experiment import load_experiment

    (tmp_path / "a.h5").write_bytes(b"")
    path = tmp_path / "e.yaml"
    path.write_text(yaml.safe_dump({
        "name": "e", "out": "results", "methods": [{"name": "doppler"}],
        "sequences": [{"path": str(tmp_path / n)} for n in ("a.h5", "x.h5", "y.h5")]}))
    with pytest.raises(DataError) as raised:
        planning.jobs_for_experiment(load_experiment(path))
    assert str(raised.value) == (f"experiment 'e': stores not found: {tmp_path / 'x.h5'}, "
                                 f"{tmp_path / 'y.h5'}")


def test_a_finished_run_of_other_settings_is_not_renamed(stores, tmp_path):
    """Only a run of the same key is reused under the new name: one of other parameters in
    the folder (an experiment's folder runs again) keeps its names."""
    import numpy as np

    from bench.runs.folders import write_run
    from methods.base import OdometryResult

    made = _job(stores["a"], tmp_path, method="doppler", seed=None,
                params={"tau_spatial_m": 2.0}, run_dir_override=tmp_path / "made")
    write_run(tmp_path / "made", OdometryResult(np.arange(3) * 0.1, np.tile(np.eye(4), (3, 1, 1)),
                                                []), None, _config_of(made),
              {"sequence": "loop", "method": "doppler", "seed": None, "frames": 3,
               "diverged": False})
    other = dataclasses.replace(made, params={"tau_spatial_m": 3.0}, name="Named",
                                display_name="Named loop")
    (planned,), said = _quiet(lambda: planning.plan([other]))
    assert said == [] and planned.run_dir_override == tmp_path / "made"
    config = yaml.safe_load((tmp_path / "made" / "config.yaml").read_text())
    assert config["sequence"]["name"] == "loop" and config["sequence"]["display_name"] == "loop"


def test_two_lengths_too_long_are_listed_together(stores, tmp_path):
    _, said = _quiet(lambda: planning.plan([_job(stores["a"], tmp_path,
                                                 lengths_m=(2.0, 50.0, 70.0))]))
    assert said == ["a: the ground truth's path is 5.6 m long: no segments of 50, 70 m (their "
                    "cells stay empty)"]


def test_the_path_of_two_scored_frames_is_their_distance():
    """Frames 0-8 of 10 calibrated on: frames 9 and 10 (2 m apart) are scored."""
    from types import SimpleNamespace

    import numpy as np

    from loaders.trajectory import Trajectory

    poses = np.tile(np.eye(4), (11, 1, 1))
    poses[:, 0, 3] = np.arange(11) * 2.0
    gt = Trajectory(np.arange(11) * 0.1, poses)

    class Seq(SimpleNamespace):
        def __len__(self):
            return len(self.stamps)

    seq = Seq(ground_truth=gt, stamps=gt.stamps, provenance={"calibration": {"frames": [0, 9]}})
    assert planning._gt_path_length(SimpleNamespace(sequence=seq)) == pytest.approx(2.0)


def test_writable_asks_for_writing_and_searching(tmp_path):
    """``os.access`` with both rights: a file without the execute bit is not, whoever runs
    this (root too); one with it is."""
    import os

    path = tmp_path / "f"
    path.write_text("")
    os.chmod(path, 0o600)
    assert planning._writable(path) is False
    os.chmod(path, 0o700)
    assert planning._writable(path) is True


def test_a_finished_runs_folder_needs_no_write_check(tmp_path, monkeypatch):
    """A folder holding a finished run (its metrics.json) is taken as it is, writable or not
    (the run is reused); an unfinished one must be writable."""
    monkeypatch.setattr(planning, "_writable", lambda path: False)
    done = tmp_path / "done"
    done.mkdir()
    (done / "metrics.json").write_text("{}")
    planning._check_writable(done)
    (tmp_path / "open").mkdir()
    with pytest.raises(DataError, match=r"open is not writable$"):
        planning._check_writable(tmp_path / "open")
