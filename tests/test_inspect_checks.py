"""`bench inspect` takes nothing on trust: the ground truth's clock is timed against the
Doppler speed (a GT 0.5 s late is found to within 0.03 s and the warning gives the
--time-offset that removes it), and the height advice names only an option the store's loader
has (campus: --elevation-sign; NTU4DRadLM has none)."""

import re

import numpy as np
import pytest

from bench.data.inspect_checks import clock_offset_lines, gt_clock_offset, height_advice
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import inv_T, make_T, transform_points
from loaders.trajectory import Trajectory
from methods.ego_velocity import speed_from_doppler


def _x(t):  # position along x [m] of a car whose speed is 8 + 3 sin(2 pi t / 4) m/s
    return 8 * t - 3 * 4 / (2 * np.pi) * np.cos(2 * np.pi * t / 4)


def _v(t):
    return 8 + 3 * np.sin(2 * np.pi * t / 4)


def accelerating(gt_late_s: float, speed_amplitude: float = 1.0, n: int = 220,
                 loader: str = "ntu4dradlm") -> MemorySequence:
    """Static points seen from a car that speeds up and slows down (exact Doppler); its ground
    truth stamped ``gt_late_s`` late (each GT pose shows the car that much earlier). 22 s: the
    lag's block bootstrap needs 5 blocks of 4 s."""
    rng = np.random.default_rng(1)
    world = np.column_stack([rng.uniform(-60, 160, 2500), rng.uniform(-40, 40, 2500),
                             rng.uniform(-2, 8, 2500)])
    stamps = np.arange(n) * 0.1
    scans = []
    for t in stamps:
        x = 8 * t + speed_amplitude * (_x(t) - 8 * t) / 3
        v = 8 + speed_amplitude * (_v(t) - 8) / 3
        p = transform_points(inv_T(make_T(np.eye(3), np.array([x, 0, 0]))), world)
        p = p[(np.linalg.norm(p, axis=1) > 1) & (np.linalg.norm(p, axis=1) < 70)]
        d = p / np.linalg.norm(p, axis=1, keepdims=True)
        scans.append(Scan(t, p, -d @ np.array([v, 0.0, 0.0])))
    tl = stamps - gt_late_s
    xs = 8 * tl + speed_amplitude * (_x(tl) - 8 * tl) / 3
    gt = Trajectory(stamps, np.array([make_T(np.eye(3), np.array([x, 0, 0])) for x in xs]))
    return MemorySequence("acc", SensorInfo("radar", 0.1), scans, gt, {"loader": loader})


@pytest.mark.parametrize("late", [0.5, -0.3, 0.0])
def test_the_gt_clock_lag_is_found_from_the_doppler_speed(late):
    seq = accelerating(late, speed_amplitude=3.0)
    s = speed_from_doppler(seq)
    est = gt_clock_offset(s["stamps"], s["speed_doppler"], s["observable"], seq.ground_truth)
    assert est.lag_s == pytest.approx(late, abs=0.03)
    assert est.correlation > 0.95 and est.spread_s < 0.05
    assert est.time_offset_s == pytest.approx(-late, abs=0.03)


def test_a_lag_above_one_period_is_a_warning_with_the_time_offset():
    seq = accelerating(0.5, speed_amplitude=3.0)
    (style, line), = clock_offset_lines(seq, speed_from_doppler(seq))
    assert style == "yellow" and line.startswith("warning:")
    assert re.search(r"lags the sensor by \+0\.(49|50|51)\d s", line)
    assert re.search(r"--time-offset -0\.(49|50|51)\d", line)
    seq = accelerating(0.0, speed_amplitude=3.0)
    (style, line), = clock_offset_lines(seq, speed_from_doppler(seq))
    assert style == "green" and "within one scan period" in line
    # a loader without a time-offset option: the advice names none
    seq = accelerating(0.5, speed_amplitude=3.0, loader="npy-frames")
    (_, line), = clock_offset_lines(seq, speed_from_doppler(seq))
    assert "--time-offset" not in line and "npy-frames takes no time-offset option" in line


def test_a_piece_too_short_for_an_interval_is_never_warned():
    """10 s (2.5 bootstrap blocks), the ground truth 0.5 s late: the lag is found but the data
    give no interval, so no warning: inconclusive."""
    seq = accelerating(0.5, speed_amplitude=3.0, n=100)
    (style, line), = clock_offset_lines(seq, speed_from_doppler(seq))
    assert not line.startswith("warning:") and "too few scans for an interval" in line
    assert "inconclusive" in line


def test_a_constant_speed_cannot_time_the_ground_truth():
    seq = accelerating(0.5, speed_amplitude=0.0)
    (style, line), = clock_offset_lines(seq, speed_from_doppler(seq))
    assert style == "dim" and "not estimated (the speed hardly changes" in line


def test_height_advice_names_only_an_existing_option():
    above = {"dominant_layer_z_m": 0.6, "verdict": "densest layer above the sensor (the "
             "elevation looks mirrored)"}
    below = {"dominant_layer_z_m": -0.6, "verdict": "road below the sensor (sign looks right)"}
    campus = MemorySequence("c", SensorInfo("radar", 0.1), [], None, {"loader": "campus"})
    ntu = MemorySequence("n", SensorInfo("radar", 0.1), [], None, {"loader": "ntu4dradlm"})
    assert "convert again with --elevation-sign -1 (bench convert campus)" in \
        height_advice(campus, above)
    text = height_advice(ntu, above)
    assert "elevation_sign" not in text and "--elevation-sign" not in text
    assert "ntu4dradlm takes no elevation-sign option" in text
    assert height_advice(ntu, below).endswith("(sign looks right)")


# -- the elevation (height) check looks at the near field ------------------------------------

SAMPLE = __import__("pathlib").Path(__file__).resolve().parents[1] / "samples" / \
    "ntu4dradlm-loop1.h5"


def _mirrored(seq, frames=50) -> MemorySequence:
    """The first ``frames`` scans with z negated: an elevation read with the wrong sign."""
    scans = []
    for i in range(min(frames, len(seq))):
        s = seq[i]
        scans.append(Scan(s.stamp, s.points * [1.0, 1.0, -1.0], s.doppler))
    return MemorySequence(f"{seq.name}-mirrored", seq.sensor, scans, None,
                          {"loader": "ntu4dradlm"})


def test_height_check_on_the_vendored_sample_and_on_it_mirrored():
    """The vendored NTU4DRadLM sample (real Eagle frames): the road lies 0.6-0.8 m below the
    radar; the same frames mirrored on purpose are flagged."""
    from bench.data.inspection import inspect_sequence
    from loaders.doppler_check import low_points_median_z
    from loaders.store import StoreSequence

    seq = StoreSequence(SAMPLE)
    z = low_points_median_z(seq)
    assert z["basis"] == "points within 30 m" and -0.9 < z["dominant_layer_z_m"] < -0.5
    assert z["verdict"] == "road below the sensor (sign looks right)"
    bad = low_points_median_z(_mirrored(seq))
    assert 0.5 < bad["dominant_layer_z_m"] < 0.9 and "looks mirrored" in bad["verdict"]
    rows = dict(inspect_sequence(_mirrored(seq, 20))["rows"])
    assert "points within 30 m): densest layer above the sensor" in rows["height check"]
    assert "ntu4dradlm takes no elevation-sign option" in rows["height check"]


def _road_and_far_canopy(sign: float = 1.0, frames: int = 5) -> MemorySequence:
    """Per scan: 300 road points at z = -0.5 m within 25 m, and 700 points of a layer at
    z = +2.1 m (trees, walls, roofs) 35-80 m away: the densest layer over all ranges is the far
    one, the road is the densest near the sensor."""
    rng = np.random.default_rng(4)
    scans = []
    for k in range(frames):
        r = np.concatenate([rng.uniform(3, 25, 300), rng.uniform(35, 80, 700)])
        a = rng.uniform(-1.0, 1.0, 1000)
        z = np.concatenate([rng.normal(-0.5, 0.03, 300), rng.normal(2.1, 0.03, 700)])
        p = np.column_stack([r * np.cos(a), r * np.sin(a), sign * z])
        scans.append(Scan(0.1 * k, p, np.zeros(len(p))))
    return MemorySequence("canopy", SensorInfo("radar", 0.1), scans, None,
                          {"loader": "campus"})


def test_a_dense_far_layer_above_the_sensor_is_no_false_alarm():
    from loaders.doppler_check import low_points_median_z

    z = low_points_median_z(_road_and_far_canopy())
    assert z["all_ranges_layer_z_m"] == pytest.approx(2.1, abs=0.15)  # the old false alarm
    assert z["dominant_layer_z_m"] == pytest.approx(-0.5, abs=0.15)
    assert z["verdict"] == "road below the sensor (sign looks right)"
    flipped = low_points_median_z(_road_and_far_canopy(sign=-1.0))
    assert flipped["dominant_layer_z_m"] == pytest.approx(0.5, abs=0.15)
    assert "looks mirrored" in flipped["verdict"]
    # with too few near points the check says it used all of them
    few = low_points_median_z(_road_and_far_canopy(), near_field_m=2.0)
    assert few["basis"].startswith("all points (only 0 within 2 m")
