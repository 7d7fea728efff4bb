"""Paper figures from run folders (``bench figures RESULTS_DIR``, ``make figures``).

- ``trajectories/<sequence>``: every method over the ground truth, top view (paper Fig. 5).
  Estimates are aligned at their first pose; start and end are marked; with-seed runs are
  solid and no-seed runs dashed so neither hides the other; the axes follow the ground truth
  (equal scale unless the path is very elongated), and a diverged run is clipped to them and
  labelled "Div.".
- the error figures of ``bench.report.figures_errors`` (box plots per length, error along the path,
  per-frame time and correspondences) and, given a ``bench speed`` CSV, its scaling curves.
Every figure is written as PDF and PNG, one paper column wide, one colour per method.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.report.figstyle import COLUMN_IN, color, run_name, save, use_paper_style
from bench.runs.folders import RunRecord, load_runs
from loaders.se3 import inv_T


def _runs_with_gt(results_dir: Path) -> list[RunRecord]:
    return [r for r in load_runs(results_dir) if r.has_gt]


def _aligned_xy(run: RunRecord) -> np.ndarray:
    T = run.gt[0] @ inv_T(run.est[0]) @ run.est
    return T[:, :2, 3]


def plot_sequence(sequence: str, runs: list[RunRecord], out_dir: Path) -> list[Path]:
    import matplotlib.pyplot as plt

    gt = runs[0].gt[:, :2, 3]
    # the axes hold the ground truth and every run that did not diverge; per-axis margins,
    # so lateral errors stay visible on a long straight path
    kept = [gt] + [_aligned_xy(r) for r in runs
                   if not r.diverged and np.all(np.isfinite(r.est))]
    lo, hi = np.min([k.min(axis=0) for k in kept], 0), np.max([k.max(axis=0) for k in kept], 0)
    span = np.maximum(hi - lo, 1.0)
    pad = np.maximum(0.08 * span, 2.0)
    elongated = span.max() / span.min() > 4
    width = COLUMN_IN
    height = COLUMN_IN * (0.55 if elongated else min(1.0, max(0.5, span[1] / span[0])))
    fig, ax = plt.subplots(figsize=(width, height + 0.5))
    ax.plot(gt[:, 0], gt[:, 1], color="black", lw=1.6, label="ground truth", zorder=1)
    ax.plot(*gt[0], "o", color="black", ms=4, zorder=5)
    ax.plot(*gt[-1], "s", color="black", ms=4, zorder=5)
    xlim = (lo[0] - pad[0], hi[0] + pad[0])
    ylim = (lo[1] - pad[1], hi[1] + pad[1])
    for run in sorted(runs, key=lambda r: (r.method, r.seed is False)):
        if not np.all(np.isfinite(run.est)):
            continue
        xy = _aligned_xy(run)
        inside = ((xy[:, 0] >= xlim[0]) & (xy[:, 0] <= xlim[1]) & (xy[:, 1] >= ylim[0])
                  & (xy[:, 1] <= ylim[1]))
        # a run that leaves the axes is drawn up to where it leaves them (clipped, labelled)
        shown = xy if inside.all() else xy[: max(1, int(np.argmin(inside)))]
        name = run_name(run) + (" - Div." if run.diverged else "")
        ax.plot(shown[:, 0], shown[:, 1], color=color(run.method),
                ls="--" if run.seed is False else "-", alpha=0.9, label=name, zorder=2)
        if inside.all():
            ax.plot(*xy[-1], "s", color=color(run.method), ms=3, zorder=4)
        else:
            ax.annotate("Div.", shown[-1], fontsize=6, color=color(run.method))
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    if not elongated:
        ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{sequence} (o start, \u25a0 end)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2, frameon=False)
    return save(fig, out_dir / "trajectories" / _safe(sequence))


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def plot_trajectories(results_dir: Path, out_dir: Path | None = None) -> list[Path]:
    """One trajectory figure per sequence; returns the written files."""
    use_paper_style()
    out_dir = Path(out_dir or Path(results_dir) / "figures")
    groups: dict[str, list[RunRecord]] = {}
    for run in _runs_with_gt(results_dir):
        if len(run.gt) >= 2:
            groups.setdefault(run.display_name, []).append(run)
    written = []
    for sequence, runs in sorted(groups.items()):
        written += plot_sequence(sequence, runs, out_dir)
    return written


def make_figures(results_dir: Path, out_dir: Path | None = None,
                 speed_csv: Path | None = None) -> list[Path]:
    """Every figure of a results folder (and of a ``bench speed`` CSV when given)."""
    from bench.report.figures_errors import (
        plot_boxplots,
        plot_error_along_path,
        plot_frames,
        plot_speed_csv,
    )

    out_dir = Path(out_dir or Path(results_dir) / "figures")
    written = plot_trajectories(results_dir, out_dir)
    runs = _runs_with_gt(results_dir)
    written += plot_boxplots(runs, out_dir)
    written += plot_error_along_path(runs, out_dir)
    written += plot_frames(runs, out_dir)
    if speed_csv is not None and Path(speed_csv).exists():
        written += plot_speed_csv(Path(speed_csv), out_dir)
    return written
