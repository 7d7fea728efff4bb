"""One scan pair, closest-point versus Doppler correspondences (the paper's Figs. 1 and 8):
``bench figures --pair STORE FRAME`` draws frame FRAME (source) and FRAME+1 (target) from
above with the pairs as lines: left, the closest target point of each source point within
3 m (point-to-point ICP's first correspondences, from the identity); right, Doppler
Correspondence's pairs (Algorithm 2's matching and masks). With ground truth, a pair is green
when the true motion brings the source point within 0.5 m of its partner, else red, and the
share of good pairs is in each title."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import small_gicp

from bench.report.figstyle import COLUMN_IN, save, use_paper_style
from loaders.errors import DataError
from loaders.se3 import inv_T, transform_points
from loaders.store import StoreSequence
from methods.doppler import DopplerCorrespondence, doppler_pairs

MAX_LINES = 400


def pair_correspondences(store: Path, frame: int) -> dict:
    seq = StoreSequence(store)
    try:
        if not 0 <= frame < len(seq) - 1:
            raise DataError(f"{store}: frame {frame} has no next frame (0..{len(seq) - 2})")
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
                "name": f"{seq.name}, frames {frame} -> {frame + 1}"}
    finally:
        seq.close()


def plot_pair(store: Path, frame: int, out_dir: Path) -> list[Path]:
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    use_paper_style()
    data = pair_correspondences(store, frame)
    src, tgt = data["source"], data["target"]
    span = np.ptp(src[:, :2], axis=0) + 1e-9
    elongated = span.max() / span.min() > 3
    fig, axes = (plt.subplots(2, 1, figsize=(COLUMN_IN * 2, COLUMN_IN * 1.3)) if elongated
                 else plt.subplots(1, 2, figsize=(COLUMN_IN * 2, COLUMN_IN * 1.1)))
    rng = np.random.default_rng(0)
    for ax, key, title in zip(axes, ("closest", "doppler"),
                              ("closest point (ICP)", "Doppler Correspondence"), strict=True):
        s_idx, t_idx = data[key]
        good = np.ones(len(s_idx), bool)
        if data["T_true"] is not None and len(s_idx):
            moved = transform_points(data["T_true"], src[s_idx])
            good = np.linalg.norm(moved - tgt[t_idx], axis=1) < 0.5
        pick = rng.permutation(len(s_idx))[:MAX_LINES]
        segs = np.stack([src[s_idx[pick], :2], tgt[t_idx[pick], :2]], axis=1)
        ax.scatter(src[:, 0], src[:, 1], s=0.15, color="#1f77b4", alpha=0.4, zorder=1,
                   label="source (frame k)")
        ax.scatter(tgt[:, 0], tgt[:, 1], s=0.15, color="#ff7f0e", alpha=0.4, zorder=1,
                   label="target (frame k+1)")
        ax.add_collection(LineCollection(segs, colors=np.where(good[pick, None],
                                                               [[0.1, 0.6, 0.1, 0.7]],
                                                               [[0.85, 0.1, 0.1, 0.7]]),
                                         linewidths=0.7, zorder=3))
        share = f" ({good.mean():.0%} consistent with the true motion)" if len(s_idx) else ""
        ax.set_title(f"{title}\n{len(s_idx)} pairs{share}")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if not elongated:
            ax.set_aspect("equal", adjustable="datalim")
    axes[0].legend(loc="upper right", markerscale=8, frameon=False)
    fig.suptitle(data["name"] + " (lines: a random subset of the pairs)", fontsize=7)
    return save(fig, out_dir / "pairs" / f"{Path(store).stem}_frame{frame}")
