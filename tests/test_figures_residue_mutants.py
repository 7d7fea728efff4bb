"""Residue survivors of bench/report/figures: pair.py's true motion looked up in the ground
truth by stamps rounded to the microsecond (a store without ground truth, ground truth that
misses the target frame, and stamps a few tenths of a microsecond apart on either side)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import bench.report.figures.draw as draw
import bench.report.figures.errors as errors
import bench.report.figures.pair as pair
from bench.runs.folders import load_runs
from conftest import constant_twist_sequence
from helpers_figure_runs import capture, straight, write_run
from loaders.scan import MemorySequence
from loaders.se3 import inv_T
from loaders.store import write_store
from loaders.trajectory import Trajectory

SUB_MICRO_S = 4e-7  # equal to the microsecond, different at a tenth of one


def _store(tmp_path, name, scan_shift=0.0, gt=lambda t: t):
    seq = constant_twist_sequence(n_frames=2, n_points=200)
    scans = [replace(seq[k], stamp=seq[k].stamp + scan_shift) for k in range(len(seq))]
    truth = gt(seq.ground_truth)
    seq = MemorySequence(seq.name, seq.sensor, scans, truth, seq.provenance)
    return write_store(seq, tmp_path / f"{name}.h5"), seq


def _true_motion(seq):
    """T_target_source of frames 0 -> 1 from the poses the sequence was made with."""
    poses = constant_twist_sequence(n_frames=2, n_points=200).ground_truth.poses
    return inv_T(poses[1]) @ poses[0]


def test_without_ground_truth_there_is_no_true_motion(tmp_path):
    path, _ = _store(tmp_path, "nogt", gt=lambda t: None)
    assert pair.pair_correspondences(path, 0)["T_true"] is None


def test_ground_truth_missing_the_target_frame_gives_no_true_motion(tmp_path):
    only_source = lambda t: Trajectory(t.stamps[:1], t.poses[:1])  # noqa: E731
    path, _ = _store(tmp_path, "half", gt=only_source)
    assert pair.pair_correspondences(path, 0)["T_true"] is None


def test_ground_truth_stamps_a_fraction_of_a_microsecond_late_still_match(tmp_path):
    late = lambda t: Trajectory(t.stamps + SUB_MICRO_S, t.poses)  # noqa: E731
    path, seq = _store(tmp_path, "gtlate", gt=late)
    got = pair.pair_correspondences(path, 0)["T_true"]
    assert got is not None
    np.testing.assert_allclose(got, _true_motion(seq), atol=1e-9)


def test_scan_stamps_a_fraction_of_a_microsecond_late_still_match(tmp_path):
    path, seq = _store(tmp_path, "scanlate", scan_shift=SUB_MICRO_S)
    got = pair.pair_correspondences(path, 0)["T_true"]
    assert got is not None
    np.testing.assert_allclose(got, _true_motion(seq), atol=1e-9)


# -- errors.py: "Div." clusters, box plots with an empty slot, the error-along-path figure ----


def _dist_texts(ax):
    return sorted((round(t.xy[0], 9), t.get_text()) for t in ax.texts)


def test_divergence_clusters_are_measured_from_their_first_exit():
    """Exits at 50 and 55 m of 100 m are 5 m apart, within 6 % of the path: one grey label at
    50 m; 90 m is 40 m on, a label of its own (a 20 in wide axes: no label touches)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(20.0, 2.0))
    ax.set_xlim(0, 100)
    ax.set_ylim(0.01, 1.0)
    ax.set_yscale("log")
    errors.label_divergence(ax, [(55.0, "#ff0000"), (50.0, "#0000ff"), (90.0, "#00ff00")],
                            1.0, 100.0)
    assert _dist_texts(ax) == [(50.0, "Div. (2)"), (90.0, "Div.")]
    plt.close(fig)


def test_a_run_without_segments_of_a_length_leaves_its_box_empty(tmp_path, monkeypatch):
    """A 200 m run and a 20 m one, lengths 8 and 100 m: the short one has no 100 m segment,
    so its translation box there is empty (NaN) while the three others hold positive errors."""
    figs = capture(monkeypatch, errors)
    bend = straight(201)
    bend[:, 1, 3] = 0.01 * np.arange(201) ** 2
    write_run(tmp_path, "s", "gicp", True, straight(201), bend, lengths=(8.0, 100.0))
    short = straight(21)
    short[:, 1, 3] = 0.01 * np.arange(21) ** 2
    write_run(tmp_path, "s", "vgicp", True, straight(21), short, lengths=(8.0,))
    errors.plot_boxplots(load_runs(tmp_path), tmp_path / "out")
    ((_, fig),) = figs
    top = fig.axes[0]  # translation: the estimates bend, no rotation error at all
    boxes = [b.get_path().vertices[:-1, 1] for b in top.patches]  # without CLOSEPOLY
    assert len(boxes) == 4  # two runs x two lengths
    assert sum(np.all(np.isnan(y)) for y in boxes) == 1
    assert all(np.all(y > 0) for y in boxes if not np.all(np.isnan(y)))


def _jump(n: int, k: int, step_m: float) -> np.ndarray:
    """A path ``step_m`` per frame that jumps 5 m sideways from frame ``k`` on."""
    est = straight(n, step_m)
    est[k:, 1, 3] = 5.0
    return est


def test_a_path_shorter_than_a_metre_clusters_exits_by_its_own_length(tmp_path, monkeypatch):
    """A 0.1 m path (0.01 m a frame): the run that held has no error, so the axes hold
    1 mm - 1 m and the 5 m jumps leave them at 0.02 and 0.07 m travelled. 0.05 m apart is
    50 % of this path (not within 6 %): two labels. The axes are 2.3 in tall in all, the
    legend below them (fit_height: + 0.75 in for titles and labels)."""
    figs = capture(monkeypatch, errors)
    gt = straight(11, 0.01)
    write_run(tmp_path, "s", "gicp", True, gt, gt)
    write_run(tmp_path, "s", "vgicp", True, gt, _jump(11, 2, 0.01), diverged=True)
    write_run(tmp_path, "s", "icp-p2p", True, gt, _jump(11, 7, 0.01), diverged=True)
    errors.plot_error_along_path(load_runs(tmp_path), tmp_path / "out")
    ((_, fig),) = figs
    top, bottom = fig.axes
    assert _dist_texts(top) == [(0.02, "Div."), (0.07, "Div.")]
    assert len(bottom.texts) == 0  # no rotation error at all
    legend_in = fig.legends[0].get_window_extent(fig.test_renderer).height / fig.dpi
    assert fig.get_figheight() == pytest.approx(2.3 + 0.75 + legend_in, abs=0.02)


# -- draw.py: "Div." labels of runs leaving on either side of the path ------------------------


def test_runs_leaving_on_either_side_get_a_label_each(tmp_path, monkeypatch):
    """Only the ground truth (0-20 m along x) holds: limits -1..21 m x -1..1 m, 22 m across,
    so exits within 1.32 m share a label. Runs leaving at (10, 0.9) and (10, -0.9) are 1.8 m
    apart: a label each (about 0.25 in apart: they do not touch)."""
    figs = capture(monkeypatch, draw)
    gt = straight(21)

    def leaving(side):
        est = straight(21)
        est[1:11, 1, 3] = 0.9 * side
        est[11:, 1, 3] = 50.0 * side
        return est

    runs = [SimpleNamespace(method=m, seed=True, label=None, config={}, gt=gt,
                            est=leaving(side), diverged=True)
            for m, side in (("gicp", 1.0), ("vgicp", -1.0))]
    draw.plot_sequence("s", runs, tmp_path)
    ((_, fig),) = figs
    texts = sorted((t.xy, t.get_text()) for t in fig.axes[0].texts)
    assert texts == [((10.0, -0.9), "Div."), ((10.0, 0.9), "Div.")]


# -- pair.py: the zoomed window against a brute-force count ----------------------------------


def _window_by_brute_force(points, width_m, height_m, cell_m=1.0):
    """The definition, point by point: cells of ``cell_m`` from the lowest corner of the
    points; the window is the run of whole cells (at least one each way) that fits in
    width x height; the first placement (by cell index) holding the most points wins, then
    it is re-centred on the points within it."""
    lo = points.min(axis=0)
    cell = np.floor((points - lo) / cell_m).astype(int)
    w, h = max(1, int(width_m / cell_m)), max(1, int(height_m / cell_m))
    best, at = -1, None
    for i in range(cell[:, 0].max() + 1):
        for j in range(cell[:, 1].max() + 1):
            n = int(np.sum((cell[:, 0] >= i) & (cell[:, 0] < i + w)
                           & (cell[:, 1] >= j) & (cell[:, 1] < j + h)))
            if n > best:
                best, at = n, (i, j)
    corner = lo + np.array(at) * cell_m
    size = np.array([width_m, height_m])
    held = points[np.all((points >= corner) & (points <= corner + size), axis=1)]
    mid = (held.min(axis=0) + held.max(axis=0)) / 2
    return mid - size / 2, mid + size / 2


def _clustered(seed):
    """A few clusters of different sizes and spreads in a 24 m square."""
    rng = np.random.default_rng(seed)
    parts = [rng.normal(rng.uniform(0, 24, 2), rng.uniform(0.3, 3.0), (rng.integers(1, 12), 2))
             for _ in range(rng.integers(2, 5))]
    return np.vstack(parts)


#: (window size, cell): windows at least a cell wide and high each way, as the figure's are
#: (30 m x 18 m in 1 m cells); a window narrower than its cell may hold none of its cell's
#: points, which the re-centring cannot handle (no caller asks for one)
_SIZES_CELLS = [((6.0, 3.0), None), ((6.0, 3.0), 0.5), ((6.0, 3.0), 2.0), ((1.0, 1.0), None),
                ((1.0, 1.0), 0.5), ((1.5, 7.0), None), ((1.5, 7.0), 0.5), ((2.0, 4.5), 2.0)]


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize(("size", "cell_m"), _SIZES_CELLS)
def test_window_holds_the_most_points_by_brute_force(seed, size, cell_m):
    points = _clustered(seed)
    kw = {} if cell_m is None else {"cell_m": cell_m}  # None: the default, 1 m cells
    got = pair._window(points, *size, **kw)
    want = _window_by_brute_force(points, *size, **kw)
    np.testing.assert_allclose(got, want, atol=1e-9)


# -- style.py: a log axis too narrow for any per-decade tick ---------------------------------


@pytest.mark.parametrize(("lo", "hi"), [(999.9, 1000.1), (0.999, 1.001)])
def test_a_log_axis_narrower_than_its_digits_gets_few_even_ticks(lo, hi):
    """1-2-5 and every digit give at most one tick inside (1000; 1), so the axis falls back
    on even steps: still the fewest that label at least two values (two to four inside, not
    matplotlib's crowded default of up to ten), evenly spaced, labelled as plain numbers."""
    import matplotlib.pyplot as plt

    from bench.report.figures.style import log_y

    fig, ax = plt.subplots()
    ax.plot([0, 1], [lo, hi])
    ax.set_ylim(lo, hi)
    log_y(ax)
    ticks = np.array([v for v in ax.yaxis.get_major_locator()() if lo <= v <= hi])
    assert 2 <= len(ticks) <= 4
    np.testing.assert_allclose(np.diff(ticks), np.diff(ticks)[0], rtol=1e-6)
    fig.canvas.draw()
    labels = {round(t.get_position()[1], 9): t.get_text() for t in ax.get_yticklabels()}
    assert [labels[round(v, 9)] for v in ticks] == [f"{v:g}" for v in ticks]
    plt.close(fig)
