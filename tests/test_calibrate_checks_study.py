"""bench calibrate's verdicts (bench.studies.calibrate_checks_study) on a correct synthetic
straight drive (truth: the identity): rotating the GT frame turns the GT cues exactly as
collecting the cues of the rotated store does; the correct drive and its GT jittered by 5 mm
have no pieces apart; a GT frame rotated by 2 deg moves the estimate by 2 deg inside its
interval; a pitch 1 deg higher from the middle on sets the pieces apart; a GT that does not
overlap the scans is refused."""

import numpy as np
import pytest

from bench.studies.calibrate_checks_study import (
    OtherGT,
    collect_cues,
    jittered,
    rotated_cues,
    rotated_gt,
    verdict,
)
from loaders.errors import DataError
from loaders.synthetic.generate import SyntheticSequence
from loaders.trajectory import Trajectory


def test_correct_drive_passes_and_each_fault_is_caught():
    seq = SyntheticSequence("straight-wall", "radar-sparse", 250, seed=10, attitude_deg=0.0)
    cues = collect_cues(seq)
    angles = (0.0, 2.0, 0.0)
    moved = collect_cues(OtherGT(seq, rotated_gt(seq.ground_truth, angles)))
    shortcut = rotated_cues(cues, angles)
    assert np.allclose(moved.b, shortcut.b, atol=1e-9)
    assert np.allclose(moved.ups, shortcut.ups, atol=1e-9)
    assert np.array_equal(moved.vel_frame, cues.vel_frame)

    base = verdict(cues, "as is")
    assert base["pieces"] == 2 and base["apart"] == []
    assert verdict(collect_cues(OtherGT(seq, jittered(seq.ground_truth))), "j")["apart"] == []

    rot = verdict(shortcut, "rotated")["cal"]
    moved_by = rot.angles_deg["pitch"] - base["cal"].angles_deg["pitch"]
    assert moved_by == pytest.approx(2.0, abs=0.01)
    lo, hi = rot.interval_deg["pitch"]
    assert lo < base["cal"].angles_deg["pitch"] + 2.0 < hi

    assert verdict(rotated_cues(cues, (0.0, 1.0, 0.0), 125), "step")["apart"] == ["pitch"]

    gt = seq.ground_truth
    with pytest.raises(DataError, match="ground truth"):
        collect_cues(OtherGT(seq, Trajectory(gt.stamps + 100.0, gt.poses)))
