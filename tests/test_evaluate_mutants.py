"""bench.runs.evaluate: what the mutation run (``tools/mutate.py``) found untested.

``score`` puts the metrics of ``metrics/`` into ``metrics.json``'s fields; each field is checked
against the metric function called directly on the scored frames (``metrics.ape``,
``metrics.relative_errors``, ``metrics.kitti_drift``, ``metrics.velocity``) and the timing
against NumPy, on a drive whose ground truth and drifting estimate are made here."""

from __future__ import annotations

import numpy as np
import pytest

from bench.runs.evaluate import (
    Scoring,
    evaluate_run,
    fallbacks,
    relative_part,
    score,
    timing_part,
)
from loaders.errors import DataError
from loaders.se3 import exp_se3
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult
from metrics import ape, kitti_drift, relative_errors
from metrics.kitti import KITTI_LENGTHS_M
from metrics.relative import DEFAULT_LENGTHS_M, relative_segments, stats_from_segments
from metrics.velocity import own_velocity_errors, velocity_errors

DT = 0.1
N = 260  # 10 m/s for 26 s: 259 m, room for the 100 m and 200 m KITTI lengths


def _drive(n: int = N, speed: float = 10.0, yaw_rate: float = 0.02, stretch: float = 1.0,
           yaw_bias: float = 0.0) -> np.ndarray:
    """Poses of a constant-twist drive (T_world_sensor, (n, 4, 4)); ``stretch`` scales the
    distance per step and ``yaw_bias`` adds to the turn rate (an estimate that drifts)."""
    step = exp_se3(np.array([speed * stretch * DT, 0.0, 0.0, 0.0, 0.0,
                             (yaw_rate + yaw_bias) * DT]))
    poses = [np.eye(4)]
    for _ in range(n - 1):
        poses.append(poses[-1] @ step)
    return np.array(poses)


@pytest.fixture(scope="module")
def drive():
    stamps = np.arange(N) * DT
    return stamps, _drive(), _drive(stretch=1.02, yaw_bias=0.003)


def _close(value, expected):
    if expected is None or not np.isfinite(expected):
        assert value is None
    else:
        np.testing.assert_allclose(value, expected, rtol=1e-9, atol=1e-12)


def _inside(ci, value):
    assert ci is not None and len(ci) == 2
    assert ci[0] <= value <= ci[1]


# ---- score: every part against the metric called directly ----------------------------------

@pytest.fixture
def scored(drive):
    """Function-scoped: each test calls ``score`` itself (a cached fixture would hide from
    ``make mutate`` which tests reach it)."""
    stamps, gt, est = drive
    own = np.tile([10.2, 0.1, 0.0], (N, 1))
    times = np.linspace(1.0, 5.0, N)
    return score(gt, est, times, lengths_m=(10.0, 50.0), stamps=stamps, velocity_mps=own,
                 name="drive.h5")


def test_the_relative_errors_are_those_of_metrics_relative(drive, scored):
    _, gt, est = drive
    expected = relative_errors(gt, est, (10.0, 50.0))
    assert [r["length_m"] for r in scored["relative_error"]] == [10.0, 50.0]
    for row in scored["relative_error"]:
        s = expected[row["length_m"]]
        for field in ("rot_deg_mean", "rot_deg_median", "rot_deg_rmse", "trans_m_mean",
                      "trans_m_median", "trans_m_rmse"):
            _close(row[field], getattr(s, field))
        assert row["n"] == s.n > 0
        _inside(row["trans_m_mean_ci"], row["trans_m_mean"])
        _inside(row["rot_deg_mean_ci"], row["rot_deg_mean"])
    assert scored["diverged"] is False and scored["frames_scored"] == N


def test_the_ape_is_that_of_metrics_ape_with_its_intervals(drive, scored):
    _, gt, est = drive
    a = ape(gt, est, "se3")
    part = scored["ape"]
    assert part["requested"] == "se3" and part["alignment"] == a.alignment == "se3"
    for field in ("trans_rmse_m", "trans_mean_m", "trans_median_m", "trans_max_m",
                  "rot_rmse_deg", "rot_mean_deg", "scale"):
        _close(part[field], getattr(a, field))
    assert part["trans_rmse_m"] > 0.1
    _inside(part["trans_rmse_m_ci"], part["trans_rmse_m"])
    _inside(part["rot_rmse_deg_ci"], part["rot_rmse_deg"])


def test_the_kitti_drift_is_that_of_metrics_kitti(drive, scored):
    _, gt, est = drive
    k = kitti_drift(gt, est, KITTI_LENGTHS_M, 10)
    part = scored["kitti"]
    assert part["lengths_m"] == [float(x) for x in KITTI_LENGTHS_M]
    assert part["step_frames"] == 10
    _close(part["trans_pct"], k.trans_pct)
    _close(part["rot_deg_per_100m"], k.rot_deg_per_100m)
    assert part["n"] == k.n > 0
    assert part["too_long"] == list(k.too_long) == [float(x) for x in KITTI_LENGTHS_M[2:]]
    assert [p["length_m"] for p in part["per_length"]] == list(k.per_length)
    for p, (t, r, n) in zip(part["per_length"], k.per_length.values(), strict=True):
        _close(p["trans_pct"], t)
        _close(p["rot_deg_per_100m"], r)
        assert p["n"] == n
    _inside(part["trans_pct_ci"], part["trans_pct"])
    _inside(part["rot_deg_per_100m_ci"], part["rot_deg_per_100m"])


def test_an_estimate_two_percent_too_long_drifts_two_percent(drive):
    """The estimate is the drive scaled by 1.02 about its start (same headings): over a
    segment the translation error is 2 % of its chord, which on this gentle curve (0.02 rad/s,
    at most 0.4 rad over 200 m) is within 0.7 % of its length; no rotation error."""
    stamps, gt, _ = drive
    part = score(gt, _drive(stretch=1.02), np.ones(N), lengths_m=(10.0,))["kitti"]
    assert part["trans_pct"] == pytest.approx(2.0, abs=0.02)
    assert part["rot_deg_per_100m"] == pytest.approx(0.0, abs=1e-6)


def _check_velocity(part, stats, source):
    assert part["source"] == source and part["window_s"] == stats.window_s == 1.0
    for got, want in zip(part["axis_mean_mps"], stats.axis_mean_mps, strict=True):
        _close(got, want)
    for got, want in zip(part["axis_rmse_mps"], stats.axis_rmse_mps, strict=True):
        _close(got, want)
    _close(part["norm_mean_mps"], stats.norm_mean_mps)
    _close(part["norm_rmse_mps"], stats.norm_rmse_mps)
    assert part["n"] == stats.n > 0
    _inside(part["norm_mean_mps_ci"], part["norm_mean_mps"])


def test_the_velocity_errors_are_those_of_metrics_velocity(drive, scored):
    stamps, gt, est = drive
    _check_velocity(scored["velocity"], velocity_errors(gt, est, stamps, 1.0), "trajectory")
    # 10 m/s driven, 10.2 m/s forward and 0.1 m/s sideways reported
    assert scored["velocity"]["norm_mean_mps"] == pytest.approx(0.2, abs=0.05)
    own = np.tile([10.2, 0.1, 0.0], (N, 1))
    _check_velocity(scored["velocity_own"], own_velocity_errors(gt, stamps, own, 1.0),
                    "doppler")
    assert scored["velocity_own"]["norm_mean_mps"] == pytest.approx(np.hypot(0.2, 0.1),
                                                                    rel=0.05)


def test_the_time_is_the_median_mean_and_95th_percentile():
    times = np.array([np.nan, 4.0, 1.0, 3.0, 2.0, 100.0])
    valid = times[1:]
    assert timing_part(times) == pytest.approx({
        "median": np.median(valid), "mean": np.mean(valid), "p95": np.percentile(valid, 95)})
    assert timing_part(np.full(3, np.nan)) == {"median": None, "mean": None, "p95": None}


def test_score_times_its_frames_unless_timings_are_given(drive, scored):
    _, gt, est = drive
    times = np.linspace(1.0, 5.0, N)
    assert scored["time_ms"] == pytest.approx({
        "median": 3.0, "mean": 3.0, "p95": np.percentile(times, 95)})
    given = {"time_ms": {"median": 7.0}, "wall_ms": {"median": 8.0}}
    out = score(gt[:40], est[:40], times[:40], lengths_m=(10.0,), timings=given)
    assert out["time_ms"] == {"median": 7.0} and out["wall_ms"] == {"median": 8.0}


# ---- which frames and which settings --------------------------------------------------------

def test_only_the_scored_frames_count(drive):
    stamps, gt, est = drive
    scored = np.ones(N, dtype=bool)
    scored[100:130] = False
    gt_holes = gt.copy()
    gt_holes[~scored] = np.nan  # what gt_for_frames gives for a frame without GT
    out = score(gt_holes, est, np.ones(N), lengths_m=(10.0,), scored=scored, stamps=stamps)
    keep = np.flatnonzero(scored)
    assert out["frames_scored"] == N - 30
    rel = relative_errors(gt[keep], est[keep], (10.0,))[10.0]
    _close(out["relative_error"][0]["trans_m_mean"], rel.trans_m_mean)
    assert out["relative_error"][0]["n"] == rel.n
    _close(out["ape"]["trans_rmse_m"], ape(gt[keep], est[keep]).trans_rmse_m)
    _close(out["velocity"]["norm_mean_mps"],
           velocity_errors(gt[keep], est[keep], stamps[keep], 1.0).norm_mean_mps)


def test_the_scoring_settings_are_used(drive):
    stamps, gt, est = drive
    scoring = Scoring(lengths_m=(20,), kitti_lengths_m=(100,), alignment="SIM3",
                      velocity_window_s=2.0)
    assert scoring == Scoring((20.0,), (100.0,), "sim3", 2.0)
    assert isinstance(scoring.lengths_m[0], float)
    assert isinstance(scoring.kitti_lengths_m[0], float)
    out = score(gt, est, np.ones(N), scoring=scoring, stamps=stamps)
    assert [r["length_m"] for r in out["relative_error"]] == [20.0]
    a = ape(gt, est, "sim3")
    assert out["ape"]["requested"] == out["ape"]["alignment"] == "sim3"
    _close(out["ape"]["scale"], a.scale)
    assert out["ape"]["scale"] == pytest.approx(1 / 1.02, rel=0.01)
    assert out["kitti"]["lengths_m"] == [100.0] and out["kitti"]["too_long"] == []
    assert out["velocity"]["window_s"] == 2.0
    _close(out["velocity"]["norm_mean_mps"],
           velocity_errors(gt, est, stamps, 2.0).norm_mean_mps)


def test_the_default_scoring_takes_the_lengths_given(drive):
    _, gt, est = drive
    out = score(gt, est, np.ones(N), lengths_m=[25, 75])
    assert [r["length_m"] for r in out["relative_error"]] == [25.0, 75.0]
    assert out["ape"]["requested"] == "se3" and "velocity" not in out
    assert [r["length_m"] for r in score(gt, est, np.ones(N))["relative_error"]] == [
        float(x) for x in DEFAULT_LENGTHS_M]


def test_a_non_finite_estimate_diverges_and_has_no_ape(drive):
    stamps, gt, est = drive
    bad = est.copy()
    bad[150, 0, 3] = np.inf
    out = score(gt, bad, np.ones(N), lengths_m=(10.0,), stamps=stamps)
    assert out["diverged"] is True
    assert out["ape"]["requested"] == "se3" and out["ape"]["scale"] is None
    assert out["ape"]["alignment"] is None and out["ape"]["trans_rmse_m"] is None


def test_one_scored_frame_has_no_ape_and_no_velocity(drive):
    stamps, gt, est = drive
    one = np.zeros(N, dtype=bool)
    one[5] = True
    with pytest.raises(DataError, match=r"^drive\.h5: .*\(1 frames with ground truth\)"):
        score(gt, est, np.ones(N), lengths_m=(10.0,), scored=one, name="drive.h5")


def test_no_scored_frame_is_an_error_naming_the_sequence(drive):
    _, gt, est = drive
    with pytest.raises(DataError, match=r"^drive\.h5: no frame has ground truth"):
        score(gt, est, np.ones(N), scored=np.zeros(N, dtype=bool), name="drive.h5")
    with pytest.raises(DataError, match=r"^ground truth: no frame has ground truth"):
        score(gt, est, np.ones(N), scored=np.zeros(N, dtype=bool))


def test_two_scored_frames_have_an_ape_and_a_velocity(drive):
    stamps, gt, est = drive
    two = np.zeros(N, dtype=bool)
    two[[0, 30]] = True
    out = score(gt, est, np.ones(N), lengths_m=(30.0,), scored=two, stamps=stamps,
                velocity_mps=np.tile([10.0, 0.0, 0.0], (N, 1)))
    assert out["frames_scored"] == 2
    _close(out["ape"]["trans_rmse_m"], ape(gt[[0, 30]], est[[0, 30]]).trans_rmse_m)
    assert out["velocity"]["n"] == 1 and out["velocity_own"]["source"] == "doppler"


def test_relative_part_summarises_the_segments_given_or_computes_them(drive):
    _, gt, est = drive
    segments = relative_segments(gt, est, (10.0, 50.0))
    rel = {length: stats_from_segments(seg) for length, seg in segments.items()}
    given = relative_part(gt, est, rel, segments)
    computed = relative_part(gt, est, rel)
    partial = relative_part(gt, est, rel, {10.0: segments[10.0]})
    assert given == computed == partial
    assert [r.length_m for r in given] == [10.0, 50.0]
    assert all(r.trans_m_mean_ci is not None and r.rot_deg_mean_ci is not None for r in given)


# ---- fallbacks and evaluate_run -------------------------------------------------------------

def _frame(i, converged=True, replaced=False, time_ms=1.0, register_ms=0.5, wall_ms=2.0):
    return FrameRecord(i, i * DT, time_ms, 100, 50, 3, converged, register_ms=register_ms,
                       wall_ms=wall_ms, replaced=replaced)


def test_fallbacks_count_the_replaced_and_the_unconverged_registered_frames():
    frames = [_frame(0, converged=False, replaced=True),  # the first frame: not registered
              _frame(1, converged=False), _frame(2, converged=False),
              _frame(3, converged=False, replaced=True), _frame(4, replaced=True), _frame(5)]
    result = OdometryResult(np.arange(6) * DT, np.tile(np.eye(4), (6, 1, 1)), frames)
    assert fallbacks(result) == {"frames_replaced": 2, "frames_unconverged": 2}


def test_frames_of_a_record_without_a_replaced_flag_count_as_not_replaced():
    from types import SimpleNamespace

    frames = [SimpleNamespace(converged=c) for c in (False, True, False, False)]
    result = SimpleNamespace(frames=frames)
    assert fallbacks(result) == {"frames_replaced": 0, "frames_unconverged": 2}


def _result(poses, stamps, velocity=None):
    frames = [_frame(i, time_ms=1.0 + i, register_ms=0.5 * i, wall_ms=3.0 * i,
                     converged=i % 7 != 3) for i in range(len(stamps))]
    return OdometryResult(stamps, poses, frames, velocity)


def test_evaluate_run_times_every_frame_and_scores_those_with_ground_truth(drive):
    stamps, gt, est = drive
    velocity = np.tile([10.0, 0.0, 0.0], (N, 1))
    result = _result(est, stamps, velocity)
    excluded = np.zeros(N, dtype=bool)
    excluded[:20] = True
    ev = evaluate_run(Trajectory(stamps, gt), result, (10.0,), name="drive.h5",
                      excluded=excluded)
    idx = np.arange(N)
    assert ev.metrics["time_ms"] == pytest.approx(timing_part(1.0 + idx))
    assert ev.metrics["register_ms"] == pytest.approx(timing_part(0.5 * idx))
    assert ev.metrics["wall_ms"] == pytest.approx(timing_part(3.0 * idx))
    unconverged = int(np.sum(idx[1:] % 7 == 3))
    assert ev.metrics["frames_unconverged"] == unconverged and ev.metrics["frames_replaced"] == 0
    assert ev.metrics["frames_scored"] == N - 20
    np.testing.assert_array_equal(ev.scored, ~excluded)
    np.testing.assert_allclose(ev.gt.stamps, stamps[20:])
    np.testing.assert_allclose(ev.gt.poses, gt[20:], atol=1e-12)
    _close(ev.metrics["ape"]["trans_rmse_m"], ape(gt[20:], est[20:]).trans_rmse_m)
    assert ev.metrics["velocity_own"]["norm_mean_mps"] == pytest.approx(0.0, abs=0.02)
    assert [r["length_m"] for r in ev.metrics["relative_error"]] == [10.0]


def test_evaluate_run_takes_the_scoring_over_the_lengths(drive):
    stamps, gt, est = drive
    ev = evaluate_run(Trajectory(stamps, gt), _result(est, stamps), (10.0,),
                      scoring=Scoring((40.0,), alignment="origin", velocity_window_s=0.5))
    assert [r["length_m"] for r in ev.metrics["relative_error"]] == [40.0]
    assert ev.metrics["ape"]["requested"] == "origin"
    assert ev.metrics["velocity"]["window_s"] == 0.5 and "velocity_own" not in ev.metrics


def test_without_ground_truth_only_the_timing_is_filled_in(drive):
    stamps, _, est = drive
    ev = evaluate_run(None, _result(est, stamps))
    idx = np.arange(N)
    assert ev.gt is None and ev.scored.shape == (0,)
    assert set(ev.metrics) == {"diverged", "relative_error", "ape", "time_ms", "register_ms",
                               "wall_ms", "frames_replaced", "frames_unconverged",
                               "frames_scored"}
    assert ev.metrics["diverged"] is None and ev.metrics["ape"] is None
    assert ev.metrics["relative_error"] == [] and ev.metrics["frames_scored"] == 0
    assert ev.metrics["wall_ms"] == pytest.approx(timing_part(3.0 * idx))
