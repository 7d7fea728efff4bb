"""The helpers of the `bench` entry point (bench/cli.py), each called in this process: how
``main`` turns each kind of failure into one message and an exit code, the early check of
every --out / --name, ``--param key=value`` parsing, the usage metavars, ``--version`` and
warnings. Written against the surviving mutants of ``make mutate`` on bench/cli.py."""

from __future__ import annotations

import warnings
from importlib.metadata import version

import click
import pytest
import typer
import yaml
from helpers_cli import bench_main
from rich.console import Console

from bench import cli
from loaders.errors import DataError

# -- main: one line and an exit code per kind of failure ----------------------------------------


class _Command:
    """A stand-in for the click command tree: ``main`` returns ``result`` or raises it."""

    def __init__(self, result):
        self.result = result
        self.calls = []

    def main(self, **kwargs):
        self.calls.append(kwargs)
        if isinstance(self.result, BaseException):
            raise self.result
        return self.result


def _main_with(monkeypatch, capsys, result, args=("list",)):
    """(exit code, stdout, stderr, the stand-in) of ``bench ARGS`` whose command gives
    ``result``."""
    command = _Command(result)
    monkeypatch.setattr(cli, "_command", lambda: command)
    monkeypatch.setattr("sys.argv", ["bench", *args])
    monkeypatch.setattr(warnings, "showwarning", warnings.showwarning)  # main replaces it
    with pytest.raises(SystemExit) as exit_:
        cli.main()
    out = capsys.readouterr()
    return exit_.value.code, out.out, out.err, command


@pytest.mark.parametrize("result, code", [(0, 0), (1, 1), (3, 3), (None, 0), ("text", 0)])
def test_main_exits_with_the_commands_code_when_it_is_a_number(monkeypatch, capsys, result,
                                                               code):
    got, out, err, command = _main_with(monkeypatch, capsys, result)
    assert got == code and out == "" and err == ""
    assert command.calls == [{"prog_name": "bench", "standalone_mode": False}]


@pytest.mark.parametrize("error", [
    DataError("no such [bold]store[/bold]"),
    FileNotFoundError("no such [bold]store[/bold]"),
    IsADirectoryError("no such [bold]store[/bold]"),
    NotADirectoryError("no such [bold]store[/bold]"),
    PermissionError("no such [bold]store[/bold]"),
])
def test_a_user_error_is_one_error_line_on_stderr_and_exit_2(monkeypatch, capsys, error):
    code, out, err, _ = _main_with(monkeypatch, capsys, error)
    # the message as given (square brackets are text, not markup), nothing on stdout
    assert code == 2 and out == "" and err == "error: no such [bold]store[/bold]\n"


@pytest.mark.parametrize("exit_code", [0, 1, 4])
def test_typer_exit_keeps_its_code(monkeypatch, capsys, exit_code):
    code, out, err, _ = _main_with(monkeypatch, capsys, typer.Exit(exit_code))
    assert code == exit_code and out == err == ""


@pytest.mark.parametrize("error", [typer.Abort(), KeyboardInterrupt()])
def test_ctrl_c_is_exit_130_with_one_line(monkeypatch, capsys, error):
    code, out, err, _ = _main_with(monkeypatch, capsys, error)
    assert code == 130 and out == "" and err == "aborted (Ctrl-C)\n"


def test_an_unexpected_error_is_not_swallowed(monkeypatch, capsys):
    with pytest.raises(RuntimeError, match="a bug"):
        _main_with(monkeypatch, capsys, RuntimeError("a bug"))


def test_a_click_error_without_context_is_shown_by_click(monkeypatch, capsys):
    # click's own form ("Error: ...") and its exit code 1, not bench's error line
    code, out, err, _ = _main_with(monkeypatch, capsys, click.ClickException("gone [x]"))
    assert code == 1 and err == "Error: gone [x]\n" and "error:" not in err


class _UsageError(Exception):
    """An error shaped as click's usage errors: shown, with an exit code and a context."""

    exit_code = 2

    def __init__(self, ctx):
        super().__init__("bad usage")
        self.ctx = ctx

    def show(self):
        raise AssertionError("a usage error is printed as bench's error line")

    def format_message(self):
        return "bad usage"


def test_a_usage_error_whose_context_has_no_command_path_gets_no_hint(monkeypatch, capsys):
    code, out, err, _ = _main_with(monkeypatch, capsys, _UsageError(object()))
    assert code == 2 and err == "error: bad usage\n"


@pytest.mark.parametrize("error", [type("Coded", (Exception,), {"exit_code": 3})("coded"),
                                   type("Shown", (Exception,), {"show": print})("shown")])
def test_an_error_with_only_an_exit_code_or_only_show_is_not_a_click_error(monkeypatch, capsys,
                                                                           error):
    with pytest.raises(type(error)):
        _main_with(monkeypatch, capsys, error)


def test_a_long_usage_error_stays_one_line_on_a_narrow_terminal(monkeypatch, capsys):
    narrow = Console(width=30, soft_wrap=False, highlight=False, no_color=True,
                     force_terminal=False, stderr=True)
    monkeypatch.setattr(cli, "status", narrow)
    ctx = click.Context(click.Command("run"), info_name="bench run")
    error = click.UsageError("No such option: --a-very-long-option-name (did you mean "
                             "--another-long-option-name?)", ctx=ctx)
    code, out, err, _ = _main_with(monkeypatch, capsys, error)
    assert code == 2 and err == ("error: No such option: --a-very-long-option-name (did you "
                                 "mean --another-long-option-name?) (see bench run --help)\n")


def test_a_usage_error_without_a_command_path_is_one_line_without_a_hint(monkeypatch, capsys):
    error = click.UsageError("a wrong [bold]thing[/bold]", ctx=None)
    code, out, err, _ = _main_with(monkeypatch, capsys, error)
    assert code == 2 and err == "error: a wrong [bold]thing[/bold]\n"


def test_an_unknown_option_is_one_line_naming_it_and_the_commands_help(monkeypatch, capsys):
    code, text = bench_main(monkeypatch, capsys, "run", "--no-such-option")
    assert code == 2
    assert text == "error: No such option: --no-such-option (see bench run --help)", text


def test_bench_without_a_command_prints_the_help(monkeypatch, capsys):
    code, text = bench_main(monkeypatch, capsys)
    assert code == 2 and text.startswith("Usage: bench [OPTIONS] COMMAND")
    assert "error:" not in text and "Commands" in text


def test_main_routes_warnings_to_one_warning_line(monkeypatch, capsys):
    _main_with(monkeypatch, capsys, 0)
    assert warnings.showwarning is cli._show_warning


def test_a_warning_is_one_line_on_stderr_with_its_text_as_given(capsys):
    cli._show_warning(UserWarning("odd [red]value[/red]"), UserWarning, "f.py", 1)
    out = capsys.readouterr()
    assert out.out == "" and out.err == "warning: odd [red]value[/red]\n"


# -- --version -----------------------------------------------------------------------------------


def test_version_prints_the_installed_version_and_exits_0(capsys):
    with pytest.raises(typer.Exit) as exit_:
        cli._version(True)
    assert exit_.value.exit_code == 0
    assert capsys.readouterr().out == f"doppler-bench {version('doppler-bench')}\n"


def test_no_version_flag_does_nothing(capsys):
    assert cli._version(False) is None
    assert capsys.readouterr().out == ""


def test_bench_version_through_main(monkeypatch, capsys):
    code, text = bench_main(monkeypatch, capsys, "--version")
    assert code == 0 and text == f"doppler-bench {version('doppler-bench')}"


# -- every --out and --name checked before anything runs -----------------------------------------


@pytest.mark.parametrize("option", ["--out", "--write", "--fidelity-out", "--plot", "--data-dir"])
def test_an_empty_output_path_is_refused_naming_its_option(option):
    for args in (["run", option, ""], ["run", f"{option}="], ["run", option, " "]):
        with pytest.raises(DataError, match=f"^{option} '.*': empty; expected the path"):
            cli.check_names(args)


def test_a_name_is_one_path_component_and_a_path_may_have_many():
    with pytest.raises(DataError, match="^--name 'a/b': expected one path component"):
        cli.check_names(["score", "t.txt", "--name", "a/b"])
    with pytest.raises(DataError, match="^--name '': expected one path component"):
        cli.check_names(["score", "--name="])
    cli.check_names(["score", "--name", "ok", "--out", "a/b/c"])  # both fine


def test_a_long_name_in_an_output_path_is_refused():
    with pytest.raises(DataError, match="^--out .*bytes long"):
        cli.check_names(["--out", "x" * 300])


def test_arguments_after_double_dash_and_other_options_are_not_checked():
    cli.check_names(["run", "--", "--out", ""])
    cli.check_names(["run", "--outs", "", "--names", "a/b", "--method", ""])
    cli.check_names(["run", "--method", "--out"])  # a value, not the option at the end
    cli.check_names(["run", "--out"])  # no value: the parser says so
    with pytest.raises(DataError, match="^--out"):  # the check goes on after other options
        cli.check_names(["run", "--method", "doppler", "--out", ""])


def test_check_names_reads_every_argument(monkeypatch, capsys):
    code, out, err, command = _main_with(monkeypatch, capsys, 0,
                                         args=("--name=x/y", "run"))
    assert code == 2 and command.calls == []
    assert err.startswith("error: --name 'x/y': expected one path component")


def test_check_names_runs_before_the_command(monkeypatch, capsys):
    code, out, err, command = _main_with(monkeypatch, capsys, 0,
                                         args=("run", "--name", "x/y"))
    assert code == 2 and command.calls == [] and out == ""
    assert err.startswith("error: --name 'x/y': expected one path component")


# -- --param / --option key=value ---------------------------------------------------------------


def test_params_parse_as_yaml_values():
    assert cli._parse_params(None) == {}
    assert cli._parse_params([]) == {}
    got = cli._parse_params([" tau = 3", "scale=0.5", "on=true", "xs=[1, 2]", "eq=a=b",
                             "name=abc", "empty="])
    assert got == {"tau": 3, "scale": 0.5, "on": True, "xs": [1, 2], "eq": "a=b",
                   "name": "abc", "empty": None}
    assert isinstance(got["tau"], int) and isinstance(got["scale"], float)


@pytest.mark.parametrize("item", ["tau", "=3", " =3", "", "= =3"])
def test_a_param_without_a_key_is_refused_naming_the_option(item):
    with pytest.raises(DataError) as err:
        cli._parse_params([item])
    assert str(err.value) == f"--param expects key=value, got {item!r}"
    with pytest.raises(DataError) as err:
        cli._parse_params(["a=1", item], "--option")
    assert str(err.value) == f"--option expects key=value, got {item!r}"


def test_a_value_that_is_no_yaml_is_refused_with_the_parsers_first_line():
    with pytest.raises(yaml.YAMLError) as parser:
        yaml.safe_load("[1, 2")
    first, second = str(parser.value).splitlines()[:2]
    assert first != second
    with pytest.raises(DataError) as err:
        cli._parse_params(["xs=[1, 2"], "--option")
    assert str(err.value) == f"--option 'xs=[1, 2': the value is not a YAML value ({first})"


def test_the_key_is_what_comes_before_the_first_equals_sign():
    assert cli._parse_params(["a=b=c"]) == {"a": "b=c"}
    with pytest.raises(DataError, match="^--param expects key=value, got '=a=b'$"):
        cli._parse_params(["=a=b"])


@pytest.mark.parametrize("value", [".nan", ".inf", "-.inf", "[1, .nan]", "{a: {b: .inf}}",
                                   "[[0.5, -.inf]]"])
def test_a_value_that_is_not_finite_is_refused(value):
    with pytest.raises(DataError) as err:
        cli._parse_params([f"k={value}"], "--option")
    assert str(err.value) == f"--option 'k={value}': expected finite numbers (not nan or inf)"


@pytest.mark.parametrize("value, finite", [
    (float("nan"), False), (float("inf"), False), (-float("inf"), False), (1e308, True),
    (-2.5, True), (0.0, True), (3, True), ("nan", True), (None, True),
    ({"a": 1.0, "b": {"c": float("nan")}}, False), ({"a": [1.0, 2]}, True),
    ([1.0, [2.0, float("inf")]], False), ([1.0, "x"], True), ({}, True), ([], True),
])
def test_finite_looks_into_lists_and_mappings(value, finite):
    assert cli._finite(value) is finite


# -- usage metavars ------------------------------------------------------------------------------


def _params(command):
    return {p.name: p for p in command.params}


def test_every_value_gets_a_metavar_in_capitals_and_flags_none():
    command = typer.main.get_command(cli.app)
    cli.tidy_help(command)
    run = _params(command.commands["run"])
    assert run["param"].metavar == "KEY=VALUE"  # from the table
    assert run["experiment"].metavar == "EXPERIMENT.yaml"
    assert run["scheduler"].metavar == "SCHEDULER"  # not in the table: its name in capitals
    assert run["force"].metavar is None and run["seed"].metavar is None  # flags
    score = _params(command.commands["score"])
    assert score["out"].metavar == "RESULTS_DIR"  # its own metavar is kept
    assert score["format"].metavar == "auto|tum|kitti|boreas|bag"
    # through the groups: bench convert dataset
    dataset = _params(command.commands["convert"].commands["dataset"])
    assert dataset["raw_dir"].metavar == "RAW_DIR" and dataset["jobs"].metavar == "N"
    # an argument's usage shows its metavar only, no Python type
    ctx = click.Context(command.commands["inspect"])
    path = _params(command.commands["inspect"])["path"]
    assert path.metavar == "STORE_OR_FOLDER" and path.display_type_rich(ctx) is None
    assert _params(command.commands["inspect"])["plot"].metavar == "PLOT"


def test_the_help_option_keeps_no_metavar():
    command = typer.main.get_command(cli.app)
    cli.tidy_help(command)
    helps = [p for p in command.commands["run"].get_params(click.Context(command))
             if p.name == "help"]
    assert helps and all(p.metavar is None for p in helps)
