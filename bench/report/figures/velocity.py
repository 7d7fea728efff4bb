"""Ego-velocity error along the path (``velocity/<sequence-slug>``): per sequence, the norm of
each run's velocity error [m/s] against the distance travelled [m], with the velocity over the
same windows as ``metrics.json``'s ``velocity`` (``metrics.velocity``: the relative translation
to the first frame at least ``window_s`` later, in the sensor frame, over the time between); the
GT speed on a second axis for scale. A diverged run is left out and named under the figure."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from bench.report.figures.style import (
    figure,
    legend_below,
    line_kwargs,
    run_name,
    run_order,
    save,
    slug,
    use_paper_style,
)
from bench.report.names import sequence_key
from metrics.relative import path_distances
from metrics.velocity import DEFAULT_WINDOW_S, velocity_series


def plot_velocity_along_path(runs, out_dir: Path) -> list[Path]:
    """One figure per sequence of the runs (``bench.runs.folders.RunRecord``s with ground
    truth); returns the written paths."""
    use_paper_style()
    written = []
    for sequence in sorted({r.display_name for r in runs}, key=sequence_key):
        group = sorted((r for r in runs if r.display_name == sequence and len(r.gt) >= 3),
                       key=run_order)
        shown = [r for r in group if not r.diverged and np.all(np.isfinite(r.est))]
        if not shown:
            continue
        window = next((r.result.velocity.window_s for r in shown if r.result.velocity),
                      DEFAULT_WINDOW_S)
        fig, (ax, speed_ax) = figure(3.0, 2, 1, sharex=True, height_ratios=(3, 1))
        handles, labels = [], []
        for k, run in enumerate(shown):
            series = velocity_series(run.gt, run.est, run.stamps, window)
            dist = path_distances(run.gt[:, :3, 3])[series.start_idx]
            line, = ax.plot(dist, np.linalg.norm(series.error_mps, axis=1),
                            **line_kwargs(run, k, len(shown), points=len(dist)))
            handles.append(line)
            labels.append(run_name(run))
            if k == 0:
                speed_ax.plot(dist, np.linalg.norm(series.gt_mps, axis=1), color="black",
                              lw=0.8)
        ax.set_ylabel("velocity error [m/s]")
        speed_ax.set_ylabel("GT speed\n[m/s]")
        speed_ax.set_xlabel("distance travelled [m]")
        ax.set_title("\n".join(textwrap.wrap(
            f"{sequence}: ego-velocity error (sensor frame, {window:g} s windows)", 56)))
        gone = [run_name(r) for r in group if r not in shown]
        legend_below(fig, handles, labels,
                     note=("Not shown (diverged): " + "; ".join(gone)) if gone else "")
        written += save(fig, out_dir / "velocity" / slug(sequence))
    return written
