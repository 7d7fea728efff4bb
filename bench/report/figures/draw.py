"""Paper figures from run folders (``bench figures RESULTS_DIR``, ``make figures``).

- ``trajectories/<sequence-slug>``: every method over the ground truth, top view (paper Fig. 5),
  always at equal scale in x and y (a long straight path gives a wide, short figure). Estimates
  are aligned at their first pose; the ground truth's start and end are marked; each method has
  its colour and each motion prior its line style and marker (with seed solid with circles, no
  seed dashed with crosses). The axes hold the ground truth and every run that did not
  diverge; a diverged run is drawn up to where it leaves them and labelled "Div.".
- ``velocity/<sequence-slug>``: the ego-velocity error along the path
  (``bench.report.figures.velocity``);
- ``forest/<sequence-slug>-<error>``: every method's figure on its 95 % interval at the
  shortest and longest length, marked as the tables mark them (``bench.report.figures.forest``);
- the error figures of ``bench.report.figures.errors`` (box plots per length, error along the
  path, per-frame time and correspondences) and, given a ``bench speed`` CSV, its scaling curves.
Every figure is written as PDF and PNG, one paper column (3.5 in) wide, legends below the axes,
file names made of readable slugs (``style.slug``).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from bench.report.figures.style import (
    COLUMN_IN,
    PRIOR_NOTE,
    SMALL_PT,
    color,
    div_labels,
    figure,
    legend_below,
    line_kwargs,
    run_name,
    run_order,
    save,
    set_title,
    slug,
    use_paper_style,
)
from bench.report.names import display_name, sequence_key
from bench.report.tables.row_keys import distinct_labels
from bench.runs.folders import BROKEN, RunRecord, load_runs
from loaders.se3 import inv_T
from methods.registry import Seed

#: height of the trajectory axes [in]: at least this (a straight path), at most that
_MIN_AXES_IN, _MAX_AXES_IN = 0.8, 3.0
#: room for tick labels and the y label beside the axes, and for the title and x label [in]
_SIDE_IN, _TOP_BOTTOM_IN = 0.5, 0.55


def _runs_with_gt(results_dir: Path) -> list[RunRecord]:
    """The finished runs with ground truth; a broken record is left out with a warning naming
    it; runs of one sequence whose legend names would be the same are told apart by what
    differs in their configurations (``bench.report.tables.row_keys``)."""
    import warnings

    runs = []
    for r in load_runs(results_dir, failed=True):
        if r.result.status == BROKEN:
            warnings.warn(f"left out of the figures: {r.result.error}", stacklevel=2)
        elif r.has_gt:
            runs.append(r)
    names = distinct_labels(runs, lambda r: r.label or display_name(r.method),
                            lambda r: (r.display_name, Seed.of(r.seed)), lambda r: r.config,
                            lambda r: r.dir)
    return [r if name == (r.label or display_name(r.method)) else
            replace(r, result=r.result.model_copy(update={"label": name}))
            for r, name in zip(runs, names, strict=True)]


def _aligned_xy(run: RunRecord) -> np.ndarray:
    T = run.gt[0] @ inv_T(run.est[0]) @ run.est
    return T[:, :2, 3]


def _limits(kept: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """x and y limits [m] around the kept paths with the same margin on both axes."""
    lo = np.min([k.min(axis=0) for k in kept], axis=0)
    hi = np.max([k.max(axis=0) for k in kept], axis=0)
    pad = max(0.05 * float(np.max(hi - lo)), 1.0)
    return lo - pad, hi + pad


def _axes_shape(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Limits widened to the axes' shape and the axes height [in]: the axes fill one column's
    width at equal scale, their height clamped (a straight path gets the minimum height and
    wider y limits, a tall path the maximum and wider x limits)."""
    span = hi - lo
    width_in = COLUMN_IN - _SIDE_IN
    height_in = float(np.clip(width_in * span[1] / span[0], _MIN_AXES_IN, _MAX_AXES_IN))
    want = np.array([span[0], span[0] * height_in / width_in])
    if want[1] < span[1]:
        want = np.array([span[1] * width_in / height_in, span[1]])
    mid = (lo + hi) / 2
    return mid - want / 2, mid + want / 2, height_in


def plot_sequence(sequence: str, runs: list[RunRecord], out_dir: Path) -> list[Path]:
    import matplotlib.pyplot as plt

    gt = runs[0].gt[:, :2, 3]
    finite = [r for r in sorted(runs, key=run_order) if np.all(np.isfinite(r.est))]
    kept = [gt] + [_aligned_xy(r) for r in finite if not r.diverged]
    lo, hi = _limits(kept)
    lo_ax, hi_ax, axes_in = _axes_shape(lo, hi)
    # a first guess of the figure's height; the legend's real height is added below
    fig, ax = figure(axes_in + _TOP_BOTTOM_IN)
    ax.plot(gt[:, 0], gt[:, 1], color="black", lw=1.4, label="ground truth", zorder=1)
    ax.plot(*gt[0], "o", color="black", ms=4, mfc="white", zorder=5)
    ax.plot(*gt[-1], "s", color="black", ms=4, zorder=5)
    labels: list[list] = []  # [x, y, colour, count] of each "Div." label
    near = 0.06 * float(np.max(hi_ax - lo_ax))
    for k, run in enumerate(finite):
        xy = _aligned_xy(run)
        inside = ((xy >= lo) & (xy <= hi)).all(axis=1)
        # a run that leaves the axes is drawn up to where it first leaves them
        shown = xy if inside.all() else xy[: max(1, int(np.argmin(inside)))]
        name = run_name(run) + (" - Div." if run.diverged else "")
        ax.plot(shown[:, 0], shown[:, 1], alpha=0.9, label=name, zorder=2,
                **line_kwargs(run, k, len(finite)))
        if not inside.all():  # one label for runs that leave at about the same place
            x, y = shown[-1]
            for lab in labels:
                if np.hypot(lab[0] - x, lab[1] - y) <= near:
                    lab[3] += 1
                    break
            else:
                labels.append([x, y, color(run.method), 1])
    ax.set_xlim(lo_ax[0], hi_ax[0])
    ax.set_ylim(lo_ax[1], hi_ax[1])
    ax.set_aspect("equal", adjustable="box")  # one metre is as long in x as in y
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    set_title(ax, f"{sequence} (\u25cb start, \u25a0 end)")
    handles, names = ax.get_legend_handles_labels()
    legend_below(fig, handles, names, note=PRIOR_NOTE)
    legend_in = fig.legends[0].get_window_extent(fig.canvas.get_renderer()).height / fig.dpi
    fig.set_figheight(axes_in + _TOP_BOTTOM_IN + legend_in + 0.1)
    # labels that would touch are merged (style.div_labels), drawn at the final size
    div_labels(ax, [tuple(lab) for lab in labels], (2, 2), SMALL_PT)
    paths = save(fig, out_dir / "trajectories" / slug(sequence))
    plt.close(fig)
    return paths


def plot_trajectories(results_dir: Path, out_dir: Path | None = None,
                      runs: list[RunRecord] | None = None) -> list[Path]:
    """One trajectory figure per sequence (of ``runs``, default the folder's runs with ground
    truth); returns the written files."""
    use_paper_style()
    out_dir = Path(out_dir or Path(results_dir) / "figures")
    groups: dict[str, list[RunRecord]] = {}
    for run in _runs_with_gt(results_dir) if runs is None else runs:
        if len(run.gt) >= 2:
            groups.setdefault(run.display_name, []).append(run)
    written = []
    for sequence in sorted(groups, key=sequence_key):
        written += plot_sequence(sequence, groups[sequence], out_dir)
    return written


def make_figures(results_dir: Path, out_dir: Path | None = None,
                 speed_csv: Path | None = None) -> list[Path]:
    """Every figure of a results folder (and of a ``bench speed`` CSV when given)."""
    from bench import guard
    from bench.report.figures.drift import plot_drift
    from bench.report.figures.errors import (
        plot_boxplots,
        plot_error_along_path,
        plot_frames,
        plot_speed_csv,
    )
    from bench.report.figures.forest import plot_forest
    from bench.report.figures.velocity import plot_velocity_along_path
    from bench.report.tables.paper import runs as table_rows

    out_dir = Path(out_dir or Path(results_dir) / "figures")
    guard.output_folder(out_dir)  # a folder of figures, never a run's own nor inside one
    runs = _runs_with_gt(results_dir)
    written = plot_trajectories(results_dir, out_dir, runs)
    written += plot_boxplots(runs, out_dir)
    written += plot_error_along_path(runs, out_dir)
    written += plot_frames(runs, out_dir)
    written += plot_drift(runs, out_dir)
    written += plot_velocity_along_path(runs, out_dir)
    written += plot_forest(table_rows(results_dir), out_dir)
    if speed_csv is not None and Path(speed_csv).exists():
        written += plot_speed_csv(Path(speed_csv), out_dir)
    return written
