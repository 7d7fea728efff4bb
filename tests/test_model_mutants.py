"""The table model (bench/report/tables/model.py) pinned piece by piece: the caption's rule and
where its intervals are, ranks by value and marks by interval per group, a figure's text, the
escapes and the three renderers. Every expected text below is written out by hand from the
module's documented format, not taken from its output."""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import rankdata
from strategies import examples

from bench.report.tables.model import (
    BEST,
    MARK_RULES,
    OTHER,
    RULE,
    RULE_UNPRINTED,
    SECOND,
    UNPRINTED,
    Cell,
    Part,
    Row,
    Stat,
    Table,
    caption_text,
    mark_column,
    md_escape,
    rank_column,
    rank_values,
    render,
    rule_name,
    rule_text,
    save_table,
    stat_text,
    tex_escape,
    to_csv,
    to_latex,
    to_markdown,
)

# ---- the caption's rule -------------------------------------------------------------------


def test_the_rule_text_states_which_rule_and_whether_the_intervals_are_printed():
    assert rule_text("intervals", ci=True) == RULE
    assert rule_text("intervals", ci=False) == RULE_UNPRINTED
    assert rule_text("significance", ci=False) == RULE_UNPRINTED  # the old name
    assert rule_text("significance", ci=True) == RULE
    assert rule_text("value", ci=True) == rule_text("value", ci=False) == MARK_RULES["value"]
    assert "by value alone" in MARK_RULES["value"] and "bold" in MARK_RULES["value"]
    assert UNPRINTED in RULE_UNPRINTED and UNPRINTED not in RULE


def test_an_unknown_rule_is_refused_naming_it_and_the_known_ones():
    assert rule_name("significance") == "intervals"
    assert rule_name("value") == "value"
    with pytest.raises(ValueError) as err:
        rule_name("loudest")
    assert str(err.value) == "unknown marking rule 'loudest': one of intervals, value"
    with pytest.raises(ValueError, match="unknown marking rule 'x'"):
        mark_column([], 0, 0, marks="x")


def _caption_table(csv_file: str, values: dict | None = None) -> Table:
    cells = [Cell([Part("1.0")], values=values or {})]
    return Table(["k"], ["c"], [Row(["a"], (), cells)], caption=f"Head. {UNPRINTED}. Tail.",
                 csv_file=csv_file)


def test_a_caption_without_the_stand_in_is_left_as_it_is():
    t = _caption_table("out/t.csv", {"x_ci_high": 1.0})
    t.caption = "Nothing to resolve."
    assert caption_text(t) == "Nothing to resolve."


def test_the_caption_names_the_csv_written_beside_the_table_and_an_example_quantity():
    t = _caption_table("out/t.csv", {"x": 1.0, "x_ci_low": 0.5, "x_ci_high": 1.5})
    assert caption_text(t) == (
        "Head. they are in the CSV out/t.csv (written beside this table), as the quantities "
        "ending in _ci_low and _ci_high beside each figure's own (for example x_ci_high "
        "beside x), and the same command with --ci (bench table, bench reproduce) prints them "
        "beside every figure. Tail.")


def test_the_caption_names_another_tables_csv_without_saying_it_is_beside():
    t = _caption_table("of the main table")
    assert caption_text(t) == (
        "Head. they are in the CSV of the main table, as the quantities ending in _ci_low and "
        "_ci_high beside each figure's own, and the same command with --ci (bench table, "
        "bench reproduce) prints them beside every figure. Tail.")


def test_an_unwritten_table_names_the_command_that_prints_its_csv():
    t = _caption_table("", {"q_ci_low": 0.1})  # no _ci_high: no example
    assert caption_text(t) == (
        "Head. they are in this table's CSV (the same command with --format csv prints it), "
        "as the quantities ending in _ci_low and _ci_high beside each figure's own, and the "
        "same command with --ci (bench table, bench reproduce) prints them beside every "
        "figure. Tail.")


def test_the_example_quantity_is_the_first_upper_end_of_the_table():
    t = Table(["k"], ["c", "d"], [
        Row(["a"], (), [Cell(status="-"), Cell([Part("1")], values={"p": 1, "p_ci_high": 2})]),
        Row(["b"], (), [Cell([Part("1")], values={"q_ci_high": 2}), Cell(status="-")])],
        caption=UNPRINTED, csv_file="t.csv")
    assert "(for example p_ci_high beside p)" in caption_text(t)


# ---- footnotes, ranks and marks -------------------------------------------------------------


def test_a_footnote_is_numbered_from_one_and_added_once():
    t = Table([], [], [])
    assert t.note("a") == 1 and t.note("b") == 2 and t.note("a") == 1
    assert t.footnotes == ["a", "b"]


def _dense_marks(values: list[float]) -> list[int]:
    """Independently: scipy's dense rank (1 = lowest) of the finite values, 1 -> BEST,
    2 -> SECOND, the rest OTHER."""
    finite = [v for v in values if math.isfinite(v)]
    dense = dict(zip(finite, rankdata(finite, method="dense"), strict=True)) if finite else {}
    return [{1: BEST, 2: SECOND}.get(int(dense[v]), OTHER) if math.isfinite(v) else OTHER
            for v in values]


def test_ranks_by_value_share_ties_and_skip_non_finite_values():
    nan, inf = math.nan, math.inf
    assert rank_values([3.0, 1.0, 2.0]) == [OTHER, BEST, SECOND]
    assert rank_values([1.0, 1.0, 2.0, 5.0]) == [BEST, BEST, SECOND, OTHER]
    assert rank_values([nan, 2.0, -inf, inf, 4.0]) == [OTHER, BEST, OTHER, OTHER, SECOND]
    assert rank_values([nan]) == [OTHER] and rank_values([]) == []


@examples(20)
@given(st.lists(st.one_of(st.integers(-3, 3).map(float), st.just(math.nan),
                          st.just(math.inf)), max_size=8))
def test_ranks_by_value_are_the_dense_ranks(values):
    assert rank_values(values) == _dense_marks(values)


def _rows(spec) -> list[Row]:
    """(group, value or status) -> one-cell rows, each part's text its value."""
    rows = []
    for group, v in spec:
        cell = Cell(status=v) if isinstance(v, str) else Cell([Part(f"{v}")], values={"v": v})
        rows.append(Row([str(v)], (group,), [cell]))
    return rows


def test_rank_column_ranks_within_each_group_and_leaves_status_cells_alone():
    rows = _rows([("a", 3.0), ("a", 1.0), ("b", 5.0), ("a", "Div."), ("b", 4.0), ("a", 2.0)])
    rank_column(rows, 0, 0, lambda r: r.cells[0].values["v"])
    assert [r.cells[0].parts[0].rank if r.cells[0].parts else None for r in rows] == \
        [OTHER, BEST, SECOND, None, BEST, SECOND]


def test_a_cell_with_fewer_parts_than_the_one_marked_is_left_out():
    rows = [Row(["a"], (), [Cell([Part("1.0"), Part("9.0")])]),
            Row(["b"], (), [Cell([Part("2.0")])]),
            Row(["c"], (), [Cell([Part("3.0"), Part("8.0")])])]
    mark_column(rows, 0, 1, marks="value")
    assert [r.cells[0].parts[-1].rank for r in rows] == [SECOND, OTHER, BEST]
    assert rows[1].cells[0].parts[0].rank == OTHER  # its only part is part 0, not ranked


def test_the_value_rule_ranks_a_plain_part_by_its_printed_number():
    rows = [Row([t], (), [Cell([Part(t)])]) for t in ("2.50 [x]", "1.25", "n/a", "", "0.75")]
    mark_column(rows, 0, 0, marks="value")
    assert [r.cells[0].parts[0].rank for r in rows] == [OTHER, SECOND, OTHER, OTHER, BEST]


def test_the_interval_rule_marks_by_the_printed_intervals_per_group():
    def part(v, lo, hi):
        return Cell([Part(f"{v}", stat=Stat(v, (lo, hi), 10))])

    # group g: U = 1.5 (first row); 1.4 <= 1.5 bold, the rest: U' = 3.0, 2.9 underlined
    rows = [Row(["a"], ("g",), [part(1.0, 0.5, 1.5)]), Row(["b"], ("g",), [part(1.4, 1.3, 3)]),
            Row(["c"], ("g",), [part(2.9, 2.0, 3.0)]), Row(["d"], ("g",), [part(3.1, 3, 4)]),
            Row(["e"], ("h",), [part(9.0, 8.0, 10.0)])]
    mark_column(rows, 0, 0)
    assert [r.cells[0].parts[0].rank for r in rows] == [BEST, BEST, SECOND, OTHER, BEST]
    mark_column(rows, 0, 0, marks="value")
    assert [r.cells[0].parts[0].rank for r in rows] == [BEST, SECOND, OTHER, OTHER, BEST]


def test_without_a_stat_the_interval_rule_reads_the_printed_number_as_its_own_interval():
    rows = [Row([t], (), [Cell([Part(t)])]) for t in ("3", "1", "2", "-")]
    mark_column(rows, 0, 0)
    assert [r.cells[0].parts[0].rank for r in rows] == [OTHER, BEST, SECOND, OTHER]


def test_an_unrankable_stat_is_never_marked_by_value():
    rows = [Row(["a"], (), [Cell([Part("0.1", stat=Stat(math.nan))])]),
            Row(["b"], (), [Cell([Part("0.2", stat=Stat(0.2, None, 5))])]),
            Row(["c"], (), [Cell([Part("0.3", stat=Stat(0.3))])])]
    mark_column(rows, 0, 0, marks="value")
    assert [r.cells[0].parts[0].rank for r in rows] == [OTHER, BEST, SECOND]


# ---- a figure's text ------------------------------------------------------------------------


def test_a_figures_text_has_its_digits_its_widened_interval_and_its_segment_count():
    assert stat_text(1.23456, (1.0, 1.5), 3, digits=2, show_ci=True) == "1.23 [1.00, 1.50]"
    # a percentile interval missing its value is widened to hold it
    assert stat_text(2.0, (2.5, 3.0), 5, digits=1, show_ci=True) == "2.0 [2.0, 3.0]"
    assert stat_text(2.0, (0.5, 1.0), 5, digits=1, show_ci=True) == "2.0 [0.5, 2.0]"
    assert stat_text(2.0, (0.5, 1.0), 1, digits=1, show_ci=True) == "2.0 [0.5, 2.0] (1 segment)"
    assert stat_text(2.0, None, None) == "2.000"
    assert stat_text(None, (0.0, 1.0), 3) == "-"
    assert stat_text(math.inf, None, 3) == "-" and stat_text(-math.inf, None, 3) == "-"


# ---- escapes --------------------------------------------------------------------------------


@pytest.mark.parametrize("text, escaped", [
    ("a & b < c > d", "a &amp; b &lt; c &gt; d"),
    ("<img src=x onerror=alert(1)>", "&lt;img src=x onerror=alert(1)&gt;"),
    (r"a|b\c`d*e", r"a\|b\\c\`d\*e"),
    ("loop_1", "loop_1"),  # inside a word: as is
    ("_x", r"\_x"), ("x_", r"x\_"), ("_", r"\_"), ("a _b", r"a \_b"), ("a_ b", r"a\_ b"),
    ("[x](url)", r"[x]\(url)"), ("(x)", "(x)"), ("a (b)", "a (b)"),
    ("(a]", "(a]"), ("](x", r"]\(x"),
    (12, "12"),
])
def test_markdown_escape(text, escaped):
    assert md_escape(text) == escaped


def test_latex_escape_of_every_special_character():
    assert tex_escape("\\&%$#_{}~^a") == (r"\textbackslash{}\&\%\$\#\_\{\}\textasciitilde{}"
                                          r"\textasciicircum{}a")
    assert tex_escape(3) == "3"


# ---- renderers ------------------------------------------------------------------------------


def _table() -> Table:
    """Two groups of the first key (a, b), two of the second inside a; marks, a status, a
    footnote, a "-" part."""
    t = Table(["S", "Q", "M"], ["x_1", "y"], [], caption="Cap & more")
    n = t.note("m_2 fails <here>")
    t.rows = [
        Row(["a", "p", "m1"], ("a", "p"), [Cell([Part("1.0", BEST), Part("2.0", SECOND)]),
                                           Cell([Part("-", BEST)])],
            {"sequence": "p", "method": "m1", "seed": True}),
        Row(["a", "p", "m_2"], ("a", "p"), [Cell(status="fa|led", note=n),
                                            Cell([Part("3.0")], note=n)],
            {"sequence": "p", "method": "m_2", "status": "failed"}),
        Row(["a", "q", "m1"], ("a", "q"), [Cell([Part("5.0", SECOND)]), Cell(status="")]),
        Row(["b", "q", "m1"], ("b", "q"), [Cell([Part("7.0", OTHER)]), Cell(status="Div.")]),
    ]
    return t


def test_markdown_table_written_out():
    assert to_markdown(_table()) == (
        "| S | Q | M | x_1 | y |\n"
        "|---|---|---|---|---|\n"
        "| a | p | m1 | **1.0** / <u>2.0</u> | - |\n"
        "|  |  | m_2 | fa\\|led [1] | 3.0 [1] |\n"
        "|  | q | m1 | <u>5.0</u> |  |\n"
        "| b | q | m1 | 7.0 | Div. |\n"
        "\n"
        "Cap &amp; more\n"
        "\n"
        "[1] m_2 fails &lt;here&gt;\n")


def test_markdown_without_footnotes_ends_with_its_caption():
    t = Table(["k"], ["c"], [Row(["a"], (), [Cell([Part("1")])])], caption="C")
    assert to_markdown(t) == "| k | c |\n|---|---|\n| a | 1 |\n\nC\n"


def test_latex_table_written_out():
    assert to_latex(_table(), label="tab:x") == "\n".join([
        r"\begin{table}[t]", r"\centering", r"\footnotesize", r"\caption{Cap \& more}",
        r"\label{tab:x}",
        r"\begin{tabular}{@{}lllcc@{}}", r"\toprule",
        r"S & Q & M & \textbf{x\_1} & \textbf{y} \\", r"\midrule",
        r"a & p & m1 & \textbf{1.0} / \underline{2.0} & \textbf{-} \\",
        r" &  & m\_2 & fa|led\textsuperscript{1} & 3.0\textsuperscript{1} \\",
        r"\cmidrule{2-5}",
        r" & q & m1 & \underline{5.0} &  \\",
        r"\midrule",
        r"b & q & m1 & 7.0 & Div. \\",
        r"\bottomrule", r"\end{tabular}",
        r"\par\smallskip\raggedright\scriptsize",
        r"\textsuperscript{1}m\_2 fails <here>\\",
        r"\end{table}"]) + "\n"


def test_latex_without_label_or_footnotes_and_one_key_uses_midrules_between_groups():
    t = Table(["k"], ["c"], [Row(["a"], ("a",), [Cell([Part("1")])]),
                             Row(["a"], ("b",), [Cell([Part("2")])])], caption="C")
    assert to_latex(t) == "\n".join([
        r"\begin{table}[t]", r"\centering", r"\footnotesize", r"\caption{C}",
        r"\begin{tabular}{@{}lc@{}}", r"\toprule", r"k & \textbf{c} \\", r"\midrule",
        r"a & 1 \\", r"\midrule", r"a & 2 \\", r"\bottomrule", r"\end{tabular}",
        r"\end{table}"]) + "\n"


def test_the_last_key_is_never_blanked_and_a_changed_key_shows_the_ones_right_of_it():
    t = Table(["A", "B", "C"], ["v"], [Row(list(k), (), [Cell(status="")]) for k in (
        ("a", "b", "c"), ("a", "b", "c"), ("a", "x", "c"), ("z", "x", "c"))])
    lines = to_markdown(t).splitlines()[2:6]
    assert lines == ["| a | b | c |  |", "|  |  | c |  |", "|  | x | c |  |",
                     "| z | x | c |  |"]


def test_csv_written_out():
    rows = list(csv.reader(io.StringIO(to_csv(_table()))))
    head = ["sequence", "sensor_class", "method", "seed", "label", "status", "row", "column",
            "quantity", "value", "note"]
    assert rows[0] == head
    assert len(rows) == 1 + 8  # one line per cell: none has values
    by = [dict(zip(head, r, strict=True)) for r in rows[1:]]
    assert by[0] == {**dict.fromkeys(head, ""), "sequence": "p", "method": "m1",
                     "seed": "True", "row": "m1", "column": "x_1"}
    assert by[2]["status"] == "fa|led" and by[2]["note"] == "m_2 fails <here>"
    assert by[3]["status"] == "failed" and by[3]["note"] == "m_2 fails <here>"
    assert by[1]["note"] == "" and by[5]["status"] == by[6]["status"] == ""
    assert by[7]["status"] == "Div." and by[7]["row"] == "m1"


def test_csv_lines_per_value_with_the_value_written_exactly():
    t = Table(["k"], ["c"], [Row(["r"], (), [Cell([Part("1")], values={
        "a": 0.1, "b": None, "c": math.nan, "d": math.inf, "e": 3})],
        {"status": "done", "label": None})])
    rows = list(csv.DictReader(io.StringIO(to_csv(t))))
    assert [(r["quantity"], r["value"]) for r in rows] == [
        ("a", "0.1"), ("b", ""), ("c", ""), ("d", ""), ("e", "3.0")]
    assert all(r["status"] == "done" and r["label"] == "" and r["note"] == "" for r in rows)
    assert float(rows[0]["value"]) == 0.1  # repr: the float read back exactly


def test_render_and_save_write_the_same_three_texts(tmp_path):
    t = _table()
    t.caption = f"C. {UNPRINTED}."
    texts = save_table(t, tmp_path / "out", "t")
    assert set(texts) == {"md", "tex", "csv"}
    assert t.csv_file == str(tmp_path / "out" / "t.csv")
    for fmt, text in texts.items():
        assert (tmp_path / "out" / f"t.{fmt}").read_text(encoding="utf-8") == text
    assert render(t) == texts
    assert f"the CSV {tmp_path / 'out' / 't.csv'} (written beside this table)" in texts["md"]


def test_marks_agree_with_the_printed_intervals_on_random_columns():
    rng = np.random.default_rng(3)
    for _ in range(20):
        v = np.round(rng.uniform(0, 2, 6), 3)
        half = np.round(rng.uniform(0, 0.5, 6), 3)
        rows = [Row([str(i)], (), [Cell([Part(f"{x:.3f}", stat=Stat(x, (x - h, x + h), 9))])])
                for i, (x, h) in enumerate(zip(v, half, strict=True))]
        mark_column(rows, 0, 0)
        ranks = np.array([r.cells[0].parts[0].rank for r in rows])
        u = np.min(np.round(v + half, 3))
        np.testing.assert_array_equal(ranks == BEST, v <= u + 1e-12)
        assert ranks[np.argmin(v)] == BEST


def test_save_table_refuses_a_users_file_and_a_run_folder_naming_what_it_would_write(tmp_path):
    from bench.guard import Refused

    t = Table(["k"], ["c"], [Row(["a"], (), [Cell([Part("1")])])], caption="C")
    save_table(t, tmp_path, "t")
    save_table(t, tmp_path, "t")  # its own table: replaced
    (tmp_path / "mine.csv").write_text("a user's file\n")
    with pytest.raises(Refused) as err:
        save_table(t, tmp_path, "mine")
    assert str(err.value) == (f"{tmp_path / 'mine.csv'}: exists and is not a table the "
                              "harness wrote; it is left as it is: choose another output")
    assert not (tmp_path / "mine.md").exists()  # nothing half written
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.json").write_text("{}")
    with pytest.raises(Refused, match="is a run folder"):
        save_table(t, run, "t")
    assert not (run / "t.md").exists()


def test_csv_lines_end_in_a_bare_newline():
    text = to_csv(Table(["k"], ["c"], [Row(["a"], (), [Cell([Part("1")], values={"q": 1})])]))
    assert text == ("sequence,sensor_class,method,seed,label,status,row,column,quantity,value,"
                    "note\n,,,,,,a,c,q,1.0,\n")


def _two_notes() -> Table:
    t = Table(["S", "M"], ["c"], [], caption="C")
    first, second = t.note("first note"), t.note("second note")
    t.rows = [Row(["a", "m1"], ("a", "p"), [Cell([Part("1")], note=second)]),
              Row(["a", "m2"], ("a", "q"), [Cell(status="failed", note=first)]),
              Row(["b", "m1"], ("b", "q"), [Cell([Part("2")])])]
    return t


def test_every_footnote_on_its_own_line_and_each_cell_names_its_own():
    t = _two_notes()
    md = to_markdown(t)
    assert md.endswith("\n\n[1] first note\n[2] second note\n")
    assert "| a | m1 | 1 [2] |" in md and "|  | m2 | failed [1] |" in md
    rows = list(csv.DictReader(io.StringIO(to_csv(t))))
    assert [r["note"] for r in rows] == ["second note", "first note", ""]


def test_two_keys_a_cmidrule_under_the_same_first_key_and_a_midrule_between_first_keys():
    body = to_latex(_two_notes()).splitlines()
    i = body.index(r"a & m1 & 1\textsuperscript{2} \\")
    assert body[i + 1:i + 5] == [r"\cmidrule{2-3}", r" & m2 & failed\textsuperscript{1} \\",
                                 r"\midrule", r"b & m1 & 2 \\"]


def test_csv_refuses_a_row_whose_cells_do_not_match_the_columns():
    t = Table(["k"], ["c", "d"], [Row(["a"], (), [Cell([Part("1")], values={"q": 1.0})])])
    with pytest.raises(ValueError):
        to_csv(t)
