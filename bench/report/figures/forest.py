"""Forest plots of the intervals behind a table's marks (``bench figures``: ``forest/``).

Per sequence and error (rotation, translation) one figure, one panel per segment length drawn
(the shortest and the longest with segments, e.g. 8 m and 48 m): every method's mean relative
error as a dot on its 95 % interval (a horizontal bar), one row per table row in the table's
order. The marks are the table's, decided from these intervals alone (``interval_marks``): U,
the smallest upper end among the ranked figures, is drawn as a dashed line, and every ranked
figure at or below it is bold (its label bold, its bar thick), so every bold bar crosses the
line; the same rule among the rest gives the underlined ones (label underlined, a dotted line
at their U): the tables' own rule on the figures as printed (``bench.report.tables.significance``),
so a plot and its table never disagree. A figure that is not ranked (fewer than 2 independent
segments) is drawn grey and hollow; a diverged run is named, not drawn. One paper column wide,
written as ``forest/<sequence-slug>-<error>.{pdf,png}``.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bench.report.figures.style import (
    COLUMN_IN,
    SMALL_PT,
    color,
    figure,
    fit_height,
    legend_below,
    prior_style,
    run_name,
    save,
    slug,
    use_paper_style,
)
from bench.report.tables.significance import Stat
from bench.report.tables.significance import interval_marks as significance_marks

#: a figure's mark: bold, underlined, none (the tables' ``bench.report.tables.model`` ranks)
BOLD, UNDERLINED, UNMARKED = 0, 1, 2

#: the errors drawn: (name, field of ``RelativeError``, unit)
ERRORS = (("rotation", "rot_deg_mean", "deg"), ("translation", "trans_m_mean", "m"))
_GREY = "0.6"
_ROW_IN, _PANEL_EXTRA_IN = 0.15, 0.5  # height of a method's row, a panel's title and axis [in]
#: a panel is never shorter than this many rows: one method's panel stays readable (its value
#: label inside the frame), centred in that height
_MIN_ROWS = 3


def interval_tiers(values: Sequence[float], lows: Sequence[float | None],
                   highs: Sequence[float | None], rankable: Sequence[bool],
                   digits: int = 3) -> tuple[list[int], list[float]]:
    """The marks (``BOLD``, ``UNDERLINED``, ``UNMARKED``) of one table column, by the tables'
    one rule (``bench.report.tables.significance.interval_marks`` on the figures as printed with
    ``digits``), and the bound U of each tier that has members (bold first): the smallest
    printed upper end among the figures left for that tier."""
    n = len(values)
    if not len(lows) == len(highs) == len(rankable) == n:
        raise ValueError(f"interval_tiers: {n} values but {len(lows)} lows, {len(highs)} highs "
                         f"and {len(rankable)} rankable flags")
    stats = [Stat(float(v), _ci(lo, hi), None if ok else 1, digits) if math.isfinite(v)
             else None for v, lo, hi, ok in zip(values, lows, highs, rankable, strict=True)]
    marks = significance_marks(stats)
    bounds = []
    for tier in (BOLD, UNDERLINED):
        left = [s.shown()[2] for s, m in zip(stats, marks, strict=True)
                if s is not None and s.rankable and m >= tier]
        if any(m == tier for m in marks):
            bounds.append(min(left))
    return marks, bounds


def interval_marks(values: Sequence[float], lows: Sequence[float | None],
                   highs: Sequence[float | None], rankable: Sequence[bool]) -> list[int]:
    """The marks of one column by the interval rule (``interval_tiers``): 0 bold, 1
    underlined, 2 none."""
    return interval_tiers(values, lows, highs, rankable)[0]


def _ci(low: float | None, high: float | None) -> tuple[float, float] | None:
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return None
    return float(low), float(high)


@dataclass
class Entry:
    """One table row in a panel: its name, run and figure (``value`` with ``low`` / ``high``;
    NaN: none), ``status`` ("" drawn, "Div." diverged, "-" no segments), whether it is ranked
    and its ``mark``."""

    name: str
    run: object
    value: float = math.nan
    low: float = math.nan
    high: float = math.nan
    status: str = ""
    rankable: bool = False
    mark: int = UNMARKED


@dataclass
class Panel:
    """One sequence's error at one length: entries in the table's order and the tiers' U."""

    sequence: str
    error: str
    unit: str
    length_m: float
    entries: list[Entry] = field(default_factory=list)
    bounds: list[float] = field(default_factory=list)


def _entry(rr, name: str, key: str, length_m: float) -> Entry:
    e = Entry(name, rr.run)
    if rr.diverged:
        e.status = "Div."
        return e
    rel = rr.result.relative(length_m)
    value = getattr(rel, key) if rel is not None and rel.n > 0 else None
    if value is None or not math.isfinite(value):
        e.status = "-"
        return e
    ci = getattr(rel, f"{key}_ci")
    e.value = float(value)
    if ci is not None and None not in ci:
        e.low, e.high = float(ci[0]), float(ci[1])
    n_ind = rel.spread.n_independent
    e.rankable = n_ind is None or n_ind >= 2
    return e


def forest_panels(rows) -> list[tuple[str, list[Panel]]]:
    """(file stem, panels) of every figure of ``rows`` (``bench.report.tables.paper.RunRow``s in the
    table's order; those that did not finish are left out): per sequence and error, a panel at
    the shortest and at the longest length where the sequence has segments."""
    groups: dict[tuple, list] = {}
    for rr in rows:
        if not rr.failed:
            groups.setdefault((rr.sensor_class, rr.sequence), []).append(rr)
    names_of = {}
    for key, members in groups.items():
        names = [run_name(rr.run) for rr in members]
        # two rows under one short name (merged folders, variants): the table's row labels
        names_of[key] = names if len(set(names)) == len(names) else [rr.label for rr in members]
    seen = [seq for _, seq in groups]
    out = []
    for (klass, sequence), members in groups.items():
        lengths = sorted({r.length_m for rr in members if not rr.diverged
                          for r in rr.result.relative_error if r.n > 0})
        if not lengths:
            continue
        stem = slug(sequence) + (f"-{slug(klass)}" if seen.count(sequence) > 1 else "")
        for error, key, unit in ERRORS:
            panels = []
            for length in dict.fromkeys((lengths[0], lengths[-1])):
                entries = [_entry(rr, name, key, length)
                           for rr, name in zip(members, names_of[(klass, sequence)],
                                               strict=True)]
                marks, bounds = interval_tiers([e.value for e in entries],
                                               [e.low for e in entries],
                                               [e.high for e in entries],
                                               [e.rankable for e in entries])
                for e, m in zip(entries, marks, strict=True):
                    e.mark = m
                panels.append(Panel(sequence, error, unit, length, entries, bounds))
            out.append((f"{stem}-{error}", panels))
    return out


def _tick_label(name: str, mark: int) -> str:
    """A row's label: bold is set by its font weight; underlined written as mathtext (the
    characters mathtext would read replaced)."""
    if mark != UNDERLINED:
        return name.replace("$", r"\$")
    safe = name.translate(str.maketrans({"$": "S", "\\": "/", "{": "(", "}": ")"}))
    return rf"$\underline{{\text{{{safe}}}}}$"


def draw_panel(ax, panel: Panel) -> None:
    """One panel: a bar per interval with its dot, the tiers' U as vertical lines, the labels
    bold / underlined by mark."""
    n = len(panel.entries)
    drawn = [e for e in panel.entries if not e.status]
    ends = [x for e in drawn for x in (e.value, e.low, e.high) if math.isfinite(x)]
    lo, hi = (min(ends), max(ends)) if ends else (0.0, 1.0)
    pad = 0.08 * (hi - lo or abs(hi) or 1.0)
    left, right = lo - pad, hi + 3.5 * pad  # room for the values printed right of the bars
    for y, e in enumerate(panel.entries):
        if e.status:
            ax.text(left + pad / 2, y, e.status, va="center", fontsize=SMALL_PT, color="0.3")
            continue
        ranked = e.rankable
        c = color(e.run.method) if ranked else _GREY
        lw = {BOLD: 2.4, UNDERLINED: 1.6}.get(e.mark, 0.9)
        if math.isfinite(e.low) and math.isfinite(e.high):
            ax.plot([e.low, e.high], [y, y], color=c, lw=lw, solid_capstyle="butt", zorder=2)
        _, marker, _ = prior_style(e.run)
        ax.plot([e.value], [y], ls="", marker=marker if marker != "x" else "o", ms=3.4,
                color=c, mfc=c if ranked else "white", mew=0.8, zorder=3)
        ax.text(max(e.value, e.high) if math.isfinite(e.high) else e.value, y,
                f"  {e.value:.3f}", va="center", fontsize=SMALL_PT - 1, color="0.25")
    for tier, u in enumerate(panel.bounds):
        ax.axvline(u, color="black" if tier == BOLD else "0.45", lw=0.8,
                   ls=(0, (4, 2)) if tier == BOLD else (0, (1, 1.5)), zorder=1)
    ax.set_xlim(left, right)
    spare = (max(n, _MIN_ROWS) - n) / 2  # a short panel's rows centred in its height
    ax.set_ylim(n - 0.5 + spare, -0.5 - spare)  # the table's first row on top
    ax.set_yticks(range(n), [_tick_label(e.name, e.mark) for e in panel.entries])
    for label, e in zip(ax.get_yticklabels(), panel.entries, strict=True):
        if e.mark == BOLD:
            label.set_fontweight("bold")
    ax.grid(axis="y", visible=False)
    ax.set_xlabel(f"mean relative {panel.error} error [{panel.unit}]")
    # ended at the axes' right edge: a long title runs over the labels, never off the figure
    ax.set_title("\n".join(textwrap.wrap(f"{panel.sequence}, {panel.length_m:g} m segments",
                                          52)), loc="right")


NOTE = ("Bar: the 95 % interval the table prints, dot: the figure. Dashed line U: the smallest "
        "upper end among the ranked figures; every ranked figure at or below it is bold (label "
        "bold, thick bar), so every bold bar crosses U. Dotted: the same among the rest "
        "(underlined). Grey, hollow: not ranked (fewer than 2 independent segments).")


def draw_forest(panels: list[Panel]):
    """The figure of one sequence and error: its panels stacked, the note below."""
    from matplotlib.lines import Line2D

    heights = [max(len(p.entries), _MIN_ROWS) * _ROW_IN + _PANEL_EXTRA_IN for p in panels]
    fig, axes = figure(sum(heights), len(panels), 1, width_in=COLUMN_IN,
                       gridspec_kw={"height_ratios": heights}, squeeze=False)
    for ax, panel in zip(axes[:, 0], panels, strict=True):
        draw_panel(ax, panel)
    handles = [Line2D([], [], color="black", lw=0.8, ls=(0, (4, 2)), label="U of bold"),
               Line2D([], [], color="0.45", lw=0.8, ls=(0, (1, 1.5)),
                      label="U of underlined")]
    legend_below(fig, handles, [h.get_label() for h in handles], note=NOTE)
    fit_height(fig, sum(heights) - 0.6)
    return fig


def plot_forest(rows, out_dir: Path) -> list[Path]:
    """The forest figures of ``rows`` (``bench.report.tables.paper.RunRow``s) under
    ``out_dir/forest``; returns the written files."""
    use_paper_style()
    written = []
    for stem, panels in forest_panels(rows):
        written += save(draw_forest(panels), Path(out_dir) / "forest" / stem)
    return written
