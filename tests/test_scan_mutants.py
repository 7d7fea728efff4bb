"""loaders/scan.py, what tests/test_scan.py leaves open (make mutate's survivors): the values a
``Scan`` keeps (float64 points and Doppler, per-point fields as given, its own copy of the
fields mapping) and the messages naming a bad one, ``SensorInfo``'s defaults and refusals, the
``Sequence`` indexing, iteration and repr, and ``FrameRange`` / ``select_frames`` /
``range_name``: the frames kept, the period scaled, the ground truth cut to the kept span (and to
the kept scans when it is sampled at the scans), the frame range composed in the provenance, and
the names of a cut.

Every sequence is built here with stamps and values chosen so each answer is counted by hand."""

import numpy as np
import pytest

from loaders.errors import DataError
from loaders.scan import (
    DOPPLER_KINDS,
    FrameRange,
    MemorySequence,
    Scan,
    SensorInfo,
    _all_on,
    _on,
    range_name,
    select_frames,
)
from loaders.trajectory import Trajectory


def points(n, value=1.0):
    return np.full((n, 3), value)


def sequence(n=10, period=0.1, gt_stamps=None, provenance=None, closes=None):
    """n scans at stamps k * period, scan k holding 2 points of value k; ground truth (x = t) at
    ``gt_stamps`` (default: the scan stamps)."""
    stamps = np.arange(n) * period
    scans = [Scan(t, points(2, k), np.full(2, -k)) for k, t in enumerate(stamps)]
    gt_t = stamps if gt_stamps is None else np.asarray(gt_stamps, float)
    poses = np.tile(np.eye(4), (len(gt_t), 1, 1))
    poses[:, 0, 3] = gt_t
    seq = MemorySequence("drive", SensorInfo("radar", period, np.diag([2.0, 2, 2, 1]),
                                             "radar-sparse", "ego-compensated"),
                         scans, Trajectory(gt_t, poses), provenance)
    if closes is not None:
        seq.close = lambda: closes.append("closed")
    return seq


def test_a_scan_holds_float64_points_and_doppler_and_the_fields_as_given():
    power = np.array([1, 2, 3], dtype=np.int16)
    given = {"power": power}
    s = Scan(np.int64(2), np.ones((3, 3), np.float32), [1, 2, 3], given, source="f")
    assert s.points.dtype == np.float64 and s.doppler.dtype == np.float64
    assert type(s.stamp) is float and s.stamp == 2.0
    assert s.fields["power"].dtype == np.int16
    given["rcs"] = np.zeros(3)
    assert list(s.fields) == ["power"]  # its own mapping
    assert len(s) == 3 and s.has_doppler
    bare = Scan(0.5, np.zeros((0, 3)))
    assert len(bare) == 0 and not bare.has_doppler and bare.doppler is None
    assert bare.fields == {} and bare.source == ""


def test_a_scans_messages_name_its_source_only_when_it_has_one():
    with pytest.raises(DataError, match=r"^points must have shape \(N, 3\), got \(4, 2\)$"):
        Scan(0.0, np.zeros((4, 2)))
    with pytest.raises(DataError, match=r"^b.bag, frame 3: points must have shape \(N, 3\), got "
                                        r"\(3,\)$"):
        Scan(0.0, np.zeros(3), source="b.bag, frame 3")
    for stamp in (np.nan, np.inf):
        with pytest.raises(DataError, match=rf"^s: stamp must be finite, got {stamp}$"):
            Scan(stamp, points(2), source="s")
    with pytest.raises(DataError, match=r"^doppler must have shape \(2,\) like the points, got "
                                        r"\(2, 1\)$"):
        Scan(0.0, points(2), np.zeros((2, 1)))
    with pytest.raises(DataError, match=r"^per-point field 'snr' must have shape \(2,\), got "
                                        r"\(3,\)$"):
        Scan(0.0, points(2), None, {"snr": np.zeros(3)})


def test_non_finite_rows_are_counted_once_per_row():
    pts = points(5)
    pts[1] = np.nan  # three bad values, one row
    pts[3, 2] = -np.inf
    with pytest.raises(DataError, match=r"^points has 2 non-finite rows \(first at row 1\); "
                                        r"expected finite values \(drop NaN points in the "
                                        r"loader and report the count\)$"):
        Scan(0.0, pts)
    with pytest.raises(DataError, match=r"^doppler has 1 non-finite rows \(first at row 4\)"):
        Scan(0.0, points(5), [0, 0, 0, 0, np.nan])


def test_select_keeps_the_stamp_source_and_absent_doppler():
    s = Scan(3.0, np.arange(12.0).reshape(4, 3), source="src")
    sub = s.select(np.array([3, 0]))
    assert sub.stamp == 3.0 and sub.source == "src" and sub.doppler is None
    np.testing.assert_array_equal(sub.points[:, 0], [9.0, 0.0])


def test_sensor_info_defaults_and_refusals():
    info = SensorInfo("lidar", 0.05)
    np.testing.assert_array_equal(info.T_body_sensor, np.eye(4))
    assert info.model == "" and info.doppler_kind == "radial"
    assert SensorInfo("radar", 1, np.eye(4, dtype=int)).T_body_sensor.dtype == np.float64
    assert DOPPLER_KINDS == ("radial", "ego-compensated", "gt-reconstructed")
    for kind in DOPPLER_KINDS:
        assert SensorInfo("radar", 0.1, doppler_kind=kind).doppler_kind == kind
    with pytest.raises(DataError, match=r"^sensor kind must be 'radar' or 'lidar', got 'sonar'$"):
        SensorInfo("sonar", 0.1)
    with pytest.raises(DataError, match=r"^doppler kind must be one of radial, ego-compensated, "
                                        r"gt-reconstructed, got 'raw'$"):
        SensorInfo("radar", 0.1, doppler_kind="raw")
    for period in (0.0, -0.1, np.nan):
        with pytest.raises(DataError, match=rf"^sensor period must be > 0 s, got {period}$"):
            SensorInfo("radar", period)
    with pytest.raises(DataError, match=r"^T_body_sensor must be 4x4, got \(3, 3\)$"):
        SensorInfo("radar", 0.1, np.eye(3))


def test_indexing_iteration_and_repr():
    seq = sequence(4)
    assert seq[0].stamp == 0.0 and seq[-1].points[0, 0] == 3.0 and seq[-4].points[0, 0] == 0.0
    for bad, shown in ((4, 4), (-5, -1)):
        with pytest.raises(IndexError, match=rf"^drive: frame {shown} out of range \(0\.\.3\)$"):
            seq[bad]
    assert [s.points[0, 0] for s in seq] == [0.0, 1.0, 2.0, 3.0]
    assert repr(seq) == "MemorySequence('drive', 4 frames, radar, with GT)"
    seq.ground_truth = None
    assert repr(seq) == "MemorySequence('drive', 4 frames, radar, no GT)"
    assert seq.close() is None
    assert seq.stamps.dtype == np.float64
    np.testing.assert_allclose(seq.stamps, [0.0, 0.1, 0.2, 0.3])


def test_a_memory_sequence_keeps_its_own_provenance_and_scan_list():
    given = {"a": 1}
    scans = [Scan(0.0, points(1))]
    seq = MemorySequence("m", SensorInfo("radar", 0.1), scans, provenance=given)
    given["b"] = 2
    scans.append(Scan(1.0, points(1)))
    assert seq.provenance == {"a": 1} and len(seq) == 1
    assert MemorySequence("m", SensorInfo("radar", 0.1), []).provenance == {}


@pytest.mark.parametrize("start, frames, stride", [(-1, None, 1), (0, 0, 1), (0, None, 0),
                                                   (0, -2, 1)])
def test_a_bad_frame_range_is_refused_naming_it(start, frames, stride):
    with pytest.raises(DataError, match=rf"^drive: bad frame range start={start}, "
                                        rf"frames={frames}, stride={stride} \(expected start >= "
                                        r"0, frames >= 1, stride >= 1\)$"):
        FrameRange(sequence(), start, frames, stride)


def test_a_range_past_the_end_names_the_last_frame():
    with pytest.raises(DataError, match=r"^drive: start=10 is past the last frame \(9\)$"):
        FrameRange(sequence(10), 10)
    assert len(FrameRange(sequence(10), 9)) == 1  # the last frame alone


def test_a_range_keeps_its_frames_and_scales_the_period():
    closes = []
    base = sequence(10, closes=closes)
    cut = FrameRange(base, 3, None, 2)  # frames 3, 5, 7, 9
    np.testing.assert_array_equal(cut.indices, [3, 5, 7, 9])
    assert len(cut) == 4 and cut.name == "drive"
    assert [cut.scan(i).points[0, 0] for i in range(4)] == [3.0, 5.0, 7.0, 9.0]
    np.testing.assert_allclose(cut.stamps, [0.3, 0.5, 0.7, 0.9])
    cut.stamps[0] = 99.0
    assert cut.stamps[0] == pytest.approx(0.3)
    s = cut.sensor
    assert s.period_s == pytest.approx(0.2) and s.kind == "radar" and s.model == "radar-sparse"
    assert s.doppler_kind == "ego-compensated"
    np.testing.assert_array_equal(s.T_body_sensor, np.diag([2.0, 2, 2, 1]))
    assert len(FrameRange(base, 2, 3, 3)) == 3  # frames 2, 5, 8 (11 is past the end)
    cut.close()
    assert closes == ["closed"]


def test_gt_sampled_at_the_scans_is_kept_at_the_kept_scans_only():
    cut = FrameRange(sequence(10), 2, 3, 2)  # scans at 0.2, 0.4, 0.6
    np.testing.assert_allclose(cut.ground_truth.stamps, [0.2, 0.4, 0.6])
    np.testing.assert_allclose(cut.ground_truth.poses[:, 0, 3], [0.2, 0.4, 0.6])


def test_gt_of_its_own_rate_is_cut_to_the_kept_span():
    gt_t = np.arange(0, 96) * 0.01 - 0.02  # 100 Hz from -0.02 s to 0.93 s
    cut = FrameRange(sequence(10, gt_stamps=gt_t), 2, 3, 2)  # scans at 0.2 ... 0.6
    np.testing.assert_allclose(cut.ground_truth.stamps, np.arange(20, 61) * 0.01)
    # a GT stamp a nanosecond outside the span still counts as inside, two do not
    near = np.array([0.2 - 0.5e-9, 0.25, 0.6 + 0.5e-9, 0.6 + 2e-9, 0.7])
    cut = FrameRange(sequence(10, gt_stamps=near), 2, 3, 2)
    np.testing.assert_allclose(cut.ground_truth.stamps, near[:3])


def test_a_range_without_gt_has_none():
    base = sequence(5)
    base.ground_truth = None
    assert FrameRange(base, 1).ground_truth is None


def test_the_frame_range_is_recorded_and_composes_with_an_earlier_cut():
    cut = FrameRange(sequence(10, provenance={"loader": "x"}), 3, 2, 2)
    assert cut.provenance == {"loader": "x",
                              "frame_range": {"start": 3, "frames": 2, "stride": 2}}
    outer = {"frame_range": {"start": 60, "frames": 10, "stride": 3, "from": "file numbers"}}
    cut = FrameRange(sequence(10, provenance=outer), 2, 4, 2)
    assert cut.provenance["frame_range"] == {"start": 66, "frames": 4, "stride": 6,
                                             "from": "file numbers"}
    cut_of_cut = FrameRange(cut, 1)
    assert cut_of_cut.provenance["frame_range"] == {"start": 72, "frames": 3, "stride": 6,
                                                    "from": "file numbers"}
    # a recorded range with empty values reads as frames 0, 1, 2 ...
    blank = {"frame_range": {"start": None, "stride": 0}}
    assert FrameRange(sequence(10, provenance=blank), 4, 1, 3).provenance["frame_range"] == \
        {"start": 4, "frames": 1, "stride": 3}


def test_on_finds_values_within_a_microsecond_of_unsorted_stamps():
    stamps = np.array([3.0, 1.0, 2.0])
    values = np.array([1.0 + 0.9e-6, 2.0 - 0.9e-6, 3.0 + 1.1e-6, 0.0, 5.0, 1.5, 2.0 + 0.5e-6])
    assert _on(values, stamps).tolist() == [True, True, False, False, False, False, True]
    none = _on(np.array([1.0, 2.0]), np.array([]))
    assert none.dtype == bool and none.tolist() == [False, False]
    assert _on(np.array([2.5]), stamps, tolerance_s=0.5).tolist() == [True]
    assert _all_on(np.array([1.0, 3.0]), stamps) is True
    assert _all_on(np.array([1.0, 3.1]), stamps) is False


def test_select_frames_returns_the_whole_or_a_named_cut():
    seq = sequence(10, provenance={"display_name": "Drive 7"})
    assert select_frames(seq) is seq
    kept = select_frames(seq, 0, 4)
    assert len(kept) == 4 and kept.name == "drive"  # no rename asked for
    assert kept.provenance["display_name"] == "Drive 7"
    cut = select_frames(seq, 2, 3, 2, rename=True)
    assert cut.name == "drive_frames2-6_every2"
    assert cut.provenance["display_name"] == "Drive 7_frames2-6_every2"
    plain = select_frames(sequence(10), 1, rename=True)
    assert plain.name == "drive_frames1-9" and "display_name" not in plain.provenance
    assert len(select_frames(seq, stride=3)) == 4


def test_range_names():
    assert range_name("data1", np.arange(60, 250)) == "data1_frames60-249"
    assert range_name("data1", np.arange(60, 439, 2)) == "data1_frames60-438_every2"
    assert range_name("d", np.array([7])) == "d_frames7-7"
    assert range_name("d", np.array([4, 7])) == "d_frames4-7_every3"


def test_a_range_starts_at_the_first_frame_by_default():
    cut = FrameRange(sequence(10), frames=2)
    np.testing.assert_array_equal(cut.indices, [0, 1])
    assert cut.provenance["frame_range"] == {"start": 0, "frames": 2, "stride": 1}
