"""Methods against sequences: one markdown table per segment length, a row per method (and
seed option or label), a column per sequence, "rotation / translation" per cell; per column
the best value is bold and the second underlined (diverged runs show "Div." and are not
ranked). For comparing one method with all others across a suite at a glance
(``bench table DIR --pivot``)."""

from __future__ import annotations

import math

from bench.report.cells import md_mark, ranks
from bench.report.names import hosts_note, order_key
from bench.report.tables import TIME_NOTE, Row, _fmt, _fmt_time  # the main table's formats


def _labels(rows: list[Row]) -> list[str]:
    """Row labels in the main table's method order (a method first seen on a later sequence
    still takes its place)."""
    first = {}
    for r in rows:
        first.setdefault(r.label, (order_key(r.method), r.method, r.seed is False, r.label))
    return sorted(first, key=first.get)


def to_pivot_markdown(rows: list[Row], length: str) -> str:
    """The table at one segment length (a key of ``Row.rot``, e.g. "48")."""
    sequences = list(dict.fromkeys(r.sequence for r in rows))
    labels = _labels(rows)
    by_key = {(r.label, r.sequence): r for r in rows}
    cells: dict[tuple[str, str], str] = {}
    for seq in sequences:
        ranked = [by_key[(lab, seq)] for lab in labels
                  if (lab, seq) in by_key and not by_key[(lab, seq)].diverged]
        rot = ranks([r.rot.get(length, math.nan) for r in ranked])
        trans = ranks([r.trans.get(length, math.nan) for r in ranked])
        for r, a, b in zip(ranked, rot, trans, strict=True):
            cells[(r.label, seq)] = (f"{md_mark(_fmt(r.rot.get(length, math.nan)), a)} / "
                                     f"{md_mark(_fmt(r.trans.get(length, math.nan)), b)}")
        for lab in labels:
            if (lab, seq) in by_key and by_key[(lab, seq)].diverged:
                cells[(lab, seq)] = "Div."
    lines = [f"| {float(length):g} m | " + " | ".join(sequences) + " |",
             "|---|" + "---|" * len(sequences)]
    for lab in labels:
        lines.append(f"| {lab} | " + " | ".join(cells.get((lab, s), "") for s in sequences)
                     + " |")
    lines.append("")
    lines.append(f"Each cell: mean rotation [deg] / translation [m] relative error over "
                 f"{float(length):g} m segments; per sequence the best is bold, the second "
                 "underlined; Div. = diverged; empty = not run.")
    return "\n".join(lines) + "\n"


def to_pivot_time_markdown(rows: list[Row]) -> str:
    """The mean time per frame [ms] of every row and sequence, formatted as the main table's
    Time column (fastest bold, second underlined; a diverged run's time is shown, not ranked)."""
    sequences = list(dict.fromkeys(r.sequence for r in rows))
    labels = _labels(rows)
    by_key = {(r.label, r.sequence): r for r in rows}
    cells: dict[tuple[str, str], str] = {}
    for seq in sequences:
        here = [by_key[(lab, seq)] for lab in labels if (lab, seq) in by_key]
        ranked = [r for r in here if not r.diverged]
        rank = dict(zip((r.label for r in ranked), ranks([r.time_ms for r in ranked]),
                        strict=True))
        for r in here:
            text = _fmt_time(r.time_ms, r.threads)
            cells[(r.label, seq)] = text if r.diverged else md_mark(text, rank[r.label])
    lines = ["| Time (ms) | " + " | ".join(sequences) + " |",
             "|---|" + "---|" * len(sequences)]
    for lab in labels:
        lines.append(f"| {lab} | " + " | ".join(cells.get((lab, s), "") for s in sequences)
                     + " |")
    lines += ["", TIME_NOTE + " " + hosts_note(r.cpu for r in rows) + "Per sequence the "
              "fastest is bold, the second underlined; empty = not run."]
    return "\n".join(lines) + "\n"


def pivot_markdown(rows: list[Row], lengths: list[str]) -> str:
    """``pivot.md``: one table per segment length, then the times."""
    return "\n".join([*(to_pivot_markdown(rows, x) for x in lengths),
                      to_pivot_time_markdown(rows)])
