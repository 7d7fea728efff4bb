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
    assert options.number_list("0.5,8", "--lengths", "lengths") == (0.5, 8.0)
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
    options.check_path_text(path + "/" + "z" * 76, "--out", False)  # 4096 bytes: at the limit
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
    assert options.flag(SimpleNamespace(name="jobs", metavar=None)) == "JOBS"  # no opts at all


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
    with pytest.raises(DataError, match="^--data .*no.h5: not found$"):
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


def test_a_number_is_shown_whole_up_to_40_characters():
    rule = Number(0, 1, "x")
    with pytest.raises(DataError, match=rf"^--n {10**39}: expected"):
        options._check_number(10**39, rule, "--n")  # 40 digits
    with pytest.raises(DataError, match=r"^--n 10000000000000000000\.\.\. \(41 digits\)"):
        options._check_number(10**40, rule, "--n")
    # only numbers are checked: a flag or a text is never refused as one
    options._check_number(True, Number(2, 3, "x"), "--n")
    options._check_number("5", Number(2, 3, "x"), "--n")


def test_the_items_of_a_list_keep_the_commands_own_rule():
    with pytest.raises(DataError, match=r"^--frames 1: expected a number of frames, at least 2"):
        options._check_value([3, 1], "synth", _param("frames"), "--frames")


def test_a_value_of_another_kind_is_not_checked_as_a_number():
    import enum

    class Mode(enum.Enum):
        FAST = 1

    options._check_value(Mode.FAST, "x", _param("new_option"), "--mode")
    options._check_value(Mode.FAST, "run", _param("frames"), "--frames")


def _typed(annotation, **more):
    return SimpleNamespace(type_descriptor=SimpleNamespace(annotation=annotation), **more)


def test_numeric_parameters_are_ints_floats_and_tuples_holding_one():
    assert options.is_numeric(_typed(int)) and options.is_numeric(_typed(float))
    assert options.is_numeric(_typed(tuple[Path, int], is_flag=False))
    assert not options.is_numeric(_typed(str)) and not options.is_numeric(_typed(tuple[str, str]))
    assert not options.is_numeric(_typed(int, is_flag=True))  # a counting flag is no option
    assert not options.is_numeric(SimpleNamespace())  # no type known
    assert not options.is_numeric(SimpleNamespace(type_descriptor=None, is_flag=False))


def test_numeric_parameters_are_found_with_their_command_path():
    n, t = _typed(int, name="n"), _typed(str, name="t")
    leaf = SimpleNamespace(params=[n, t])
    group = SimpleNamespace(commands={"npy": leaf}, params=[])
    top = SimpleNamespace(commands={"convert": group}, params=[_typed(float, name="f")])
    found = [(path, p.name) for path, p in options.numeric_params(top)]
    assert found == [(("convert", "npy"), "n"), ((), "f")]


def _app(calls):
    import typer

    app = typer.Typer()

    def version(value: bool):
        return value

    @app.command()
    def run(data: Path = typer.Option(None, "--data"), out: Path = typer.Option(None, "--out"),
            frames: int = typer.Option(1, "-n", "--frames"),
            verbose: bool = typer.Option(False, "--verbose"),
            show: bool = typer.Option(False, "--version", is_eager=True, callback=version)):
        calls.append(("run", data, out, frames))

    @app.command()
    def synth(frames: int = typer.Option(10, "--frames")):
        calls.append(("synth", frames))

    return typer.main.get_command(app)


def test_attach_checks_every_parameter_by_its_commands_rules_before_the_body(tmp_path):
    calls = []
    command = _app(calls)
    options.attach(command)
    command.main(["run", "--frames", "5", "--data", str(tmp_path)], standalone_mode=False)
    assert calls == [("run", tmp_path, None, 5)]  # the converted values reach the command
    command.main(["run", "--frames", "1"], standalone_mode=False)
    for args, says in ((["run", "-n", "0"], "--frames 0: expected a number of frames"),
                       (["synth", "--frames", "1"], "--frames 1: expected a number of frames, "
                                                    "at least 2"),
                       (["run", "--data", ""], "--data '': expected a path, got an empty one"),
                       (["run", "--out", "a\0b"], "--out 'a\\x00b': a path cannot hold a NUL"),
                       (["run", "--data", str(tmp_path / "no")], f"--data {tmp_path / 'no'}: "
                                                                 "not found")):
        with pytest.raises(DataError) as err:
            command.main(args, standalone_mode=False)
        assert str(err.value).startswith(says), str(err.value)
    assert len(calls) == 2  # no refused command ran
    command.main(["run", "--out", ""], standalone_mode=False)  # an output may be empty


def test_attach_wraps_each_parameter_once_and_skips_flags(monkeypatch):
    seen = []
    monkeypatch.setattr(options, "_check_value",
                        lambda value, command, param, option: seen.append((command, option)))
    command = _app([])
    options.attach(command)
    options.attach(command)  # a second walk wraps nothing again
    command.main(["run", "--frames", "3", "--verbose"], standalone_mode=False)
    assert sorted(seen) == [("run", "--data"), ("run", "--frames"), ("run", "--out")]


def test_path_parameters_are_those_typed_path():
    assert options._is_path_param(_typed(Path)) and options._is_path_param(_typed(Path | None))
    assert options._is_path_param(_typed(list[Path]))
    assert not options._is_path_param(_typed(str)) and not options._is_path_param(_typed(int))
    assert not options._is_path_param(SimpleNamespace())


def test_arguments_eager_options_and_the_context_of_a_wrapped_parameter(tmp_path):
    """An argument (no is_flag of its own) is checked like an option; an eager option that is
    no flag is left to its own callback (--seeds -5 would be refused); the parameter's
    callback still gets the context."""
    import click

    seen = []

    def doubled(ctx, param, value):
        seen.append(ctx.info_name)
        return value * 2

    cmd = click.Command("gen", callback=lambda **kw: seen.append(kw), params=[
        click.Argument(["store"], type=click.Path(path_type=Path)),
        click.Option(["--seeds"], is_eager=True, type=int, default=-5),
        click.Option(["--frames"], type=int, default=5),
        click.Option(["--stride"], type=int, default=5, callback=doubled)])
    cmd.params[0].type_descriptor = SimpleNamespace(annotation=Path)
    group = click.Group("top", commands={})
    group.add_command(cmd, name="synth")  # registered under another name than its own
    options.attach(group)
    with pytest.raises(DataError, match=f"^STORE {tmp_path / 'no'}: not found$"):
        group.main(["synth", str(tmp_path / "no")], standalone_mode=False)
    group.main(["synth", str(tmp_path)], standalone_mode=False)
    assert seen == ["synth", {"store": tmp_path, "seeds": -5, "frames": 5,
                    "stride": 10}]
    # the name it is registered under picks the rule: synth's frames are 2 and more
    with pytest.raises(DataError, match=r"^--frames 1: expected a number of frames, at least 2"):
        group.main(["synth", str(tmp_path), "--frames", "1"], standalone_mode=False)


def test_a_command_attached_alone_is_checked_under_its_own_name():
    import click

    cmd = click.Command("synth", callback=lambda **kw: None,
                        params=[click.Option(["--frames"], type=int, default=5)])
    options.attach(cmd)
    with pytest.raises(DataError, match=r"^--frames 1: expected a number of frames, at least 2"):
        cmd.main(["--frames", "1"], standalone_mode=False)


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    from methods import registry

    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    monkeypatch.delenv("DOPPLER_BENCH_METHODS", raising=False)
    registry.load_plugins("")  # the built-in methods only, for the tests after this one


def test_the_environment_is_checked_variable_by_variable(plugins, monkeypatch):
    from methods import registry

    monkeypatch.delenv("DOPPLER_BENCH_METHODS", raising=False)
    options.check_environment()
    monkeypatch.setenv("BENCH_MAX_FRAME_MB", "nan")
    with pytest.raises(DataError, match="BENCH_MAX_FRAME_MB"):
        options.check_environment()
    monkeypatch.delenv("BENCH_MAX_FRAME_MB")
    monkeypatch.setenv("DOPPLER_BENCH_TIMING_LOCK", str(plugins / "missing" / "t.lock"))
    with pytest.raises(DataError, match="DOPPLER_BENCH_TIMING_LOCK"):
        options.check_environment()
    monkeypatch.delenv("DOPPLER_BENCH_TIMING_LOCK")
    (plugins / "good_plugin_rules.py").write_text(
        "from methods.icp import PointToPointIcp\n\n\nclass Mine(PointToPointIcp):\n"
        "    name = 'mine-rules'\n\n\nMETHODS = [Mine]\n")
    monkeypatch.setenv("DOPPLER_BENCH_METHODS", "good_plugin_rules")
    options.check_environment()
    assert registry.get_method("mine-rules").__name__ == "Mine"
    monkeypatch.delenv("DOPPLER_BENCH_METHODS")
    options.check_environment()  # unset: the plugins of the earlier value are forgotten
    with pytest.raises(Exception, match="mine-rules"):
        registry.get_method("mine-rules")


def _fresh_check(env: dict, plugin_dir) -> list[str]:
    """check_environment in a fresh interpreter (the package this test imported first on its
    path, so a mutated copy is the one run): which of the registry and a plugin it loaded."""
    import subprocess
    import sys
    from pathlib import Path

    import bench

    code = ("import sys\nfrom bench import options\noptions.check_environment()\n"
            "print('registry' if 'methods.registry' in sys.modules else 'no-registry')\n"
            "if 'methods.registry' in sys.modules:\n"
            "    from methods import registry\n"
            "    print(sorted(n for n in registry.METHODS if n.startswith('fresh-')))\n")
    root = Path(bench.__file__).resolve().parents[1]
    path = os.pathsep.join([str(root), str(plugin_dir)])
    run_env = {k: v for k, v in os.environ.items() if k != "DOPPLER_BENCH_METHODS"}
    run_env.update(PYTHONPATH=path, **env)
    # run from the package's root, as a user in a checkout would (mutmut's trampolines find
    # their configuration there); the check writes nothing
    out = subprocess.run([sys.executable, "-c", code], env=run_env, cwd=root,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.split("\n")[:2]


def test_a_fresh_process_imports_the_registry_only_to_load_plugins(tmp_path, monkeypatch):
    """The registry (every method's module) is imported by the environment check only when the
    variable names plugins: without it a command's check stays cheap; with it the plugin's
    method is registered before any work. (The check runs here too, so that mutation testing,
    which picks a mutant's tests by the functions they call in-process, runs this test.)"""
    monkeypatch.delenv("DOPPLER_BENCH_METHODS", raising=False)
    options.check_environment()
    (tmp_path / "fresh_plugin_rules.py").write_text(
        "from methods.icp import PointToPointIcp\n\n\nclass Fresh(PointToPointIcp):\n"
        "    name = 'fresh-rules'\n\n\nMETHODS = [Fresh]\n")
    assert _fresh_check({}, tmp_path)[0] == "no-registry"
    assert _fresh_check({"DOPPLER_BENCH_METHODS": " , "}, tmp_path)[0] == "no-registry"
    assert _fresh_check({"DOPPLER_BENCH_METHODS": "fresh_plugin_rules"}, tmp_path) == [
        "registry", "['fresh-rules']"]
