"""The forest plot's bookkeeping at unit level (bench.report.figures.forest), on hand-made rows:
which figure a row shows (a run's relative error at a length, its interval, whether it is
ranked: 2 or more independent segments), which lengths get a panel, the file stems, the
printed-digits rule of the marks and the U bounds. The drawing itself and the marks on real
run folders: tests/test_figures_forest.py."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from bench.report.figures.forest import (
    BOLD,
    UNDERLINED,
    UNMARKED,
    _ci,
    _entry,
    _tick_label,
    forest_panels,
    interval_tiers,
    plot_forest,
)


def _rel(length_m, n=5, rot=1.0, rot_ci=(0.8, 1.2), trans=0.1, trans_ci=(0.05, 0.15),
         n_independent=4):
    return SimpleNamespace(length_m=length_m, n=n, rot_deg_mean=rot, rot_deg_mean_ci=rot_ci,
                           trans_m_mean=trans, trans_m_mean_ci=trans_ci,
                           spread=SimpleNamespace(n_independent=n_independent))


def _row(method, rels, sequence="seq", sensor_class="radar", diverged=False, failed=False,
         label=None, seed=True):
    run = SimpleNamespace(method=method, seed=seed, label=None, config={}, doppler_kind=None)
    by_length = {r.length_m: r for r in rels}
    result = SimpleNamespace(relative_error=rels, relative=by_length.get)
    return SimpleNamespace(run=run, result=result, sequence=sequence, sensor_class=sensor_class,
                           diverged=diverged, failed=failed, label=label or method)


def test_an_interval_needs_both_ends_finite():
    assert _ci(1.0, 2.0) == (1.0, 2.0)
    for low, high in ((None, 2.0), (1.0, None), (math.nan, 2.0), (1.0, math.inf),
                      (None, None)):
        assert _ci(low, high) is None, (low, high)


def test_an_entry_shows_the_runs_figure_at_the_length():
    e = _entry(_row("doppler", [_rel(8.0, rot=1.5, rot_ci=(1.0, 2.0))]), "D", "rot_deg_mean",
               8.0)
    assert (e.name, e.value, e.low, e.high, e.status, e.rankable) == \
        ("D", 1.5, 1.0, 2.0, "", True)
    # one segment's figure is a figure (drawn), n = 0 is none ("-", named not drawn)
    assert _entry(_row("d", [_rel(8.0, n=1)]), "D", "rot_deg_mean", 8.0).status == ""
    for rels in ([_rel(8.0, n=0)], [_rel(16.0)], [_rel(8.0, rot=math.nan)]):
        assert _entry(_row("d", rels), "D", "rot_deg_mean", 8.0).status == "-"
    assert _entry(_row("d", [_rel(8.0)], diverged=True), "D", "rot_deg_mean",
                  8.0).status == "Div."
    # an interval with an end missing: the figure without a bar
    for ci in (None, (None, 1.0), (1.0, None)):
        e = _entry(_row("d", [_rel(8.0, rot_ci=ci)]), "D", "rot_deg_mean", 8.0)
        assert e.value == 1.0 and math.isnan(e.low) and math.isnan(e.high), ci


@pytest.mark.parametrize("n_independent, ranked", [(None, True), (1, False), (2, True),
                                                   (3, True)])
def test_a_figure_is_ranked_from_two_independent_segments(n_independent, ranked):
    e = _entry(_row("d", [_rel(8.0, n_independent=n_independent)]), "D", "rot_deg_mean", 8.0)
    assert e.rankable is ranked


def test_underlined_labels_are_mathtext_with_its_special_characters_replaced():
    assert _tick_label("a$b\\c{d}", UNDERLINED) == r"$\underline{\text{aSb/c(d)}}$"
    assert _tick_label("a$b", BOLD) == r"a\$b"
    assert _tick_label("a{b}", UNMARKED) == "a{b}"


def test_marks_compare_figures_as_printed():
    # no intervals: by value as printed, ties sharing
    assert interval_tiers([1.0001, 1.0004], [None] * 2, [None] * 2, [True] * 2)[0] == \
        [BOLD, BOLD]
    assert interval_tiers([1.0001, 1.0004], [None] * 2, [None] * 2, [True] * 2,
                          digits=4)[0] == [BOLD, UNDERLINED]


def test_a_figure_without_a_value_sets_no_bound_wherever_it_stands():
    marks, bounds = interval_tiers([math.nan, 1.0, 2.0], [math.nan, 0.9, 1.9],
                                   [math.nan, 1.1, 2.1], [True] * 3)
    assert marks == [UNMARKED, BOLD, UNDERLINED]
    assert bounds == [1.1, 2.1]


def test_panels_at_the_shortest_and_longest_lengths_with_segments():
    rows = [_row("doppler", [_rel(8.0, n=0), _rel(12.0, n=1), _rel(24.0), _rel(48.0, n=0)]),
            _row("icp-p2p", [_rel(16.0, rot=2.0, rot_ci=(1.9, 2.1)), _rel(32.0, n=2)])]
    (stem, panels), (stem2, panels2) = forest_panels(rows)
    assert (stem, stem2) == ("seq-rotation", "seq-translation")
    assert [p.length_m for p in panels] == [12.0, 32.0]  # n = 1 counts, n = 0 does not
    assert [e.status for e in panels[0].entries] == ["", "-"]  # icp-p2p: no figure at 12 m
    rows[0].result.relative_error[1].n = 5
    rows[1].result.relative_error[0].length_m = 12.0
    rows[1].result.relative = {12.0: rows[1].result.relative_error[0],
                               32.0: rows[1].result.relative_error[1]}.get
    (stem, panels), _ = forest_panels(rows)
    p = panels[0]
    assert (p.sequence, p.error, p.unit) == ("seq", "rotation", "deg")
    assert (panels2[0].error, panels2[0].unit) == ("translation", "m")
    assert [e.mark for e in p.entries] == [BOLD, UNDERLINED] and p.bounds == [1.2, 2.1]
    # distinct short names: the methods' legend names
    assert [e.name for e in p.entries] == ["Doppler Correspondence (Ours)", "ICP point-to-point"]


def test_a_sequence_without_segments_is_skipped_not_the_end():
    rows = [_row("doppler", [_rel(8.0, n=0)], sequence="empty"),
            _row("doppler", [_rel(8.0)], sequence="full"),
            _row("doppler", [_rel(8.0)], sequence="gone", failed=True)]
    assert [stem for stem, _ in forest_panels(rows)] == ["full-rotation", "full-translation"]


def test_two_rows_of_one_short_name_take_their_table_labels():
    rows = [_row("doppler", [_rel(8.0)], label="Doppler A"),
            _row("doppler", [_rel(8.0, rot=2.0)], label="Doppler B")]
    names = [e.name for e in forest_panels(rows)[0][1][0].entries]
    assert names == ["Doppler A", "Doppler B"]


def test_one_sequence_under_two_sensor_classes_names_its_class():
    rows = [_row("doppler", [_rel(8.0)], sensor_class="radar"),
            _row("doppler", [_rel(8.0)], sensor_class="lidar"),
            _row("doppler", [_rel(8.0)], sequence="other")]
    stems = [stem for stem, _ in forest_panels(rows)]
    assert stems == ["seq-radar-rotation", "seq-radar-translation", "seq-lidar-rotation",
                     "seq-lidar-translation", "other-rotation", "other-translation"]


def test_the_figures_are_written_under_forest(tmp_path):
    written = plot_forest([_row("doppler", [_rel(8.0)])], tmp_path)
    assert sorted(p.relative_to(tmp_path).as_posix() for p in written) == [
        "forest/seq-rotation.pdf", "forest/seq-rotation.png", "forest/seq-translation.pdf",
        "forest/seq-translation.png"]
    assert all(p.is_file() for p in written)


def _drawn(entries, bounds):
    import matplotlib

    matplotlib.use("Agg")
    from bench.report.figures.forest import Panel, draw_forest
    from bench.report.figures.style import use_paper_style

    use_paper_style()
    return draw_forest([Panel("a-long-sequence-name " * 4, "translation", "m", 48.0, entries,
                              bounds)])


def _dashes(line):
    # matplotlib keeps a line's dash pattern (offset, on-off) only privately; get_linestyle()
    # says "--" for every pattern
    return line._unscaled_dash_pattern


def test_the_legend_explains_the_lines_the_panel_draws():
    """The legend's two entries are the U lines as drawn (colour, width, dash pattern), named
    as the note below names them."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgba

    from bench.report.figures.forest import Entry

    entries = [Entry("A", SimpleNamespace(method="doppler", seed=True, label=None), 1.0, 0.8,
                     1.2, rankable=True, mark=BOLD),
               Entry("B", SimpleNamespace(method="gicp", seed=True, label=None), 1.5, 1.3,
                     1.7, rankable=True, mark=UNDERLINED)]
    fig = _drawn(entries, [1.2, 1.7])
    try:
        (ax,) = fig.axes
        u_lines = {float(line.get_xdata()[0]): line for line in ax.lines
                   if len(line.get_xdata()) == 2 and len(set(line.get_xdata())) == 1}
        (legend,) = fig.legends
        labels = [t.get_text() for t in legend.get_texts()]
        assert labels == ["U of bold", "U of underlined"]
        for handle, u in zip(legend.legend_handles, (1.2, 1.7), strict=True):
            line = u_lines[u]
            assert to_rgba(handle.get_color()) == to_rgba(line.get_color())
            assert handle.get_linewidth() == line.get_linewidth()
            assert _dashes(handle) == _dashes(line)
        assert _dashes(u_lines[1.2]) != _dashes(u_lines[1.7])  # dashed vs dotted
        assert to_rgba(u_lines[1.2].get_color()) == to_rgba("black")
        # a long title wrapped into lines of at most 52 characters, no word lost
        title = ax.get_title(loc="right")
        assert "\n" in title and all(len(x) <= 52 for x in title.split("\n"))
        expected = f"{'a-long-sequence-name ' * 4}, 48 m segments"
        assert "".join(title.split()) == "".join(expected.split())  # every character kept
    finally:
        plt.close(fig)


def test_rows_after_a_diverged_one_are_drawn_and_a_panel_of_diverged_rows_too():
    import matplotlib.pyplot as plt

    from bench.report.figures.forest import Entry

    run = SimpleNamespace(method="doppler", seed=True, label=None)
    fig = _drawn([Entry("A", run, status="Div."), Entry("B", run, 1.0, 0.9, 1.1, rankable=True,
                                                        mark=BOLD)], [1.1])
    try:
        drawn = [line for line in fig.axes[0].lines if list(line.get_ydata()) in ([1], [1, 1])]
        assert len(drawn) == 2  # row B (after the diverged row A): its bar and its dot
    finally:
        plt.close(fig)
    fig = _drawn([Entry("A", run, status="Div."), Entry("B", run, status="-")], [])
    try:
        assert [t.get_text() for t in fig.axes[0].texts] == ["Div.", "-"]
        assert not fig.axes[0].lines
    finally:
        plt.close(fig)


def test_a_dot_keeps_its_priors_marker_but_a_cross_which_cannot_be_hollow():
    """An unranked figure is a hollow dot: a run without a seed (whose prior's marker is a
    cross, which has no face) is drawn as a circle; other priors keep their marker."""
    import matplotlib.pyplot as plt

    from bench.report.figures.forest import Entry
    from bench.report.figures.style import prior_style

    seeded = SimpleNamespace(method="doppler", seed=True, label=None)
    unseeded = SimpleNamespace(method="doppler", seed=False, label=None)
    variant = SimpleNamespace(method="doppler", seed=True, label="a variant of the forest test")
    assert prior_style(unseeded)[1] == "x" and prior_style(variant)[1] not in ("o", "x")
    fig = _drawn([Entry("A", seeded, 1.0, 0.9, 1.1, rankable=True, mark=BOLD),
                  Entry("B", unseeded, 2.0, 1.9, 2.1, rankable=False),
                  Entry("C", variant, 3.0, 2.9, 3.1, rankable=True, mark=UNDERLINED)], [1.1])
    try:
        dots = {float(line.get_xdata()[0]): line.get_marker() for line in fig.axes[0].lines
                if len(line.get_xdata()) == 1}
        assert dots == {1.0: prior_style(seeded)[1], 2.0: "o", 3.0: prior_style(variant)[1]}
    finally:
        plt.close(fig)


def test_a_forest_is_as_tall_as_its_rows():
    """A panel's height grows with its rows (0.15 in each, at least 3 rows, plus its title and
    axis): a one-row and a twelve-row forest stay within a page, the taller by the rows."""
    import matplotlib.pyplot as plt

    from bench.report.figures.forest import Entry

    run = SimpleNamespace(method="doppler", seed=True, label=None)
    heights = []
    for n in (1, 12):
        fig = _drawn([Entry(f"M{i}", run, 1.0 + i, 0.9 + i, 1.1 + i, rankable=True)
                      for i in range(n)], [])
        heights.append(fig.get_figheight())
        plt.close(fig)
    assert 1.0 < heights[0] < 4.0 and heights[1] < 6.0
    assert heights[1] - heights[0] == pytest.approx((12 - 3) * 0.15, abs=0.05)
