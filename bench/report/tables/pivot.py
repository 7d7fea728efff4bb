"""Methods against sequences: one table per segment length, a row per method (and seed option
or label), a column per sequence, the main table's "rotation / translation" cell per sequence
(marked per sequence as there, by the same rule: ``bench.report.tables.model.MARK_RULES``; "Div."
not
ranked; "failed" with its footnote), then the times. For comparing one method with all others
across a suite at a glance (``bench table DIR --pivot``). Built from ``tables.relative_table``,
so a cell reads exactly as in the main table."""

from __future__ import annotations

from bench.report.names import hosts_note, order_key
from bench.report.tables.model import Cell, Row, Table, rule_text, to_markdown
from bench.report.tables.paper import TIME_NOTE, RunRow, relative_table


def pivot_tables(rows: list[RunRow], lengths: list[float], marks: str = "intervals",
                 ci: bool = False) -> list[Table]:
    """One table per length and one of the times (the intervals in the cells with ``ci``)."""
    main = relative_table(rows, lengths, marks, ci)
    sequences = list(dict.fromkeys(r.sequence for r in rows))
    order = {}
    for rr in rows:
        order.setdefault(rr.label, (order_key(rr.method), rr.method, rr.seed.rank, rr.label))
    labels = sorted(order, key=order.get)
    at = {(rr.label, rr.sequence): row for rr, row in zip(rows, main.rows, strict=True)}
    tables = []
    for col, title in enumerate(main.columns):
        t = Table([title], sequences, [], footnotes=main.footnotes,
                  csv_file="of the same table without --pivot (bench table --format csv "
                           "prints it)")
        for label in labels:
            cells = [at[(label, s)].cells[col] if (label, s) in at else Cell(status="")
                     for s in sequences]
            t.rows.append(Row([label], (), cells))
        if col < len(lengths):
            t.caption = (f"Each cell: mean rotation [deg] / translation [m] relative error over "
                         f"{title} segments. {rule_text(marks, ci)} Div. = diverged; "
                         "empty = not run.")
        else:
            t.caption = (TIME_NOTE + " " + hosts_note(r.result.cpu for r in rows
                                                      if r.result.finished
                                                      and r.result.timed_by_harness)
                         + "Per sequence the fastest is bold, the second underlined (by "
                         "value: times have no interval); empty = not run.")
        tables.append(t)
    return tables


def pivot_markdown(rows: list[RunRow], lengths: list[float], marks: str = "intervals",
                   ci: bool = False) -> str:
    """``pivot.md``: one table per segment length, then the times."""
    return "\n".join(to_markdown(t) for t in pivot_tables(rows, lengths, marks, ci))
