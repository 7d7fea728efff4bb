"""bench/studies/calibration_coverage.py, in-process: the rotated ground truth, the coverage
counts, rates and report lines (on stated results worked out by hand), and the study loop at
the smallest size."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from bench.studies import calibration_coverage as cc
from bench.studies.calibration_coverage import TRUTH_DEG, Coverage, rotated_gt


def _rx(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_default_truth_differs_in_every_angle():
    assert TRUTH_DEG == {"roll": 1.0, "pitch": 2.0, "yaw": -1.5}


def test_rotated_gt_applies_the_transpose_of_rz_ry_rx():
    base = SimpleNamespace(name="s", sensor=SimpleNamespace(
        kind="radar", period_s=0.1, T_body_sensor=np.eye(4), model="m", doppler_kind="radial"),
        ground_truth=None, provenance={})
    truth = {"roll": 3.0, "pitch": -5.0, "yaw": 7.0}
    R = _rz(7.0) @ _ry(-5.0) @ _rx(3.0)
    out = rotated_gt(base, truth)
    np.testing.assert_allclose(out.provenance["calibration"]["R_gt_sensor"], R.T, atol=1e-12)
    np.testing.assert_allclose(out.sensor.T_body_sensor[:3, :3], R.T, atol=1e-12)
    default = rotated_gt(base)
    R0 = _rz(-1.5) @ _ry(2.0) @ _rx(1.0)
    np.testing.assert_allclose(default.provenance["calibration"]["R_gt_sensor"], R0.T,
                               atol=1e-12)


def _cal(angles, lo_hi, std, frames=10, hidden=()):
    block = None if frames is None else SimpleNamespace(frames=frames)
    return SimpleNamespace(level=0.95, block=block, not_observable=set(hidden),
                           angles_deg=angles, interval_deg=lo_hi, std_deg=std)


TRUTH = {"roll": 1.0, "pitch": 2.0, "yaw": -1.5}


def _two_results():
    cov = Coverage(0.95, dict(TRUTH))
    # roll: interval edge exactly at the truth (covered); pitch: misses; yaw: not observable
    cov.add(_cal({"roll": 1.2, "pitch": 2.5, "yaw": 0.0},
                 {"roll": (1.0, 1.4), "pitch": (2.1, 2.9), "yaw": (-9, 9)},
                 {"roll": 0.1, "pitch": 0.2, "yaw": 5.0}, frames=12, hidden=("yaw",)))
    # roll: upper edge at the truth (covered); pitch covered; yaw covered
    cov.add(_cal({"roll": 0.8, "pitch": 1.9, "yaw": -1.4},
                 {"roll": (0.6, 1.0), "pitch": (1.7, 2.1), "yaw": (-1.6, -1.2)},
                 {"roll": 0.3, "pitch": 0.4, "yaw": 0.05}, frames=None))
    return cov


def test_add_counts_only_observable_angles_and_closed_intervals():
    cov = _two_results()
    assert cov.tried == {"roll": 2, "pitch": 2, "yaw": 1}
    assert cov.covered == {"roll": 2, "pitch": 1, "yaw": 1}
    np.testing.assert_allclose(cov.errors_deg["roll"], [0.2, -0.2], atol=1e-12)
    np.testing.assert_allclose(cov.errors_deg["pitch"], [0.5, -0.1], atol=1e-12)
    np.testing.assert_allclose(cov.errors_deg["yaw"], [0.1], atol=1e-12)
    assert cov.sd_deg == {"roll": [0.1, 0.3], "pitch": [0.2, 0.4], "yaw": [0.05]}
    assert cov.blocks == [12, 0]


def test_fresh_coverage_is_empty_per_angle():
    a, b = Coverage(0.9, dict(TRUTH)), Coverage(0.9, dict(TRUTH))
    assert a.tried == a.covered == {"roll": 0, "pitch": 0, "yaw": 0}
    assert a.errors_deg == a.sd_deg == {"roll": [], "pitch": [], "yaw": []}
    assert a.blocks == []
    a.errors_deg["roll"].append(1.0)
    assert b.errors_deg["roll"] == []  # not shared between instances


def test_rates():
    cov = _two_results()
    assert cov.rate("roll") == pytest.approx(1.0)
    assert cov.rate("pitch") == pytest.approx(0.5)
    assert cov.rate() == pytest.approx(4 / 5)
    assert math.isnan(Coverage(0.95, dict(TRUTH)).rate())
    assert math.isnan(Coverage(0.95, dict(TRUTH)).rate("yaw"))


def test_lines_report_counts_spread_errors_and_blocks():
    cov = _two_results()
    lines = cov.lines()
    # binomial sd 100 * sqrt(0.95 * 0.05 / n): n=2 -> 15.4 %, n=1 -> 21.8 %
    assert lines[0] == ("  roll  2/2 covered (100.0 %, binomial sd 15.4 %); error mean +0.000 "
                        "deg, rms 0.200; stated sd mean 0.200 deg")
    assert lines[1] == ("  pitch 1/2 covered (50.0 %, binomial sd 15.4 %); error mean +0.200 "
                        "deg, rms 0.361; stated sd mean 0.300 deg")
    assert lines[2] == ("  yaw   1/1 covered (100.0 %, binomial sd 21.8 %); error mean +0.100 "
                        "deg, rms 0.100; stated sd mean 0.050 deg")
    assert lines[3] == "  all angles: 80.0 % covered; block length median 6 frames (range 0-12)"
    assert len(lines) == 4


def test_lines_name_an_angle_never_observed():
    cov = Coverage(0.95, dict(TRUTH))
    cov.add(_cal({"roll": 1.0, "pitch": 2.0, "yaw": 0.0},
                 {"roll": (0.5, 1.5), "pitch": (1.5, 2.5), "yaw": (0, 0)},
                 {"roll": 0.1, "pitch": 0.1, "yaw": 0.1}, frames=5, hidden=("yaw",)))
    lines = cov.lines()
    assert lines[2] == "  yaw   not observable in any sequence"
    assert lines[3] == "  all angles: 100.0 % covered; block length median 5 frames (range 5-5)"


def test_no_seed_is_an_error():
    with pytest.raises(ValueError, match="^calibration coverage needs at least one seed$"):
        cc.calibration_coverage([])


def test_the_loop_passes_its_settings(monkeypatch):
    import loaders.synthetic

    made, calls = [], []

    def fake_seq(scene, sensor, frames, seed, noise, **opts):
        made.append((scene, sensor, frames, seed, noise, opts))
        return SimpleNamespace(seed=seed)

    rotations = []

    def fake_cal(seq, bootstrap, seed):
        calls.append((seq.base.seed, bootstrap, seed))
        return _cal({"roll": 1.0, "pitch": 2.0, "yaw": -1.5},
                    {"roll": (0, 2), "pitch": (0, 3), "yaw": (-2, -1)},
                    {"roll": 0.1, "pitch": 0.1, "yaw": 0.1}, frames=seed)

    monkeypatch.setattr(loaders.synthetic, "SyntheticSequence", fake_seq)
    monkeypatch.setattr(cc, "calibrate_sequence", fake_cal)
    monkeypatch.setattr(cc, "CorrectedSequence",
                        lambda base, R: rotations.append(R) or SimpleNamespace(base=base, R=R))
    seen, got = [], []
    truth = {"roll": 0.5, "pitch": -1.0, "yaw": 2.0}

    def progress(s, cal):
        seen.append(s)
        got.append(cal.block.frames)

    cov = cc.calibration_coverage(np.array([4, 9]), frames=33, scene="campus", sensor="x",
                                  bootstrap=7, truth_deg=truth, progress=progress)
    assert made == [("campus", "x", 33, 4, True, {"edge_band": True}),
                    ("campus", "x", 33, 9, True, {"edge_band": True})]
    assert all(type(m[3]) is int for m in made)
    assert calls == [(4, 7, 4), (9, 7, 9)]
    assert seen == [4, 9] and all(type(s) is int for s in seen)
    R = _rz(2.0) @ _ry(-1.0) @ _rx(0.5)
    np.testing.assert_allclose(rotations[0], R.T, atol=1e-12)
    assert got == [4, 9]  # progress is given each result
    assert cov.level == 0.95 and cov.truth_deg == truth
    assert cov.blocks == [4, 9]
    # truth: roll 0.5 in (0, 2); pitch -1.0 not in (0, 3); yaw 2.0 not in (-2, -1)
    assert cov.covered == {"roll": 2, "pitch": 0, "yaw": 0}


def test_defaults_of_the_loop(monkeypatch):
    import loaders.synthetic

    made, calls = [], []
    monkeypatch.setattr(loaders.synthetic, "SyntheticSequence",
                        lambda *a, **k: made.append((a, k)) or SimpleNamespace())
    monkeypatch.setattr(cc, "CorrectedSequence", lambda base, R: R)

    def fake_cal(R, bootstrap, seed):
        calls.append((R, bootstrap))
        return _cal(dict(TRUTH), {a: (-5, 5) for a in TRUTH}, dict.fromkeys(TRUTH, 0.1))

    monkeypatch.setattr(cc, "calibrate_sequence", fake_cal)
    cc.calibration_coverage([1])
    assert made[0][0] == ("loop", "radar-semidense", 125)
    R = _rz(-1.5) @ _ry(2.0) @ _rx(1.0)
    np.testing.assert_allclose(calls[0][0], R.T, atol=1e-12)
    assert calls[0][1] == 200


def test_a_real_small_run_covers_with_small_errors():
    seen = []
    cov = cc.calibration_coverage([3], frames=40, bootstrap=10,
                                  progress=lambda s, cal: seen.append(s))
    assert seen == [3]
    assert cov.level == pytest.approx(0.95)
    assert sum(cov.tried.values()) >= 2
    for ax, errs in cov.errors_deg.items():
        # a tilt of a few degrees is recovered to well under half a degree
        assert all(abs(e) < 0.5 for e in errs), ax


def test_an_unobservable_first_angle_skips_only_itself():
    cov = Coverage(0.95, dict(TRUTH))
    cov.add(_cal({"roll": 0.0, "pitch": 2.1, "yaw": -1.5},
                 {"roll": (0, 0), "pitch": (1.9, 2.3), "yaw": (-1.7, -1.3)},
                 {"roll": 0.1, "pitch": 0.1, "yaw": 0.1}, frames=4, hidden=("roll",)))
    assert cov.tried == {"roll": 0, "pitch": 1, "yaw": 1}
    lines = cov.lines()
    assert lines[0] == "  roll  not observable in any sequence"
    assert lines[1].startswith("  pitch 1/1 covered (100.0 %")
    assert lines[2].startswith("  yaw   1/1 covered (100.0 %")
    assert len(lines) == 4
