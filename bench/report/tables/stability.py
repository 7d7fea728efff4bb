"""Do a table's marks hold on both halves of each sequence?

One table is one drive: a mark says how methods compared on it, not whether they would on the
next stretch of road. Here every run's scored frames are cut in two halves (the first
``floor(n / 2)`` frames and the rest), each half is scored on its own (the relative errors and
their intervals, exactly as a run is: ``bench.runs.evaluate.relative_part``), and the same
table is built and marked by the same rule for each half. A mark of the whole sequence (bold or
underlined) *holds* when both halves give its cell the same mark and each half could have told
otherwise; a half *cannot tell* when it has no marked figure there (it rests on fewer than two
independent segments) or marks every figure of that column and sequence bold (its intervals
separate nothing, so a bold there says nothing). Otherwise the mark *differs*. The table then
says, per sequence, how many of its marks hold, differ and cannot be told, and flags every cell
whose mark differs on a half (``CHANGED``). Times are one figure per run, not per half: left
out.

Nothing is cached or written: the halves cost one more scoring of the relative errors, made
when the table or the report asks for them (``bench table --stability``, the report).
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from dataclasses import dataclass

from bench.report.tables.model import Table
from bench.report.tables.paper import RunRow, relative_table
from bench.report.tables.significance import BEST, OTHER
from bench.runs.evaluate import relative_part
from metrics import relative_errors

#: the flag of a cell whose mark differs on a half
CHANGED = "†"


def half(rr: RunRow, which: int, lengths: list[float]) -> RunRow:
    """The run of ``rr`` scored on half ``which`` (0: first, 1: second) of its scored frames
    only: its relative errors replaced, everything else as it is."""
    if rr.failed or rr.diverged or not rr.run.has_gt:
        return rr
    try:
        gt, est = rr.run.gt, rr.run.est
        cut = len(gt) // 2
        part = slice(0, cut) if which == 0 else slice(cut, len(gt))
        figures = relative_part(gt[part], est[part], relative_errors(gt[part], est[part],
                                                                     lengths))
    except (OSError, ValueError):
        # a half too short for any segment (MetricError), or trajectory files that cannot be
        # read (the report lists them): no figure, so no mark of it holds
        figures = []
    result = rr.result.model_copy(update={"relative_error": figures})
    return RunRow(dataclasses.replace(rr.run, result=result), rr.label)


@dataclass
class Stability:
    """Per sequence, (marks holding on both halves, marks of the whole sequence, marks a half
    cannot tell); the cells (row, column, part) whose mark differs on a half."""

    held: dict[str, tuple[int, int, int]]
    changed: set[tuple[int, int, int]]

    def text(self) -> str:
        """The sentence a caption gets."""
        counts = "; ".join(f"{seq}: {k} hold, {n - k - u} differ, {u} cannot tell (of {n})"
                           for seq, (k, n, u) in self.held.items())
        return (f"Stability (each half of a sequence's scored frames scored on its own, marked "
                f"by the same rule), per sequence, of its marks: {counts or 'none'}. A mark "
                "holds when both halves give it and each could have told otherwise; a half "
                "cannot tell where its figure rests on fewer than 2 independent segments or "
                f"every figure of its column is bold; {CHANGED} = a cell whose mark differs on "
                "a half.")


def _blind(table: Table, i: int, col: int, p: int) -> bool:
    """Can a half's table not tell row ``i``'s mark at (col, part)? Its figure is unmarked for
    want of segments, or every ranked figure of that column and group is bold."""
    row = table.rows[i]
    if len(row.cells[col].parts) <= p:
        return True
    stat = row.cells[col].parts[p].stat
    if stat is None or not stat.rankable:
        return True
    peers = [r.cells[col].parts[p] for r in table.rows if r.group == row.group
             and len(r.cells[col].parts) > p and r.cells[col].parts[p].stat is not None
             and r.cells[col].parts[p].stat.rankable]
    return len(peers) < 2 or all(q.rank == BEST for q in peers)


def stability(rows: list[RunRow], lengths: list[float], table: Table,
              marks: str = "intervals") -> Stability:
    """Compare ``table`` (``relative_table(rows, lengths, marks)``, in the same row order)
    with the same table of each half."""
    halves = [relative_table([half(rr, w, lengths) for rr in rows], lengths, marks)
              for w in (0, 1)]
    held: dict[str, list[int]] = defaultdict(lambda: [0, 0, 0])
    changed = set()
    for i, (rr, row) in enumerate(zip(rows, table.rows, strict=True)):
        for col in range(len(lengths)):
            for p, part in enumerate(row.cells[col].parts):
                ranks = [h.rows[i].cells[col].parts[p].rank
                         if len(h.rows[i].cells[col].parts) > p else OTHER for h in halves]
                same = all(r == part.rank for r in ranks)
                blind = any(_blind(h, i, col, p) for h in halves)
                if part.rank != OTHER:
                    held[rr.sequence][1] += 1
                    held[rr.sequence][0] += same and not blind
                    held[rr.sequence][2] += blind
                if not same and not blind:
                    changed.add((i, col, p))
    return Stability({s: (k, n, u) for s, (k, n, u) in held.items()}, changed)


def with_stability(rows: list[RunRow], lengths: list[float], table: Table,
                   marks: str = "intervals") -> Stability:
    """Flag ``table``'s cells whose mark does not hold on both halves (``CHANGED`` after
    the figure) and add the counts to its caption; returns what was found."""
    found = stability(rows, lengths, table, marks)
    for i, col, p in found.changed:
        part = table.rows[i].cells[col].parts[p]
        part.text += f" {CHANGED}"
    table.caption += " " + found.text()
    return found
