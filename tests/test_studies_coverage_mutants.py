"""bench.studies.coverage, piece by piece (mutation testing): the synthetic drive and its noisy
odometry against their definitions, the figures against ``metrics.units`` called directly, the
study's truth and coverage against ``bench.runs.uncertainty.intervals`` called directly, the
Markdown table and the command line."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import metrics.intervals as metric_intervals
from bench.runs.uncertainty import intervals
from bench.studies import coverage
from bench.studies.coverage import (
    FIGURES,
    LENGTHS_M,
    NOISE_MODELS,
    Coverage,
    NoiseModel,
    ground_truth,
    noisy_estimate,
    study,
    table,
)
from metrics.units import ape_units, kitti_units, relative_units, velocity_units


def _yaw(poses: np.ndarray) -> np.ndarray:
    return np.arctan2(poses[:, 1, 0], poses[:, 0, 0])


# ---- the ground truth ---------------------------------------------------------------------

def test_the_drive_is_planar_at_its_speed_along_its_heading():
    gt = ground_truth(400, speed_mps=4.0, rate_hz=20.0)
    assert gt.shape == (400, 4, 4)
    np.testing.assert_allclose(gt[0], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(gt[:, 3], np.tile([0, 0, 0, 1.0], (400, 1)), atol=0)
    np.testing.assert_allclose(gt[:, 2, 3], 0.0, atol=0)
    # rotations about z only
    np.testing.assert_allclose(gt[:, 2, :3], np.tile([0, 0, 1.0], (400, 1)), atol=1e-12)
    step = np.diff(gt[:, :3, 3], axis=0)
    np.testing.assert_allclose(np.linalg.norm(step, axis=1), 4.0 / 20.0, rtol=1e-12)
    # each step goes along the heading of the pose it leaves
    yaw = _yaw(gt)[:-1]
    np.testing.assert_allclose(step[:, :2], 0.2 * np.c_[np.cos(yaw), np.sin(yaw)], atol=1e-12)


def test_the_yaw_rate_is_a_slow_sum_of_three_sinusoids():
    """yaw rate = sum of a_i sin(2 pi t / p_i), a_i in [0.05, 0.25] rad/s, p_i in [8, 30] s:
    0 at t = 0, at most 0.75 rad/s, changing by at most sum(a_i 2 pi / p_i) per second."""
    rate = 10.0
    for seed in (7, 1, 2):
        gt = ground_truth(3000, rate_hz=rate, seed=seed)
        yaw = np.unwrap(_yaw(gt))
        assert yaw[0] == 0.0 and abs(yaw[1]) < 1e-12  # the rate is sin(0) = 0 at the start
        yaw_rate = np.diff(yaw) * rate
        assert np.abs(yaw_rate).max() <= 0.75
        assert np.abs(yaw_rate).max() >= 0.05  # the largest sinusoid peaks within 300 s
        assert np.abs(np.diff(yaw_rate)).max() * rate <= 0.75 * 2 * np.pi / 8
        # three periods of 8-30 s: its spectrum has nothing below 1/30 Hz ... above 1/8 Hz
        spectrum = np.abs(np.fft.rfft(yaw_rate))
        freq = np.fft.rfftfreq(len(yaw_rate), 1 / rate)
        assert 1 / 31 <= freq[np.argmax(spectrum)] <= 1 / 7.5
        assert spectrum[freq > 0.5].max() < 0.05 * spectrum.max()


def test_the_drive_depends_on_its_seed_and_on_nothing_else():
    np.testing.assert_array_equal(ground_truth(50, seed=3), ground_truth(50, seed=3))
    assert not np.allclose(ground_truth(200, seed=3), ground_truth(200, seed=4))
    np.testing.assert_array_equal(ground_truth(200), ground_truth(200, seed=7))
    default = ground_truth(200)
    step = np.linalg.norm(np.diff(default[:, :3, 3], axis=0), axis=1)
    np.testing.assert_allclose(step, 0.5, rtol=1e-12)  # 5 m/s at 10 Hz


# ---- the noise ----------------------------------------------------------------------------

def test_white_noise_is_the_generators_normal_draws():
    got = coverage._ar1(np.random.default_rng(5), 0.3, 0.0, (40, 3))
    np.testing.assert_array_equal(got, np.random.default_rng(5).normal(0.0, 0.3, (40, 3)))


def test_ar1_noise_keeps_its_sd_and_has_its_lag_one_correlation():
    w = np.random.default_rng(6).normal(0.0, 2.0, (20_000, 2))
    got = coverage._ar1(np.random.default_rng(6), 2.0, 0.9, (20_000, 2))
    np.testing.assert_array_equal(got[0], w[0])
    # x_k = phi x_{k-1} + sqrt(1 - phi^2) w_k, exactly
    np.testing.assert_allclose(got[1:], 0.9 * got[:-1] + np.sqrt(1 - 0.81) * w[1:], atol=1e-12)
    np.testing.assert_allclose(got.std(axis=0), 2.0, rtol=0.1)
    for c in range(2):
        np.testing.assert_allclose(np.corrcoef(got[1:, c], got[:-1, c])[0, 1], 0.9, atol=0.02)


def test_without_noise_the_estimate_is_the_ground_truth():
    gt = ground_truth(120)
    np.testing.assert_allclose(noisy_estimate(gt, NoiseModel(0.0, 0.0), 3), gt, atol=1e-9)


def test_the_estimate_chains_the_true_steps_each_perturbed_by_its_draw():
    """Step k of the estimate: rotation exp(r_k) R_k (r_k: a draw of rot_noise_deg per axis,
    in degrees), translation t_k + e_k (e_k: a draw of trans_noise_m per axis), the draws
    rotation first, from the seed's generator; chained from the first true pose."""
    gt = ground_truth(60)
    gt[0, :3, 3] = (1.0, -2.0, 0.5)  # a first pose off the origin
    noise = NoiseModel(0.5, 0.03)
    est = noisy_estimate(gt, noise, 11)
    rng = np.random.default_rng(11)
    rot = Rotation.from_rotvec(np.radians(rng.normal(0.0, 0.5, (59, 3)))).as_matrix()
    trans = rng.normal(0.0, 0.03, (59, 3))
    true_steps = np.linalg.inv(gt[:-1]) @ gt[1:]
    est_steps = np.linalg.inv(est[:-1]) @ est[1:]
    np.testing.assert_allclose(est[0], gt[0], atol=0)
    np.testing.assert_allclose(est_steps[:, :3, :3], rot @ true_steps[:, :3, :3], atol=1e-9)
    np.testing.assert_allclose(est_steps[:, :3, 3], true_steps[:, :3, 3] + trans, atol=1e-9)


def test_correlated_noise_reaches_the_estimate():
    gt = ground_truth(3000)
    noise = NoiseModel(0.0, 0.05, correlation=0.9)
    est = noisy_estimate(gt, noise, 2)
    true_steps, est_steps = (np.linalg.inv(p[:-1]) @ p[1:] for p in (gt, est))
    err = est_steps[:, :3, 3] - true_steps[:, :3, 3]
    np.testing.assert_allclose(err.std(axis=0), 0.05, rtol=0.2)
    assert np.corrcoef(err[1:, 0], err[:-1, 0])[0, 1] > 0.8


def test_the_noise_models_and_their_labels():
    assert NoiseModel() == NoiseModel(0.05, 0.01, 0.0)
    assert NOISE_MODELS["white"] == NoiseModel()
    assert NOISE_MODELS["correlated"] == NoiseModel(0.05, 0.01, 0.9)
    assert NoiseModel().label == ("0.05 deg and 1 cm per step and axis, independent from "
                                  "step to step")
    assert NoiseModel(0.1, 0.025, 0.9).label == (
        "0.1 deg and 2.5 cm per step and axis, correlated from step to step (AR(1), 0.9)")


# ---- the figures --------------------------------------------------------------------------

def test_every_figure_is_its_units_quantity():
    gt = ground_truth(700)
    est = noisy_estimate(gt, NoiseModel(), 1)
    assert len(FIGURES) == 2 * len(LENGTHS_M) + 5
    assert LENGTHS_M == (8.0, 16.0, 24.0, 32.0, 40.0, 48.0)
    stamps = np.arange(700) / 10.0
    direct = {"APE translation RMSE": ape_units(gt, est, "se3").statistic("trans_m"),
              "APE rotation RMSE": ape_units(gt, est, "se3").statistic("rot_deg"),
              "KITTI translation drift": kitti_units(gt, est).statistic("trans_pct"),
              "KITTI rotation drift": kitti_units(gt, est).statistic("rot_deg_per_100m"),
              "velocity error": velocity_units(gt, est, stamps).statistic("norm_mps")}
    for L in LENGTHS_M:
        direct[f"relative {L:g} m rotation"] = relative_units(gt, est, L).statistic("rot_deg")
        direct[f"relative {L:g} m translation"] = relative_units(gt, est, L).statistic("trans_m")
    assert set(direct) == set(FIGURES)
    for name, (make, key) in FIGURES.items():
        np.testing.assert_allclose(make(gt, est).statistic(key), direct[name], rtol=1e-12,
                                   err_msg=name)


def test_figures_of_the_same_units_share_one_computation_and_one_interval_call():
    gt = ground_truth(400)
    est = noisy_estimate(gt, NoiseModel(), 1)
    names = ("relative 8 m rotation", "APE translation RMSE", "relative 8 m translation",
             "APE rotation RMSE")
    made = coverage._units_by_maker(gt, est, names)
    assert list(made) == list(names)
    assert made[names[0]][0] is made[names[2]][0]
    assert made[names[1]][0] is made[names[3]][0]
    assert made[names[0]][0] is not made[names[1]][0]
    assert [made[n][1] for n in names] == ["rot_deg", "trans_m", "trans_m", "rot_deg"]
    assert coverage._scored_together("APE rotation RMSE") == {"trans_m": "trans_m",
                                                              "rot_deg": "rot_deg"}
    assert coverage._scored_together("relative 16 m translation") == {"rot_deg": "rot_deg",
                                                                      "trans_m": "trans_m"}
    assert coverage._scored_together("KITTI rotation drift") == {
        "trans_pct": "trans_pct", "rot_deg_per_100m": "rot_deg_per_100m"}
    assert coverage._scored_together("velocity error") == {"norm_mps": "norm_mps"}


# ---- the study ----------------------------------------------------------------------------

def _expected(figure: str, n: int, speed: float, noise: NoiseModel, trials: int, truths: int,
              first: int, reps: int) -> dict:
    """The study's row for ``figure``, from its definition: the truth is the mean figure of
    the seeds after the trials', the intervals are a run's (every quantity of the units)."""
    gt = ground_truth(n, speed_mps=speed)
    make, key = FIGURES[figure]
    truth = np.mean([make(gt, noisy_estimate(gt, noise, first + trials + s)).statistic(key)
                     for s in range(truths)])
    keys = {k: k for m, k in FIGURES.values() if m is make}
    rows = []
    for s in range(trials):
        units = make(gt, noisy_estimate(gt, noise, first + s))
        part = intervals(units, n, keys, reps=reps)
        if part[key] is not None:
            rows.append((part[key], part["spread"], units.statistic(key)))
    return {"truth": truth, "rows": rows}


def test_the_study_measures_coverage_against_the_long_run_mean():
    noise = NoiseModel(0.08, 0.02, 0.5)
    figures = ("relative 8 m translation", "APE rotation RMSE", "velocity error",
               "KITTI translation drift")
    got = study(n_frames=260, trials=3, truth_seeds=2, noise=noise, figures=figures,
                first_seed=50, reps=40, speed_mps=4.0)
    assert [c.figure for c in got] == list(figures)
    for c in got[:3]:
        want = _expected(c.figure, 260, 4.0, noise, 3, 2, 50, 40)
        assert c.trials == len(want["rows"]) == 3
        np.testing.assert_allclose(c.truth, want["truth"], rtol=1e-12)
        cis = [ci for ci, _, _ in want["rows"]]
        np.testing.assert_allclose(c.coverage, np.mean([lo <= want["truth"] <= hi
                                                         for lo, hi in cis]), atol=0)
        np.testing.assert_allclose(c.median_width, np.median([hi - lo for lo, hi in cis]),
                                   rtol=1e-12)
        np.testing.assert_allclose(c.median_block, np.median(
            [sp.block_frames for _, sp, _ in want["rows"]]), rtol=1e-12)
        np.testing.assert_allclose(c.median_independent, np.median(
            [sp.n_independent for _, sp, _ in want["rows"]]), rtol=1e-12)
        np.testing.assert_allclose(c.contains_own, np.mean(
            [lo <= x <= hi for (lo, hi), _, x in want["rows"]]), atol=0)
    # KITTI's 100 m segments on a 104 m drive: no interval, the truth still its mean
    kitti = got[3]
    assert kitti.trials == 0
    assert all(math.isnan(v) for v in (kitti.coverage, kitti.median_width, kitti.median_block,
                                       kitti.median_independent, kitti.contains_own))
    gt = ground_truth(260, speed_mps=4.0)
    np.testing.assert_allclose(kitti.truth, np.mean([kitti_units(
        gt, noisy_estimate(gt, noise, 53 + s)).statistic("trans_pct") for s in range(2)]))


def test_one_trial_covers_exactly_when_its_interval_holds_the_long_run_mean():
    got = study(n_frames=200, trials=1, truth_seeds=3, figures=("relative 8 m rotation",),
                first_seed=0, reps=30)[0]
    want = _expected("relative 8 m rotation", 200, 5.0, NoiseModel(), 1, 3, 0, 30)
    (lo, hi), _, _ = want["rows"][0]
    assert got.coverage == float(lo <= want["truth"] <= hi)
    assert got.contains_own == 1.0


def test_the_study_defaults():
    import inspect

    defaults = {k: v.default for k, v in inspect.signature(study).parameters.items()}
    assert defaults == {"n_frames": 1500, "trials": 200, "truth_seeds": 400,
                        "noise": NoiseModel(), "figures": tuple(FIGURES), "first_seed": 10_000,
                        "reps": metric_intervals.REPS, "speed_mps": 5.0}


# ---- the table ----------------------------------------------------------------------------

def test_the_table_has_a_column_per_noise_model():
    rows = {"white": [Coverage("APE translation RMSE", 0.1, 0.955, 40, 0.01234567, 5.0, 59.5),
                      Coverage("KITTI rotation drift", 0.2, math.nan, 0, math.nan, math.nan,
                               math.nan)],
            "correlated": [Coverage("APE translation RMSE", 0.1, 0.9, 40, 2.5, 7.0, 30.0),
                           Coverage("KITTI rotation drift", 0.2, 0.5, 2, 1.0, 3.0, 1.0)]}
    assert table(rows).splitlines() == [
        "| figure | coverage, white noise | coverage, correlated noise | median width, white "
        "| median width, correlated | median block [frames] | median independent pieces |",
        "|---|---|---|---|---|---|---|",
        "| APE translation RMSE | 95.5 % | 90.0 % | 0.01235 | 2.5 | 5 / 7 | 59.5 / 30 |",
        "| KITTI rotation drift | no interval | 50.0 % | nan | 1 | nan / 3 | nan / 1 |"]


# ---- the command line ---------------------------------------------------------------------

def _main(monkeypatch, capsys, *argv: str) -> tuple[list, str]:
    calls = []

    def fake_study(n_frames, trials, truth_seeds, noise, **kw):
        calls.append({"n_frames": n_frames, "trials": trials, "truth_seeds": truth_seeds,
                      "noise": noise, **kw, "block_factor": metric_intervals.BLOCK_FACTOR})
        own = 0.5 if noise.correlation else 1.0
        return [Coverage("velocity error", 0.1, 0.9, 4, 0.2, 3.0, 10.0, own)]

    monkeypatch.setattr(coverage, "study", fake_study)
    monkeypatch.setattr(metric_intervals, "BLOCK_FACTOR", metric_intervals.BLOCK_FACTOR)
    monkeypatch.setattr(sys, "argv", ["coverage", *argv])
    coverage.main()
    return calls, capsys.readouterr().out


def test_the_command_runs_both_noise_models_with_the_documented_defaults(monkeypatch, capsys):
    factor = metric_intervals.BLOCK_FACTOR
    calls, out = _main(monkeypatch, capsys)
    assert calls == [{"n_frames": 1500, "trials": 400, "truth_seeds": 800, "noise": noise,
                      "first_seed": 10_000, "reps": metric_intervals.REPS, "speed_mps": 5.0,
                      "block_factor": factor}
                     for noise in (NOISE_MODELS["white"], NOISE_MODELS["correlated"])]
    lines = out.splitlines()
    assert lines[0] == (f"400 trajectories of 1500 poses (5 m/s, 10 Hz: 750 m) per noise "
                        f"model, long-run mean from 800 more, noise seeds from 10000, "
                        f"{metric_intervals.REPS} resamples, block factor {factor:g}")
    assert lines[1] == f"- white: {NOISE_MODELS['white'].label}"
    assert lines[2] == f"- correlated: {NOISE_MODELS['correlated'].label}"
    assert lines[3].startswith("| figure | coverage, white noise | coverage, correlated noise")
    # the correlated row's intervals hold their own figure half the time only
    assert lines[-1] == "intervals not holding their own figure: [('correlated', " \
                        "'velocity error')]"


def test_the_command_passes_its_options_and_sets_the_block_factor(monkeypatch, capsys):
    calls, out = _main(monkeypatch, capsys, "--frames", "250", "--speed", "4.4", "--trials",
                       "7", "--truth-seeds", "9", "--first-seed", "3", "--noise", "white",
                       "--reps", "33", "--block-factor", "2.5")
    assert calls == [{"n_frames": 250, "trials": 7, "truth_seeds": 9,
                      "noise": NOISE_MODELS["white"], "first_seed": 3, "reps": 33,
                      "speed_mps": 4.4, "block_factor": 2.5}]
    assert out.splitlines()[0] == ("7 trajectories of 250 poses (4.4 m/s, 10 Hz: 110 m) per "
                                   "noise model, long-run mean from 9 more, noise seeds from 3, "
                                   "33 resamples, block factor 2.5")
    assert "intervals not holding" not in out
    assert "correlated" not in out


def test_the_command_refuses_an_unknown_noise_model(monkeypatch, capsys):
    with pytest.raises(SystemExit) as exit_:
        _main(monkeypatch, capsys, "--noise", "pink")
    assert exit_.value.code == 2
    assert "--noise" in capsys.readouterr().err


# ---- killing the first run's survivors ----------------------------------------------------

def test_the_drive_follows_its_documented_construction():
    """From ``default_rng(seed)``: three amplitudes uniform in [0.05, 0.25] rad/s, then three
    periods uniform in [8, 30] s; yaw rate sum a_i sin(2 pi t / p_i), integrated by steps
    (the yaw of pose k holds the rates before it)."""
    for seed, rate in ((7, 10.0), (3, 20.0)):
        gt = ground_truth(900, rate_hz=rate, seed=seed)
        rng = np.random.default_rng(seed)
        amps, periods = rng.uniform(0.05, 0.25, 3), rng.uniform(8.0, 30.0, 3)
        t = np.arange(900) / rate
        rate_of = sum(a * np.sin(2 * np.pi * t / p) for a, p in zip(amps, periods, strict=True))
        want = np.r_[0.0, np.cumsum(rate_of[:-1]) / rate]
        np.testing.assert_allclose(np.unwrap(_yaw(gt)), want, atol=1e-9)


def test_a_relative_figure_maker_is_relative_units_at_its_length():
    """``_relative`` called here (FIGURES' makers are made at import)."""
    gt = ground_truth(400)
    est = noisy_estimate(gt, NoiseModel(), 2)
    for length in (8.0, 24.0):
        got = coverage._relative(length)(gt, est)
        want = relative_units(gt, est, length)
        for key in ("rot_deg", "trans_m"):
            np.testing.assert_allclose(got.values[key], want.values[key], rtol=1e-12)
        np.testing.assert_array_equal(got.anchor, want.anchor)
        np.testing.assert_array_equal(got.end, want.end)
    assert len(coverage._relative(8.0)(gt, est)) != len(coverage._relative(24.0)(gt, est))


def test_ar1_noise_of_coefficient_one_stays_at_its_first_draw():
    """phi = 1: x_k = x_{k-1} + 0 w_k, the first draw for ever."""
    got = coverage._ar1(np.random.default_rng(8), 1.0, 1.0, (30, 3))
    first = np.random.default_rng(8).normal(0.0, 1.0, (30, 3))[0]
    np.testing.assert_allclose(got, np.tile(first, (30, 1)), atol=0)


def test_the_commands_help_describes_every_option(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["coverage", "--help"])
    monkeypatch.setenv("COLUMNS", "1000")  # argparse wraps (at hyphens too) to the terminal
    with pytest.raises(SystemExit) as exit_:
        coverage.main()
    assert exit_.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    first = " ".join(coverage.__doc__.split("\n\n")[0].split())
    assert first.startswith("How often the harness's 95 % intervals contain the long-run mean")
    assert first in text
    assert "``python -m" not in text  # the first paragraph only
    for option, help_ in (
            ("--frames FRAMES", "poses per trajectory"),
            ("--speed SPEED", "driving speed [m/s] (10 Hz poses); e.g. --frames 250 --speed "
                              "4.4 for a drive like the real 250-frame sample (110 m)"),
            ("--trials TRIALS", "trajectories checked"),
            ("--truth-seeds TRUTH_SEEDS", "trajectories averaged for the long-run mean"),
            ("--first-seed FIRST_SEED", "the first noise seed (trials, then the long-run "
                                        "mean's drives)"),
            ("--reps REPS", "bootstrap resamples"),
            ("--block-factor BLOCK_FACTOR", "metrics.intervals.BLOCK_FACTOR for this study "
                                            "(default: the harness's, "
                                            f"{metric_intervals.BLOCK_FACTOR:g}): how it was "
                                            "chosen")):
        assert f"{option} {help_}" in text, option


class _Spread:
    def __init__(self, block: float, independent: float):
        self.block_frames, self.n_independent = block, independent


def test_interval_ends_count_as_inside(monkeypatch):
    """Without noise every estimate is the ground truth, so each trial's figure is the long-run
    mean exactly; intervals ending at it ([x, x+1], [x-1, x]) hold it, one above it
    ([x+1, x+2]) does not: coverage and own-figure share 2/3, widths 1, the spreads' medians."""
    calls = []

    def fake_intervals(units, n_frames, keys, reps):
        calls.append((n_frames, keys, reps))
        x = units.statistic("trans_m")
        ends = ([x, x + 1.0], [x - 1.0, x], [x + 1.0, x + 2.0])[len(calls) - 1]
        return {"trans_m": ends, "rot_deg": None,
                "spread": _Spread(10.0 * len(calls), len(calls))}

    monkeypatch.setattr(coverage, "intervals", fake_intervals)
    (got,) = study(n_frames=120, trials=3, truth_seeds=2, noise=NoiseModel(0.0, 0.0),
                   figures=("relative 8 m translation",), reps=17)
    assert calls == [(120, {"rot_deg": "rot_deg", "trans_m": "trans_m"}, 17)] * 3
    assert got.trials == 3
    np.testing.assert_allclose(got.coverage, 2 / 3, rtol=1e-12)
    np.testing.assert_allclose(got.contains_own, 2 / 3, rtol=1e-12)
    np.testing.assert_allclose(got.median_width, 1.0, rtol=1e-9)
    assert (got.median_block, got.median_independent) == (20.0, 2.0)


def test_a_figure_without_interval_leaves_the_next_ones_measured():
    got = study(n_frames=200, trials=1, truth_seeds=1, figures=(
        "KITTI rotation drift", "velocity error"), reps=20)
    assert got[0].trials == 0 and math.isnan(got[0].coverage)
    assert got[1].figure == "velocity error" and got[1].trials == 1


def test_the_studys_defaults_reach_its_parts(monkeypatch):
    """``study()`` as the command's defaults leave it: 1500 poses at 5 m/s, 400 truth seeds
    after 200 trial seeds from 10,000, white noise, every figure, REPS resamples (its parts
    replaced by recorders: the real study at this size takes minutes)."""
    seen = {"gt": [], "seeds": [], "noise": set(), "figures": set(), "reps": set()}

    class Units:
        def statistic(self, key):
            return 1.0

    def fake_gt(n, speed_mps):
        seen["gt"].append((n, speed_mps))
        return np.zeros((2, 4, 4))

    def fake_estimate(gt, noise, seed):
        seen["seeds"].append(seed)
        seen["noise"].add(noise)
        return gt

    def fake_units(gt, est, figures):
        seen["figures"].add(tuple(figures))
        return {f: (Units(), FIGURES[f][1]) for f in figures}

    def fake_intervals(units, n_frames, keys, reps):
        seen["reps"].add((n_frames, reps))
        return {**{k: [0.0, 2.0] for k in keys}, "spread": _Spread(1, 1)}

    monkeypatch.setattr(coverage, "ground_truth", fake_gt)
    monkeypatch.setattr(coverage, "noisy_estimate", fake_estimate)
    monkeypatch.setattr(coverage, "_units_by_maker", fake_units)
    monkeypatch.setattr(coverage, "intervals", fake_intervals)
    got = study()
    assert seen["gt"] == [(1500, 5.0)]
    assert seen["seeds"] == list(range(10_200, 10_600)) + list(range(10_000, 10_200))
    assert seen["noise"] == {NoiseModel()}
    assert seen["figures"] == {tuple(FIGURES)}
    assert seen["reps"] == {(1500, metric_intervals.REPS)}
    assert [c.figure for c in got] == list(FIGURES)
    assert all(c.trials == 200 and c.coverage == 1.0 for c in got)


def test_the_command_takes_both_noise_models_by_name(monkeypatch, capsys):
    calls, _ = _main(monkeypatch, capsys, "--noise", "both")
    assert [c["noise"] for c in calls] == [NOISE_MODELS["white"], NOISE_MODELS["correlated"]]
    calls, _ = _main(monkeypatch, capsys, "--noise", "correlated")
    assert [c["noise"] for c in calls] == [NOISE_MODELS["correlated"]]
