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


def accelerating(gt_late_s: float, speed_amplitude: float = 1.0, n: int = 100,
                 loader: str = "ntu4dradlm") -> MemorySequence:
    """Static points seen from a car that speeds up and slows down (exact Doppler); its ground
    truth stamped ``gt_late_s`` late (each GT pose shows the car that much earlier)."""
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
