"""The ranks the cross-dataset page is made of (``bench.report.summary.overview`` and
``bench.report.summary.pairwise``): a method's mark on one figure of one sequence, exactly the
mark the tables of the page give it (``significance.interval_marks`` over every row of the
sequence: 1 = bold, 2 = underlined, 3 = neither; a method's seed and no-seed rows: its better
mark), the lengths ranked at, and a contender's name. One rule per page: a method bold in
every table cell ranks 1 here, one underlined anywhere does not. Sequences under two names that
hold one content (``bench.runs.sequence_identity.one_content``: one store run under two names,
one recording converted twice) are one sequence here, counted once under the first name
(``counted_as``) and named in the captions (``same_content_note``)."""

from __future__ import annotations

from collections import defaultdict

from bench.report.tables.model import Row
from bench.report.tables.paper import RunRow, stat_part
from bench.report.tables.significance import contender, interval_marks
from bench.runs.result import EXTERNAL_MARK
from bench.runs.sequence_identity import one_content


def counted_as(rows: list[RunRow]) -> dict[str, str]:
    """Sequence label -> the label it is counted under across sequences (itself, or the first
    label holding the same content)."""
    return one_content([rr.sequence for rr in rows], [rr.run.config for rr in rows])


def same_content_note(rows: list[RunRow]) -> str:
    """" Sequences holding one content, counted once: a = b." (with a leading space), or ""."""
    groups: dict[str, set[str]] = defaultdict(set)
    for label, first in counted_as(rows).items():
        groups[first].add(label)
    alike = [sorted(g) for g in groups.values() if len(g) > 1]
    if not alike:
        return ""
    return (" Sequences holding one content under different names, counted once (as the "
            "first): " + "; ".join(" = ".join(g) for g in sorted(alike)) + ".")


def figure_ranks(rows: list[RunRow], length_m: float,
                 quantity: str) -> dict[str, dict[tuple, int]]:
    """sequence -> contender -> its mark on ``quantity`` at ``length_m`` as a number (1 bold,
    2 underlined, 3 neither), decided as the tables decide it: every row of the sequence
    marked together by the printed intervals, a contender's better row counted."""
    by_seq: dict[str, list[tuple[tuple, object]]] = defaultdict(list)
    counted = counted_as(rows)
    for rr in rows:
        if rr.failed or rr.diverged:
            continue
        rel = rr.result.relative(length_m)
        if rel is None or not rel.n:
            continue
        value = rel.rot_deg_mean if quantity == "rot_deg" else rel.trans_m_mean
        ci = rel.rot_deg_mean_ci if quantity == "rot_deg" else rel.trans_m_mean_ci
        part = stat_part(value, ci, rel.spread.n_independent)
        if not part.stat.rankable:
            continue
        key = contender(Row([rr.label], (), [], {"method": rr.method, "label": rr.run.label}))
        by_seq[counted[rr.sequence]].append((key, part.stat))
    out: dict[str, dict[tuple, int]] = {}
    for seq, entries in by_seq.items():
        marks = interval_marks([stat for _, stat in entries])  # the tables' marks, per row
        best: dict[tuple, int] = {}
        for (key, _), mark in zip(entries, marks, strict=True):
            # a method's better row (of either name of one content)
            best[key] = min(best.get(key, mark + 1), mark + 1)
        out[seq] = best
    return out


def ranked_lengths(rows: list[RunRow]) -> tuple[float, ...]:
    """The lengths the summary ranks at: the shortest and the longest segment length at which
    some run has segments (one length when they are the same; none when no run has any)."""
    have = sorted({r.length_m for rr in rows if not rr.failed
                   for r in rr.result.relative_error if r.n})
    return tuple(dict.fromkeys(have[:1] + have[-1:]))


def contender_name(method: str, label: str) -> str:
    """A contender's name in the summary: its method and variant label, an external run's
    label alone ("kiss-ext (external)")."""
    if label.endswith(EXTERNAL_MARK):
        return label
    return method + (f" [{label}]" if label else "")
