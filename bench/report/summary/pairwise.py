"""Across sequences, pairwise: on how many sequences of a sensor class each method ranks better
than another, and whether that verdict holds across the sequences, not only a mean mark.

On one sequence, method A ranks better than B when A's mean mark
(``bench.report.summary.ranks.figure_ranks``: the tables' own marks, 1 bold, 2 underlined, 3
neither) over the figures both are marked on (the mean rotation and translation
relative error at the summary's lengths) is lower than B's; equal means tie. Over the n
sequences of a class where both are ranked, A is better on k, B on l, n - k - l tie. Whether the
verdict holds across sequences: a two-sided exact sign test (binomial, p = 1/2) on the k + l
untied sequences; it holds at p < 0.05, which needs at least 6 untied sequences all one way (2 /
2^6 = 0.031): with fewer, no verdict can hold, however the sequences fall. The test treats
sequences as independent draws of the class (sequences of one drive are not quite). """

from __future__ import annotations

import math

from bench.report.summary.ranks import (
    contender_name,
    counted_as,
    figure_ranks,
    ranked_lengths,
    same_content_note,
)
from bench.report.tables.model import BEST, OTHER, Cell, Part, Row, Table
from bench.report.tables.paper import RunRow
from loaders.sensor_classes import class_rank
from methods.registry import order_key

#: the level at which a pairwise verdict holds across sequences
LEVEL = 0.05


def sign_test_p(wins: int, losses: int) -> float:
    """Two-sided exact sign test: the probability, with each untied sequence a fair coin, of a
    split at least as uneven as ``wins`` : ``losses`` (twice the smaller tail, at most 1);
    1.0 when there is no untied sequence."""
    n = wins + losses
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(wins, losses) + 1)) / 2 ** n
    return min(1.0, 2.0 * tail)


def verdicts(per_sequence: dict[str, dict[tuple, list[int]]], a: tuple, b: tuple
             ) -> tuple[int, int, int]:
    """(sequences where ``a`` ranks better, where ``b`` does, ties) over the sequences where
    both are ranked; ``per_sequence``: sequence -> contender -> its rank on each figure (None
    where not ranked), the figures in one order."""
    wins = losses = ties = 0
    for ranks in per_sequence.values():
        ra, rb = ranks.get(a), ranks.get(b)
        if ra is None or rb is None:
            continue
        both = [(x, y) for x, y in zip(ra, rb, strict=True) if x is not None and y is not None]
        if not both:
            continue
        mean_a = sum(x for x, _ in both) / len(both)
        mean_b = sum(y for _, y in both) / len(both)
        if mean_a < mean_b:
            wins += 1
        elif mean_b < mean_a:
            losses += 1
        else:
            ties += 1
    return wins, losses, ties


def _per_sequence(rows: list[RunRow], lengths: tuple[float, ...]
                  ) -> dict[str, dict[tuple, list[int | None]]]:
    figures = [figure_ranks(rows, L, q) for L in lengths for q in ("rot_deg", "trans_m")]
    out: dict[str, dict[tuple, list[int | None]]] = {}
    for seq in sorted({s for f in figures for s in f}):
        keys = {k for f in figures for k in f.get(seq, {})}
        out[seq] = {k: [f.get(seq, {}).get(k) for f in figures] for k in keys}
    return out


def pairwise_table(rows: list[RunRow], lengths_m: tuple[float, ...] | None = None) -> Table:
    """Per sensor class with at least two ranked sequences, a matrix: the cell of row A and
    column B is "k/n, p": A ranks better than B on k of the n sequences where both are ranked,
    and the sign test's p (see the module's doc); bold where the verdict holds (p < 0.05)."""
    lengths = ranked_lengths(rows) if lengths_m is None else tuple(lengths_m)
    per_seq = _per_sequence(rows, lengths)
    counted = counted_as(rows)  # two names of one content: one sequence
    class_of = {counted[rr.sequence]: rr.sensor_class for rr in rows}
    classes = sorted({class_of[s] for s in per_seq}, key=lambda c: (class_rank(c), c))
    found = {}
    for cls_name in classes:
        mine = {s: r for s, r in per_seq.items() if class_of[s] == cls_name}
        if len(mine) < 2:
            continue
        keys = sorted({k for r in mine.values() for k in r},
                      key=lambda k: (order_key(k[0]), k[0], k[1] or ""))
        found[cls_name] = (mine, keys)
    names = list(dict.fromkeys(contender_name(k[0], k[1] or "")
                               for _, keys in found.values() for k in keys))
    table = Table(["Sensor class", "Method"], names, [])
    for cls_name, (mine, keys) in found.items():
        for a in keys:
            cells = {}
            for b in keys:
                if a == b:
                    continue
                wins, losses, ties = verdicts(mine, a, b)
                n = wins + losses + ties
                if n == 0:
                    continue
                p = sign_test_p(wins, losses)
                holds = p < LEVEL and wins > losses
                cells[contender_name(b[0], b[1] or "")] = Cell(
                    [Part(f"{wins}/{n}, p {p:.2g}", rank=BEST if holds else OTHER)],
                    values={"better": wins, "worse": losses, "tied": ties, "sequences": n,
                            "p": p})
            table.rows.append(Row([cls_name, contender_name(a[0], a[1] or "")], (cls_name,),
                                  [cells.get(name, Cell(status="-")) for name in names],
                                  {"method": a[0], "label": a[1]}))
    at = " and ".join(f"{L:g} m" for L in lengths)
    table.caption = (
        "Across sequences, pairwise, per sensor class with two or more sequences: the cell of "
        "row A and column B reads \"k/n, p\": A ranks better than B on k of the n sequences "
        "where both are ranked (on a sequence, the lower mean mark, 1 bold, 2 underlined, 3 "
        "neither as the tables print it, over "
        f"the mean rotation and translation relative error at {at or 'no length'}; equal is a "
        "tie), and p is a two-sided exact sign test (binomial, 1/2) over the untied sequences, "
        "sequences taken as independent. Bold: the verdict holds across sequences (p < 0.05), "
        "which needs at least 6 untied sequences all one way; \"-\": never ranked together."
        + same_content_note(rows))
    return table
