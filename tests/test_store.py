import h5py
import numpy as np
import pytest

from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.store import StoreSequence, write_store


def test_round_trip_is_exact_at_float32(tmp_path, twist_sequence):
    path = write_store(twist_sequence, tmp_path / "s.h5")
    back = StoreSequence(path)
    assert len(back) == len(twist_sequence)
    assert back.name == "twist" and back.sensor.kind == "lidar"
    assert back.provenance == {"test": 1}
    for a, b in zip(twist_sequence, back, strict=True):
        assert b.stamp == a.stamp
        np.testing.assert_array_equal(b.points, a.points.astype(np.float32))
        np.testing.assert_array_equal(b.doppler, a.doppler.astype(np.float32))
        np.testing.assert_array_equal(b.fields["power"], a.fields["power"].astype(np.float32))
    np.testing.assert_array_equal(back.ground_truth.poses, twist_sequence.ground_truth.poses)
    np.testing.assert_array_equal(back.points_per_frame(), [len(s) for s in twist_sequence])
    assert back[7].source.endswith("frame 7")


def test_same_input_gives_byte_identical_files(tmp_path, twist_sequence):
    a = write_store(twist_sequence, tmp_path / "a.h5").read_bytes()
    b = write_store(twist_sequence, tmp_path / "b.h5").read_bytes()
    assert a == b


def test_crash_while_writing_leaves_no_file(tmp_path):
    class Broken(MemorySequence):
        def scan(self, index):
            if index == 3:
                raise DataError("bag.bag, frame 3: truncated message")
            return super().scan(index)

    scans = [Scan(i * 0.1, np.ones((5, 3)) * (i + 1), np.zeros(5)) for i in range(6)]
    seq = Broken("b", SensorInfo("radar", 0.1), scans)
    with pytest.raises(DataError, match="frame 3"):
        write_store(seq, tmp_path / "out.h5")
    assert list(tmp_path.iterdir()) == []


def test_doppler_must_be_consistent_across_frames(tmp_path):
    scans = [Scan(0.0, np.ones((5, 3)), np.zeros(5)), Scan(0.1, np.ones((5, 3)))]
    with pytest.raises(DataError, match="frame 1: Doppler is missing"):
        write_store(MemorySequence("m", SensorInfo("radar", 0.1), scans), tmp_path / "x.h5")


def test_bad_files_get_clear_errors(tmp_path, twist_sequence):
    with pytest.raises(DataError, match="store not found"):
        StoreSequence(tmp_path / "missing.h5")
    text = tmp_path / "notes.h5"
    text.write_text("hello")
    with pytest.raises(DataError, match="not an HDF5 file"):
        StoreSequence(text)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(DataError, match="not a doppler-bench-store file"):
        StoreSequence(foreign)
    good = write_store(twist_sequence, tmp_path / "good.h5").read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(good[: len(good) // 2])
    with pytest.raises(DataError, match="cut.h5"):
        seq = StoreSequence(cut)
        for _ in seq:
            pass


def test_store_without_doppler_or_gt(tmp_path):
    scans = [Scan(i * 0.1, np.random.default_rng(i).normal(size=(10, 3))) for i in range(3)]
    seq = MemorySequence("plain", SensorInfo("lidar", 0.1), scans)
    back = StoreSequence(write_store(seq, tmp_path / "p.h5"))
    assert back.ground_truth is None and back[0].doppler is None
