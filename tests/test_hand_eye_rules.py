"""Hand-eye alignment (bench.data.calibration.hand_eye) on noise-free synthetic drives with a
known mounting rotation: the segment vectors follow ``A R = R B`` (GT vectors = R x odometry
vectors), the thresholds on movement and turn, the two-stage fit recovers the rotation
(checked against scipy's align_vectors), which cue fixes which angle, and the errors."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.data.calibration import hand_eye as he_mod
from bench.data.calibration.hand_eye import (
    DISPLACEMENTS,
    HE_BLOCK_S,
    TURN_AXES,
    hand_eye_on,
    hand_eye_rotation,
    segment_vectors,
)
from loaders.errors import DataError

#: the mounting: R_gt_sensor = Rz(yaw) Ry(pitch) Rx(roll), roll 1, pitch 2, yaw -1.5 deg
MOUNT = Rotation.from_euler("ZYX", [-1.5, 2.0, 1.0], degrees=True).as_matrix()


def pose(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def drive(n=200, period=0.1, speed=10.0, tilt=0.0, wiggle=0.3):
    """GT poses of a car at ``speed`` m/s whose heading wanders (yaw 0.6 sin(0.3 t) + ...)
    and whose body pitches and rolls by ``tilt`` rad (default none: every turn is about the
    body's vertical, so the turn axes fix roll and pitch exactly)."""
    t = np.arange(n) * period
    yaw = 0.6 * np.sin(wiggle * t) + 0.2 * t
    pitch = tilt * np.sin(0.7 * t)
    roll = tilt * np.sin(0.5 * t + 1.0)
    R = Rotation.from_euler("ZYX", np.c_[yaw, pitch, roll]).as_matrix()
    pos = np.cumsum(R[:, :, 0] * speed * period, axis=0)
    return np.array([pose(r, p) for r, p in zip(R, pos, strict=True)])


def sensor_poses(gt, R_gt_sensor=MOUNT):
    """The sensor's poses on the GT's drive: P_k = G_k T, T = (R_gt_sensor, no lever arm)."""
    return gt @ pose(R_gt_sensor, np.zeros(3))


def test_segment_vectors_are_the_mount_turned_odometry_vectors():
    gt = drive(60)
    v = segment_vectors(gt, sensor_poses(gt), step=10)
    np.testing.assert_allclose(v.gt, v.odometry @ MOUNT.T, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(v.odometry, axis=1), 1.0, atol=1e-12)
    moves = ~v.turn
    # every segment moves 10 m: one displacement per start 0..49
    np.testing.assert_array_equal(v.start[moves], np.arange(50))
    np.testing.assert_array_equal(v.weight[moves], 1.0)
    # a turn's weight is its angle / 10 deg, at most 1
    for k, w in zip(v.start[v.turn], v.weight[v.turn], strict=True):
        A = np.linalg.inv(gt[k]) @ gt[k + 10]
        angle = np.degrees(Rotation.from_matrix(A[:3, :3]).magnitude())
        assert angle >= 2.0 and w == pytest.approx(min(angle / 10.0, 1.0))
        R_A = Rotation.from_matrix(A[:3, :3]).as_rotvec()
        row = (v.start == k) & v.turn
        np.testing.assert_allclose(v.gt[row][0], R_A / np.linalg.norm(R_A), atol=1e-9)


def test_segment_thresholds_at_their_bounds():
    """A straight drive at 1 m per segment: displacements kept at min_move_m = 1.0, none at
    1.0 + 1e-9; no turn at all. A steady turn of 2 deg (+1e-7) per segment is kept at
    min_turn_deg 2, not at 2 + 1e-6."""
    n = 5
    straight = np.array([pose(np.eye(3), [k * 1.0, 0, 0]) for k in range(n)])
    v = segment_vectors(straight, straight, step=1)
    assert len(v.start) == n - 1 and not v.turn.any()
    np.testing.assert_array_equal(v.start, np.arange(n - 1))
    assert len(segment_vectors(straight, straight, 1, min_move_m=1.0 + 1e-9).start) == 0
    turning = np.array([pose(Rotation.from_euler("z", (2.0 + 1e-7) * k,
                                                       degrees=True).as_matrix(),
                             [0.0, 0.0, 0.0]) for k in range(n)])
    v = segment_vectors(turning, turning, step=1)
    assert v.turn.all() and len(v.start) == n - 1
    np.testing.assert_allclose(v.weight, 0.2)
    np.testing.assert_allclose(v.gt, np.tile([0, 0, 1.0], (n - 1, 1)), atol=1e-12)
    assert len(segment_vectors(turning, turning, 1, min_turn_deg=2.0 + 1e-6).start) == 0
    # step 2: segments k -> k + 2, starts 0 .. n - 3
    v = segment_vectors(straight, straight, step=2)
    np.testing.assert_array_equal(v.start, np.arange(n - 2))
    np.testing.assert_allclose(v.odometry, np.tile([1.0, 0, 0], (n - 2, 1)))


def test_hand_eye_recovers_the_mount_on_a_noise_free_drive():
    """Turns about the near-vertical spread around x and y (roll, pitch from the turn axes);
    yaw from the displacement directions. Recovered to 1e-6 deg, like scipy's
    align_vectors of all the segment vectors; intervals hold the truth."""
    gt = drive(300)
    res = hand_eye_rotation(gt, sensor_poses(gt), 0.1, odometry="odo", bootstrap=20)
    truth = {"roll": 1.0, "pitch": 2.0, "yaw": -1.5}
    for ax, deg in truth.items():
        assert res.angles_deg[ax] == pytest.approx(deg, abs=1e-6)
        lo, hi = res.interval_deg[ax]
        assert lo - 1e-9 <= deg <= hi + 1e-9
    v = segment_vectors(gt, sensor_poses(gt), 10)
    ref, _ = Rotation.align_vectors(v.gt, v.odometry)
    np.testing.assert_allclose(res.R_gt_sensor, ref.as_matrix(), atol=1e-9)
    assert res.source == {"roll": TURN_AXES, "pitch": TURN_AXES, "yaw": DISPLACEMENTS}
    assert res.observable == {"roll": True, "pitch": True, "yaw": True}
    assert res.odometry == "odo" and res.segments == len(v.start)
    assert res.frames_total == 300 and res.level == 0.95 and res.resamples == 20
    # blocks of at least HE_BLOCK_S (10 s = 100 frames at 10 Hz)
    assert HE_BLOCK_S == 10.0
    assert res.block.frames >= 100 and res.block.wanted >= 100
    assert all(isinstance(x, float) for x in res.angles_deg.values())


def test_a_shorter_block_and_level_are_passed_on():
    gt = drive(300)
    res = hand_eye_rotation(gt, sensor_poses(gt), 0.1, bootstrap=10, block_s=2.0, level=0.8)
    assert res.level == 0.8 and res.resamples == 10
    # the floor: max(one segment + 1 = 11, 2 s = 20 frames); noise-free residuals add little
    assert 20 <= res.block.frames < 100


def test_without_turns_the_displacements_fix_what_they_spread_around():
    """A straight drive along x that never turns: no turn axes; the displacements spread
    around y and z (pitch and yaw) but not around x: roll not observable. Pitch and yaw are
    recovered to second order (the fit holds the x axis of its own rotation vector, not the
    Euler roll, at 0: 1 deg x 1.5 deg ~ 0.03 deg)."""
    n, period = 100, 0.1
    gt = np.array([pose(np.eye(3), [k * 1.0, 0.0, 0.0]) for k in range(n)])
    res = hand_eye_rotation(gt, sensor_poses(gt), period, bootstrap=5)
    assert res.source == {"roll": "not observable", "pitch": DISPLACEMENTS, "yaw": DISPLACEMENTS}
    assert res.observable == {"roll": False, "pitch": True, "yaw": True}
    assert res.angles_deg["pitch"] == pytest.approx(2.0, abs=0.05)
    assert res.angles_deg["yaw"] == pytest.approx(-1.5, abs=0.05)
    # the direction of travel itself is matched exactly
    np.testing.assert_allclose(res.R_gt_sensor @ MOUNT.T @ [1.0, 0, 0], [1.0, 0, 0],
                               atol=1e-9)


def test_too_few_segments_is_an_error_naming_them():
    gt = np.array([pose(np.eye(3), [k * 0.05, 0, 0]) for k in range(30)])
    with pytest.raises(DataError, match=r"hand-eye alignment: only 0 usable segments of 1.0 s "
                                        r"\(the sensor must move at least 1 m per segment\)"):
        hand_eye_rotation(gt, gt, 0.1)


def test_hand_eye_on_runs_the_odometry_and_aligns_it(monkeypatch):
    """The odometry named is made with the sequence's sensor and run (seeded); its poses are
    aligned to the GT at the result's stamps; a sequence without GT is refused."""
    import methods.base
    import methods.registry
    from loaders.trajectory import Trajectory

    gt = drive(300)
    stamps = np.arange(300) * 0.1
    made = {}

    def make_method(name, params, sensor):
        made["method"] = (name, params, sensor)
        return "the method"

    def run_timed(method, sequence, seed):
        made["run"] = (method, sequence, seed)
        return SimpleNamespace(stamps=stamps, poses=sensor_poses(gt))

    monkeypatch.setattr(methods.registry, "make_method", make_method)
    monkeypatch.setattr(methods.base, "run_timed", run_timed)
    sensor = SimpleNamespace(period_s=0.1)
    seq = SimpleNamespace(name="seq", ground_truth=Trajectory(stamps, gt), sensor=sensor)
    res = hand_eye_on(seq, "geo", bootstrap=5)
    assert made["method"] == ("geo", {}, sensor) and made["run"] == ("the method", seq, True)
    assert res.odometry == "geo" and res.resamples == 5
    assert res.angles_deg["pitch"] == pytest.approx(2.0, abs=1e-6)
    with pytest.raises(DataError, match="seq: hand-eye alignment needs ground truth"):
        hand_eye_on(SimpleNamespace(name="seq", ground_truth=None, sensor=sensor))
    assert he_mod.HE_BLOCK_S == 10.0


# ---------------------------------------------------------------- rules, one at a time


def test_spread_is_the_weighted_rms_sine_to_each_axis():
    """z and x with weights 3 and 1: around x the sines are 1 and 0, around y 1 and 1,
    around z 0 and 1 -> sqrt(3/4), 1, sqrt(1/4); no vectors: 0."""
    v = np.array([[0, 0, 1.0], [1.0, 0, 0]])
    np.testing.assert_allclose(he_mod._spread(v, np.array([3.0, 1.0])),
                               [np.sqrt(0.75), 1.0, 0.5], rtol=1e-12)
    tilted = np.array([[np.sqrt(0.5), 0, np.sqrt(0.5)]])
    np.testing.assert_allclose(he_mod._spread(tilted, np.ones(1)),
                               [np.sqrt(0.5), 1.0, np.sqrt(0.5)], rtol=1e-12)
    np.testing.assert_array_equal(he_mod._spread(np.empty((0, 3)), np.empty(0)), np.zeros(3))


def test_weighted_fit_agrees_with_scipy_weighted_alignment():
    """All axes free: the rotation minimising sum w |b - R a|^2 (scipy's align_vectors with
    weights), on noisy pairs whose weights matter."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(40, 3))
    a /= np.linalg.norm(a, axis=1)[:, None]
    b = a @ MOUNT.T + rng.normal(scale=0.05, size=(40, 3))
    w = rng.uniform(0.05, 1.0, 40)
    ref, _ = Rotation.align_vectors(b, a, weights=w)
    R = he_mod._weighted_fit(a, b, w, np.ones(3, bool))
    np.testing.assert_allclose(R, ref.as_matrix(), atol=1e-8)
    plain, _ = Rotation.align_vectors(b, a)
    assert not np.allclose(R, plain.as_matrix(), atol=1e-6)  # the weights mattered


def test_a_segment_counts_only_when_both_trajectories_move_enough():
    """The odometry at half the GT's scale: GT segments of 1.5 m, odometry 0.75 m: none."""
    gt = np.array([pose(np.eye(3), [k * 1.5, 0, 0]) for k in range(5)])
    half = np.array([pose(np.eye(3), [k * 0.75, 0, 0]) for k in range(5)])
    assert len(segment_vectors(gt, half, 1).start) == 0
    assert len(segment_vectors(half, gt, 1).start) == 0


def test_defaults_kiss_icp_200_resamples_and_the_segment_step():
    """Defaults: odometry "kiss-icp", 200 resamples; one segment per frame when the segment
    is one period long; exactly 5 segments are enough, 4 are not (an error saying to use more
    frames)."""
    gt = np.array([pose(np.eye(3), [k * 2.0, 0.0, 0.0]) for k in range(6)])
    res = hand_eye_rotation(gt, sensor_poses(gt), 1.0)
    assert res.odometry == "kiss-icp" and res.resamples == 200 and res.segments == 5
    with pytest.raises(DataError, match=r"only 4 usable segments of 1.0 s .*; use more frames$"):
        hand_eye_rotation(gt[:5], sensor_poses(gt[:5]), 1.0)


def turns(count):
    """One segment per frame, 2 m apart; the heading turns by 5 deg on ``count`` segments
    (starting at frame 3), 13 + count - 3 frames."""
    yaw = np.cumsum([0.0] * 4 + [5.0] * count + [0.0] * 6)
    R = Rotation.from_euler("z", yaw[:, None], degrees=True).as_matrix()
    pos = np.cumsum(R[:, :, 0] * 2.0, axis=0)
    return np.array([pose(r, p) for r, p in zip(R, pos, strict=True)])


def test_a_resample_is_fitted_only_with_three_turns_and_three_displacements():
    """Three turns in 13 frames, blocks of half the frames: a resample draws each segment as
    often as its start frame; those with fewer than 3 turn rows are left out (counted here
    from the same draws, metrics.intervals.block_indices)."""
    from metrics.intervals import block_indices

    gt = turns(3)
    res = hand_eye_rotation(gt, sensor_poses(gt), 1.0, bootstrap=60)
    v = segment_vectors(gt, sensor_poses(gt), 1)
    counts = []
    for idx in block_indices(len(gt), res.block.frames, 60, 0):
        drawn = np.bincount(idx, minlength=len(gt))[v.start]
        counts.append((drawn[v.turn].sum(), drawn[~v.turn].sum()))
    counts = np.array(counts)
    assert (counts[:, 0] == 3).any() and (counts[:, 0] < 3).any()  # both sides of the bound
    assert res.resamples == int(((counts[:, 0] >= 3) & (counts[:, 1] >= 3)).sum())


def test_a_resample_needs_three_displacement_rows_too():
    """Three 2 m moves (frames 0-3), then nine 5 deg turns in place: the displacement rows
    (yaw) are the scarce ones; resamples with fewer than 3 of them are left out, those with
    exactly 3 kept (counted from the same draws)."""
    from metrics.intervals import block_indices

    yaw = np.r_[np.zeros(4), 5.0 * np.arange(1, 10)]
    R = Rotation.from_euler("z", yaw[:, None], degrees=True).as_matrix()
    pos = np.r_[np.c_[2.0 * np.arange(4), np.zeros((4, 2))], np.tile([6.0, 0, 0], (9, 1))]
    gt = np.array([pose(r, p) for r, p in zip(R, pos, strict=True)])
    res = hand_eye_rotation(gt, sensor_poses(gt), 1.0, bootstrap=60)
    assert res.source == {"roll": TURN_AXES, "pitch": TURN_AXES, "yaw": DISPLACEMENTS}
    v = segment_vectors(gt, sensor_poses(gt), 1)
    assert (~v.turn).sum() == 3 and v.turn.sum() == 9
    counts = []
    for idx in block_indices(len(gt), res.block.frames, 60, 0):
        drawn = np.bincount(idx, minlength=len(gt))[v.start]
        counts.append((drawn[v.turn].sum(), drawn[~v.turn].sum()))
    counts = np.array(counts)
    assert (counts[:, 1] == 3).any() and (counts[:, 1] < 3).any()
    assert res.resamples == int(((counts[:, 0] >= 3) & (counts[:, 1] >= 3)).sum())


def test_exactly_three_turns_are_trusted():
    """The heading turns by 5 deg on exactly three segments: their axes (vertical) fix roll
    and pitch; with two turns, they do not."""

    gt = turns(3)
    assert segment_vectors(gt, sensor_poses(gt), 1).turn.sum() == 3
    res = hand_eye_rotation(gt, sensor_poses(gt), 1.0, bootstrap=5)
    assert res.source["roll"] == TURN_AXES and res.source["pitch"] == TURN_AXES
    gt = turns(2)
    res = hand_eye_rotation(gt, sensor_poses(gt), 1.0, bootstrap=5)
    assert TURN_AXES not in res.source.values()


def test_spread_thresholds_are_at_least():
    """An angle is fitted from a cue spreading around it by at least the threshold: exactly
    the drive's own spread passes, a hair more does not."""
    gt = drive(300)
    v = segment_vectors(gt, sensor_poses(gt), 10)
    turn = he_mod._spread(v.odometry[v.turn], v.weight[v.turn])
    moves = he_mod._spread(v.odometry[~v.turn], v.weight[~v.turn])
    res = hand_eye_rotation(gt, sensor_poses(gt), 0.1, bootstrap=3, min_turn_spread=turn[0],
                            min_spread=moves[2])
    assert res.source["roll"] == TURN_AXES and res.source["yaw"] == DISPLACEMENTS
    res = hand_eye_rotation(gt, sensor_poses(gt), 0.1, bootstrap=3,
                            min_turn_spread=turn[0] + 1e-9, min_spread=moves[2] + 1e-9)
    assert res.source["roll"] != TURN_AXES and res.source["yaw"] == "not observable"


def test_the_turn_spread_is_weighted_by_the_turns():
    """A body that pitches and rolls (turn axes off the vertical by varying amounts, turns of
    varying size): yaw is fitted from the turn axes exactly when their turn-weighted spread
    around z reaches the threshold."""
    gt = drive(300, tilt=0.05)
    v = segment_vectors(gt, sensor_poses(gt), 10)
    weighted = he_mod._spread(v.odometry[v.turn], v.weight[v.turn])[2]
    plain = he_mod._spread(v.odometry[v.turn], np.ones(v.turn.sum()))[2]
    assert abs(weighted - plain) > 1e-6  # the weights matter on this drive
    res = hand_eye_rotation(gt, sensor_poses(gt), 0.1, bootstrap=3, min_turn_spread=weighted)
    assert res.source["yaw"] == TURN_AXES
    res = hand_eye_rotation(gt, sensor_poses(gt), 0.1, bootstrap=3,
                            min_turn_spread=weighted + 1e-9)
    assert res.source["yaw"] != TURN_AXES


def test_the_block_floor_is_the_asked_seconds_and_one_segment():
    """At 10 Hz: 10 s is 100 frames exactly (not 101); 0.1 s is less than a segment (10
    frames) plus one: 11. The residuals (noise-free) may ask for more, by their own rule."""
    gt = drive(300)
    for block_s, floor in ((10.0, 100), (0.1, 11)):
        res = hand_eye_rotation(gt, sensor_poses(gt), 0.1, bootstrap=3, block_s=block_s)
        wanted = max([floor, *(2 * c for c in res.block.correlation)])
        assert res.block.wanted == wanted
        assert len(res.block.correlation) == 3  # roll, pitch from turns; yaw from displacements


def _noisy(gt, seed, sd_deg=0.3):
    """The sensor's poses with a per-frame attitude error (white, sd_deg per axis)."""
    rng = np.random.default_rng(seed)
    noise = Rotation.from_rotvec(np.radians(rng.normal(scale=sd_deg, size=(len(gt), 3))))
    out = sensor_poses(gt).copy()
    out[:, :3, :3] = out[:, :3, :3] @ noise.as_matrix()
    return out


def test_noisy_odometry_gets_a_bootstrap_spread_at_the_asked_level():
    """Per-frame attitude noise: the resamples differ (sd > 0); the interval at level 0.8 is
    t(0.9) / t(0.975) of the 95 % one (same block, same resamples); the block's correlation
    lengths are those of the residuals of each fitted angle in frame order."""
    from scipy.stats import t as student_t

    from bench.data.calibration.bootstrap import residual_series
    from metrics.intervals import correlation_length

    gt = drive(300)
    est = _noisy(gt, 1)
    a = hand_eye_rotation(gt, est, 0.1, bootstrap=30, block_s=2.0)
    b = hand_eye_rotation(gt, est, 0.1, bootstrap=30, block_s=2.0, level=0.8)
    assert all(s > 1e-4 for s in a.std_deg.values())
    assert a.std_deg == b.std_deg and a.block == b.block
    dof = a.block.dof(300)
    for ax in ("roll", "pitch", "yaw"):
        half_a = 0.5 * (a.interval_deg[ax][1] - a.interval_deg[ax][0])
        half_b = 0.5 * (b.interval_deg[ax][1] - b.interval_deg[ax][0])
        assert half_b / half_a == pytest.approx(student_t.ppf(0.9, dof)
                                                / student_t.ppf(0.975, dof), rel=1e-9)
    v = segment_vectors(gt, est, 10)
    R, t = a.R_gt_sensor, v.turn
    series = residual_series(v.odometry[t] @ R.T, v.gt[t], np.array([True, True, False]),
                             v.start[t])
    series += residual_series(v.odometry[~t] @ R.T, v.gt[~t], np.array([False, False, True]),
                              v.start[~t])
    assert a.block.correlation == tuple(int(correlation_length(s)) for s in series)


def test_hand_eye_on_defaults_to_kiss_icp(monkeypatch):
    import methods.base
    import methods.registry
    from loaders.trajectory import Trajectory

    gt = drive(200)
    stamps = np.arange(200) * 0.1
    made = []
    monkeypatch.setattr(methods.registry, "make_method",
                        lambda name, params, sensor: made.append(name))
    monkeypatch.setattr(methods.base, "run_timed", lambda m, s, seed: SimpleNamespace(
        stamps=stamps, poses=sensor_poses(gt)))
    seq = SimpleNamespace(name="s", ground_truth=Trajectory(stamps, gt),
                          sensor=SimpleNamespace(period_s=0.1))
    assert hand_eye_on(seq, bootstrap=3).odometry == "kiss-icp" and made == ["kiss-icp"]
