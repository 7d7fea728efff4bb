"""bench/report/figures/pair.py, the scan-pair figure: the closest-point pairs checked against
scipy's kd-tree within the 3 m gate, the true motion from the ground truth, a pair's colour
by whether that motion brings its source point within 0.5 m of its partner (the share in each
title), the zoomed window with the most points (worked out by hand), the titles, legend entries
with and without ground truth, the file name, and a frame without a next one or a store
without Doppler refused with a message naming them."""

from __future__ import annotations

import matplotlib.colors as mcolors
import numpy as np
import pytest
from scipy.spatial import cKDTree

import bench.report.figures.pair as pair
from conftest import constant_twist_sequence
from helpers_figure_runs import capture
from loaders.errors import DataError
from loaders.se3 import inv_T, transform_points
from loaders.store import write_store


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    root = tmp_path_factory.mktemp("pair")
    seq = constant_twist_sequence(n_frames=3, n_points=600, max_range_m=40, noise_m=0.3)
    return write_store(seq, root / "Twist Store.h5"), seq


def test_correspondences_of_a_pair(store):
    path, seq = store
    data = pair.pair_correspondences(path, 1)
    src, tgt = seq[1].points, seq[2].points
    np.testing.assert_allclose(data["source"], src, atol=1e-4)
    np.testing.assert_allclose(data["target"], tgt, atol=1e-4)
    # closest points: scipy's kd-tree, within the 3 m gate
    dist, idx = cKDTree(data["target"]).query(data["source"])
    s_idx, t_idx = data["closest"]
    np.testing.assert_array_equal(s_idx, np.flatnonzero(dist <= 3.0))
    np.testing.assert_array_equal(t_idx, idx[dist <= 3.0])
    assert 0 < len(s_idx) < len(src)
    # the true motion T_target_source from the ground truth poses
    want = inv_T(seq.ground_truth.poses[2]) @ seq.ground_truth.poses[1]
    np.testing.assert_allclose(data["T_true"], want, atol=1e-6)
    d_s, d_t = data["doppler"]
    assert len(d_s) == len(d_t) > 0
    assert np.all(np.linalg.norm(data["source"][d_s] - data["target"][d_t], axis=1) <= 3.0 + 1e-4)
    assert data["name"] == "twist, frames 1 -> 2"


@pytest.mark.parametrize("frame", [-1, 2])
def test_a_frame_without_a_next_one_is_refused(store, frame):
    path, _ = store
    with pytest.raises(DataError) as err:
        pair.pair_correspondences(path, frame)
    assert str(err.value) == f"{path}: frame {frame} has no next frame (0..1)"


def test_a_store_without_doppler_is_refused(tmp_path):
    from dataclasses import replace

    from loaders.scan import MemorySequence

    seq = constant_twist_sequence(n_frames=2, n_points=200)
    seq = MemorySequence(seq.name, seq.sensor, [replace(seq[k], doppler=None)
                                                 for k in range(len(seq))],
                         seq.ground_truth, seq.provenance)
    path = write_store(seq, tmp_path / "nodop.h5")
    with pytest.raises(DataError) as err:
        pair.pair_correspondences(path, 0)
    assert str(err.value).startswith(f"{path}: Doppler Correspondence's pairs needs Doppler, "
                                     "but the store has no Doppler values")


def test_a_synthetic_store_is_named_so(tmp_path):
    from loaders.scan import MemorySequence

    seq = constant_twist_sequence(n_frames=2, n_points=200)
    seq = MemorySequence(seq.name, seq.sensor, [seq[k] for k in range(len(seq))],
                         seq.ground_truth, {"source": "synthetic"})
    path = write_store(seq, tmp_path / "synth.h5")
    assert pair.pair_correspondences(path, 0)["name"] == "twist (synthetic), frames 0 -> 1"


def test_window_with_the_most_points_centred_on_what_it_holds():
    rng = np.random.default_rng(1)
    dense = rng.uniform(0, 5, (100, 2)) + [40.0, 10.0]
    sparse = rng.uniform(0, 5, (10, 2))
    lo, hi = pair._window(np.vstack([sparse, dense]), 30.0, 18.0)
    mid = (dense.min(axis=0) + dense.max(axis=0)) / 2
    np.testing.assert_allclose(lo, mid - [15.0, 9.0])
    np.testing.assert_allclose(hi, mid + [15.0, 9.0])
    lo, hi = pair._window(np.empty((0, 2)), 30.0, 18.0)
    np.testing.assert_allclose(lo, [-15.0, -9.0])
    np.testing.assert_allclose(hi, [15.0, 9.0])


def test_window_of_points_spread_wider_than_it_holds_the_dense_end():
    x = np.concatenate([np.linspace(0, 10, 50), np.linspace(60, 100, 10)])
    points = np.column_stack([x, np.zeros_like(x)])
    lo, hi = pair._window(points, 20.0, 4.0, cell_m=2.0)
    np.testing.assert_allclose((lo + hi) / 2, [5.0, 0.0])
    np.testing.assert_allclose(hi - lo, [20.0, 4.0])


def _hex(c) -> str:
    return mcolors.to_hex(c)


def test_pair_figure(store, tmp_path, monkeypatch):
    path, _ = store
    figs = capture(monkeypatch, pair)
    paths = pair.plot_pair(path, 1, tmp_path)
    assert paths == [tmp_path / "pairs" / f"twist-store-frame-1.{x}" for x in ("pdf", "png")]
    ((_, fig),) = figs
    data = pair.pair_correspondences(path, 1)
    src, tgt, T = data["source"], data["target"], data["T_true"]
    top, bottom = fig.axes
    for ax, key, title in ((top, "closest", "Closest point (ICP)"),
                           (bottom, "doppler", "Doppler Correspondence")):
        s_idx, t_idx = data[key]
        moved = transform_points(T, src[s_idx])
        good = np.linalg.norm(moved - tgt[t_idx], axis=1) < 0.5
        head, tail = ax.get_title().split("\n")
        assert head == f"{title}: {len(s_idx)} pairs, {good.mean():.0%} consistent"
        lines = ax.collections[-1]
        segs = np.array(lines.get_segments())
        assert 0 < len(segs) <= pair.MAX_LINES
        # each drawn pair is a source point and its partner, coloured by consistency
        lookup = {tuple(np.round(src[s, :2], 4)): (t, g) for s, t, g in
                  zip(s_idx, t_idx, good, strict=True)}
        colours = [_hex(c) for c in lines.get_colors()]
        for seg, c in zip(segs, colours, strict=True):
            t, g = lookup[tuple(np.round(seg[0], 4))]
            np.testing.assert_allclose(seg[1], tgt[t, :2], atol=1e-4)
            assert c == ("#0072b2" if g else "#d55e00")
        lo, hi = ax.get_xlim(), ax.get_ylim()
        assert hi[1] - hi[0] == pytest.approx(0.6 * (lo[1] - lo[0]))
        assert lo[1] - lo[0] == pytest.approx(pair.WINDOW_M)
        in_view = [(seg >= [lo[0] - 0.5, hi[0] - 0.5]).all() and
                   (seg <= [lo[1] + 0.5, hi[1] + 0.5]).all() for seg in segs]
        assert all(in_view)
        # in view: both ends within 0.5 m of the window
        ends = np.stack([src[s_idx, :2], tgt[t_idx, :2]], axis=1)
        box_lo, box_hi = np.array([lo[0], hi[0]]) - 0.5, np.array([lo[1], hi[1]]) + 0.5
        n_view = int(((ends >= box_lo) & (ends <= box_hi)).all(axis=(1, 2)).sum())
        assert tail == f"({min(n_view, pair.MAX_LINES)} of the {n_view} in view drawn)"
        assert len(segs) == min(n_view, pair.MAX_LINES)
        assert min(lines.get_linewidths()) >= 0.7 and lines.get_alpha() >= 0.8  # visible
        assert ax.get_ylabel() == "y [m]"
        scatter = ax.collections[:2]
        np.testing.assert_allclose(scatter[0].get_offsets(), src[:, :2])
        np.testing.assert_allclose(scatter[1].get_offsets(), tgt[:, :2])
        assert [_hex(s.get_facecolor()[0]) for s in scatter] == [_hex("0.65"), _hex("0.2")]
    assert bottom.get_xlabel() == "x [m] (sensor frame of frame k)"
    assert top.get_shared_x_axes().joined(top, bottom)  # the same window in both panels
    assert top.get_shared_y_axes().joined(top, bottom)
    assert fig.get_suptitle() == "twist, frames 1 -> 2"
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()] == [
        "frame k (source)", "frame k+1 (target)",
        "pair consistent with the true motion (< 0.5 m)", "pair inconsistent with it"]
    keys = legend.legend_handles  # the legend's keys look like what they name
    assert [_hex(h.get_color()) for h in keys] == [_hex("0.65"), _hex("0.2"), "#0072b2",
                                                   "#d55e00"]
    assert [h.get_marker() for h in keys[:2]] == ["o", "o"]
    assert [h.get_linestyle() for h in keys[:2]] == ["None", "None"]
    legend_in = legend.get_window_extent(fig.test_renderer).height / fig.dpi
    axes_in = 2 * 0.6 * 3.0 + 0.3  # two panels 0.6 x 3 in (the column less the labels)
    assert fig.get_figheight() == pytest.approx(axes_in + 0.75 + legend_in, abs=0.02)
    note = " ".join(legend.get_title().get_text().split("\n"))
    assert note == ("Zoom: the 30 m x 18 m window with the most pairs; closest points from "
                    "the identity within 3 m.")


def test_pair_figure_without_ground_truth_has_one_colour_and_no_share(store, tmp_path,
                                                                     monkeypatch):
    path, _ = store
    real = pair.pair_correspondences
    monkeypatch.setattr(pair, "pair_correspondences",
                        lambda s, f: {**real(s, f), "T_true": None})
    figs = capture(monkeypatch, pair)
    pair.plot_pair(path, 0, tmp_path, window_m=20.0)
    ((_, fig),) = figs
    data = pair.pair_correspondences(path, 0)
    for ax, key, title in zip(fig.axes, ("closest", "doppler"),
                              ("Closest point (ICP)", "Doppler Correspondence"), strict=True):
        assert ax.get_title().split("\n")[0] == f"{title}: {len(data[key][0])} pairs"
        assert {_hex(c) for c in ax.collections[-1].get_colors()} == {"#0072b2"}
        assert ax.get_xlim()[1] - ax.get_xlim()[0] == pytest.approx(20.0)
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()][2:] == ["pair (no ground truth)"]
    assert _hex(legend.legend_handles[2].get_color()) == "#0072b2"
    assert "the 20 m x 12 m window" in legend.get_title().get_text()


def test_pair_figure_draws_the_same_pairs_every_time(store, tmp_path, monkeypatch):
    path, _ = store
    figs = capture(monkeypatch, pair)
    pair.plot_pair(path, 0, tmp_path, window_m=60.0)
    pair.plot_pair(path, 0, tmp_path, window_m=60.0)
    (_, a), (_, b) = figs
    for ax_a, ax_b in zip(a.axes, b.axes, strict=True):
        np.testing.assert_array_equal(np.array(ax_a.collections[-1].get_segments()),
                                      np.array(ax_b.collections[-1].get_segments()))


def test_window_picks_the_placement_holding_the_most_points():
    """30 points at 0-2 m, one a metre from 3 to 49 m, 40 at 50-52 m (all at y = 0): a 30 m
    window holds at most 68 of them, from 22 to 52 m (40 + 28 against 30 + 28 at 0-30 m);
    it is centred on what it holds, at 37 m."""
    x = np.concatenate([np.linspace(0, 2, 30), np.arange(3.0, 50.0), np.linspace(50, 52, 40)])
    points = np.column_stack([x, np.zeros_like(x)])
    lo, hi = pair._window(points, 30.0, 4.0)
    np.testing.assert_allclose((lo + hi) / 2, [37.0, 0.0])
    np.testing.assert_allclose(hi - lo, [30.0, 4.0])
    swapped = pair._window(points[:, ::-1], 4.0, 30.0)  # the same along y
    np.testing.assert_allclose((swapped[0] + swapped[1]) / 2, [0.0, 37.0])
