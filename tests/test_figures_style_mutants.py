"""bench/report/figures/style.py, what every figure relies on: one colour per method and one
line style / marker per motion prior (variants cycling through their own), markers spread
along a line, the paper's 6-7 pt fonts with embedded TrueType, one column wide, legends below
the axes in as many columns as fit (a note above them), log axes labelled with plain numbers,
wrapped titles, slug names, "Div." labels merged when they touch, legend names and row order,
and ``save`` writing PDF + PNG through the guard (a user's own file refused)."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

from bench.guard import Refused  # noqa: E402
from bench.report.figures import style  # noqa: E402
from bench.report.names import display_name, order_key  # noqa: E402
from methods.registry import Seed  # noqa: E402


def _run(method="icp-p2p", seed=True, label=None, config=None, doppler_kind=None):
    return SimpleNamespace(method=method, seed=seed, label=label, config=config or {},
                           doppler_kind=doppler_kind)


def test_line_of_a_run_has_its_methods_colour_and_its_priors_style():
    seed = style.line_kwargs(_run("gicp", True))
    noseed = style.line_kwargs(_run("gicp", False))
    assert seed["color"] == noseed["color"] == style.color("gicp")
    assert (seed["ls"], seed["marker"]) == ("-", "o")  # with seed: solid with circles
    assert (noseed["ls"], noseed["marker"]) == ("--", "x")  # no seed: dashed with crosses
    assert seed["mfc"] == "none"  # open circles, so lines on top of each other show
    assert noseed["mfc"] is None  # a cross has no face to leave open


@pytest.mark.parametrize("k, n, points, every", [(0, 1, None, (0.0, 0.1)),
                                                 (1, 2, None, (0.05, 0.1)),
                                                 (3, 4, None, (0.075, 0.1)),
                                                 (0, 3, 100, (0, 10)),
                                                 (1, 2, 100, (5, 10)),
                                                 (2, 3, 95, (6, 9)),
                                                 (1, 2, 5, (0, 1)),
                                                 (1, 0, None, (0.1, 0.1))])
def test_about_ten_markers_per_line_each_run_at_its_own_offset(k, n, points, every):
    """By axes distance a tenth apart, run k of n starting k / n of a tenth in; by index
    (``points``) every points // 10 (at least every point), run k of n k / n of that in."""
    got = style.line_kwargs(_run(), k, n, points)["markevery"]
    np.testing.assert_allclose(got, every)
    if points is not None:
        assert all(isinstance(v, int) for v in got)  # an index step, not a distance


def test_marker_and_line_sizes_are_the_papers():
    kw = style.line_kwargs(_run())
    np.testing.assert_allclose([kw["ms"], kw["mew"], kw["lw"]], [3.2, 0.8, 1.0])


def test_variants_get_their_own_styles_in_order_of_first_sight_and_cycle():
    labels = [f"mfig variant {k} {id(object())}" for k in range(len(style._VARIANT_STYLE) + 1)]
    first = style._variant_index.get(labels[0], len(style._variant_index))
    got = [style.prior_style(_run(label=lab)) for lab in labels]
    n = len(style._VARIANT_STYLE)
    assert got[:n] == [style._VARIANT_STYLE[(first + i) % n] for i in range(n)]
    assert got[n] == got[0]  # the seventh variant reuses the first one's style
    assert style.prior_style(_run(label=labels[3])) == got[3]  # the same in every figure
    assert style.prior_style(_run(seed=False)) == Seed.WITHOUT.style("icp-p2p")


def test_paper_style_fonts_are_6_to_7_pt_embedded_as_truetype():
    style.use_paper_style()
    rc = plt.rcParams
    assert matplotlib.get_backend().lower() == "agg"
    assert rc["font.size"] == rc["axes.titlesize"] == rc["axes.labelsize"] == 7
    assert rc["legend.fontsize"] == rc["xtick.labelsize"] == rc["ytick.labelsize"] == 6
    assert rc["pdf.fonttype"] == rc["ps.fonttype"] == 42  # journals want TrueType fonts
    assert rc["axes.grid"] is True


def test_figure_is_one_column_wide_with_constrained_layout():
    fig, axes = style.figure(2.0, 2, 1, sharex=True)
    try:
        np.testing.assert_allclose(fig.get_size_inches(), [3.5, 2.0])
        assert fig.get_layout_engine().__class__.__name__ == "ConstrainedLayoutEngine"
        assert len(axes) == 2 and axes[0].get_shared_x_axes().joined(axes[0], axes[1])
    finally:
        plt.close(fig)
    fig, ax = style.figure(1.0, width_in=7.0)
    np.testing.assert_allclose(fig.get_size_inches(), [7.0, 1.0])
    plt.close(fig)


def _handles(names):
    return [Line2D([], [], label=n) for n in names], list(names)


def test_legend_below_two_columns_of_short_names_with_the_note_above():
    style.use_paper_style()
    fig, ax = style.figure(2.0)
    handles, labels = _handles(["A", "B", "C"])
    note = style.PRIOR_NOTE  # 104 characters: two lines
    style.legend_below(fig, handles, labels, note=note)
    (legend,) = fig.legends
    assert legend._ncols == 2
    assert legend._loc == 8  # lower center ...
    assert legend._outside_loc == "lower"  # ... outside the axes
    assert not legend.get_frame_on()
    title = legend.get_title()
    rows = title.get_text().split("\n")
    assert " ".join(rows) == note and len(rows) == 2  # wrapped at 76 characters
    assert 70 < len(rows[0]) <= int(3.5 * 72 / 3.3)
    assert title.get_fontsize() == pytest.approx(5.5)
    assert matplotlib.colors.to_hex(title.get_color()) == matplotlib.colors.to_hex("0.3")
    plt.close(fig)


def test_legend_below_one_column_when_two_do_not_fit_and_three_columns_when_asked():
    style.use_paper_style()
    fig, ax = style.figure(2.0)
    long = ["a very long legend entry name that takes most of the column " + c for c in "ab"]
    style.legend_below(fig, *_handles(long))
    (legend,) = fig.legends
    assert legend._ncols == 1
    assert legend.get_title().get_text() == ""  # no note, no title
    plt.close(fig)
    fig, ax = style.figure(2.0)
    style.legend_below(fig, *_handles(["A", "B", "C", "D"]), max_ncol=3)
    assert fig.legends[0]._ncols == 3
    plt.close(fig)
    fig, ax = style.figure(2.0)
    style.legend_below(fig, *_handles(["A"]))
    assert fig.legends[0]._ncols == 1
    plt.close(fig)


def test_legend_below_with_nothing_to_say_adds_no_legend_but_a_note_alone_is_shown():
    fig, ax = style.figure(2.0)
    style.legend_below(fig, [], [])
    assert not fig.legends
    style.legend_below(fig, [], [], note="Not shown (diverged): X")
    (legend,) = fig.legends
    assert legend.get_title().get_text() == "Not shown (diverged): X"
    assert legend._ncols == 1
    plt.close(fig)


def test_fit_height_gives_the_axes_their_inches_plus_room_for_the_legend():
    fig, ax = style.figure(1.0)
    style.fit_height(fig, 2.0)
    assert fig.get_figheight() == pytest.approx(2.75)  # no legend: 0.75 in for labels
    style.legend_below(fig, *_handles(["A", "B", "C", "D", "E"]))
    renderer = fig.canvas.get_renderer()
    legend_in = fig.legends[0].get_window_extent(renderer).height / fig.dpi
    assert legend_in > 0.1
    style.fit_height(fig, 2.0)
    assert fig.get_figheight() == pytest.approx(2.75 + legend_in, rel=0.02)
    plt.close(fig)


def _log_axis(lo, hi, axis="y"):
    style.use_paper_style()
    fig, ax = style.figure(2.0)
    getattr(ax, f"set_{axis}scale")("log")
    getattr(ax, f"set_{axis}lim")(lo, hi)
    style.log_y(ax, axis)
    fig.canvas.draw()
    target = ax.yaxis if axis == "y" else ax.xaxis
    ticks = [v for v in target.get_majorticklocs() if lo <= v * (1 + 1e-9) and
             v <= hi * (1 + 1e-9)]
    texts = {t.get_text() for t in target.get_majorticklabels() if t.get_text()}
    minor = {t.get_text() for t in target.get_minorticklabels() if t.get_text()}
    plt.close(fig)
    return ticks, texts, minor


def test_log_axis_over_many_decades_is_labelled_at_the_decades_with_plain_numbers():
    ticks, texts, minor = _log_axis(0.001, 10.0)  # four decades: 1 per decade
    np.testing.assert_allclose(ticks, [0.001, 0.01, 0.1, 1.0, 10.0])
    assert {"0.001", "0.01", "0.1", "1", "10"} <= texts and not minor


def test_log_axis_over_two_decades_is_labelled_at_1_2_5():
    ticks, texts, _ = _log_axis(1.0, 100.0)
    np.testing.assert_allclose(ticks, [1, 2, 5, 10, 20, 50, 100])
    assert {"1", "2", "5", "10", "20", "50", "100"} <= texts


def test_log_axis_over_three_decades_is_labelled_at_the_decades():
    ticks, _, _ = _log_axis(1.0, 1000.0)  # three decades (> 2.5): decades only
    np.testing.assert_allclose(ticks, [1, 10, 100, 1000])


def test_log_x_axis_is_labelled_like_the_y_axis():
    ticks, texts, _ = _log_axis(10.0, 1000.0, "x")
    np.testing.assert_allclose(ticks, [10, 20, 50, 100, 200, 500, 1000])
    assert {"10", "100", "1000"} <= texts


def test_log_axis_inside_one_digit_step_gets_plain_evenly_spaced_values():
    ticks, texts, _ = _log_axis(2100.0, 2900.0)
    assert len(ticks) >= 2 and all(float(t).is_integer() for t in texts if t)


def test_log_axis_with_nothing_positive_keeps_matplotlibs_ticks():
    fig, ax = style.figure(2.0)
    ax.set_yscale("log")
    ax.get_ylim = lambda: (0.0, 1.0)  # nothing positive plotted
    style.log_y(ax)
    assert ax.get_yscale() == "log"
    assert not isinstance(ax.yaxis.get_major_formatter(), FuncFormatter)
    ax.get_ylim = lambda: (1.0, float("inf"))
    style.log_y(ax)
    assert not isinstance(ax.yaxis.get_major_formatter(), FuncFormatter)
    plt.close(fig)


def test_titles_wrap_at_58_characters():
    fig, ax = style.figure(2.0)
    text = "Baker-Barry Tunnel (Empty) " * 4
    style.set_title(ax, text)
    rows = ax.get_title().split("\n")
    assert len(rows) == 2 and max(len(r) for r in rows) <= 58
    assert " ".join(rows) == text.strip()
    style.set_title(ax, "x" * 58)
    assert ax.get_title() == "x" * 58
    plt.close(fig)


def test_slug_keeps_letters_and_digits_only():
    assert style.slug("A_b.C 9") == "a-b-c-9"
    assert style.slug("--x--") == "x"
    assert style.slug("") == "unnamed"


def test_run_name_marks_no_seed_overrides_and_gt_assisted():
    assert style.run_name(_run("gicp", None)) == display_name("gicp")
    config = {"method": {"given": {"max_iterations": 3}}}
    assert style.run_name(_run("gicp", False, config=config)) == \
        f"{display_name('gicp')} [max_iterations=3] (no seed)"
    assert style.run_name(_run("gicp", True, doppler_kind="gt-reconstructed")) == \
        f"{display_name('gicp')} [GT-assisted]"
    assert style.run_name(_run("gicp", True, label="ablation")) == "ablation"
    bare = SimpleNamespace(method="gicp", seed=True, label=None)  # no config, no kind
    assert style.run_name(bare) == display_name("gicp")
    assert "(no seed)" in style.PRIOR_NOTE and "With seed" in style.PRIOR_NOTE


def test_runs_are_in_the_tables_order_seed_before_no_seed_then_label():
    runs = [_run("gicp", False), _run("gicp", True, label="b"), _run("doppler", None),
            _run("gicp", True), _run("gicp", True, label="a")]
    ordered = sorted(runs, key=style.run_order)
    assert order_key("doppler") != order_key("gicp")
    first, second = sorted(["doppler", "gicp"], key=order_key)
    got = [(r.method, Seed.of(r.seed), r.label) for r in ordered]
    gicp = [(("gicp"), Seed.WITH, None), ("gicp", Seed.WITH, "a"), ("gicp", Seed.WITH, "b"),
            ("gicp", Seed.WITHOUT, None)]
    doppler = [("doppler", Seed.NONE, None)]
    assert got == (doppler + gicp if first == "doppler" else gicp + doppler)
    assert style.run_order(_run("gicp", True))[1] == "gicp"


def test_div_labels_are_one_per_item_coloured_or_merged_grey_when_they_touch():
    fig, ax = plt.subplots(figsize=(3.5, 2.0))
    ax.plot([0, 100], [0, 10])
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 10)
    labels = style.div_labels(ax, [(90.0, 5.0, "#123456", 1), (10.0, 5.0, "#654321", 2)],
                              (2, 2), 6)
    assert [a.get_text() for a in labels] == ["Div. (2)", "Div."]  # sorted by x
    assert labels[0].xy == (10.0, 5.0) and labels[1].xy == (90.0, 5.0)
    assert matplotlib.colors.to_hex(labels[1].get_color()) == "#123456"
    assert matplotlib.colors.to_hex(labels[0].get_color()) == matplotlib.colors.to_hex("0.25")
    assert labels[0].get_fontsize() == 6
    assert labels[0].xyann == (2, 2) and labels[0].anncoords == "offset points"
    assert labels[0].get_annotation_clip() is False
    assert len(ax.texts) == 2
    # three labels at one place: merged into one at the first's place, counts added
    fig2, ax2 = plt.subplots(figsize=(3.5, 2.0))
    ax2.set_xlim(0, 100)
    ax2.set_ylim(0, 10)
    merged = style.div_labels(ax2, [(50.2, 5.0, "C1", 1), (50.0, 5.0, "C0", 1),
                                    (50.1, 5.0, "C2", 3)], (2, 2), 6)
    assert [a.get_text() for a in merged] == ["Div. (5)"] and merged[0].xy == (50.0, 5.0)
    assert len(ax2.texts) == 1
    assert style.div_labels(ax2, [], (2, 2), 6) == []
    plt.close(fig)
    plt.close(fig2)


def test_save_writes_pdf_and_png_through_the_guard_and_closes_the_figure(tmp_path):
    fig, ax = style.figure(1.0)
    ax.plot([0, 1], [0, 1])
    paths = style.save(fig, tmp_path / "sub" / "name")
    assert paths == [tmp_path / "sub" / "name.pdf", tmp_path / "sub" / "name.png"]
    assert all(p.stat().st_size > 0 for p in paths)
    assert (tmp_path / "sub" / "name.pdf").read_bytes().startswith(b"%PDF")
    assert not plt.fignum_exists(fig.number)
    fig, ax = style.figure(1.0)
    assert style.save(fig, tmp_path / "sub" / "name") == paths  # its own files: made again


def test_save_refuses_a_users_own_file_of_that_name_and_writes_neither(tmp_path):
    own = tmp_path / "fig.png"
    own.write_bytes(b"my holiday photo")
    fig, ax = style.figure(1.0)
    with pytest.raises(Refused, match="fig.png: exists and is not a figure"):
        style.save(fig, tmp_path / "fig")
    assert own.read_bytes() == b"my holiday photo"
    assert not (tmp_path / "fig.pdf").exists()  # refused before either is written
    assert not plt.fignum_exists(fig.number)  # closed all the same


def test_for_the_page_restores_the_mode_after_an_error(tmp_path):
    with pytest.raises(RuntimeError), style.for_the_page():
        assert style._page_only
        raise RuntimeError
    assert not style._page_only
    with style.for_the_page():
        fig, _ = style.figure(1.0)
        assert style.save(fig, tmp_path / "page") == [tmp_path / "page.png"]
    assert not (tmp_path / "page.pdf").exists()


# -- what the first mutation run left -----------------------------------------------------------

def test_colour_is_the_registrys_and_differs_between_methods():
    from methods import registry

    assert style.color("gicp") == registry.color("gicp") != style.color("doppler")


def test_figure_with_several_columns_of_axes():
    fig, axes = style.figure(3.9, 3, 2)
    assert axes.shape == (3, 2)
    plt.close(fig)


def test_note_wraps_at_76_characters_of_a_column():
    fig, ax = style.figure(2.0)
    note = "a" * 70 + " " + "b" * 6  # 77 characters: one too many for a line
    style.legend_below(fig, *_handles(["A"]), note=note)
    assert fig.legends[0].get_title().get_text() == "a" * 70 + "\n" + "b" * 6
    plt.close(fig)


def test_default_marker_offset_and_a_run_given_without_its_count():
    assert style.line_kwargs(_run())["markevery"] == (0.0, 0.1)
    np.testing.assert_allclose(style.line_kwargs(_run(), 1)["markevery"], (0.1, 0.1))
    assert style.line_kwargs(_run(), 1, 0, 100)["markevery"] == (10, 10)


@pytest.mark.parametrize("lo, hi, want", [
    (1.0, 3.0, [1.0, 2.0]),  # two of 1-2-5 inside, the limits themselves counted
    (0.3, 1.0, [0.5, 1.0]),
    (900.0, 1900.0, [900.0, 1000.0]),  # only 1000 of 1-2-5: every digit
    (1.0, 10**2.5, [1, 2, 5, 10, 20, 50, 100, 200]),  # 2.5 decades: still 1-2-5
])
def test_log_axis_ticks_follow_the_rule_at_its_edges(lo, hi, want):
    if hi == 10**2.5:
        assert np.log10(hi / lo) == 2.5  # exactly at the switch to decades
    ticks, _, _ = _log_axis(lo, hi)
    np.testing.assert_allclose(ticks, want)


def test_own_model_prior_and_a_run_without_a_label_attribute():
    own = SimpleNamespace(method="kiss-icp", seed=True)  # no label attribute at all
    assert style.prior_style(own) == Seed.WITH.style("kiss-icp")
    assert style.prior_style(own)[1] != Seed.WITH.style("icp-p2p")[1]  # its own marker


def test_an_unlabelled_run_comes_before_its_labelled_variants():
    runs = [_run("gicp", True, label="ABC"), _run("gicp", True)]
    assert [r.label for r in sorted(runs, key=style.run_order)] == [None, "ABC"]


def test_div_labels_at_one_x_are_ordered_by_height():
    fig, ax = plt.subplots(figsize=(3.5, 2.0))
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 10)
    labels = style.div_labels(ax, [(50.0, 8.0, "#000001", 1), (50.0, 1.0, "#fffffe", 1)],
                              (2, 2), 6)
    assert [a.xy for a in labels] == [(50.0, 1.0), (50.0, 8.0)]
    plt.close(fig)


def test_refusal_names_the_figure_and_the_png_is_saved_at_300_dpi(tmp_path):
    from matplotlib.image import imread

    own = tmp_path / "fig.pdf"
    own.write_bytes(b"%PDF my paper")
    fig, _ = style.figure(1.0)
    with pytest.raises(Refused) as err:
        style.save(fig, tmp_path / "fig")
    assert str(err.value).startswith(f"figure {own}: exists and is not a figure this command")
    fig, _ = style.figure(1.0)
    other, _ = style.figure(1.0)  # the current figure is another one: it stays open
    (_, png) = style.save(fig, tmp_path / "ok")
    assert imread(png).shape[:2] == (300, round(3.5 * 300))
    assert plt.fignum_exists(other.number) and not plt.fignum_exists(fig.number)
    plt.close(other)


def test_titles_break_a_word_longer_than_58_characters():
    fig, ax = style.figure(2.0)
    style.set_title(ax, "x" * 59)
    assert ax.get_title() == "x" * 58 + "\nx"
    plt.close(fig)
