"""Error and timing figures: relative error box plots per segment length by sensor class
(paper Fig. 6, rpg_trajectory_evaluation style), error along the path, per-frame time and
correspondences, and ``bench speed``'s scaling curves with p5-p95 bands."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from bench.report.figstyle import COLUMN_IN, color, run_name, save, use_paper_style
from bench.report.names import display_name
from bench.runs.folders import RunRecord
from loaders.se3 import inv_T, rotation_angle_deg
from metrics.relative import DEFAULT_LENGTHS_M, MetricError, path_distances, segment_errors


def plot_boxplots(runs: list[RunRecord], out_dir: Path,
                  lengths_m=DEFAULT_LENGTHS_M) -> list[Path]:
    """Per sensor class: translation [m] and rotation [deg] relative errors per length, one
    box per run name (all sequences of the class pooled; diverged runs left out)."""
    import matplotlib.pyplot as plt

    use_paper_style()
    written = []
    for klass in sorted({r.sensor_class for r in runs}):
        by_name: dict[str, tuple[str, dict]] = {}
        for run in (r for r in runs if r.sensor_class == klass and not r.diverged):
            entry = by_name.setdefault(run_name(run),
                                       (run.method, {L: ([], []) for L in lengths_m}))
            for length in lengths_m:
                try:
                    seg = segment_errors(run.gt, run.est, length)
                except MetricError:
                    continue
                entry[1][length][0].extend(seg.trans_m)
                entry[1][length][1].extend(seg.rot_deg)
        if not by_name:
            continue
        fig, axes = plt.subplots(2, 1, figsize=(COLUMN_IN * 1.6, 3.6), sharex=True)
        names = sorted(by_name)
        width = 0.8 / len(names)
        for k, name in enumerate(names):
            method, data = by_name[name]
            pos = np.arange(len(lengths_m)) + (k - (len(names) - 1) / 2) * width
            for ax, part in zip(axes, (0, 1), strict=True):
                values = [data[L][part] or [np.nan] for L in lengths_m]
                bp = ax.boxplot(values, positions=pos, widths=width * 0.9, showfliers=False,
                                patch_artist=True, manage_ticks=False,
                                medianprops={"color": "black", "linewidth": 0.8})
                for box in bp["boxes"]:
                    box.set(facecolor=color(method), alpha=0.6 if "no seed" in name else 0.9)
            axes[0].plot([], [], color=color(method), lw=6, label=name)
        axes[0].set_ylabel("translation error [m]")
        axes[1].set_ylabel("rotation error [deg]")
        axes[1].set_xticks(range(len(lengths_m)), [f"{L:g}" for L in lengths_m])
        axes[1].set_xlabel("segment length [m]")
        axes[0].set_title(f"{klass}: relative error per segment length")
        axes[0].legend(ncol=2, loc="upper left", frameon=False)
        written += save(fig, out_dir / "boxplots" / klass.replace(" ", "_"))
    return written


def plot_error_along_path(runs: list[RunRecord], out_dir: Path) -> list[Path]:
    """Per sequence: translation [m] and rotation [deg] error of each frame against the
    distance travelled [m], estimates aligned at the first pose."""
    import matplotlib.pyplot as plt

    use_paper_style()
    written = []
    for sequence in sorted({r.display_name for r in runs}):
        group = [r for r in runs if r.display_name == sequence and np.all(np.isfinite(r.est))]
        if not group:
            continue
        fig, axes = plt.subplots(2, 1, figsize=(COLUMN_IN, 3.0), sharex=True)
        for run in group:
            E = inv_T(inv_T(run.gt[0]) @ run.gt) @ (inv_T(run.est[0]) @ run.est)
            dist = path_distances(run.gt[:, :3, 3])
            ls = "--" if run.seed is False else "-"
            axes[0].plot(dist, np.linalg.norm(E[:, :3, 3], axis=1), ls, color=color(run.method),
                         label=run_name(run) + (" - Div." if run.diverged else ""))
            axes[1].plot(dist, rotation_angle_deg(E[:, :3, :3]), ls, color=color(run.method))
        axes[0].set_yscale("symlog", linthresh=0.1)
        axes[0].set_ylabel("translation error [m]")
        axes[1].set_ylabel("rotation error [deg]")
        axes[1].set_xlabel("distance travelled [m]")
        axes[0].set_title(f"{sequence}: error along the path")
        _legend_below(axes)
        written += save(fig, out_dir / "error_along_path" / _safe(sequence))
    return written


def plot_frames(runs: list[RunRecord], out_dir: Path) -> list[Path]:
    """Per sequence: registration time [ms] and correspondences per frame (frames.csv)."""
    import matplotlib.pyplot as plt

    use_paper_style()
    written = []
    for sequence in sorted({r.display_name for r in runs}):
        fig, axes = plt.subplots(2, 1, figsize=(COLUMN_IN, 3.0), sharex=True)
        for run in (r for r in runs if r.display_name == sequence):
            rows = list(csv.DictReader((run.dir / "frames.csv").open()))[1:]
            idx = [int(r["index"]) for r in rows]
            ls = "--" if run.seed is False else "-"
            axes[0].plot(idx, [float(r["time_ms"]) for r in rows], ls, color=color(run.method),
                         label=run_name(run), lw=0.6)
            axes[1].plot(idx, [int(r["correspondences"]) for r in rows], ls, lw=0.8,
                         color=color(run.method))
        axes[0].set_yscale("log")
        axes[0].set_ylabel("time per frame [ms]")
        axes[1].set_ylabel("correspondences")
        axes[1].set_xlabel("frame")
        axes[0].set_title(f"{sequence}: per-frame time and correspondences")
        _legend_below(axes)
        written += save(fig, out_dir / "frames" / _safe(sequence))
    return written


def plot_speed_csv(path: Path, out_dir: Path) -> list[Path]:
    """``bench speed``'s LiDAR scaling curves: median time per frame [ms] against input
    points, with the p5-p95 band of the repeats."""
    import matplotlib.pyplot as plt

    use_paper_style()
    rows = [r for r in csv.DictReader(path.open()) if r["scenario"] == "lidar"]
    fig, ax = plt.subplots(figsize=(COLUMN_IN, 2.6))
    for method in dict.fromkeys(r["method"] for r in rows):
        pts = sorted((int(r["points"]), float(r["median_ms"]), float(r["p5_ms"]),
                      float(r["p95_ms"])) for r in rows if r["method"] == method)
        n, med, lo, hi = (np.array(v) for v in zip(*pts, strict=True))
        ax.loglog(n, med, "o-", ms=3, color=color(method), label=display_name(method))
        ax.fill_between(n, lo, hi, color=color(method), alpha=0.2, lw=0)
    ax.set_xlabel("input points per scan")
    ax.set_ylabel("registration time per frame [ms]")
    ax.set_title("speed scaling (median, p5-p95 band)")
    ax.legend(ncol=2, frameon=False, fontsize=5)
    return save(fig, out_dir / "speed")


def _legend_below(axes) -> None:
    handles, labels = axes[0].get_legend_handles_labels()
    axes[-1].legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.35), ncol=2,
                    frameon=False)


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
