"""bench/report/figures/errors.py, what a reader takes from the error and timing figures:
errors along the path known by hand (a path sliding 0.1 m sideways per metre, a heading turning
1 deg per frame), log limits with headroom from the runs that held, a diverged run drawn up to
the top with a mark and a "Div." label; box plots per sensor class with one box per run name at
its own offset, in its method's colour, hatched without seed, medians and 5-95 % whiskers of
the segment errors, only lengths with segments, diverged runs named under the figure; time and
correspondences per frame (frame 0 and non-positive values not drawn); bench speed's curves
with their bands, and a CSV that is not one refused with the columns it needs."""

from __future__ import annotations

import matplotlib.colors as mcolors
import numpy as np
import pytest

import bench.report.figures.errors as errors
from bench.report.figures.style import PRIOR_NOTE, SMALL_PT, color
from bench.report.names import display_name
from bench.runs.folders import load_runs
from helpers_figure_runs import capture, lines_by_label, rot_z, straight, write_run
from loaders.errors import DataError
from metrics.relative import segment_errors

ICP, GICP = display_name("icp-p2p"), display_name("gicp")


def _sliding(n: int, per_m: float = 0.1) -> np.ndarray:
    est = straight(n)
    est[:, 1, 3] = per_m * np.arange(n)
    return est


def _turning(n: int) -> np.ndarray:
    est = straight(n)
    for k in range(n):
        est[k, :3, :3] = rot_z(float(k))
    return est


def _bending(n: int) -> np.ndarray:
    est = straight(n)
    est[:, 1, 3] = 0.01 * np.arange(n) ** 2  # segment errors grow along the path
    return est


def _diverging(n: int) -> np.ndarray:
    est = straight(n)
    est[:, 1, 3] = 0.5 * np.arange(n) ** 2
    return est


def _hex(c) -> str:
    return mcolors.to_hex(c)


# -- errors along the path ---------------------------------------------------------------------

def test_errors_along_the_path_by_hand(tmp_path):
    gt = straight(11)
    write_run(tmp_path, "s", "icp-p2p", True, gt, _sliding(11))
    write_run(tmp_path, "s", "gicp", True, gt, _turning(11))
    runs = {r.method: r for r in load_runs(tmp_path)}
    dist, trans, rot = errors._errors_along_path(runs["icp-p2p"])
    np.testing.assert_allclose(dist, np.arange(1, 11))  # frames after the first
    np.testing.assert_allclose(trans, 0.1 * np.arange(1, 11), atol=1e-6)
    np.testing.assert_allclose(rot, 0.0, atol=1e-4)
    dist, trans, rot = errors._errors_along_path(runs["gicp"])
    np.testing.assert_allclose(trans, 0.0, atol=1e-6)  # same positions, turned
    np.testing.assert_allclose(rot, np.arange(1, 11), atol=1e-4)


@pytest.mark.parametrize("values, lo, hi", [
    ([np.array([0.1, 2.0])], 0.1 / 1.5, 6.0),  # 3 x the largest above, the smallest / 1.5
    ([np.array([0.5, 0.0, np.nan]), np.array([np.inf, 1.0])], 0.5 / 1.5, 5.0),
    ([np.array([1e-9, 1.0])], 1e-5 / 1.5, 3.0),  # at most five decades below the largest
    ([np.array([1.0, 1.0])], 1.0 / 1.5, 10.0),  # at least a decade
    ([np.array([0.0, -1.0])], 1e-3, 1.0),  # nothing positive
    ([], 1e-3, 1.0),
])
def test_log_limits(values, lo, hi):
    got = errors._log_limits(values)
    np.testing.assert_allclose(got, (lo, hi))


def test_error_along_path_figure(tmp_path, monkeypatch):
    gt = straight(21)
    root = tmp_path / "r"
    write_run(root, "seq A", "icp-p2p", True, gt, _sliding(21))
    write_run(root, "seq A", "icp-p2p", False, gt, _sliding(21, 0.05))
    write_run(root, "seq A", "gicp", True, gt, _diverging(21), diverged=True)
    runs = load_runs(root)
    figs = capture(monkeypatch, errors, write=True)
    paths = errors.plot_error_along_path(runs, tmp_path / "out")
    assert paths == [tmp_path / "out" / "error-along-path" / f"seq-a.{x}" for x in
                     ("pdf", "png")]
    ((_, fig),) = figs
    top, bottom = fig.axes
    lines = lines_by_label(top)
    assert set(lines) == {ICP, f"{ICP} (no seed)", f"{GICP} - Div."}
    np.testing.assert_allclose(lines[ICP].get_xdata(), np.arange(1, 21))
    np.testing.assert_allclose(lines[ICP].get_ydata(), 0.1 * np.arange(1, 21), atol=1e-6)
    np.testing.assert_allclose(lines[f"{ICP} (no seed)"].get_ydata(), 0.05 * np.arange(1, 21),
                               atol=1e-6)
    # limits from the runs that held: 0.05 m .. 2 m, with headroom
    lo, hi = 0.05 / 1.5, 2.0 * 3
    np.testing.assert_allclose(top.get_ylim(), (lo, hi), rtol=1e-5)
    assert top.get_yscale() == bottom.get_yscale() == "log"
    # the diverged run: errors 0.5 k^2 m, above 6 m from frame 4: drawn to there, at the top
    div = lines[f"{GICP} - Div."]
    np.testing.assert_allclose(div.get_xdata(), [1, 2, 3, 4])
    np.testing.assert_allclose(div.get_ydata(), [0.5, 2.0, 4.5, hi], rtol=1e-5)
    assert div.get_color() == color("gicp") and div.get_linestyle() == "-"
    assert top.get_shared_x_axes().joined(top, bottom)
    (mark,) = [m for m in top.get_lines() if m.get_marker() == "^"]
    np.testing.assert_allclose(mark.get_xydata(), [[4.0, hi]], rtol=1e-6)
    assert mark.get_color() == color("gicp") and mark.get_clip_on() is False
    (label,) = top.texts
    assert label.get_text() == "Div." and label.xy == (4.0, hi)
    assert _hex(label.get_color()) == _hex(color("gicp"))
    assert label.get_fontsize() == SMALL_PT - 0.5 and label.xyann == (4, -7)
    # the rotation panel: no rotation error is drawn (zeros are not on a log axis)
    assert np.all(np.isnan(lines_by_label(bottom)[ICP].get_ydata()) |
                  (lines_by_label(bottom)[ICP].get_ydata() < 1e-3))
    assert lines[ICP].get_markevery() == (0, 2)  # 20 points: every second, run 0 of 3
    assert top.get_ylabel() == "translation error [m]"
    assert bottom.get_ylabel() == "rotation error [deg]"
    assert bottom.get_xlabel() == "distance travelled [m]"
    assert top.get_title() == "seq A: error along the path"
    (legend,) = fig.legends
    assert len(legend.get_texts()) == 3
    assert " ".join(legend.get_title().get_text().split("\n")) == PRIOR_NOTE


def test_when_every_run_diverged_the_axes_hold_them_all(tmp_path, monkeypatch):
    gt = straight(11)
    write_run(tmp_path, "s", "gicp", True, gt, _sliding(11), diverged=True)
    figs = capture(monkeypatch, errors)
    errors.plot_error_along_path(load_runs(tmp_path), tmp_path / "out")
    ((_, fig),) = figs
    np.testing.assert_allclose(fig.axes[0].get_ylim(), (0.1 / 1.5, 3.0), rtol=1e-5)
    assert not fig.axes[0].texts


def test_no_error_figure_without_two_poses_and_sequences_in_order(tmp_path, monkeypatch):
    capture(monkeypatch, errors)
    gt = straight(11)
    for seq in ("run10", "run2"):
        write_run(tmp_path, seq, "gicp", True, gt, gt)
    write_run(tmp_path, "one", "gicp", True, gt[:1], gt[:1])
    write_run(tmp_path, "two", "gicp", True, gt[:2], gt[:2])  # two poses: a figure
    paths = errors.plot_error_along_path(load_runs(tmp_path), tmp_path / "out")
    assert [p.name for p in paths] == ["run2.pdf", "run2.png", "run10.pdf", "run10.png",
                                       "two.pdf", "two.png"]


def test_exact_estimates_draw_no_error_and_exits_cluster_by_distance(tmp_path, monkeypatch):
    """An estimate equal to the ground truth has no error to draw on a log axis (NaN, not 0);
    two runs leaving 3 m apart along a 20 m path (more than 6 % of it) get a label each."""
    gt = straight(21)
    write_run(tmp_path, "s", "icp-p2p", True, gt, gt)
    late = _diverging(21)
    late[:, 1, 3] = 0.5 * np.maximum(np.arange(21) - 3, 0) ** 2  # leaves 3 m later
    write_run(tmp_path, "s", "gicp", True, gt, _diverging(21), diverged=True)
    write_run(tmp_path, "s", "vgicp", True, gt, late, diverged=True)
    figs = capture(monkeypatch, errors)
    errors.plot_error_along_path(load_runs(tmp_path), tmp_path / "out")
    ((_, fig),) = figs
    for ax in fig.axes:
        assert np.all(np.isnan(lines_by_label(ax)[ICP].get_ydata()))
    # nothing held with an error: limits 0.001-1 m, so the runs leave at 2 m and 5 m
    assert sorted((t.get_text(), t.xy[0]) for t in fig.axes[0].texts) == [("Div.", 2.0),
                                                                          ("Div.", 5.0)]


def test_runs_leaving_at_about_one_distance_share_one_label():
    """Exits within 6 % of the path of the first of a cluster share one label (0 and 5 m of
    100 m; 10 m is 6 % past the first, not the last); the labels are far apart on a 7 in wide
    axes, so none is merged for touching."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 2.0))
    ax.set_xlim(0, 100)
    ax.set_ylim(0.01, 1.0)
    ax.set_yscale("log")
    errors.label_divergence(ax, [(60.0, "#00ff00"), (5.0, "#ff0000"), (0.0, "#0000ff"),
                                 (10.0, "#000000")], 1.0, 100.0)
    got = sorted((t.xy, t.get_text(), _hex(t.get_color())) for t in ax.texts)
    assert got == [((0.0, 1.0), "Div. (2)", _hex("0.25")), ((10.0, 1.0), "Div.", "#000000"),
                   ((60.0, 1.0), "Div.", "#00ff00")]
    plt.close(fig)


# -- box plots ---------------------------------------------------------------------------------

#: the method of the box plots: not matplotlib's default first colour (a box without its
#: method's colour would show)
VG = display_name("vgicp")


@pytest.fixture
def box_runs(tmp_path):
    """A 200 m path (8 m segments: 193, so the 5th and 6th percentile fall on different
    segments) with a bending estimate; a sliding one without seed; diverged ones."""
    gt = straight(201)
    root = tmp_path / "r"
    write_run(root, "seq A", "vgicp", True, gt, _bending(201), lengths=(8.0, 16.0, 640.0))
    write_run(root, "seq A", "vgicp", False, gt, _sliding(201), lengths=(8.0,))
    write_run(root, "seq A", "gicp", True, gt, _diverging(201), diverged=True,
              lengths=(8.0, 16.0))
    write_run(root, "seq B (synthetic)", "gicp", True, gt[:41], _diverging(41), diverged=True,
              sensor_class="Sparse 4D Radar", lengths=(8.0,))
    write_run(root, "seq B (synthetic)", "vgicp", True, gt[:41], _turning(41),
              sensor_class="Sparse 4D Radar", lengths=(8.0,))
    return load_runs(root)


def _box_extent(box) -> tuple[float, float, float, float]:
    xy = box.get_path().vertices
    return xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()


def test_box_plots_per_class_one_box_per_run_name(box_runs, tmp_path, monkeypatch):
    figs = capture(monkeypatch, errors)
    paths = errors.plot_boxplots(box_runs, tmp_path / "out")
    # classes in the paper's order: the sparse radar first
    assert [p.relative_to(tmp_path / "out").as_posix() for p in paths] == [
        "boxplots/sparse-4d-radar.pdf", "boxplots/sparse-4d-radar.png",
        "boxplots/dense-4d-lidar.pdf", "boxplots/dense-4d-lidar.png"]
    (_, radar), (_, lidar) = figs
    assert radar.axes[0].get_title() == "Sparse 4D Radar (synthetic): relative error"
    assert lidar.axes[0].get_title() == "Dense 4D LiDAR: relative error"
    top, bottom = lidar.axes
    # lengths scored by a run that held: 8 and 16 m; 640 m (listed, no segment on 200 m) is not
    assert [t.get_text() for t in bottom.get_xticklabels()] == ["8", "16"]
    assert list(bottom.get_xticks()) == [0, 1]
    assert bottom.get_xlim() == (-0.5, 1.5)
    assert bottom.get_xlabel() == "segment length [m]"
    assert top.get_ylabel() == "translation error [m]"
    assert bottom.get_ylabel() == "rotation error [deg]"
    assert top.get_yscale() == bottom.get_yscale() == "log"
    # one box per run name and length: seed at -0.21, no seed at +0.21 (width 0.84 / 2)
    boxes = [p for p in top.patches]
    assert len(boxes) == 4  # both at 8 and 16 m (every run's segments at every slot's length)
    ext = [_box_extent(b) for b in boxes]
    centres = sorted(round((e[0] + e[1]) / 2, 6) for e in ext if np.all(np.isfinite(e)))
    np.testing.assert_allclose(centres, [-0.21, 0.21, 0.79, 1.21])
    seed_centres = sorted(round((e[0] + e[1]) / 2, 6) for b, e in zip(boxes, ext, strict=True)
                          if not b.get_hatch())
    np.testing.assert_allclose(seed_centres, [-0.21, 0.79])  # the first name on the left
    assert top.get_shared_x_axes().joined(top, bottom)
    widths = [e[1] - e[0] for e in ext if np.all(np.isfinite(e))]
    np.testing.assert_allclose(widths, 0.42 * 0.85)
    seed_boxes = [b for b in boxes if not b.get_hatch()]
    noseed_boxes = [b for b in boxes if b.get_hatch()]
    assert len(seed_boxes) == len(noseed_boxes) == 2
    assert {_hex(b.get_facecolor()) for b in boxes} == {_hex(color("vgicp"))}
    assert {b.get_hatch() for b in noseed_boxes} == {"//////"}
    # medians and whiskers of the segment errors (5-95 %), no fliers
    run = next(r for r in box_runs if r.method == "vgicp" and r.seed.option is True
               and r.sensor_class == "Dense 4D LiDAR")
    seg = segment_errors(run.gt, run.est, 8.0).trans_m
    medians = [line for line in top.get_lines() if _hex(line.get_color()) == "#000000"]
    got = sorted(float(np.mean(m.get_ydata())) for m in medians)
    assert any(np.isclose(g, np.median(seg), rtol=1e-6) for g in got)
    wy = sorted(float(y) for line in top.get_lines() for y in line.get_ydata()
                if np.isfinite(y))
    # whiskers end at the outermost segments inside the 5-95 % percentiles
    lo, hi = np.percentile(seg, [5, 95])
    ends = (seg[seg >= lo].min(), seg[seg <= hi].max())
    for end in ends:
        assert any(np.isclose(y, end, rtol=1e-6) for y in wy), end
    assert seg.min() < ends[0] and ends[1] < seg.max()  # not the extremes
    for ax in (top, bottom):  # grid lines across (error levels), none between boxes
        assert ax.yaxis.get_gridlines()[0].get_visible()
        assert not any(g.get_visible() for g in ax.xaxis.get_gridlines())
    legend_in = lidar.legends[0].get_window_extent(lidar.test_renderer).height / lidar.dpi
    assert lidar.get_figheight() == pytest.approx(2.6 + 0.75 + legend_in, abs=0.02)
    assert not top.collections
    assert not [line for line in top.get_lines()  # no fliers: no markers at all
                if line.get_marker() not in (None, "None", "", " ") and len(line.get_xdata())]
    assert [round(line.get_xdata()[0], 6) for line in top.get_lines()
            if line.get_linestyle() == "-" and _hex(line.get_color()) == _hex("0.8")] == [0.5]
    legend = lidar.legends[0]
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts == [VG, f"{VG} (no seed)"]
    assert [h.get_hatch() for h in legend.legend_handles] == [None, "//////"] or \
        [bool(h.get_hatch()) for h in legend.legend_handles] == [False, True]
    assert [_hex(h.get_facecolor()) for h in legend.legend_handles] == [
        _hex(color("vgicp"))] * 2
    note = " ".join(legend.get_title().get_text().split("\n"))
    assert note == ("Boxes: quartiles and median; whiskers: 5-95 %; the class's sequences "
                    f"pooled. {PRIOR_NOTE} Not shown (diverged): {GICP} on seq A")


def test_box_plots_of_errors_all_exactly_zero_are_drawn_not_a_crash(tmp_path, monkeypatch):
    """An estimate equal to the ground truth (every segment error exactly 0, none on a log
    axis): both panels are drawn empty over 0.001-1, where ``bench figures`` stopped with
    matplotlib's "Data cannot be log-scaled" ValueError."""
    gt = straight(11)
    write_run(tmp_path, "s", "gicp", True, gt, gt, lengths=(8.0,))
    figs = capture(monkeypatch, errors)
    paths = errors.plot_boxplots(load_runs(tmp_path), tmp_path / "out")
    assert [p.name for p in paths] == ["dense-4d-lidar.pdf", "dense-4d-lidar.png"]
    ((_, fig),) = figs
    for ax in fig.axes:
        assert ax.get_yscale() == "log"
        np.testing.assert_allclose(ax.get_ylim(), (1e-3, 1.0))


def test_class_with_no_segments_gets_no_box_plot(tmp_path, monkeypatch):
    capture(monkeypatch, errors)
    gt = straight(11)
    write_run(tmp_path, "s", "gicp", True, gt, gt, lengths=(8.0,))
    write_run(tmp_path, "t", "gicp", True, gt, gt, lengths=(), sensor_class="Sparse 4D Radar")
    runs = load_runs(tmp_path)
    paths = errors.plot_boxplots(runs, tmp_path / "out")
    assert [p.name for p in paths] == ["dense-4d-lidar.pdf", "dense-4d-lidar.png"]
    assert errors._scored_lengths(runs) == [8.0]


def test_segments_of_a_path_too_short_are_empty():
    gt = straight(3)
    run = type("R", (), {"gt": gt, "est": gt})()
    t, r = errors._segments(run, 8.0)
    assert t.shape == r.shape == (0,)
    t, r = errors._segments(run, -1.0)  # not a length: none either
    assert len(t) == len(r) == 0
    t, r = errors._segments(run, 1.0)
    np.testing.assert_allclose(t, 0.0, atol=1e-12) and np.testing.assert_allclose(r, 0.0)
    assert len(t) == 2


def test_diverged_note_names_runs_and_their_sequences_in_order():
    from types import SimpleNamespace

    def run(method, seq, diverged=True):
        return SimpleNamespace(method=method, seed=True, label=None, display_name=seq,
                               diverged=diverged)

    assert errors._diverged_note([run("gicp", "a", False)]) == ""
    note = errors._diverged_note([run("gicp", "run10"), run("gicp", "run2"),
                                  run("icp-p2p", "x"), run("vgicp", "y", False)])
    assert note == f" Not shown (diverged): {GICP} on run2, run10; {ICP} on x"


# -- frames ------------------------------------------------------------------------------------

def test_frames_figure_time_and_correspondences_per_frame(tmp_path, monkeypatch):
    gt = straight(5)
    write_run(tmp_path, "seq A", "icp-p2p", True, gt, gt,
              frames=[(0, 99.0, 99.0), (1, 2.0, 300.0), (2, 0.0, 0.0), (3, 0.5, "x"),
                      (4, 8.0, 1.0)])
    write_run(tmp_path, "seq A", "gicp", True, gt, gt,  # scored without times: left out
              frames=[(k, "", 0) for k in range(5)])
    write_run(tmp_path, "seq A", "vgicp", True, gt, gt,  # times below 1 ms, no pairs: shown
              frames=[(k, 0.25, 0) for k in range(5)])
    figs = capture(monkeypatch, errors)
    paths = errors.plot_frames(load_runs(tmp_path), tmp_path / "out")
    assert [p.relative_to(tmp_path / "out").as_posix() for p in paths] == [
        "frames/seq-a.pdf", "frames/seq-a.png"]
    ((_, fig),) = figs
    top, bottom = fig.axes
    times = lines_by_label(top)
    assert set(times) == {ICP, display_name("vgicp")}
    time_line = times[ICP]
    np.testing.assert_allclose(time_line.get_xdata(), [1, 2, 3, 4])  # frame 0 not registered
    np.testing.assert_allclose(time_line.get_ydata(), [2.0, np.nan, 0.5, 8.0])
    np.testing.assert_allclose(times[display_name("vgicp")].get_ydata(), 0.25)
    pairs = {_hex(line.get_color()): line for line in bottom.get_lines()}
    icp_pairs = pairs[_hex(color("icp-p2p"))]
    np.testing.assert_allclose(icp_pairs.get_xdata(), [1, 2, 3, 4])
    np.testing.assert_allclose(icp_pairs.get_ydata(), [300.0, np.nan, np.nan, 1.0])
    assert np.all(np.isnan(pairs[_hex(color("vgicp"))].get_ydata()))
    assert time_line.get_linewidth() == 0.7
    assert time_line.get_color() == color("icp-p2p")
    runs = sorted((r for r in load_runs(tmp_path) if r.method != "gicp"), key=errors.run_order)
    for k, run in enumerate(runs):  # markers at each run's own offset, by index
        want = errors.line_kwargs(run, k, 2, points=4)["markevery"]
        assert times[errors.run_name(run)].get_markevery() == want
    assert top.get_yscale() == bottom.get_yscale() == "log"
    assert top.get_shared_x_axes().joined(top, bottom)
    assert top.get_ylabel() == "time per frame [ms]"
    assert bottom.get_ylabel() == "correspondences" and bottom.get_xlabel() == "frame"
    assert top.get_title() == "seq A"
    legend = fig.legends[0]
    note = " ".join(legend.get_title().get_text().split("\n"))
    assert note == ("Time: all per-frame work from a scan in memory to its pose (time_ms); "
                    f"the first frame is not registered. {PRIOR_NOTE}")
    legend_in = legend.get_window_extent(fig.test_renderer).height / fig.dpi
    assert fig.get_figheight() == pytest.approx(2.3 + 0.75 + legend_in, abs=0.02)


def test_frames_of_a_sequence_without_times_give_no_figure(tmp_path, monkeypatch):
    capture(monkeypatch, errors)
    gt = straight(3)
    write_run(tmp_path, "a", "gicp", True, gt, gt, frames=[(k, 0.0, -1.0) for k in range(3)])
    for seq in ("run10", "run2"):
        write_run(tmp_path, seq, "gicp", True, gt, gt, frames=[(0, 1, 1), (1, 0, 1), (2, 0, 0)])
    paths = errors.plot_frames(load_runs(tmp_path), tmp_path / "out")
    # correspondences alone are enough; in the tables' order; "a" has nothing
    assert [p.name for p in paths] == ["run2.pdf", "run2.png", "run10.pdf", "run10.png"]


def test_float_of_a_frames_value():
    assert errors._float("2.5") == 2.5
    assert np.isnan(errors._float("")) and np.isnan(errors._float(None))


# -- bench speed -------------------------------------------------------------------------------

def test_speed_curves_with_their_bands(tmp_path, monkeypatch):
    """Four methods (none of them in matplotlib's first default colours, so a band drawn
    without its method's colour shows): each its median curve over the LiDAR rows only and
    its p5-p95 band, in the tables' order, plain-number log axes, legend in three columns."""
    from bench.report.names import order_key

    methods = ("vgicp", "dicp", "kiss-icp", "doppler-ego")
    rows = "".join(f"lidar,{m},8000,{25 * (i + 1)},{24 * (i + 1)},{27 * (i + 1)}\n"
                   f"lidar,{m},1000,{2 * (i + 1)},{1.8 * (i + 1)},{2.5 * (i + 1)}\n"
                   f"radar,{m},500,1,1,1\n" for i, m in enumerate(methods))
    csv = tmp_path / "speed.csv"
    csv.write_text("scenario,method,points,median_ms,p5_ms,p95_ms\n" + rows)
    figs = capture(monkeypatch, errors)
    paths = errors.plot_speed_csv(csv, tmp_path / "out")
    assert paths == [tmp_path / "out" / "speed.pdf", tmp_path / "out" / "speed.png"]
    ((_, fig),) = figs
    (ax,) = fig.axes
    lines = lines_by_label(ax)
    bands = {_hex(c.get_facecolor()[0][:3]): c for c in ax.collections}
    for i, m in enumerate(methods):
        line = lines[display_name(m)]
        np.testing.assert_allclose(line.get_xydata(), [[1000, 2 * (i + 1)],
                                                       [8000, 25 * (i + 1)]])  # lidar only
        assert line.get_color() == color(m) and line.get_marker() == "o"
        band = bands[_hex(color(m))].get_paths()[0].vertices
        corners = {(1000, 1.8 * (i + 1)), (8000, 24.0 * (i + 1)), (8000, 27.0 * (i + 1)),
                   (1000, 2.5 * (i + 1))}
        got = {(round(x), round(y, 6)) for x, y in band}
        assert {(x, round(y, 6)) for x, y in corners} <= got
    assert ax.get_xscale() == ax.get_yscale() == "log"
    xlabels = {t.get_text() for t in ax.get_xticklabels() if t.get_text()}
    assert {"1000", "2000", "5000"} <= xlabels  # plain numbers, 1-2-5
    assert ax.get_xlabel() == "input points per scan"
    assert ax.get_ylabel() == "time per frame [ms]"
    assert ax.get_title() == "speed scaling: all per-frame work (median, p5-p95 band)"
    legend = fig.legends[0]
    names = [t.get_text() for t in legend.get_texts()]
    assert names == [display_name(m) for m in sorted(methods, key=order_key)]
    assert legend._ncols == 3
    legend_in = legend.get_window_extent(fig.test_renderer).height / fig.dpi
    assert fig.get_figheight() == pytest.approx(1.9 + 0.75 + legend_in, abs=0.02)


@pytest.mark.parametrize("text", [
    "scenario,method,points,median_ms,p5_ms\nlidar,gicp,10,1,1\n",  # no p95_ms
    "scenario,method,points,median_ms,p5_ms,p95_ms\nlidar,gicp,ten,1,1,1\n",
    "scenario,method,points,median_ms,p5_ms,p95_ms\nlidar,gicp,10,1,1,x\n",
    "scenario,method,points,median_ms,p5_ms,p95_ms\nlidar,gicp,10,1\n",  # short row
])
def test_a_csv_that_is_not_bench_speeds_is_refused_naming_the_columns(tmp_path, text):
    csv = tmp_path / "speed.csv"
    csv.write_text(text)
    with pytest.raises(DataError) as err:
        errors.plot_speed_csv(csv, tmp_path / "out")
    assert str(err.value) == (f"--speed-csv {csv}: not a `bench speed` CSV; expected the "
                              "columns scenario, method, points, median_ms, p5_ms, p95_ms "
                              "(results/speed/speed.csv)")
    assert not (tmp_path / "out").exists()


def test_a_binary_file_as_speed_csv_is_refused(tmp_path):
    csv = tmp_path / "speed.csv"
    csv.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(DataError, match="not a `bench speed` CSV"):
        errors.plot_speed_csv(csv, tmp_path / "out")
