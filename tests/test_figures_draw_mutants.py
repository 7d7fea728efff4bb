"""bench/report/figures/draw.py, the trajectory figure a reader compares methods on: the
ground truth in black with its start and end marked, every run aligned at its first pose in its
method's colour, axes at equal scale around the paths that held (limits worked out by hand), a
diverged run cut where it leaves them and labelled "Div.", legend names with the prior note,
one file per sequence named by its slug; the runs read (broken records warned about, runs
without ground truth left out, clashing names told apart) and ``make_figures`` writing every
kind into a folder the guard allows."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import bench.report.figures.draw as draw
from bench.guard import Refused
from bench.report.figures.style import COLUMN_IN, PRIOR_NOTE, color
from bench.report.names import display_name
from bench.runs.folders import load_runs
from helpers_figure_runs import capture, lines_by_label, rot_z, straight, write_run
from loaders.se3 import make_T

ICP, GICP = display_name("icp-p2p"), display_name("gicp")


def _moved(poses: np.ndarray) -> np.ndarray:
    """The same path seen from another world frame (turned 90 deg, shifted): aligned at the
    first pose it is the path itself."""
    return make_T(rot_z(90.0), np.array([5.0, -3.0, 1.0])) @ poses


def _drifting(n: int) -> np.ndarray:
    est = straight(n)
    est[:, 1, 3] = 0.1 * np.arange(n)  # 2 m sideways over 20 m
    return est


def _diverging(n: int) -> np.ndarray:
    est = straight(n)
    est[:, 1, 3] = 0.5 * np.arange(n) ** 2  # 200 m sideways at the end
    return est


@pytest.fixture
def results(tmp_path):
    root = tmp_path / "results"
    gt = straight(21)
    write_run(root, "seq A", "icp-p2p", True, gt, _moved(gt))
    write_run(root, "seq A", "icp-p2p", False, gt, _drifting(21))
    write_run(root, "seq A", "gicp", True, gt, _diverging(21), diverged=True)
    return root


def test_aligned_at_the_first_pose():
    gt = straight(5)
    gt[:, :3, :3] = rot_z(30.0)
    run = type("R", (), {"gt": gt, "est": _moved(gt)})()
    np.testing.assert_allclose(draw._aligned_xy(run), gt[:, :2, 3], atol=1e-12)


def test_limits_hold_the_paths_with_one_margin_on_both_axes():
    lo, hi = draw._limits([np.array([[0.0, 0.0], [20.0, 0.0]]), np.array([[0.0, 2.0]])])
    np.testing.assert_allclose(lo, [-1.0, -1.0])  # 5 % of 20 m is below the 1 m minimum
    np.testing.assert_allclose(hi, [21.0, 3.0])
    lo, hi = draw._limits([np.array([[-100.0, 10.0], [100.0, 50.0]])])
    np.testing.assert_allclose(lo, [-110.0, 0.0])  # 5 % of the larger span, 200 m
    np.testing.assert_allclose(hi, [110.0, 60.0])


@pytest.mark.parametrize("span, lo, hi, height", [
    ((30.0, 3.0), (0.0, -2.5), (30.0, 5.5), 0.8),  # straight: minimum height, wider y
    ((3.0, 30.0), (-13.5, 0.0), (16.5, 30.0), 3.0),  # tall: maximum height, wider x
    ((30.0, 20.0), (0.0, 0.0), (30.0, 20.0), 2.0),  # in between: exactly the paths
])
def test_axes_fill_the_column_at_equal_scale(span, lo, hi, height):
    """The axes are 3.0 in wide (the column less 0.5 in for the y labels): the height in
    inches is 3.0 x span_y / span_x clamped to 0.8-3.0, the limits widened about their middle
    to that shape."""
    got_lo, got_hi, got_h = draw._axes_shape(np.zeros(2), np.array(span))
    np.testing.assert_allclose(got_lo, lo)
    np.testing.assert_allclose(got_hi, hi)
    assert got_h == pytest.approx(height)
    got = (np.array(got_hi) - got_lo)
    assert got[1] / got[0] == pytest.approx(got_h / (COLUMN_IN - 0.5))  # equal scale
    shifted = draw._axes_shape(np.array([100.0, -50.0]), np.array([100.0, -50.0]) + span)
    np.testing.assert_allclose(shifted[0], np.array(lo) + [100.0, -50.0])  # only the span
    np.testing.assert_allclose(shifted[1], np.array(hi) + [100.0, -50.0])  # counts


def test_trajectory_figure_draws_what_the_reader_compares(results, tmp_path, monkeypatch):
    figs = capture(monkeypatch, draw, write=True)
    out = tmp_path / "out"
    paths = draw.plot_trajectories(results, out)
    assert paths == [out / "trajectories" / "seq-a.pdf", out / "trajectories" / "seq-a.png"]
    assert all(p.exists() for p in paths)
    ((stem, fig),) = figs
    ax = fig.axes[0]
    lines = lines_by_label(ax)
    assert set(lines) == {"ground truth", ICP, f"{ICP} (no seed)", f"{GICP} - Div."}
    gt = lines["ground truth"]
    np.testing.assert_allclose(gt.get_xydata(), straight(21)[:, :2, 3])
    assert gt.get_color() == "black"
    # the moved run is the ground truth once aligned; the drifting one 0.1 m per metre off
    np.testing.assert_allclose(lines[ICP].get_xydata(), straight(21)[:, :2, 3], atol=1e-6)
    np.testing.assert_allclose(lines[f"{ICP} (no seed)"].get_xydata(),
                               _drifting(21)[:, :2, 3], atol=1e-6)
    assert lines[ICP].get_color() == color("icp-p2p")
    assert lines[GICP + " - Div."].get_color() == color("gicp")
    # start and end of the ground truth
    marks = [line for line in ax.get_lines() if line.get_label().startswith("_")]
    by_marker = {m.get_marker(): m for m in marks}
    np.testing.assert_allclose(by_marker["o"].get_xydata(), [[0.0, 0.0]])
    np.testing.assert_allclose(by_marker["s"].get_xydata(), [[20.0, 0.0]])
    assert by_marker["o"].get_markerfacecolor() == "white"
    # limits: the paths that held, 0-20 m x 0-2 m, 1 m margin, widened to 0.8 in height
    lo, hi, axes_in = draw._axes_shape(np.array([-1.0, -1.0]), np.array([21.0, 3.0]))
    np.testing.assert_allclose(ax.get_xlim(), [lo[0], hi[0]])
    np.testing.assert_allclose(ax.get_ylim(), [lo[1], hi[1]])
    assert axes_in == pytest.approx(0.8)
    assert ax.get_aspect() == 1.0
    # the diverged run: drawn while inside the limits of the paths that held, then labelled
    div = lines[GICP + " - Div."].get_xydata()
    np.testing.assert_allclose(div, _diverging(21)[:3, :2, 3])  # y = 0, 0.5, 2 m: then 4.5 m
    (label,) = ax.texts
    assert label.get_text() == "Div." and label.xy == (2.0, 2.0)
    assert label.get_color() == color("gicp")
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"
    assert ax.get_title() == "seq A (\u25cb start, \u25a0 end)"
    (legend,) = fig.legends
    assert [t.get_text() for t in legend.get_texts()] == [
        "ground truth", ICP, f"{ICP} (no seed)", f"{GICP} - Div."]
    assert " ".join(legend.get_title().get_text().split("\n")) == PRIOR_NOTE
    assert fig.get_figwidth() == pytest.approx(COLUMN_IN)
    legend_in = legend.get_window_extent(fig.test_renderer).height / fig.dpi
    assert fig.get_figheight() == pytest.approx(0.8 + 0.55 + legend_in + 0.1, abs=0.05)


def test_runs_leaving_at_one_place_share_a_grey_label(tmp_path, monkeypatch):
    root = tmp_path / "results"
    gt = straight(21)
    write_run(root, "seq A", "gicp", True, gt, _diverging(21), diverged=True)
    write_run(root, "seq A", "vgicp", True, gt, _diverging(21), diverged=True)
    late = straight(21)
    late[15:, 1, 3] = 0.5 * np.arange(1, 7) ** 2  # leaves 14 m further on
    write_run(root, "seq A", "icp-p2p", True, gt, late, diverged=True)
    figs = capture(monkeypatch, draw)
    draw.plot_trajectories(root, tmp_path / "out")
    ((_, fig),) = figs
    # only the ground truth held: y limits -1..1 m (widened for the axes' shape), so the runs
    # are drawn while |y| <= 1 m: up to (1, 0.5) and (15, 0.5)
    texts = {t.get_text(): t for t in fig.axes[0].texts}
    assert set(texts) == {"Div.", "Div. (2)"}
    assert texts["Div. (2)"].xy == (1.0, 0.5) and texts["Div."].xy == (15.0, 0.5)
    assert texts["Div."].get_color() == color("icp-p2p")


def test_a_run_with_non_finite_poses_is_not_drawn(tmp_path, monkeypatch):
    gt = straight(21, 2.0)
    bad = straight(21, 2.0)
    bad[5:, 0, 3] = np.nan

    def run(method, est):
        return SimpleNamespace(method=method, seed=True, label=None, config={}, gt=gt, est=est,
                               diverged=False)

    figs = capture(monkeypatch, draw)
    draw.plot_sequence("seq A", [run("gicp", bad), run("icp-p2p", gt)], tmp_path)
    ((_, fig),) = figs
    lines = lines_by_label(fig.axes[0])
    assert set(lines) == {"ground truth", ICP}
    np.testing.assert_allclose(lines["ground truth"].get_xydata(), gt[:, :2, 3])  # 0-40 m
    np.testing.assert_allclose(lines[ICP].get_xydata(), gt[:, :2, 3])
    marks = {m.get_marker(): m for m in fig.axes[0].get_lines()
             if m.get_label().startswith("_")}
    np.testing.assert_allclose(marks["s"].get_xydata(), [[40.0, 0.0]])
    assert marks["o"].get_color() == marks["s"].get_color() == "black"  # the GT's marks


def test_one_figure_per_sequence_in_the_tables_order_default_folder(tmp_path, monkeypatch):
    root = tmp_path / "results"
    gt = straight(11)
    for seq in ("run10", "run2"):
        write_run(root, seq, "icp-p2p", True, gt, gt)
    write_run(root, "one pose", "icp-p2p", True, gt[:1], gt[:1])  # nothing to draw
    write_run(root, "two poses", "icp-p2p", True, gt[:2], gt[:2])  # a path
    no_gt = write_run(root, "no gt", "icp-p2p", True, gt, gt)
    (no_gt / "gt_tum.txt").unlink()
    figs = capture(monkeypatch, draw)
    paths = draw.plot_trajectories(root)
    assert [p.relative_to(root) for p in paths] == [
        draw.Path(f"figures/trajectories/{s}.{x}") for s in ("run2", "run10", "two-poses")
        for x in ("pdf", "png")]
    assert [stem.name for stem, _ in figs] == ["run2", "run10", "two-poses"]


def test_given_runs_are_drawn_instead_of_the_folders(tmp_path, monkeypatch):
    capture(monkeypatch, draw)
    root = tmp_path / "results"
    gt = straight(11)
    write_run(root, "seq A", "icp-p2p", True, gt, gt)
    write_run(root, "seq B", "icp-p2p", True, gt, gt)
    runs = [r for r in load_runs(root) if r.display_name == "seq B"]
    paths = draw.plot_trajectories(root, tmp_path / "out", runs)
    assert [p.name for p in paths] == ["seq-b.pdf", "seq-b.png"]


def test_runs_read_a_broken_record_warned_about_no_gt_left_out(tmp_path):
    root = tmp_path / "results"
    gt = straight(11)
    write_run(root, "seq A", "icp-p2p", True, gt, gt)
    no_gt = write_run(root, "seq A", "gicp", True, gt, gt)
    (no_gt / "gt_tum.txt").unlink()
    broken = root / "seq A" / "vgicp_seed"
    broken.mkdir()
    (broken / "metrics.json").write_text("{not json")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        runs = draw._runs_with_gt(root)
    assert [r.method for r in runs] == ["icp-p2p"]
    (warning,) = [w for w in caught if "left out of the figures" in str(w.message)]
    assert "metrics.json" in str(warning.message) and "not valid JSON" in str(warning.message)


def test_runs_whose_names_clash_are_told_apart_by_their_folders(tmp_path):
    root = tmp_path / "results"
    gt = straight(11)
    write_run(root, "seq A", "icp-p2p", True, gt, gt, folder_name="first")
    write_run(root, "seq A", "icp-p2p", True, gt, gt, folder_name="second")
    write_run(root, "seq A", "icp-p2p", False, gt, gt)  # no seed: no clash
    write_run(root, "seq B", "icp-p2p", True, gt, gt)  # another sequence: no clash
    runs = draw._runs_with_gt(root)
    got = sorted((r.display_name, r.dir.name, r.label) for r in runs)
    assert got == [("seq A", "first", f"{ICP} [run folder first]"),
                   ("seq A", "icp-p2p_noseed", None),
                   ("seq A", "second", f"{ICP} [run folder second]"),
                   ("seq B", "icp-p2p_seed", None)]


def _stub_plotters(monkeypatch) -> list:
    """Each plotter of make_figures replaced by one recording what it was given."""
    import bench.report.figures.drift as drift
    import bench.report.figures.errors as errors
    import bench.report.figures.forest as forest
    import bench.report.figures.velocity as velocity
    import bench.report.tables.paper as paper

    calls = []

    def stub(name):
        def plot(data, out_dir):
            calls.append((name, data, out_dir))
            return [out_dir / name]
        return plot

    for mod, name in ((errors, "plot_boxplots"), (errors, "plot_error_along_path"),
                      (errors, "plot_frames"), (errors, "plot_speed_csv"),
                      (drift, "plot_drift"), (velocity, "plot_velocity_along_path"),
                      (forest, "plot_forest")):
        monkeypatch.setattr(mod, name, stub(name))
    monkeypatch.setattr(paper, "runs", lambda folder: ("table rows of", folder))
    monkeypatch.setattr(draw, "plot_trajectories",
                        lambda folder, out, runs: [out / "plot_trajectories"] if
                        calls.append(("plot_trajectories", runs, out)) is None else [])
    return calls


def test_make_figures_draws_every_kind_and_the_speed_csv_only_when_it_exists(
        results, tmp_path, monkeypatch):
    calls = _stub_plotters(monkeypatch)
    speed = tmp_path / "speed.csv"
    speed.write_text("x")
    out = results / "figures"  # the default folder
    paths = draw.make_figures(results, speed_csv=speed)
    names = ["plot_trajectories", "plot_boxplots", "plot_error_along_path", "plot_frames",
             "plot_drift", "plot_velocity_along_path", "plot_forest", "plot_speed_csv"]
    assert paths == [out / n for n in names]
    assert [c[0] for c in calls] == names and all(c[2] == out for c in calls)
    runs = calls[0][1]
    assert sorted(r.dir.name for r in runs) == ["gicp_seed", "icp-p2p_noseed", "icp-p2p_seed"]
    assert all(c[1] is runs for c in calls[1:6])  # every figure of the same runs
    assert calls[6][1] == ("table rows of", results)
    assert calls[7][1] == speed
    calls.clear()
    speed.unlink()  # gone: no speed figure
    assert draw.make_figures(results, tmp_path / "figs", speed) == [
        tmp_path / "figs" / n for n in names[:-1]]
    calls.clear()
    assert draw.make_figures(results, tmp_path / "figs") == [
        tmp_path / "figs" / n for n in names[:-1]]


def test_make_figures_refuses_a_run_folder_as_its_output(results):
    run_dir = results / "seq A" / "icp-p2p_seed"
    with pytest.raises(Refused, match="is a run folder"):
        draw.make_figures(results, run_dir)
    assert not (run_dir / "trajectories").exists()


def _ns_run(method, gt, est, diverged=False, seed=True):
    return SimpleNamespace(method=method, seed=seed, label=None, config={}, gt=gt, est=est,
                           diverged=diverged)


def test_a_short_path_gets_the_one_metre_margin(tmp_path, monkeypatch):
    figs = capture(monkeypatch, draw)
    gt = straight(6, 2.0)  # 10 m: 5 % would be 0.5 m
    draw.plot_sequence("s", [_ns_run("gicp", gt, gt)], tmp_path)
    ((_, fig),) = figs
    np.testing.assert_allclose(fig.axes[0].get_xlim(), (-1.0, 11.0))


def test_runs_leaving_within_6_percent_of_the_axes_share_a_label(tmp_path, monkeypatch):
    """Only the ground truth (0-20 m along x) holds: limits -1..21 m x -1..1 m, widened to
    -2.93..2.93 m in y for the minimum height: 22 m across, so exits within 1.32 m share a
    label. Exits at (10, 0.5) and (11.25, 0.5) are 1.25 m apart: one label; a run whose
    second pose is already outside is drawn as its first point, labelled there."""
    figs = capture(monkeypatch, draw)
    gt = straight(21)

    def leaving(last_x, last_k):
        est = straight(21)
        est[1:last_k + 1, 1, 3] = 0.5
        est[last_k, 0, 3] = last_x
        est[last_k + 1:, 1, 3] = 50.0
        return est

    first = straight(21)
    first[1:, 1, 3] = 50.0
    runs = [_ns_run("gicp", gt, leaving(10.0, 10), True),
            _ns_run("vgicp", gt, leaving(11.25, 11), True),
            _ns_run("icp-p2p", gt, first, True)]
    draw.plot_sequence("s", runs, tmp_path)
    ((_, fig),) = figs
    ax = fig.axes[0]
    texts = sorted((t.xy, t.get_text()) for t in ax.texts)
    assert texts == [((0.0, 0.0), "Div."), ((10.0, 0.5), "Div. (2)")]
    assert {(t.xyann, t.get_fontsize()) for t in ax.texts} == {((2, 2), 6)}  # up right, 6 pt
    np.testing.assert_allclose(lines_by_label(ax)[f"{ICP} - Div."].get_xydata(), [[0.0, 0.0]])
    ordered = sorted(runs, key=draw.run_order)
    for k, run in enumerate(ordered):  # markers at each run's own offset
        line = lines_by_label(ax)[draw.run_name(run) + " - Div."]
        assert line.get_markevery() == draw.line_kwargs(run, k, 3)["markevery"]


def test_exits_one_above_the_other_within_6_percent_share_a_label(tmp_path, monkeypatch):
    """Exits at (10, 0.62) and (10, -0.62): 1.24 m apart, within 6 % of the 22 m span
    (1.32 m): one label, though their labels would not touch (1.24 m is some 12 pt)."""
    figs = capture(monkeypatch, draw)
    gt = straight(21)

    def leaving(y):
        est = straight(21)
        est[1:11, 1, 3] = y
        est[11:, 1, 3] = 50.0 * np.sign(y)
        return est

    draw.plot_sequence("s", [_ns_run("gicp", gt, leaving(0.62), True),
                             _ns_run("vgicp", gt, leaving(-0.62), True)], tmp_path)
    ((_, fig),) = figs
    assert [(t.get_text(), t.xy) for t in fig.axes[0].texts] == [("Div. (2)", (10.0, 0.62))]
