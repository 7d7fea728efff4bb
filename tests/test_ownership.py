"""Whose run a run folder holds (bench.runs.ownership), at unit level: ``run_identity`` reads
a harness run's method, seed option, parameters, frame range and store (its resolved path),
an external run's trajectory file, topic and store; ``foreign_run`` refuses a folder holding
another run and names what it holds and what the command would write instead. The CLI-level
cases are in tests/test_write_guard.py."""

from __future__ import annotations

import os

import pytest
import yaml

from bench.runs.ownership import foreign_run, run_identity
from loaders.errors import DataError


def _harness(tmp_path, **identity):
    ident = {"method": "doppler-ego", "seed": "none", "params": {"a": 1, "b": 2},
             "frame_range": [0, 10]}
    ident.update(identity)
    return {"method": {"name": "ignored", "params": {"z": 9}}, "seed": "ignored",
            "identity": ident, "sequence": {"store": str(tmp_path / "store")}}


def test_a_harness_runs_identity_prefers_the_identity_block(tmp_path):
    got = run_identity(_harness(tmp_path))
    assert got == {"method": "doppler-ego", "seed option": "none",
                   "parameters": {"a": 1, "b": 2}, "frame range": [0, 10],
                   "store": os.path.realpath(tmp_path / "store")}


def test_an_older_config_without_identity_falls_back_to_method_and_seed(tmp_path):
    config = {"method": {"name": "icp", "params": {"k": 3}}, "seed": "gt",
              "sequence": {"store": str(tmp_path / "s")}}
    assert run_identity(config) == {"method": "icp", "seed option": "gt", "parameters": {"k": 3},
                                    "frame range": None,
                                    "store": os.path.realpath(tmp_path / "s")}
    # blocks that are not mappings are read as absent, never as a crash
    assert run_identity({"method": "icp", "identity": "x", "sequence": "y"}) == {
        "method": None, "seed option": None, "parameters": None, "frame range": None,
        "store": None}


def test_the_store_path_is_resolved_through_symlinks_and_relative_paths(tmp_path, monkeypatch):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    monkeypatch.chdir(tmp_path)
    config = {"method": {"name": "m"}, "sequence": {"store": "link"}}
    assert run_identity(config)["store"] == os.path.realpath(tmp_path / "real")
    assert run_identity({"method": {"name": "m"}, "sequence": {"store": ""}})["store"] is None


@pytest.mark.parametrize("config", [
    {"external": {"trajectory": "t.txt", "topic": "/odom"}, "sequence": {"store": "st"}},
    {"identity": {"kind": "external"}, "external": {"trajectory": "t.txt", "topic": "/odom"},
     "sequence": {"store": "st"}},
])
def test_an_external_runs_identity_is_its_trajectory_topic_and_store(config, tmp_path,
                                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert run_identity(config) == {"trajectory": os.path.realpath(tmp_path / "t.txt"),
                                    "topic": "/odom",
                                    "store": os.path.realpath(tmp_path / "st")}


def test_an_external_kind_without_its_blocks_reads_as_nothing_known():
    # the identity's kind alone makes it an external run, with or without an external block
    for config in ({"identity": {"kind": "external"}, "sequence": 3},
                   {"identity": {"kind": "external"}, "external": "x", "sequence": 3}):
        assert run_identity(config) == {"trajectory": None, "topic": None, "store": None}


def _folder(tmp_path, config):
    run = tmp_path / "run"
    run.mkdir(exist_ok=True)
    (run / "config.yaml").write_text(yaml.safe_dump(config), encoding="utf-8")
    return run


def test_a_new_folder_or_an_unreadable_config_is_nobodys(tmp_path):
    foreign_run(tmp_path / "absent", {"method": "x"}, "bench run")
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text("a: [unclosed", encoding="utf-8")
    foreign_run(run, {"method": "x"}, "bench run")
    (run / "config.yaml").write_text("- a list\n", encoding="utf-8")
    foreign_run(run, {"method": "x"}, "bench run")


def test_the_same_run_is_its_own_even_with_tuples_for_lists(tmp_path):
    config = _harness(tmp_path)
    run = _folder(tmp_path, config)
    wanted = run_identity(config)
    wanted["frame range"] = (0, 10)  # a tuple asked, a list read back: the same range
    foreign_run(run, wanted, "bench run")


def test_another_method_is_refused_naming_both_and_not_their_parameters(tmp_path):
    config = _harness(tmp_path)
    run = _folder(tmp_path, config)
    wanted = dict(run_identity(config), method="icp", parameters={"k": 3})
    with pytest.raises(DataError) as err:
        foreign_run(run, wanted, "bench run")
    assert str(err.value) == (
        f"{run}: holds another run (method 'doppler-ego'); bench run would replace it with "
        "method 'icp': choose another folder or name (--force re-does only the same run, "
        "never another)")


def test_other_parameters_name_the_method_and_only_the_entries_that_differ(tmp_path):
    config = _harness(tmp_path)
    run = _folder(tmp_path, config)
    wanted = dict(run_identity(config), parameters={"a": 1, "b": 5})
    with pytest.raises(DataError) as err:
        foreign_run(run, wanted, "bench run")
    assert ("holds another run (method 'doppler-ego', parameters {'b': 2}); bench run would "
            "replace it with parameters {'b': 5}: choose") in str(err.value)


def test_another_store_says_a_folder_holds_one_stores_runs(tmp_path):
    config = _harness(tmp_path)
    run = _folder(tmp_path, config)
    other = os.path.realpath(tmp_path / "other")
    wanted = dict(run_identity(config), store=other, **{"seed option": "gt"})
    with pytest.raises(DataError) as err:
        foreign_run(run, wanted, "bench run")
    held = os.path.realpath(tmp_path / "store")
    assert (f"holds another run (method 'doppler-ego', seed option 'none', store {held!r}); "
            f"bench run would replace it with seed option 'gt', store {other!r} (a folder holds "
            "one store's runs: another store of that name is another sequence): choose") \
        in str(err.value)


def test_a_scored_run_of_another_trajectory_names_the_trajectory_first(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    config = {"external": {"trajectory": "t.txt", "topic": None}, "sequence": {"store": "st"}}
    run = _folder(tmp_path, config)
    held = run_identity(config)
    foreign_run(run, held, "bench score")  # its own run
    with pytest.raises(DataError) as err:
        foreign_run(run, dict(held, topic="/odom"), "bench score")
    assert (f"holds another run (trajectory {held['trajectory']!r}, topic None); bench score "
            "would replace it with topic '/odom': choose") in str(err.value)
    # a key the folder's run does not have is not compared
    foreign_run(run, dict(held, method="x"), "bench score")


def test_parameters_held_against_none_asked_are_shown_whole(tmp_path):
    """Only a dict against a dict is narrowed to its differing entries: parameters held, none
    asked, show every held entry and None."""
    config = _harness(tmp_path)
    run = _folder(tmp_path, config)
    with pytest.raises(DataError) as err:
        foreign_run(run, dict(run_identity(config), parameters=None), "bench run")
    assert ("holds another run (method 'doppler-ego', parameters {'a': 1, 'b': 2}); bench run "
            "would replace it with parameters None: choose") in str(err.value)


def test_an_identity_asked_with_sets_compares_by_its_items(tmp_path):
    """A value JSON cannot write as it is (a set) is compared as the list of its items, never
    a crash: one topic asked as a set is the run that holds it as a list."""
    config = _harness(tmp_path, params={"topics": ["/radar"]})
    run = _folder(tmp_path, config)
    foreign_run(run, dict(run_identity(config), parameters={"topics": {"/radar"}}), "bench run")
    with pytest.raises(DataError, match="holds another run"):
        foreign_run(run, dict(run_identity(config), parameters={"topics": {"/lidar"}}),
                    "bench run")
