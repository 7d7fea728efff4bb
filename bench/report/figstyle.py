"""Shared style of the paper figures: one colour per method across every figure, paper-column
sizes and display names as in the tables. Runs come from ``bench.runs.folders.load_runs``."""

from __future__ import annotations

from pathlib import Path

from bench.report.names import PAPER_ORDER, run_label
from loaders.fileio import atomic_path

COLUMN_IN = 3.5  # one paper column [inch]
PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#bcbd22", "#7f7f7f"]


def color(method: str) -> str:
    """The method's colour, the same in every figure."""
    i = PAPER_ORDER.index(method) if method in PAPER_ORDER else len(PAPER_ORDER)
    return PALETTE[i % len(PALETTE)]


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


def run_name(run) -> str:
    """A run's legend name (a ``bench.runs.folders.RunRecord``)."""
    return run_label(run.method, run.seed, run.label)
