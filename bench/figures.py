"""Paper-style figures from run folders: top-view trajectories per sequence (paper Fig. 4).

Each estimate is aligned to the ground truth at its first pose (origin alignment), as the
odometry is drawn in the paper; diverged runs are drawn dashed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from bench.tables import method_label
from loaders.fileio import atomic_path
from loaders.scan import Trajectory
from loaders.se3 import inv_T


def _runs_by_sequence(results_dir: Path) -> dict[str, list[Path]]:
    groups: dict[str, list[Path]] = {}
    for metrics in sorted(Path(results_dir).rglob("metrics.json")):
        run_dir = metrics.parent
        if (run_dir / "gt_tum.txt").exists():
            groups.setdefault(run_dir.parent.name, []).append(run_dir)
    return groups


def plot_trajectories(results_dir: Path, out_dir: Path | None = None) -> list[Path]:
    """One PNG per sequence plus ``trajectories.png`` with all of them; returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir or Path(results_dir) / "figures")
    groups = _runs_by_sequence(results_dir)
    if not groups:
        return []
    cols = min(5, len(groups))
    rows = math.ceil(len(groups) / cols)
    grid, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.4 * rows), squeeze=False)
    written = []
    for k, (sequence, run_dirs) in enumerate(groups.items()):
        fig, ax = plt.subplots(figsize=(5, 4.5))
        for target in (ax, axes[k // cols][k % cols]):
            _draw(target, sequence, run_dirs)
        ax.legend(fontsize=7, loc="best")
        fig.tight_layout()
        path = out_dir / f"{sequence}.png"
        _save(fig, path)
        written.append(path)
        plt.close(fig)
    for k in range(len(groups), rows * cols):
        axes[k // cols][k % cols].axis("off")
    axes[0][0].legend(fontsize=6, loc="best")
    grid.tight_layout()
    _save(grid, out_dir / "trajectories.png")
    plt.close(grid)
    return [out_dir / "trajectories.png", *written]


def _draw(ax, sequence: str, run_dirs: list[Path]) -> None:
    gt = Trajectory.read_tum(run_dirs[0] / "gt_tum.txt").positions
    ax.plot(gt[:, 0], gt[:, 1], color="black", lw=2.0, label="ground truth")
    for run_dir in run_dirs:
        metrics = json.loads((run_dir / "metrics.json").read_text())
        gt_T = Trajectory.read_tum(run_dir / "gt_tum.txt").poses
        est_T = Trajectory.read_tum(run_dir / "est_tum.txt").poses
        if not np.all(np.isfinite(est_T)):
            continue
        aligned = gt_T[0] @ inv_T(est_T[0]) @ est_T
        ax.plot(aligned[:, 0, 3], aligned[:, 1, 3], lw=1.0,
                ls="--" if metrics.get("diverged") else "-",
                label=method_label(metrics["method"], metrics["seed"])
                + (" (Div.)" if metrics.get("diverged") else ""))
    span = np.ptp(gt[:, :2], axis=0).max() if len(gt) > 1 else 1.0
    center = gt[:, :2].mean(axis=0)
    ax.set_xlim(center[0] - 0.65 * span, center[0] + 0.65 * span)
    ax.set_ylim(center[1] - 0.65 * span, center[1] + 0.65 * span)
    ax.set_aspect("equal")
    ax.set_title(sequence, fontsize=9)
    ax.set_xlabel("x [m]", fontsize=8)
    ax.set_ylabel("y [m]", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
