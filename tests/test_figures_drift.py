"""bench/figures_drift.py: one paper-column figure per sequence with six panels."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.figstyle import COLUMN_IN, Run
from bench.figures_drift import plot_drift
from loaders.se3 import make_T


def _run(method, seed, est, gt, sequence="seq A"):
    stamps = np.arange(len(gt)) * 0.1
    return Run(Path("."), sequence, "radar", method, seed, None, False, stamps, gt, est)


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
    assert sorted(p.name for p in paths) == ["seq_A.pdf", "seq_A.png", "seq_B.pdf",
                                             "seq_B.png"]
    height, width = mpimg.imread(tmp_path / "drift" / "seq_A.png").shape[:2]
    assert abs(width / 200 - COLUMN_IN) < 0.6  # one paper column at 200 dpi (tight bbox)
    assert height > width
