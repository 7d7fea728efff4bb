"""Per-axis drift figure: each method's roll / pitch / yaw error and along / across / vertical
position error against the distance travelled, from the first frame (``metrics.drift``).

One paper column wide, six small panels (rotation left, translation right), one colour per
method (``bench.figstyle``), no-seed runs dashed. A slow roll-over or a scale error along the
road that a relative-error table only hints at is visible at a glance.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from bench.figstyle import COLUMN_IN, Run, color, save, use_paper_style
from metrics.drift import AXES_ROT, AXES_TRANS, drift_from_first_frame


def plot_drift(runs: list[Run], out_dir: Path) -> list[Path]:
    """Per sequence, one figure ``out_dir/drift/<sequence>.{pdf,png}`` with the per-axis drift
    of every run of that sequence (diverged runs are drawn up to where they leave finite
    values). Returns the written paths."""
    import matplotlib.pyplot as plt

    use_paper_style()
    written = []
    for sequence in sorted({r.sequence for r in runs}):
        group = [r for r in runs if r.sequence == sequence]
        fig, axes = plt.subplots(3, 2, figsize=(COLUMN_IN, 3.6), sharex=True)
        for run in group:
            drift = drift_from_first_frame(run.gt, run.est)
            style = {"color": color(run.method), "ls": "--" if run.seed is False else "-",
                     "lw": 0.8}
            for k in range(3):
                axes[k, 0].plot(drift.distance_m, drift.rot_err_deg[:, k], **style,
                                label=run.name + (" - Div." if run.diverged else "") if k == 0
                                else None)
                axes[k, 1].plot(drift.distance_m, drift.trans_err_m[:, k], **style)
        for k in range(3):
            axes[k, 0].set_ylabel(f"{AXES_ROT[k]} [deg]")
            axes[k, 1].set_ylabel(f"{AXES_TRANS[k]} [m]")
            for ax in axes[k]:
                ax.axhline(0.0, color="black", lw=0.4)
        for ax in axes[-1]:
            ax.set_xlabel("distance travelled [m]")
        fig.suptitle(textwrap.fill(f"{sequence}: drift from the first frame (estimate - GT, "
                                   "GT body axes)", 60), fontsize=7)
        handles, labels = axes[0, 0].get_legend_handles_labels()
        rows = int(np.ceil(len(labels) / 2))
        legend_in = 0.12 * rows + 0.05  # inches kept below the panels for the legend
        fig.set_size_inches(COLUMN_IN, 3.6 + legend_in)
        fig.tight_layout(pad=0.3, h_pad=0.2, w_pad=0.6,
                         rect=(0, legend_in / (3.6 + legend_in), 1, 0.97))
        fig.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=2,
                   frameon=False)
        written += save(fig, out_dir / "drift" / _safe(sequence))
    return written


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
