"""Residual mutants of the loaders and of bench/data/inspect_checks.lag_interval."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from bench.data.inspect_checks import MAX_LAG_S, lag_interval
from loaders.errors import DataError
from loaders.npy_frames import NpyFramesSequence
from loaders.snail_radar import SnailRadarSequence


def _speed(t: np.ndarray) -> np.ndarray:
    """A smooth, non-periodic-looking speed (m/s)."""
    return 5 + np.sin(2 * np.pi * t / 7.0) + 0.5 * np.sin(2 * np.pi * t / 3.1)


def test_lag_interval_refines_a_sub_step_lag():
    """GT that is the Doppler speed delayed by 4 ms (less than half the 10 ms lag step): the
    parabolic refinement of the correlation peak finds 4 ms to within 0.5 ms. Kills
    lag_interval 177 (the curvature 2 * r[k] written 2 / r[k]: a third of the shift)."""
    t = np.arange(0, 60, 0.1)
    lag = 0.004
    lo, hi = lag_interval(t, _speed(t), _speed(t - lag))
    assert lo <= hi
    np.testing.assert_allclose([lo, hi], [lag, lag], atol=5e-4)


def _fast(t: np.ndarray) -> np.ndarray:
    return 5 + np.sin(2 * np.pi * t / 1.7) + 0.5 * np.sin(2 * np.pi * t / 0.93)


def test_lag_interval_is_finite_when_the_gt_covers_only_one_end():
    """GT only over the first 3 s of a 30 s record (31 scans): at the lags that push the GT
    window off the scans fewer than 10 scans overlap, so the best lag of a replicate can sit
    next to a lag with no correlation; the interval must still be two finite lags within
    +-MAX_LAG_S (not refined against a missing neighbour). Kills lag_interval 167 (the k - 1
    neighbour not checked) and 170 (the k + 1 neighbour not checked)."""
    t = np.arange(0, 30, 0.1)
    for covered, shift in ((t <= 3.05, -0.3), (t >= 26.95, 0.3)):
        v_g = np.where(covered, _fast(t - shift), np.nan)
        interval = lag_interval(t, _fast(t), v_g)
        assert interval is not None
        lo, hi = interval
        assert np.isfinite(lo) and np.isfinite(hi)
        assert -MAX_LAG_S - 1e-9 <= lo <= hi <= MAX_LAG_S + 1e-9


def test_lag_interval_survives_replicates_that_miss_the_only_feature():
    """A speed that is flat but for one scan (6 m/s at 15 s) and GT that has it 0.3 s later:
    a replicate (8 blocks of 40 of the 300 scans) misses that scan with chance
    (260/300)**8 = 0.32 and then has no correlation at any lag; the other ~136 of 200 still
    place the lag at 0.3 s, so there is an interval and it is about 0.3 s. Kills lag_interval
    156 (the first failing replicate ending the bootstrap)."""
    t = np.arange(0, 30, 0.1)
    v_d = np.full(len(t), 5.0)
    v_d[150] = 6.0
    v_g = np.interp(t - 0.3, t, v_d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        interval = lag_interval(t, v_d, v_g)
    assert interval is not None
    lo, hi = interval
    assert lo <= hi
    np.testing.assert_allclose([lo, hi], [0.3, 0.3], atol=5e-3)


def test_lag_interval_counts_a_scan_on_the_first_gt_stamp():
    """Scans every 0.125 s (exact in binary) and GT over exactly 10 of them (14.5 to 15.625 s)
    that is the speed 2 s earlier: at the lag -2 s (the first lag searched, exact) the 10 GT
    stamps fall exactly on scans, the first on the GT span's first stamp; the span includes
    both its ends, so that lag has the 10 scans a correlation needs and the interval starts
    there. Kills lag_interval 26 (the first GT stamp excluded: 9 scans, no interval)."""
    t = np.arange(200) * 0.125
    v_d = 5 + np.sin(2 * np.pi * t / 3.0)
    v_g = np.full(len(t), np.nan)
    v_g[116:126] = 5 + np.sin(2 * np.pi * (t[116:126] + 2.0) / 3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        interval = lag_interval(t, v_d, v_g)
    assert interval is not None
    lo, hi = interval
    np.testing.assert_allclose(lo, -MAX_LAG_S, atol=1e-12)
    assert lo <= hi <= MAX_LAG_S


def test_lag_interval_refines_a_peak_one_step_inside_the_searchable_lags():
    """100 Hz scans over 20 s and GT only over the last second, the speed delayed by -0.886 s:
    lags below -0.9 s leave fewer than 10 scans under the GT (no correlation), so the peak's
    grid lag -0.89 s is one step inside the searchable ones; its two neighbours have a
    correlation and the parabolic refinement brings the interval's lower end to -0.886 s
    (within 1 ms; the grid lag is 4 ms off). Kills lag_interval 168 (the k - 2 neighbour
    checked instead of k - 1: no refinement there)."""
    t = np.arange(2000) * 0.01

    def speed(x):
        return 5 + np.sin(2 * np.pi * x / 0.37) + 0.5 * np.sin(2 * np.pi * x / 0.23)

    lag = -0.886
    v_g = np.where(t >= 18.995, speed(t - lag), np.nan)
    lo, hi = lag_interval(t, speed(t), v_g)
    np.testing.assert_allclose(lo, lag, atol=1e-3)
    assert lo <= hi <= MAX_LAG_S


def test_lag_interval_is_none_when_most_replicates_find_no_lag():
    """30 scans 5 s apart (blocks of one scan: an iid bootstrap) under GT sampled every 0.1 s:
    the speed is flat but for scan 5, the GT flat but for a 1 s bump at scan 20, so a replicate
    correlates at some lag only if it draws both scans: chance 1 - 2 (29/30)**30 +
    (28/30)**30 = 0.40, about 81 of the 200 replicates (sd 7), under the half the interval
    needs: no interval. Kills lag_interval 198 (a third of the replicates enough)."""
    t = np.round(np.arange(0, 150, 0.1), 6)
    scans = np.flatnonzero(np.isclose(t % 5.0, 0.0))
    assert len(scans) == 30
    v_d = np.full(len(t), np.nan)
    v_d[scans] = 5.0
    v_d[scans[5]] = 6.0
    v_g = np.where(np.abs(t - t[scans[20]]) <= 0.5, 6.0, 5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for seed in (0, 1):
            assert lag_interval(t, v_d, v_g, seed=seed) is None


def _npy_folder(folder, gt_stamps) -> None:
    rng = np.random.default_rng(0)
    for i in range(1, 6):
        np.save(folder / f"frame_{i:03d}.npy", rng.normal(size=(50, 3)) * 10)
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(size=50))
    t = np.asarray(gt_stamps, float)
    np.savetxt(folder / "gt.txt", np.column_stack(
        [t, t * 5.0, np.zeros((len(t), 5)), np.ones(len(t))]))


def test_time_association_of_gt_stamps_that_never_advance(tmp_path):
    """associate="time" with GT rows that all share one stamp (0.3 s, x = 1.5 m): there is
    no GT step to scale a gap limit from, so none is set (max_gap_s None, not a NaN from the
    median of no steps, with its "Mean of empty slice" warning); the one frame at 0.3 s gets
    the pose. Kills NpyFramesSequence._associate 57 (the median taken of no steps)."""
    _npy_folder(tmp_path, [0.3, 0.3, 0.3])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        seq = NpyFramesSequence(tmp_path, period_s=0.1, associate="time")
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert seq.gt_report["max_gap_s"] is None
    np.testing.assert_allclose(seq.ground_truth.stamps, [0.3])
    np.testing.assert_allclose(seq.ground_truth.poses[0, :3, 3], [1.5, 0.0, 0.0])


def test_a_damaged_pointcloud2_in_a_bag_is_named_by_bag_topic_and_message(tmp_path):
    """A Snail-Radar bag whose second PointCloud2 lost its last 20 bytes: the first frame
    reads, the second fails with a DataError naming the bag, the topic and message 1 (no
    "None" location). Kills _BagFrames.read 3 (the location not passed to the parser)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from helpers_snail import EAGLE_OFFSETS, EAGLE_STEP, cloud2_msg, radar_array

    day = tmp_path / "20240123"
    day.mkdir()
    bag = day / "data2.bag"
    store = get_typestore(Stores.ROS1_NOETIC)
    msgtype = "sensor_msgs/msg/PointCloud2"
    rng = np.random.default_rng(0)
    with Writer(bag) as w:
        conn = w.add_connection("/radar_enhanced_pcl2", msgtype, typestore=store)
        for i in range(3):
            t = 1706000000.0 + 0.1 * i
            arr = radar_array("eagle", rng.uniform(-20, 20, (6, 3)), rng.uniform(-3, 3, 6), rng)
            raw = store.serialize_ros1(cloud2_msg(store, t, arr, EAGLE_OFFSETS, EAGLE_STEP,
                                                  seq=i), msgtype)
            w.write(conn, int(round((t + 0.004) * 1e9)), raw[:-20] if i == 1 else raw)
    seq = SnailRadarSequence(bag)
    assert len(seq) == 3 and len(seq[0].points) == 6
    with pytest.raises(DataError) as err:
        seq[1]
    text = str(err.value)
    assert text.startswith(f"{bag}, /radar_enhanced_pcl2 message 1: ")
    assert "None" not in text
