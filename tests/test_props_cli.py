"""Properties of the whole command surface (Hypothesis; strategies in tests/strategies.py):
whatever is typed - numbers, paths, names, environment variables - ``bench`` ends with exit 0
or with exit 2 and one ``error:`` line naming what was wrong, never a traceback, with its
memory bounded and nothing outside its own output changed."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
import typer
from hypothesis import assume, given
from hypothesis import strategies as st
from strategies import (
    any_numbers,
    assert_clean,
    bad_numbers,
    bench,
    examples,
    frame_limits,
    lock_paths,
    names,
    number_lists,
    path_texts,
    tree_digest,
)

from bench import options
from bench.cli import app
from conftest import constant_twist_sequence
from loaders.registry import LOADERS
from loaders.store import write_store


class World:
    """Inputs every command can be pointed at: a tiny store, one without ground truth, an
    empty folder, a junk file, and a folder for outputs."""

    def __init__(self, root: Path) -> None:
        self.root = root
        seq = constant_twist_sequence(n_frames=12, n_points=300, max_range_m=60)
        self.store = write_store(seq, root / "in" / "twist.h5")
        self.nogt = write_store(type(seq)("nogt", seq.sensor, list(seq), None, {}),
                                root / "in" / "nogt.h5")
        self.empty = root / "in" / "empty"
        self.empty.mkdir()
        self.junk = root / "in" / "junk.txt"
        self.junk.write_text("not what any command reads\n")
        from loaders.posefile import write_tum

        self.tum = root / "in" / "gt.txt"
        write_tum(seq.ground_truth, self.tum)
        self.out = root / "out"

    def fill(self, text: str) -> str:
        return text.format(store=self.store, nogt=self.nogt, empty=self.empty, junk=self.junk,
                           tum=self.tum, out=self.out)


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> World:
    return World(tmp_path_factory.mktemp("world"))


def _commands():
    """(command path, click command) of every command, convert's loaders included."""
    from bench.data.convert import loader_command

    root = typer.main.get_command(app)
    found = []

    def walk(cmd, path):
        subs = getattr(cmd, "commands", {})
        for name, sub in subs.items():
            walk(sub, (*path, name))
        if not subs:
            found.append((path, cmd))

    walk(root, ())
    found += [(("convert", name), loader_command(e)) for name, e in LOADERS.items()]
    return found


#: arguments that make each command stop early with an error naming them once every option
#: is accepted (so an accepted value never starts real work): the positional inputs
EARLY_STOP = {
    "synth": ["no-such-scene", "--out", "{out}/s.h5"],
    "inspect": ["{junk}", "--plot", "-"],
    "calibrate": ["{nogt}"],
    "calibrate-coverage": ["--scene", "no-such-scene"],
    "run": ["--method", "no-such-method", "--data", "{store}", "--out", "{out}/r"],
    "score": ["{junk}", "--store", "{store}", "--name", "n", "--out", "{out}"],
    "export": ["{junk}", "--out", "{out}/x.bag"],
    "table": ["{empty}"],
    "compare": ["{empty}", "{empty}"],
    "figures": ["{empty}", "--out", "{out}/f"],
    "report": ["{empty}", "--out", "{out}/r.html"],
    "view": ["{junk}", "--out", "{out}/v.rrd"],
    "speed": ["--methods", "no-such-method", "--out", "{out}/speed"],
    "dataset": ["no-such-dataset", "--data-dir", "{out}/d"],
    "list": [], "datasets": [],  # no options that take a value: nothing to stop
    "regress": None,  # no early stop: it runs the CI suite (only refused values are tried)
    "reproduce": None,
}
CONVERT_STOP = ["{empty}", "--out", "{out}/c.h5"]
NUMERIC = [(path, p) for path, cmd in _commands() for p in cmd.params if options.is_numeric(p)]


def _early(path) -> list[str] | None:
    if path[0] == "convert" and path[-1] != "dataset":
        return list(CONVERT_STOP)
    return EARLY_STOP[path[-1]]


def _argv(world, path, param, value) -> list[str]:
    """``bench PATH OPTION VALUE ...`` with the early-stop inputs; ``--pair`` takes STORE FRAME."""
    rest = [world.fill(a) for a in (_early(path) or [])]
    if path[-1] in ("regress", "reproduce"):
        rest = ["--out", str(world.out / path[-1]), "--data-dir", str(world.out / "data")]
    flag = options.flag(param)
    given_ = [flag, str(world.store), value] if param.name == "pair" else [flag, value]
    return [*path, *given_, *rest]


def test_the_early_stops_cover_every_command():
    assert {p[-1] for p, _ in _commands() if p[0] != "convert" or p[-1] == "dataset"} \
        == set(EARLY_STOP)
    assert len(NUMERIC) > 60


@examples(12)
@given(data=st.data())
def test_a_refused_number_is_one_error_naming_its_option(world, data):
    # bench score checks its clock and coverage options itself (OWN_CHECKS), some only once
    # the trajectory is read: the other properties cover them
    path, param = data.draw(st.sampled_from([(p, q) for p, q in NUMERIC
                                             if (p[-1], q.name) not in options.OWN_CHECKS]),
                            label="option")
    value = data.draw(bad_numbers, label="value")
    before = tree_digest(world.root, Path.cwd())
    out = bench(_argv(world, path, param, value))
    assert out.code == 2, out.text
    # "-nan" after an option that takes a value reads as an option itself ("-n"): named too
    assert_clean(out, names=(options.flag(param), "No such option: -"))
    assert tree_digest(world.root, Path.cwd()) == before


@examples(12)
@given(data=st.data())
def test_any_number_ends_cleanly_and_a_default_is_never_refused(world, data):
    path, param = data.draw(st.sampled_from([(p, q) for p, q in NUMERIC if _early(p)]),
                            label="option")
    default = param.default
    value = data.draw(st.one_of(any_numbers, st.just(str(default)) if default is not None
                                and not isinstance(default, (tuple, list)) else any_numbers),
                      label="value")
    before = tree_digest(world.root, Path.cwd(), skip=(world.out,))
    out = bench(_argv(world, path, param, value))
    assert_clean(out)  # the early stop makes every accepted value end in an error
    flag = options.flag(param)
    if default is not None and value == str(default):
        assert not out.errors or not out.errors[0].startswith(f"error: {flag} "), out.text
        assert f"'{flag}'" not in out.text, out.text
    assert tree_digest(world.root, Path.cwd(), skip=(world.out,)) == before


#: every input path, in a command that reads it first: (argv with {input}, the option's name)
INPUT_CASES = [
    (["inspect", "{input}", "--plot", "-"], "STORE_OR_FOLDER"),
    (["calibrate", "{input}", "--bootstrap", "10"], "STORE.h5"),
    (["run", "--method", "no-such", "--data", "{input}", "--out", "{out}/r"], "--data"),
    (["run", "{input}"], "EXPERIMENT.yaml"),
    (["score", "{input}", "--store", "{nogt}", "--name", "n", "--out", "{out}"], "TRAJECTORY"),
    (["score", "{junk}", "--store", "{input}", "--name", "n", "--out", "{out}"], "--store"),
    (["score", "{junk}", "--store", "{nogt}", "--name", "n", "--stamps", "{input}", "--out",
      "{out}"], "--stamps"),
    (["score", "{tum}", "--store", "{store}", "--name", "n", "--frame-times", "{input}",
      "--out", "{out}"], "--frame-times"),
    (["export", "{input}", "--out", "{out}/x.bag"], "STORE.h5"),
    (["table", "{input}"], "RESULTS_DIR"),
    (["compare", "{input}", "{empty}"], "A"),
    (["figures", "{input}", "--out", "{out}/f"], "RESULTS_DIR"),
    (["figures", "{empty}", "--speed-csv", "{input}", "--out", "{out}/f"], "--speed-csv"),
    (["report", "{input}", "--out", "{out}/r.html", "--no-figures"], "RESULTS_DIR"),
    (["view", "{input}", "--out", "{out}/v.rrd"], "STORE.h5"),
    (["view", "{nogt}", "--run", "{input}", "--out", "{out}/v.rrd"], "--run"),
    (["inspect", "{input}", "--period", "0.1", "--plot", "-"], "STORE_OR_FOLDER"),
    (["convert", "npy-frames", "{input}", "--out", "{out}/c.h5", "--period", "0.1"], "INPUT"),
    (["convert", "aeva", "{input}", "--out", "{out}/c.h5"], "INPUT"),
    (["convert", "coloradar", "{input}", "--out", "{out}/c.h5"], "INPUT"),
]


@examples(12)
@given(data=st.data())
def test_any_input_path_ends_cleanly_naming_it(world, data):
    argv, option = data.draw(st.sampled_from(INPUT_CASES), label="command")
    existing = [world.junk, world.empty, world.nogt, world.root / "in"]
    text = data.draw(path_texts(existing), label="path")
    args = [world.fill(a) if a != "{input}" else text for a in argv]
    before = tree_digest(world.root, Path.cwd(), skip=(world.out,))
    out = bench(args)
    assert_clean(out, names=(option, text.strip() or "''", repr(text), "error"))
    if out.code == 2 and ("\0" in text or not text.strip()):
        assert option in out.errors[0], out.text
    assert tree_digest(world.root, Path.cwd(), skip=(world.out,)) == before


@examples(6)
@given(name=names, fmt=st.sampled_from(["auto", "tum", "kitti", "boreas", "bag", "xyz"]),
       unit=st.sampled_from([None, "s", "ms", "us", "ns", "h", ""]),
       extrinsic=st.one_of(st.none(), st.sampled_from(["0 0 0 0 0 0 1", "nan 0 0 0 0 0 1",
                                                        "1 2 3", "", "0 0 0 0 0 0 0"])))
def test_score_options_end_cleanly(world, name, fmt, unit, extrinsic):
    args = ["score", str(world.junk), "--store", str(world.store), "--name", name, "--out",
            str(world.out / "score"), "--format", fmt]
    args += ["--stamp-unit", unit] if unit is not None else []
    args += ["--extrinsic", extrinsic] if extrinsic is not None else []
    before = tree_digest(world.root, Path.cwd(), skip=(world.out,))
    assert_clean(bench(args))
    assert tree_digest(world.root, Path.cwd(), skip=(world.out,)) == before


@examples(6)
@given(lists=number_lists, which=st.sampled_from([
    ["table", "{empty}", "--lengths"], ["run", "--method", "no-such", "--data", "{store}",
                                        "--out", "{out}/r", "--lengths"],
    ["run", "--method", "no-such", "--data", "{store}", "--out", "{out}/r", "--kitti-lengths"],
    ["speed", "--methods", "no-such", "--out", "{out}/sp", "--sizes"],
    ["speed", "--scale", "--out", "{out}/sp", "--poses"]]))
def test_number_lists_end_cleanly(world, lists, which):
    if which[-1] == "--poses":  # an accepted list would start the study: only refused ones
        good = options.NUMBER_LISTS["poses"][0]
        assume(not all(p.strip().lstrip("+-").isdigit() and len(p) < 20 and good.holds(int(p))
                       for p in lists.split(",")))
    args = [world.fill(a) for a in which] + [lists]
    out = bench(args)
    assert_clean(out, names=(which[-1], "no-such", "no finished runs", "--scale"))
    if which[-1] == "--poses":
        assert out.code == 2 and "--poses" in out.errors[0], out.text


# ---- environment variables ---------------------------------------------------------------------

PLUGINS = {
    "good": """
        from methods.icp import PointToPointIcp

        class Mine(PointToPointIcp):
            name = "mine-{n}"

        METHODS = [Mine]
        """,
    "syntax": "def broken(:\n",
    "raises": "raise RuntimeError('boom')\n",
    "exits": "import sys\nsys.exit(3)\n",
    "shadow": """
        from methods.icp import PointToPointIcp

        class Fake(PointToPointIcp):
            name = "doppler"

        METHODS = [Fake]
        """,
    "no-methods": "X = 1\n",
    "bad-name": """
        from methods.icp import PointToPointIcp

        class Escape(PointToPointIcp):
            name = "../escape-{n}"

        METHODS = [Escape]
        """,
    "case-clash": """
        from methods.icp import PointToPointIcp

        class Loud(PointToPointIcp):
            name = "DOPPLER"

        METHODS = [Loud]
        """,
    "not-a-list": "METHODS = 'doppler'\n",
    "not-a-method": "METHODS = [int]\n",
}
_counter = [0]


@pytest.fixture
def plugin_dir(tmp_path_factory, monkeypatch):
    folder = tmp_path_factory.mktemp("plugins")
    monkeypatch.syspath_prepend(str(folder))
    yield folder
    from methods import registry

    registry.load_plugins("")


@examples(10)
@given(data=st.data())
def test_environment_variables_are_checked_before_any_command(world, plugin_dir, data):
    limit = data.draw(st.one_of(st.none(), frame_limits), label="BENCH_MAX_FRAME_MB")
    lock = data.draw(st.one_of(st.none(), lock_paths(world.root / "in")),
                     label="DOPPLER_BENCH_TIMING_LOCK")
    kinds = data.draw(st.lists(st.sampled_from([*PLUGINS, "missing", "bad-module"]),
                               max_size=2), label="plugins")
    modules = []
    for kind in kinds:
        _counter[0] += 1
        name = f"props_plugin_{kind.replace('-', '_')}_{_counter[0]}"
        if kind == "bad-module":
            name = "not a module"
        elif kind != "missing":
            (plugin_dir / f"{name}.py").write_text(
                textwrap.dedent(PLUGINS[kind]).replace("{n}", str(_counter[0])))
        modules.append(name)
    env = {"BENCH_MAX_FRAME_MB": limit, "DOPPLER_BENCH_TIMING_LOCK": lock,
           "DOPPLER_BENCH_METHODS": ",".join(modules) if modules else None}
    out = bench(["table", str(world.empty)], env=env)
    assert_clean(out)
    assert out.code == 2, out.text
    wrong = []
    if limit is not None and limit.strip():
        try:
            if not float(limit) > 0:
                wrong.append("BENCH_MAX_FRAME_MB")
        except ValueError:
            wrong.append("BENCH_MAX_FRAME_MB")
    if lock is not None and lock != str(world.root / "in" / "timing.lock"):
        wrong.append("DOPPLER_BENCH_TIMING_LOCK")
    if any(k != "good" for k in kinds):
        wrong.append("DOPPLER_BENCH_METHODS")
    if wrong:  # the first one checked is named
        assert any(w in out.errors[0] for w in wrong), (wrong, out.text)
    else:
        assert str(world.empty) in out.errors[0], out.text
    from methods import registry

    assert registry.get_method("doppler").__name__ == "DopplerCorrespondence"
