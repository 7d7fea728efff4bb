"""`bench inspect` on a store `bench calibrate --write` made: it says which frames runs score
(not those the correction was estimated on) and the angles applied (bench.data.inspection)."""

from __future__ import annotations

from bench.data.calibration.estimate import CorrectedSequence
from bench.data.calibration.write import applied_rotation
from bench.data.inspection import inspect_sequence
from conftest import constant_twist_sequence
from loaders.store import StoreSequence, write_store


def test_inspect_shows_the_frames_scored_and_the_applied_angles(tmp_path):
    base = constant_twist_sequence(n_frames=20, n_points=800)
    applied = {"pitch": -2.5, "yaw": -0.3}
    details = {"applied_estimate": "doppler", "applied_rpy_deg": [0.0, -2.5, -0.3],
               "left_alone": {"roll": "interval 2.65 deg wide, not narrower than 2"}}
    path = write_store(CorrectedSequence(base, applied_rotation(applied), (0, 8), details),
                       tmp_path / "fixed.h5")
    seq = StoreSequence(path)
    try:
        rows = dict(inspect_sequence(seq)["rows"])
    finally:
        seq.close()
    assert rows["frames scored"].startswith("12 of 20: 20 have ground truth")
    assert "frames 0-7" in rows["frames scored"] and "not scored" in rows["frames scored"]
    shown = rows["GT calibrated"]
    assert "pitch -2.500, yaw -0.300 deg" in shown and "doppler estimate on frames 0-7" in shown
    assert "left alone (0): roll (interval 2.65 deg wide" in shown
    # a store calibrate did not write: neither line changes
    plain = dict(inspect_sequence(base)["rows"])
    assert plain["frames scored"] == "20 of 20 have ground truth (the others run, unscored)"
    assert "GT calibrated" not in plain
