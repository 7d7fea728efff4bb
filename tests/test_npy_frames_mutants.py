"""loaders/npy_frames.py, what tests/test_npy_frames.py leaves open (make mutate's survivors):
frames taken in numeric order and only under their exact names, stamps from the GT file (and
its refusals), association by order (rows out of time order, repeated poses counted) and an
unknown association, the name, sensor and provenance recorded, the frame range read from the
file numbers (stride, irregular numbers, a single file, the 0/1 boundary), frames whose arrays
have the wrong shapes or cannot be read, and the per-frame limit checked from the .npy header.

Every folder is written here with known values, so each answer is worked out from the files."""

import re
import warnings

import numpy as np
import pytest

from loaders.errors import DataError
from loaders.limits import ENV_VAR
from loaders.npy_frames import NpyFramesSequence, Options, find_frames, find_tum
from test_npy_frames import _load as load  # the shared helper: the sequence and its warnings


def write_frames(folder, numbers, n_points=5):
    """frame_<k>.npy with points whose x is the file number k (so the order is visible) and
    Doppler -k."""
    folder.mkdir(parents=True, exist_ok=True)
    for k in numbers:
        pts = np.zeros((n_points, 3))
        pts[:, 0] = k
        pts[:, 1] = np.arange(n_points)
        np.save(folder / f"frame_{k:03d}.npy", pts)
        np.save(folder / f"frame_{k:03d}_dop.npy", np.full(n_points, -float(k)))
    return folder


def write_tum(path, stamps, x=None):
    stamps = np.asarray(stamps, float)
    x = np.arange(len(stamps), dtype=float) if x is None else np.asarray(x, float)
    rows = np.column_stack([stamps, x, np.zeros((len(stamps), 5)), np.ones(len(stamps))])
    np.savetxt(path, rows)
    return path


def test_frames_are_ordered_by_number_and_only_exact_names_count(tmp_path):
    folder = write_frames(tmp_path / "d", [9, 10, 100])
    (folder / "frame_011.npy.bak").write_text("")
    (folder / "frame_x.npy").write_text("")
    (folder / "xframe_012.npy").write_text("")
    frame_dir, files = find_frames(folder)
    assert frame_dir == folder
    assert [f.name for f in files] == ["frame_009.npy", "frame_010.npy", "frame_100.npy"]
    # numeric order: 1000 after 100 whatever the padding ("frame_1000" sorts before as text)
    np.save(folder / "frame_1000.npy", np.zeros((5, 3)))
    np.save(folder / "frame_1000_dop.npy", np.zeros(5))
    assert [f.name for f in find_frames(folder)[1]][-2:] == ["frame_100.npy", "frame_1000.npy"]


def test_frames_in_the_folder_itself_win_over_its_frames_subfolder(tmp_path):
    write_frames(tmp_path / "d", [1, 2])
    write_frames(tmp_path / "d" / "frames", [5, 6, 7])
    frame_dir, files = find_frames(tmp_path / "d")
    assert frame_dir == tmp_path / "d" and len(files) == 2
    frame_dir, files = find_frames(tmp_path / "d" / "frames")
    assert len(files) == 3


def test_no_frames_names_both_places_looked_in(tmp_path):
    with pytest.raises(DataError, match=rf"^{tmp_path}: no frame_XXX.npy files \(looked in "
                                        rf"{tmp_path} and {tmp_path}/frames\)$"):
        find_frames(tmp_path)
    with pytest.raises(DataError, match=rf"^{tmp_path}/nope: not a folder$"):
        NpyFramesSequence(tmp_path / "nope", period_s=0.1)


def test_find_tum_takes_the_one_txt_file_or_none(tmp_path):
    assert find_tum(tmp_path) is None
    (tmp_path / "gt.txt").write_text("")
    assert find_tum(tmp_path) == tmp_path / "gt.txt"


def test_scans_carry_their_own_files_values_and_period_stamps(tmp_path):
    folder = write_frames(tmp_path / "drive", [1, 2, 3])
    seq, _ = load(folder, period_s=0.5, kind="lidar")
    assert len(seq) == 3
    np.testing.assert_allclose(seq.stamps, [0.0, 0.5, 1.0])
    seq.stamps[0] = 99.0  # a copy: the sequence's stamps stay
    assert seq.stamps[0] == 0.0
    for i, k in enumerate([1, 2, 3]):
        s = seq.scan(i)
        assert s.stamp == pytest.approx(0.5 * i)
        np.testing.assert_array_equal(s.points[:, 0], k)
        np.testing.assert_array_equal(s.doppler, -k)
        assert s.source.endswith(f"frame_00{k}.npy, frame {i}")
    assert seq.name == "drive"
    assert seq.sensor.kind == "lidar" and seq.sensor.period_s == 0.5
    assert seq.sensor.model == "npy-frames"
    assert seq.ground_truth is None


def test_the_provenance_says_what_was_read(tmp_path):
    folder = write_frames(tmp_path / "drive", [1, 2, 3])
    gt = write_tum(folder / "gt.txt", [0.0, 0.1, 0.2])
    seq, _ = load(folder, period_s=0.25, name="given")
    assert seq.name == "given"
    assert seq.provenance == {"loader": "npy-frames", "folder": str(folder.resolve()),
                              "frames": 3, "gt": str(gt), "period_s": 0.25,
                              "gt_association": "order", "repeated_gt_poses": 0}
    np.testing.assert_allclose(seq.ground_truth.stamps, [0.0, 0.25, 0.5])
    np.testing.assert_allclose(seq.ground_truth.poses[:, 0, 3], [0.0, 1.0, 2.0])


def test_options_open_the_sequence_with_every_option(tmp_path):
    folder = write_frames(tmp_path / "drive", [1, 2, 3])
    write_tum(folder / "gt.txt", [10.0, 10.2, 10.4])
    options = Options(period_s=None, stamps_from_gt=True, kind="lidar", name="n",
                      associate="order", model="lidar-dense")
    seq = NpyFramesSequence.open([folder], options)
    np.testing.assert_allclose(seq.stamps, [10.0, 10.2, 10.4])
    assert seq.name == "n" and seq.sensor.kind == "lidar"
    assert seq.sensor.model == "lidar-dense"
    other = tmp_path / "elsewhere.txt"
    write_tum(other, [0.0, 1.0, 2.0])
    seq = NpyFramesSequence.open([folder], Options(period_s=0.1, gt=other))
    assert seq.provenance["gt"] == str(other)
    assert seq.provenance["period_s"] == 0.1


def test_stamps_from_the_gt_file_set_the_period_to_their_median_step(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3, 4, 5])
    write_tum(folder / "gt.txt", [1.0, 1.2, 1.4, 1.9, 2.1])  # steps 0.2, 0.2, 0.5, 0.2
    seq, _ = load(folder, stamps_from_gt=True)
    np.testing.assert_allclose(seq.stamps, [1.0, 1.2, 1.4, 1.9, 2.1])
    assert seq.sensor.period_s == pytest.approx(0.2)
    assert seq.provenance["period_s"] == pytest.approx(0.2)
    two = write_frames(tmp_path / "two", [1, 2])
    write_tum(two / "gt.txt", [5.0, 5.3])
    assert load(two, stamps_from_gt=True)[0].sensor.period_s == pytest.approx(0.3)


def test_a_single_frame_stamped_from_the_gt_gets_a_tenth_of_a_second(tmp_path):
    folder = write_frames(tmp_path / "d", [1])
    write_tum(folder / "gt.txt", [7.0])
    seq, msgs = load(folder, stamps_from_gt=True)
    np.testing.assert_allclose(seq.stamps, [7.0])
    assert seq.sensor.period_s == 0.1
    assert seq.repeated_gt_poses == 0 and msgs == []
    np.testing.assert_allclose(seq.ground_truth.poses[0], np.eye(4))


@pytest.mark.parametrize("stamps, row, count", [([0.0, 0.1, 0.1, 0.3], 2, 1),
                                                ([0.0, 0.2, 0.1, 0.05], 2, 2)])
def test_gt_stamps_that_repeat_or_go_back_cannot_stamp_frames(tmp_path, stamps, row, count):
    folder = write_frames(tmp_path / "d", [1, 2, 3, 4])
    gt = write_tum(folder / "gt.txt", stamps)
    with pytest.raises(DataError, match=rf"^{gt}, pose row {row}: stamps must increase to stamp "
                                        rf"the frames \({count} rows repeat or go backwards\); "
                                        "give --period instead$"):
        NpyFramesSequence(folder, stamps_from_gt=True)


def test_gt_stamps_need_one_row_per_frame_and_exclude_a_period(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3])
    with pytest.raises(DataError, match=r"stamps from the GT file need one TUM row per frame "
                                        r"\(3 frames, 0 rows\)"):
        NpyFramesSequence(folder, stamps_from_gt=True)
    write_tum(folder / "gt.txt", [0.0, 0.1])
    with pytest.raises(DataError, match=r"\(3 frames, 2 rows\); give the scan period"):
        NpyFramesSequence(folder, stamps_from_gt=True)
    with pytest.raises(DataError, match=r"give either the scan period or stamps from the GT "
                                        "file, not both"):
        NpyFramesSequence(folder, period_s=0.1, stamps_from_gt=True)


def test_order_association_refuses_rows_out_of_time_order(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3, 4])
    gt = write_tum(folder / "gt.txt", [0.0, 0.3, 0.2, 0.1])
    with pytest.raises(DataError, match=rf"^{gt}, pose row 2: stamp 0.200000 s goes backwards "
                                        r"from 0.300000 s \(2 such rows\); association by "
                                        "order needs the rows in time order"):
        NpyFramesSequence(folder, period_s=0.1)
    write_tum(gt, [0.0, 0.1, 0.1, 0.2])  # a repeated stamp is not out of order
    seq, _ = load(folder, period_s=0.1)
    assert len(seq.ground_truth) == 4


def test_repeated_gt_poses_are_counted_and_warned_about(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3, 4, 5])
    gt = write_tum(folder / "gt.txt", [0.0, 0.1, 0.2, 0.3, 0.4], x=[0.0, 0.0, 1.0, 1.0, 1.0])
    seq, msgs = load(folder, period_s=0.1)
    assert seq.repeated_gt_poses == 3 and seq.provenance["repeated_gt_poses"] == 3
    assert msgs == [f"{gt}: 3 GT rows repeat the previous pose exactly; frame-to-frame errors "
                    "are meaningless, evaluate over metres"]
    write_tum(gt, [0.0, 0.1, 0.2, 0.3, 0.4], x=[0.0, 1e-9, 1.0, 2.0, 3.0])
    seq, msgs = load(folder, period_s=0.1)
    assert seq.repeated_gt_poses == 0 and msgs == []


def test_an_unknown_association_is_refused(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2])
    write_tum(folder / "gt.txt", [0.0, 0.1])
    with pytest.raises(DataError, match=r"^unknown GT association 'nearest' \(expected 'order' "
                                        r"or 'time'\)$"):
        NpyFramesSequence(folder, period_s=0.1, associate="nearest")


def test_time_association_interpolates_at_the_frame_stamps(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3, 4])
    write_tum(folder / "gt.txt", [0.0, 0.2, 0.4, 0.6], x=[0.0, 2.0, 4.0, 6.0])
    seq, _ = load(folder, period_s=0.1, associate="time")
    np.testing.assert_allclose(seq.ground_truth.stamps, [0.0, 0.1, 0.2, 0.3])
    np.testing.assert_allclose(seq.ground_truth.poses[:, 0, 3], [0.0, 1.0, 2.0, 3.0])
    assert seq.provenance["gt_association"] == "time"
    assert seq.gt_report is not None


@pytest.mark.parametrize("numbers, frame_range", [
    ([60, 61, 62], {"start": 60, "frames": 3, "stride": 1, "from": "file numbers"}),
    ([10, 12, 14, 16], {"start": 10, "frames": 4, "stride": 2, "from": "file numbers"}),
    ([7], {"start": 7, "frames": 1, "stride": 1, "from": "file numbers"}),
    ([2, 3], {"start": 2, "frames": 2, "stride": 1, "from": "file numbers"}),
    ([1, 2, 3], None),  # numbered from 1: the whole drive
    ([0, 1, 2], None),
    ([1], None),
    ([5, 6, 8], None),  # irregular numbers: no range to record
    ([5, 7, 8], None),
])
def test_the_frame_range_is_read_from_regular_file_numbers(tmp_path, numbers, frame_range):
    folder = write_frames(tmp_path / "d", numbers)
    seq, _ = load(folder, period_s=0.1)
    assert seq.provenance.get("frame_range") == frame_range


def test_frames_with_wrong_shapes_are_refused_naming_the_frame(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3, 4])
    np.save(folder / "frame_001.npy", np.zeros((5, 2)))
    np.save(folder / "frame_002.npy", np.zeros(15))
    np.save(folder / "frame_003_dop.npy", np.zeros(4))
    np.save(folder / "frame_004_dop.npy", np.zeros((5, 1)))
    seq, _ = load(folder, period_s=0.1)
    for i, (pts, dop) in enumerate([((5, 2), (5,)), ((15,), (5,)), ((5, 3), (4,)),
                                    ((5, 3), (5, 1))]):
        expected = (f"frame_00{i + 1}.npy, frame {i}: expected points (N, 3) and Doppler (N,), "
                    f"got {pts} and {dop}")
        with pytest.raises(DataError, match=re.escape(expected)):
            seq.scan(i)


def test_a_frame_that_is_not_an_npy_file_is_one_data_error(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2])
    (folder / "frame_002.npy").write_bytes(b"garbage, not numpy")
    seq, _ = load(folder, period_s=0.1)
    with pytest.raises(DataError, match=r"frame_002\.npy, frame 1: cannot read the frame \("):
        seq.scan(1)


def test_a_header_promising_more_than_the_limit_is_refused_before_reading(tmp_path,
                                                                          monkeypatch):
    folder = write_frames(tmp_path / "d", [1, 2], n_points=1000)  # 24 kB of points a frame
    seq, _ = load(folder, period_s=0.1)
    monkeypatch.setenv(ENV_VAR, "0.01")  # 10 kB: the files are small enough, the arrays not
    np.save(folder / "frame_002.npy", np.zeros((400, 3), np.float32))  # 4.9 kB file, 4.8 kB
    np.save(folder / "frame_002_dop.npy", np.zeros(400, np.float32))
    assert len(seq.scan(1)) == 400
    with pytest.raises(DataError, match=r"frame_001\.npy, frame 0: the file \(24,128 bytes\) "
                                        "would take 0 MB"):
        seq.scan(0)
    # a header that promises more than the file holds: refused when it is mapped
    with open(folder / "frame_002.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False,
                                                 "shape": (5000, 3)})
        f.write(b"\0" * 64)
    with pytest.raises(DataError, match=r"frame_002\.npy, frame 1: cannot read the frame \("):
        seq.scan(1)


def test_unpadded_numbers_are_ordered_as_numbers(tmp_path):
    folder = tmp_path / "d"
    folder.mkdir()
    for k in (10, 9, 100):
        np.save(folder / f"frame_{k}.npy", np.full((2, 3), float(k)))
        np.save(folder / f"frame_{k}_dop.npy", np.zeros(2))
    assert [f.name for f in find_frames(folder)[1]] == ["frame_9.npy", "frame_10.npy",
                                                       "frame_100.npy"]


def test_two_files_of_one_number_record_no_frame_range(tmp_path):
    folder = write_frames(tmp_path / "d", [5])
    np.save(folder / "frame_5.npy", np.zeros((5, 3)))
    np.save(folder / "frame_5_dop.npy", np.zeros(5))
    seq, _ = load(folder, period_s=0.1)
    assert len(seq) == 2 and "frame_range" not in seq.provenance


def test_two_files_with_a_stride_record_it(tmp_path):
    seq, _ = load(write_frames(tmp_path / "d", [4, 6]), period_s=0.1)
    assert seq.provenance["frame_range"] == {"start": 4, "frames": 2, "stride": 2,
                                             "from": "file numbers"}


def test_a_folder_without_gt_records_no_repeated_poses(tmp_path):
    seq, _ = load(write_frames(tmp_path / "d", [1, 2]), period_s=0.1)
    assert seq.repeated_gt_poses == 0 and seq.provenance["repeated_gt_poses"] == 0
    assert seq.provenance["gt"] is None


def test_the_messages_that_ask_for_an_option_name_it(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3])
    with pytest.raises(DataError, match=re.escape(
            "give the scan period (--period SECONDS, e.g. 0.0833333 for a 12 Hz radar), or "
            "--stamps-from-gt when the TUM file's stamps are the sensor clock") + "$"):
        NpyFramesSequence(folder)
    with pytest.raises(DataError, match=re.escape(
            "(3 frames, 0 rows); give the scan period (--period SECONDS) instead") + "$"):
        NpyFramesSequence(folder, stamps_from_gt=True)
    gt = write_tum(folder / "gt.txt", [0.0, 0.1])
    with pytest.raises(DataError, match="^" + re.escape(
            f"{gt}: 2 GT rows but 3 frames in {folder}; association by order needs one row "
            "per frame (use associate='time')") + "$"):
        NpyFramesSequence(folder, period_s=0.1)
    (folder / "other.txt").write_text("")
    with pytest.raises(DataError, match=re.escape(
            "(gt.txt, other.txt); name the ground truth with --gt FILE (option gt)") + "$"):
        NpyFramesSequence(folder, period_s=0.1)


def test_options_pass_the_association_on(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3])
    write_tum(folder / "gt.txt", [0.0, 0.1, 0.2, 0.3, 0.4])  # 5 rows: only time can associate
    seq = NpyFramesSequence.open([folder], Options(period_s=0.1, associate="time"))
    assert seq.provenance["gt_association"] == "time"
    np.testing.assert_allclose(seq.ground_truth.stamps, [0.0, 0.1, 0.2])


def test_time_association_names_the_files_in_its_report_and_warning(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2, 3, 4, 5, 6])
    gt = write_tum(folder / "gt.txt", [0.0, 0.1, 0.2, 0.3])  # frames at 0.4, 0.5 uncovered
    seq, msgs = load(folder, period_s=0.1, associate="time")
    assert len(seq) == 6 and len(seq.ground_truth) == 4
    assert seq.gt_report["gt_file"] == str(gt)
    assert any(m.startswith(f"{folder}: ") and str(gt) in m for m in msgs), msgs


def test_a_gt_with_repeated_stamps_bridges_gaps_of_its_moving_steps(tmp_path):
    """Rows repeat each stamp (a 5 Hz GT written three times a step): the largest gap bridged
    is 3 of its steps that advance (0.2 s: 0.6 s), not 3 x 0 s, so every frame is scored."""
    folder = write_frames(tmp_path / "d", range(1, 8))
    t = np.repeat([0.0, 0.2, 0.4, 0.6], 3)
    write_tum(folder / "gt.txt", t, x=t * 10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the duplicate rows are reported
        seq = NpyFramesSequence(folder, period_s=0.1, associate="time")
    np.testing.assert_allclose(seq.ground_truth.stamps, np.arange(7) * 0.1, atol=1e-12)
    np.testing.assert_allclose(seq.ground_truth.poses[:, 0, 3], np.arange(7) * 1.0, atol=1e-9)


def test_a_doppler_file_above_the_limit_names_the_frame(tmp_path, monkeypatch):
    folder = write_frames(tmp_path / "d", [1, 2], n_points=3)
    np.save(folder / "frame_002_dop.npy", np.zeros(2000))  # 16 kB
    seq, _ = load(folder, period_s=0.1)
    monkeypatch.setenv(ENV_VAR, "0.01")
    with pytest.raises(DataError, match=r"^" + re.escape(str(folder / "frame_002.npy")) +
                       r", frame 1: the file \(16,128 bytes\)"):
        seq.scan(1)


def test_a_header_claiming_petabytes_is_refused_without_allocating(tmp_path):
    folder = write_frames(tmp_path / "d", [1, 2])
    with open(folder / "frame_002.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False,
                                                 "shape": (10**15, 3)})
        f.write(b"\0" * 240)
    seq, _ = load(folder, period_s=0.1)
    with pytest.raises(DataError, match=r"frame_002\.npy, frame 1: cannot read the frame"):
        seq.scan(1)
