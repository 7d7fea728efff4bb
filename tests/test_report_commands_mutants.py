"""bench/report/commands.py (``bench table``, ``compare``, ``figures``, ``report``) in-process,
its collaborators (the table builders, the figure and page writers) replaced by stand-ins that
record what they were asked: the option checks and their messages, where a table is written
(the results folder, --out, never a run folder, a filtered view not at all), what is printed
and the exit codes."""

from __future__ import annotations

import io
import os
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest
from rich.console import Console

import bench.report.compare as compare_mod
import bench.report.figures.draw as draw
import bench.report.figures.pair as pair_mod
import bench.report.html.page as page
import bench.report.tables.ape as ape
import bench.report.tables.model as model
import bench.report.tables.paper as paper
import bench.report.tables.pivot as pivot
import bench.report.tables.stability as stability
import bench.runs.folders as folders
from bench import guard
from bench.report.commands import (
    compare_command,
    figures_command,
    figures_current,
    report_command,
    table_command,
)
from loaders.errors import DataError

#: a folder name that rich markup would eat: every line naming it must print it whole
RES = "[bold]res"


def _console() -> Console:
    return Console(file=io.StringIO(), width=1000, color_system=None)


def _out(console) -> list[str]:
    return console.file.getvalue().splitlines()


def _files(folder: Path) -> list[Path]:
    """The files in ``folder`` but the guard's ledger (a dot file)."""
    return [p for p in folder.iterdir() if not p.name.startswith(".")]


def _row(method="m", variant=False, status="finished", error=None, run_dir="r/x"):
    return SimpleNamespace(method=method, is_variant=variant, run=SimpleNamespace(dir=run_dir),
                           result=SimpleNamespace(status=status, error=error))


@pytest.fixture
def made(monkeypatch):
    """The table builders replaced; returns what they were asked (``asked``) and the rows
    ``select`` returns (``rows``), the runs ``load_runs`` lists (``runs``)."""
    state = SimpleNamespace(asked=[], rows=[_row()], runs=[], select_error=None)

    def select(dirs, lengths_m, keep):
        state.asked.append(("select", dirs, lengths_m, keep))
        if state.select_error:
            raise ValueError(state.select_error)
        return state.rows, "chosen"

    def build(metric, rows, chosen, marks, ci):
        state.asked.append(("build", metric, rows, chosen, marks, ci))
        return SimpleNamespace(csv_file=None, name="built")

    def collect(folder, only, marks, ci):
        state.asked.append(("ape", folder, only, marks, ci))
        return SimpleNamespace(table=SimpleNamespace(csv_file=None, name="ape"))

    def render(table):
        state.asked.append(("render", table.name, table.csv_file))
        return {"md": f"MD {table.name}\n", "tex": "TEX\n", "csv": "CSV\n"}

    def pivot_markdown(rows, chosen, marks, ci):
        state.asked.append(("pivot", rows, chosen, marks, ci))
        return "PIVOT\n"

    def with_stability(rows, chosen, table, marks):
        state.asked.append(("stability", rows, chosen, table.name, marks))

    def load_runs(folder, failed=False):
        state.asked.append(("load_runs", folder, failed))
        return state.runs

    monkeypatch.setattr(paper, "select", select)
    monkeypatch.setattr(paper, "build", build)
    monkeypatch.setattr(ape, "collect_ape", collect)
    monkeypatch.setattr(model, "render", render)
    monkeypatch.setattr(pivot, "pivot_markdown", pivot_markdown)
    monkeypatch.setattr(stability, "with_stability", with_stability)
    monkeypatch.setattr(folders, "load_runs", load_runs)
    return state


def _table(tmp_path, dirs=None, **given):
    args = dict(format="md", out=None, lengths=None, pivot=False, methods=None, variants=True)
    args.update(given)
    console, status = _console(), _console()
    code = table_command(console, status, dirs or [tmp_path / RES], **args)
    return code, status


@pytest.mark.parametrize("given, message", [
    ({"format": "html"}, "unknown table format 'html'; choose from md, tex, csv"),
    ({"metric": "rpe"}, "unknown metric 'rpe'; choose from relative, kitti, ape, velocity"),
    ({"stability": True, "metric": "ape"},
     "--stability: for the relative-error table (Table III) only, not --metric ape"),
    ({"stability": True, "pivot": True},
     "--stability: for the relative-error table (Table III) only, not --pivot"),
    ({"marks": "bold"}, "--marks 'bold': choose from intervals, value"),
    ({"lengths": "8,x"}, "--lengths '8,x': expected numbers in metres, e.g. 8,48"),
])
def test_a_bad_option_is_one_message_naming_it_before_any_work(tmp_path, made, given, message):
    with pytest.raises(DataError) as err:
        _table(tmp_path, **given)
    assert str(err.value) == message
    assert made.asked == []


def test_the_whole_table_of_one_folder_is_written_into_it(tmp_path, made, capsys):
    res = tmp_path / RES
    res.mkdir()
    code, status = _table(tmp_path, marks="significance", ci=True)
    assert code == 0
    assert capsys.readouterr().out == "MD built\n"
    assert made.asked[0][:3] == ("select", [res], None)
    assert made.asked[1] == ("build", "relative", made.rows, "chosen", "intervals", True)
    assert made.asked[2] == ("render", "built", str(res / "table.csv"))
    assert {p.name: p.read_text() for p in _files(res)} == {
        "table.md": "MD built\n", "table.tex": "TEX\n", "table.csv": "CSV\n"}
    assert _out(status) == [f"wrote {res}/table.{{md,tex,csv}}"]
    assert made.asked[-1] == ("load_runs", res, True)


def test_another_metric_is_its_own_file_and_format(tmp_path, made, capsys):
    res = tmp_path / RES
    res.mkdir()
    assert _table(tmp_path, metric="kitti", format="tex")[0] == 0
    assert capsys.readouterr().out == "TEX\n"
    assert made.asked[1][1] == "kitti"
    assert sorted(p.name for p in res.glob("table_kitti.*")) == [
        "table_kitti.csv", "table_kitti.md", "table_kitti.tex"]


@pytest.mark.parametrize("given", [{"variants": False}, {"methods": "m"}, {"lengths": "8"},
                                   {"pivot": True}])
def test_a_filtered_view_is_printed_not_written(tmp_path, made, capsys, given):
    res = tmp_path / RES
    res.mkdir()
    code, status = _table(tmp_path, **given)
    assert code == 0
    assert list(res.iterdir()) == []
    assert _out(status) == ["a filtered or merged view: not written (--out DIR writes it)"]
    assert capsys.readouterr().out in ("MD built\n", "PIVOT\n")


def test_a_merged_view_goes_to_out_only(tmp_path, made, capsys):
    a, b, out = tmp_path / "a", tmp_path / "b", tmp_path / "out"
    a.mkdir(), b.mkdir()
    code, status = _table(tmp_path, dirs=[a, b], out=out, lengths="8,48")
    assert code == 0
    assert made.asked[0][:3] == ("select", [a, b], [8.0, 48.0])
    assert sorted(p.name for p in _files(out)) == ["table.csv", "table.md", "table.tex"]
    assert list(a.iterdir()) == [] and list(b.iterdir()) == []
    assert _out(status) == [f"wrote {out}/table.{{md,tex,csv}}"]


def test_the_pivot_is_markdown_whatever_the_format(tmp_path, made, capsys):
    out = tmp_path / "out"
    code, status = _table(tmp_path, pivot=True, format="csv", out=out, marks="value")
    assert code == 0 and capsys.readouterr().out == "PIVOT\n"
    assert made.asked[1] == ("pivot", made.rows, "chosen", "value", False)
    assert [p.name for p in _files(out)] == ["pivot.md"]
    assert _out(status) == [f"wrote {out}/pivot.{{md}}"]


def test_the_methods_and_variants_kept(tmp_path, made):
    _table(tmp_path, methods=" a, b", variants=False)
    keep = made.asked[0][3]
    assert keep(_row("a")) and keep(_row("b"))
    assert not keep(_row("c")) and not keep(_row("a", variant=True))
    _table(tmp_path)
    keep = [a for a in made.asked if a[0] == "select"][-1][3]
    assert keep(_row("c", variant=True))


def test_a_run_folder_is_never_written_into(tmp_path, made, capsys, monkeypatch):
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)  # nothing goes to the working folder either
    run = tmp_path / "[b]run"
    run.mkdir()
    (run / "metrics.json").write_text("{}")
    code, status = _table(tmp_path, dirs=[run])
    assert code == 0
    assert sorted(p.name for p in run.iterdir()) == ["metrics.json"]
    assert _out(status) == [f"{run} is a run folder: the table is printed, not written "
                            "into it (--out DIR writes it)"]
    assert list(cwd.iterdir()) == []
    inner = run / "sub"
    inner.mkdir()
    _table(tmp_path, dirs=[inner])
    assert list(inner.iterdir()) == [] and list(cwd.iterdir()) == []


def test_two_folders_without_out_are_a_view_printed_only(tmp_path, made, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    code, status = _table(tmp_path, dirs=[a, b])
    assert code == 0 and list(a.iterdir()) == [] and list(b.iterdir()) == []
    assert _out(status) == ["a filtered or merged view: not written (--out DIR writes it)"]


def test_out_that_is_a_file_is_refused(tmp_path, made):
    mine = tmp_path / "notes.txt"
    mine.write_text("mine")
    with pytest.raises(guard.Refused, match="is a file; expected a folder"):
        _table(tmp_path, out=mine)
    assert made.asked == [] and mine.read_text() == "mine"


def test_a_user_s_table_file_is_refused_before_any_work(tmp_path, made):
    res = tmp_path / RES
    res.mkdir()
    (res / "table.tex").write_text("my own table")
    with pytest.raises(guard.Refused, match="is not a table this command wrote"):
        _table(tmp_path)
    assert made.asked == [] and (res / "table.tex").read_text() == "my own table"


def test_a_selection_error_is_one_message(tmp_path, made):
    made.select_error = "no runs under res"
    with pytest.raises(DataError) as err:
        _table(tmp_path)
    assert str(err.value) == "no runs under res"


def test_ape_is_collected_from_one_folder_of_the_selected_runs(tmp_path, made, capsys):
    res = tmp_path / RES
    res.mkdir()
    made.rows = [_row(run_dir="r/1"), _row(run_dir="r/2")]
    assert _table(tmp_path, metric="ape", ci=True)[0] == 0
    assert made.asked[1] == ("ape", res, {"r/1", "r/2"}, "intervals", True)
    assert capsys.readouterr().out == "MD ape\n"
    with pytest.raises(DataError) as err:
        _table(tmp_path, dirs=[res, tmp_path], metric="ape")
    assert str(err.value) == "--metric ape: one results folder at a time"


def test_stability_flags_the_built_table(tmp_path, made):
    _table(tmp_path, stability=True, marks="value", out=tmp_path / "o")
    assert ("stability", made.rows, "chosen", "built", "value") in made.asked


def test_a_broken_record_fails_and_a_run_without_ground_truth_is_named(tmp_path, made, capsys):
    res = tmp_path / RES
    res.mkdir()
    made.rows = [_row(), _row(status=folders.BROKEN, error="r/[i]y/metrics.json: not JSON")]
    made.runs = [SimpleNamespace(dir="r/a", result=SimpleNamespace(finished=True, scored=True)),
                 SimpleNamespace(dir="r/[b]b", result=SimpleNamespace(finished=True, scored=False)),
                 SimpleNamespace(dir="r/c", result=SimpleNamespace(finished=False, scored=False))]
    code, status = _table(tmp_path)
    assert code == 1
    assert _out(status) == ["broken run record: r/[i]y/metrics.json: not JSON",
                            "not in the table: r/[b]b (no ground truth: nothing to score)",
                            f"wrote {res}/table.{{md,tex,csv}}"]
    code, status = _table(tmp_path, variants=False)
    assert code == 1 and _out(status)[-1].startswith("a filtered or merged view")


# --- bench compare ----------------------------------------------------------------------------

def test_compare_prints_the_markdown_and_fails_only_when_asked(tmp_path, monkeypatch, capsys):
    cells = pd.DataFrame({"regression": [False, True, True]})
    asked = []
    monkeypatch.setattr(compare_mod, "compare",
                        lambda a, b, t: asked.append(("cells", a, b, t)) or cells)
    monkeypatch.setattr(compare_mod, "compare_times",
                        lambda a, b: asked.append(("times", a, b)) or "times")
    monkeypatch.setattr(compare_mod, "compare_run_metrics",
                        lambda a, b: asked.append(("runs", a, b)) or "runs")
    monkeypatch.setattr(compare_mod, "to_markdown",
                        lambda c, times, a, b, t, runs: f"{len(c)} {times} {a} {b} {t} {runs}\n")
    a, b = Path("A"), Path("B")
    assert compare_command(_console(), a, b, 0.2, False) == 0
    assert capsys.readouterr().out == "3 times A B 0.2 runs\n"
    assert asked == [("cells", a, b, 0.2), ("times", a, b), ("runs", a, b)]
    assert compare_command(_console(), a, b, 0.2, True) == 1
    cells = pd.DataFrame({"regression": [False, False]})
    assert compare_command(_console(), a, b, 0.2, True) == 0
    cells = pd.DataFrame([])  # no cell in common: no columns at all
    assert compare_command(_console(), a, b, 0.2, True) == 0


# --- bench figures ----------------------------------------------------------------------------

@pytest.fixture
def drawn(monkeypatch):
    state = SimpleNamespace(asked=[], runs=[])

    def make_figures(results_dir, out=None, speed_csv=None):
        state.asked.append(("figures", results_dir, out, speed_csv))
        return [Path("f/[b]a.png"), Path("f/a.pdf"), Path("f/b.png")]

    def plot_pair(store, frame, out):
        state.asked.append(("pair", store, frame, out))
        return [Path("f/[i]pair.png")]

    monkeypatch.setattr(draw, "make_figures", make_figures)
    monkeypatch.setattr(pair_mod, "plot_pair", plot_pair)
    monkeypatch.setattr(folders, "load_runs",
                        lambda d, failed=False: state.asked.append(("load_runs", d, failed))
                        or state.runs)
    return state


def test_figures_of_a_folder_are_listed_png_by_png(tmp_path, drawn, monkeypatch):
    monkeypatch.chdir(tmp_path)
    console = _console()
    assert figures_command(console, tmp_path / RES, None, None, None) == 0
    assert drawn.asked == [("figures", tmp_path / RES, None, None),
                           ("load_runs", tmp_path / RES, True)]
    assert _out(console) == ["wrote f/[b]a.png (+ .pdf)", "wrote f/b.png (+ .pdf)"]


def test_figures_use_the_speed_table_given_else_the_default_one_if_there(tmp_path, drawn,
                                                                         monkeypatch):
    monkeypatch.chdir(tmp_path)
    figures_command(_console(), Path("res"), Path("out"), Path("s.csv"), None)
    assert drawn.asked[-2] == ("figures", Path("res"), Path("out"), Path("s.csv"))
    Path("results/speed").mkdir(parents=True)
    Path("results/speed/speed.csv").write_text("x")
    figures_command(_console(), Path("res"), None, None, None)
    assert drawn.asked[-2] == ("figures", Path("res"), None, Path("results/speed/speed.csv"))


def test_a_pair_figure_goes_to_out_else_results_figures(tmp_path, drawn, monkeypatch):
    monkeypatch.chdir(tmp_path)
    console = _console()
    assert figures_command(console, None, None, None, (Path("s.h5"), 7)) == 0
    assert drawn.asked == [("pair", Path("s.h5"), 7, Path("results/figures"))]
    assert _out(console) == ["wrote f/[i]pair.png (+ .pdf)"]
    figures_command(console, None, tmp_path / "o", None, (Path("s.h5"), 3))
    assert drawn.asked[-1] == ("pair", Path("s.h5"), 3, tmp_path / "o")
    assert (tmp_path / "o").is_dir() is False  # checked, not made (the writers make it)


def test_a_pair_and_a_folder_s_figures_are_all_listed(tmp_path, drawn):
    console = _console()
    assert figures_command(console, tmp_path, tmp_path / "o", None, (Path("s.h5"), 7)) == 0
    assert _out(console) == ["wrote f/[i]pair.png (+ .pdf)", "wrote f/[b]a.png (+ .pdf)",
                             "wrote f/b.png (+ .pdf)"]


def test_figures_refuse_a_run_folder_as_out_and_nothing_to_draw(tmp_path, drawn):
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.json").write_text("{}")
    with pytest.raises(guard.Refused):
        figures_command(_console(), tmp_path, run, None, None)
    assert drawn.asked == []
    with pytest.raises(DataError) as err:
        figures_command(_console(), None, None, None, None)
    assert str(err.value) == "give a RESULTS_DIR with finished runs, or --pair STORE FRAME"


def test_figures_fail_when_a_run_record_is_broken(tmp_path, drawn):
    drawn.runs = [SimpleNamespace(result=SimpleNamespace(status="finished")),
                  SimpleNamespace(result=SimpleNamespace(status=folders.BROKEN))]
    assert figures_command(_console(), tmp_path, None, None, None) == 1
    drawn.runs = drawn.runs[:1]
    assert figures_command(_console(), tmp_path, None, None, None) == 0


# --- figures_current and bench report ---------------------------------------------------------

def _touch(path: Path, mtime: float) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("x")
    os.utime(path, (mtime, mtime))
    return path


def test_figures_are_current_when_none_is_older_than_the_newest_record(tmp_path):
    assert not figures_current(tmp_path)
    _touch(tmp_path / "figures" / "a.png", 100)
    assert figures_current(tmp_path)  # no records: nothing newer
    _touch(tmp_path / "figures" / "a.png", 0.5)
    assert figures_current(tmp_path)  # however old the figure
    _touch(tmp_path / "figures" / "a.png", 100)
    _touch(tmp_path / "s" / "r1" / "metrics.json", 90)
    _touch(tmp_path / "figures" / "sub" / "b.png", 200)
    assert figures_current(tmp_path)
    _touch(tmp_path / "s" / "r2" / "failed.json", 100)
    assert figures_current(tmp_path)  # as old as the oldest figure: current
    _touch(tmp_path / "s" / "r3" / "failed.json", 101)
    assert not figures_current(tmp_path)
    _touch(tmp_path / "figures" / "a.png", 150)
    _touch(tmp_path / "s" / "r4" / "metrics.json", 160)
    assert not figures_current(tmp_path)
    _touch(tmp_path / "figures" / "old.pdf", 1)  # PNGs only
    _touch(tmp_path / "s" / "r4" / "metrics.json", 150)
    assert figures_current(tmp_path)


@pytest.fixture
def paged(monkeypatch):
    state = SimpleNamespace(asked=[], counts={"tables": 2, "figures": 3, "runs": 4, "failed": 1,
                                              "broken": 0, "damaged": 0},
                            figures=[Path("f/[b]a.png"), Path("f/a.pdf"), Path("f/b.png")],
                            error=None, current=False)

    def write_page(results_dir, out):
        state.asked.append(("page", results_dir, out))
        return Path(out or Path(results_dir) / page.PAGE_NAME), state.counts

    def make_figures(results_dir):
        state.asked.append(("figures", results_dir))
        if state.error is not None:
            raise state.error
        return state.figures

    import bench.report.commands as commands

    monkeypatch.setattr(page, "write_page", write_page)
    monkeypatch.setattr(draw, "make_figures", make_figures)
    monkeypatch.setattr(commands, "figures_current", lambda d: state.current)
    return state


def test_the_report_draws_missing_figures_then_writes_the_page(tmp_path, paged):
    res = tmp_path / RES
    res.mkdir()
    console = _console()
    assert report_command(console, res, None) == 0
    assert paged.asked == [("figures", res), ("page", res, None)]
    assert _out(console) == [
        f"drew 2 figure(s) into {res / 'figures'} (PNG, for the page; `bench figures` "
        "writes PDF too)",
        f"wrote {res / page.PAGE_NAME}: 2 table(s), 3 figure(s), 4 run(s), 1 not finished"]


def test_the_report_asks_about_the_figures_of_its_folder(tmp_path, paged, monkeypatch):
    import bench.report.commands as commands

    asked = []
    monkeypatch.setattr(commands, "figures_current", lambda d: asked.append(d) or True)
    report_command(_console(), tmp_path, None)
    assert asked == [tmp_path] and paged.asked == [("page", tmp_path, None)]


def test_the_report_skips_current_figures_or_when_asked(tmp_path, paged):
    paged.current = True
    report_command(_console(), tmp_path, tmp_path / "p.html")
    paged.current = False
    report_command(_console(), tmp_path, None, figures=False)
    assert paged.asked == [("page", tmp_path, tmp_path / "p.html"), ("page", tmp_path, None)]
    paged.figures = [Path("f/a.pdf")]
    console = _console()
    report_command(console, tmp_path, None)
    assert len(_out(console)) == 1 and _out(console)[0].startswith("wrote ")


def test_figures_that_cannot_be_drawn_are_said_and_the_page_still_written(tmp_path, paged):
    paged.error = DataError("r/[b]x/est.tum: unreadable\nmore")
    console = _console()
    assert report_command(console, tmp_path, None) == 0
    assert _out(console)[0] == "figures not drawn: r/[b]x/est.tum: unreadable"
    assert paged.asked[-1] == ("page", tmp_path, None)
    paged.error = guard.Refused("figures/a.png: a user's file")
    with pytest.raises(guard.Refused):
        report_command(_console(), tmp_path, None)


def test_broken_records_and_damaged_folders_fail_the_report(tmp_path, paged):
    paged.counts.update(broken=2, damaged=1)
    console = _console()
    assert report_command(console, tmp_path, None, figures=False) == 1
    assert _out(console)[1:] == [
        "2 run record(s) broken (metrics.json not a valid record): listed under \"Failed runs "
        "and missing data\" on the page; `bench run` runs them again",
        "1 run folder(s) with unreadable files (config.yaml, meta.json or trajectory files): "
        "listed under \"Failed runs and missing data\" on the page"]
    paged.counts.update(broken=0, damaged=1)
    assert report_command(_console(), tmp_path, None, figures=False) == 1
    paged.counts.update(broken=1, damaged=0)
    assert report_command(_console(), tmp_path, None, figures=False) == 1


def test_the_report_never_replaces_a_user_s_page(tmp_path, paged):
    (tmp_path / page.PAGE_NAME).write_text("<html>mine</html>")
    with pytest.raises(guard.Refused, match="is not a report page this command wrote"):
        report_command(_console(), tmp_path, None)
    mine = tmp_path / "elsewhere.html"
    mine.write_text("<html>mine too</html>")
    with pytest.raises(guard.Refused, match="elsewhere.html: exists and is not a report page"):
        report_command(_console(), tmp_path / "new", mine)
    assert paged.asked == []


def test_the_folder_s_own_table_is_written_again(tmp_path, made, capsys):
    res = tmp_path / RES
    res.mkdir()
    _table(tmp_path)
    made.rows = [_row("other")]
    assert _table(tmp_path, format="csv")[0] == 0
    assert (res / "table.md").read_text() == "MD built\n"
    assert made.asked[-2][0] == "render"  # built and written again, not refused
    assert sorted(p.name for p in _files(res)) == ["table.csv", "table.md", "table.tex"]


def test_out_that_is_a_run_folder_is_refused_as_such(tmp_path, made):
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.json").write_text("{}")
    with pytest.raises(guard.Refused, match=f"^--out {run}: is a run folder \\(made by bench run"):
        _table(tmp_path, out=run)
    assert made.asked == []
