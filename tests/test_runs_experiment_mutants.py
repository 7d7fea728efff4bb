"""bench/runs/experiment.py: loading an experiment (paths relative to its YAML, one message per
kind of bad file), globbed and optional sequences, synthetic entries, the criterion's sequence
names and the "did you mean" keys (the mutation run of tools/mutate.py over
bench/runs/experiment.py)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import pytest
import yaml

from bench.runs.experiment import (
    Criterion,
    Experiment,
    ExternalEntry,
    MethodEntry,
    SequenceEntry,
    SyntheticEntry,
    _known_keys,
    _natural,
    _shown,
    expand_sequences,
    load_experiment,
)
from loaders.errors import DataError
from loaders.sensor_classes import DENSE_LIDAR


def write(path: Path, data) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


# ---- load_experiment --------------------------------------------------------------------------

def test_relative_paths_are_taken_from_the_yaml_folder(tmp_path):
    folder = tmp_path / "cfg"
    folder.mkdir()
    exp = load_experiment(write(folder / "e.yaml", {
        "name": "e", "data_dir": "d", "out": "o",
        "sequences": [{"path": "s.h5"}, {"path": "/abs/t.h5"}],
        "methods": [{"name": "doppler"}],
        "external": [{"name": "mine", "trajectory": "odom.tum", "store": "s.h5",
                      "stamps": "st.txt"}]}))
    base = folder.resolve()
    assert exp.data_dir == base / "d" and exp.out == base / "o" and exp.out_dir == base / "o"
    assert [s.path for s in exp.sequences] == [base / "s.h5", Path("/abs/t.h5")]
    (ext,) = exp.external
    assert (ext.trajectory, ext.store, ext.stamps) == (base / "odom.tum", base / "s.h5",
                                                       base / "st.txt")
    assert ext.frame_times is None


def test_resolved_keeps_absolute_paths_and_no_out():
    exp = Experiment(name="n", sequences=[SequenceEntry(path=Path("/a/s.h5"))],
                     methods=[MethodEntry(name="doppler")], data_dir=Path("/data"),
                     external=[ExternalEntry(name="x", trajectory=Path("/t.tum"),
                                             store=Path("s.h5"), frame_times=Path("f.txt"))])
    got = exp.resolved(Path("/base"))
    assert got.out is None and got.out_dir == Path("results") / "n"
    assert got.data_dir == Path("/data") and got.sequences[0].path == Path("/a/s.h5")
    ext = got.external[0]
    assert (ext.trajectory, ext.store, ext.frame_times, ext.stamps) == (
        Path("/t.tum"), Path("/base/s.h5"), Path("/base/f.txt"), None)
    assert exp.out_dir == Path("results/n")


def test_a_missing_file(tmp_path):
    with pytest.raises(DataError) as caught:
        load_experiment(tmp_path / "none.yaml")
    assert str(caught.value) == f"{tmp_path / 'none.yaml'}: experiment file not found"


def test_a_file_that_is_not_yaml(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: [unclosed\n")
    with pytest.raises(DataError) as caught:
        load_experiment(path)
    assert str(caught.value).startswith(f"{path}: not valid YAML: ")


def test_a_store_given_as_an_experiment(tmp_path):
    path = tmp_path / "s.h5"
    path.write_bytes(b"\x89HDF\r\n\x1a\n\xff\xfe\x00binary")
    with pytest.raises(DataError) as caught:
        load_experiment(path)
    assert str(caught.value) == (f"{path}: not a text file; expected an experiment YAML (a "
                                 "store is run with `bench run --method M --data STORE.h5`)")


def test_an_invalid_experiment_lists_each_problem_with_a_suggestion(tmp_path):
    path = write(tmp_path / "e.yaml", {"name": "e", "sequences": [{"path": "s.h5"}],
                                       "methods": [{"name": "doppler"}], "lenghts_m": [8],
                                       "jobs": 0})
    with pytest.raises(DataError) as caught:
        load_experiment(path)
    text = str(caught.value)
    head, *problems = text.split("\n  ")
    assert head == f"{path}: invalid experiment:"
    assert len(problems) == 2
    assert any(p.startswith("jobs: ") for p in problems)
    assert all(p.startswith(("jobs: ", "unknown key 'lenghts_m'")) for p in problems)
    unknown = next(p for p in problems if "lenghts_m" in p)
    assert "did you mean 'lengths_m'" in unknown and "known keys: name, suite" in unknown


# ---- expand_sequences --------------------------------------------------------------------------

def test_a_glob_is_one_sequence_per_store_in_natural_order(tmp_path):
    for n in (10, 2, 1):
        (tmp_path / f"run{n}.h5").write_bytes(b"")
    after = SequenceEntry(path=tmp_path / "run1.h5", name="after")
    got = expand_sequences([SequenceEntry(path=tmp_path / "run*.h5", name="x",
                                          display_name="X", start=3), after])
    assert [(s.path.name, s.name, s.display_name, s.start) for s in got[:3]] == [
        ("run1.h5", "run1", None, 3), ("run2.h5", "run2", None, 3),
        ("run10.h5", "run10", None, 3)]
    assert got[3] == after and len(got) == 4


def test_a_glob_of_one_store_keeps_its_names(tmp_path):
    (tmp_path / "only.h5").write_bytes(b"")
    (got,) = expand_sequences([SequenceEntry(path=tmp_path / "onl?.h5", name="n",
                                             display_name="N")])
    assert (got.path, got.name, got.display_name) == (tmp_path / "only.h5", "n", "N")
    (bare,) = expand_sequences([SequenceEntry(path=tmp_path / "onl?.h5")])
    assert (bare.name, bare.display_name) == ("only", None)


def test_an_absent_optional_store_is_skipped_with_one_line(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    said = []
    kept = SequenceEntry(path=tmp_path / "present.h5")
    (tmp_path / "present.h5").write_bytes(b"")
    entries = [
        SequenceEntry(path=tmp_path / "data" / "x*.h5", optional=True, dataset="NTU"),
        SequenceEntry(path=tmp_path / "data" / "y*.h5", optional=True),
        SequenceEntry(path=tmp_path / "gone.h5", optional=True, name="g"),
        SequenceEntry(path=tmp_path / "gone.h5", optional=True, dataset="D", name="g"),
        SequenceEntry(path=tmp_path / "gone.h5", optional=True),
        SequenceEntry(path=tmp_path / "present.h5", optional=True), kept]
    got = expand_sequences(entries, said.append)
    assert got == [entries[5], kept]
    gone = tmp_path / "gone.h5"
    assert said == [f"skipped NTU: no store matches {os.path.join('data', 'x*.h5')}",
                    f"skipped {tmp_path / 'data' / 'y*.h5'}: no store matches "
                    f"{os.path.join('data', 'y*.h5')}",
                    "skipped g: store gone.h5 not found",
                    "skipped D: store gone.h5 not found",
                    f"skipped {gone}: store gone.h5 not found"]


def test_an_absent_store_that_is_not_optional_is_kept_for_the_planner(tmp_path):
    said = []
    entries = [SequenceEntry(path=tmp_path / "z*.h5"), SequenceEntry(path=tmp_path / "no.h5"),
               SequenceEntry(path=tmp_path / "w*.h5")]
    assert expand_sequences(entries, said.append) == entries and said == []


def test_the_default_is_a_warning(tmp_path):
    def caller():
        return expand_sequences([SequenceEntry(path=tmp_path / "q*.h5", optional=True)])

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert caller() == []
    (w,) = caught
    pattern = tmp_path / "q*.h5"
    assert str(w.message) == f"skipped {pattern}: no store matches {_shown(pattern)}"


def test_shown_paths_are_relative_inside_the_working_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert _shown(tmp_path / "a" / ".." / "b.h5") == "b.h5"
    outside = tmp_path.parent / "elsewhere" / "c.h5"
    assert _shown(outside) == str(outside)


def test_natural_order_key():
    assert _natural(Path("x/a10b2.h5")) == ["a", 10, "b", 2, ".h", 5, ""]


# ---- synthetic entries, criterion, known keys ----------------------------------------------------

def test_a_synthetic_entry_is_a_suite_entry():
    entry = SyntheticEntry(name="c1", scene="campus", sensor="lidar-dense", frames=5, seed=7,
                           options={"k": 1})
    got = entry.suite_entry()
    assert (got.name, got.display, got.klass, got.scene, got.sensor, got.frames, got.seed,
            got.options) == ("c1", "c1", DENSE_LIDAR, "campus", "lidar-dense", 5, 7, {"k": 1})
    assert got.options is not entry.options
    radar = SyntheticEntry(name="r", display_name="R", scene="loop", sensor="radar-sparse",
                           frames=3, seed=1).suite_entry()
    assert (radar.display, radar.klass) == ("R", "4D Radar")
    own = SyntheticEntry(name="r", sensor_class="Mine", scene="loop", sensor="radar-sparse",
                         frames=3, seed=1).suite_entry()
    assert own.klass == "Mine"


def test_an_unknown_synthetic_sensor_or_scene():
    from loaders.synthetic.scenes import SCENES
    from loaders.synthetic.sensors import SENSORS

    with pytest.raises(DataError) as caught:
        SyntheticEntry(name="x", scene="loop", sensor="sonar", frames=3, seed=1).suite_entry()
    assert str(caught.value) == f"unknown synthetic sensor 'sonar'; known: {', '.join(SENSORS)}"
    with pytest.raises(DataError) as caught:
        SyntheticEntry(name="x", scene="moon", sensor="radar-sparse", frames=3,
                       seed=1).suite_entry()
    assert str(caught.value) == f"unknown synthetic scene 'moon'; known: {', '.join(SCENES)}"


def test_the_criterions_sequence_names_in_order_once():
    c = Criterion(lengths_m=[8.0], folds=[{"tuning": ["a", "b"], "validation": ["c"]},
                                          {"tuning": ["c"], "validation": ["a", "d"]}],
                  domain=["e", "b"])
    assert c.sequence_names() == ["a", "b", "c", "d", "e"]
    assert Criterion(lengths_m=[8.0], error="both", domain=["x"]).sequence_names() == ["x"]


def test_known_keys_by_location():
    assert _known_keys(()) == list(Experiment.model_fields)
    assert _known_keys(("methods", 0)) == list(MethodEntry.model_fields)
    assert _known_keys(("criterion", "folds", 1)) == list(
        Criterion.model_fields["folds"].annotation.__args__[0].__args__[0].model_fields)
    assert _known_keys(("external", 2)) == list(ExternalEntry.model_fields)
    assert _known_keys(("synthetic", 0)) == list(SyntheticEntry.model_fields)
    assert _known_keys(("sequences", 0)) == list(SequenceEntry.model_fields)
    assert _known_keys(("criterion",)) == list(Criterion.model_fields)
    assert _known_keys(("nowhere",)) is None
