"""Tests for loaders.ntu4dradlm (and the shared bag helpers in loaders.ros1)."""

import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest

from helpers_bags import (
    Motion,
    _raw_pointcloud,
    doppler_sign_cosine,
    make_truth,
    pointcloud_msg,
    write_gt_tum,
    write_imu_only_bag,
    write_ntu_bag,
)
from loaders.errors import DataError, GroundTruthWarning
from loaders.ntu4dradlm import DEFAULT_T_GTBODY_RADAR, NtuSequence
from loaders.posefile import parse_extrinsic
from loaders.store import StoreSequence, write_store

T_BS = parse_extrinsic(DEFAULT_T_GTBODY_RADAR)
MOTION = Motion(T_body_sensor=T_BS)


@pytest.fixture(scope="module")
def truth():
    return make_truth(MOTION, frames=8, points=40)


@pytest.fixture(scope="module")
def bag(tmp_path_factory, truth):
    d = tmp_path_factory.mktemp("ntu")
    path = write_ntu_bag(d / "ntu-car-day-loop1_2022-06-03_0.bag", truth)
    gt = d / "gt_odom.txt"
    write_gt_tum(gt, MOTION, truth.stamps[0] - 0.3, truth.stamps[-1] + 0.3)
    return path, gt


def assert_same_scans(seq, truth, indices=None):
    for i in indices if indices is not None else range(len(seq)):
        s = seq.scan(i)
        np.testing.assert_array_equal(s.points.astype(np.float32), truth.points[i])
        np.testing.assert_array_equal(s.doppler.astype(np.float32), truth.doppler[i])
        assert s.stamp == pytest.approx(truth.stamps[i], abs=1e-6)


def test_pointcloud_channels_by_name_and_gt_in_sensor_frame(bag, truth):
    path, gt = bag
    seq = NtuSequence([path], gt=gt)
    assert len(seq) == len(truth.stamps) and seq.sensor.kind == "radar"
    assert_same_scans(seq, truth)
    s = seq.scan(2)
    assert set(s.fields) == {"power", "range"}
    np.testing.assert_array_equal(s.fields["power"], truth.fields[2]["power"])
    np.testing.assert_array_equal(s.fields["range"], truth.fields[2]["range"])
    # stamps are header stamps (the record time is 5 ms later)
    np.testing.assert_allclose(seq.stamps, truth.stamps, atol=1e-6)
    np.testing.assert_allclose(seq.ground_truth.stamps, seq.stamps)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-5)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, T_BS)
    assert seq.sensor.period_s == pytest.approx(0.08, abs=1e-6)


def test_doppler_sign_convention(bag):
    path, gt = bag
    assert doppler_sign_cosine(NtuSequence([path], gt=gt)) > 0.99
    assert doppler_sign_cosine(NtuSequence([path], gt=gt, doppler_sign=-1)) < -0.99


def test_time_offset(tmp_path, bag, truth):
    path, _ = bag
    gt = tmp_path / "gt_shifted.txt"
    write_gt_tum(gt, MOTION, truth.stamps[0] - 0.3, truth.stamps[-1] + 0.3, stamp_shift=1000.0)
    with pytest.raises(DataError, match="does not overlap") as err:
        NtuSequence([path], gt=gt)
    assert str(gt) in str(err.value) and str(path) in str(err.value)
    seq = NtuSequence([path], gt=gt, time_offset_s=1000.0)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-5)


def test_frames_outside_gt_are_kept_and_unscored(tmp_path, bag, truth):
    path, _ = bag
    gt = tmp_path / "gt_short.txt"
    write_gt_tum(gt, MOTION, truth.stamps[2] - 0.01, truth.stamps[-1] + 0.3)
    with pytest.warns(GroundTruthWarning, match="2 of the 8 scans kept have no ground truth"):
        seq = NtuSequence([path], gt=gt)
    assert len(seq) == 8 and seq.provenance["gt_association"]["uncovered_before"] == 2
    np.testing.assert_allclose(seq.stamps, truth.stamps, atol=1e-6)
    np.testing.assert_allclose(seq.ground_truth.stamps, truth.stamps[2:], atol=1e-6)
    np.testing.assert_array_equal(seq.scan(0).points.astype(np.float32), truth.points[0])
    with pytest.warns(GroundTruthWarning, match="trimmed"):
        trimmed = NtuSequence([path], gt=gt, uncovered="trim")
    assert len(trimmed) == 6
    np.testing.assert_array_equal(trimmed.scan(0).points.astype(np.float32), truth.points[2])


@pytest.mark.parametrize("big_endian", [False, True])
def test_pointcloud2_with_configurable_doppler_field(tmp_path, truth, big_endian):
    path = write_ntu_bag(tmp_path / "pc2.bag", truth, kind="PointCloud2", big_endian=big_endian,
                         doppler_name="velocity")
    seq = NtuSequence([path], doppler_field="velocity")
    assert_same_scans(seq, truth)
    np.testing.assert_array_equal(seq.scan(1).fields["power"], truth.fields[1]["power"])
    with pytest.raises(DataError, match=r"no Doppler field 'doppler'.*velocity"):
        NtuSequence([path], doppler_field="doppler").scan(0)


def test_several_bags_are_merged_in_time_order(tmp_path, truth):
    from helpers_bags import Truth

    first = Truth(truth.stamps[:4], truth.points[:4], truth.doppler[:4], truth.fields[:4], MOTION)
    second = Truth(truth.stamps[4:], truth.points[4:], truth.doppler[4:], truth.fields[4:],
                   MOTION)
    b1 = write_ntu_bag(tmp_path / "x_1.bag", second)
    b0 = write_ntu_bag(tmp_path / "x_0.bag", first)
    seq = NtuSequence([b1, b0])
    assert len(seq) == 8
    assert_same_scans(seq, truth)
    assert "x_0.bag" in seq.scan(0).source and "x_1.bag" in seq.scan(7).source


def test_missing_topic_lists_topics(bag):
    path, _ = bag
    with pytest.raises(DataError) as err:
        NtuSequence([path], topic="/radar_pcl")
    msg = str(err.value)
    assert str(path) in msg and "/radar_pcl" in msg
    assert "/radar_enhanced_pcl (sensor_msgs/msg/PointCloud)" in msg and "/vectornav/imu" in msg


def test_wrong_message_type(tmp_path):
    path = write_imu_only_bag(tmp_path / "imu.bag", "/radar_enhanced_pcl")
    with pytest.raises(DataError, match=r"sensor_msgs/msg/Imu; expected one of "
                                        r"sensor_msgs/msg/PointCloud"):
        NtuSequence([path])


def test_missing_doppler_channel(tmp_path, truth):
    path = write_ntu_bag(tmp_path / "nodop.bag", truth, channel_order=("Power", "Range"))
    seq = NtuSequence([path])
    with pytest.raises(DataError, match=r"no Doppler channel 'Doppler'.*\['Power', 'Range'\]"):
        seq.scan(0)


def test_empty_scan_names_file_and_frame(tmp_path, truth):
    path = write_ntu_bag(tmp_path / "empty.bag", truth, empty_frame=3)
    seq = NtuSequence([path])
    seq.scan(2)
    with pytest.raises(DataError, match=r"empty\.bag.*frame 3.*empty scan"):
        seq.scan(3)


def test_nan_points_dropped_with_warning_and_count(tmp_path, truth):
    path = write_ntu_bag(tmp_path / "nan.bag", truth, nan_frame=1)
    seq = NtuSequence([path])
    with pytest.warns(UserWarning, match="dropped 1 of 40 points"):
        s = seq.scan(1)
    assert len(s) == 39 and seq.provenance["nan_points_dropped"] == 1
    np.testing.assert_array_equal(s.points.astype(np.float32), truth.points[1][1:])
    np.testing.assert_array_equal(s.fields["power"], truth.fields[1]["power"][1:])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        seq.scan(0)


def test_truncated_bag_is_one_clear_error(tmp_path, bag):
    path, _ = bag
    data = Path(path).read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError, match=r"cut\.bag.*truncated"):
        NtuSequence([cut])
    with pytest.raises(DataError, match="not found"):
        NtuSequence([tmp_path / "missing.bag"])


def test_store_round_trip(tmp_path, bag, truth):
    path, gt = bag
    seq = NtuSequence([path], gt=gt)
    out = write_store(seq, tmp_path / "Loop1_0.h5")
    st = StoreSequence(out)
    assert len(st) == len(seq) and st.fields == ["power", "range"]
    for i in range(len(seq)):
        a, b = seq.scan(i), st.scan(i)
        np.testing.assert_array_equal(a.points.astype(np.float32), b.points)
        np.testing.assert_array_equal(a.doppler.astype(np.float32), b.doppler)
        assert a.stamp == b.stamp
    np.testing.assert_allclose(st.ground_truth.poses, seq.ground_truth.poses)
    np.testing.assert_allclose(st.ground_truth.stamps, seq.ground_truth.stamps)
    assert st.provenance["loader"] == "ntu4dradlm"
    st.close()


def test_pickles_for_worker_processes(bag, truth):
    path, gt = bag
    seq = NtuSequence([path], gt=gt)
    seq.scan(0)
    clone = pickle.loads(pickle.dumps(seq))
    np.testing.assert_array_equal(clone.scan(5).points.astype(np.float32), truth.points[5])


def test_fast_raw_serializer_matches_rosbags(truth):
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    chans = {"Power": truth.fields[0]["power"], "Doppler": truth.doppler[0]}
    ref = store.serialize_ros1(pointcloud_msg(store, truth.stamps[0], 7, truth.points[0], chans),
                               "sensor_msgs/msg/PointCloud")
    assert bytes(ref) == _raw_pointcloud(7, truth.stamps[0], truth.points[0], chans)


@pytest.mark.parametrize("compression", ["lz4", "bz2"])
def test_compressed_bags(tmp_path, truth, compression):
    path = write_ntu_bag(tmp_path / f"{compression}.bag", truth, compression=compression)
    seq = NtuSequence([path])
    assert_same_scans(seq, truth, indices=[5, 0, 7, 3])  # random access across chunks


def test_dataset_configs_match_loader_options(tmp_path, truth):
    from bench.data.datasets import read_dataset_config
    from bench.paths import DATASET_CONFIGS as CONFIG_DIR
    from loaders.registry import LOADERS

    names = sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))
    assert {"Campus1", "Campus2", "Loop1_0", "Loop1_4", "StraightWall", "CurvedWall",
            "Tunnel_Empty", "Tunnel_Vehicles"} <= set(names)
    for name in names:
        cfg = read_dataset_config(name)
        assert cfg.store == f"{cfg.name}.h5"
        assert cfg.sensor_class in ("Sparse 4D Radar", "Semi-Dense 4D Radar", "Dense 4D LiDAR")
        # the config's options are the loader's Options model (the one `bench convert` uses)
        options = cfg.loader_options(tmp_path)
        assert isinstance(options, LOADERS[cfg.loader].load_class().Options)
        assert set(cfg.options) <= set(options.model_fields), name
    # the config opens a bag laid out as documented
    cfg = read_dataset_config("Loop1_0")
    write_ntu_bag(tmp_path / cfg.raw_files[0], truth)
    write_gt_tum(tmp_path / "gt_odom.txt", MOTION, truth.stamps[0] - 0.3, truth.stamps[-1] + 0.3)
    seq = cfg.open(tmp_path)
    assert seq.name == "Loop1_0" and len(seq) == len(truth.stamps)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-5)


def test_record_time_stamps_and_unset_header_stamps(tmp_path, bag, truth):
    path, _ = bag
    seq = NtuSequence([path], stamp="record")
    np.testing.assert_allclose(seq.stamps, truth.stamps + 0.005, atol=1e-6)
    assert seq.scan(2).stamp == seq.stamps[2]
    from helpers_bags import Truth

    zero = Truth(np.zeros(4) + 0.0, truth.points[:4], truth.doppler[:4], truth.fields[:4], MOTION)
    p0 = write_ntu_bag(tmp_path / "zero.bag", zero)
    with pytest.raises(DataError, match="unset header.stamp"):
        NtuSequence([p0])
