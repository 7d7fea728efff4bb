"""bench/report/html/page.py's tables made for the page (``_tables_in_memory``) and the
page across datasets in its tables section, in-process on stand-ins for the table builders
(``select``, ``build``, ``collect_ape``, ``with_stability``, ``cross_dataset``): which
builder makes which table with which arguments, in which order the tables appear, and the
line a metric without runs gets. Finished runs over two datasets take the slow set-up
elsewhere; here what page.py does with the builders' answers is checked. Written for a
mutation run of the module."""

import os
import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from bench.report.html import page as P
from bench.report.tables import ape, paper, stability
from bench.report.tables.model import Cell, Part, Row, Table

SHARED = "This caption sentence is long enough to be said once per page, not twice."
NOT_MADE = ("Not made: no run of this folder has this metric (a finished run with ground "
            "truth and its figure in metrics.json; runs without ground truth and runs that "
            "did not finish are listed under Failed runs and missing data).")


def _table(value: str, caption: str = "") -> Table:
    return Table(["Sequence"], ["Figure"], [Row(["s1"], ("g",), [Cell([Part(value)])])],
                 caption=caption)


def _empty() -> Table:
    return Table(["Sequence"], ["Figure"], [], caption="empty.")


class _Builders:
    """Stand-ins for the table builders, recording how page.py calls them."""

    def __init__(self, monkeypatch, select_error=None, empty=()):
        self.calls = []
        self.rows = [SimpleNamespace(run=SimpleNamespace(dir=Path(d))) for d in ("a", "b", "a")]
        self.lengths = (8.0, 100.0)
        self.error = select_error
        self.empty = set(empty)
        self.stable = []
        monkeypatch.setattr(paper, "select", self.select)
        monkeypatch.setattr(paper, "build", self.build)
        monkeypatch.setattr(ape, "collect_ape", self.collect_ape)
        monkeypatch.setattr(stability, "with_stability", self.with_stability)

    def select(self, results_dir):
        self.calls.append(("select", results_dir))
        if self.error is not None:
            raise self.error
        return self.rows, self.lengths

    def _made(self, metric):
        return _empty() if metric in self.empty else _table(f"{metric}-cell",
                                                            f"The {metric} table.")

    def build(self, metric, rows, lengths, ci=False):
        self.calls.append(("build", metric, rows, lengths, ci))
        return self._made(metric)

    def collect_ape(self, results_dir, only=None, ci=False):
        self.calls.append(("ape", results_dir, only, ci))
        return SimpleNamespace(table=self._made("ape"))

    def with_stability(self, rows, lengths, table):
        self.calls.append(("stability", rows, lengths, table.rows[0].cells[0].parts[0].text))
        table.caption += " Stable on both halves."


def test_the_four_tables_made_for_the_page(monkeypatch, tmp_path):
    b = _Builders(monkeypatch)
    made = P._tables_in_memory(tmp_path)
    assert [t for t, _ in made] == ["Relative error per segment length (Table III)",
                                    "KITTI drift", "Absolute pose error (Tables IV / V)",
                                    "Ego-velocity error"]
    assert b.calls == [
        ("select", tmp_path),
        ("build", "relative", b.rows, b.lengths, True),
        ("stability", b.rows, b.lengths, "relative-cell"),
        ("build", "kitti", b.rows, b.lengths, True),
        ("ape", tmp_path, {Path("a"), Path("b")}, True),
        ("build", "velocity", b.rows, b.lengths, True)]
    texts = dict(made)
    for title, metric in P.PAGE_TABLES:
        assert f"| s1 | {metric}-cell |" in texts[title]
        assert f"The {metric} table." in texts[title]
    # only the relative error's table is checked on both halves of each sequence
    assert [t for t, text in made if "Stable on both halves." in text] == [
        "Relative error per segment length (Table III)"]


def test_a_metric_without_runs_gets_a_line_saying_why(monkeypatch, tmp_path):
    _Builders(monkeypatch, empty={"kitti", "ape"})
    made = dict(P._tables_in_memory(tmp_path))
    assert made["KITTI drift"] == NOT_MADE
    assert made["Absolute pose error (Tables IV / V)"] == NOT_MADE
    assert "| s1 | velocity-cell |" in made["Ego-velocity error"]


@pytest.mark.parametrize("error", [FileNotFoundError("no runs"), ValueError("no GT")])
def test_no_table_without_finished_runs(monkeypatch, tmp_path, error):
    b = _Builders(monkeypatch, select_error=error)
    assert P._tables_in_memory(tmp_path) == []
    assert b.calls == [("select", tmp_path)]


def _heads(html):
    return re.findall(r"<h3[^>]*>(.*?)</h3>", html)


def test_the_tables_section_with_the_page_across_datasets(monkeypatch, tmp_path):
    _Builders(monkeypatch, empty={"velocity"})
    across = [("Across datasets: <mean> & mark", _table("2.50", f"Summary. {SHARED}")),
              ("Dataset: B", _table("b-cell", "Per dataset B."))]
    seen = []

    def cross_dataset(results_dir):
        seen.append(results_dir)
        return across

    monkeypatch.setattr(P, "cross_dataset", cross_dataset)
    (tmp_path / "pivot.md").write_text(f"| a |\n|---|\n| 1 |\n\nPivot. {SHARED}\n")
    html, n = P._tables_section(tmp_path, 0.0)
    assert seen == [tmp_path]
    assert _heads(html) == ["Relative error per segment length (Table III)", "KITTI drift",
                            "Absolute pose error (Tables IV / V)", "Ego-velocity error",
                            "Across datasets: &lt;mean&gt; &amp; mark", "Dataset: B",
                            "pivot.md"]
    # three made tables (the velocity one is a line), two across datasets, one written file
    assert n == 6
    assert html.count("<table>") == 6
    assert html.startswith("<p>Tables of the folder's finished runs, made for this page: "
                           "every figure with its 95 % confidence interval [low, high];")
    across_part = html.split("Across datasets: &lt;mean&gt; &amp; mark</h3>")[1]
    summary, rest = across_part.split("<h3>Dataset: B</h3>")
    assert '<td class="num">2.50</td>' in summary and SHARED in summary  # a number
    assert "<td>b-cell</td>" in rest.split("<p>Tables written into this folder")[0]
    # the written pivot.md repeats the summary's long sentence: said once, under the summary
    pivot = html.split('<h3 id="pivot">pivot.md</h3>')[1]
    assert SHARED not in pivot
    assert ("The other notes of this caption are given once, under &quot;Across datasets: "
            "&lt;mean&gt; &amp; mark&quot; above.") in pivot


def test_without_made_tables_no_intro_and_no_table_line(monkeypatch, tmp_path):
    _Builders(monkeypatch, select_error=FileNotFoundError("none"))
    monkeypatch.setattr(P, "cross_dataset", lambda results_dir: [])
    assert P._tables_section(tmp_path, 0.0) == (
        "<p>No table: no finished run with ground truth.</p>", 0)


def test_a_table_file_older_than_the_newest_run_by_more_than_1_ms(tmp_path):
    f = tmp_path / "t.md"
    f.write_text("x")
    os.utime(f, ns=(100_000_000_000, 100_000_000_000))  # mtime 100 s exactly
    assert P._stale_note(f, 100.002) != ""
    assert P._stale_note(f, 100.0009) == ""
    assert 100.001 - 1e-3 == 100.0  # exactly 1 ms older (no rounding here): not stale yet
    assert P._stale_note(f, 100.001) == ""
    assert P._stale_note(f, 99.0) == ""
    assert P._stale_note(f, 0.0) == ""  # no run record: nothing to be stale against
