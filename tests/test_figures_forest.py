"""Forest plots and the interval rule behind their marks (bench.report.figures.forest).

The rule: U = the smallest upper interval end among the ranked figures; bold = every ranked
figure whose value is at most U; the same among the rest gives underlined. Checked on cases
where other plausible rules differ (the best's interval overlapping a figure; a figure outside
its own interval; ties in value), on random columns for its two promises (no two figures marked
alike with disjoint intervals, equal values marked alike), and on run folders with known
intervals: the figure is written and what it draws (bold / underlined labels, the U lines)
follows the rule."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench.report.figures.forest import (
    BOLD,
    UNDERLINED,
    UNMARKED,
    draw_forest,
    forest_panels,
    interval_marks,
    interval_tiers,
    plot_forest,
)
from bench.report.tables.paper import runs as table_rows
from bench.runs.evaluate import evaluate_run
from bench.runs.folders import write_run
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult


def test_bold_is_every_figure_at_or_below_the_smallest_upper_end():
    # the best's interval [0.7, 1.3] overlaps the third's [1.1, 2.0], but 1.5 > U = 1.3: the
    # third is not bold (an "overlaps the best" rule would bold it), it is the rest's best
    values, lows, highs = [1.0, 1.2, 1.5], [0.7, 1.0, 1.1], [1.3, 1.4, 2.0]
    marks, bounds = interval_tiers(values, lows, highs, [True] * 3)
    assert marks == [BOLD, BOLD, UNDERLINED]
    assert bounds == [1.3, 2.0]


def test_the_smallest_upper_end_need_not_be_the_best_value():
    # the narrow interval of 1.1 sets U = 1.15; the wide 0.9 [0.2, 3.0] is below it: both bold,
    # 1.2 is not (it lies above U although its interval overlaps both)
    marks = interval_marks([0.9, 1.1, 1.2], [0.2, 1.05, 1.0], [3.0, 1.15, 1.4], [True] * 3)
    assert marks == [BOLD, BOLD, UNDERLINED]


def test_unranked_figures_take_no_part_and_no_mark():
    # the unranked 0.1 would set U = 0.2 and leave the others unmarked
    marks = interval_marks([0.1, 1.0, 2.0, math.nan], [0.0, 0.9, 1.9, math.nan],
                           [0.2, 1.1, 2.1, math.nan], [False, True, True, True])
    assert marks == [UNMARKED, BOLD, UNDERLINED, UNMARKED]


def test_a_figure_outside_its_interval_and_figures_without_one():
    # the interval is taken to hold its value: a lone figure above its interval is still bold
    assert interval_marks([2.0], [1.0], [1.5], [True]) == [BOLD]
    # no intervals (times): by value, ties sharing
    assert interval_marks([3.0, 1.0, 2.0, 1.0], [None] * 4, [None] * 4, [True] * 4) == \
        [UNMARKED, BOLD, UNDERLINED, BOLD]


def test_lists_of_different_lengths_are_refused():
    with pytest.raises(ValueError, match="3 values but 2 lows"):
        interval_marks([1.0, 2.0, 3.0], [0.0, 1.0], [2.0, 3.0, 4.0], [True] * 3)


def test_random_columns_keep_both_promises():
    rng = np.random.default_rng(4)
    for _ in range(400):
        n = int(rng.integers(2, 9))
        values = np.round(rng.uniform(0.5, 2.0, n), 1)  # rounded: ties in value occur
        lows = values - rng.uniform(0.0, 0.4, n)
        highs = values + rng.uniform(0.0, 0.4, n)
        rankable = rng.random(n) > 0.15
        marks = interval_marks(values.tolist(), lows.tolist(), highs.tolist(),
                               rankable.tolist())
        ranked = np.flatnonzero(rankable)
        if len(ranked):
            # the figure with the smallest upper end is always bold
            assert marks[ranked[np.argmin(highs[ranked])]] == BOLD
        for i in range(n):
            assert rankable[i] or marks[i] == UNMARKED
            for j in range(n):
                if marks[i] == marks[j] != UNMARKED:
                    assert lows[i] <= highs[j] and lows[j] <= highs[i], (values, i, j)
                if rankable[i] and rankable[j] and values[i] == values[j]:
                    assert marks[i] == marks[j]


# ---- run folders with known intervals ---------------------------------------------------------

#: (folder, method, seed, {length: (rotation mean, low, high)}) written into metrics.json
KNOWN = [("icp-p2p_seed", "icp-p2p", True, {8.0: (0.60, 0.55, 0.66), 48.0: (1.6, 1.3, 2.0)}),
         ("icp-p2p_noseed", "icp-p2p", False, {8.0: (0.30, 0.25, 0.35), 48.0: (2.0, 1.8, 2.2)}),
         ("gicp_seed", "gicp", True, {8.0: (0.33, 0.31, 0.36), 48.0: (0.95, 0.84, 1.08)}),
         ("doppler", "doppler", None, {8.0: (0.38, 0.36, 0.41), 48.0: (0.79, 0.64, 0.96)}),
         ("vgicp_seed", "vgicp", True, {8.0: (0.38, 0.37, 0.40), 48.0: (0.68, 0.59, 0.78)})]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("forest")
    gt = ground_truth(700)
    stamps = np.arange(len(gt)) / 10.0
    for k, (name, method, seed, known) in enumerate(KNOWN):
        est = noisy_estimate(gt, NoiseModel(), seed=k)
        frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(len(gt))]
        result = OdometryResult(stamps, est, frames)
        ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(8.0, 16.0, 48.0))
        config = {"method": method, "seed": seed, "label": None,
                  "sequence": {"name": "drive", "display_name": "drive",
                               "sensor_class": "Semi-Dense 4D Radar"}}
        metrics = {**ev.metrics, "sequence": "drive", "method": method, "seed": seed,
                   "frames": len(gt), "status": "done"}
        for rel in metrics["relative_error"]:  # the known figures and intervals
            if rel["length_m"] in known:
                value, low, high = known[rel["length_m"]]
                rel.update(rot_deg_mean=value, rot_deg_mean_ci=[low, high])
                rel["spread"] = {**rel["spread"], "n_independent": 8}
        write_run(root / "drive" / name, result, ev.gt, config, metrics)
    return root


def _expected(length):
    """The marks of the rotation column by the rule, every row on its own (as the tables)."""
    rows = {name: v[length] for name, _, _, v in KNOWN}
    names = list(rows)
    u = min(rows[n][2] for n in names)
    bold = {n for n in names if rows[n][0] <= u}
    rest = [n for n in names if n not in bold]
    u2 = min(rows[n][2] for n in rest)
    return u, u2, bold, {n for n in rest if rows[n][0] <= u2}


def test_the_figure_is_written_and_draws_the_rule(results, tmp_path):
    rows = table_rows(results)
    written = plot_forest(rows, tmp_path)
    names = sorted(p.name for p in written)
    assert names == ["drive-rotation.pdf", "drive-rotation.png", "drive-translation.pdf",
                     "drive-translation.png"]
    assert all(p.stat().st_size > 1000 for p in written)
    figures = dict(forest_panels(rows))
    panels = figures["drive-rotation"]
    assert [p.length_m for p in panels] == [8.0, 48.0]  # the shortest and the longest
    folder_of = {e.run.dir.name: e for e in panels[0].entries}
    assert list(folder_of) == [r.run.dir.name for r in rows]  # the table's order
    fig = draw_forest(panels)
    for ax, panel in zip(fig.axes, panels, strict=True):
        u, u2, bold, underlined = _expected(panel.length_m)
        lines = sorted(ln.get_xdata()[0] for ln in ax.get_lines()
                       if ln.get_linestyle() != "None" and len(set(ln.get_xdata())) == 1)
        assert lines == pytest.approx(sorted([u, u2]))  # the two U lines, where the rule says
        labels = ax.get_yticklabels()
        for label, entry in zip(labels, panel.entries, strict=True):
            folder = entry.run.dir.name
            assert (label.get_fontweight() == "bold") == (folder in bold), (panel.length_m,
                                                                           folder)
            assert label.get_text().startswith(r"$\underline") == (folder in underlined)
    # 8 m: vgicp and doppler share 0.38; the rule marks them alike
    at8 = {e.run.dir.name: e.mark for e in panels[0].entries}
    assert at8["vgicp_seed"] == at8["doppler"]
    # every row is marked on its own, as in the tables: the no-seed ICP row bold, the seed
    # row (0.60, above the underlined tier's U 0.40) unmarked
    assert at8["icp-p2p_noseed"] == BOLD and at8["icp-p2p_seed"] == UNMARKED


def test_a_diverged_run_is_named_not_ranked(results, tmp_path):
    bad = results / "drive" / "gicp_seed"
    data = json.loads((bad / "metrics.json").read_text())
    (bad / "metrics.json").write_text(json.dumps({**data, "diverged": True}))
    try:
        panels = dict(forest_panels(table_rows(results)))["drive-rotation"]
        gicp = next(e for e in panels[0].entries if e.run.method == "gicp")
        assert gicp.status == "Div." and gicp.mark == UNMARKED
        fig = draw_forest(panels)
        assert any(t.get_text() == "Div." for t in fig.axes[0].texts)
    finally:
        (bad / "metrics.json").write_text(json.dumps(data))


def test_the_legend_is_below_and_nothing_runs_off_the_figure(results):
    panels = dict(forest_panels(table_rows(results)))["drive-translation"]
    for p in panels:  # a long sequence name, as real ones are
        p.sequence = "Baker-Barry Tunnel (Vehicles) (synthetic), GT calibrated on frames 0-124"
    fig = draw_forest(panels)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    page = fig.bbox
    assert fig.legends
    for ax in fig.axes:
        assert ax.get_legend() is None
        for legend in fig.legends:
            assert not ax.get_window_extent(renderer).overlaps(legend.get_window_extent(renderer))
        for text in (ax.title, *ax.get_yticklabels()):
            box = text.get_window_extent(renderer)
            assert box.x0 >= page.x0 - 1 and box.x1 <= page.x1 + 1, text.get_text()


def test_one_method_keeps_a_readable_panel_with_its_value_inside_the_frame(results):
    """A sequence with one method: the layout does not collapse (one row's height left the
    axes no room, matplotlib gave up its layout and drew a sliver), each panel keeps a
    readable height and the value printed beside the bar lies inside the axes, not across its
    frame."""
    import warnings

    from bench.report.figures.style import use_paper_style

    use_paper_style()  # as plot_forest does (alone, this test would draw in matplotlib's style)
    rows = [r for r in table_rows(results) if r.run.dir.name == "doppler"]
    panels = dict(forest_panels(rows))["drive-rotation"]
    assert all(len(p.entries) == 1 for p in panels)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fig = draw_forest(panels)
        fig.canvas.draw()
    assert not [w for w in caught if "collapsed" in str(w.message)]
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        frame = ax.get_window_extent(renderer)
        assert frame.height >= 0.2 * fig.dpi
        values = [t for t in ax.texts if t.get_text().strip()[:1].isdigit()]
        assert values
        for t in values:
            box = t.get_window_extent(renderer)
            assert frame.y0 < box.y0 and box.y1 < frame.y1, (box, frame)
            assert box.x1 <= frame.x1 + 1, (box, frame)


def _panel_axes(entries, bounds, length_m=8.0):
    """draw_panel on its own axes, for a handmade panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench.report.figures.forest import Panel, draw_panel
    from bench.report.figures.style import use_paper_style

    use_paper_style()

    fig, ax = plt.subplots()
    draw_panel(ax, Panel("seq", "rotation", "deg", length_m, entries, bounds))
    return fig, ax


def _run(method="doppler", seed=True):
    from types import SimpleNamespace

    return SimpleNamespace(method=method, seed=seed, label=None)


def test_a_panel_draws_what_its_note_says():
    """The contract of one panel, read off its artists: one bar per interval at its row, the
    bold thickest and the unmarked thinnest; an unranked figure grey with a hollow dot; a
    diverged or empty row named, not drawn; U of bold dashed black, U of underlined dotted grey;
    the table's first row on top; bold labels bold, underlined ones underlined; every end and
    value inside the x range; the title names the sequence and the length, the axis the error
    and its unit."""
    from matplotlib.colors import to_rgba

    from bench.report.figures.forest import Entry
    from bench.report.figures.style import color

    entries = [Entry("A", _run(), 1.0, 0.8, 1.2, rankable=True, mark=BOLD),
               Entry("B", _run("icp-p2p"), 1.5, 1.3, 1.7, rankable=True, mark=UNDERLINED),
               Entry("C", _run("gicp"), 2.5, 2.2, 2.9, rankable=True, mark=UNMARKED),
               Entry("D", _run("vgicp"), 0.5, 0.1, 3.5, rankable=False, mark=UNMARKED),
               Entry("E$x", _run("kiss-icp"), status="Div.")]
    fig, ax = _panel_axes(entries, [1.2, 1.7])
    try:
        bars = {tuple(line.get_xdata()): line for line in ax.lines
                if len(line.get_xdata()) == 2 and line.get_linestyle() == "-"}
        assert set(bars) == {(0.8, 1.2), (1.3, 1.7), (2.2, 2.9), (0.1, 3.5)}
        assert [tuple(bars[k].get_ydata()) for k in ((0.8, 1.2), (1.3, 1.7), (2.2, 2.9))] == \
            [(0, 0), (1, 1), (2, 2)]
        widths = [bars[k].get_linewidth() for k in ((0.8, 1.2), (1.3, 1.7), (2.2, 2.9))]
        assert widths[0] > widths[1] > widths[2]
        assert to_rgba(bars[(0.8, 1.2)].get_color()) == to_rgba(color("doppler"))
        assert to_rgba(bars[(0.1, 3.5)].get_color()) == to_rgba("0.6")  # unranked: grey
        dots = {(float(line.get_xdata()[0]), float(line.get_ydata()[0])): line
                for line in ax.lines if len(line.get_xdata()) == 1}
        assert set(dots) == {(1.0, 0.0), (1.5, 1.0), (2.5, 2.0), (0.5, 3.0)}
        assert to_rgba(dots[(0.5, 3.0)].get_markerfacecolor()) == to_rgba("white")
        assert to_rgba(dots[(1.0, 0.0)].get_markerfacecolor()) == to_rgba(color("doppler"))
        # the diverged row: its status written at its row, nothing drawn there
        texts = {t.get_text().strip(): t for t in ax.texts}
        assert texts["Div."].get_position()[1] == 4
        assert not [line for line in ax.lines if 4 in list(line.get_ydata())]
        # every figure printed beside its bar, right of its interval's end
        for value, high, y in ((1.0, 1.2, 0), (2.5, 2.9, 2)):
            t = texts[f"{value:.3f}"]
            assert t.get_position() == (high, y)
        u_lines = [line for line in ax.lines if len(set(line.get_xdata())) == 1
                   and len(line.get_xdata()) == 2 and line.get_linestyle() != "-"]
        assert sorted(float(line.get_xdata()[0]) for line in u_lines) == [1.2, 1.7]
        bold_u = next(line for line in u_lines if line.get_xdata()[0] == 1.2)
        under_u = next(line for line in u_lines if line.get_xdata()[0] == 1.7)
        assert to_rgba(bold_u.get_color()) == to_rgba("black")
        assert to_rgba(under_u.get_color()) != to_rgba("black")
        low, high = ax.get_xlim()
        assert low < 0.1 and high > 3.5  # every end and value inside
        bottom, top = ax.get_ylim()
        assert top < 0 < 4 < bottom  # the first row on top, all five rows shown
        labels = ax.get_yticklabels()
        assert [label.get_fontweight() for label in labels].count("bold") == 1
        assert labels[0].get_fontweight() == "bold"
        assert r"\underline" in labels[1].get_text() and "B" in labels[1].get_text()
        assert labels[4].get_text() == r"E\$x"  # a dollar is no mathtext
        assert "seq" in ax.get_title(loc="right") and "8 m" in ax.get_title(loc="right")
        assert ax.get_xlabel() == "mean relative rotation error [deg]"
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_a_short_panel_keeps_three_rows_its_rows_centred():
    from bench.report.figures.forest import Entry

    fig, ax = _panel_axes([Entry("A", _run(), 1.0, 0.9, 1.1, rankable=True, mark=BOLD)], [1.1])
    try:
        bottom, top = ax.get_ylim()
        assert bottom - top == pytest.approx(3.0)  # the height of three rows
        assert (bottom + top) / 2 == pytest.approx(0.0)  # the one row in the middle
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)
