"""Tests for loaders.campus (msgs_radar/RadarScanExtended + nav_msgs/Odometry bags)."""

from pathlib import Path

import numpy as np
import pytest

from helpers_bags import (
    Motion,
    Truth,
    doppler_sign_cosine,
    make_truth,
    write_campus_bag,
    write_imu_only_bag,
    write_tum,
)
from loaders.campus import (
    RADAR_SCAN_MSG,
    SCAN_TYPE,
    TARGET_TYPE,
    CampusSequence,
    low_points_median_z,
    spherical_to_xyz,
)
from loaders.errors import DataError
from loaders.ros1 import make_typestore
from loaders.se3 import make_T
from loaders.store import StoreSequence, write_store

UTM = (351234.5, 3456789.25, 12.0)
MOTION = Motion()


@pytest.fixture(scope="module")
def truth():
    return make_truth(MOTION, frames=8, points=30, period=0.06)


@pytest.fixture(scope="module")
def bag(tmp_path_factory, truth):
    d = tmp_path_factory.mktemp("campus")
    path, cols = write_campus_bag(d / "Campus_1.bag", truth, utm=UTM)
    return path, cols


def expected_gt(truth, first_gt_stamp, T_bs=np.eye(4)):
    origin = MOTION.body_pose(first_gt_stamp)[0, :3, 3]
    poses = MOTION.body_pose(truth.stamps)
    poses[:, :3, 3] -= origin
    return poses @ T_bs


def test_points_doppler_fields_and_gt(bag, truth):
    path, cols = bag
    seq = CampusSequence(path)
    assert len(seq) == 8
    for i in range(len(seq)):
        s = seq.scan(i)
        c = cols[i]
        xyz = spherical_to_xyz(c["range"], c["azimuth"], c["elevation"])
        np.testing.assert_allclose(s.points, xyz, atol=1e-9)
        np.testing.assert_allclose(s.points, truth.points[i], atol=1e-5)
        np.testing.assert_array_equal(s.doppler.astype(np.float32), c["velocity"])
        for name in ("snr", "power", "rcs", "detectionconfidence", "std_dev_azimuthangle",
                     "mean_square_error_range", "range", "azimuth", "elevation"):
            assert name in s.fields
        np.testing.assert_array_equal(s.fields["rcs"], c["rcs"])
        assert "velocity" not in s.fields
    origin = np.array(seq.provenance["gt_origin_removed"])
    assert np.linalg.norm(origin - UTM) < 10  # the UTM origin was removed
    first_gt = MOTION.t0 + 0.02 * np.floor((truth.stamps[0] - 0.1 - MOTION.t0) / 0.02)
    np.testing.assert_allclose(seq.ground_truth.poses, expected_gt(truth, first_gt), atol=1e-5)
    assert np.abs(seq.ground_truth.positions).max() < 20


def test_doppler_sign_and_elevation_sign(bag):
    path, _ = bag
    assert doppler_sign_cosine(CampusSequence(path)) > 0.99
    assert doppler_sign_cosine(CampusSequence(path, doppler_sign=-1)) < -0.99
    up = CampusSequence(path).scan(0).points
    down = CampusSequence(path, elevation_sign=-1).scan(0).points
    np.testing.assert_allclose(down[:, 2], -up[:, 2])
    np.testing.assert_allclose(down[:, :2], up[:, :2])


def test_elevation_check_finds_the_road(tmp_path):
    rng = np.random.default_rng(3)
    n = 200
    stamps = MOTION.t0 + 0.5 + 0.06 * np.arange(4)
    pts, dop = [], []
    for _ in stamps:
        road = np.column_stack([rng.uniform(5, 40, n), rng.uniform(-8, 8, n), np.full(n, -0.6)])
        poles = np.column_stack([rng.uniform(5, 40, 40), rng.uniform(-8, 8, 40),
                                 rng.uniform(-0.6, 4.0, 40)])
        p = np.vstack([road, poles]).astype(np.float32)
        pts.append(p)
        dop.append(np.zeros(len(p), np.float32))
    tr = Truth(stamps, pts, dop, [{}] * 4, MOTION)
    path, _ = write_campus_bag(tmp_path / "road.bag", tr, gt_topic=None)
    good = low_points_median_z(CampusSequence(path, gt_topic=None))
    bad = low_points_median_z(CampusSequence(path, gt_topic=None, elevation_sign=-1))
    assert good["dominant_layer_z_m"] == pytest.approx(-0.6, abs=0.01)
    assert bad["dominant_layer_z_m"] == pytest.approx(0.6, abs=0.01)
    assert "looks mirrored" in bad["verdict"] and "right" in good["verdict"]


def test_gt_from_tum_file_and_extrinsic(tmp_path, bag, truth):
    path, _ = bag
    t = truth.stamps[0] - 0.2 + 0.02 * np.arange(40)
    poses = MOTION.body_pose(t)
    poses[:, :3, 3] += UTM
    gt = tmp_path / "campus_gt.txt"
    write_tum(gt, t, poses)
    T = make_T(np.eye(3), [3.5, 0.0, 0.5])
    seq = CampusSequence(path, gt=gt, T_body_radar="3.5 0 0.5 0 0 0 1")
    np.testing.assert_allclose(seq.ground_truth.poses, expected_gt(truth, t[0], T), atol=1e-5)
    assert seq.provenance["gt_association"]["gt_file"] == str(gt)


def test_missing_gt_topic_lists_topics(bag):
    path, _ = bag
    with pytest.raises(DataError, match=r"no topic /odom.*/ground_truth \(nav_msgs/msg/Odometry\)"):
        CampusSequence(path, gt_topic="/odom")


def test_wrong_radar_type(tmp_path):
    path = write_imu_only_bag(tmp_path / "imu.bag", "/radar_scan")
    with pytest.raises(DataError, match=r"sensor_msgs/msg/Imu; expected msgs_radar/msg/"
                                        r"RadarScanExtended.*range, azimuth, elevation, velocity"):
        CampusSequence(path, gt_topic=None)


def test_target_definition_without_velocity(tmp_path, truth):
    target = "float32 range\nfloat32 azimuth\nfloat32 elevation\nfloat32 snr\n"
    store = make_typestore({TARGET_TYPE: target, SCAN_TYPE: RADAR_SCAN_MSG})
    small = Truth(truth.stamps[:2], truth.points[:2], truth.doppler[:2], truth.fields[:2], MOTION)
    path, _ = write_campus_bag(tmp_path / "novel.bag", small, store=store, gt_topic=None)
    with pytest.raises(DataError, match=r"lacks \['velocity'\]"):
        CampusSequence(path, gt_topic=None)


def test_empty_scan_and_truncated_bag(tmp_path, truth):
    pts = [p.copy() for p in truth.points[:3]]
    dop = [d.copy() for d in truth.doppler[:3]]
    pts[1], dop[1] = pts[1][:0], dop[1][:0]
    tr = Truth(truth.stamps[:3], pts, dop, truth.fields[:3], MOTION)
    path, _ = write_campus_bag(tmp_path / "empty.bag", tr, gt_topic=None)
    seq = CampusSequence(path, gt_topic=None)
    with pytest.raises(DataError, match=r"empty\.bag.*frame 1.*empty scan"):
        seq.scan(1)
    data = Path(path).read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError, match=r"cut\.bag"):
        CampusSequence(cut, gt_topic=None)


def test_store_round_trip(tmp_path, bag):
    path, _ = bag
    seq = CampusSequence(path)
    st = StoreSequence(write_store(seq, tmp_path / "Campus1.h5"))
    a, b = seq.scan(3), st.scan(3)
    np.testing.assert_array_equal(a.points.astype(np.float32), b.points)
    np.testing.assert_array_equal(a.fields["snr"], b.fields["snr"])
    np.testing.assert_allclose(st.ground_truth.poses, seq.ground_truth.poses)
    st.close()


def test_non_float_target_fields_use_the_generic_path(tmp_path, truth):
    target = ("float32 range\nfloat32 azimuth\nfloat32 elevation\nfloat32 velocity\n"
              "uint16 track_id\nfloat64 snr\n")
    store = make_typestore({TARGET_TYPE: target, SCAN_TYPE: RADAR_SCAN_MSG})
    small = Truth(truth.stamps[:2], truth.points[:2], truth.doppler[:2], truth.fields[:2], MOTION)
    path, cols = write_campus_bag(tmp_path / "generic.bag", small, store=store, gt_topic=None)
    seq = CampusSequence(path, gt_topic=None)
    assert seq._fast_dtype is None
    s = seq.scan(1)
    np.testing.assert_allclose(s.points, truth.points[1], atol=1e-5)
    np.testing.assert_array_equal(s.doppler.astype(np.float32), cols[1]["velocity"])
    assert {"track_id", "snr"} <= set(s.fields)
