"""The whole sensor-to-GT rotation estimate (bench.data.calibration.estimate: calibrate_cues,
its bootstrap, calibrate_sequence, CorrectedSequence, rotation_check) on small synthetic cues
and drives made from a known mounting rotation: the estimate must recover it, its bootstrap
interval contain it, shrink with more frames and come back the same for the same seed. The
expected values come from the rotation the data were built with (scipy's Euler angles) or are
worked out by hand from the definitions in the docstrings."""

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import t as student_t

import bench.data.calibration.estimate as est
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import make_T
from loaders.trajectory import Trajectory
from methods.ego_velocity import estimate_ego_velocity
from metrics.intervals import block_indices, correlation_length


def _rot(roll, pitch, yaw):
    """R_gt_sensor = Rz(yaw) Ry(pitch) Rx(roll) [deg], from scipy."""
    return Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True).as_matrix()


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _jitter(v, sd_deg, rng):
    """Each unit vector turned by a random small rotation of ``sd_deg`` per axis."""
    turn = Rotation.from_rotvec(rng.normal(scale=np.radians(sd_deg), size=v.shape))
    return turn.apply(v)


def _cues(R, n=60, car=False, road=0, noise_deg=0.3, seed=0, period=0.1, heights=None):
    """Cues of ``n`` frames from R_gt_sensor ``R``: velocity directions all round the sphere
    (or, ``car``, all near the sensor's x axis, so that roll is not observable from them), GT
    directions ``R a`` with noise; ``road`` frames with a road normal ``R^T up`` of a world up
    within a degree of the GT's z."""
    rng = np.random.default_rng(seed)
    if car:
        a = _unit(np.column_stack([np.ones(n), 0.01 * rng.normal(size=(n, 2))]))
    else:
        a = _unit(rng.normal(size=(n, 3)))
    b = _jitter(a @ R.T, noise_deg, rng)
    ups = _unit(np.column_stack([0.01 * rng.normal(size=(road, 2)), np.ones(road)]))
    normals = _jitter(ups @ R, noise_deg, rng)  # R^T up, row-wise
    road_frame = np.arange(road) * n // max(road, 1)
    if heights is None:
        heights = np.full(road, 1.5)
    return est.FrameCues(n, period, np.arange(n), a, b, road_frame.astype(int),
                         normals.reshape(-1, 3), ups.reshape(-1, 3), np.asarray(heights, float))


TRUE = (3.0, -2.0, 40.0)  # roll, pitch, yaw [deg]


@pytest.fixture(scope="module")
def sphere():
    """The estimate on 60 frames with directions all round the sphere."""
    return est.calibrate_cues(_cues(_rot(*TRUE)), bootstrap=60, seed=1)


def test_all_three_angles_from_velocity_directions_all_round(sphere):
    np.testing.assert_allclose([sphere.angles_deg[a] for a in est.ANGLES], TRUE, atol=0.2)
    np.testing.assert_allclose(sphere.R_gt_sensor, _rot(*TRUE), atol=0.004)
    assert sphere.source == dict.fromkeys(est.ANGLES, "velocity")
    assert sphere.fitted == list(est.ANGLES) and sphere.not_observable == []
    assert sphere.reasons == {}
    assert sphere.frames_used == 60 and sphere.frames_total == 60
    assert sphere.resamples == 60 and sphere.level == 0.95
    assert sphere.road == {}
    magnitude = np.degrees(Rotation.from_matrix(_rot(*TRUE)).magnitude())
    assert sphere.total_deg == pytest.approx(magnitude, abs=0.2)


def test_the_interval_holds_the_truth_and_matches_the_spread(sphere):
    for ax, truth in zip(est.ANGLES, TRUE, strict=True):
        low, high = sphere.interval_deg[ax]
        assert low < truth < high
        assert low < sphere.angles_deg[ax] < high
        # 0.3 deg of noise per axis over 60 frames: an sd of some 0.3 / sqrt(60) ~ 0.04 deg
        assert 0.01 < sphere.std_deg[ax] < 0.15
        # a t interval about the estimate: symmetric, about 2 sd either side
        assert (low + high) / 2 == pytest.approx(sphere.angles_deg[ax], abs=1e-9)
        assert 3.0 < (high - low) / sphere.std_deg[ax] < 6.0


def test_the_bootstrap_is_reproducible_and_shrinks_with_more_frames():
    cues = _cues(_rot(*TRUE), n=40, seed=3)
    one = est.calibrate_cues(cues, bootstrap=40, seed=7)
    again = est.calibrate_cues(cues, bootstrap=40, seed=7)
    other = est.calibrate_cues(cues, bootstrap=40, seed=8)
    assert one.std_deg == again.std_deg and one.interval_deg == again.interval_deg
    assert one.std_deg["yaw"] != other.std_deg["yaw"]
    assert one.angles_deg == other.angles_deg  # the estimate itself draws nothing
    more = est.calibrate_cues(_cues(_rot(*TRUE), n=320, seed=3), bootstrap=40, seed=7)
    for ax in est.ANGLES:
        wide = np.subtract(*one.interval_deg[ax][::-1])
        narrow = np.subtract(*more.interval_deg[ax][::-1])
        # eight times the frames: about a third of the width (1 / sqrt(8))
        assert 0.15 < narrow / wide < 0.6


def test_a_gross_outlier_neither_moves_the_angles_nor_makes_roll_observable():
    cues = _cues(_rot(*TRUE), n=30, car=True, noise_deg=0.05)
    cues.b[7] = _rot(0, 0, 100) @ cues.b[7]  # one pair 100 deg off
    cues.a[7] = [0.0, 1.0, 0.0]  # and its direction far from x
    cal = est.calibrate_cues(cues, bootstrap=20)
    assert cal.frames_used == 29
    assert cal.source["roll"] == "not observable" and cal.not_observable == ["roll"]
    assert cal.fitted == ["pitch", "yaw"]
    # roll held at 0: a direction along x is turned by pitch and yaw alone
    b_true = _rot(*TRUE) @ np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(cal.R_gt_sensor @ [1.0, 0.0, 0.0], b_true, atol=0.002)
    assert cal.angles_deg["roll"] == 0.0
    assert np.isnan(cal.std_deg["roll"]) and all(np.isnan(cal.interval_deg["roll"]))
    assert np.isfinite(cal.std_deg["yaw"]) and np.isfinite(cal.std_deg["pitch"])
    spread = np.sqrt(np.mean(1 - np.delete(cues.a, 7, axis=0)[:, 0] ** 2))
    assert cal.reasons == {"roll": "the velocity directions hardly turn about the sensor's x "
                                   f"axis (RMS spread {spread:.3f}, below 0.05), and the road "
                                   "plane was found in only 0 frames (5 needed)"}


def test_roll_from_the_road_plane_when_the_velocity_misses_it():
    heights = [1.4, 1.9, 1.5, 1.3, 1.6, 9.0, 1.45]  # median 1.5
    cues = _cues(_rot(*TRUE), n=40, car=True, road=7, noise_deg=0.05, heights=heights)
    cal = est.calibrate_cues(cues, bootstrap=30)
    assert cal.source == {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}
    assert cal.fitted == list(est.ANGLES) and cal.reasons == {}
    np.testing.assert_allclose([cal.angles_deg[a] for a in est.ANGLES], TRUE, atol=0.3)
    low, high = cal.interval_deg["roll"]
    assert low < TRUE[0] < high and np.isfinite(cal.std_deg["roll"])
    assert cal.road["frames"] == 7.0 and cal.road["height_m"] == pytest.approx(1.5)
    # three correlation lengths for the block: one per fitted angle
    assert len(cal.block.correlation) == 3


def test_four_road_planes_are_too_few_for_roll_five_enough():
    cal = est.calibrate_cues(_cues(_rot(*TRUE), n=30, car=True, road=4), bootstrap=10)
    assert cal.source["roll"] == "not observable"
    assert "found in only 4 frames (5 needed)" in cal.reasons["roll"]
    assert cal.road["frames"] == 4.0
    cal = est.calibrate_cues(_cues(_rot(*TRUE), n=30, car=True, road=5, noise_deg=0.05),
                             bootstrap=10)
    assert cal.source["roll"] == "road plane" and cal.reasons == {}
    assert cal.angles_deg["roll"] == pytest.approx(TRUE[0], abs=0.2)


def test_five_velocity_frames_are_enough():
    cal = est.calibrate_cues(_cues(_rot(*TRUE), n=5, noise_deg=0.0), bootstrap=0)
    np.testing.assert_allclose([cal.angles_deg[a] for a in est.ANGLES], TRUE, atol=1e-6)


def test_the_road_check_values_from_the_mean_normal_and_up():
    cues = _cues(np.eye(3), n=20, road=5)
    p_s, r_s, p_g, r_g = np.radians([4.0, -3.0, 1.5, 2.5])
    # a normal of pitch p and roll r: (-tan p, tan r, 1) normalised (then atan2 gives them back)
    cues.normals[:] = _unit(np.array([-np.tan(p_s), np.tan(r_s), 1.0]))
    cues.normals[0] *= 2.0  # the mean direction counts, not the length of the sum
    cues.ups[:] = _unit(np.array([-np.tan(p_g), np.tan(r_g), 1.0]))
    cues.heights[:] = [1.0, 2.0, 3.0, 10.0, 0.5]
    road = est.calibrate_cues(cues, bootstrap=0).road
    expected = {"frames": 5.0, "height_m": 2.0, "road_pitch_in_sensor_deg": 4.0,
                "road_roll_in_sensor_deg": -3.0, "up_pitch_in_gt_deg": 1.5,
                "up_roll_in_gt_deg": 2.5}
    assert road.keys() == expected.keys()
    for key, value in expected.items():
        assert road[key] == pytest.approx(value, abs=1e-9), key


def test_no_bootstrap_leaves_the_spread_unknown():
    cal = est.calibrate_cues(_cues(_rot(*TRUE), n=20), bootstrap=0)
    assert cal.resamples == 0
    assert all(np.isnan(cal.std_deg[a]) for a in est.ANGLES)
    np.testing.assert_allclose([cal.angles_deg[a] for a in est.ANGLES], TRUE, atol=0.3)


def test_too_few_velocity_frames_are_refused_by_name():
    cues = _cues(np.eye(3), n=4)
    with pytest.raises(DataError, match=r"^drive 7: only 4 frames fast enough with an "
                                        r"observable ego velocity; calibration needs at least 5$"):
        est.calibrate_cues(cues, name="drive 7")
    with pytest.raises(DataError, match=r"^sequence: only 4 frames"):
        est.calibrate_cues(cues)


def _loose_roll():
    """Velocity directions that fix roll only loosely (spread about x just over 0.05) and a
    good road plane in every frame."""
    rng = np.random.default_rng(11)
    n = 40
    a = _unit(np.column_stack([np.ones(n), 0.09 * rng.normal(size=(n, 2))]))
    b = _jitter(a @ _rot(*TRUE).T, 1.0, rng)
    ups = np.tile([0.0, 0.0, 1.0], (n, 1))
    normals = _jitter(ups @ _rot(*TRUE), 0.05, rng)
    return est.FrameCues(n, 0.1, np.arange(n), a, b, np.arange(n), normals, ups,
                         np.full(n, 1.5))


def test_a_loosely_fixed_roll_comes_from_the_road_instead():
    cues = _loose_roll()
    kept = est.calibrate_cues(cues, bootstrap=30, max_std_deg=1e3)
    assert kept.source["roll"] == "velocity"
    sd = kept.std_deg["roll"]
    assert 1.0 < sd < 2.0  # the velocity knows roll only to a degree or two
    # beyond the default limit of 1 deg: roll from the road
    assert est.calibrate_cues(cues, bootstrap=30).source["roll"] == "road plane"
    # an sd exactly at the limit is still within it
    assert est.calibrate_cues(cues, bootstrap=30, max_std_deg=sd).source["roll"] == "velocity"
    road = est.calibrate_cues(cues, bootstrap=30, max_std_deg=sd * 0.999)
    assert road.source == {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}
    # the refit after the switch keeps a block length that was set (an odd length above 3:
    # never one the rule picks, twice a correlation length)
    switched = est.calibrate_cues(cues, bootstrap=5, max_std_deg=0.0, block_frames=7)
    assert switched.source["roll"] == "road plane" and switched.block.frames == 7
    # the road plane knows roll far better, and gives the truth
    assert road.std_deg["roll"] < sd / 5
    assert road.angles_deg["roll"] == pytest.approx(TRUE[0], abs=0.1)
    low, high = road.interval_deg["roll"]
    assert low < TRUE[0] < high


def test_an_unknown_roll_spread_counts_as_loose():
    # no resamples, no sd: an unknown spread is not within the limit
    cues = _loose_roll()
    cal = est.calibrate_cues(cues, bootstrap=0, max_std_deg=1e3)
    assert cal.source["roll"] == "road plane"


def test_roll_seen_sideways_but_loosely_comes_from_the_road():
    # a sensor turned sideways: its velocity directions lie near y, so pitch is not observable
    # from them but roll is; a limit on roll's sd below its value sends roll to the road
    cues = _cues(_rot(*TRUE), n=30, car=True, road=6, noise_deg=0.05)
    cues.a[:] = cues.a[:, [1, 0, 2]]
    cues.b[:] = _jitter(cues.a @ _rot(*TRUE).T, 0.05, np.random.default_rng(1))
    cal = est.calibrate_cues(cues, bootstrap=10, max_std_deg=1e-9)
    assert cal.source == {"roll": "road plane", "pitch": "not observable", "yaw": "velocity"}
    assert cal.angles_deg["roll"] == pytest.approx(TRUE[0], abs=0.3)


def test_a_spread_exactly_at_the_limit_is_observable():
    cues = _cues(_rot(*TRUE), n=30, car=True, noise_deg=0.05)
    # the RMS spread of the directions about x, as the docstring defines it
    spread = np.sqrt(np.mean(1.0 - (cues.a @ np.eye(3)) ** 2, axis=0))[0]
    assert est.calibrate_cues(cues, bootstrap=0, min_spread=spread).source["roll"] == "velocity"


def test_min_spread_decides_which_axes_velocity_observes():
    cues = _cues(_rot(*TRUE), n=30, car=True, noise_deg=0.05)
    spread = np.sqrt(np.mean(1 - cues.a[:, 0] ** 2))
    at = est.calibrate_cues(cues, bootstrap=0, min_spread=spread * (1 - 1e-9))
    assert at.source["roll"] == "velocity"
    above = est.calibrate_cues(cues, bootstrap=0, min_spread=spread * (1 + 1e-9))
    assert above.source["roll"] == "not observable"
    assert f"RMS spread {spread:.3f}, below {spread * (1 + 1e-9):g}" in above.reasons["roll"]


def _correlations(cues):
    """The correlation lengths of the per-frame residuals about x, y, z of a free fit (scipy's
    Kabsch: what the estimate is with all three angles from velocity and no outlier)."""
    R = Rotation.align_vectors(cues.b, cues.a)[0].as_matrix()
    r = np.cross(cues.a @ R.T, cues.b)
    return tuple(int(correlation_length(r[:, k])) for k in range(3))


def test_the_block_is_twice_the_longest_correlation_and_at_least_three_frames():
    free, none = np.ones(3, bool), np.zeros(3, bool)
    cues = _cues(_rot(*TRUE), n=60, seed=2)
    block, spread = est._bootstrap(cues, free, none, 20, 0, 0.95)
    lengths = _correlations(cues)
    assert block.correlation == lengths and max(lengths) >= 2
    assert block.frames == block.wanted == 2 * max(lengths)
    assert block.seconds == pytest.approx(0.1 * block.frames)
    assert spread.resamples == 20 and spread.level == 0.95
    short = _cues(_rot(*TRUE), n=10, seed=1)
    assert _correlations(short) == (1, 1, 1)
    block, _ = est._bootstrap(short, free, none, 5, 0, 0.95)
    # white-noise residuals: the 3-frame floor decides (the span of a central difference)
    assert (block.frames, block.wanted) == (3, 3)


def test_the_block_can_be_set():
    free, none = np.ones(3, bool), np.zeros(3, bool)
    cues = _cues(_rot(*TRUE), n=60, seed=2)
    set_block, _ = est._bootstrap(cues, free, none, 20, 0, 0.95, block_frames=7)
    assert (set_block.frames, set_block.wanted) == (7, 7)
    assert set_block.seconds == pytest.approx(0.7)
    assert set_block.correlation == _correlations(cues)
    cal = est.calibrate_cues(cues, bootstrap=5, block_frames=9)
    assert cal.block.frames == 9 and cal.block.seconds == pytest.approx(0.9)


def test_the_level_sets_the_interval_width():
    cues = _cues(_rot(*TRUE), n=40, seed=4)
    wide = est.calibrate_cues(cues, bootstrap=30, level=0.99)
    narrow = est.calibrate_cues(cues, bootstrap=30, level=0.5)
    assert wide.level == 0.99 and narrow.level == 0.5
    assert wide.std_deg == narrow.std_deg
    for ax in est.ANGLES:
        ratio = np.subtract(*narrow.interval_deg[ax][::-1]) / np.subtract(
            *wide.interval_deg[ax][::-1])
        # the same sd: the ratio of the t quantiles 0.75 and 0.995 (blocks - 1 dof)
        dof = 40 / wide.block.frames - 1
        assert ratio == pytest.approx(student_t.ppf(0.75, dof) / student_t.ppf(0.995, dof))


def test_resamples_with_fewer_than_five_velocity_frames_are_left_out():
    cues = _cues(_rot(*TRUE), n=12, seed=5)
    sparse = est.FrameCues(40, 0.1, np.array([0, 6, 13, 19, 26, 33]), cues.a[:6], cues.b[:6],
                           np.zeros(0, int), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    block, spread = est._bootstrap(sparse, np.ones(3, bool), np.zeros(3, bool), 50, 3, 0.95,
                                   block_frames=4)
    drawn = block_indices(40, 4, 50, 3)
    enough = sum(np.isin(idx, sparse.vel_frame).sum() >= 5 for idx in drawn)
    assert 0 < enough < 50 and spread.resamples == enough


def test_the_residual_series_in_frame_order():
    R = _rot(*TRUE)
    cues = _cues(R, n=8, road=6, seed=6)
    cues.vel_frame[:] = [5, 0, 7, 1, 6, 2, 4, 3]
    cues.road_frame[:] = [4, 2, 0, 5, 1, 3]
    fit = _rot(2.0, -1.0, 41.0)
    both = est._angle_series(cues, fit, np.array([False, True, True]),
                             np.array([True, False, False]))
    assert sorted(both) == [0, 1, 2]
    order = np.argsort(cues.vel_frame)
    vel = np.cross(cues.a @ fit.T, cues.b)[order]
    road = np.cross(cues.normals @ fit.T, cues.ups)[np.argsort(cues.road_frame)]
    np.testing.assert_allclose(both[0], road[:, 0])
    np.testing.assert_allclose(both[1], vel[:, 1])
    np.testing.assert_allclose(both[2], vel[:, 2])
    # without road normals roll has no series; velocity alone gives all three
    no_road = est._angle_series(est.FrameCues(8, 0.1, cues.vel_frame, cues.a, cues.b,
                                              np.zeros(0, int), np.zeros((0, 3)),
                                              np.zeros((0, 3)), np.zeros(0)),
                                fit, np.array([False, True, True]),
                                np.array([True, False, False]))
    assert sorted(no_road) == [1, 2]
    alone = est._angle_series(cues, fit, np.ones(3, bool), np.zeros(3, bool))
    np.testing.assert_allclose(alone[0], vel[:, 0])


def test_the_residual_series_leave_out_the_outlier():
    cues = _cues(_rot(*TRUE), n=12, seed=8)
    cues.b[4] = _rot(0, 0, 90) @ cues.b[4]
    series = est._angle_series(cues, _rot(*TRUE), np.ones(3, bool), np.zeros(3, bool))
    keep = np.arange(12) != 4
    np.testing.assert_allclose(series[2],
                               np.cross(cues.a[keep] @ _rot(*TRUE).T, cues.b[keep])[:, 2])


# ---- whole drives: points, Doppler and ground truth ----------------------------------------

def _heading(t, turn=1.0):
    """Travel direction [world] at time t: turning and climbing (``turn`` scales both)."""
    th, ph = turn * 0.9 * np.sin(0.8 * t), turn * 0.3 * np.sin(1.3 * t + 0.5)
    return np.column_stack([np.cos(ph) * np.cos(th), np.cos(ph) * np.sin(th), np.sin(ph)])


def _drive(R, n=16, speed=6.0, period=0.1, gt=True, name="d", turn=1.0, noise_mps=0.0):
    """A sensor mounted with R_gt_sensor ``R`` on a vehicle whose GT frame keeps the world's
    axes while it travels along ``_heading``: static points (a road 1.5 m below the GT origin
    and scattered clutter) seen in the sensor frame with their radial Doppler velocity (plus
    Gaussian noise of ``noise_mps``)."""
    fine = np.arange(-1.0, n * period + 1.0, 0.002)
    pos = np.cumsum(speed * _heading(fine, turn), axis=0) * 0.002
    stamps = np.arange(n) * period
    rng = np.random.default_rng(0)
    scans = []
    for k, t in enumerate(stamps):
        v_sensor = speed * _heading(np.array([t]), turn)[0] @ R  # R^T v
        road = np.column_stack([rng.uniform(-20, 20, (250, 2)), np.full(250, -1.5)])
        clutter = rng.uniform(-1, 1, (150, 3)) * [30, 30, 3] + [0, 0, 2]
        p = np.vstack([road, clutter]) @ R  # GT frame -> sensor frame
        d = -_unit(p) @ v_sensor + rng.normal(scale=noise_mps, size=len(p))
        scans.append(Scan(t, p, d, source=f"{name}/{k}"))
    poses = np.array([make_T(np.eye(3), x) for x in pos])
    traj = Trajectory(fine, poses) if gt else None
    sensor = SensorInfo("lidar", period, make_T(_rot(0, 0, 90), np.array([1.0, 0, 2.0])))
    return MemorySequence(name, sensor, scans, traj, provenance={"origin": "synthetic"})


MOUNT = (4.0, -3.0, 25.0)


@pytest.fixture(scope="module")
def mounted():
    return _drive(_rot(*MOUNT))


def test_a_mounting_rotation_comes_back_from_a_drive(mounted):
    cal = est.calibrate_sequence(mounted, bootstrap=20)
    assert cal.source == dict.fromkeys(est.ANGLES, "velocity")
    np.testing.assert_allclose([cal.angles_deg[a] for a in est.ANGLES], MOUNT, atol=0.1)
    assert cal.frames_total == 16 and cal.resamples == 20
    # every frame has the road 1.5 m below, tilted in the sensor frame by the mount
    assert cal.road["frames"] == 16.0 and cal.road["height_m"] == pytest.approx(1.5, abs=0.01)
    n_s = np.array([0.0, 0.0, 1.0]) @ _rot(*MOUNT)  # R^T e_z
    assert cal.road["road_roll_in_sensor_deg"] == pytest.approx(
        np.degrees(np.arctan2(n_s[1], n_s[2])), abs=0.05)
    assert cal.road["up_pitch_in_gt_deg"] == pytest.approx(0.0, abs=1e-9)


def test_the_speed_threshold_and_options_reach_the_estimate(mounted):
    with pytest.raises(DataError, match=r"^d: only 0 frames faster than 7\.0 m/s"):
        est.calibrate_sequence(mounted, min_speed_mps=7.0, bootstrap=2)
    cal = est.calibrate_sequence(mounted, min_spread=0.99, bootstrap=2, seed=3, level=0.5)
    assert cal.level == 0.5 and cal.resamples == 2
    assert set(cal.reasons) == {"pitch", "yaw"} and cal.source["roll"] == "road plane"
    a = est.calibrate_sequence(mounted, bootstrap=6, seed=3, max_std_deg=0.0)
    b = est.calibrate_sequence(mounted, bootstrap=6, seed=4, max_std_deg=0.0)
    assert a.source["roll"] == "road plane" and a.std_deg["yaw"] != b.std_deg["yaw"]


def test_the_sequence_is_named_by_its_path():
    seq = _drive(np.eye(3), n=4)
    seq.path = "/data/drive_04"
    with pytest.raises(DataError, match="^/data/drive_04: only 4 frames faster"):
        est.calibrate_sequence(seq)


def test_the_corrected_store_moves_only_the_ground_truth(mounted):
    R = _rot(*MOUNT)
    fixed = est.CorrectedSequence(mounted, R, frames=(2, 9), details={"velocity": "x"})
    assert fixed.name == "d" and len(fixed) == 16
    np.testing.assert_array_equal(fixed.stamps, mounted.stamps)
    assert fixed.scan(5) is mounted.scan(5)
    assert [s.source for s in fixed][:2] == ["d/0", "d/1"]
    T_fix = make_T(R, np.zeros(3))
    np.testing.assert_allclose(fixed.ground_truth.poses, mounted.ground_truth.poses @ T_fix)
    np.testing.assert_array_equal(fixed.ground_truth.stamps, mounted.ground_truth.stamps)
    s = fixed.sensor
    assert (s.kind, s.period_s, s.model, s.doppler_kind) == ("lidar", 0.1, "", "radial")
    np.testing.assert_allclose(s.T_body_sensor, mounted.sensor.T_body_sensor @ T_fix)
    cal = fixed.provenance["calibration"]
    assert fixed.provenance["origin"] == "synthetic"
    np.testing.assert_allclose(cal["R_gt_sensor"], R)
    np.testing.assert_allclose(cal["roll_pitch_yaw_deg"], MOUNT, atol=1e-9)
    assert cal["applied_to"] == "ground truth and T_body_sensor (points unchanged)"
    assert cal["frames"] == [2, 9] and cal["velocity"] == "x"
    # the corrected store's GT frame is the sensor's: nothing left to calibrate
    again = est.calibrate_sequence(fixed, bootstrap=2)
    np.testing.assert_allclose([again.angles_deg[a] for a in est.ANGLES], 0.0, atol=0.1)


def test_a_corrected_store_without_gt_or_frames():
    seq = _drive(np.eye(3), n=4, gt=False)
    seq.sensor = SensorInfo("radar", 0.05, np.eye(4), "radar-x", "gt-reconstructed")
    fixed = est.CorrectedSequence(seq, _rot(0, 0, 10))
    assert fixed.sensor.doppler_kind == "gt-reconstructed"
    assert fixed.ground_truth is None and fixed.provenance["calibration"]["frames"] is None
    assert set(fixed.provenance["calibration"]) == {"R_gt_sensor", "roll_pitch_yaw_deg",
                                                    "applied_to", "frames"}
    assert (fixed.sensor.kind, fixed.sensor.period_s, fixed.sensor.model) == \
        ("radar", 0.05, "radar-x")


def test_inspect_warns_of_a_rotated_mount_only(mounted):
    cal, warning = est.rotation_check(mounted)
    assert cal is not None and cal.resamples == 50
    assert warning.startswith("the ground truth's frame looks rotated against the sensor "
                              "frame (Doppler ego velocity vs GT velocity): roll +")
    # the mount's angles, each with its sd and cue
    found = re.findall(r"(roll|pitch|yaw) ([-+]\d+\.\d\d) deg \(\+-(\d\.\d\d), velocity\)",
                       warning)
    assert [f[0] for f in found] == list(est.ANGLES)
    np.testing.assert_allclose([float(f[1]) for f in found], MOUNT, atol=0.1)
    assert all(float(f[2]) < 0.3 for f in found)
    assert warning.endswith("velocity); see `bench calibrate`")
    assert warning.count("velocity), ") == 2  # three angles joined by ", "
    # a limit above every angle: nothing off
    assert est.rotation_check(mounted, limit_deg=30.0)[1] is None
    _, only_yaw = est.rotation_check(mounted, limit_deg=4.5)
    assert "): yaw +2" in only_yaw and "roll" not in only_yaw and "pitch" not in only_yaw
    straight = _drive(_rot(0.0, 0.0, 0.2), n=12)
    cal, warning = est.rotation_check(straight)
    assert warning is None and cal.angles_deg["yaw"] == pytest.approx(0.2, abs=0.05)
    # one degree of yaw: beyond the default limit of half a degree
    _, warning = est.rotation_check(_drive(_rot(0.0, 0.0, 1.0), n=12))
    assert re.search(r"\): yaw \+(0\.9\d|1\.0\d) deg \(\+-0\.\d\d, velocity\); see", warning)
    assert est.rotation_check(_drive(np.eye(3), n=6, gt=False)) == (None, None)


def test_the_defaults_of_a_drive_are_those_of_its_cues(mounted):
    # calibrate_sequence(seq) is calibrate_cues with min spread 0.05, 200 resamples, seed 0,
    # level 0.95 on the cues of the frames faster than 2 m/s
    cal = est.calibrate_sequence(mounted)
    cues = est.collect_cues(mounted, 2.0)
    same = est.calibrate_cues(cues, 0.05, 1.0, 200, 0, 0.95)
    assert cal.resamples == 200 and cal.level == 0.95
    assert cal.std_deg == same.std_deg and cal.interval_deg == same.interval_deg
    assert cal.block == same.block
    default = est.calibrate_cues(cues)
    assert default.resamples == 200 and default.std_deg == same.std_deg


def test_a_drive_at_two_and_a_half_metres_per_second_is_fast_enough():
    cal, _ = est.rotation_check(_drive(_rot(*MOUNT), n=8, speed=2.5))
    assert cal is not None and cal.frames_total == 8 and cal.frames_used >= 5


def test_inspect_names_an_angle_beyond_three_of_its_sigmas():
    # noisy Doppler on gentle turns: roll known only to about half a degree
    noisy = _drive(_rot(-0.6, -3.0, 25.0), turn=0.3, noise_mps=0.1)
    cal, warning = est.rotation_check(noisy, limit_deg=0.01)
    assert 3.0 < abs(cal.angles_deg["roll"]) / cal.std_deg["roll"] < 4.0  # the set-up
    assert "roll +" in warning and "yaw +" in warning
    nearer = _drive(_rot(-1.2, -3.0, 25.0), turn=0.3, noise_mps=0.1)
    cal, warning = est.rotation_check(nearer, limit_deg=0.01)
    assert 1.0 < abs(cal.angles_deg["roll"]) / cal.std_deg["roll"] < 3.0  # the set-up
    assert "roll" not in warning and "yaw +" in warning


def test_a_drive_that_fixes_roll_loosely_takes_it_from_the_road():
    d = _drive(_rot(0.5, -3.0, 25.0), turn=0.15, noise_mps=0.08)
    loose = est.calibrate_sequence(d, bootstrap=50, max_std_deg=1e3)
    assert loose.source["roll"] == "velocity" and 1.0 < loose.std_deg["roll"] < 2.0
    cal, _ = est.rotation_check(d)  # the default limit of 1 deg
    assert cal.source["roll"] == "road plane"
    assert cal.angles_deg["roll"] == pytest.approx(0.5, abs=0.1)


def test_a_resample_without_road_frames_is_still_fitted():
    # roll from the road, whose 5 frames lie together at the start: some resamples of 3-frame
    # blocks miss them all and are fitted with roll held at 0 (none is left out)
    cues = _cues(_rot(*TRUE), n=60, car=True, road=5, noise_deg=0.05)
    cues.road_frame[:] = np.arange(5)
    drawn = block_indices(60, 3, 40, 0)
    missed = sum(not np.isin(idx, cues.road_frame).any() for idx in drawn)
    assert missed > 0  # the set-up
    block, spread = est._bootstrap(cues, np.array([False, True, True]),
                                   np.array([True, False, False]), 40, 0, 0.95, block_frames=3)
    assert spread.resamples == 40
    assert np.isfinite(spread.sd_deg).all()


@pytest.mark.parametrize("kind", ["lidar", "radar"])
def test_points_moving_half_a_metre_per_second_are_left_out_of_the_ego_velocity(kind):
    # a quarter of the points (x > 0, y > 0) belong to something moving: their Doppler is
    # 0.5 m/s off, beyond the inlier band (0.1 m/s lidar, 0.2 m/s radar), so the velocity
    # directions are the sensor's own exactly
    R = _rot(*MOUNT)
    base = _drive(R, n=8)
    scans = []
    for s in base:
        moving = (s.points[:, 0] > 0) & (s.points[:, 1] > 0)
        scans.append(Scan(s.stamp, s.points, s.doppler + 0.5 * moving))
    seq = MemorySequence("m", SensorInfo(kind, 0.1), scans, base.ground_truth)
    cues = est.collect_cues(seq)
    assert list(cues.vel_frame) == list(range(8))
    np.testing.assert_allclose(cues.a, _heading(base.stamps) @ R, atol=1e-4)


def test_the_road_plane_comes_from_the_static_points_only():
    # a moving vehicle's flat deck alongside, 1.05 m below the GT origin and tilted 5 deg,
    # has more points below the sensor than the road; its Doppler says it moves (3, 1, 0)
    # m/s, so it is no inlier of the ego velocity and the road (1.5 m below) is still found
    R = _rot(*MOUNT)
    base = _drive(R, n=8)
    rng = np.random.default_rng(3)
    scans = []
    for s in base:
        xy = rng.uniform([2, -6], [6, -2], (330, 2))
        deck = np.column_stack([xy, -1.05 + np.tan(np.radians(5)) * (xy[:, 0] - 4)]) @ R
        v_rel = (6.0 * _heading(np.array([s.stamp]))[0] - [3.0, 1.0, 0.0]) @ R
        scans.append(Scan(s.stamp, np.vstack([s.points, deck]),
                          np.concatenate([s.doppler, -_unit(deck) @ v_rel])))
    cues = est.collect_cues(MemorySequence("m", SensorInfo("lidar", 0.1), scans,
                                           base.ground_truth))
    assert list(cues.road_frame) == list(range(8))
    np.testing.assert_allclose(cues.normals, np.tile([0.0, 0.0, 1.0] @ R, (8, 1)), atol=1e-4)
    np.testing.assert_allclose(cues.heights, 1.5, atol=1e-3)


def _still_scans(n, v, seed=4):
    """``n`` identical scans (stamps k / 8 s) of static points around a sensor moving at ``v``
    [m/s, sensor frame]: every frame gives the same ego velocity, bit for bit."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(-1, 1, (300, 3)) * [30, 30, 3] + [0, 0, 1]
    d = -_unit(p) @ np.asarray(v, float)
    return [Scan(k / 8, p, d) for k in range(n)]


def _straight_gt(n, speed):
    """GT along x at ``speed`` [m/s], poses at the scan stamps (binary fractions: the central
    differences give the speed exactly)."""
    t = np.arange(n) / 8
    return Trajectory(t, np.array([make_T(np.eye(3), np.array([speed * s, 0, 0])) for s in t]))


def test_a_frame_exactly_at_the_speed_limit_is_too_slow():
    # the GT says exactly 2 m/s: not faster than 2 m/s
    seq = MemorySequence("m", SensorInfo("lidar", 0.125), _still_scans(8, [5, 0, 0]),
                         _straight_gt(8, 2.0))
    with pytest.raises(DataError, match=r"^m: only 0 frames faster than 2\.0 m/s"):
        est.collect_cues(seq, min_speed_mps=2.0)
    assert len(est.collect_cues(seq, min_speed_mps=1.999).a) == 8
    # the Doppler says exactly the limit (the ego velocity of every frame, computed here)
    scans = _still_scans(8, [5, 0, 0])
    speed = estimate_ego_velocity(scans[0].points, scans[0].doppler, threshold_mps=0.1).speed_mps
    seq = MemorySequence("m", SensorInfo("lidar", 0.125), scans, _straight_gt(8, 8.0))
    with pytest.raises(DataError, match="^m: only 0 frames faster than"):
        est.collect_cues(seq, min_speed_mps=speed)
    assert len(est.collect_cues(seq, min_speed_mps=speed * 0.999).a) == 8


def test_the_road_cues_are_reproducible():
    # a rough road (10 cm): which points a RANSAC plane keeps depends on its draws, so the same
    # normals twice means seeded draws
    base = _drive(_rot(*MOUNT), n=6)
    rng = np.random.default_rng(9)
    scans = [Scan(s.stamp, s.points + rng.normal(scale=[0, 0, 0.1], size=s.points.shape),
                  s.doppler) for s in base]
    seq = MemorySequence("m", base.sensor, scans, base.ground_truth)
    one, two = est.collect_cues(seq), est.collect_cues(seq)
    assert list(one.road_frame) == list(range(6))
    np.testing.assert_array_equal(one.normals, two.normals)
    np.testing.assert_array_equal(one.heights, two.heights)


def test_a_frame_without_an_ego_velocity_still_gives_its_road_plane():
    # frames 6 and 7 have Doppler values no velocity explains: no velocity cue there, but
    # their road plane is found among all their points
    base = _drive(_rot(*MOUNT), n=8)
    rng = np.random.default_rng(2)
    scans = [s if k < 6 else Scan(s.stamp, s.points, rng.uniform(-8, 8, len(s.points)))
             for k, s in enumerate(base)]
    ego = estimate_ego_velocity(scans[7].points, scans[7].doppler, threshold_mps=0.1)
    assert not ego.observable  # the set-up
    cues = est.collect_cues(MemorySequence("m", base.sensor, scans, base.ground_truth))
    assert list(cues.vel_frame) == list(range(6)) and list(cues.road_frame) == list(range(8))
    np.testing.assert_allclose(cues.heights, 1.5, atol=1e-3)


def test_each_frame_draws_its_own_road_samples():
    # the same rough scan in every frame: each frame's RANSAC draws differ (its index seeds
    # them), so the planes differ slightly from frame to frame
    base = _drive(_rot(*MOUNT), n=6)
    rng = np.random.default_rng(9)
    first = base.scan(0)
    rough = first.points + rng.normal(scale=[0, 0, 0.1], size=first.points.shape)
    scans = [Scan(s.stamp, rough, first.doppler) for s in base]
    cues = est.collect_cues(MemorySequence("m", base.sensor, scans, base.ground_truth))
    assert list(cues.road_frame) == list(range(6))
    assert len({tuple(n) for n in cues.normals}) > 1
    np.testing.assert_allclose(cues.normals, np.tile([0.0, 0.0, 1.0] @ _rot(*MOUNT), (6, 1)),
                               atol=0.01)
