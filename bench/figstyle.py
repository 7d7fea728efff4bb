"""Shared style and data of the paper figures: one colour per method across every figure,
paper-column sizes, display names as in the tables, and run folders read as paired arrays."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from bench.names import PAPER_ORDER, long_name
from loaders.fileio import atomic_path
from loaders.scan import Trajectory

COLUMN_IN = 3.5  # one paper column [inch]
PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#bcbd22", "#7f7f7f"]


def color(method: str) -> str:
    """The method's colour, the same in every figure."""
    i = PAPER_ORDER.index(method) if method in PAPER_ORDER else len(PAPER_ORDER)
    return PALETTE[i % len(PALETTE)]


def run_label(method: str, seed: bool | None, label: str | None = None) -> str:
    name = label or long_name(method)
    return name if seed is None else f"{name} ({'seed' if seed else 'no seed'})"


def use_paper_style() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 7, "axes.titlesize": 7, "axes.labelsize": 7,
                         "legend.fontsize": 6, "xtick.labelsize": 6, "ytick.labelsize": 6,
                         "lines.linewidth": 1.0, "axes.grid": True, "grid.alpha": 0.3})


def save(fig, path_stem: Path) -> list[Path]:
    """Write ``path_stem``.pdf and .png atomically; returns both paths."""
    import matplotlib.pyplot as plt

    path_stem.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in ("pdf", "png"):
        path = path_stem.with_suffix(f".{fmt}")
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=200, bbox_inches="tight")
        paths.append(path)
    plt.close(fig)
    return paths


@dataclass
class Run:
    """A finished run with ground truth, its poses paired by stamp."""

    dir: Path
    sequence: str
    sensor_class: str
    method: str
    seed: bool | None
    label: str | None
    diverged: bool
    stamps: np.ndarray
    gt: np.ndarray    # (N, 4, 4) T_world_sensor at the scored scans
    est: np.ndarray   # (N, 4, 4) estimates at the same stamps

    @property
    def name(self) -> str:
        return run_label(self.method, self.seed, self.label)


def load_runs_with_gt(results_dir: Path) -> list[Run]:
    runs = []
    for metrics_path in sorted(Path(results_dir).rglob("metrics.json")):
        d = metrics_path.parent
        if not (d / "gt_tum.txt").exists():
            continue
        m = json.loads(metrics_path.read_text())
        cfg = yaml.safe_load((d / "config.yaml").read_text()) if (d / "config.yaml").exists() \
            else {}
        gt = Trajectory.read_tum(d / "gt_tum.txt")
        est = Trajectory.read_tum(d / "est_tum.txt")
        idx = np.searchsorted(est.stamps, gt.stamps).clip(0, len(est) - 1)
        keep = np.abs(est.stamps[idx] - gt.stamps) < 1e-6
        seq = cfg.get("sequence", {})
        runs.append(Run(d, seq.get("display_name") or m["sequence"],
                        seq.get("sensor_class", "4D sensor"), m["method"], m["seed"],
                        cfg.get("label"), bool(m.get("diverged")), gt.stamps[keep],
                        gt.poses[keep], est.poses[idx[keep]]))
    return runs
