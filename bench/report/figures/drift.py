"""Per-axis drift figure: each method's roll / pitch / yaw error and along / across / vertical
position error against the distance travelled, from the first frame (``metrics.drift``).

One paper column wide, six small panels (rotation left, translation right), one colour per
method, the motion prior told by line style and marker (``bench.report.figures.style``), the legend
below. A slow roll-over or a scale error along the road that a relative-error table only hints
at is visible at a glance. Written by ``bench figures`` as ``drift/<sequence>.{pdf,png}``.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from bench.report.figures.style import (
    PRIOR_NOTE,
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
from metrics.drift import AXES_ROT, AXES_TRANS, drift_from_first_frame


def plot_drift(runs, out_dir: Path) -> list[Path]:
    """Per sequence, one figure ``out_dir/drift/<sequence>.{pdf,png}`` with the per-axis drift
    of every run of that sequence (``bench.runs.folders.RunRecord``s; a diverged run is drawn
    while its poses are finite). Returns the written paths."""
    use_paper_style()
    written = []
    for sequence in sorted({r.display_name for r in runs}, key=sequence_key):
        group = sorted((r for r in runs if r.display_name == sequence and len(r.gt) >= 2),
                       key=run_order)
        if not group:
            continue
        fig, axes = figure(3.9, 3, 2, sharex=True)
        handles, labels = [], []
        for k, run in enumerate(group):
            finite = np.all(np.isfinite(run.est), axis=(1, 2))
            stop = len(finite) if finite.all() else int(np.argmin(finite))
            if stop < 2:
                continue
            drift = drift_from_first_frame(run.gt[:stop], run.est[:stop])
            style = line_kwargs(run, k, len(group))
            for a in range(3):
                line, = axes[a, 0].plot(drift.distance_m, drift.rot_err_deg[:, a], **style)
                axes[a, 1].plot(drift.distance_m, drift.trans_err_m[:, a], **style)
            handles.append(line)
            labels.append(run_name(run) + (" - Div." if run.diverged else ""))
        for a in range(3):
            axes[a, 0].set_ylabel(f"{AXES_ROT[a]}\n[deg]")  # two lines: the rows are short
            axes[a, 1].set_ylabel(f"{AXES_TRANS[a]}\n[m]")
            for ax in axes[a]:
                ax.axhline(0.0, color="black", lw=0.4)
        for ax in axes[-1]:
            ax.set_xlabel("distance travelled [m]")
        fig.suptitle("\n".join(textwrap.wrap(f"{sequence}: drift from the first frame (estimate "
                                              "- GT, GT body axes)", 56)))
        legend_below(fig, handles, labels, note=PRIOR_NOTE)
        written += save(fig, out_dir / "drift" / slug(sequence))
    return written
