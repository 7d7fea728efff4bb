"""Marks that hold within the noise: which figures of a table column are the best.

Per group (a sequence) and column, the contenders are the methods (a method's seed and no-seed
rows are one contender, represented by its better row); a figure resting on fewer than two
independent segments takes no part. The contender with the lowest value leads; every other
contender whose difference to the leader is not significant shares the leader's mark (bold).
The best of the rest and its ties are underlined. Nothing else is marked.

"Significant": the 95 % interval of the paired difference (the same segments of both runs,
resampled with the same blocks of frames: ``metrics.intervals.paired_interval``; for APE both
estimates' frame-to-frame errors resampled with the same blocks:
``metrics.drift_intervals.paired_ape_interval``) excludes zero.
Two figures without common segments (other frames scored) are significantly different only when
their own intervals do not overlap; figures without intervals (the time per frame) by value.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from metrics.drift_intervals import paired_ape_interval
from metrics.intervals import paired_interval

#: a part's mark: bold, underlined, none
BEST, SECOND, OTHER = 0, 1, 2


@dataclass
class Stat:
    """What a figure stands on: its ``value``, its confidence interval ``ci`` (low, high),
    the independent units behind it, and ``units()`` -> (scored frames, ``metrics.units.Units``,
    quantity, rmse) for a paired comparison (None: not available)."""

    value: float
    ci: tuple[float, float] | None = None
    n_independent: int | None = None
    units: Callable[[], tuple | None] | None = None

    @property
    def rankable(self) -> bool:
        return math.isfinite(self.value) and (self.n_independent is None
                                               or self.n_independent >= 2)


def contender(row) -> tuple:
    """A row's contender: its method and variant label (seed options merged)."""
    if row.meta.get("method"):
        return (row.meta.get("method"), row.meta.get("label"))
    return tuple(row.keys)


def mark_significant(rows: list, parts: list) -> list[int]:
    """The mark (``BEST``, ``SECOND``, ``OTHER``) of each part (``bench.report.table.Part``,
    one per ``Row``, same column)."""
    ranks = [OTHER] * len(parts)
    lead_of: dict[tuple, int] = {}
    for i, (row, part) in enumerate(zip(rows, parts, strict=True)):
        if part.stat is None or not part.stat.rankable:
            continue
        key = contender(row)
        if key not in lead_of or part.stat.value < parts[lead_of[key]].stat.value:
            lead_of[key] = i
    order = sorted(lead_of.values(), key=lambda i: parts[i].stat.value)
    for tier in (BEST, SECOND):
        if not order:
            break
        lead = parts[order[0]].stat
        ties = [i for i in order if i == order[0] or not worse(parts[i].stat, lead)]
        for i in ties:
            ranks[i] = tier
        order = [i for i in order if i not in ties]
    return ranks


def worse(a: Stat, b: Stat) -> bool:
    """Is ``a`` significantly above ``b`` (see the module docstring)?"""
    ua = a.units() if a.units is not None else None
    ub = b.units() if b.units is not None else None
    if ua is not None and ub is not None:
        drift = _paired_drift(ua, ub)
        if drift is not None:
            return bool(drift.low > 0.0)
        common = _common(ua, ub)
        if common is not None:
            n_frames, anchor, end, va, vb, rmse = common
            return bool(paired_interval(n_frames, anchor, end, va, vb, rmse=rmse).low > 0.0)
    if a.ci is not None and b.ci is not None:
        return bool(a.ci[0] > b.ci[1])
    return a.value > b.value


def _paired_drift(ua: tuple, ub: tuple):
    """The paired APE interval (``metrics.drift_intervals``) when both figures are APE of the
    same quantity on the same GT frames with the same alignment; else None."""
    (_, units_a, key_a, _), (_, units_b, key_b, _) = ua, ub
    da, db = units_a.drift, units_b.drift
    if da is None or db is None or key_a != key_b or not da.same_frames(db):
        return None
    return paired_ape_interval(da, db, key_a)


def _common(ua: tuple, ub: tuple):
    """(frames, anchor, end, values a, values b, rmse) on the units both runs have."""
    (na, units_a, key_a, rmse), (nb, units_b, key_b, _) = ua, ub
    if na != nb:
        return None
    if np.array_equal(units_a.anchor, units_b.anchor) and np.array_equal(units_a.end,
                                                                         units_b.end):
        return na, units_a.anchor, units_a.end, units_a.values[key_a], units_b.values[key_b], \
            rmse
    pairs_b = {(int(s), int(e)): k for k, (s, e) in enumerate(zip(units_b.anchor, units_b.end,
                                                                   strict=True))}
    ia, ib = [], []
    for k, (s, e) in enumerate(zip(units_a.anchor, units_a.end, strict=True)):
        j = pairs_b.get((int(s), int(e)))
        if j is not None:
            ia.append(k)
            ib.append(j)
    if len(ia) < 2:
        return None
    ia, ib = np.array(ia), np.array(ib)
    return (na, units_a.anchor[ia], units_a.end[ia], units_a.values[key_a][ia],
            units_b.values[key_b][ib], rmse)
