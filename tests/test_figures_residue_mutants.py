"""Residue survivors of bench/report/figures: pair.py's true motion looked up in the ground
truth by stamps rounded to the microsecond (a store without ground truth, ground truth that
misses the target frame, and stamps a few tenths of a microsecond apart on either side)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

import bench.report.figures.pair as pair
from conftest import constant_twist_sequence
from loaders.scan import MemorySequence
from loaders.se3 import inv_T
from loaders.store import write_store
from loaders.trajectory import Trajectory

SUB_MICRO_S = 4e-7  # equal to the microsecond, different at a tenth of one


def _store(tmp_path, name, scan_shift=0.0, gt=lambda t: t):
    seq = constant_twist_sequence(n_frames=2, n_points=200)
    scans = [replace(seq[k], stamp=seq[k].stamp + scan_shift) for k in range(len(seq))]
    truth = gt(seq.ground_truth)
    seq = MemorySequence(seq.name, seq.sensor, scans, truth, seq.provenance)
    return write_store(seq, tmp_path / f"{name}.h5"), seq


def _true_motion(seq):
    """T_target_source of frames 0 -> 1 from the poses the sequence was made with."""
    poses = constant_twist_sequence(n_frames=2, n_points=200).ground_truth.poses
    return inv_T(poses[1]) @ poses[0]


def test_without_ground_truth_there_is_no_true_motion(tmp_path):
    path, _ = _store(tmp_path, "nogt", gt=lambda t: None)
    assert pair.pair_correspondences(path, 0)["T_true"] is None


def test_ground_truth_missing_the_target_frame_gives_no_true_motion(tmp_path):
    only_source = lambda t: Trajectory(t.stamps[:1], t.poses[:1])  # noqa: E731
    path, _ = _store(tmp_path, "half", gt=only_source)
    assert pair.pair_correspondences(path, 0)["T_true"] is None


def test_ground_truth_stamps_a_fraction_of_a_microsecond_late_still_match(tmp_path):
    late = lambda t: Trajectory(t.stamps + SUB_MICRO_S, t.poses)  # noqa: E731
    path, seq = _store(tmp_path, "gtlate", gt=late)
    got = pair.pair_correspondences(path, 0)["T_true"]
    assert got is not None
    np.testing.assert_allclose(got, _true_motion(seq), atol=1e-9)


def test_scan_stamps_a_fraction_of_a_microsecond_late_still_match(tmp_path):
    path, seq = _store(tmp_path, "scanlate", scan_shift=SUB_MICRO_S)
    got = pair.pair_correspondences(path, 0)["T_true"]
    assert got is not None
    np.testing.assert_allclose(got, _true_motion(seq), atol=1e-9)
