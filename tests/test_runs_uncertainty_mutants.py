"""bench/runs/uncertainty.py: the ``*_ci`` fields and the ``spread`` beside a figure are the
intervals of metrics.intervals / metrics.drift_intervals at the documented level, seed and
number of resamples (the mutation run of tools/mutate.py over bench/runs/uncertainty.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.runs.result import Spread
from bench.runs.uncertainty import SEED, _ci, intervals
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from metrics.drift_intervals import ape_intervals
from metrics.intervals import LEVEL, Interval, unit_intervals
from metrics.units import Units, ape_units, relative_units

REPS = 200  # few resamples: fast, and unlike the default 1000


@pytest.fixture(scope="module")
def drive():
    gt = ground_truth(300)
    return gt, noisy_estimate(gt, NoiseModel(), 3)


def test_the_documented_level_and_seed():
    assert LEVEL == 0.95
    assert SEED == 0


def test_no_units_no_interval():
    empty = Units(np.zeros(0, int), np.zeros(0, int), {"trans_m": np.zeros(0)})
    out = intervals(empty, 10, {"trans_m": "trans_m_mean_ci", "rot_deg": "rot_deg_mean_ci"})
    assert out == {"trans_m_mean_ci": None, "rot_deg_mean_ci": None,
                   "spread": Spread(n_independent=0)}


def test_a_relative_error_interval_is_the_units_one_at_95_percent(drive):
    gt, est = drive
    u = relative_units(gt, est, 8.0)
    keys = {"trans_m": "trans_m_mean_ci", "rot_deg": "rot_deg_mean_ci"}
    out = intervals(u, len(gt), keys, reps=REPS)
    want = unit_intervals(len(gt), u.anchor, u.end, {k: u.values[k] for k in keys},
                          level=0.95, reps=REPS, seed=0)
    for key, field in keys.items():
        np.testing.assert_allclose(out[field], [want[key].low, want[key].high], rtol=1e-12)
        # the interval holds the mean it stands beside
        assert out[field][0] <= u.statistic(key) <= out[field][1]
    other = unit_intervals(len(gt), u.anchor, u.end, {"trans_m": u.values["trans_m"]},
                           level=0.95, reps=REPS + 100, seed=0)["trans_m"]
    assert [other.low, other.high] != pytest.approx(out["trans_m_mean_ci"], rel=1e-9)
    assert set(out) == {*keys.values(), "spread"}
    spread = out["spread"]
    assert spread.block_frames == want["trans_m"].block_frames >= 1
    assert spread.n_independent == want["trans_m"].n_independent >= 2
    assert spread.resampled == "units"


def test_an_ape_interval_resamples_the_step_errors(drive):
    gt, est = drive
    u = ape_units(gt, est, "se3")
    keys = {"trans_m": "trans_rmse_m_ci", "rot_deg": "rot_rmse_deg_ci"}
    out = intervals(u, len(gt), keys, reps=REPS)
    want = ape_intervals(u.drift, level=0.95, reps=REPS, seed=0)
    for key, field in keys.items():
        np.testing.assert_allclose(out[field], [want[key].low, want[key].high], rtol=1e-12)
    other = ape_intervals(u.drift, level=0.95, reps=REPS + 100, seed=0)["trans_m"]
    assert [other.low, other.high] != pytest.approx(out["trans_rmse_m_ci"], rel=1e-9)
    assert out["spread"] == Spread(block_frames=want["trans_m"].block_frames,
                                   n_independent=want["trans_m"].n_independent,
                                   resampled="step errors")


def test_a_seed_gives_the_same_interval_twice(drive):
    gt, est = drive
    u = relative_units(gt, est, 8.0)
    keys = {"trans_m": "ci"}
    assert intervals(u, len(gt), keys, reps=REPS) == intervals(u, len(gt), keys, reps=REPS)
    seeded = unit_intervals(len(gt), u.anchor, u.end, {"trans_m": u.values["trans_m"]},
                            reps=REPS, seed=1)["trans_m"]
    assert [seeded.low, seeded.high] != pytest.approx(intervals(u, len(gt), keys, reps=REPS)["ci"],
                                                      rel=1e-12)


def test_a_block_of_zero_frames_is_no_block(drive):
    # an APE over two frames is too short to resample: NaN interval, block 0, no pieces
    gt, est = drive
    u = ape_units(gt[:2], est[:2], "se3")
    out = intervals(u, 2, {"trans_m": "trans_rmse_m_ci"}, reps=REPS)
    assert out["trans_rmse_m_ci"] is None
    assert out["spread"] == Spread(block_frames=None, n_independent=0,
                                   resampled="step errors")


def test_ci_is_a_finite_pair_or_none():
    def iv(low, high):
        return Interval(low, high, 0.95, 1, 2)

    assert _ci(iv(1.0, 2.0)) == [1.0, 2.0]
    assert _ci(iv(math.nan, 2.0)) is None
    assert _ci(iv(1.0, math.nan)) is None
    assert _ci(iv(-math.inf, 2.0)) is None
    assert _ci(iv(1.0, math.inf)) is None
    assert type(_ci(iv(np.float64(1.0), 2))[1]) is float
