"""Shared style of the paper figures: one paper column wide (3.5 in, fonts 6-7 pt), one colour
per method in every figure, the motion prior told apart by line style and marker (and in box
plots by hatching), legends below the axes in two columns of the tables' method names (only
"(no seed)" marked: ``run_name``), log axes labelled at two values at least and file names made
of readable slugs. Runs come from ``bench.runs.folders.load_runs``."""

from __future__ import annotations

import math
import re
from contextlib import contextmanager
from pathlib import Path

from bench.report.names import display_name, is_gt_assisted, order_key, overrides_note
from methods.registry import Seed
from methods.registry import color as _method_color

COLUMN_IN = 3.5  # one paper column [inch]
DPI = 300
FONT_PT = 7
SMALL_PT = 6


def color(method: str) -> str:
    """The method's colour, the same in every figure: declared with its class
    (``Odometry.presentation``); a method without one (a plugin) gets one of its own,
    distinct from every other method's (``methods.registry.color``)."""
    return _method_color(method)


#: (line style, marker, box hatch) of a labelled variant (an ablation), by order of first sight
_VARIANT_STYLE = [((0, (1, 1)), "^", "...."), ((0, (4, 1, 1, 1)), "v", "xxxx"),
                  ((0, (6, 2)), "<", "\\\\\\"), ((0, (2, 1, 2, 3)), ">", "++++"),
                  ((0, (1, 2)), "p", "oo"), ((0, (3, 1, 1, 1, 1, 1)), "h", "--")]
_variant_index: dict[str, int] = {}


def prior_style(run) -> tuple[str, str, str]:
    """(line style, marker, hatch) of a run's motion prior (``Seed.style``); a labelled
    variant of a method (an ablation, same colour) gets a style of its own instead, the same
    in every figure of a command (its label names the prior)."""
    label = getattr(run, "label", None)
    if label:
        k = _variant_index.setdefault(label, len(_variant_index))
        return _VARIANT_STYLE[k % len(_VARIANT_STYLE)]
    return Seed.of(run.seed).style(run.method)


def line_kwargs(run, k: int = 0, n: int = 1, points: int | None = None) -> dict:
    """Plot keywords of a run's line: its method's colour, its prior's line style and about
    ten markers along the line (run ``k`` of ``n`` starts its markers at its own offset, so
    lines on top of each other still show every marker kind). Markers are spaced by distance
    on the axes, or, given the line's number of ``points`` (a noisy series), by index."""
    ls, marker, _ = prior_style(run)
    if points is None:
        every = (0.1 * k / max(n, 1), 0.1)
    else:
        step = max(1, points // 10)
        every = (step * k // max(n, 1), step)
    return {"color": color(run.method), "ls": ls, "marker": marker, "ms": 3.2,
            "markevery": every, "mfc": "none" if marker != "x" else None, "mew": 0.8,
            "lw": 1.0}


def use_paper_style() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": FONT_PT, "axes.titlesize": FONT_PT,
                         "axes.labelsize": FONT_PT, "legend.fontsize": SMALL_PT,
                         "xtick.labelsize": SMALL_PT, "ytick.labelsize": SMALL_PT,
                         "lines.linewidth": 1.0, "axes.linewidth": 0.6, "axes.grid": True,
                         "grid.alpha": 0.3, "grid.linewidth": 0.4, "hatch.linewidth": 0.6,
                         "pdf.fonttype": 42, "ps.fonttype": 42, "figure.dpi": 100,
                         "legend.handlelength": 2.2, "legend.columnspacing": 1.0,
                         "legend.handletextpad": 0.5, "legend.labelspacing": 0.35})


def figure(height_in: float, nrows: int = 1, ncols: int = 1, width_in: float = COLUMN_IN,
           **kwargs):
    """A figure one column wide laid out by matplotlib's constrained layout (legends placed
    "outside" get their own room, nothing is cut off and the width stays exact)."""
    import matplotlib.pyplot as plt

    return plt.subplots(nrows, ncols, figsize=(width_in, height_in), layout="constrained",
                        **kwargs)


def legend_below(fig, handles, labels, max_ncol: int = 2, note: str = "") -> None:
    """The legend below the axes (never over the data), as many columns as fit the figure's
    width; ``note`` (e.g. which runs are not shown) is written above its entries."""
    import textwrap

    if not handles and not note:
        return
    fig_w = fig.get_figwidth() * fig.dpi
    # about 3.2 pt per character at 6 pt: a line of the note fits the column
    title = "\n".join(textwrap.wrap(note, int(fig.get_figwidth() * 72 / 3.3))) or None
    for ncol in range(min(max_ncol, max(len(handles), 1)), 0, -1):
        legend = fig.legend(handles, labels, loc="outside lower center", ncol=ncol,
                            frameon=False, title=title, title_fontsize=SMALL_PT - 0.5)
        width = legend.get_window_extent(fig.canvas.get_renderer()).width
        if width <= 0.98 * fig_w or ncol == 1:
            if title:
                legend.get_title().set_color("0.3")
            return
        legend.remove()


def fit_height(fig, axes_in: float) -> None:
    """Make the figure tall enough for ``axes_in`` of axes (with their titles and labels) plus
    its legend, so that the axes keep their size."""
    renderer = fig.canvas.get_renderer()
    extra = sum(a.get_window_extent(renderer).height for a in fig.legends)
    fig.set_figheight(axes_in + 0.75 + extra / fig.dpi)


def log_y(ax, axis: str = "y") -> None:
    """A log axis (``axis`` "y" or "x") labelled with plain numbers (0.2, 0.5, 1, 2 ...; 1,
    10, 100 ... over more than two decades). Call it after the limits are final."""
    import matplotlib.ticker as mticker

    getattr(ax, f"set_{axis}scale")("log")
    lo, hi = getattr(ax, f"get_{axis}lim")()
    target = ax.yaxis if axis == "y" else ax.xaxis
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        return  # nothing positive plotted: matplotlib's own ticks
    # the fewest ticks that still label at least two values inside the limits: 1-2-5 per
    # decade, else every digit (1000-4000 has only 2000 among 1-2-5); where the digits too
    # would give at most one tick inside, matplotlib's LogLocator itself places evenly spaced
    # linear ticks (1100-4500: 1500, 2000, ... 4500; 1.2-1.8: 1.2, 1.3, ...), so the
    # MaxNLocator below is a last resort only
    locator = None
    for subs in ((1.0,), (1.0, 2.0, 5.0), tuple(float(d) for d in range(1, 10))):
        if subs == (1.0,) and math.log10(hi / lo) <= 2.5:
            continue
        candidate = mticker.LogLocator(base=10, subs=subs)
        if sum(lo <= v <= hi for v in candidate.tick_values(lo, hi)) >= 2:
            locator = candidate
            break
    target.set_major_locator(locator or mticker.MaxNLocator(nbins=3))
    target.set_major_formatter(mticker.FuncFormatter(lambda v, _: f"{v:g}"))
    target.set_minor_formatter(mticker.NullFormatter())


def set_title(ax, text: str) -> None:
    """An axes title, wrapped to fit a column (long sequence names get a second line)."""
    import textwrap

    ax.set_title("\n".join(textwrap.wrap(text, 58)))


def slug(name: str) -> str:
    """A safe, readable file name: "Baker-Barry Tunnel (Empty)" -> "baker-barry-tunnel-empty"."""
    return re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-") or "unnamed"


#: ``save`` writes PNG only, and a PDF where one already exists (``for_the_page``)
_page_only = False


@contextmanager
def for_the_page():
    """Figures drawn for ``bench report``'s page: PNG (what the page shows), and a PDF only
    where the figure already has one (written by ``bench figures``: made again, so that no
    stale PDF stays beside a new PNG). Half the drawing: a PDF costs as much as its PNG and
    embedding the fonts more."""
    global _page_only
    before, _page_only = _page_only, True
    try:
        yield
    finally:
        _page_only = before


def save(fig, path_stem: Path) -> list[Path]:
    """Write ``path_stem``.pdf and .png atomically at the figure's exact size; returns both
    (in ``for_the_page``: the PNG, and the PDF only if it existed)."""
    import matplotlib.pyplot as plt

    from bench import guard

    planned = [path_stem.with_name(path_stem.name + f".{fmt}") for fmt in ("pdf", "png")]
    planned = [p for p in planned if not (p.suffix == ".pdf" and _page_only and not p.exists())]
    try:
        guard.make_folder(path_stem.parent)
        for path in planned:  # a user's own PNG / PDF of that name: refused before either is
            guard.regenerated_file(path, guard.derived, "a figure", "figure")  # written
        for path in planned:
            guard.savefig(fig, path, path.suffix[1:], guard.derived, "a figure", dpi=DPI)
    finally:
        plt.close(fig)
    return planned


#: the legends' note on the motion prior (``run_name`` marks only "no seed")
PRIOR_NOTE = ("With seed (each step starts from the previous motion, or the method's own "
              "model) unless marked (no seed).")


def run_name(run) -> str:
    """A run's legend name (a ``bench.runs.folders.RunRecord``): its table row's method name
    (or variant label) without the seed tag, "(no seed)" added when it ran without one. The
    tag is left out because a method's other priors are fixed by the method (no initial guess,
    own model) and with seed is the default (``PRIOR_NOTE``): a legend of short names fits two
    columns and takes a third of the height it took with the tables' full row names."""
    name = (run.label or display_name(run.method)) + overrides_note(getattr(run, "config", {}))
    if is_gt_assisted(getattr(run, "doppler_kind", None)):
        name += " [GT-assisted]"
    return f"{name} (no seed)" if Seed.of(run.seed) is Seed.WITHOUT else name


def run_order(run) -> tuple:
    """Runs in the tables' row order: the paper's methods, with seed before without."""
    return (order_key(run.method), run.method, Seed.of(run.seed).rank, run.label or "")


def div_labels(ax, items: list[tuple[float, float, str, int]], xytext: tuple[float, float],
               fontsize: float) -> list:
    """Draw one "Div." label per item (x, y [data], colour, count of diverged runs), "Div. (n)"
    in dark grey for several; labels whose boxes would touch are merged into one (at the
    first one's place, their counts added), so no two labels ever print over each other.
    Call it after the axes' limits and the figure's size are final. Returns the labels."""
    renderer = ax.figure.canvas.get_renderer()
    ax.get_xlim(), ax.get_ylim()  # the pending autoscale, now
    ax.apply_aspect()
    groups = [list(it) for it in sorted(items, key=lambda t: (t[0], t[1]))]
    while True:
        labels = [ax.annotate("Div." if n == 1 else f"Div. ({n})", (x, y), xytext=xytext,
                              textcoords="offset points", fontsize=fontsize,
                              color=c if n == 1 else "0.25", annotation_clip=False)
                  for x, y, c, n in groups]
        boxes = [a.get_window_extent(renderer).padded(1.0) for a in labels]
        clash = next(((i, j) for i in range(len(boxes)) for j in range(i + 1, len(boxes))
                      if boxes[i].overlaps(boxes[j])), None)
        if clash is None:
            return labels
        for a in labels:
            a.remove()
        i, j = clash
        groups[i][3] += groups[j][3]
        del groups[j]
