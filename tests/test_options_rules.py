"""The option rules of bench/options.py at unit level (no command run): ranges and their
words, comma-separated lists, path texts, input paths, the coerced values of parameters and how
an option is named. The CLI cases (one error before any work) are in tests/test_options.py."""

from __future__ import annotations

import math
import os
from pathlib import Path
from types import SimpleNamespace

import pytest

from bench import options
from bench.options import Number
from loaders.errors import DataError


def test_a_range_holds_its_ends_unless_above_and_nothing_outside_or_not_finite():
    r = Number(1, 10, "a count")
    assert r.holds(1) and r.holds(10) and r.holds(5.5)
    assert not r.holds(0.999) and not r.holds(10.001)
    assert not r.holds(math.nan) and not r.holds(math.inf)
    above = Number(0, 3600, "a period", above=True)
    assert not above.holds(0) and above.holds(1e-9) and above.holds(3600)
    assert not above.holds(3600.5) and not above.holds(-1)
    # an integer of 400 digits is compared as an integer (a float of it would overflow)
    assert not r.holds(10**400) and Number(-math.inf, math.inf, "x").holds(10**400)


def test_a_range_says_what_it_expects_with_readable_numbers():
    assert Number(1, 10_000_000, "a number of frames").expected() == (
        "a number of frames, at least 1 and at most 10,000,000")
    assert Number(0, 3600, "a period", above=True).expected() == (
        "a period, above 0 and at most 3,600")
    assert Number(0, 1e6, "a width", above=True).expected() == "a width, above 0 and at most " \
        "1,000,000"
    assert Number(0.5, 1e15, "x").expected() == "x, at least 0.5 and at most 1e+15"
    assert Number(-1e10, 1e10, "x").expected() == "x, at least -10,000,000,000 and at most " \
        "10,000,000,000"


def test_a_command_of_its_own_overrides_the_names_rule():
    assert options.number_rule("synth", "frames") == Number(2, 100_000, "a number of frames")
    assert options.number_rule("run", "frames") == Number(1, 10_000_000, "a number of frames")
    assert options.number_rule("run", "no_such_option") is None


def test_number_lists_are_checked_item_by_item_and_said_whole():
    assert options.number_list("8,48", "--lengths", "lengths") == (8.0, 48.0)
    assert options.number_list("1000,64000", "--sizes", "sizes") == (1000, 64000)
    assert all(isinstance(v, int) for v in options.number_list("1,2", "--sizes", "sizes"))
    with pytest.raises(DataError) as err:
        options.number_list("8,0", "--lengths", "lengths")
    assert str(err.value) == ("--lengths '8,0': expected segment lengths in metres (numbers, "
                              "above 0 and at most 100,000), comma separated, e.g. 8,48")
    with pytest.raises(DataError) as err:
        options.number_list("1.5", "--sizes", "sizes")  # whole numbers only
    assert str(err.value).startswith("--sizes '1.5': expected point counts (whole numbers, "
                                     "at least 1 and at most 1,000,000), comma separated, "
                                     "e.g. 1000,64000")
    for bad in ("", "8,,48", "8;48", "8,inf", "nan"):
        with pytest.raises(DataError):
            options.number_list(bad, "--lengths", "lengths")
    long = ",".join(["8"] * 30) + ",x"
    with pytest.raises(DataError) as err:
        options.number_list(long, "--lengths", "lengths")
    assert str(err.value).startswith(f"--lengths {long[:40]!r}... ({len(long)} characters): ")
    edge = ",".join(["8"] * 30) + "x"  # 60 characters: shown whole
    assert len(edge) == 60
    with pytest.raises(DataError) as err:
        options.number_list(edge, "--lengths", "lengths")
    assert str(err.value).startswith(f"--lengths {edge!r}: ")
    with pytest.raises(DataError) as err:
        options.number_list(edge + "x", "--lengths", "lengths")  # 61: cut
    assert str(err.value).startswith(f"--lengths {edge[:40]!r}... (61 characters): ")


def test_path_texts_no_nul_no_empty_input_names_the_file_system_takes():
    options.check_path_text("a/b.h5", "--data", True)
    options.check_path_text("", "--out", False)  # an output may be empty (the default)
    with pytest.raises(DataError, match=r"^--data 'a\\x00b': a path cannot hold a NUL byte$"):
        options.check_path_text("a\0b", "--data", True)
    with pytest.raises(DataError, match=r"^--data '  ': expected a path, got an empty one$"):
        options.check_path_text("  ", "--data", True)
    name = "x" * options.NAME_MAX
    options.check_path_text(f"{name}/{name}", "--out", False)  # at the limit
    with pytest.raises(DataError) as err:
        options.check_path_text(f"d/{name}x", "--out", False)
    assert str(err.value) == (f"--out {f'd/{name}x'[:60]!r}...: a path of 258 bytes with a name "
                              "of 256; expected names of at most 255 bytes and paths of at most "
                              "4096")
    path = "/".join(["y" * 200] * 20)  # short names, a long path
    assert len(path) == 4019
    options.check_path_text(path[:options.PATH_MAX], "--out", False)
    with pytest.raises(DataError, match="a path of 4097 bytes with a name of 200"):
        options.check_path_text(path + "/" + "z" * 77, "--out", False)


def test_an_input_path_exists(tmp_path):
    options.check_input(tmp_path, "--data")
    with pytest.raises(DataError) as err:
        options.check_input(tmp_path / "no.h5", "--data")
    assert str(err.value) == f"--data {tmp_path / 'no.h5'}: not found"
    with pytest.raises(DataError, match=r"^--data .*: cannot be read \(Not a directory\)$"):
        (tmp_path / "f").write_text("x")
        options.check_input(tmp_path / "f" / "g", "--data")


def _param(name, opts=(), metavar=None):
    return SimpleNamespace(name=name, opts=list(opts), metavar=metavar)


def test_a_parameter_is_named_as_typed():
    assert options.flag(_param("min_speed", ["-m", "--min-speed"])) == "--min-speed"
    assert options.flag(_param("store", ["store"], "STORE_PATH")) == "STORE_PATH"
    assert options.flag(_param("store", ["store"])) == "STORE"
    assert options.flag(_param(None)) == "VALUE"


def test_values_are_checked_by_kind(tmp_path):
    check = options._check_value
    check(None, "run", _param("frames"), "--frames")
    check(5, "run", _param("frames"), "--frames")
    with pytest.raises(DataError) as err:
        check(0, "run", _param("frames"), "--frames")
    assert str(err.value) == ("--frames 0: expected a number of frames, at least 1 and at most "
                              "10,000,000")
    with pytest.raises(DataError, match=r"^--frames 1: expected a number of frames, at least 2"):
        check(1, "synth", _param("frames"), "--frames")  # the command's own rule
    with pytest.raises(DataError, match=r"^--pair -2: expected a frame index"):
        check(("store.h5", -2), "figures", _param("pair"), "--pair")  # inside a tuple
    with pytest.raises(DataError, match=r"^--frames 1000000000"):
        check([3, 10**9], "run", _param("frames"), "--frames")  # every item of a list
    check(True, "run", _param("frames"), "--frames")  # a flag is no number
    check(-5.0, "score", _param("time_offset"), "--time-offset")  # score checks its own
    check(-5.0, "x", _param("new_option"), "--new-option")  # no rule: finite is enough
    with pytest.raises(DataError, match=r"^--new-option inf: expected a finite number$"):
        check(math.inf, "x", _param("new_option"), "--new-option")
    with pytest.raises(DataError) as err:
        check(10**60, "run", _param("frames"), "--frames")
    shown = repr(10**60)
    assert str(err.value).startswith(f"--frames {shown[:20]}... ({len(shown)} digits): expected")
    with pytest.raises(DataError, match=r"^--frames 1000000000000000000000000000000000000: "):
        check(10**36, "run", _param("frames"), "--frames")  # 37 digits: shown whole
    # paths: an input exists, an output need not
    check(tmp_path, "run", _param("data"), "--data")
    check(tmp_path / "new", "run", _param("out"), "--out")
    with pytest.raises(DataError, match="not found"):
        check(tmp_path / "no.h5", "run", _param("data"), "--data")
    # texts: number lists, registry names, fixed forms
    with pytest.raises(DataError, match=r"^--lengths '8,-1'"):
        check("8,-1", "table", _param("lengths"), "--lengths")
    check("tcp://host:8786", "run", _param("scheduler"), "--scheduler")
    with pytest.raises(DataError) as err:
        check("host:8786", "run", _param("scheduler"), "--scheduler")
    assert str(err.value) == ("--scheduler 'host:8786': expected a dask scheduler address, "
                              "e.g. tcp://HOST:8786")
    check("anything", "run", _param("label"), "--label")


def test_a_scene_or_sensor_is_one_of_the_registrys(monkeypatch):
    from loaders.synthetic import list_scenes

    scenes = list(list_scenes())
    options._check_value(scenes[0], "synth", _param("scene"), "--scene")
    with pytest.raises(DataError) as err:
        options._check_value(scenes[0] + "x", "synth", _param("scene"), "--scene")
    assert str(err.value) == (f"--scene {scenes[0] + 'x'!r}: unknown scene (did you mean "
                              f"{scenes[0]!r}?); choose from {', '.join(scenes)}")
    options._check_value("no-such-scene", "run", _param("scene"), "--scene")  # only there


def test_raw_texts_flatten_nested_values():
    assert options._raw_texts("a") == ["a"]
    assert options._raw_texts(("a", ["b", ("c",)], 3, None)) == ["a", "b", "c"]
    assert options._raw_texts(Path("a")) == []
    assert options._raw_texts(os.sep) == [os.sep]
