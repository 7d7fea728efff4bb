"""One table model for every results table, rendered once each to markdown, LaTeX and CSV.

A ``Table`` is rows of cells under column titles, with row keys (sensor, sequence, method ...)
on the left, rows grouped (a rule between groups; ranks are per group), a caption and
footnotes. A cell is one or more ``Part``s ("rotation / translation"), each a formatted number
with its rank (0 best, 1 second, 2 other: bold / underlined) and the ``Stat`` behind it (value,
confidence interval, independent units, and its per-unit errors for a paired comparison), or a
status ("Div.", "failed", "-" for no value, "" for not run), and the values behind it for the
CSV.

Marks (``mark_column``) follow one of two rules, stated in every caption (``MARK_RULES``):
"intervals" (the default: ``bench.report.tables.significance``, decided from the printed figures and
their printed intervals alone, so a reader can check every mark) or "value" (the paper's plain
style: the lowest value bold, the next underlined).

Every table of the harness is built as a ``Table`` (``bench.report.tables.paper``) and written by
``save_table``: ``to_markdown`` (pipe table + caption + footnotes), ``to_latex`` (a booktabs
``table`` with its caption and the synthetic notice) and ``to_csv`` (long format: one line per
cell value, for pandas). Another renderer (HTML) needs only ``Table.rows`` / ``Row.cells`` /
``Cell.parts`` and ``Part.rank``.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

from bench.report.tables.significance import (  # noqa: F401
    BEST,
    OTHER,
    RULE,
    RULE_UNPRINTED,
    SECOND,
    UNPRINTED,
    Stat,
    interval_marks,
    shown_interval,
)

#: the marking rules and how a caption states them ("significance", the name of the rule before
#: marks were read from the printed intervals, is accepted for "intervals": ``rule_name``)
MARK_RULES = {
    "intervals": RULE,
    "value": ("Best value per sequence in bold, second underlined (by value alone, the "
              "paper's style: differences may lie within the noise)."),
}


def rule_text(marks: str, ci: bool) -> str:
    """The caption's sentence for the rule ``marks``: with the intervals printed (``ci``) the
    rule as read from them; without, the same rule and where the intervals are (resolved when
    the table is rendered: ``caption_text``)."""
    marks = rule_name(marks)
    if marks == "intervals" and not ci:
        return RULE_UNPRINTED
    return MARK_RULES[marks]


def caption_text(table: Table) -> str:
    """The caption as rendered: the stand-in for where unprinted intervals are replaced by
    the CSV written beside the table (``Table.csv_file``), or by the command that prints that
    CSV when the table is not written."""
    if UNPRINTED not in table.caption:
        return table.caption
    beside = "" if table.csv_file.startswith("of ") else " (written beside this table)"
    where = (f"the CSV {table.csv_file}{beside}" if table.csv_file else
             "this table's CSV (the same command with --format csv prints it)")
    high = next((k for r in table.rows for c in r.cells for k in c.values
                 if k.endswith("_ci_high")), "")
    example = (f" (for example {high} beside {high.removesuffix('_ci_high')})" if high else "")
    said = (f"they are in {where}, as the quantities ending in _ci_low and _ci_high beside "
            f"each figure's own{example}, and the same command with --ci (bench table, bench "
            "reproduce) prints them beside every figure")
    return table.caption.replace(UNPRINTED, said)


@dataclass
class Part:
    """A formatted value, its rank within its group and column (``OTHER``: unranked) and the
    statistic behind it (None: a plain number, ranked by value)."""

    text: str
    rank: int = OTHER
    stat: Stat | None = None


@dataclass
class Cell:
    """One cell: its parts (joined by " / "), or a ``status`` text instead ("Div.", "failed",
    "-", ""); ``values`` (quantity -> number) go to the CSV; ``note`` is a footnote number."""

    parts: list[Part] = field(default_factory=list)
    status: str | None = None
    values: dict[str, float | None] = field(default_factory=dict)
    note: int | None = None


@dataclass
class Row:
    """A row: its key texts (one per ``Table.keys``), its ``group`` (ranked together, a rule
    between groups), its cells (one per ``Table.columns``) and what it is (``meta``: sequence,
    method, seed, label, status ... for the CSV)."""

    keys: list[str]
    group: tuple
    cells: list[Cell]
    meta: dict = field(default_factory=dict)


@dataclass
class Table:
    """``keys``: the titles of the row-key columns; ``columns``: the value columns' titles."""

    keys: list[str]
    columns: list[str]
    rows: list[Row]
    caption: str = ""
    footnotes: list[str] = field(default_factory=list)
    #: the CSV written beside the table (named by a caption whose intervals are not printed);
    #: "of ..." names another table's CSV (the pivot: the main table's)
    csv_file: str = ""

    def note(self, text: str) -> int:
        """The footnote number of ``text`` (added once)."""
        if text not in self.footnotes:
            self.footnotes.append(text)
        return self.footnotes.index(text) + 1


def rank_values(values: list[float]) -> list[int]:
    """BEST for the lowest finite value, SECOND for the next, OTHER otherwise (ties share)."""
    finite = sorted({v for v in values if math.isfinite(v)})
    return [finite.index(v) if math.isfinite(v) and finite.index(v) < 2 else OTHER
            for v in values]


def rank_column(rows: list[Row], col: int, part: int, value_of) -> None:
    """Rank part ``part`` of column ``col`` within each group by value (rows with a status
    unranked); ``value_of(row)`` gives the number ranked (lower is better)."""
    for members in _groups(rows, col, part).values():
        for r, rank in zip(members, rank_values([value_of(r) for r in members]), strict=True):
            r.cells[col].parts[part].rank = rank


def _groups(rows: list[Row], col: int, part: int) -> dict[tuple, list[Row]]:
    groups: dict[tuple, list[Row]] = {}
    for r in rows:
        if r.cells[col].status is None and len(r.cells[col].parts) > part:
            groups.setdefault(r.group, []).append(r)
    return groups


def rule_name(marks: str) -> str:
    """The key of ``MARK_RULES`` that ``marks`` names (its old name accepted)."""
    marks = "intervals" if marks == "significance" else marks
    if marks not in MARK_RULES:
        raise ValueError(f"unknown marking rule {marks!r}: one of {', '.join(MARK_RULES)}")
    return marks


def mark_column(rows: list[Row], col: int, part: int, marks: str = "intervals") -> None:
    """Mark part ``part`` of column ``col`` within each group by the rule ``marks`` (see
    ``MARK_RULES``) from each part's ``Stat``; a part without one is its printed value."""
    marks = rule_name(marks)
    for members in _groups(rows, col, part).values():
        parts = [r.cells[col].parts[part] for r in members]
        ranks = (rank_values([_value(p) for p in parts]) if marks == "value"
                 else interval_marks([_stat(p) for p in parts]))
        for p, rank in zip(parts, ranks, strict=True):
            p.rank = rank


def _stat(p: Part) -> Stat:
    """The statistic a part is marked on: its own, or its printed number."""
    return p.stat if p.stat is not None else Stat(_value(p))


def _value(p: Part) -> float:
    """The number a part is ranked by (NaN: not ranked)."""
    if p.stat is not None:
        return p.stat.value if p.stat.rankable else math.nan
    try:
        return float(p.text.split()[0])
    except (ValueError, IndexError):
        return math.nan


def stat_text(value: float | None, ci: tuple | list | None, n_independent: int | None,
              digits: int = 3, show_ci: bool = False) -> str:
    """A figure's text: the value, with ``show_ci`` its interval "[low, high]" (as the marks
    read it: ``significance.shown_interval``), and "(1 segment)" when fewer than two
    independent units stand behind it."""
    if value is None or not math.isfinite(value):
        return "-"
    text = f"{value:.{digits}f}"
    interval = shown_interval(value, ci)
    if show_ci and interval is not None:
        text += f" [{interval[0]:.{digits}f}, {interval[1]:.{digits}f}]"
    if n_independent is not None and n_independent < 2:
        text += f" ({n_independent} segment{'' if n_independent == 1 else 's'})"
    return text


# ---- renderers --------------------------------------------------------------------------------

def _md_part(p: Part) -> str:
    text = md_escape(p.text)
    if p.text == "-":
        return text
    return {BEST: f"**{text}**", SECOND: f"<u>{text}</u>"}.get(p.rank, text)


def _tex_part(p: Part) -> str:
    return {BEST: rf"\textbf{{{p.text}}}", SECOND: rf"\underline{{{p.text}}}"}.get(p.rank,
                                                                                   p.text)


def _cell_text(c: Cell, part, note, escape=lambda s: s) -> str:
    text = escape(c.status) if c.status is not None else " / ".join(part(p) for p in c.parts)
    return text + (note(c.note) if c.note else "")


def _shown_keys(table: Table) -> list[list[str]]:
    """Row keys with repeats of the row above blanked (left to right, as in the paper)."""
    out, prev = [], None
    for r in table.rows:
        keys = list(r.keys)
        if prev is not None:
            for i in range(len(keys) - 1):
                if r.keys[: i + 1] != prev[: i + 1]:
                    break
                keys[i] = ""
        out.append(keys)
        prev = list(r.keys)
    return out


#: characters a markdown renderer would read as markup, and their escaped forms: HTML's own
#: characters as entities (every renderer passes entities through as text), the rest with a
#: backslash (CommonMark / GFM escapes)
_MD_ENTITIES = {"&": "&amp;", "<": "&lt;", ">": "&gt;"}
_MD_BACKSLASHED = set("\\|`*")


def md_escape(text: str) -> str:
    """Text from data (a name, a label, a message) as markdown that renders as that text in
    any renderer: ``<img src=x onerror=alert(1)>`` stays text, a ``|`` stays in its cell,
    ``**`` / backticks / ``[x](url)`` make no bold, code or link. Normal names stay readable:
    an underscore is escaped only at a word's edge (``loop_1`` as is; GFM makes no emphasis
    inside a word)."""
    text, out = str(text), []
    for i, ch in enumerate(text):
        if ch in _MD_ENTITIES:
            out.append(_MD_ENTITIES[ch])
        elif ch in _MD_BACKSLASHED:
            out.append("\\" + ch)
        elif ch == "_" and not (0 < i < len(text) - 1 and text[i - 1].isalnum()
                                and text[i + 1].isalnum()):
            out.append("\\_")
        elif ch == "(" and i > 0 and text[i - 1] == "]":
            out.append("\\(")  # "[x](url)" is no link
        else:
            out.append(ch)
    return "".join(out)


def to_markdown(table: Table) -> str:
    """A pipe table, its caption and footnotes; every text escaped (``md_escape``) and only
    the marks (``**`` bold, ``<u>`` underlined) written as markdown."""
    lines = ["| " + " | ".join(md_escape(x) for x in [*table.keys, *table.columns]) + " |",
             "|" + "---|" * (len(table.keys) + len(table.columns))]
    for r, keys in zip(table.rows, _shown_keys(table), strict=True):
        cells = [_cell_text(c, _md_part, lambda n: f" [{n}]", md_escape) for c in r.cells]
        lines.append("| " + " | ".join([*(md_escape(x) for x in keys), *cells]) + " |")
    out = "\n".join(lines) + "\n\n" + md_escape(caption_text(table)) + "\n"
    if table.footnotes:
        out += "\n" + "\n".join(f"[{i}] {md_escape(t)}" for i, t in
                                enumerate(table.footnotes, 1)) + "\n"
    return out


def tex_escape(s: str) -> str:
    """LaTeX special characters escaped."""
    table = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#",
             "_": r"\_", "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}",
             "^": r"\textasciicircum{}"}
    return "".join(table.get(ch, ch) for ch in str(s))


def to_latex(table: Table, label: str = "") -> str:
    """A booktabs ``table`` float: caption (with the synthetic notice), ``\\toprule``,
    ``\\midrule`` between groups of the first key, ``\\cmidrule`` between other groups,
    ``\\bottomrule``, footnotes below."""
    nkeys, ncol = len(table.keys), len(table.keys) + len(table.columns)
    out = [r"\begin{table}[t]", r"\centering", r"\footnotesize",
           rf"\caption{{{tex_escape(caption_text(table))}}}"]
    if label:
        out.append(rf"\label{{{label}}}")
    out += [r"\begin{tabular}{@{}" + "l" * nkeys + "c" * len(table.columns) + "@{}}",
            r"\toprule",
            " & ".join([*(tex_escape(k) for k in table.keys),
                        *(rf"\textbf{{{tex_escape(c)}}}" for c in table.columns)]) + r" \\",
            r"\midrule"]
    prev = None
    for r, keys in zip(table.rows, _shown_keys(table), strict=True):
        if prev is not None and r.group != prev.group:
            same_first = nkeys > 1 and r.keys[:1] == prev.keys[:1]
            out.append(rf"\cmidrule{{2-{ncol}}}" if same_first else r"\midrule")
        cells = [_cell_text(c, lambda p: _tex_part(Part(tex_escape(p.text), p.rank)),
                            lambda n: rf"\textsuperscript{{{n}}}") for c in r.cells]
        out.append(" & ".join([*(tex_escape(k) for k in keys), *cells]) + r" \\")
        prev = r
    out += [r"\bottomrule", r"\end{tabular}"]
    if table.footnotes:
        out.append(r"\par\smallskip\raggedright\scriptsize")
        out += [rf"\textsuperscript{{{i}}}{tex_escape(t)}\\" for i, t in
                enumerate(table.footnotes, 1)]
    out.append(r"\end{table}")
    return "\n".join(out) + "\n"


CSV_META = ("sequence", "sensor_class", "method", "seed", "label", "status")


def to_csv(table: Table) -> str:
    """Long format: one line per cell value (``CSV_META`` of its row, ``row`` = its label,
    ``column`` = its column title, ``quantity`` and ``value``; a cell with a status ("Div.",
    "failed", "-") has it as its ``status``, and its footnote as its ``note``)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*CSV_META, "row", "column", "quantity", "value", "note"])
    for r in table.rows:
        for col, c in zip(table.columns, r.cells, strict=True):
            meta = {**r.meta, **({"status": c.status} if c.status else {})}
            meta = ["" if meta.get(k) is None else meta[k] for k in CSV_META]
            note = table.footnotes[c.note - 1] if c.note else ""
            items = c.values.items() if c.values else [("", None)]
            for quantity, value in items:
                text = "" if value is None or not math.isfinite(value) else repr(float(value))
                w.writerow([*meta, r.keys[-1], col, quantity, text, note])
    return buf.getvalue()


RENDERERS = {"md": to_markdown, "tex": to_latex, "csv": to_csv}


def render(table: Table) -> dict[str, str]:
    """The table in every format."""
    return {fmt: fn(table) for fmt, fn in RENDERERS.items()}


def save_table(table: Table, out_dir: Path, stem: str) -> dict[str, str]:
    """Write ``<stem>.md/.tex/.csv`` atomically (a caption whose intervals are not printed
    names the CSV); return the texts by format."""
    from bench import guard

    table.csv_file = str(Path(out_dir) / f"{stem}.csv")
    texts = render(table)
    guard.output_folder(Path(out_dir))
    guard.write_texts({Path(out_dir) / f"{stem}.{fmt}": text for fmt, text in texts.items()},
                      guard.derived, "a table")
    return texts
