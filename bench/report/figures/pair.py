"""One scan pair, closest-point versus Doppler correspondences (the paper's Figs. 1 and 8):
``bench figures --pair STORE FRAME`` draws frame FRAME (source, light grey) and FRAME+1
(target, dark grey) from above with the pairs as lines: top, the closest target point of each
source point within 3 m (point-to-point ICP's first correspondences, from the identity); bottom,
Doppler Correspondence's pairs (Algorithm 2's matching and masks). Pairs between consecutive
scans are a few metres long, so both panels show the same zoomed window (30 m wide, where the
pairs are densest) and at most 300 of its pairs. With ground truth, a pair is blue when the
true motion brings the source point within 0.5 m of its partner, else vermillion, and the share
of consistent pairs is in each title. One column wide, written as
``pairs/<store-slug>-frame-<FRAME>.{pdf,png}``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import small_gicp

from bench.report.figures.style import (
    COLUMN_IN,
    FONT_PT,
    SMALL_PT,
    figure,
    fit_height,
    legend_below,
    save,
    slug,
    use_paper_style,
)
from loaders.errors import DataError
from loaders.se3 import inv_T, transform_points
from loaders.sensor_classes import is_synthetic
from loaders.store import StoreSequence
from methods.doppler import DopplerCorrespondence, doppler_pairs

MAX_LINES = 300   # pairs drawn per panel (a random subset of those in view)
WINDOW_M = 30.0   # width of the zoomed window [m]
GOOD_M = 0.5      # a pair is consistent when the true motion brings it within this [m]
_GOOD, _BAD = "#0072B2", "#D55E00"  # blue / vermillion: told apart with any colour vision


def pair_correspondences(store: Path, frame: int) -> dict:
    seq = StoreSequence(store)
    try:
        if not 0 <= frame < len(seq) - 1:
            raise DataError(f"{store}: frame {frame} has no next frame (0..{len(seq) - 2})")
        from bench.data.advice import doppler_refusal

        refusal = doppler_refusal(store, "Doppler Correspondence's pairs", seq)
        if refusal is not None:  # the words bench run refuses such a store with
            raise DataError(refusal)
        src, tgt = seq[frame], seq[frame + 1]
        if src.doppler is None:
            raise DataError(f"{store}, frame {frame}: no Doppler values")
        dc = DopplerCorrespondence(backend="numpy")  # the paper's gates (its defaults)
        gate_m = dc.params.tau_spatial_m
        s_idx, t_idx = doppler_pairs(dc.preprocess(src), dc.preprocess(tgt), gate_m,
                                     dc.params.tau_doppler)
        idx, sq = small_gicp.KdTree(tgt.points).batch_knn_search(src.points, 1)
        idx = np.asarray(idx).astype(np.int64).ravel()
        near = np.asarray(sq).ravel() <= gate_m**2
        T_true = None
        gt = seq.ground_truth
        if gt is not None:
            at = {round(t, 6): k for k, t in enumerate(gt.stamps)}
            a, b = at.get(round(src.stamp, 6)), at.get(round(tgt.stamp, 6))
            if a is not None and b is not None:
                T_true = inv_T(gt.poses[b]) @ gt.poses[a]  # T_target_source
        return {"source": src.points, "target": tgt.points, "T_true": T_true,
                "closest": (np.flatnonzero(near), idx[near]), "doppler": (s_idx, t_idx),
                "name": f"{seq.name}{' (synthetic)' if is_synthetic(seq.provenance) else ''}, "
                        f"frames {frame} -> {frame + 1}"}
    finally:
        seq.close()


def _window(points_xy: np.ndarray, width_m: float, height_m: float,
            cell_m: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The width x height window [m] (lower and upper corner) holding the most of the points:
    pairs between consecutive scans are a few metres long, so only a zoom shows them."""
    if not len(points_xy):
        return np.array([-width_m / 2, -height_m / 2]), np.array([width_m / 2, height_m / 2])
    lo = points_xy.min(axis=0)
    cells = np.floor((points_xy - lo) / cell_m).astype(int)
    grid = np.zeros(cells.max(axis=0) + 1)
    np.add.at(grid, (cells[:, 0], cells[:, 1]), 1)
    w, h = max(1, int(width_m / cell_m)), max(1, int(height_m / cell_m))
    padded = np.zeros((grid.shape[0] + w, grid.shape[1] + h))
    padded[:grid.shape[0], :grid.shape[1]] = grid
    c = np.pad(padded.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    sums = c[w:, h:] - c[:-w, h:] - c[w:, :-h] + c[:-w, :-h]  # points in the window at (i, j)
    i, j = np.unravel_index(int(np.argmax(sums[:grid.shape[0], :grid.shape[1]])),
                            grid[:, :].shape)
    corner = lo + np.array([i, j]) * cell_m
    size = np.array([width_m, height_m])
    inside = points_xy[((points_xy >= corner) & (points_xy <= corner + size)).all(axis=1)]
    mid = (inside.min(axis=0) + inside.max(axis=0)) / 2  # centred on what it holds
    return mid - size / 2, mid + size / 2


def plot_pair(store: Path, frame: int, out_dir: Path, window_m: float = WINDOW_M) -> list[Path]:
    """The pair figure of ``store``'s frames ``frame`` -> ``frame + 1``, one column wide: both
    kinds of correspondences in the same ``window_m`` wide window (the one with the most
    pairs), at most ``MAX_LINES`` pairs drawn per panel."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    use_paper_style()
    data = pair_correspondences(store, frame)
    src, tgt = data["source"], data["target"]
    height_m = window_m * 0.6
    paired = np.concatenate([src[data[k][0], :2] for k in ("closest", "doppler")])
    lo, hi = _window(paired, window_m, height_m)
    pad = 0.5
    fig, axes = figure(2 * 0.6 * (COLUMN_IN - 0.5) + 1.2, 2, 1, sharex=True, sharey=True)
    rng = np.random.default_rng(0)
    has_gt = data["T_true"] is not None
    for ax, key, title in zip(axes, ("closest", "doppler"),
                              ("Closest point (ICP)", "Doppler Correspondence"),
                              strict=True):
        s_idx, t_idx = data[key]
        good = np.ones(len(s_idx), bool)
        if has_gt and len(s_idx):
            moved = transform_points(data["T_true"], src[s_idx])
            good = np.linalg.norm(moved - tgt[t_idx], axis=1) < GOOD_M
        ends = np.stack([src[s_idx, :2], tgt[t_idx, :2]], axis=1)
        in_view = np.flatnonzero(((ends >= lo - pad) & (ends <= hi + pad)).all(axis=(1, 2)))
        pick = rng.permutation(in_view)[:MAX_LINES]
        for pts, shade, mk in ((src, "0.65", "o"), (tgt, "0.2", "o")):
            ax.scatter(pts[:, 0], pts[:, 1], s=0.6, color=shade, lw=0, zorder=1, marker=mk,
                       rasterized=True)
        colors = [_GOOD if g else _BAD for g in good[pick]]
        ax.add_collection(LineCollection(ends[pick], colors=colors, linewidths=0.8,
                                         alpha=0.9, zorder=3))
        share = f", {good.mean():.0%} consistent" if has_gt and len(s_idx) else ""
        ax.set_title(f"{title}: {len(s_idx)} pairs{share}\n({len(pick)} of the "
                     f"{len(in_view)} in view drawn)", fontsize=SMALL_PT)
        ax.set_ylabel("y [m]")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
    axes[-1].set_xlabel("x [m] (sensor frame of frame k)")
    handles = [Line2D([], [], ls="", marker="o", ms=3, color="0.65", label="frame k (source)"),
               Line2D([], [], ls="", marker="o", ms=3, color="0.2", label="frame k+1 (target)")]
    if has_gt:
        handles += [Line2D([], [], color=_GOOD, lw=1.2,
                           label=f"pair consistent with the true motion (< {GOOD_M:g} m)"),
                    Line2D([], [], color=_BAD, lw=1.2, label="pair inconsistent with it")]
    else:
        handles += [Line2D([], [], color=_GOOD, lw=1.2, label="pair (no ground truth)")]
    fig.suptitle(data["name"], fontsize=FONT_PT)
    legend_below(fig, handles, [h.get_label() for h in handles],
                 note=f"Zoom: the {window_m:g} m x {height_m:g} m window with the most pairs; "
                 "closest points from the identity within 3 m.")
    fit_height(fig, 2 * 0.6 * (COLUMN_IN - 0.5) + 0.3)
    return save(fig, out_dir / "pairs" / f"{slug(Path(store).stem)}-frame-{frame}")
