"""``bench convert LOADER`` as built from a loader's Options model (bench/data/convert.py), each
piece called in this process: field types to command-line types and metavars, the ground-truth
note and warning, the store written with its throughput line, the group's listing, and the
refusals before any input is read. Written against the surviving mutants of ``make mutate`` on
bench/data/convert.py."""

from __future__ import annotations

import re
import time
import typing
from pathlib import Path
from typing import Literal

import click
import numpy as np
import pytest
from pydantic import Field
from rich.console import Console
from typer.testing import CliRunner

from bench.cli import app
from bench.data import convert
from bench.data.convert import (
    _cli_type,
    _metavar,
    _unwrap,
    ground_truth_note,
    gt_flags,
    loader_command,
    option_parameters,
    report_ground_truth,
    write_with_progress,
)
from conftest import constant_twist_sequence
from loaders.errors import DataError, GroundTruthWarning
from loaders.options import GroundTruthTimeOptions, LoaderOptions
from loaders.registry import LOADERS, LoaderEntry
from loaders.store import StoreSequence, write_store
from test_data_convert_batch_mutants import _frames as npy_frame_folder

runner = CliRunner()

# -- field types -> command-line types --------------------------------------------------------


@pytest.mark.parametrize("annotation, unwrapped, optional", [
    (int, int, False),
    (int | None, int, True),
    (typing.Optional[str], str, True),  # noqa: UP045 - the typing spelling too
    (str | Path | None, str | Path, True),
    (list[int], list[int], False),
    (Literal["a", "b"] | None, Literal["a", "b"], True),
    (tuple[int, type(None)], tuple[int, type(None)], False),  # None inside, not optional
])
def test_unwrap_drops_none(annotation, unwrapped, optional):
    got, was_optional = _unwrap(annotation)
    assert was_optional is optional
    assert got == unwrapped or set(typing.get_args(got)) == set(typing.get_args(unwrapped))


@pytest.mark.parametrize("tp, cli", [
    (str, str), (int, int), (float, float), (Path, Path), (bool, bool),
    (Literal["keep", "trim"], Literal["keep", "trim"]),
    (Literal[1, 2], int), (Literal[1, 0.5], float), (Literal[0.25, 0.5], float),
    (list[int], list[int]), (list[Path], list[Path]), (list[float], list[float]),
    (list[Literal["a", "b"]], None),  # a list of choices: config only
    (list[dict], None), (dict, None), (dict[str, int], None), (tuple, None),
    (str | Path, Path), (Path | str, Path), (int | str, str), (int | float, str),
    (int | Path, str),
    (str | dict, None),
])
def test_cli_type_of_each_field_type(tp, cli):
    assert _cli_type(tp) == cli


@pytest.mark.parametrize("name, flag, tp, metavar", [
    ("kind", "kind", Literal["radar", "lidar"], "radar|lidar"),
    ("uncovered", "uncovered", Literal["keep", "trim", "error"], "keep|trim|error"),
    ("gt", "gt", Path, "PATH"),
    ("period_s", "period", float, "SECONDS"),
    ("max_gap_s", "max-gap", float, "SECONDS"),
    ("doppler_field", "doppler-field", str, "DOPPLER_FIELD"),
    ("limit", "limit", Literal[1, 2], "LIMIT"),
    ("path_like", "path-like", str, "PATH_LIKE"),
])
def test_metavar_of_each_option(name, flag, tp, metavar):
    assert _metavar(name, flag, tp) == metavar


def test_gt_flags_are_the_ground_truth_options_in_order():
    flags = {"gt_topic": "--gt-topic", "period_s": "--period", "gt": "--gt"}
    assert gt_flags(flags) == ["--gt", "--gt-topic"]
    assert gt_flags({"gt_topic": "--gt-topic"}) == ["--gt-topic"]
    assert gt_flags({"period_s": "--period"}) == []


class _Options(GroundTruthTimeOptions):
    """A loader's options: one of each kind of field."""

    zeta: int = Field(3, description="a count")
    alpha_s: float | None = Field(None, description="a time")
    mode: Literal["fast", "slow"] = Field("fast", description="a choice")
    on: bool = Field(True, description="on by default")
    off: bool = Field(False, description="off by default")
    hidden: int = Field(1, description="config only", json_schema_extra={"cli": False})
    table: dict = Field(default_factory=dict, description="a mapping")
    empty: str = Field("", description="empty default")
    bare: int = 5


def _built(Options):
    """The click options of a command made from ``option_parameters(Options)``, by name, and
    the flags for messages."""
    params, flags = option_parameters(Options)

    def run(**values) -> None:
        pass

    command = convert._command_from("x", run, params, "help", "short")
    return {p.name: p for p in command.params}, params, flags


def test_option_parameters_one_per_command_line_field():
    options, params, flags = _built(_Options)
    # the loader's own fields first (as the model has them), the shared ones last
    assert [p.name for p in params] == ["zeta", "alpha_s", "mode", "on", "off", "empty", "bare",
                                        "name", "time_offset_s", "max_gap_s", "uncovered"]
    assert "hidden" not in options and "table" not in options  # config only / no CLI form
    assert flags == {"zeta": "--zeta", "alpha_s": "--alpha", "mode": "--mode", "on": "--on",
                     "off": "--off", "empty": "--empty", "bare": "--bare", "name": "--name",
                     "time_offset_s": "--time-offset", "max_gap_s": "--max-gap",
                     "uncovered": "--uncovered"}
    assert all(p.kind is p.KEYWORD_ONLY and p.default is None for p in params)
    assert all(o.default is None for o in options.values())  # unset: the model's default
    assert (options["on"].opts, options["on"].secondary_opts) == (["--on"], ["--no-on"])
    assert options["on"].help == "on by default [default: on]"
    assert (options["off"].opts, options["off"].secondary_opts) == (["--off"], [])
    assert options["off"].help == "off by default" and options["off"].is_flag
    assert options["zeta"].help == "a count [default: 3]" and options["zeta"].metavar == "ZETA"
    assert options["alpha_s"].help == "a time" and options["alpha_s"].metavar == "SECONDS"
    assert options["mode"].metavar == "fast|slow" and options["mode"].opts == ["--mode"]
    assert options["uncovered"].help.endswith(" [default: keep]")
    assert options["empty"].help == "empty default"
    assert options["bare"].help == "[default: 5]"  # no description: the default only
    assert all(o.show_default is False for o in options.values())


def test_a_bool_field_with_its_own_pair_of_flags():
    class Own(LoaderOptions):
        origin: bool = Field(True, description="d",
                             json_schema_extra={"cli": "remove-origin/keep-utm"})

    options, _, flags = _built(Own)
    assert options["origin"].opts == ["--remove-origin"]
    assert options["origin"].secondary_opts == ["--keep-utm"]
    assert flags["origin"] == "--remove-origin"


# -- ground truth: where it came from, or a warning ---------------------------------------------


class _Seq:
    def __init__(self, n, gt, provenance=None, name="seq"):
        self.n, self.ground_truth, self.name = n, gt, name
        if provenance is not ...:
            self.provenance = provenance

    def __len__(self):
        return self.n


@pytest.mark.parametrize("provenance, note", [
    ({"gt_file": "a.txt", "gt": "x"}, "ground truth: a.txt (7 poses)"),
    ({"gt": "c.txt"}, "ground truth: c.txt (7 poses)"),
    ({}, "ground truth: from the input (7 poses)"),
    (None, "ground truth: from the input (7 poses)"),
    (..., "ground truth: from the input (7 poses)"),  # no provenance at all
    ({"gt_association": {"gt_file": "b.txt", "with_gt": 3, "kept": 4}},
     "ground truth: b.txt (3 of 4 scans have a pose)"),
    ({"gt_association": {"with_gt": 3}, "gt_file": "a.txt"},
     "ground truth: a.txt (3 of 9 scans have a pose)"),
    ({"gt_association": "text", "gt": "d.txt"}, "ground truth: d.txt (7 poses)"),
])
def test_ground_truth_note(provenance, note):
    assert ground_truth_note(_Seq(9, [0] * 7, provenance)) == note


def test_no_ground_truth_is_no_note_and_a_warning_naming_the_options(capsys):
    seq = _Seq(3, None, {"gt_file": "a.txt"}, name="run7")
    assert ground_truth_note(seq) is None
    with pytest.warns(GroundTruthWarning) as caught:
        report_ground_truth(seq, ["--gt", "--gt-topic"])
    assert str(caught[0].message) == (
        "run7: no ground truth found: the store will hold the scans only, and `bench run` on "
        "it computes trajectories but scores none (give it with --gt or --gt-topic)")
    with pytest.warns(GroundTruthWarning, match=r"scores none \(this loader reads none from "
                                                r"its input\)$"):
        report_ground_truth(seq, [])
    assert capsys.readouterr().out == ""


def test_ground_truth_is_one_line_as_given(capsys):
    report_ground_truth(_Seq(2, [0, 0], {"gt_file": "[bold]g.txt"}), ["--gt"])
    assert capsys.readouterr().out == "ground truth: [bold]g.txt (2 poses)\n"


# -- the store and its throughput line ------------------------------------------------------------


def _recording_console(monkeypatch):
    console = Console(record=True, width=400, force_terminal=False)
    monkeypatch.setattr(convert, "console", console)
    return console


def test_write_with_progress_writes_the_store_and_says_how_fast(tmp_path, monkeypatch):
    console = _recording_console(monkeypatch)
    seq = constant_twist_sequence(n_frames=12, n_points=50)
    out = tmp_path / "sub" / "s.h5"
    t0 = time.perf_counter()
    assert write_with_progress(seq, str(out)) == out
    took = time.perf_counter() - t0
    st = StoreSequence(out)
    try:
        assert len(st) == 12
        np.testing.assert_allclose(st.scan(11).points, seq.scan(11).points, atol=1e-5)
    finally:
        st.close()
    text = console.export_text()
    size = out.stat().st_size / 1e6
    wrote = re.search(rf"wrote {re.escape(str(out))}: 12 frames in (\d+\.\d) s \((\d+) frames/s\), "
                      rf"{size:.1f} MB", text)
    assert wrote, text
    wall, fps = float(wrote.group(1)), int(wrote.group(2))
    assert wall <= took + 0.05  # the time of the write, not a clock reading
    assert fps >= int(12 / took) - 1 and fps >= 1  # 12 frames over at most that time
    # the progress line as it ended: every frame counted, its rate, elapsed and left
    bar = re.search(rf"{re.escape(seq.name)} -> s\.h5 ━+ 12/12 (\d+) frames/s \d:\d\d:\d\d "
                    r"\d:\d\d:\d\d", text)
    assert bar, text
    assert int(bar.group(1)) >= int(fps * 0.9) - 1  # at the last frame, nearly the whole time


def test_write_with_progress_replaces_only_what_its_owner_recognises(tmp_path, monkeypatch):
    _recording_console(monkeypatch)
    seq = constant_twist_sequence(n_frames=3, n_points=20)
    mine = tmp_path / "notes.h5"
    mine.write_text("mine")
    with pytest.raises(DataError, match="is not a store the harness wrote"):
        write_with_progress(seq, mine)  # default: only a store
    with pytest.raises(DataError, match="is not a calibrated store the harness wrote"):
        write_with_progress(seq, mine, lambda p: False, "a calibrated store")
    assert mine.read_text() == "mine"
    write_with_progress(seq, mine, lambda p: True, "a scratch file")
    assert len(StoreSequence(mine)) == 3
    store = write_store(seq, tmp_path / "old.h5")
    write_with_progress(constant_twist_sequence(n_frames=4, n_points=20), store)
    assert len(StoreSequence(store)) == 4


# -- the group and the generated commands --------------------------------------------------------


def test_the_convert_group_lists_dataset_then_every_loader():
    import typer

    group = typer.main.get_command(app).commands["convert"]
    ctx = click.Context(group)
    assert group.list_commands(ctx) == ["dataset", *LOADERS]
    assert group.get_command(ctx, "no-such-loader") is None
    assert group.get_command(ctx, "dataset").name == "dataset"
    command = group.get_command(ctx, "npy-frames")
    assert command.name == "npy-frames"
    assert {"--out", "--period", "--force"} <= {o for p in command.params for o in p.opts}


def test_convert_help_lists_each_loader_with_its_description(monkeypatch):
    ghost = LoaderEntry("ghost", "a loader not written yet", "loaders.no_such_module", "Ghost")
    monkeypatch.setitem(LOADERS, "ghost", ghost)
    res = runner.invoke(app, ["convert", "--help"])
    assert res.exit_code == 0
    text = " ".join(res.output.split())
    assert "ghost a loader not written yet [unavailable]" in text
    assert "dataset sequences from their dataset configs (resumable)" in text
    for name, entry in LOADERS.items():
        if name != "ghost":
            assert f" {name} {' '.join(entry.description.split())} " in text + " ", name
            assert f"{entry.description} [unavailable]" not in text


def test_an_option_of_a_generated_command_is_checked_as_it_is_read(tmp_path):
    res = runner.invoke(app, ["convert", "npy-frames", str(tmp_path), "--period", "nan",
                              "--out", str(tmp_path / "o.h5")])
    assert res.exit_code != 0 and "--period" in str(res.exception) + res.output
    assert not (tmp_path / "o.h5").exists()


def test_the_frame_options_of_every_loader():
    command = loader_command(LOADERS["npy-frames"])
    params = {p.name: p for p in command.params}
    assert params["out"].required and params["out"].metavar == "STORE.h5"
    assert (params["start"].default, params["start"].metavar) == (0, "FRAME")
    assert (params["frames"].default, params["frames"].metavar) == (None, "N")
    assert (params["stride"].default, params["stride"].metavar) == (1, "K")
    assert params["force"].default is False and params["force"].is_flag
    for bad, least in ((["--start", "-1"], 0), (["--frames", "0"], 1), (["--stride", "0"], 1)):
        with pytest.raises(Exception, match=f"greater than or equal to {least}") as err:
            command.make_context("npy-frames", ["in", "--out", "o.h5", *bad])
        assert type(err.value).__name__ == "BadParameter"  # typer's own click
    ctx = command.make_context("npy-frames", ["in", "--out", "o.h5", "--start", "0",
                                              "--frames", "1", "--stride", "1"])
    assert (ctx.params["start"], ctx.params["frames"], ctx.params["stride"]) == (0, 1, 1)
    assert params["inputs"].metavar == "INPUT" and params["inputs"].nargs == 1
    bags = {p.name: p for p in loader_command(LOADERS["ntu4dradlm"]).params}
    assert bags["inputs"].metavar == "INPUT..." and bags["inputs"].nargs == -1
    assert command.help.startswith(f"{LOADERS['npy-frames'].description}.\n\nINPUT: ")
    assert f"\n\nLayout: {LOADERS['npy-frames'].layout}." in command.help
    assert command.short_help == LOADERS["npy-frames"].description


def test_an_unavailable_loader_is_a_command_that_says_so(monkeypatch):
    ghost = LoaderEntry("ghost", "a loader not written yet", "loaders.no_such_module", "Ghost",
                        dataset="Ghost Set")
    command = loader_command(ghost)
    assert command.name == "ghost" and command.help == "a loader not written yet"
    with pytest.raises(DataError) as err:
        command.main(["x", "--any", "option"], standalone_mode=False)
    assert str(err.value) == ("loader 'ghost' (Ghost Set) is listed but unavailable in this "
                              "installation: module loaders.no_such_module not found")
    bare = LoaderEntry("ghost", "a loader not written yet", "loaders.no_such_module", "Ghost")
    with pytest.raises(DataError, match=r"^loader 'ghost' \(a loader not written yet\) is"):
        loader_command(bare).main([], standalone_mode=False)


def _frames(folder, n=6, points=30):
    """Raw npy frames and a GT file (test_data_convert_batch_mutants' helper, seed 5)."""
    return npy_frame_folder(folder, n, points, seed=5)


def test_a_cut_is_named_by_its_frames_unless_a_name_is_given(tmp_path):
    _frames(tmp_path / "f")
    out = tmp_path / "cut.h5"
    res = runner.invoke(app, ["convert", "npy-frames", str(tmp_path / "f"), "--period", "0.1",
                              "--start", "2", "--frames", "3", "--out", str(out)])
    assert res.exit_code == 0, res.output
    st = StoreSequence(out)
    whole_name, cut_name, n = "f", st.name, len(st)
    st.close()
    assert n == 3 and cut_name != whole_name and "2" in cut_name
    named = tmp_path / "named.h5"
    res = runner.invoke(app, ["convert", "npy-frames", str(tmp_path / "f"), "--period", "0.1",
                              "--start", "2", "--frames", "3", "--name", "mine", "--out",
                              str(named)])
    assert res.exit_code == 0, res.output
    st = StoreSequence(named)
    assert st.name == "mine"
    st.close()


def test_an_existing_out_is_replaced_only_with_force_and_only_a_store(tmp_path):
    pts = _frames(tmp_path / "f")
    out = write_store(constant_twist_sequence(n_frames=3, n_points=20), tmp_path / "s.h5")
    args = ["convert", "npy-frames", str(tmp_path / "f"), "--period", "0.1", "--out", str(out)]
    res = runner.invoke(app, args)
    assert isinstance(res.exception, DataError)
    assert str(res.exception).startswith(f"--out {out}: exists (a store); give another --out "
                                         "or --force")
    res = runner.invoke(app, [*args, "--force"])
    assert res.exit_code == 0, res.output
    st = StoreSequence(out)
    np.testing.assert_allclose(st.scan(5).points, pts[5], atol=1e-5)
    st.close()
    # an input named as --out: refused, even with --force
    res = runner.invoke(app, ["convert", "npy-frames", str(tmp_path / "f"), "--period", "0.1",
                              "--gt", str(tmp_path / "f" / "gt.txt"), "--force", "--out",
                              str(tmp_path / "f" / "gt.txt")])
    assert isinstance(res.exception, DataError)
    assert "is an input of this command" in str(res.exception)
    assert (tmp_path / "f" / "gt.txt").read_text().startswith("0.0 0 0 0")


def test_a_long_ground_truth_note_stays_one_line(monkeypatch):
    console = Console(record=True, width=50, force_terminal=False)
    monkeypatch.setattr(convert, "console", console)
    source = "/data/raw/" + "a_rather_long_folder_name/" * 4 + "gt.txt"
    report_ground_truth(_Seq(2, [0, 0], {"gt_file": source}), ["--gt"])
    assert console.export_text() == f"ground truth: {source} (2 poses)\n"


def test_convert_help_lists_its_commands_under_one_heading():
    res = runner.invoke(app, ["convert", "--help"])
    assert res.exit_code == 0
    assert [line for line in res.output.splitlines() if line.endswith(":")
            and not line.startswith(" ")] == ["Options:", "Commands:"]
