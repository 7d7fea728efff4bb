import warnings

import numpy as np
import pytest

from loaders.doppler_check import doppler_sign_check
from loaders.errors import DataError
from loaders.npy_frames import NpyFramesSequence
from loaders.trajectory import Trajectory


def _load(path, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        seq = NpyFramesSequence(path, **kw)
    return seq, [str(w.message) for w in caught]


def test_real_sample_loads_with_period_and_order_association(sample_dir):
    seq, msgs = _load(sample_dir, period_s=1 / 12)
    assert len(seq) == 60
    np.testing.assert_allclose(seq.stamps[:3], [0, 1 / 12, 2 / 12])
    np.testing.assert_allclose(seq.ground_truth.stamps, seq.stamps)
    assert seq.provenance["repeated_gt_poses"] == 10
    assert any("repeat the previous pose" in m for m in msgs)
    s = seq[0]
    assert 2000 <= len(s) <= 6000 and s.doppler.shape == (len(s),)


def test_real_sample_doppler_convention_is_confirmed(sample_dir):
    seq, _ = _load(sample_dir, period_s=1 / 12)
    check = doppler_sign_check(seq, seq.ground_truth.poses)
    assert check.verdict == "confirmed"
    assert check.median_cosine > 0.95
    assert 0.8 < check.median_speed_ratio < 1.3


def test_a_wrong_period_is_not_confirmed(sample_dir):
    """The sample's TUM rows are 0.1 s apart but the radar runs at 12 Hz: stamped with 0.1 s
    the GT speed comes out 1/1.2 of the truth (Doppler / GT speed 1.19), and the check says to
    look at the period."""
    seq, _ = _load(sample_dir, period_s=0.1)
    check = doppler_sign_check(seq, seq.ground_truth.poses)
    assert check.median_speed_ratio == pytest.approx(1.19, abs=0.05)
    assert check.verdict.startswith("confirmed in direction") and "(their period)" in check.verdict


def _write_folder(tmp_path, n=4, gt_rows=None):
    rng = np.random.default_rng(0)
    for i in range(1, n + 1):
        np.save(tmp_path / f"frame_{i:03d}.npy", rng.normal(size=(50, 3)) * 10)
        np.save(tmp_path / f"frame_{i:03d}_dop.npy", rng.normal(size=50))
    rows = n if gt_rows is None else gt_rows
    np.savetxt(tmp_path / "gt.txt", np.column_stack(
        [np.arange(rows) * 0.1, np.arange(rows), np.zeros((rows, 5)), np.ones(rows)]))
    return tmp_path


def test_sign_check_detects_a_flipped_convention(sample_dir):
    from loaders.scan import MemorySequence, Scan

    seq, _ = _load(sample_dir, period_s=1 / 12)
    flipped = MemorySequence("f", seq.sensor, [Scan(s.stamp, s.points, -s.doppler)
                                               for s in seq], seq.ground_truth)
    assert doppler_sign_check(flipped, seq.ground_truth.poses).verdict == "appears FLIPPED"


def test_bad_folders_get_clear_errors(tmp_path):
    with pytest.raises(DataError, match="no frame_XXX.npy"):
        NpyFramesSequence(tmp_path, period_s=0.1)
    folder = _write_folder(tmp_path)
    (folder / "frame_002_dop.npy").unlink()
    with pytest.raises(DataError, match="frame_002.npy: missing Doppler file"):
        NpyFramesSequence(folder, period_s=0.1)


def test_gt_count_mismatch_and_missing_period(tmp_path):
    folder = _write_folder(tmp_path, n=4, gt_rows=6)
    with pytest.raises(DataError, match="6 GT rows but 4 frames"):
        NpyFramesSequence(folder, period_s=0.1)
    (folder / "gt.txt").unlink()
    with pytest.raises(DataError, match="--period"):
        NpyFramesSequence(folder)


def test_nan_points_are_dropped_with_a_count_and_empty_scans_fail(tmp_path):
    folder = _write_folder(tmp_path)
    pts = np.load(folder / "frame_001.npy")
    pts[[3, 7]] = np.nan
    np.save(folder / "frame_001.npy", pts)
    np.save(folder / "frame_003.npy", np.full((5, 3), np.nan))
    np.save(folder / "frame_003_dop.npy", np.zeros(5))
    seq, _ = _load(folder, period_s=0.1)
    with pytest.warns(UserWarning, match=r"frame 0: dropped 2 of \d+ points"):
        assert len(seq[0]) == 48
    with pytest.raises(DataError, match=r"frame_003.npy, frame 2: empty scan"), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq[2]


def test_single_tum_file_in_folder_is_used(tmp_path):
    folder = _write_folder(tmp_path)
    seq, _ = _load(folder, period_s=0.25)
    assert isinstance(seq.ground_truth, Trajectory)
    np.testing.assert_allclose(seq.ground_truth.stamps, [0, 0.25, 0.5, 0.75])


@pytest.mark.parametrize("gap_steps, bridged", [(3, True), (4, False)])
def test_time_association_bridges_a_gt_gap_of_at_most_three_steps(tmp_path, gap_steps, bridged):
    """associate="time": the GT (here 0.25 s rows, exact in binary, with one gap) is
    interpolated across at most 3 of its median steps; frames in a longer gap stay in the
    sequence without GT (the boundary: 3 steps bridged, 4 not)."""
    n = 40
    rng = np.random.default_rng(0)
    for i in range(1, n + 1):
        np.save(tmp_path / f"frame_{i:03d}.npy", rng.normal(size=(50, 3)) * 10)
        np.save(tmp_path / f"frame_{i:03d}_dop.npy", rng.normal(size=50))
    t = np.concatenate([np.arange(0, 9) * 0.25, 2.0 + gap_steps * 0.25 + np.arange(0, 9) * 0.25])
    np.savetxt(tmp_path / "gt.txt", np.column_stack(
        [t, t * 5.0, np.zeros((len(t), 5)), np.ones(len(t))]))
    seq, _ = _load(tmp_path, period_s=0.1, associate="time")
    in_gap = (seq.stamps > 2.0) & (seq.stamps < 2.0 + gap_steps * 0.25)
    scored = np.isin(seq.stamps, seq.ground_truth.stamps)
    assert len(seq) == n and in_gap.sum() >= 7
    assert scored[in_gap].all() == bridged and scored[in_gap].any() == bridged
    assert scored[~in_gap & (seq.stamps <= t[-1])].all()


def test_two_txt_files_beside_the_frames_are_named_and_gt_asked_for(tmp_path, monkeypatch,
                                                                    capsys):
    """Two .txt files: neither is taken and the message is not "no ground truth found": it
    names both and asks for --gt; with --gt the named one is the ground truth."""
    from helpers_cli import bench_main

    (tmp_path / "f").mkdir()
    folder = _write_folder(tmp_path / "f")
    (folder / "notes.txt").write_text("a note, not a trajectory\n")
    with pytest.raises(DataError, match=r"2 \.txt files beside the frames \(gt\.txt, "
                       r"notes\.txt\); name the ground truth with --gt"):
        NpyFramesSequence(folder, period_s=0.1)
    code, text = bench_main(monkeypatch, capsys, "convert", "npy-frames", folder, "--period",
                            "0.1", "--out", tmp_path / "s.h5")
    assert code == 2 and "name the ground truth with --gt" in text, text
    assert "no ground truth found" not in text
    seq = NpyFramesSequence(folder, period_s=0.1, gt=folder / "gt.txt")
    assert len(seq.ground_truth) == 4


def test_a_frames_folder_is_named_by_its_drive_placed_in_it_and_classed_by_its_model(tmp_path):
    """A folder `drive7/frames` of files frame_060 ... frame_069: the sequence is "drive7" (not
    "frames"), its provenance says frames 60-69 of the drive, by the files' numbers (so a run's
    label names them, not "frames 0-9"), a further cut composes (62, 64, ...), and --model
    radar-semidense puts it in the class the drive's own loader gives the Oculii Eagle."""
    from bench.runs.sequence_identity import frames_text
    from loaders.scan import select_frames
    from loaders.sensor_classes import SEMI_DENSE_RADAR, sensor_class

    folder = tmp_path / "drive7" / "frames"
    folder.mkdir(parents=True)
    rng = np.random.default_rng(0)
    for i in range(60, 70):
        np.save(folder / f"frame_{i:03d}.npy", rng.normal(size=(50, 3)) * 10)
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(size=50))
    seq, _ = _load(folder, period_s=0.1)
    assert seq.name == "drive7"
    assert seq.provenance["frame_range"] == {"start": 60, "frames": 10, "stride": 1,
                                             "from": "file numbers"}
    config = {"sequence": {"frames": 10, "store_frame_range": seq.provenance["frame_range"]}}
    assert frames_text(config) == "frame files 60-69"
    cut = select_frames(seq, 2, None, 2)
    assert cut.provenance["frame_range"]["start"] == 62
    assert len(cut) == 4 and frames_text(
        {"sequence": {"frames": 4, "store_frame_range": cut.provenance["frame_range"]}}) \
        == "frame files 62-68, stride 2"  # a cut of the folder, by the folder's numbers
    assert sensor_class(seq.sensor) == "4D Radar"
    semi, _ = _load(folder, period_s=0.1, model="radar-semidense (Oculii Eagle)")
    assert sensor_class(semi.sensor) == SEMI_DENSE_RADAR
    # a folder numbered from 1 (the reference format's whole drive) records no cut
    (tmp_path / "w").mkdir()
    whole, _ = _load(_write_folder(tmp_path / "w"), period_s=0.1)
    assert "frame_range" not in whole.provenance
