"""bench score tells units and conventions apart by what fits (on the vendored NTU4DRadLM
sample, its ground truth taken as the estimate): quaternions in w x y z order and Boreas files
holding T_i_k are refused by which reading's relative motions agree with the ground truth's;
a sheared rotation block is refused with its file and line; positions in millimetres are told
from stamps in milliseconds by the path length; frame indices as stamps are named; a bridged
gap wider than 3 periods is a warning with its width; a tolerance below the stamps' rounding
names the tolerance that takes them; stamps on the scans with poses a few frames off are
scored with a warning."""

from pathlib import Path

import numpy as np
import pytest

from bench.runs.external.checks import check_estimate
from bench.runs.external.score import ExternalSpec, score_external
from bench.runs.folders import read_run
from loaders.errors import DataError
from loaders.estimate import read_estimate
from loaders.se3 import inv_T, tum_from_T
from loaders.store import StoreSequence

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "ntu4dradlm-loop1.h5"


@pytest.fixture(scope="module")
def seq():
    s = StoreSequence(SAMPLE, fields=())
    yield s
    s.close()


def tum_rows(stamps, poses, order="xyzw", fmt="%.9f"):
    xyz, q = tum_from_T(np.asarray(poses))
    if order == "wxyz":
        q = q[:, [3, 0, 1, 2]]
    return np.column_stack([stamps, xyz, q])


def check(seq, path: Path, **options):
    """``check_estimate`` as bench score runs it (no scoring: the checks only)."""
    spec = ExternalSpec(path, "probe", **options)
    est = read_estimate(path, spec.fmt, spec.stamps, spec.topic, spec.frame_times,
                        spec.stamp_unit)
    return check_estimate(seq, est, spec, np.eye(4), str(path), str(SAMPLE))


def test_quaternions_in_wxyz_order_are_refused_and_xyzw_pass(seq, tmp_path):
    gt = seq.ground_truth
    right = tmp_path / "xyzw.tum"
    np.savetxt(right, tum_rows(gt.stamps, gt.poses), fmt="%.9f")
    found = check(seq, right)
    assert found.convention.startswith("wxyz: as read") and not found.warnings
    wrong = tmp_path / "wxyz.tum"
    np.savetxt(wrong, tum_rows(gt.stamps, gt.poses, "wxyz"), fmt="%.9f")
    with pytest.raises(DataError, match=r"wxyz.tum: read as tum, its relative motions disagree "
                                        r".*the file holds quaternions in w x y z order"):
        check(seq, wrong)


def _boreas(path: Path, stamps, T_rows):
    us = np.round(np.asarray(stamps) * 1e6).astype(np.int64)
    with open(path, "w") as f:
        for t, r in zip(us, T_rows[:, :3, :].reshape(-1, 12), strict=True):
            f.write(f"{t} " + " ".join(f"{v:.9f}" for v in r) + "\n")
    return path


def test_a_boreas_file_holding_T_i_k_is_refused(seq, tmp_path):
    gt = seq.ground_truth
    right = _boreas(tmp_path / "right.txt", gt.stamps, inv_T(gt.poses))  # T_k_i, as the format
    assert check(seq, right).convention.startswith("inverse: as read")
    wrong = _boreas(tmp_path / "wrong.txt", gt.stamps, gt.poses)  # T_i_k
    with pytest.raises(DataError, match=r"wrong.txt: read as boreas, .*the file holds the poses "
                                        r"T_i_k where the format holds T_k_i"):
        check(seq, wrong)


def test_a_sheared_rotation_block_is_refused_with_its_line(seq, tmp_path):
    gt = seq.ground_truth
    times = tmp_path / "times.txt"
    np.savetxt(times, gt.stamps, fmt="%.9f")
    rows = gt.poses[:, :3, :].copy()
    four = tmp_path / "four.kitti"  # printed with 4 decimals: off orthonormal by ~1e-4
    np.savetxt(four, rows.reshape(-1, 12), fmt="%.4f")
    assert check(seq, four, stamps=times).coverage["scored"] == 250
    shear = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # det 1
    rows[6, :, :3] = rows[6, :, :3] @ shear
    bad = tmp_path / "sheared.kitti"
    np.savetxt(bad, rows.reshape(-1, 12), fmt="%.9e")
    with pytest.raises(DataError, match=r"sheared.kitti, line 7: the 3x3 block is no rotation "
                                        r"\(determinant 1.0000, max \|R R\^T - I\| = "
                                        r"0\.1\d+, beyond 0.001"):
        check(seq, bad, stamps=times)


def test_millimetres_are_told_from_milliseconds_by_the_path_length(seq, tmp_path):
    gt = seq.ground_truth
    mm = tum_rows(gt.stamps, gt.poses)
    mm[:, 1:4] *= 1000.0
    np.savetxt(tmp_path / "mm.tum", mm, fmt="%.9f")
    with pytest.raises(DataError, match="the path length settles it: positions in millimetres"
                       ) as err:
        check(seq, tmp_path / "mm.tum")
    assert "--stamp-unit" not in str(err.value)
    ms = tum_rows(gt.stamps * 1000.0, gt.poses)
    np.savetxt(tmp_path / "ms.tum", ms, fmt="%.9f")
    with pytest.raises(DataError, match=r"the path length settles it: stamps in milliseconds "
                                        r".*score it with --stamp-unit ms"):
        check(seq, tmp_path / "ms.tum")


def test_frame_indices_as_stamps_are_named(seq, tmp_path):
    gt = seq.ground_truth
    np.savetxt(tmp_path / "idx.tum", tum_rows(np.arange(len(gt)), gt.poses), fmt="%.9f")
    with pytest.raises(DataError, match=r"idx.tum: its stamps are frame indices \(0, 1, 2, "):
        check(seq, tmp_path / "idx.tum")


def test_a_bridged_gap_wider_than_three_periods_is_warned_with_its_width(seq, tmp_path):
    gt = seq.ground_truth
    rows = tum_rows(gt.stamps, gt.poses)
    hole = tmp_path / "hole.tum"
    np.savetxt(hole, rows[(gt.stamps < 5.0) | (gt.stamps > 8.3)], fmt="%.9f")
    found = check(seq, hole, max_gap_s=1e9)
    assert found.coverage["scored"] == 250
    assert found.coverage["widest_bridged_s"] == pytest.approx(3.4167, abs=1e-3)
    assert any("bridged a gap of 3.42 s (41.0 scan periods)" in w for w in found.warnings)
    small = tmp_path / "small.tum"  # every other pose: gaps of 2 periods, no warning
    np.savetxt(small, rows[::2], fmt="%.9f")
    found = check(seq, small, max_gap_s=0.2)
    assert found.coverage["widest_bridged_s"] == pytest.approx(2 / 12, abs=1e-6)
    assert not found.warnings


def test_a_tolerance_below_the_stamps_rounding_names_the_tolerance(seq, tmp_path):
    gt = seq.ground_truth
    rows = tum_rows(np.round(gt.stamps, 5), gt.poses)
    path = tmp_path / "r10us.tum"
    np.savetxt(path, rows, fmt="%.5f %.9f %.9f %.9f %.9f %.9f %.9f %.9f")
    with pytest.raises(DataError, match=r"250 of its stamps lie within 3.33e-06 s of a scan's "
                                        r".*--tolerance 3.4e-06 takes them") as err:
        check(seq, path, tolerance_s=0.0)
    assert "--max-gap" not in str(err.value)
    assert check(seq, path, tolerance_s=3.4e-6).coverage["matched"] == 250


def test_stamps_on_the_scans_with_poses_three_frames_off_are_scored_with_a_warning(seq,
                                                                                   tmp_path):
    """The stamps are the scans' own, so the estimate is on the store's clock and scored; its
    poses a 3-frame misassociation (the profile decisively fits 0.25 s away) get a warning."""
    gt = seq.ground_truth
    poses = np.concatenate([gt.poses[3:], gt.poses[-1:].repeat(3, axis=0)])
    poses[-3:, :3, 3] += np.arange(1, 4)[:, None] * (gt.poses[-1, :3, 3] - gt.poses[-2, :3, 3])
    path = tmp_path / "rolled.tum"
    np.savetxt(path, tum_rows(gt.stamps, poses), fmt="%.9f")
    found = check(seq, path)
    assert found.clock.startswith("on the store's clock")
    assert len(found.warnings) == 1 and "poses written against the wrong scans' stamps" in \
        found.warnings[0]


def test_score_prints_the_warning_and_keeps_it_in_the_notes(seq, tmp_path):
    gt = seq.ground_truth
    hole = tmp_path / "hole.tum"
    rows = tum_rows(gt.stamps, gt.poses)
    np.savetxt(hole, rows[(gt.stamps < 5.0) | (gt.stamps > 8.3)], fmt="%.9f")
    out = score_external(SAMPLE, ExternalSpec(hole, "hole", max_gap_s=1e9), tmp_path / "r")
    assert any("bridged a gap of 3.42 s" in w for w in out.warnings)
    notes = read_run(out.run_dir).result.notes
    assert any(n.startswith("warning: ") and "bridged a gap of 3.42 s" in n for n in notes)
