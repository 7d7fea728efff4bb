"""Marks a reader can check with a ruler: decided from the figures and intervals as printed.

One rule, for every table, figure and page of the harness (``interval_marks``):

    In each column (per sequence), let U be the smallest upper end of the printed 95 %
    intervals; **bold**: every figure printed at or below U. Among the rest, the same rule
    again: **underlined**.

Every bold interval therefore contains U (its low end <= its value <= U <= its high end), so no
two figures marked alike have disjoint intervals; the figure with the lowest value is always
bold; and since the rule reads only the printed numbers (rounded to the digits shown), equal
printed values always carry equal marks. A figure without an interval (the time per frame) is
its own interval: such a column is marked by value (the lowest printed value bold, the next
underlined). A figure resting on fewer than ``MIN_INDEPENDENT`` independent segments ("(1
segment)") is shown but never marked.

The interval printed beside a figure is its own interval from ``metrics.json`` (the run's
scoring: ``bench.runs.uncertainty``), widened only so that it contains the figure's value
(``shown``); nothing else decides a mark, so the caption's one sentence (``RULE``) states all
of it. Each row is marked on its own (a method's seed and no-seed rows are two figures).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from metrics.intervals import MIN_INDEPENDENT

#: a part's mark: bold, underlined, none
BEST, SECOND, OTHER = 0, 1, 2

#: the rule as every caption states it, when the table prints the intervals
RULE = ("Marks are read from the printed numbers: in each column and sequence, bold = every "
        "figure at or below the smallest upper end U of the printed 95 % intervals (so every "
        "bold interval contains U), underlined = the same rule among the rest; a figure without "
        "an interval counts as its own interval; a figure on fewer than "
        f"{MIN_INDEPENDENT} independent segments is not marked.")

#: a caption's stand-in for where the intervals are when the table does not print them,
#: resolved when the table is rendered (``bench.report.tables.model.caption_text``: the CSV
#: written beside the table, or the command that prints it)
UNPRINTED = "<<where the intervals are>>"

#: the rule as a caption states it when the table does not print the intervals: a reader is
#: told exactly where they are, so every mark can still be checked
RULE_UNPRINTED = ("Marks are read from each figure's 95 % interval, which this table does not "
                  f"print: {UNPRINTED}. In each column and sequence, bold = every figure at or "
                  "below the smallest upper end U of those intervals (so every bold interval "
                  "contains U), underlined = the same rule among the rest (the intervals "
                  "rounded to the digits the figures are printed with, and widened to hold "
                  "their figure where needed); a figure without an interval counts as its own "
                  "interval; a figure on fewer than "
                  f"{MIN_INDEPENDENT} independent segments is not marked.")


@dataclass
class Stat:
    """What a figure stands on: its ``value``, its confidence interval ``ci`` (low, high), the
    independent units behind it and the ``digits`` it is printed with."""

    value: float
    ci: tuple[float, float] | None = None
    n_independent: int | None = None
    digits: int = 3

    @property
    def rankable(self) -> bool:
        return math.isfinite(self.value) and (self.n_independent is None
                                               or self.n_independent >= MIN_INDEPENDENT)

    def shown(self) -> tuple[float, float, float]:
        """(value, low, high) as printed: rounded to ``digits``, the interval widened to hold
        the value (no interval: the value itself)."""
        return shown(self.value, self.ci, self.digits)


def _printed(x: float, digits: int) -> float:
    return float(f"{x:.{digits}f}")


def shown_interval(value: float, ci) -> tuple[float, float] | None:
    """The interval as printed beside ``value``: ``ci`` widened to contain the value (a
    percentile interval of a skewed statistic may, rarely, miss its own value); None without
    a finite interval."""
    if ci is None or None in ci:
        return None
    low, high = float(ci[0]), float(ci[1])
    if not (math.isfinite(low) and math.isfinite(high)):
        return None
    return min(low, value), max(high, value)


def shown(value: float, ci, digits: int = 3) -> tuple[float, float, float]:
    """(value, low, high) rounded to ``digits`` as printed; without an interval low = high =
    value."""
    interval = shown_interval(value, ci) if math.isfinite(value) else None
    low, high = interval if interval is not None else (value, value)
    return _printed(value, digits), _printed(low, digits), _printed(high, digits)


def interval_marks(stats: list[Stat | None]) -> list[int]:
    """The mark (``BEST``, ``SECOND``, ``OTHER``) of each figure of one column and group, by
    the module's rule; None and unrankable figures are ``OTHER``."""
    marks = [OTHER] * len(stats)
    left = {i: s.shown() for i, s in enumerate(stats) if s is not None and s.rankable}
    for tier in (BEST, SECOND):
        if not left:
            break
        upper = min(high for _, _, high in left.values())
        tied = [i for i, (value, _, _) in left.items() if value <= upper]
        for i in tied:
            marks[i] = tier
            del left[i]
    return marks


def worse(a: Stat, b: Stat) -> bool:
    """Is ``a`` distinguishably above ``b`` by their printed intervals (a's low end above b's
    high end; without intervals, a's printed value above b's)?"""
    _, low_a, _ = a.shown()
    _, _, high_b = b.shown()
    return low_a > high_b


def contender(row) -> tuple:
    """A row's method and variant label (seed options merged), for summaries across rows."""
    if row.meta.get("method"):
        return (row.meta.get("method"), row.meta.get("label"))
    return tuple(row.keys)
