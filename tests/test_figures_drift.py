"""bench/report/figures/drift.py: one paper-column figure per sequence with six panels."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bench.report.figures.drift import plot_drift
from bench.report.figures.style import COLUMN_IN
from loaders.se3 import make_T


def _run(method, seed, est, gt, sequence="seq A"):
    """The parts of a run record the figure reads (bench.runs.folders.RunRecord)."""
    return SimpleNamespace(display_name=sequence, method=method, seed=seed, label=None,
                           diverged=False, gt=gt, est=est)


def test_one_figure_per_sequence_one_column_wide(tmp_path):
    import matplotlib.image as mpimg

    n = 30
    gt = make_T(np.repeat(np.eye(3)[None], n, 0),
                np.column_stack([np.arange(n) * 0.5, np.zeros(n), np.zeros(n)]))
    est = gt.copy()
    est[:, 1, 3] += np.linspace(0, 0.4, n)  # an across-track drift
    runs = [_run("doppler-ego", True, est, gt), _run("kiss-icp", False, gt, gt),
            _run("gicp", True, est, gt, sequence="seq B")]
    paths = plot_drift(runs, tmp_path)
    assert sorted(p.name for p in paths) == ["seq-a.pdf", "seq-a.png", "seq-b.pdf",
                                             "seq-b.png"]
    height, width = mpimg.imread(tmp_path / "drift" / "seq-a.png").shape[:2]
    assert width == round(COLUMN_IN * 300)  # exactly one paper column at 300 dpi
    assert height > width
