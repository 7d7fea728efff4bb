"""The one table model (bench/report/tables/model.py) and its three renderers: keys shown once per
group, ranks marked, booktabs rules, caption with the synthetic notice, footnotes, long CSV."""

import csv
import io

from bench.report.tables.model import (
    Cell,
    Part,
    Row,
    Table,
    rank_column,
    to_csv,
    to_latex,
    to_markdown,
)
from loaders.sensor_classes import SYNTHETIC_MARK


def _table() -> Table:
    t = Table(["Sensor", "Sequence", "Method"], ["8 m"], [], caption="A caption.")
    seq1, seq2 = f"Loop1_0 {SYNTHETIC_MARK}", f"Loop1_2 {SYNTHETIC_MARK}"
    for klass, seq, method, value in (("Radar", seq1, "a", 2.0), ("Radar", seq1, "b", 1.0),
                                      ("Radar", seq2, "a", 3.0), ("LiDAR", "Wall", "a", 5.0)):
        t.rows.append(Row([klass, seq, method], (klass, seq),
                          [Cell([Part(f"{value:.1f}")], values={"err": value})],
                          {"sequence": seq, "method": method}))
    t.rows.append(Row(["LiDAR", "Wall", "b"], ("LiDAR", "Wall"),
                      [Cell(status="failed", note=t.note("b on Wall: out of memory"))],
                      {"sequence": "Wall", "method": "b", "status": "failed"}))
    rank_column(t.rows, 0, 0, lambda r: r.cells[0].values.get("err", float("nan")))
    return t


def test_markdown_shows_each_key_once_per_group_and_marks_ranks():
    lines = to_markdown(_table()).splitlines()
    assert lines[2].startswith("| Radar | Loop1_0") and "<u>2.0</u>" in lines[2]
    assert lines[3].startswith("|  |  | b | **1.0** |")
    assert lines[4].startswith("|  | Loop1_2") and "**3.0**" in lines[4]  # its own group
    assert lines[6] == "|  |  | b | failed [1] |"
    assert lines[-1] == "[1] b on Wall: out of memory"


def test_latex_is_a_booktabs_table_with_its_caption_and_footnote():
    tex = to_latex(_table())
    assert tex.startswith("\\begin{table}") and "\\caption{A caption.}" in tex
    assert tex.count("\\toprule") == tex.count("\\bottomrule") == 1
    assert "\\hline" not in tex and "\\cmidrule{2-4}" in tex  # Loop1_0 -> Loop1_2
    assert tex.count("\\midrule") == 2  # under the header and Radar -> LiDAR
    assert "failed\\textsuperscript{1}" in tex and "out of memory" in tex


def test_csv_is_long_one_line_per_value_with_status_and_note():
    rows = list(csv.DictReader(io.StringIO(to_csv(_table()))))
    assert len(rows) == 5 and rows[1]["value"] == "1.0" and rows[1]["method"] == "b"
    assert rows[-1]["status"] == "failed" and rows[-1]["note"] == "b on Wall: out of memory"


def test_relative_table_caption_carries_the_synthetic_notice(tmp_path):
    from bench.report.tables.paper import relative_table, runs
    from bench.runs.result import RelativeError, RunResult

    d = tmp_path / "Loop1_0" / "dicp_seed"
    d.mkdir(parents=True)
    (d / "metrics.json").write_text(RunResult(
        sequence="Loop1_0", method="dicp", seed=True, diverged=False,
        display_name=f"Loop1_0 {SYNTHETIC_MARK}", sensor_class="Semi-Dense 4D Radar",
        relative_error=[RelativeError(length_m=8.0, rot_deg_mean=1.0, trans_m_mean=0.1, n=3)],
    ).dump())
    tex = to_latex(relative_table(runs(tmp_path), [8.0]))
    assert "\\caption{SYNTHETIC DATA:" in tex


def test_stat_text_states_the_interval_and_too_few_segments():
    from bench.report.tables.model import stat_text

    assert stat_text(1.23456, None, 2) == "1.235"  # two independent segments: nothing added
    assert stat_text(1.0, None, 1) == "1.000 (1 segment)"
    assert stat_text(1.0, None, 0) == "1.000 (0 segments)"
    assert stat_text(1.0, [0.5, 1.5], 5, show_ci=True) == "1.000 [0.500, 1.500]"
    assert stat_text(1.0, [None, None], 5, show_ci=True) == "1.000"  # no interval
    assert stat_text(1.0, [0.5, 1.5], 5) == "1.000"
    assert stat_text(float("nan"), None, 5) == "-"


def test_the_value_rule_leaves_a_figure_on_one_segment_unmarked():
    from bench.report.tables.model import mark_column
    from bench.report.tables.significance import BEST, OTHER, SECOND, Stat

    rows = [Row([k], (), [Cell([Part(k, stat=Stat(v, None, n))])])
            for k, v, n in (("a", 0.1, 1), ("b", 0.5, 10), ("c", 0.7, 10), ("d", 0.9, 10))]
    mark_column(rows, 0, 0, marks="value")
    assert [r.cells[0].parts[0].rank for r in rows] == [OTHER, BEST, SECOND, OTHER]
