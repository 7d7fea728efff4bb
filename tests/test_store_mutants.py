"""loaders/store.py, what tests/test_store.py and tests/test_store_reads.py leave open (make
mutate's survivors): the writer's refusals and messages, the header attributes it records, a
final flush with nothing left to write, the reader's checks of a damaged header (fields, name,
provenance, stamps, ground-truth poses, sensor, per-point arrays, frame counts), the defaults of
older stores' missing attributes, a contiguous (unchunked) store, the block read once for a
stream of small scans, and a store sent to another process (pickled) reading the same.

Stores are written here from small sequences of known values and then damaged with h5py, so
every expected message or value is the one the damage implies."""

import json
import pickle
import re
import time
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest

import loaders.store as store_module
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.store import StoreSequence, store_has_ground_truth, write_store
from loaders.trajectory import Trajectory


def small_sequence(n=4, points=3, doppler=True, fields=("power",), gt=True, provenance=None):
    """Scan k: ``points`` points with x = k, y = 0 .. points-1, Doppler -k, power 10 k."""
    scans = []
    for k in range(n):
        pts = np.column_stack([np.full(points, k), np.arange(points), np.zeros(points)])
        scans.append(Scan(0.5 * k, pts, np.full(points, -k) if doppler else None,
                          {f: np.full(points, 10.0 * k) for f in fields}))
    traj = None
    if gt:
        poses = np.tile(np.eye(4), (n, 1, 1))
        poses[:, 0, 3] = np.arange(n)
        traj = Trajectory(0.5 * np.arange(n), poses)
    sensor = SensorInfo("radar", 0.5, np.diag([1.0, -1, -1, 1]), "radar-semidense",
                        "gt-reconstructed")
    return MemorySequence("seq one", sensor, scans, traj,
                          {"loader": "t"} if provenance is None else provenance)


def stored(tmp_path, name="s.h5", **kw) -> Path:
    return write_store(small_sequence(**kw), tmp_path / name)


def damaged(path, attrs=None, delete=(), replace=None):
    """Change a store's attributes / datasets in place."""
    with h5py.File(path, "r+") as h5:
        for key, value in (attrs or {}).items():
            if value is None:
                del h5.attrs[key]
            else:
                h5.attrs[key] = value
        for key in delete:
            del h5[key]
        for key, data in (replace or {}).items():
            del h5[key]
            h5[key] = data
    return path


def test_the_header_records_the_sequence(tmp_path):
    path = write_store(small_sequence(provenance={"loader": "t", "from": Path("/a/b")}),
                       tmp_path / "s.h5")
    with h5py.File(path) as h5:
        a = dict(h5.attrs)
        assert a["format"] == "doppler-bench-store" and a["format_version"] == 2
        assert a["name"] == "seq one" and a["sensor_kind"] == "radar"
        assert a["sensor_model"] == "radar-semidense" and a["doppler_kind"] == "gt-reconstructed"
        assert a["period_s"] == 0.5 and a["n_frames"] == 4 and a["n_points"] == 12
        assert json.loads(a["fields"]) == ["power"]
        assert a["provenance"] == '{"from": "/a/b", "loader": "t"}'  # sorted, paths as text
        np.testing.assert_array_equal(h5["frames/offset"][:], [0, 3, 6, 9, 12])
        assert h5["frames/offset"].dtype == np.int64 and h5["frames/stamp"].dtype == np.float64
        np.testing.assert_array_equal(h5["frames/stamp"][:], [0.0, 0.5, 1.0, 1.5])
        np.testing.assert_array_equal(h5["extrinsic/T_body_sensor"][:], np.diag([1.0, -1, -1, 1]))
        assert h5["points/xyz"].dtype == np.float32 and h5["points/power"].dtype == np.float32
        np.testing.assert_array_equal(h5["points/doppler"][:], np.repeat([0, -1, -2, -3], 3))
    back = StoreSequence(path)
    assert back.sensor.model == "radar-semidense"
    assert back.sensor.doppler_kind == "gt-reconstructed" and back.sensor.period_s == 0.5
    np.testing.assert_array_equal(back.sensor.T_body_sensor, np.diag([1.0, -1, -1, 1]))
    assert back.provenance == {"from": "/a/b", "loader": "t"}
    assert back.fields == ["power"] and back.has_doppler and back.reads == ("doppler", "power")
    np.testing.assert_array_equal(back[2].fields["power"], [20.0, 20.0, 20.0])


def test_fields_are_stored_sorted_whatever_their_order_in_the_scans(tmp_path):
    path = stored(tmp_path, fields=("snr", "power", "a"))
    assert StoreSequence(path).fields == ["a", "power", "snr"]


def test_progress_is_called_once_per_frame_in_order(tmp_path):
    calls = []
    write_store(small_sequence(n=5), tmp_path / "s.h5", progress=calls.append)
    assert calls == [0, 1, 2, 3, 4]


def test_the_writers_refusals_name_the_sequence_and_frame(tmp_path):
    with pytest.raises(DataError, match=r"^unknown store compression 'zip'; choose from fast, "
                                        r"lzf, gzip$"):
        write_store(small_sequence(), tmp_path / "a.h5", compression="zip")
    empty = MemorySequence("nothing", SensorInfo("radar", 0.1), [])
    with pytest.raises(DataError, match=r"^nothing: the sequence has no frames; nothing to "
                                        r"store$"):
        write_store(empty, tmp_path / "b.h5")
    scans = [Scan(0.0, np.ones((2, 3))), Scan(0.1, np.zeros((0, 3)))]
    with pytest.raises(DataError, match=r"^e, frame 1: empty scan \(0 points\); expected at least "
                                        r"one point$"):
        write_store(MemorySequence("e", SensorInfo("radar", 0.1), scans), tmp_path / "c.h5")
    scans = [Scan(0.0, np.ones((2, 3))), Scan(0.1, np.ones((2, 3)), np.zeros(2))]
    with pytest.raises(DataError, match=r"^d, frame 1: Doppler is present but was missing in "
                                        r"frame 0$"):
        write_store(MemorySequence("d", SensorInfo("radar", 0.1), scans), tmp_path / "d.h5")
    scans = [Scan(0.0, np.ones((2, 3)), None, {"power": np.ones(2)}),
             Scan(0.1, np.ones((2, 3)), None, {"rcs": np.ones(2), "power": np.ones(2)})]
    with pytest.raises(DataError, match=r"^f, frame 1: per-point fields \['power', 'rcs'\] "
                                        r"differ from frame 0's \['power'\]$"):
        write_store(MemorySequence("f", SensorInfo("radar", 0.1), scans), tmp_path / "f.h5")
    assert not any(tmp_path.iterdir())  # nothing left behind by any refusal


def test_an_empty_first_scan_is_refused(tmp_path):
    scans = [Scan(0.0, np.zeros((0, 3)))]
    with pytest.raises(DataError, match=r"^z, frame 0: empty scan"):
        write_store(MemorySequence("z", SensorInfo("radar", 0.1), scans), tmp_path / "z.h5")


def test_a_stream_that_fills_the_buffer_exactly_ends_with_an_empty_flush(tmp_path, monkeypatch):
    monkeypatch.setattr(store_module, "_FLUSH_POINTS", 6)
    path = stored(tmp_path, n=4, points=3)  # flushes after frames 1 and 3: nothing left at the end
    back = StoreSequence(path)
    for k in range(4):
        np.testing.assert_array_equal(back[k].points[:, 0], [k, k, k])
        np.testing.assert_array_equal(back[k].fields["power"], [10.0 * k] * 3)


def test_store_has_ground_truth(tmp_path):
    assert store_has_ground_truth(stored(tmp_path, "a.h5")) is True
    assert store_has_ground_truth(stored(tmp_path, "b.h5", gt=False)) is False
    (tmp_path / "c.h5").write_text("not hdf5")
    assert store_has_ground_truth(tmp_path / "c.h5") is None
    assert store_has_ground_truth(tmp_path / "absent.h5") is None


@pytest.mark.parametrize("value, shown", [('{"a": 1}', "{'a': 1}"), ("[1]", "[1]"),
                                          ('"power"', "'power'")])
def test_fields_that_are_no_list_of_names_are_refused(tmp_path, value, shown):
    path = damaged(stored(tmp_path), {"fields": value})
    expected = (f"{path}: damaged store: attribute fields is {shown}; expected a list of field "
                "names")
    with pytest.raises(DataError, match=f"^{re.escape(expected)}$"):
        StoreSequence(path)


@pytest.mark.parametrize("name", ["", "  "])
def test_an_empty_name_is_refused(tmp_path, name):
    path = damaged(stored(tmp_path), {"name": name})
    expected = (f"{path}: damaged store: attribute name {name!r} is empty or holds a NUL byte; "
                "expected the sequence's name")
    with pytest.raises(DataError, match=f"^{re.escape(expected)}$"):
        StoreSequence(path)


def test_a_name_with_separators_is_a_label_and_reads(tmp_path):
    path = damaged(stored(tmp_path), {"name": "a/b.c"})
    assert StoreSequence(path).name == "a/b.c"


def test_a_provenance_that_is_no_mapping_is_refused(tmp_path):
    path = damaged(stored(tmp_path), {"provenance": "[1, 2]"})
    with pytest.raises(DataError, match=rf"^{path}: damaged store: attribute provenance is not "
                                        "a mapping$"):
        StoreSequence(path)


def test_a_non_finite_stamp_is_refused_naming_the_frame(tmp_path):
    path = damaged(stored(tmp_path), replace={"frames/stamp": [0.0, 0.5, np.inf, np.nan]})
    with pytest.raises(DataError, match=rf"^{path}: damaged store: frame 2's stamp is inf; "
                                        r"expected finite stamps \[s\]$"):
        StoreSequence(path)


def bad_gt(tmp_path, k, pose=None, stamp=None):
    path = stored(tmp_path)
    with h5py.File(path, "r+") as h5:
        if pose is not None:
            poses = h5["ground_truth/poses"][:]
            poses[k] = pose
            h5["ground_truth/poses"][...] = poses
        if stamp is not None:
            stamps = h5["ground_truth/stamps"][:]
            stamps[k] = stamp
            h5["ground_truth/stamps"][...] = stamps
    return path


def rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


@pytest.mark.parametrize("k, pose, stamp", [
    (1, np.diag([1.01, 1.0, 1.0, 1.0]), None),  # R R^T - I = 0.0201: not a rotation
    (2, np.diag([1.0, 1.0, -1.0, 1.0]), None),  # a reflection: orthogonal, det -1
    (3, np.full((4, 4), np.nan), None),
    (0, None, np.nan),
    (1, np.diag([np.inf, 1.0, 1.0, 1.0]), None),
])
def test_ground_truth_that_is_no_rigid_transform_is_refused(tmp_path, k, pose, stamp):
    path = bad_gt(tmp_path, k, pose, stamp)
    with pytest.raises(DataError, match=rf"^{path}: damaged store: ground-truth pose {k} \(stamp "
                                        r".*\) is not a rigid transform \(its rotation is not a "
                                        r"rotation, or a value is not finite\)$"):
        StoreSequence(path)


def test_ground_truth_within_the_rotation_tolerance_reads(tmp_path):
    pose = np.eye(4)
    pose[:3, :3] = rot_z(0.3) * (1 + 4e-4)  # R R^T - I = 8e-4: within 1e-3 (printed digits)
    path = bad_gt(tmp_path, 2, pose)
    back = StoreSequence(path)
    np.testing.assert_allclose(back.ground_truth.poses[2][:3, :3], rot_z(0.3) * (1 + 4e-4))
    empty = damaged(stored(tmp_path, "e.h5"), replace={"ground_truth/stamps": np.zeros(0),
                                                      "ground_truth/poses": np.zeros((0, 4, 4))})
    assert len(StoreSequence(empty).ground_truth) == 0


def test_a_newer_format_version_asks_for_an_upgrade(tmp_path):
    path = damaged(stored(tmp_path), {"format_version": 3})
    with pytest.raises(DataError, match=rf"^{path}: store format version 3 is newer than this "
                                        r"package's 2; upgrade doppler-bench$"):
        StoreSequence(path)


def test_a_foreign_format_is_named(tmp_path):
    path = damaged(stored(tmp_path), {"format": "other"})
    with pytest.raises(DataError, match=rf"^{path}: not a doppler-bench-store file \(format "
                                        r"attribute 'other'\); convert data with `bench "
                                        "convert`$"):
        StoreSequence(path)


def test_a_header_error_without_the_path_is_given_it(tmp_path):
    path = damaged(stored(tmp_path), {"sensor_kind": "sonar"})
    with pytest.raises(DataError, match=rf"^{path}: damaged store: sensor kind must be 'radar' "
                                        r"or 'lidar', got 'sonar'$"):
        StoreSequence(path)


@pytest.mark.parametrize("key", ["n_frames", "fields", "name", "period_s"])
def test_a_missing_attribute_is_a_damaged_store(tmp_path, key):
    path = damaged(stored(tmp_path), {key: None})
    with pytest.raises(DataError, match=rf"^{path}: damaged or truncated store \("):
        StoreSequence(path)


def test_a_missing_dataset_is_a_damaged_store(tmp_path):
    path = damaged(stored(tmp_path), delete=["frames/offset"])
    with pytest.raises(DataError, match=rf"^{path}: damaged or truncated store \("):
        StoreSequence(path)


def test_older_stores_without_model_kind_or_provenance_read_with_defaults(tmp_path):
    path = damaged(stored(tmp_path), {"sensor_model": None, "doppler_kind": None,
                                      "provenance": None})
    back = StoreSequence(path)
    assert back.sensor.model == "" and back.sensor.doppler_kind == "radial"
    assert back.provenance == {}


@pytest.mark.parametrize("key, rows", [("points/power", 11), ("points/doppler", 13)])
def test_a_per_point_array_of_another_length_is_refused(tmp_path, key, rows):
    path = damaged(stored(tmp_path), replace={key: np.zeros(rows, np.float32)})
    name = key.split("/")[1]
    with pytest.raises(DataError, match=rf"^{path}: damaged store: points/{name} has {rows} "
                                        r"rows, points/xyz has 12; expected one value per "
                                        "point$"):
        StoreSequence(path)


def test_a_missing_field_array_is_refused(tmp_path):
    path = damaged(stored(tmp_path), delete=["points/power"])
    with pytest.raises(DataError, match=rf"^{path}: damaged store: points/power has no dataset, "
                                        "points/xyz has 12"):
        StoreSequence(path)


@pytest.mark.parametrize("attrs, replace", [
    ({"n_frames": 5}, {}),
    ({}, {"frames/offset": np.array([0, 3, 6, 9, 11])}),
    ({}, {"frames/offset": np.array([0, 3, 6, 12])}),
    ({}, {"frames/stamp": np.array([0.0, 0.5, 1.0])}),
])
def test_counts_that_disagree_are_a_truncated_store(tmp_path, attrs, replace):
    path = damaged(stored(tmp_path), attrs, replace=replace)
    offsets = len(replace.get("frames/offset", range(5)))
    stamps = len(replace.get("frames/stamp", range(4)))
    frames = attrs.get("n_frames", 4)
    with pytest.raises(DataError, match=rf"^{path}: truncated store: {stamps} stamps, {offsets} "
                                        rf"offsets, 12 points, header says {frames} frames$"):
        StoreSequence(path)


def test_an_empty_frame_in_a_store_is_refused_when_read(tmp_path):
    path = damaged(stored(tmp_path), replace={"frames/offset": np.array([0, 3, 3, 9, 12])})
    seq = StoreSequence(path)
    np.testing.assert_array_equal(seq.points_per_frame(), [3, 0, 6, 3])
    with pytest.raises(DataError, match=rf"^{path}, frame 1: empty scan \(0 points\); expected "
                                        "at least one point$"):
        seq[1]
    assert len(seq[2]) == 6


def test_a_read_error_names_the_frame(tmp_path, monkeypatch):
    seq = StoreSequence(stored(tmp_path))

    def fail(lo, hi):
        raise OSError("Can't read data (checksum)")

    monkeypatch.setattr(seq, "_read_block", fail)
    with pytest.raises(DataError, match=rf"^{seq.path}, frame 2: cannot read points \(Can't read "
                                        r"data \(checksum\)\)$"):
        seq[2]


def test_a_contiguous_store_reads_point_by_point_chunks(tmp_path):
    path = stored(tmp_path)
    with h5py.File(path, "r+") as h5:
        for name in ("xyz", "doppler", "power"):
            data = h5[f"points/{name}"][:]
            del h5[f"points/{name}"]
            h5.create_dataset(f"points/{name}", data=data)  # no chunks
    seq = StoreSequence(path)
    assert seq._chunk == 1
    for k in (3, 0, 2):
        np.testing.assert_array_equal(seq[k].points[:, 0], [k, k, k])
        np.testing.assert_array_equal(seq[k].doppler, [-k, -k, -k])


def test_a_stream_of_small_scans_is_read_in_one_block(tmp_path, monkeypatch):
    seq = StoreSequence(stored(tmp_path, n=6))
    reads = []
    real = seq._read_block
    monkeypatch.setattr(seq, "_read_block", lambda lo, hi: (reads.append((lo, hi)),
                                                            real(lo, hi))[1])
    for k in (0, 1, 5, 2, 0):
        np.testing.assert_array_equal(seq[k].points[:, 0], [k, k, k])
    assert reads == [(0, 3)]
    block = seq._block
    assert (block.lo, block.hi) == (0, 18)  # whole chunk, cut at the last point
    seq.close()
    assert seq._block is None and seq._h5 is None
    np.testing.assert_array_equal(seq[4].points[:, 0], [4, 4, 4])  # reopens
    assert reads == [(0, 3), (12, 15)]


def test_blocks_start_on_a_chunk_and_hold_at_least_block_points(tmp_path, monkeypatch):
    monkeypatch.setattr(store_module, "CHUNK_POINTS", 4)
    monkeypatch.setattr(store_module, "BLOCK_POINTS", 5)
    seq = StoreSequence(stored(tmp_path, n=8, points=3))  # 24 points, chunks of 4
    seq[3]  # points [9, 12): block from chunk start 8, at least 5 points -> 8 .. 16
    assert (seq._block.lo, seq._block.hi) == (8, 16)
    seq[7]  # points [21, 24): 20 .. min(24, 28)
    assert (seq._block.lo, seq._block.hi) == (20, 24)
    seq[0]
    assert (seq._block.lo, seq._block.hi) == (0, 8)
    seq[2]  # points [6, 9) cross the block's end: a new block from chunk 4
    assert (seq._block.lo, seq._block.hi) == (4, 12)
    for k in range(8):
        np.testing.assert_array_equal(seq[k].points[:, 0], [k] * 3)


def test_a_store_sent_to_another_process_reads_the_same(tmp_path):
    seq = StoreSequence(stored(tmp_path), fields={"power"})
    first = seq[1]
    copy = pickle.loads(pickle.dumps(seq))
    assert copy._h5 is None and copy._block is None and copy._datasets is None
    assert seq._h5 is not None  # the original keeps its file open
    again = copy[1]
    np.testing.assert_array_equal(again.points, first.points)
    assert again.doppler is None and list(again.fields) == ["power"]
    np.testing.assert_array_equal(copy.stamps, [0.0, 0.5, 1.0, 1.5])
    s = copy.stamps
    s[0] = 9.0
    assert copy.stamps[0] == 0.0


def test_scans_carry_the_arrays_asked_for_that_the_store_has(tmp_path):
    path = stored(tmp_path, fields=("power", "snr"))
    assert StoreSequence(path, fields=["snr", "rcs"]).reads == ("snr",)
    assert StoreSequence(path, fields=()).reads == ()
    scan = StoreSequence(path, fields={"doppler", "snr"})[3]
    np.testing.assert_array_equal(scan.doppler, [-3, -3, -3])
    assert list(scan.fields) == ["snr"]
    assert scan.source == f"{path}, frame 3" and scan.stamp == 1.5
    no_doppler = stored(tmp_path, "n.h5", doppler=False, fields=())
    seq = StoreSequence(no_doppler)
    assert not seq.has_doppler and seq.reads == () and seq[0].doppler is None


@pytest.mark.parametrize("value", [np.inf, np.nan, 1e200])
def test_non_finite_or_huge_gt_poses_are_refused_without_runtime_warnings(tmp_path, value):
    path = bad_gt(tmp_path, 1, np.full((4, 4), value))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(DataError, match="ground-truth pose 1 .* is not a rigid transform"):
            StoreSequence(path)


def test_a_file_that_is_not_hdf5_says_to_convert_it(tmp_path):
    path = tmp_path / "run.bag"
    path.write_bytes(b"#ROSBAG V2.0\n")
    with pytest.raises(DataError, match="^" + re.escape(
            f"{path}: not an HDF5 file (truncated, or not a store: a raw recording is converted "
            "first with `bench convert LOADER`)") + "$"):
        StoreSequence(path)


class FailingOnce:
    """A dataset whose first read fails (a checksum error), later reads succeed."""

    def __init__(self, ds):
        self.ds, self.failed = ds, False

    def __getitem__(self, key):
        if not self.failed:
            self.failed = True
            raise OSError("Can't read data (checksum)")
        return self.ds[key]


def test_a_failed_block_read_is_retried_on_the_next_scan(tmp_path, monkeypatch):
    monkeypatch.setattr(store_module, "CHUNK_POINTS", 4)
    monkeypatch.setattr(store_module, "BLOCK_POINTS", 5)
    seq = StoreSequence(stored(tmp_path, n=8, points=3))
    seq[0]  # block 0 .. 8
    seq._datasets["xyz"] = FailingOnce(seq._datasets["xyz"])
    with pytest.raises(DataError, match=r"frame 7: cannot read points"):
        seq[7]
    np.testing.assert_array_equal(seq[7].points[:, 0], [7, 7, 7])


def test_a_store_written_a_second_later_is_byte_identical(tmp_path):
    """No dataset carries its creation time (HDF5 records it in whole seconds)."""
    first = stored(tmp_path, "a.h5").read_bytes()
    time.sleep(1.1)
    assert stored(tmp_path, "b.h5").read_bytes() == first


def test_a_frame_without_the_doppler_of_frame_0_is_named(tmp_path):
    scans = [Scan(0.0, np.ones((2, 3)), np.zeros(2)), Scan(0.1, np.ones((2, 3)))]
    with pytest.raises(DataError, match=r"^d, frame 1: Doppler is missing but was present in "
                                        r"frame 0$"):
        write_store(MemorySequence("d", SensorInfo("radar", 0.1), scans), tmp_path / "d.h5")


def test_a_sequence_without_a_name_is_named_by_its_store_path(tmp_path):
    seq = MemorySequence("x", SensorInfo("radar", 0.1), [])
    del seq.name
    path = tmp_path / "out.h5"
    with pytest.raises(DataError, match="^" + re.escape(
            f"{path}: the sequence has no frames; nothing to store") + "$"):
        write_store(seq, path)
