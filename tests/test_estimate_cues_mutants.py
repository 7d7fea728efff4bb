"""collect_cues (bench.data.calibration.estimate) on drives made on purpose: the road cues of a
flat road at a known height, the frames counted and skipped, and the messages when too few
scans have ground truth (written against the survivors of a mutation run)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import bench.data.calibration.estimate as est
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import make_T
from loaders.trajectory import Trajectory

ROT = Rotation.from_euler("ZYX", [20, 0, 5], degrees=True)  # the GT's attitude


def _drive(n=10, speed_dop=5.0, speed_gt=5.0, gt_frames=None, height=1.5, source=""):
    """A sensor driving along its x axis at ``speed_dop`` (what its Doppler says) over a flat
    road ``height`` below it plus clutter above; GT at ``speed_gt`` along the GT's x axis with
    attitude ROT, only at ``gt_frames`` (all by default)."""
    t = np.arange(n) * 0.1
    rng = np.random.default_rng(3)
    v = np.array([speed_dop, 0.0, 0.0])
    scans = []
    for k in range(n):
        road = np.column_stack([rng.uniform(-20, 20, (300, 2)), np.full(300, -height)])
        clutter = rng.uniform(-1, 1, (300, 3)) * [30, 30, 2] + [0, 0, 1.5]
        p = np.concatenate([road, clutter])
        d = -(p / np.linalg.norm(p, axis=1, keepdims=True)) @ v
        scans.append(Scan(t[k], p, d, source=source and f"{source} {k}"))
    keep = np.arange(n) if gt_frames is None else np.asarray(gt_frames)
    poses = np.array([make_T(ROT.as_matrix(), ROT.apply([speed_gt * s, 0, 0])) for s in t[keep]])
    return MemorySequence("m", SensorInfo("lidar", 0.1), scans, Trajectory(t[keep], poses))


def test_the_road_cues_of_a_flat_road():
    cues = est.collect_cues(_drive())
    np.testing.assert_array_equal(cues.road_frame, np.arange(10))
    np.testing.assert_allclose(cues.normals, np.tile([0, 0, 1.0], (10, 1)), atol=1e-9)
    np.testing.assert_allclose(cues.ups, np.tile(ROT.inv().apply([0, 0, 1.0]), (10, 1)),
                               atol=1e-9)
    np.testing.assert_allclose(cues.heights, np.full(10, 1.5), atol=1e-9)
    assert cues.vel_frame.dtype.kind == "i" and cues.road_frame.dtype.kind == "i"
    np.testing.assert_allclose(cues.b, np.tile([1.0, 0, 0], (10, 1)), atol=1e-9)


def test_five_fast_frames_after_frames_without_gt_are_enough():
    cues = est.collect_cues(_drive(gt_frames=range(5, 10)))
    np.testing.assert_array_equal(cues.vel_frame, [5, 6, 7, 8, 9])
    assert cues.a.shape == (5, 3) and cues.b.shape == (5, 3) and cues.normals.shape == (5, 3)


def test_both_the_doppler_and_the_gt_must_be_fast():
    with pytest.raises(DataError, match=r"^m: only 0 frames faster than 2\.0 m/s"):
        est.collect_cues(_drive(speed_dop=1.5, speed_gt=5.0))
    with pytest.raises(DataError, match=r"^m: only 0 frames faster than 2\.0 m/s"):
        est.collect_cues(_drive(speed_dop=5.0, speed_gt=1.5))


def test_the_messages_when_few_scans_have_gt():
    with pytest.raises(DataError, match=r"^m: only 3 frames faster than"):
        est.collect_cues(_drive(gt_frames=[2, 3, 4]))  # 3 scans with GT: enough to try
    with pytest.raises(DataError, match=r"^m: only 2 scan\(s\) have ground truth \(its ground "
                                        r"truth spans 0\.200-0\.300 s, the 10 scans "
                                        r"0\.000-0\.900 s\); calibration needs the GT "
                                        r"velocity at 3 or more scans: check the GT's clock "
                                        r"\(`bench inspect` shows its coverage\)$"):
        est.collect_cues(_drive(gt_frames=[2, 3]))
    seq = _drive()
    empty = MemorySequence("m", seq.sensor, [], seq.ground_truth)
    with pytest.raises(DataError, match=r"^m: no scan has ground truth \(its ground truth spans "
                                        r"0\.000-0\.900 s, no scans\)"):
        est.collect_cues(empty)


def test_messages_name_the_sequence_by_its_path_and_a_scan_by_its_source():
    seq = _drive(speed_dop=1.0)
    seq.path = "/data/drive.h5"
    with pytest.raises(DataError, match=r"^/data/drive\.h5: only 0 frames"):
        est.collect_cues(seq)
    seq = _drive(source="file.bag frame")
    bare = MemorySequence("m", seq.sensor, [Scan(s.stamp, s.points, None, source=s.source)
                                            for s in seq], seq.ground_truth)
    with pytest.raises(DataError, match=r"^file\.bag frame 0: frame 0: calibration needs "
                                        "Doppler$"):
        est.collect_cues(bare)
