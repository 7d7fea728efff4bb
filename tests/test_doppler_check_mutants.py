"""The convention checks of loaders.doppler_check against answers worked out by hand: scans whose
Doppler is built from a known sensor velocity (exact ``-d . v``), GT poses of a known constant
motion, height layers placed on purpose. Each check is tested on data it must accept (no false
alarm) and on data it must refuse, and at the edges of its thresholds."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import loaders.doppler_check as dc
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo

PERIOD = 0.125  # exact in binary


def _directions(n: int, rng, max_angle_deg: float = 180.0) -> np.ndarray:
    """``n`` unit vectors within ``max_angle_deg`` of the x axis (uniform on that cap)."""
    cos_min = np.cos(np.radians(max_angle_deg))
    c = rng.uniform(cos_min, 1.0, n)
    a = rng.uniform(0, 2 * np.pi, n)
    s = np.sqrt(1 - c * c)
    return np.column_stack([c, s * np.cos(a), s * np.sin(a)])


def _poses(n: int, speed: float, yaw: float = 0.7) -> np.ndarray:
    """T_world_sensor of a sensor driving forward (its own x) at ``speed`` [m/s], yawed."""
    R = Rotation.from_euler("z", yaw).as_matrix()
    out = np.repeat(np.eye(4)[None], n, axis=0)
    out[:, :3, :3] = R
    out[:, :3, 3] = (np.arange(n) * PERIOD * speed)[:, None] * R[:, 0]
    return out


def _seq(points: list[np.ndarray], dopplers: list[np.ndarray | None],
         kind: str = "radial") -> MemorySequence:
    scans = [Scan(k * PERIOD, p, d) for k, (p, d) in enumerate(zip(points, dopplers,
                                                                   strict=True))]
    return MemorySequence("s", SensorInfo("radar", PERIOD, doppler_kind=kind), scans)


def _radial(points: np.ndarray, v: np.ndarray) -> np.ndarray:
    return -(points / np.linalg.norm(points, axis=1, keepdims=True)) @ v


# -- the ego velocity from Doppler -------------------------------------------------------------

def test_the_ego_velocity_is_exact_on_static_points_and_drops_moving_ones():
    rng = np.random.default_rng(0)
    v = np.array([7.0, -1.5, 0.4])
    p = _directions(200, rng, 80) * rng.uniform(2, 60, (200, 1))
    d = _radial(p, v)
    np.testing.assert_allclose(dc.ego_velocity_from_doppler(p, d), v, atol=1e-9)
    moving = d.copy()
    moving[:10] += rng.uniform(8, 12, 10)  # 5 % of the points move (a car ahead)
    np.testing.assert_allclose(dc.ego_velocity_from_doppler(p, moving), v, atol=1e-9)
    # small noise: everything is an inlier (the 0.2 m/s floor), the fit stays unbiased
    noisy = d + rng.normal(0, 0.01, 200)
    np.testing.assert_allclose(dc.ego_velocity_from_doppler(p, noisy), v, atol=0.01)


def test_the_ego_velocity_needs_ten_points_beyond_half_a_metre():
    rng = np.random.default_rng(1)
    v = np.array([5.0, 0.0, 0.0])
    far = _directions(10, rng) * 10.0
    near = _directions(50, rng) * np.array([[0.5]])  # exactly 0.5 m: not used
    p = np.concatenate([far, near])
    d = np.concatenate([_radial(far, v), rng.normal(0, 30, 50)])
    np.testing.assert_allclose(dc.ego_velocity_from_doppler(p, d), v, atol=1e-9)
    assert dc.ego_velocity_from_doppler(p[1:], d[1:]) is None
    # a point 1 m away counts
    half = np.concatenate([far[:5], _directions(5, rng) * 1.0])
    np.testing.assert_allclose(dc.ego_velocity_from_doppler(half, _radial(half, v)), v,
                               atol=1e-9)


def test_a_slow_mover_is_dropped_beyond_the_0_2_m_s_floor():
    """200 static points and 10 of a car moving 0.8 m/s towards the sensor: the first fit
    leans a little; every static point stays within 0.2 m/s of it, the car's do not, and the
    fit on the static points alone is exact."""
    rng = np.random.default_rng(6)
    v = np.array([6.0, 0.5, 0.0])
    p = _directions(210, rng, 80) * rng.uniform(3, 50, (210, 1))
    d = _radial(p, v)
    d[:10] -= 0.8
    np.testing.assert_allclose(dc.ego_velocity_from_doppler(p, d), v, atol=1e-9)


def test_ten_inliers_are_enough_for_the_second_pass():
    """12 points: 10 static, 2 off by 1 m/s: the 10 static ones are refitted exactly."""
    rng = np.random.default_rng(9)
    v = np.array([5.0, -1.0, 0.2])
    p = _directions(12, rng, 80) * 20.0
    d = _radial(p, v)
    d[:2] += 1.0
    np.testing.assert_allclose(dc.ego_velocity_from_doppler(p, d), v, atol=1e-9)


# -- GT velocities ------------------------------------------------------------------------------

def test_the_half_window_is_half_a_second_of_frames_at_least_two():
    assert dc.half_window_frames(np.arange(50) * 0.125) == 4
    assert dc.half_window_frames(np.arange(50) * 0.2) == 3  # ceil(2.5)
    assert dc.half_window_frames(np.arange(50) * 0.25) == 2
    assert dc.half_window_frames(np.arange(50) * 0.5) == 2  # one frame is too few
    assert dc.half_window_frames(np.arange(50) * 0.0625, half_window_s=1.0) == 16
    # repeated stamps do not count as a period; no step at all: a period of 1 s
    assert dc.half_window_frames(np.repeat(np.arange(20) * 0.125, 3)) == 4
    assert dc.half_window_frames(np.zeros(5)) == 2
    assert dc.half_window_frames(np.zeros(5), half_window_s=3.0) == 3


def test_gt_velocities_are_in_the_sensor_frame():
    poses = _poses(40, 6.0, yaw=0.7)
    v = dc.gt_velocities(np.arange(40) * PERIOD, poses)
    np.testing.assert_allclose(v, np.tile([6.0, 0.0, 0.0], (40, 1)), atol=1e-9)
    # a sensor looking left (yaw +90 deg) while the car drives along world x: v = (0, -s, 0)
    R = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    p = np.repeat(np.eye(4)[None], 10, axis=0)
    p[:, :3, :3] = R
    p[:, 0, 3] = np.arange(10) * 0.5
    np.testing.assert_allclose(dc.gt_velocities(np.arange(10) * 0.25, p, half_window=1),
                               np.tile([0.0, -2.0, 0.0], (10, 1)), atol=1e-9)


def test_gt_velocities_difference_over_the_window_and_skip_repeated_stamps():
    t = np.arange(12) * 0.25
    p = np.repeat(np.eye(4)[None], 12, axis=0)
    p[:, 0, 3] = t ** 2  # accelerating: v(t) = 2 t; a central difference of +-h is exact
    v = dc.gt_velocities(t, p, half_window=2)
    np.testing.assert_allclose(v[2:10, 0], 2 * t[2:10], atol=1e-12)
    # at the ends the window is clipped: frame 0 differences frames 0 and 2
    assert v[0, 0] == pytest.approx((t[2] ** 2 - 0) / t[2])
    assert v[11, 0] == pytest.approx((t[11] ** 2 - t[9] ** 2) / (t[11] - t[9]))
    same = np.zeros(5)
    assert np.isnan(dc.gt_velocities(same, np.repeat(np.eye(4)[None], 5, axis=0))).all()


# -- the sign check -----------------------------------------------------------------------------

def _moving(n_frames: int, speed: float, turn_deg: float = 0.0, scale: float = 1.0,
            n_points: int = 120, seed: int = 0):
    """Scans whose Doppler is that of a sensor moving at ``speed`` along x, its velocity turned
    by ``turn_deg`` about z and scaled by ``scale`` (0, 1: exact and right)."""
    rng = np.random.default_rng(seed)
    R = Rotation.from_euler("z", turn_deg, degrees=True).as_matrix()
    v = scale * (R @ np.array([speed, 0.0, 0.0]))
    pts = [_directions(n_points, rng, 75) * rng.uniform(3, 50, (n_points, 1))
           for _ in range(n_frames)]
    return _seq(pts, [_radial(p, v) for p in pts]), _poses(n_frames, speed)


def test_a_right_convention_is_confirmed_and_a_flipped_one_refused():
    seq, poses = _moving(20, 8.0)
    ok = dc.doppler_sign_check(seq, poses)
    assert ok.verdict == "confirmed" and ok.frames_used == 20
    assert ok.median_cosine == pytest.approx(1.0) and ok.median_speed_ratio == pytest.approx(1.0)
    assert ok.describe() == ("Doppler sign check over 20 moving frames: median cosine +1.000, "
                             "median speed ratio 1.000 -> receding-positive convention "
                             "confirmed")
    seq, poses = _moving(20, 8.0, turn_deg=180)
    bad = dc.doppler_sign_check(seq, poses)
    assert bad.verdict == "appears FLIPPED" and bad.median_cosine == pytest.approx(-1.0)


@pytest.mark.parametrize("turn, verdict", [(55, "confirmed"), (65, "inconclusive"),
                                           (115, "inconclusive"), (125, "appears FLIPPED")])
def test_the_sign_needs_a_cosine_beyond_one_half(turn, verdict):
    seq, poses = _moving(6, 8.0, turn_deg=turn)
    check = dc.doppler_sign_check(seq, poses)
    assert check.verdict == verdict
    assert check.median_cosine == pytest.approx(np.cos(np.radians(turn)), abs=1e-6)


@pytest.mark.parametrize("scale, off", [(1.08, False), (0.92, False), (1.12, True),
                                        (0.5, True)])
def test_a_speed_ratio_off_by_more_than_ten_percent_questions_the_stamps(scale, off):
    seq, poses = _moving(6, 8.0, scale=scale)
    check = dc.doppler_sign_check(seq, poses)
    assert check.median_speed_ratio == pytest.approx(scale)
    if off:
        assert check.verdict == (f"confirmed in direction, but the Doppler speed is {scale:.2f} "
                                 "x the GT speed: check the scan stamps (their period) and the "
                                 "GT clock, which scale every speed")
    else:
        assert check.verdict == "confirmed"


def test_the_sign_check_says_why_it_checked_nothing():
    seq, poses = _moving(6, 8.0)
    none = dc.doppler_sign_check(seq, None)
    assert none.frames_used == 0 and none.verdict == "not checked (no ground truth)"
    assert none.describe() == "Doppler sign check: not checked (no ground truth)"
    no_doppler = _seq([seq[k].points for k in range(6)], [None] * 6)
    for check in (none, dc.doppler_sign_check(no_doppler, poses)):
        assert check.frames_used == 0
        assert np.isnan(check.median_cosine) and np.isnan(check.median_speed_ratio)
    assert dc.doppler_sign_check(no_doppler, poses).verdict == "not checked (no Doppler)"
    # standing still for 8 frames (1 s), then moving: the moving frames are checked
    seq14, poses14 = _moving(14, 8.0, n_points=30)
    still = np.concatenate([np.repeat(poses14[:1], 8, axis=0), poses14[:6]])
    assert dc.gt_velocities(seq14.stamps, still)[0] == pytest.approx(np.zeros(3))
    assert dc.doppler_sign_check(seq14, still).frames_used >= 1
    # slower than 0.5 m/s: no moving frame; just faster: checked
    slow, slow_poses = _moving(6, 0.45)
    still = dc.doppler_sign_check(slow, slow_poses)
    assert still.verdict == "inconclusive (no moving frames)" and still.frames_used == 0
    assert np.isnan(still.median_cosine) and np.isnan(still.median_speed_ratio)
    fast, fast_poses = _moving(6, 0.55)
    assert dc.doppler_sign_check(fast, fast_poses).verdict == "confirmed"
    assert dc.doppler_sign_check(fast, fast_poses, min_speed_mps=0.6).frames_used == 0
    # a frame without a Doppler fit (all points within 0.5 m) is skipped
    pts = [seq[k].points for k in range(6)]
    dop = [seq[k].doppler for k in range(6)]
    pts[2] = pts[2] / np.linalg.norm(pts[2], axis=1, keepdims=True) * 0.4
    assert dc.doppler_sign_check(_seq(pts, dop), poses).frames_used == 5
    # a first frame whose Doppler reads 0 everywhere gives no direction: skipped
    dop[0] = np.zeros(len(dop[0]))
    check = dc.doppler_sign_check(_seq(pts, dop), poses)
    assert check.frames_used == 4 and check.verdict == "confirmed"


def test_the_sign_check_samples_at_most_max_frames_across_the_sequence():
    seq, poses = _moving(30, 8.0, n_points=40)
    assert dc.doppler_sign_check(seq, poses, max_frames=7).frames_used == 7
    assert dc.doppler_sign_check(seq, poses).frames_used == 30
    # by default at most 200 frames
    long, long_poses = _moving(230, 8.0, n_points=20)
    assert dc.doppler_sign_check(long, long_poses).frames_used == 200
    # frames without ground truth (NaN poses) are skipped, not failed on
    poses[10:] = np.nan
    # the difference reaches 4 frames ahead: frames 0-5 have a GT velocity
    assert dc.doppler_sign_check(seq, poses).frames_used == 6


# -- the height check ---------------------------------------------------------------------------

def test_the_densest_layer_is_the_median_of_the_fullest_quarter_metre():
    z = np.concatenate([np.full(30, -0.6), np.full(20, -0.52), np.full(40, 1.3)])
    # bins of 0.25 m from -1: [-0.75, -0.5) holds 50 points, [1.25, 1.5) 40
    assert dc._densest_layer(z) == pytest.approx(-0.6)
    assert dc._densest_layer(np.full(7, 2.0)) == pytest.approx(2.0)
    # a layer's median, both its edges included (not the points beyond its upper edge): the
    # layer [0.25, 0.5) holds 4 points, [0.5, 0.75) 3; the median of 0.25 .. 0.5 inclusive
    z = np.array([0.25, 0.3, 0.35, 0.4, 0.5, 0.5, 0.6, 2.0, 2.1])
    assert dc._densest_layer(z) == pytest.approx(0.375)
    # layers are a quarter metre, not a metre: 50 points at +0.6 m outnumber 36 at -0.6 m and
    # 34 at -0.1 m, which share one metre
    z = np.concatenate([np.full(36, -0.6), np.full(34, -0.1), np.full(50, 0.6)])
    assert dc._densest_layer(z) == pytest.approx(0.6)


def _frame(road_z: float, road: int = 30, near_above: int = 10, far: int = 100,
           seed: int = 0) -> np.ndarray:
    """``road`` points at ``road_z`` within 20 m, ``near_above`` at +1.0 m within 20 m and
    ``far`` at +3.0 m 40-80 m away."""
    rng = np.random.default_rng(seed)

    def ring(n, lo, hi, z):
        r, a = rng.uniform(lo, hi, n), rng.uniform(-np.pi, np.pi, n)
        return np.column_stack([r * np.cos(a), r * np.sin(a), np.full(n, z)])

    return np.concatenate([ring(road, 2, 20, road_z), ring(near_above, 2, 20, 1.0),
                           ring(far, 40, 80, 3.0)])


def _frames_seq(frames: list[np.ndarray]) -> MemorySequence:
    return _seq(frames, [None] * len(frames))


def test_the_height_check_reads_the_road_below_and_says_what_it_used():
    seq = _frames_seq([_frame(-0.5, seed=k) for k in range(100)])
    z = dc.low_points_median_z(seq)
    assert z["frames"] == 60 and z["frames_with_layer"] == 60
    assert z["points"] == 60 * 40 and z["basis"] == "points within 30 m"
    assert z["dominant_layer_z_m"] == pytest.approx(-0.5)
    assert z["frames_below_sensor"] == 1.0
    assert z["all_ranges_layer_z_m"] == pytest.approx(3.0)  # far away the walls outnumber it
    assert z["median_z_m"] == pytest.approx(-0.5) and z["low_points_median_z_m"] == -0.5
    assert z["share_above_sensor"] == pytest.approx(0.25)
    assert z["verdict"] == "road below the sensor (sign looks right)"
    mirrored = dc.low_points_median_z(_frames_seq([_frame(0.5, seed=k) for k in range(10)]))
    assert mirrored["frames"] == 10 and mirrored["dominant_layer_z_m"] == pytest.approx(0.5)
    assert mirrored["frames_below_sensor"] == 0.0
    assert mirrored["verdict"] == "densest layer above the sensor (the elevation looks mirrored)"


def test_a_road_at_the_sensors_height_is_not_below_it():
    z = dc.low_points_median_z(_frames_seq([_frame(0.0, seed=k) for k in range(10)]))
    assert z["dominant_layer_z_m"] == 0.0 and "looks mirrored" in z["verdict"]
    assert z["frames_below_sensor"] == 0.0
    assert z["share_above_sensor"] == pytest.approx(0.25)  # the road at 0 is not above


def test_the_per_frame_layers_decide_and_sparse_frames_give_none():
    # 6 frames with the road below, 4 with a wall layer above: most frames agree on the road
    frames = [_frame(-0.5, seed=k) for k in range(6)] + \
        [_frame(-0.5, road=5, near_above=60, seed=k) for k in range(4)]
    z = dc.low_points_median_z(_frames_seq(frames))
    assert z["dominant_layer_z_m"] == pytest.approx(-0.5)
    assert z["frames_below_sensor"] == pytest.approx(0.6)
    # a frame with 19 near points gives no layer of its own, one with 20 does
    frames = [_frame(-0.5, seed=k) for k in range(8)] + [_frame(-0.5, road=9),
                                                          _frame(-0.5, road=10)]
    z = dc.low_points_median_z(_frames_seq(frames))
    assert z["frames_with_layer"] == 9
    # the first and the last frames are sampled too: the only frame with a layer of its own
    frames = [_frame(-0.5, road=9, seed=k) for k in range(9)] + [_frame(-0.5)]
    assert dc.low_points_median_z(_frames_seq(frames))["frames_with_layer"] == 1
    assert dc.low_points_median_z(_frames_seq(frames[::-1]))["frames_with_layer"] == 1


def test_without_a_frame_of_its_own_layer_the_pooled_near_points_decide():
    """15 frames of 15 near points: 225 near points (enough), but no frame has 20."""
    import warnings

    frames = [_frame(-0.5, road=10, near_above=5, seed=k) for k in range(15)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no mean of an empty list of frames
        z = dc.low_points_median_z(_frames_seq(frames))
    assert z["basis"] == "points within 30 m" and z["frames_with_layer"] == 0
    assert z["dominant_layer_z_m"] == pytest.approx(-0.5) and np.isnan(z["frames_below_sensor"])
    assert z["verdict"] == "road below the sensor (sign looks right)"


def test_with_too_few_near_points_every_point_is_used_and_said():
    # 10 frames of 20 near points each: exactly 200, enough
    frames = [_frame(-0.5, road=10, seed=k) for k in range(10)]
    assert dc.low_points_median_z(_frames_seq(frames))["basis"] == "points within 30 m"
    frames[0] = _frame(-0.5, road=9)
    z = dc.low_points_median_z(_frames_seq(frames))
    assert z["basis"] == "all points (only 199 within 30 m, fewer than 200)"
    assert z["points"] == 10 * 100 + 199
    # on all points the far layer at +3 m is the densest
    assert z["dominant_layer_z_m"] == pytest.approx(3.0) and z["median_z_m"] == 3.0
    # a point exactly 30 m away is near
    p = np.column_stack([np.full(200, 30.0), np.zeros(200), np.full(200, -0.4)])
    z = dc.low_points_median_z(_frames_seq([p]))
    assert z["basis"] == "points within 30 m" and z["points"] == 200


def test_the_low_points_are_the_lowest_tenth():
    z = np.linspace(-1.0, 1.49, 250)
    p = np.column_stack([np.full(250, 10.0), np.zeros(250), z])
    out = dc.low_points_median_z(_frames_seq([p]))
    lowest = np.sort(z)[:25]  # 10 % of 250 (the 0.1 quantile lies between the 25th and 26th)
    assert out["low_points_median_z_m"] == pytest.approx(np.median(lowest))
    assert out["median_z_m"] == pytest.approx(np.median(z))
    assert dc.low_points_median_z(_frames_seq([p]), quantile=0.2)["low_points_median_z_m"] == \
        pytest.approx(np.median(np.sort(z)[:50]))
    # 201 heights: the 0.1 quantile is the 21st lowest, which counts as low
    z = np.linspace(-1.0, 1.0, 201)
    p = np.column_stack([np.full(201, 10.0), np.zeros(201), z])
    assert dc.low_points_median_z(_frames_seq([p]))["low_points_median_z_m"] == \
        pytest.approx(z[10])


def test_an_empty_sequence_is_refused_by_name():
    with pytest.raises(DataError, match="^s: no frames to check$"):
        dc.low_points_median_z(_frames_seq([]))


# -- the Doppler kind check ---------------------------------------------------------------------

SPEED = 10.0  # tolerance max(0.15, 0.1 x 10) = 1 m/s; a point tells the kinds apart beyond 3


def _kind_seq(parts: dict[str, int], n_frames: int = 3, speed: float = SPEED,
              kind: str = "radial", offset: float = 0.0):
    """Frames of points within 25 deg of the direction of travel (predicted radial speed
    about -speed); ``parts``: how many read the radial value ("radial"), minus it
    ("negated"), 0 ("zero"), or neither ("other", +0.4 speed)."""
    rng = np.random.default_rng(7)
    v = np.array([speed, 0.0, 0.0])
    pts, dop = [], []
    for _ in range(n_frames):
        p, d = [], []
        for what, n in parts.items():
            q = _directions(n, rng, 25) * rng.uniform(3, 40, (n, 1))
            r = _radial(q, v)
            p.append(q)
            d.append({"radial": r + offset, "negated": -r, "zero": np.zeros(n) + offset,
                      "other": np.full(n, 0.4 * speed)}[what])
        pts.append(np.concatenate(p))
        dop.append(np.concatenate(d))
    return _seq(pts, dop, kind), _poses(n_frames, speed)


def test_radial_doppler_is_measured_radial_and_agrees():
    seq, poses = _kind_seq({"radial": 80, "negated": 20})
    k = dc.doppler_kind_check(seq, poses)
    assert k.measured == "radial" and k.frames_used == 3
    assert k.share_radial == 1.0 and k.share_compensated == 0.0 and not k.disagrees
    assert k.describe() == ("Doppler kind: declared radial; measured over 3 moving frames: "
                            "100 % of the points fit the raw radial velocity of a static "
                            "world, 0 % read about 0 m/s -> radial")


def test_compensated_doppler_is_measured_so_and_a_radial_declaration_disagrees():
    seq, poses = _kind_seq({"zero": 90, "radial": 10})
    k = dc.doppler_kind_check(seq, poses)
    assert k.measured == "ego-compensated" and k.disagrees
    assert k.share_compensated == pytest.approx(0.9) and k.share_radial == pytest.approx(0.1)
    assert k.describe() == (
        "Doppler kind: declared radial; measured over 3 moving frames: 10 % of the points fit "
        "the raw radial velocity of a static world, 90 % read about 0 m/s -> ego-compensated: "
        "the sensor's own motion is already removed (static points near 0 m/s while the sensor "
        "moves); a Doppler method cannot use it as radial velocity - this DISAGREES with the "
        "declared kind (radial)")
    seq, poses = _kind_seq({"zero": 90, "radial": 10}, kind="ego-compensated")
    assert not dc.doppler_kind_check(seq, poses).disagrees


@pytest.mark.parametrize("parts, measured", [
    ({"radial": 50, "other": 50}, "radial"),
    ({"radial": 49, "other": 51}, "inconclusive"),
    ({"radial": 50, "zero": 25, "other": 25}, "inconclusive"),
    ({"radial": 52, "zero": 25, "other": 23}, "radial"),
    ({"zero": 50, "other": 50}, "ego-compensated"),
    ({"zero": 49, "other": 51}, "inconclusive"),
    ({"zero": 50, "radial": 25, "other": 25}, "inconclusive"),
    ({"zero": 52, "radial": 25, "other": 23}, "ego-compensated"),
])
def test_the_kind_needs_half_the_points_and_twice_the_other_share(parts, measured):
    seq, poses = _kind_seq(parts, n_frames=2)
    k = dc.doppler_kind_check(seq, poses)
    assert k.measured == measured
    assert k.share_radial == pytest.approx(parts.get("radial", 0) / 100)
    assert k.share_compensated == pytest.approx(parts.get("zero", 0) / 100)


@pytest.mark.parametrize("offset, fits", [(0.9, True), (1.1, False)])
def test_a_point_fits_within_a_tenth_of_the_speed(offset, fits):
    seq, poses = _kind_seq({"radial": 50, "zero": 50}, n_frames=2, offset=offset)
    k = dc.doppler_kind_check(seq, poses)
    assert k.share_radial == pytest.approx(0.5 if fits else 0.0)
    assert k.share_compensated == pytest.approx(0.5 if fits else 0.0)


@pytest.mark.parametrize("offset, fits", [(0.14, True), (0.16, False)])
def test_a_slow_sensor_keeps_a_floor_of_0_15_m_s(offset, fits):
    seq, poses = _kind_seq({"radial": 100}, n_frames=2, speed=1.2, offset=offset)
    k = dc.doppler_kind_check(seq, poses)
    assert k.share_radial == pytest.approx(1.0 if fits else 0.0)


def test_points_that_cannot_tell_the_kinds_apart_are_left_out():
    seq, poses = _kind_seq({"zero": 60}, n_frames=2)
    rng = np.random.default_rng(3)
    # sideways points: predicted radial speed below 3 tolerances (3 m/s at 10 m/s) reads 0
    # under both kinds; 10 points 0.5 m or nearer are not used at all
    a = rng.uniform(-1, 1, 40)
    side = np.column_stack([0.25 * np.ones(40), np.cos(a), np.sin(a)]) * 12.0
    side *= 1 / np.linalg.norm(side / 12.0, axis=1, keepdims=True)
    assert (np.abs(_radial(side, np.array([SPEED, 0, 0]))) < 3.0).all()
    near = _directions(10, rng, 25) * 0.5
    p = np.concatenate([seq[0].points, side, near])
    d = np.concatenate([seq[0].doppler, _radial(side, np.array([SPEED, 0, 0])),
                        _radial(near, np.array([SPEED, 0, 0]))])
    k = dc.doppler_kind_check(_seq([p, seq[1].points], [d, seq[1].doppler]), poses)
    assert k.share_compensated == 1.0 and k.share_radial == 0.0


def test_a_frame_needs_ten_telling_points():
    seq9, poses = _kind_seq({"radial": 9}, n_frames=2)
    assert dc.doppler_kind_check(seq9, poses).measured == "inconclusive (no moving frames)"
    seq10, poses = _kind_seq({"radial": 10}, n_frames=2)
    assert dc.doppler_kind_check(seq10, poses).measured == "radial"


def test_the_kind_check_says_why_it_measured_nothing():
    seq, poses = _kind_seq({"radial": 30})
    k = dc.doppler_kind_check(seq, None)
    assert (k.frames_used, k.measured) == (0, "not checked (no ground truth)")
    assert k.describe() == "Doppler kind: declared radial; measured: not checked (no ground " \
                           "truth)"
    assert not k.disagrees
    none = _seq([seq[k].points for k in range(3)], [None] * 3)
    assert dc.doppler_kind_check(none, poses).measured == "not checked (no Doppler)"
    for check in (k, dc.doppler_kind_check(none, poses)):
        assert check.frames_used == 0 and check.declared == "radial"
        assert np.isnan(check.share_radial) and np.isnan(check.share_compensated)
    # standing still for 8 frames (1 s), then moving: the moving frames are measured
    seq14, poses14 = _kind_seq({"radial": 20}, n_frames=14)
    still = np.concatenate([np.repeat(poses14[:1], 8, axis=0), poses14[:6]])
    assert dc.doppler_kind_check(seq14, still).frames_used >= 1
    slow, slow_poses = _kind_seq({"radial": 30}, speed=0.95, kind="ego-compensated")
    still = dc.doppler_kind_check(slow, slow_poses)
    assert still.measured == "inconclusive (no moving frames)" and still.frames_used == 0
    assert np.isnan(still.share_radial) and np.isnan(still.share_compensated)
    assert still.declared == "ego-compensated"
    quick, quick_poses = _kind_seq({"radial": 30}, speed=1.05)
    assert dc.doppler_kind_check(quick, quick_poses).measured == "radial"
    nan_poses = poses.copy()
    nan_poses[:] = np.nan
    assert dc.doppler_kind_check(seq, nan_poses).measured == "inconclusive (no moving frames)"


def test_the_kind_check_samples_at_most_max_frames():
    seq, poses = _kind_seq({"radial": 20}, n_frames=12)
    assert dc.doppler_kind_check(seq, poses, max_frames=5).frames_used == 5
    assert dc.doppler_kind_check(seq, poses).frames_used == 12
    # by default at most 100 frames
    long, long_poses = _kind_seq({"radial": 12}, n_frames=115)
    assert dc.doppler_kind_check(long, long_poses).frames_used == 100


def test_a_gt_reconstructed_store_is_radial_and_says_gt_assisted():
    seq, poses = _kind_seq({"radial": 40}, kind="gt-reconstructed")
    k = dc.doppler_kind_check(seq, poses)
    assert k.measured == "radial" and not k.disagrees
    assert k.describe().endswith("-> radial (rebuilt from the GT's ego motion: every result "
                                 "from this store is GT-assisted)")
    seq, poses = _kind_seq({"zero": 40}, kind="gt-reconstructed")
    k = dc.doppler_kind_check(seq, poses)
    assert k.disagrees and "DISAGREES with the declared kind (gt-reconstructed)" in k.describe()
    assert dc.KindCheck("ego-compensated", 3, 0.1, 0.2, "inconclusive").disagrees is False
    assert dc.KindCheck("gt-reconstructed", 1, 0.875, 0.0, "radial").describe() == (
        "Doppler kind: declared gt-reconstructed; measured over 1 moving frames: 88 % of the "
        "points fit the raw radial velocity of a static world, 0 % read about 0 m/s -> radial "
        "(rebuilt from the GT's ego motion: every result from this store is GT-assisted)")


def test_one_moving_frame_is_described_in_full():
    assert dc.SignCheck(1, 0.875, 1.03125, "confirmed").describe() == (
        "Doppler sign check over 1 moving frames: median cosine +0.875, median speed ratio "
        "1.031 -> receding-positive convention confirmed")


def test_points_a_metre_away_and_just_beyond_three_tolerances_tell():
    """At 10 m/s (tolerance 1 m/s): 60 forward points reading 0, 10 radial ones 1 m away and
    10 radial ones whose predicted value is -3.5 m/s (just beyond 3 tolerances) - 20 of 80
    fit the radial velocity."""
    seq, poses = _kind_seq({"zero": 60}, n_frames=2)
    rng = np.random.default_rng(12)
    v = np.array([SPEED, 0.0, 0.0])
    near = _directions(10, rng, 25) * 1.0
    a = rng.uniform(-np.pi, np.pi, 10)
    s = np.sqrt(1 - 0.35 ** 2)
    oblique = np.column_stack([np.full(10, 0.35), s * np.cos(a), s * np.sin(a)]) * 10.0
    np.testing.assert_allclose(_radial(oblique, v), -3.5)
    p = np.concatenate([seq[0].points, near, oblique])
    d = np.concatenate([seq[0].doppler, _radial(near, v), _radial(oblique, v)])
    k = dc.doppler_kind_check(_seq([p, p], [d, d]), poses)
    assert k.share_radial == pytest.approx(0.25) and k.share_compensated == pytest.approx(0.75)


def test_a_frame_with_too_few_telling_points_is_skipped_not_the_end():
    seq, poses = _kind_seq({"radial": 20}, n_frames=3)
    pts = [seq[0].points[:5]] + [seq[k].points for k in (1, 2)]
    dop = [seq[0].doppler[:5]] + [seq[k].doppler for k in (1, 2)]
    k = dc.doppler_kind_check(_seq(pts, dop), poses)
    assert k.frames_used == 2 and k.measured == "radial"
