"""Mutation-driven tests for loaders.coloradar, second round: the default GT gap when the
ground truth repeats rows (a logger that wrote a message twice), on a run folder written in
the dataset's layout (helpers_public.write_coloradar)."""

import numpy as np
import pytest

from helpers_public import write_coloradar
from loaders.coloradar import ColoradarSequence
from loaders.errors import GroundTruthWarning
from loaders.se3 import make_T


def test_repeated_gt_rows_do_not_shrink_the_default_gap(tmp_path):
    """__init__ 147: every GT row written twice (stamps 0.1 s apart otherwise). The default
    max gap is 3 median *positive* GT steps, 0.3 s: the repeats (zero steps) do not count, so
    every scan is covered."""
    stamps = 100.0 + 0.1 * np.arange(4)
    rng = np.random.default_rng(2)
    points = [rng.uniform(-10, 10, (5, 3)).astype(np.float32) for _ in stamps]
    doppler = [rng.uniform(-2, 2, 5).astype(np.float32) for _ in stamps]
    once = 99.8 + 0.1 * np.arange(8)  # 99.8 .. 100.5 s
    gt_stamps = np.repeat(once, 2)
    poses = np.stack([make_T(np.eye(3), [2.0 * (t - 100.0), 0.0, 0.0]) for t in gt_stamps])
    run = write_coloradar(tmp_path / "run0", stamps, points, doppler, gt_stamps, poses)
    with pytest.warns(GroundTruthWarning, match="8 rows repeat the previous row.s stamp and pose"):
        seq = ColoradarSequence(run)
    assert seq.provenance["gt_association"]["max_gap_s"] == pytest.approx(0.3)
    assert len(seq.ground_truth) == 4
    np.testing.assert_allclose(seq.ground_truth.stamps, stamps, atol=1e-9)
