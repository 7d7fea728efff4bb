"""Error and timing figures: relative error box plots per segment length by sensor class
(paper Fig. 6, rpg_trajectory_evaluation style), error along the path, per-frame time and
correspondences, and ``bench speed``'s scaling curves with p5-p95 bands.

Errors are drawn on log axes, so a run that drifts far never squashes the others to zero; a
diverged run is left out of the box plots (a note under the figure names it) and along the path
it is drawn up to the axis' top and marked "Div." there. Only segment lengths with segments get
a slot. One paper column wide, legends below the axes (``style``).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from bench.report.figures.style import (
    PRIOR_NOTE,
    SMALL_PT,
    color,
    div_labels,
    figure,
    fit_height,
    legend_below,
    line_kwargs,
    log_y,
    prior_style,
    run_name,
    run_order,
    save,
    set_title,
    slug,
    use_paper_style,
)
from bench.report.names import display_name, order_key, sequence_key
from bench.runs.folders import RunRecord
from loaders.errors import DataError
from loaders.se3 import inv_T, rotation_angle_deg
from loaders.sensor_classes import SYNTHETIC_MARK, class_rank
from metrics.relative import MetricError, path_distances, segment_errors

#: the top of an error axis is this factor above the largest error of a run that did not diverge
_HEADROOM = 3.0


def _scored_lengths(runs: list[RunRecord]) -> list[float]:
    """Segment lengths [m] at which any of the runs has segments (metrics.json)."""
    return sorted({L for r in runs for L in r.result.lengths_m})


def _segments(run: RunRecord, length_m: float) -> tuple[np.ndarray, np.ndarray]:
    try:
        seg = segment_errors(run.gt, run.est, length_m)
    except MetricError:
        return np.empty(0), np.empty(0)
    return np.asarray(seg.trans_m, float), np.asarray(seg.rot_deg, float)


def plot_boxplots(runs: list[RunRecord], out_dir: Path) -> list[Path]:
    """Per sensor class: translation [m] and rotation [deg] relative errors per segment length
    on log axes, one box per run name (the class's sequences pooled; diverged runs left out and
    named under the figure). No-seed boxes are hatched."""
    from matplotlib.patches import Patch

    use_paper_style()
    written = []
    for klass in sorted({r.sensor_class for r in runs}, key=lambda k: (class_rank(k), k)):
        here = sorted((r for r in runs if r.sensor_class == klass), key=run_order)
        good = [r for r in here if not r.diverged]
        lengths = _scored_lengths(good)
        names = list(dict.fromkeys(run_name(r) for r in good))
        data = {n: {L: ([], []) for L in lengths} for n in names}
        for run in good:
            for L in lengths:
                t, rot = _segments(run, L)
                data[run_name(run)][L][0].extend(t)
                data[run_name(run)][L][1].extend(rot)
        # a length slot only where some box has segments
        lengths = [L for L in lengths if any(data[n][L][0] for n in names)]
        if not lengths:
            continue
        first = {run_name(r): r for r in reversed(good)}
        fig, axes = figure(3.0, 2, 1, sharex=True)
        width = 0.84 / len(names)
        handles = []
        for k, name in enumerate(names):
            run = first[name]
            hatch = prior_style(run)[2]
            pos = np.arange(len(lengths)) + (k - (len(names) - 1) / 2) * width
            for ax, part in zip(axes, (0, 1), strict=True):
                values = [np.asarray(data[name][L][part], float) for L in lengths]
                values = [v[v > 0] if len(v) else np.array([np.nan]) for v in values]
                bp = ax.boxplot(values, positions=pos, widths=width * 0.85, showfliers=False,
                                patch_artist=True, manage_ticks=False, whis=(5, 95),
                                medianprops={"color": "black", "linewidth": 0.8},
                                whiskerprops={"linewidth": 0.6}, capprops={"linewidth": 0.6},
                                boxprops={"linewidth": 0.5})
                for box in bp["boxes"]:
                    box.set(facecolor=color(run.method), alpha=0.85, hatch=hatch,
                            edgecolor="0.15")
            handles.append(Patch(facecolor=color(run.method), alpha=0.85, hatch=hatch,
                                 edgecolor="0.15", linewidth=0.5, label=name))
        for ax in axes:
            ax.set_yscale("log")
            ax.autoscale_view()
            if not np.isfinite(ax.dataLim.y0):  # no positive error (all exactly 0): an
                ax.set_ylim(*_log_limits([]))  # empty log axis, not a non-positive one
            log_y(ax)
            for x in np.arange(len(lengths) - 1) + 0.5:
                ax.axvline(x, color="0.8", lw=0.5, zorder=0)
            ax.grid(axis="x", visible=False)
        axes[0].set_ylabel("translation error [m]")
        axes[1].set_ylabel("rotation error [deg]")
        axes[1].set_xticks(range(len(lengths)), [f"{L:g}" for L in lengths])
        axes[1].set_xlim(-0.5, len(lengths) - 0.5)
        axes[1].set_xlabel("segment length [m]")
        synthetic = any(SYNTHETIC_MARK in r.display_name for r in runs if r.sensor_class == klass)
        set_title(axes[0], f"{klass}{' (synthetic)' if synthetic else ''}: relative error")
        legend_below(fig, handles, [h.get_label() for h in handles],
                     note="Boxes: quartiles and median; whiskers: 5-95 %; the class's "
                     f"sequences pooled. {PRIOR_NOTE}{_diverged_note(here)}")
        fit_height(fig, 2.6)
        written += save(fig, out_dir / "boxplots" / slug(klass))
    return written


def _diverged_note(runs: list[RunRecord]) -> str:
    """"Not shown (diverged): <run> on <sequences>; ..." for the diverged runs."""
    where: dict[str, list[str]] = {}
    for r in runs:
        if r.diverged:
            where.setdefault(run_name(r), []).append(r.display_name)
    if not where:
        return ""
    return " Not shown (diverged): " + "; ".join(
        f"{name} on {', '.join(sorted(seqs, key=sequence_key))}" for name, seqs in where.items())


#: runs that leave the axes within this fraction of the path of each other share one label
_DIV_CLUSTER = 0.06


def label_divergence(ax, exits: list[tuple[float, str]], top: float, span: float) -> None:
    """One "Div." label per cluster of runs that leave the axes at about the same distance
    (the legend names them): in the run's colour when it is alone, dark grey for several, so
    labels never print over each other (as four ICPs in a tunnel did)."""
    clusters: list[list[tuple[float, str]]] = []
    for x, c in sorted(exits):
        if clusters and x - clusters[-1][0][0] <= _DIV_CLUSTER * span:
            clusters[-1].append((x, c))
        else:
            clusters.append([(x, c)])
    # clusters whose labels would still touch ("Div. (3)" next to "Div. (2)") are merged
    div_labels(ax, [(cluster[0][0], top, cluster[0][1], len(cluster)) for cluster in clusters],
               (4, -7), SMALL_PT - 0.5)


def _errors_along_path(run: RunRecord) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance travelled [m], translation [m] and rotation [deg] error of each frame after
    the first (estimate aligned at the first pose)."""
    E = inv_T(inv_T(run.gt[0]) @ run.gt) @ (inv_T(run.est[0]) @ run.est)
    dist = path_distances(run.gt[:, :3, 3])
    return dist[1:], np.linalg.norm(E[1:, :3, 3], axis=1), rotation_angle_deg(E[1:, :3, :3])


def _log_limits(values: list[np.ndarray]) -> tuple[float, float]:
    """Log-axis limits that hold the positive values (at most five decades below the largest),
    with room above the largest."""
    v = np.concatenate([x[np.isfinite(x) & (x > 0)] for x in values] or [np.empty(0)])
    if not len(v):
        return 1e-3, 1.0
    hi = float(v.max())
    lo = max(float(v.min()), hi * 1e-5)  # an error of exactly 0 at one frame is no limit
    return lo / 1.5, max(hi * _HEADROOM, lo * 10)


def plot_error_along_path(runs: list[RunRecord], out_dir: Path) -> list[Path]:
    """Per sequence: translation [m] and rotation [deg] error of each frame against the
    distance travelled [m] on log axes, estimates aligned at the first pose. The axes hold the
    runs that did not diverge; a diverged run is drawn up to the top and marked "Div."."""
    use_paper_style()
    written = []
    for sequence in sorted({r.display_name for r in runs}, key=sequence_key):
        group = sorted((r for r in runs if r.display_name == sequence
                        and np.all(np.isfinite(r.est)) and len(r.gt) >= 2), key=run_order)
        if not group:
            continue
        curves = {id(r): _errors_along_path(r) for r in group}
        kept = [r for r in group if not r.diverged] or group
        fig, axes = figure(2.6, 2, 1, sharex=True)
        span = max(float(np.nanmax([curves[id(r)][0].max() for r in group])), 1e-9)
        pending = []  # (axes, exits, top): labelled once the figure's size is final
        for part, ax in zip((1, 2), axes, strict=True):
            lo, hi = _log_limits([curves[id(r)][part] for r in kept])
            exits = []
            for k, run in enumerate(group):
                dist, err = curves[id(run)][0], curves[id(run)][part]
                err = np.where(err > 0, err, np.nan)
                name = run_name(run) + (" - Div." if run.diverged else "")
                above = np.flatnonzero(err > hi)
                if len(above):  # drawn up to the axis' top, marked where it leaves
                    cut = above[0]
                    ax.plot(dist[:cut + 1], np.minimum(err[:cut + 1], hi), label=name,
                            **line_kwargs(run, k, len(group), points=len(dist)))
                    ax.plot(dist[cut], hi, marker="^", color=color(run.method), ms=4,
                            clip_on=False, zorder=5)
                    exits.append((float(dist[cut]), color(run.method)))
                else:
                    ax.plot(dist, err, label=name,
                            **line_kwargs(run, k, len(group), points=len(dist)))
            pending.append((ax, exits, hi))
            ax.set_yscale("log")
            ax.set_ylim(lo, hi)
            log_y(ax)
        axes[0].set_ylabel("translation error [m]")
        axes[1].set_ylabel("rotation error [deg]")
        axes[1].set_xlabel("distance travelled [m]")
        set_title(axes[0], f"{sequence}: error along the path")
        handles, labels = axes[0].get_legend_handles_labels()
        legend_below(fig, handles, labels, note=PRIOR_NOTE)
        fit_height(fig, 2.3)
        for ax, exits, top in pending:
            label_divergence(ax, exits, top, span)
        written += save(fig, out_dir / "error-along-path" / slug(sequence))
    return written


def _frames_rows(run: RunRecord) -> list[dict]:
    with (run.dir / "frames.csv").open() as f:
        return list(csv.DictReader(f))[1:]  # frame 0 is not registered


def _float(x: str) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def plot_frames(runs: list[RunRecord], out_dir: Path) -> list[Path]:
    """Per sequence: time per frame [ms] (all per-frame work, ``time_ms``) and correspondences
    per frame (frames.csv), both on log axes. A run with neither (a trajectory scored with
    ``bench score`` without per-frame times) is left out; a sequence with no other run gets
    no figure."""
    use_paper_style()
    written = []
    for sequence in sorted({r.display_name for r in runs}, key=sequence_key):
        series = []
        for run in sorted((r for r in runs if r.display_name == sequence), key=run_order):
            rows = _frames_rows(run)
            time_ms = np.array([_float(r["time_ms"]) for r in rows])
            pairs = np.array([_float(r["correspondences"]) for r in rows])
            if np.any(time_ms > 0) or np.any(pairs > 0):
                series.append((run, [int(r["index"]) for r in rows], time_ms, pairs))
        if not series:
            continue
        fig, axes = figure(2.6, 2, 1, sharex=True)
        for k, (run, idx, time_ms, pairs) in enumerate(series):
            kw = line_kwargs(run, k, len(series), points=len(idx)) | {"lw": 0.7}
            axes[0].plot(idx, np.where(time_ms > 0, time_ms, np.nan), label=run_name(run), **kw)
            axes[1].plot(idx, np.where(pairs > 0, pairs, np.nan), **kw)
        for ax in axes:
            ax.set_yscale("log")
            ax.autoscale_view()
            log_y(ax)
        axes[0].set_ylabel("time per frame [ms]")
        axes[1].set_ylabel("correspondences")
        axes[1].set_xlabel("frame")
        set_title(axes[0], sequence)
        handles, labels = axes[0].get_legend_handles_labels()
        legend_below(fig, handles, labels, note="Time: all per-frame work from a scan in memory "
                     f"to its pose (time_ms); the first frame is not registered. {PRIOR_NOTE}")
        fit_height(fig, 2.3)
        written += save(fig, out_dir / "frames" / slug(sequence))
    return written


def plot_speed_csv(path: Path, out_dir: Path) -> list[Path]:
    """``bench speed``'s LiDAR scaling curves: median time per frame [ms] (all per-frame work)
    against input points, with the p5-p95 band of the repeats."""
    use_paper_style()
    columns = ("scenario", "method", "points", "median_ms", "p5_ms", "p95_ms")
    try:
        with path.open() as f:
            rows = [r for r in csv.DictReader(f) if r.get("scenario") == "lidar"]
        for r in rows:
            int(r["points"]), float(r["median_ms"]), float(r["p5_ms"]), float(r["p95_ms"])
    except (UnicodeDecodeError, csv.Error, KeyError, TypeError, ValueError):
        raise DataError(f"--speed-csv {path}: not a `bench speed` CSV; expected the columns "
                        f"{', '.join(columns)} (results/speed/speed.csv)") from None
    fig, ax = figure(2.4)
    for method in sorted(dict.fromkeys(r["method"] for r in rows), key=order_key):
        pts = sorted((int(r["points"]), float(r["median_ms"]), float(r["p5_ms"]),
                      float(r["p95_ms"])) for r in rows if r["method"] == method)
        n, med, lo, hi = (np.array(v) for v in zip(*pts, strict=True))
        ax.loglog(n, med, "o-", ms=3, color=color(method), label=display_name(method))
        ax.fill_between(n, lo, hi, color=color(method), alpha=0.2, lw=0)
    log_y(ax, "x")
    log_y(ax, "y")
    ax.set_xlabel("input points per scan")
    ax.set_ylabel("time per frame [ms]")
    set_title(ax, "speed scaling: all per-frame work (median, p5-p95 band)")
    handles, labels = ax.get_legend_handles_labels()
    legend_below(fig, handles, labels, max_ncol=3)
    fit_height(fig, 1.9)
    return save(fig, out_dir / "speed")
