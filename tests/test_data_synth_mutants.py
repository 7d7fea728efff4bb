"""bench/data/synth.py (``bench synth``), in-process: the listing, the suite and entries with
their progress bars, the refusals (no SCENE/--out, a bad option, a file that is not a synthetic
store) and the store written. Tiny sequences (3 frames of 200 points) keep it fast."""

from __future__ import annotations

import io
import re
from pathlib import Path
from types import SimpleNamespace

import pytest
from rich.console import Console

import loaders.synthetic
from bench import guard
from bench.data import synth
from bench.data.synth import ensure_entries_with_progress, ensure_suite_with_progress, synth_command
from loaders.errors import DataError
from loaders.store import StoreSequence


def _console() -> Console:
    return Console(file=io.StringIO(), width=1000, color_system=None)


def _run(console, tmp_path, **given) -> int:
    args = dict(scene="loop", sensor="radar-sparse", frames=3, seed=1, out=tmp_path / "s.h5",
                noise=False, options={"points": 200}, list_=False, suite=None,
                data_dir=tmp_path / "data")
    args.update(given)
    return synth_command(console, **args)


def test_the_list_names_every_scene_sensor_option_and_suite(tmp_path):
    console = _console()
    assert _run(console, tmp_path, list_=True, scene=None, out=None) == 0
    lines = console.file.getvalue().splitlines()
    titles = [line for line in lines if not line.startswith("  ")]
    assert titles == ["scenes", "sensors", "options (-o key=value)", "suites"]
    items = {line.split()[0]: line for line in lines if line.startswith("  ")}
    expect = {**loaders.synthetic.list_scenes(), **loaders.synthetic.list_sensors(),
              **loaders.synthetic.OPTIONS,
              **{k: f"{len(v)} sequences" for k, v in loaders.synthetic.SUITES.items()}}
    assert set(items) == set(expect)
    for name, text in expect.items():  # the name in a column 18 wide, then its text
        assert items[name] == f"  {name.ljust(18)} {text}"
    assert not (tmp_path / "s.h5").exists()


def test_a_suite_is_made_under_the_data_folder_and_counted(tmp_path, monkeypatch):
    asked = []

    def ensure(suite, data_dir, console):
        asked.append((suite, data_dir, console))
        return [data_dir / suite / "a.h5", data_dir / suite / "b.h5"]

    monkeypatch.setattr(synth, "ensure_suite_with_progress", ensure)
    console = _console()
    assert _run(console, tmp_path, suite="mini", scene=None, out=None) == 0
    assert asked == [("mini", tmp_path / "data", console)]
    assert console.file.getvalue() == f"2 stores under {tmp_path / 'data' / 'mini'}\n"


@pytest.mark.parametrize("missing", [{"scene": None}, {"out": None}])
def test_without_a_scene_or_out_it_says_what_to_give(tmp_path, missing):
    with pytest.raises(DataError) as err:
        _run(_console(), tmp_path, **missing)
    assert str(err.value) == "give a SCENE and --out PATH.h5 (or --list, or --suite NAME)"


def test_a_bad_option_or_name_is_one_error_naming_it_before_anything_is_written(tmp_path):
    with pytest.raises(DataError) as err:
        _run(_console(), tmp_path, options={"points": 0})
    assert str(err.value).startswith("bench synth: --option points=0: expected ")
    with pytest.raises(DataError) as err:
        _run(_console(), tmp_path, scene="no-such-scene")
    assert str(err.value).startswith("bench synth: ")
    assert "no-such-scene" in str(err.value)
    assert not (tmp_path / "s.h5").exists()


def test_the_store_holds_the_sequence_asked_for_and_is_made_again(tmp_path):
    assert _run(_console(), tmp_path) == 0
    store = StoreSequence(tmp_path / "s.h5")
    assert len(store) == 3
    p = store.provenance
    assert (p["scene"], p["sensor"], p["seed"], p["noise"], p["options"]) == (
        "loop", "radar-sparse", 1, False, {"points": 200})
    store.close()
    assert _run(_console(), tmp_path, frames=4, seed=2, noise=True) == 0  # replaced
    store = StoreSequence(tmp_path / "s.h5")
    assert (len(store), store.provenance["seed"], store.provenance["noise"]) == (4, 2, True)
    store.close()


def test_a_file_that_is_not_a_synthetic_store_is_never_replaced(tmp_path):
    mine = tmp_path / "s.h5"
    mine.write_text("my notes")
    with pytest.raises(guard.Refused) as err:
        _run(_console(), tmp_path)
    assert str(err.value).startswith(f"--out {mine}: exists and is not a synthetic store this "
                                     "command wrote")  # checked before generating
    assert mine.read_text() == "my notes"


def _bars(console) -> list[list[str]]:
    """Each progress bar's description and count (the bar itself left out); every line has
    its bar and the time elapsed."""
    lines = [line for line in console.file.getvalue().splitlines() if "/" in line]
    assert all("━" in line and re.search(r" \d+:\d\d:\d\d$", line) for line in lines)
    return [[w for w in line.split() if "━" not in w][:2] for line in lines]


def _tiny(name="t"):
    return loaders.synthetic.SyntheticSequence("loop", "radar-sparse", frames=3, seed=1,
                                               noise=False, points=200, name=name)


def test_a_suite_reports_each_sequence_s_progress_and_writes_synthetic_stores_only(
        tmp_path, monkeypatch):
    written = []

    def ensure_suite(suite, data_dir, progress, writer):
        for name in ("s1", "s2"):
            for done in range(4):
                progress(name, done, 3)
        steps = []
        path = writer(_tiny(), data_dir / suite / "s1.h5", steps.append)
        written.append((path, steps))
        (data_dir / suite / "s2.h5").write_text("a user's file")
        with pytest.raises(guard.Refused) as err:
            writer(_tiny(), data_dir / suite / "s2.h5", None)
        assert "is not a synthetic store the harness wrote" in str(err.value)
        writer(_tiny("again"), path, None)  # a stale synthetic store is made again
        assert StoreSequence(path).name == "again"
        return [path]

    monkeypatch.setattr(loaders.synthetic, "ensure_suite", ensure_suite)
    (tmp_path / "mini").mkdir()
    console = _console()
    assert ensure_suite_with_progress("mini", tmp_path, console) == [tmp_path / "mini" / "s1.h5"]
    ((path, steps),) = written
    assert steps == [0, 1, 2]  # the writer's progress callback is the suite's
    assert len(StoreSequence(path)) == 3
    assert _bars(console) == [["mini/s1", "3/3"], ["mini/s2", "3/3"]]


def _entry(name, frames=3):
    return SimpleNamespace(name=name, frames=frames, entry_hash=lambda: "h" + name,
                           sequence=lambda suite: _tiny(f"{suite}-{name}"))


def test_entries_are_written_once_under_their_hash_with_a_bar_each(tmp_path, monkeypatch):
    import loaders.synthetic.suite as suite

    current = {tmp_path / "out" / "e2-he2.h5"}
    monkeypatch.setattr(suite, "store_is_current",
                        lambda path, entry: path in current and entry.name == "e2")
    console = _console()
    paths = ensure_entries_with_progress([_entry("e1"), _entry("e2")], tmp_path / "out",
                                         console)
    assert paths == [tmp_path / "out" / "e1-he1.h5", tmp_path / "out" / "e2-he2.h5"]
    assert not paths[1].exists()  # current: not written again
    store = StoreSequence(paths[0])
    assert (len(store), store.name) == (3, "out-e1")
    store.close()
    assert _bars(console) == [["out/e1", "3/3"]]


def test_an_entry_s_path_held_by_a_user_s_file_is_refused(tmp_path, monkeypatch):
    import loaders.synthetic.suite as suite

    monkeypatch.setattr(suite, "store_is_current", lambda path, entry: False)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "e1-he1.h5").write_text("mine")
    with pytest.raises(guard.Refused) as err:
        ensure_entries_with_progress([_entry("e1")], tmp_path / "out", _console())
    assert "is not a synthetic store the harness wrote" in str(err.value)
    assert (tmp_path / "out" / "e1-he1.h5").read_text() == "mine"


def test_an_entry_s_stale_synthetic_store_is_made_again(tmp_path, monkeypatch):
    import loaders.synthetic.suite as suite

    monkeypatch.setattr(suite, "store_is_current", lambda path, entry: False)
    guard.write_store(_tiny("stale"), tmp_path / "o2" / "e1-he1.h5", guard.is_synthetic_store)
    ensure_entries_with_progress([_entry("e1")], tmp_path / "o2", _console())
    store = StoreSequence(tmp_path / "o2" / "e1-he1.h5")
    assert store.name == "o2-e1"
    store.close()


def test_a_default_console_is_made_when_none_is_given(tmp_path, monkeypatch):
    import loaders.synthetic.suite as suite

    monkeypatch.setattr(suite, "store_is_current", lambda path, entry: True)
    monkeypatch.setattr(loaders.synthetic, "ensure_suite", lambda *a, **k: [Path("x")])
    assert ensure_entries_with_progress([_entry("e1")], tmp_path) == [tmp_path / "e1-he1.h5"]
    assert ensure_suite_with_progress("mini", tmp_path) == [Path("x")]
