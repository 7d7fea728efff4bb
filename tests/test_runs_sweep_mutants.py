"""bench/runs/sweep.py: a sweep's variants, its index (sweeps.json: each point's runs and the
method's resolved default on each sequence, for the seed option swept) and reading it back
(the mutation run of tools/mutate.py over bench/runs/sweep.py). The index is built from
hand-made jobs on a small LiDAR store, where GICP's no-seed default differs from its seeded
one."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench import guard
from bench.runs.experiment import Experiment, MethodEntry
from bench.runs.job import Job
from bench.runs.sweep import (
    INDEX,
    Variant,
    _admits_sequence,
    _plain,
    expand,
    format_value,
    read_sweep_index,
    sweep_index,
    takes_a_list,
    write_sweep_index,
)
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import write_store


@pytest.fixture(scope="module")
def lidar_store(tmp_path_factory) -> Path:
    seq = constant_twist_sequence(n_frames=3, n_points=200)
    return write_store(seq, tmp_path_factory.mktemp("sweep") / "lidar.h5")


def test_which_parameters_take_a_list():
    assert takes_a_list("doppler-ego", "angle_noise_deg")  # tuple[float, float] | None
    assert not takes_a_list("doppler", "tau_spatial_m")
    assert not takes_a_list("doppler", "no_such_parameter")
    assert _admits_sequence(list[float]) and _admits_sequence(tuple) and _admits_sequence(set)
    assert _admits_sequence(frozenset[int]) and _admits_sequence(float | list[float])
    assert not _admits_sequence(float) and not _admits_sequence(float | None)
    assert not _admits_sequence(str)


def test_a_method_without_parameters_takes_no_list(monkeypatch):
    from bench.runs import sweep

    class Bare:
        pass

    monkeypatch.setattr(sweep, "get_method", lambda name: Bare)
    assert takes_a_list("bare", "anything") is False


def test_format_value_is_the_json_spelling():
    assert format_value(3.0) == "3.0" and format_value(True) == "true"
    assert format_value([0.4, 2.6]) == "[0.4, 2.6]" and format_value(None) == "null"


def test_an_entry_without_a_sweep_is_itself():
    entry = MethodEntry(name="doppler", label="mine", params={"tau_spatial_m": 2.0})
    assert expand(entry) == [Variant("mine", {"tau_spatial_m": 2.0})]
    (v,) = expand(entry)
    assert v.point == {} and v.group is None


def test_a_grid_is_every_point_labelled_by_its_group():
    entry = MethodEntry(name="doppler", params={"tau_spatial_m": [2.0, 3.0], "downsample": 2},
                        sweep={"tau_doppler": [4.0, 5.0]})
    got = expand(entry)
    assert [v.label for v in got] == [
        "doppler tau_spatial_m=2.0 tau_doppler=4.0", "doppler tau_spatial_m=2.0 tau_doppler=5.0",
        "doppler tau_spatial_m=3.0 tau_doppler=4.0", "doppler tau_spatial_m=3.0 tau_doppler=5.0"]
    assert got[1].params == {"downsample": 2, "tau_spatial_m": 2.0, "tau_doppler": 5.0}
    assert got[1].point == {"tau_spatial_m": 2.0, "tau_doppler": 5.0}
    assert {v.group for v in got} == {"doppler"}
    labelled = MethodEntry(name="doppler", label="d", params={"tau_spatial_m": [2.0, 3.0]})
    assert [(v.label, v.group) for v in expand(labelled)] == [
        ("d tau_spatial_m=2.0", "d"), ("d tau_spatial_m=3.0", "d")]


def test_a_bad_sweep_says_what_is_wrong():
    def entry(**kw):
        return MethodEntry.model_construct(name="doppler", label=None, **kw)

    with pytest.raises(ValueError, match="^doppler: 'tau_doppler' is both in params and in "
                                         "sweep$"):
        expand(entry(params={"tau_doppler": 4.0}, sweep={"tau_doppler": [4.0]}))
    with pytest.raises(ValueError, match="^doppler: the sweep over 'tau_doppler' lists no "
                                         "values$"):
        expand(entry(params={}, sweep={"tau_doppler": []}))
    with pytest.raises(ValueError, match="^doppler: the sweep over 'tau_doppler' lists a value "
                                         "twice$"):
        expand(entry(params={}, sweep={"tau_doppler": [4.0, 5.0, 4.0]}))


def _experiment(store: Path, out: Path, **extra) -> Experiment:
    return Experiment.model_validate({
        "name": "sw", "out": str(out),
        "sequences": [{"path": str(store), "name": "a"}, {"path": str(store), "name": "b"}],
        "methods": [
            {"name": "gicp", "seeds": [False],
             "params": {"max_correspondence_m": [0.5, 2.0], "neighbours": 12}},
            {"name": "doppler", "label": "plain"},
            {"name": "doppler", "label": "d", "sweep": {"tau_doppler": [4.0, 6.0]}}],
        **extra})


def _jobs(exp: Experiment, store: Path) -> list[Job]:
    out = Path(exp.out_dir)
    jobs = []
    for m in exp.methods:
        for v in m.variants():
            for name in ("a", None) if m.name == "gicp" else ("b",):
                seed = False if m.name == "gicp" else None
                folder = out / (name or store.stem) / v.label.replace(" ", "_")
                jobs.append(Job(store, m.name, seed, out, dict(v.params), name=name,
                                label=v.label, run_dir_override=folder))
    # a run of the plain entry on a sequence no sweep point runs on
    jobs.append(Job(store, "doppler", None, out, name="c", label="plain",
                    run_dir_override=out / "c" / "plain"))
    return jobs


def test_the_index_of_two_sweeps(lidar_store, tmp_path):
    exp = _experiment(lidar_store, tmp_path, default_differs="because",
                      criterion={"error": "rotation", "lengths_m": [8.0]})
    index = sweep_index(exp, _jobs(exp, lidar_store))
    assert list(index) == ["experiment", "criterion", "default_differs", "sweeps"]
    assert index["experiment"] == "sw" and index["default_differs"] == "because"
    assert index["criterion"] == exp.criterion.model_dump()
    gicp, doppler = index["sweeps"]
    assert list(gicp) == ["method", "group", "keys", "defaults", "points"]
    assert (gicp["method"], gicp["group"], gicp["keys"]) == (
        "gicp", "gicp", ["max_correspondence_m"])
    # the no-seed default on LiDAR (1.0 m; a seeded run's is 0.75 m), not a swept value
    assert gicp["defaults"] == {"a": {"max_correspondence_m": 1.0},
                                "lidar": {"max_correspondence_m": 1.0}}
    assert gicp["points"] == [
        {"label": f"gicp max_correspondence_m={x}", "point": {"max_correspondence_m": x},
         "runs": [{"sequence": "a", "seed": False,
                   "dir": f"a/gicp_max_correspondence_m={x}"},
                  {"sequence": "lidar", "seed": False,
                   "dir": f"lidar/gicp_max_correspondence_m={x}"}]}
        for x in (0.5, 2.0)]
    assert (doppler["method"], doppler["group"], doppler["keys"]) == (
        "doppler", "d", ["tau_doppler"])
    assert doppler["defaults"] == {"b": {"tau_doppler": 5.0}}
    assert [p["label"] for p in doppler["points"]] == ["d tau_doppler=4.0", "d tau_doppler=6.0"]
    assert doppler["points"][1]["runs"] == [
        {"sequence": "b", "seed": None, "dir": "b/d_tau_doppler=6.0"}]


def test_an_index_without_a_criterion_and_without_sweeps(lidar_store, tmp_path):
    exp = _experiment(lidar_store, tmp_path)
    index = sweep_index(exp, _jobs(exp, lidar_store))
    assert index["criterion"] is None and index["default_differs"] is None
    plain = Experiment.model_validate({"name": "p", "out": str(tmp_path),
                                       "sequences": [{"path": str(lidar_store)}],
                                       "methods": [{"name": "doppler"}]})
    assert sweep_index(plain, [Job(lidar_store, "doppler", None, tmp_path,
                                   run_dir_override=tmp_path / "x")]) is None


def test_plain_values_are_json_values():
    assert _plain((0.4, 2.6)) == [0.4, 2.6]
    assert _plain({"a": (1, 2)}) == {"a": [1, 2]}
    assert _plain(frozenset()) == []
    assert _plain(3.0) == 3.0


def test_the_index_is_written_as_a_derived_file_and_read_back(tmp_path):
    index = {"experiment": "e", "sweeps": [{"keys": ["k"]}]}
    path = write_sweep_index(tmp_path / "out", index)
    assert path == tmp_path / "out" / INDEX and INDEX == "sweeps.json"
    assert path.read_text() == json.dumps(index, indent=1) + "\n"
    assert guard.derived(path)  # listed in the folder's ledger
    assert read_sweep_index(tmp_path / "out") == index
    # written again over its own earlier file
    write_sweep_index(tmp_path / "out", {"experiment": "f"})
    assert read_sweep_index(tmp_path / "out") == {"experiment": "f"}


def test_a_users_file_is_not_replaced(tmp_path):
    (tmp_path / INDEX).write_text("{}")
    with pytest.raises(DataError) as caught:
        write_sweep_index(tmp_path, {"experiment": "e"})
    assert str(caught.value).startswith(
        f"{tmp_path / INDEX}: exists and is not an experiment's sweep index the harness wrote")


def test_a_missing_or_broken_index_is_one_clear_error(tmp_path):
    with pytest.raises(DataError) as caught:
        read_sweep_index(tmp_path)
    assert str(caught.value) == (f"{tmp_path}: no sweeps.json here (written by `bench run` for "
                                 "an experiment with a parameter sweep)")
    (tmp_path / INDEX).write_text("{broken")
    with pytest.raises(DataError) as caught:
        read_sweep_index(tmp_path)
    assert str(caught.value).startswith(f"{tmp_path / INDEX}: not a readable sweep index: ")
