"""Behaviours a mutation run found unpinned (issue 46, item 4: its known survivors), each pinned
here by a test that fails on the mutant (checked by applying each mutation by hand):

1. the APE resamples drawn on several threads are the draws of one thread (a chunk never
   reseeds: the intervals do not change with the thread count);
2. a run's APE interval resamples with the run's own alignment, not SE(3);
4. the sequence key holds the run's own frame range (two ranges of one store never merge);
8. the scale benchmark's CPU time counts the worker processes the command waited for;
9. the forest plot never ranks a figure on one independent segment;
10. a paired interval's block is the longest of both estimates' (and their difference's), not
    one estimate's.
(3, 5, 6 and 7 are pinned on the branches that rewrite that code.)
Then the survivors of `make mutate BASE=942ccd0` on metrics/units.py, metrics/intervals.py,
bench/report/tables/significance.py and bench/runs/sequence_identity.py that are not
equivalent mutants (each test checked against its mutants applied by hand, and the intervals'
by a second mutmut run)."""

from __future__ import annotations

import json
import sys
import textwrap

import numpy as np
import pytest

from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from metrics import drift_intervals
from metrics.drift_intervals import Drift, draws_batched, paired_ape_interval
from metrics.intervals import block_frames, paired_interval

# ---- 1. threads never change the draws --------------------------------------------------------

def test_the_threaded_draws_are_the_one_thread_draws():
    """Five chunks of resamples (450 at 100 a chunk) on three threads, two batches: every
    resample's block starts are the one-thread run's (the generator draws row after row,
    whatever thread computes the row), so the drawn RMSEs and the interval are equal."""
    gt = ground_truth(301)
    est = noisy_estimate(gt, NoiseModel(0.05, 0.01, correlation=0.6), seed=21)
    try:
        drift_intervals.set_threads(1)
        one = Drift(gt, est).draws(9, 450, seed=4)
        drift_intervals.set_threads(3)
        three = Drift(gt, est).draws(9, 450, seed=4)
        reference = draws_batched(Drift(gt, est), 9, 450, seed=4)
    finally:
        drift_intervals.set_threads(1)
    for q in ("trans_m", "rot_deg"):
        np.testing.assert_array_equal(three[q], one[q])
        np.testing.assert_allclose(three[q], reference[q], rtol=1e-9, atol=1e-11)
        # five chunks of different draws (a chunk that restarted the generator repeats)
        chunks = three[q].reshape(-1, 90)  # 450 / 5, not aligned with the 100-row chunks
        assert len({round(float(c.mean()), 12) for c in chunks}) == 5
        assert not np.allclose(three[q][:100], three[q][100:200])


# ---- 2. the run's own alignment ---------------------------------------------------------------

def test_a_runs_ape_interval_is_that_of_its_alignment():
    """An estimate 5 % too long: SE(3)'s APE is large, Sim(3)'s (which fits the scale) small.
    A run scored with Sim(3) prints the Sim(3) figure with an interval about it; resampled
    with SE(3) the interval would lie far above it."""
    from bench.runs.evaluate import Scoring, score
    from metrics.units import ape_units

    gt = ground_truth(400)
    est = noisy_estimate(gt, NoiseModel(), seed=3)
    est[:, :3, 3] *= 1.05
    assert ape_units(gt, est, "sim3").drift.alignment == "sim3"
    out = {a: score(gt, est, np.ones(len(gt)), lengths_m=(8.0,),
                    scoring=Scoring((8.0,), alignment=a))["ape"] for a in ("se3", "sim3")}
    se3, sim3 = out["se3"], out["sim3"]
    assert sim3["trans_rmse_m"] < 0.5 * se3["trans_rmse_m"]  # the case tells them apart
    for a in (se3, sim3):
        low, high = a["trans_rmse_m_ci"]
        assert low <= a["trans_rmse_m"] <= high
    # each interval about its own figure: Sim(3)'s lies wholly below SE(3)'s figure
    assert sim3["trans_rmse_m_ci"][1] < se3["trans_rmse_m"]


# ---- 4. a run's own frame range is part of its sequence ---------------------------------------

def test_two_frame_ranges_of_one_store_are_two_sequences():
    from bench.runs.sequence_identity import content_key, sequence_tags

    def run(own, frames):
        return {"identity": {"store_sha256": "a" * 64, "frame_range": own},
                "sequence": {"name": "data1", "frames": frames, "store": "data1.h5"}}

    early, late = run([0, 100], 100), run([100, 100], 100)
    assert content_key(early) == ("a" * 64, (0, 100))
    assert content_key(early) != content_key(late)
    assert sequence_tags(["data1", "data1"], [early, late]) == ["frames 0-99", "frames 100-199"]
    # the whole store and its first 100 frames: two sequences too
    assert sequence_tags(["data1", "data1"], [run(None, 400), early]) == \
        ["frames 0-399", "frames 0-99"]


# ---- 8. the scale benchmark counts its worker processes ---------------------------------------

def test_the_scale_probe_counts_the_cpu_of_the_processes_it_waited_for(tmp_path, monkeypatch):
    """A command whose work is done by a child process (as an experiment's workers do): the
    probe's CPU time holds the child's (0.4 s of busy work) although its own is near 0."""
    from bench.studies.scale import child

    (tmp_path / "burner.py").write_text(textwrap.dedent(f"""
        import subprocess

        BUSY = "import time\\nt = time.process_time()\\nwhile time.process_time() - t < 0.4: pass"

        def main():
            subprocess.run([{sys.executable!r}, "-c", BUSY], check=True)
        """))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    got = child([], entry="burner")
    assert got["cpu_s"] >= 0.4
    assert got["wall_s"] >= 0.4


# ---- 9. the forest plot never ranks a one-segment figure --------------------------------------

def test_the_forest_plot_leaves_a_one_segment_figure_unranked(tmp_path):
    """The best figure of a column on one independent segment: hollow and unmarked, and the
    column's U is the smallest upper end of the others (as the tables' "(1 segment)")."""
    from bench.report.figures.forest import BOLD, UNMARKED, forest_panels
    from bench.report.tables.paper import runs as table_rows
    from bench.runs.evaluate import evaluate_run
    from bench.runs.folders import write_run
    from loaders.trajectory import Trajectory
    from methods.base import FrameRecord, OdometryResult

    gt = ground_truth(700)
    stamps = np.arange(len(gt)) / 10.0
    known = {"icp-p2p": (0.30, 0.25, 0.35, 1), "gicp": (0.40, 0.36, 0.45, 5),
             "doppler": (0.50, 0.44, 0.56, 2)}
    for k, (method, (value, low, high, n_ind)) in enumerate(known.items()):
        est = noisy_estimate(gt, NoiseModel(), seed=k)
        frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(len(gt))]
        result = OdometryResult(stamps, est, frames)
        ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(8.0,))
        metrics = {**ev.metrics, "sequence": "drive", "method": method, "seed": None,
                   "frames": len(gt), "status": "done"}
        rel = metrics["relative_error"][0]
        rel.update(rot_deg_mean=value, rot_deg_mean_ci=[low, high])
        rel["spread"] = {**rel["spread"], "n_independent": n_ind}
        config = {"method": method, "seed": None, "label": None,
                  "sequence": {"name": "drive", "display_name": "drive",
                               "sensor_class": "Semi-Dense 4D Radar"}}
        write_run(tmp_path / "drive" / method, result, ev.gt, config, metrics)
    panel = dict(forest_panels(table_rows(tmp_path)))["drive-rotation"][0]
    entry = {e.run.method: e for e in panel.entries}
    assert not entry["icp-p2p"].rankable and entry["icp-p2p"].mark == UNMARKED
    assert entry["gicp"].rankable and entry["doppler"].rankable  # 5 and 2 segments
    assert entry["gicp"].mark == BOLD
    assert panel.bounds[0] == pytest.approx(0.45)  # not icp-p2p's 0.35
    assert json.loads((tmp_path / "drive" / "icp-p2p" / "metrics.json").read_text())[
        "relative_error"][0]["spread"]["n_independent"] == 1


# ---- 10. a paired block is the longest of both estimates' -------------------------------------

def _ar1(n, phi, seed):
    rng = np.random.default_rng(seed)
    x = np.empty(n)
    x[0] = rng.normal()
    for k in range(1, n):
        x[k] = phi * x[k - 1] + rng.normal()
    return x


def test_a_paired_interval_blocks_by_the_more_correlated_estimate():
    """Per-frame units, A white and B strongly correlated: whichever comes first, the paired
    interval's block is the tables' rule over both series and their difference -
    ceil(BLOCK_FACTOR x the longest correlation length), B's or the difference's, never A's
    one frame."""
    import math

    from metrics.intervals import BLOCK_FACTOR

    n = 400
    anchor = np.arange(n)
    white = 1.0 + 0.1 * np.random.default_rng(1).normal(size=n)
    walk = 1.0 + 0.1 * _ar1(n, 0.95, 2)
    assert block_frames(n, 1, white) < block_frames(n, 1, walk)
    ab = paired_interval(n, anchor, anchor + 5, white, walk, reps=50)
    ba = paired_interval(n, anchor, anchor + 5, walk, white, reps=50)
    longest = max(block_frames(n, 5, v) for v in (white, walk, white - walk))
    assert longest >= block_frames(n, 5, walk) > block_frames(n, 5, white)
    assert ab.block_frames == ba.block_frames == min(math.ceil(BLOCK_FACTOR * longest), n // 2)


def test_a_paired_ape_interval_blocks_by_both_estimates_step_errors():
    """Step errors of A white, of B strongly correlated: the paired APE block is the same in
    both orders and B's (the longer), as drift_block of both."""
    from metrics.drift_intervals import drift_block

    gt = ground_truth(400)
    white = Drift(gt, noisy_estimate(gt, NoiseModel(0.05, 0.01), seed=5))
    corr = Drift(gt, noisy_estimate(gt, NoiseModel(0.05, 0.01, correlation=0.95), seed=6))
    alone = drift_block([white.errors]), drift_block([corr.errors])
    assert alone[0] < alone[1]
    ab = paired_ape_interval(white, corr, reps=40)
    ba = paired_ape_interval(corr, white, reps=40)
    assert ab.block_frames == ba.block_frames == alone[1]


# ---- make mutate BASE=942ccd0: metrics/units.py ------------------------------------------------

def _drive(n=400, seed=7):
    gt = ground_truth(n)
    return gt, noisy_estimate(gt, NoiseModel(), seed), np.arange(n) / 10.0


def test_each_units_function_passes_its_own_options_on():
    """Every option of a units function reaches the metric it wraps: the units reproduce the
    metric computed with the same non-default option (and differ from the default's)."""
    from metrics.ape import ape
    from metrics.kitti import kitti_segments
    from metrics.relative import segment_errors
    from metrics.units import ape_units, kitti_units, relative_units, velocity_units
    from metrics.velocity import velocity_series

    gt, est, stamps = _drive()
    est_long = est.copy()
    est_long[:, :3, 3] *= 1.05
    sim3 = ape_units(gt, est_long, "sim3")  # errors computed here, with the alignment asked
    assert sim3.statistic("trans_m") == pytest.approx(ape(gt, est_long, "sim3").trans_rmse_m,
                                                      rel=1e-9)
    assert sim3.statistic("trans_m") < 0.5 * ape_units(gt, est_long).statistic("trans_m")
    np.testing.assert_array_equal(sim3.end, sim3.anchor + 1)  # single frames
    loose = relative_units(gt, est, 8.0, tolerance=0.5)
    assert len(loose) == len(segment_errors(gt, est, 8.0, 0.5).start_idx)
    assert len(loose) != len(relative_units(gt, est, 8.0))
    steps = kitti_units(gt, est, (100.0,), step_frames=1)
    assert len(steps) == len(kitti_segments(gt, est, (100.0,), 1).start_idx)
    assert len(steps) > len(kitti_units(gt, est, (100.0,)))
    short = velocity_units(gt, est, stamps, window_s=0.3)
    series = velocity_series(gt, est, stamps, 0.3)
    np.testing.assert_array_equal(short.end, series.end_idx)
    assert not np.array_equal(short.end, velocity_units(gt, est, stamps).end)


def test_a_statistic_of_one_unit_is_that_unit():
    from metrics.units import Units

    one = Units(np.array([3]), np.array([4]), {"x": np.array([-2.0])})
    assert one.statistic("x") == -2.0
    assert Units(one.anchor, one.end, one.values, rmse=True).statistic("x") == 2.0
    assert np.isnan(Units(np.array([], int), np.array([], int),
                          {"x": np.array([])}).statistic("x"))


# ---- make mutate BASE=942ccd0: bench/report/tables/significance.py ------------------------------

def test_an_interval_with_an_end_missing_is_no_interval_and_digits_are_the_stats_own():
    from bench.report.tables.significance import Stat, shown, shown_interval, worse

    for broken in ((0.1, float("nan")), (float("nan"), 0.9), (0.1, float("inf"))):
        assert shown_interval(0.5, broken) is None
        assert shown(0.5, broken) == (0.5, 0.5, 0.5)  # the figure is its own interval
    # a figure that is not a number has no interval to print, whatever its ci says
    value, low, high = shown(float("nan"), (1.0, 2.0))
    assert np.isnan(value) and np.isnan(low) and np.isnan(high)
    assert not worse(Stat(float("nan"), (1.0, 2.0)), Stat(0.5, (0.4, 0.6)))
    assert worse(Stat(1.5, (1.0, 2.0)), Stat(0.5, (0.4, 0.6)))  # the control
    # a stat is printed with its own digits: 2 digits make 0.541 and 0.544 one figure
    assert Stat(0.12345, (0.1, 0.2), digits=2).shown() == (0.12, 0.1, 0.2)
    a, b = Stat(0.541, (0.541, 0.541), digits=2), Stat(0.544, (0.544, 0.544), digits=2)
    assert not worse(b, a)
    assert worse(Stat(0.544, (0.544, 0.544), digits=4), Stat(0.541, (0.541, 0.541), digits=4))


# ---- make mutate BASE=942ccd0: metrics/intervals.py ---------------------------------------------

def test_block_draws_of_one_frame_blocks_and_any_chunk_size_are_the_same_draws():
    """Blocks of one frame: each resample's indices are its block starts (n of them); the
    chunked indices are the whole draws for any chunk size, one resample at a time too."""
    from metrics.intervals import (
        block_counts,
        block_index_chunks,
        block_indices,
        block_starts,
    )

    n, reps = 23, 9
    starts = block_starts(n, 1, reps, seed=2)
    assert starts.shape == (reps, n)
    np.testing.assert_array_equal(block_indices(n, 1, reps, seed=2), starts)
    counts = block_counts(n, 1, reps, seed=2)
    assert counts.dtype == np.float64
    np.testing.assert_array_equal(counts[0], np.bincount(starts[0], minlength=n))
    for b in (1, 4):
        whole = block_indices(n, b, reps, seed=2)
        for chunk in (1, 2, 4, 100):
            parts = list(block_index_chunks(n, b, reps, seed=2, chunk=chunk))
            assert [c0 for c0, _ in parts] == list(range(0, reps, chunk))
            np.testing.assert_array_equal(np.concatenate([p for _, p in parts]), whole)


def test_paired_interval_edges_and_the_rmse_known_answer():
    n = 40
    anchor, end = np.arange(n), np.arange(n) + 1
    ones = np.ones(n)
    # random signs: RMSE 1 in any draw, a mean that varies from draw to draw
    alternating = np.where(np.random.default_rng(3).random(n) < 0.5, 1.0, -1.0)
    # RMSE: 3 - 1 in every resample, so the interval is that point; the mean would be about 3
    rms = paired_interval(n, anchor, end, 3.0 * ones, alternating, rmse=True, reps=60,
                          level=0.9)
    assert (rms.low, rms.high) == pytest.approx((2.0, 2.0), abs=1e-12)
    assert rms.level == 0.9 and rms.block_frames >= 10  # at least n / APE_MIN_BLOCKS
    mean = paired_interval(n, anchor, end, 3.0 * ones, alternating, reps=60)
    observed = 3.0 - alternating.mean()
    assert mean.low < observed < mean.high and mean.high - mean.low > 0.1
    # the default seed is 0; a given block is kept
    again = paired_interval(n, anchor, end, 3.0 * ones, alternating, reps=60, seed=0)
    assert (again.low, again.high) == (mean.low, mean.high)
    assert paired_interval(n, anchor, end, ones, alternating, reps=20, block=7).block_frames == 7
    # nothing to resample: NaN, no block, the units counted, the level kept
    for args in ((n, anchor[:0], end[:0], ones[:0], ones[:0]),  # no unit
                 (1, anchor[:1], end[:1], ones[:1], ones[:1]),  # one frame
                 (n, anchor, end, ones, np.where(anchor == 5, np.nan, 1.0)),  # B not finite
                 (n, anchor, end, np.where(anchor == 5, np.inf, 1.0), ones)):  # A not finite
        iv = paired_interval(*args, level=0.8, reps=20)
        assert np.isnan(iv.low) and np.isnan(iv.high), args[0]
        assert (iv.level, iv.block_frames, iv.n_independent) == (0.8, 0, len(args[1]))
    # two frames are enough to resample; one unit is resampled but gives no interval
    two = paired_interval(2, np.arange(2), np.arange(2) + 1, np.array([1.0, 2.0]),
                          np.zeros(2), reps=20)
    assert np.isfinite(two.low) and np.isfinite(two.high) and two.block_frames == 1
    one = paired_interval(10, np.array([3]), np.array([4]), np.ones(1), np.zeros(1), reps=20)
    assert np.isnan(one.low) and one.block_frames > 0 and one.n_independent == 1


def test_the_widening_steps_on_missing_ends_and_known_answers():
    from scipy import stats

    from metrics.intervals import contain, overlap_factor, scale_pivot, widen

    nan = float("nan")
    # an end that is not a number stays so, and the other end is not stretched
    low, high = contain(5.0, nan, 1.0)
    assert np.isnan(low) and high == 1.0
    low, high = contain(0.0, 1.0, nan)
    assert low == 1.0 and np.isnan(high)
    assert contain(5.0, 1.0, 2.0) == (1.0, 5.0) and contain(0.5, 1.0, 2.0) == (0.5, 2.0)
    for args in ((1.0, nan, 2.0, 5, 0.95), (1.0, 0.5, nan, 5, 0.95),
                 (1.0, 0.5, 1.5, 1, 0.95)):
        assert all(np.isnan(widen(*args))) and all(np.isnan(widen(*args, batch_means=True)))
    # t_{K-1} / z (and sqrt(K / (K - 1)) for batch means) about the figure
    f = stats.t.ppf(0.975, 4) / stats.norm.ppf(0.975)
    assert widen(1.0, 0.8, 1.1, 5, 0.95) == pytest.approx((1.0 - 0.2 * f, 1.0 + 0.1 * f))
    g = f * np.sqrt(5 / 4)
    assert widen(1.0, 0.8, 1.1, 5, 0.95, True) == pytest.approx((1.0 - 0.2 * g, 1.0 + 0.1 * g))
    # the scale pivot leaves a figure of 0 (no ratio) alone
    assert scale_pivot(0.0, 0.5, 1.0) == (0.5, 1.0)
    assert scale_pivot(2.0, 1.0, 4.0) == pytest.approx((1.0, 4.0))
    # overlap factor, blocks of one frame under units of one frame: a third of the variance lost
    k = 6
    expected = (stats.t.ppf(0.975, 1.5 * (k - 1)) / stats.norm.ppf(0.975)
                * np.sqrt(k / (k - 1)) / np.sqrt(1 - 1 / 3))
    assert overlap_factor(k, 0.95, 1.0, 1) == pytest.approx(expected, rel=1e-12)
    assert overlap_factor(k, 0.95, 4.0, 12) == pytest.approx(
        expected * np.sqrt(1 - 1 / 3) / np.sqrt(1 - 4 / 36), rel=1e-12)
    assert np.isnan(overlap_factor(1, 0.95, 1.0, 1))


def test_every_block_draw_defaults_to_the_same_seed_and_a_block_is_at_least_one_frame():
    """block_starts, block_counts, block_indices, block_index_chunks and block_sums draw the
    same resamples by default (seed 0), as their docstrings promise."""
    from metrics.intervals import (
        block_counts,
        block_frames,
        block_index_chunks,
        block_indices,
        block_starts,
        block_sums,
        widen_overlapping,
    )

    n, b, reps = 30, 4, 7
    np.testing.assert_array_equal(block_starts(n, b, reps), block_starts(n, b, reps, seed=0))
    np.testing.assert_array_equal(block_indices(n, b, reps), block_indices(n, b, reps, seed=0))
    counts = block_counts(n, b, reps)
    np.testing.assert_array_equal(counts, block_counts(n, b, reps, seed=0))
    chunks = np.concatenate([p for _, p in block_index_chunks(n, b, reps)])
    np.testing.assert_array_equal(chunks, block_indices(n, b, reps, seed=0))
    x = np.arange(n, dtype=float)
    np.testing.assert_allclose(block_sums(n, b, x, reps), counts @ x)
    # a unit under one frame: blocks of one frame
    assert block_frames(100, 1) == 1 and block_frames(100, 0.5) == 1
    assert block_frames(100, 7.2) == 8 and block_frames(10, 9) == 5
    nan = float("nan")
    for low, high in ((nan, 2.0), (0.5, nan)):
        assert all(np.isnan(widen_overlapping(1.0, low, high, 5, 0.95, 1.0, 3)))


def test_unit_intervals_with_nothing_to_resample_are_nan_with_no_block():
    from metrics.intervals import unit_intervals

    for n, anchor, end in ((30, np.array([], int), np.array([], int)),  # no unit
                           (1, np.array([0]), np.array([1]))):  # one frame
        out = unit_intervals(n, anchor, end, {"x": np.ones(anchor.size),
                                              "y": np.zeros(anchor.size)}, level=0.8, reps=10)
        assert set(out) == {"x", "y"}
        for iv in out.values():
            assert np.isnan(iv.low) and np.isnan(iv.high)
            assert (iv.level, iv.block_frames, iv.n_independent) == (0.8, 0, anchor.size)


def test_unit_intervals_follow_their_documented_steps_exactly():
    """The interval of a figure, recomposed from the module's documented steps (resample with
    the given block, percentile interval, scale pivot, widened for min(independent units,
    whole blocks) pieces and the units' median span, stretched to hold the figure, stopped
    at 0), for the mean and the RMSE, on values with a zero among them (still errors that
    cannot be negative)."""
    from metrics import intervals as iv

    n, span, b, reps = 60, 5, 8, 200
    anchor = np.arange(0, 55)
    end = anchor + span
    v = np.abs(np.random.default_rng(4).normal(1.0, 0.3, anchor.size))
    v[3] = 0.0
    n_ind = iv.independent_count(anchor, end)
    pieces = min(n_ind, n // b)
    assert (n_ind, pieces) == (11, 7)  # 60 / 8 frames is 7.5 blocks: 7 whole ones
    for rmse in (False, True):
        got = iv.unit_intervals(n, anchor, end, {"v": v}, rmse=rmse, reps=reps, seed=1,
                                block=b)["v"]
        stats = iv._resampled(n, b, reps, 1, anchor, [v], rmse)[0]
        lo, hi = iv._percentiles(stats, 0.95)
        x = float(np.sqrt(np.mean(v**2))) if rmse else float(np.mean(v))
        lo, hi = iv.scale_pivot(x, lo, hi)
        lo, hi = iv.contain(x, *iv.widen_overlapping(x, lo, hi, pieces, 0.95, float(span), b))
        assert (got.low, got.high) == pytest.approx((max(lo, 0.0), hi), rel=1e-12), rmse
        assert (got.block_frames, got.n_independent) == (b, n_ind)


def test_unit_intervals_without_an_interval_still_record_their_block():
    from metrics.intervals import unit_intervals

    # one unit: no interval, but the block it would have used
    one = unit_intervals(10, np.array([3]), np.array([4]), {"x": np.ones(1)}, level=0.8,
                         reps=10)["x"]
    assert np.isnan(one.low) and np.isnan(one.high)
    assert (one.level, one.n_independent) == (0.8, 1) and one.block_frames > 0
    # a value that is not a number: that quantity has none, the others do
    n = 40
    anchor = np.arange(n)
    out = unit_intervals(n, anchor, anchor + 1, {"bad": np.where(anchor == 7, np.nan, 1.0),
                                                  "good": np.linspace(0.5, 1.5, n)},
                         level=0.8, reps=30)
    assert np.isnan(out["bad"].low) and np.isnan(out["bad"].high)
    assert out["bad"].level == 0.8 and out["bad"].block_frames == out["good"].block_frames > 0
    assert np.isfinite(out["good"].low) and np.isfinite(out["good"].high)
    # two frames are enough to resample
    two = unit_intervals(2, np.arange(2), np.arange(2) + 1, {"x": np.array([1.0, 2.0])},
                         reps=20)["x"]
    assert np.isfinite(two.low) and np.isfinite(two.high) and two.block_frames == 1


def test_the_block_rule_for_single_frames_and_for_units_in_any_order():
    """Single-frame units: blocks of at least ceil(n / APE_MIN_BLOCKS) frames (times the
    BLOCK_FACTOR 1.5, for a figure and for a paired difference alike); units spanning 2 frames
    have no such floor. The units' order does not matter: the values are ordered by anchor."""
    from metrics.intervals import _percentiles, unit_intervals

    n = 42  # ceil(42 / 4) = 11, not 10
    anchor = np.arange(n)
    white = 1.0 + 0.1 * np.random.default_rng(8).normal(size=n)
    single = unit_intervals(n, anchor, anchor + 1, {"v": white}, reps=20)["v"]
    assert single.block_frames == 17  # ceil(1.5 * 11)
    paired = paired_interval(n, anchor, anchor + 1, white, white + 0.01, reps=20)
    assert paired.block_frames == 17  # the tables' rule: ceil(1.5 * 11)
    # single frames: the independent pieces are the whole blocks (42 // 17)
    assert (single.n_independent, single.level) == (2, 0.95)
    assert isinstance(single.n_independent, int)
    two = unit_intervals(n, anchor[:-1], anchor[:-1] + 2, {"v": white[:-1]}, reps=20)["v"]
    assert two.block_frames == 3  # ceil(1.5 * 2): the span, no floor
    assert two.n_independent == 21  # the chain 0, 2, ..., 40: not capped by blocks
    # a block is at most half the frames: 30 frames, units of 12 want 18
    long = unit_intervals(30, np.arange(18), np.arange(18) + 12,
                          {"v": np.linspace(1.0, 2.0, 18)}, reps=20)["v"]
    assert long.block_frames == 15
    # a given block that leaves one whole block: one independent piece, no interval
    lone = paired_interval(10, np.arange(10), np.arange(10) + 1, white[:10], white[:10] + 1,
                           reps=20, block=8)
    assert lone.n_independent == 1 and np.isnan(lone.low) and np.isnan(lone.high)
    # units given in another order: the same interval
    m = 300
    starts = np.arange(m - 10)
    walk = 1.0 + 0.1 * np.cumsum(np.random.default_rng(9).normal(size=starts.size)) / 10
    walk = np.abs(walk)
    ref = unit_intervals(m, starts, starts + 10, {"v": walk}, reps=50)["v"]
    perm = np.random.default_rng(10).permutation(starts.size)
    got = unit_intervals(m, starts[perm], starts[perm] + 10, {"v": walk[perm]}, reps=50)["v"]
    assert (got.block_frames, got.n_independent) == (ref.block_frames, ref.n_independent)
    assert ref.block_frames > 15  # the walk's correlation, not a shuffled series' (span 10)
    assert (got.low, got.high) == pytest.approx((ref.low, ref.high), rel=1e-9)
    assert _percentiles(np.array([2.0]), 0.95) == (2.0, 2.0)
    assert all(np.isnan(_percentiles(np.array([np.nan]), 0.95)))


# ---- make mutate BASE=942ccd0: bench/runs/sequence_identity.py ---------------------------------

def _h5(path, cut=None, scalar=1.0, rows=(0.0, 0.1)):
    import h5py

    with h5py.File(path, "w") as f:
        f.attrs["name"] = "data1"
        f.attrs["provenance"] = json.dumps({"frame_range": cut} if cut else {})
        f.create_dataset("frames/stamp", data=np.array(rows))
        f.create_dataset("extrinsic/scale", data=scalar)  # a scalar dataset
    return path


def test_the_sequence_key_and_tags_read_what_older_runs_and_stores_record(tmp_path):
    from bench.runs.sequence_identity import (
        content_digest,
        content_key,
        frames_text,
        sequence_tags,
    )

    # an older run: its frame range only in sequence.frame_range
    old = {"identity": {"store_sha256": "a" * 64},
           "sequence": {"frame_range": [10, 5], "frames": 5}}
    assert content_key(old) == ("a" * 64, (10, 5))
    assert frames_text(old) == "frames 10-14"
    assert frames_text({"sequence": {"frames": 1}}) == "frames 0-0"
    assert frames_text({"sequence": {}}) is None and frames_text({}) is None
    # the store's own cut, read from the store when the run did not record it
    store = _h5(tmp_path / "cut.h5", cut={"start": 60, "frames": 100, "stride": 2})
    run = {"identity": {"store_sha256": "b" * 64}, "sequence": {"store": str(store),
                                                                "frames": 3}}
    assert frames_text(run) == "frames 60-64, stride 2"
    # its content: read from the store when not recorded; recorded wins; else the SHA-256
    assert content_key(run) == (content_digest(store), None)
    recorded = {**run, "sequence": {**run["sequence"], "content_sha256": "c" * 64}}
    assert content_key(recorded) == ("c" * 64, None)
    gone = {"identity": {"store_sha256": "d" * 64}, "sequence": {"store": "nowhere.h5"}}
    assert content_key(gone) == ("d" * 64, None)
    assert content_key({"sequence": {"store": str(store)}}) is None  # nothing recorded
    # a scalar dataset and the first row count
    assert content_digest(_h5(tmp_path / "s1.h5", scalar=1.0)) != \
        content_digest(_h5(tmp_path / "s2.h5", scalar=2.0))
    assert content_digest(_h5(tmp_path / "r1.h5", rows=(0.0, 0.1))) != \
        content_digest(_h5(tmp_path / "r2.h5", rows=(0.5, 0.1)))

    def cfg(sha, frames=400, store="data1.h5", kind=None):
        seq = {"frames": frames, "store": store}
        if kind:
            seq["doppler_kind"] = kind
        return {"identity": {"store_sha256": sha}, "sequence": seq}

    # what tells contents apart, in its words: the store's file name; what is not recorded
    assert sequence_tags(["x", "x"], [cfg("a" * 64, store="a.h5"), cfg("b" * 64,
                                                                       store="b.h5")]) == \
        ["a.h5", "b.h5"]
    assert sequence_tags(["x", "x"], [cfg("a" * 64, store=None), cfg("b" * 64)]) == \
        ["store not recorded", "data1.h5"]
    assert sequence_tags(["x", "x"], [cfg("a" * 64), cfg("b" * 64, frames=None)]) == \
        ["frames 0-399", "frames not recorded"]
    assert sequence_tags(["x", "x"], [cfg("a" * 64), cfg("b" * 64, kind="ego-compensated")]) \
        == ["radial Doppler", "ego-compensated Doppler"]
    # two attributes needed: both, joined by ", "; a name with one content before another
    three = [cfg("a" * 64), cfg("b" * 64, frames=190), cfg("c" * 64, kind="ego-compensated")]
    assert sequence_tags(["one", "x", "x", "x"], [cfg("e" * 64), *three]) == \
        ["", "frames 0-399, radial Doppler", "frames 0-189, radial Doppler",
         "frames 0-399, ego-compensated Doppler"]


def test_malformed_records_are_ignored_not_trusted(tmp_path):
    """A store without provenance, a cut that is not a mapping, a content or SHA-256 that is
    empty or not text: each is as if not recorded; an empty tag adds nothing to a name."""
    import h5py

    from bench.runs.sequence_identity import content_key, frames_text, tagged

    bare = tmp_path / "bare.h5"
    with h5py.File(bare, "w") as f:
        f.create_dataset("frames/stamp", data=np.arange(3.0))
    assert frames_text({"sequence": {"store": str(bare), "frames": 3}}) == "frames 0-2"
    listed = _h5(tmp_path / "listed.h5")
    with h5py.File(listed, "a") as f:
        f.attrs["provenance"] = json.dumps({"frame_range": [60, 100]})
    assert frames_text({"sequence": {"store": str(listed), "frames": 3}}) == "frames 0-2"
    assert frames_text({"sequence": {"store_frame_range": [60, 100], "frames": 3}}) == \
        "frames 0-2"
    assert content_key({"identity": {"store_sha256": ""}, "sequence": {}}) is None
    assert content_key({"identity": {"store_sha256": "a" * 64},
                        "sequence": {"content_sha256": 123}}) == ("a" * 64, None)
    assert tagged("data1", "") == "data1" and tagged("data1", "x") == "data1 [x]"


def test_the_resampling_primitives_at_their_edges():
    from metrics.intervals import (
        _resampled,
        block_counts,
        block_start_chunks,
        block_starts,
        correlation_length,
        independent_count,
    )

    # a unit that starts where the previous one ends does not overlap it
    assert independent_count(np.array([0, 5, 10]), np.array([5, 10, 15])) == 3
    assert independent_count(np.array([0, 4, 10]), np.array([5, 10, 15])) == 2
    # too short or constant: blocks of one
    assert correlation_length(np.arange(7.0)) == 1
    assert correlation_length(np.full(50, 3.0)) == 1
    # chunks of one resample, and the default seed: the same draws as block_starts
    one = np.concatenate([s for _, s in block_start_chunks(20, 3, 5, seed=0, chunk=1)])
    np.testing.assert_array_equal(one, block_starts(20, 3, 5, seed=0))
    default = np.concatenate([s for _, s in block_start_chunks(20, 3, 5)])
    np.testing.assert_array_equal(default, one)
    # one unit drawn once is a resample (not "nothing drawn"); an RMSE below 1 stays so
    stats = _resampled(4, 1, 200, 0, np.array([0]), [np.array([2.0])], False)[0]
    drawn = block_counts(4, 1, 200, seed=0)[:, 0]
    assert np.array_equal(np.isfinite(stats), drawn > 0) and np.any(drawn == 1)
    assert np.all(stats[drawn > 0] == 2.0)
    rms = _resampled(10, 2, 50, 0, np.arange(10), [np.full(10, 0.5)], True)[0]
    np.testing.assert_allclose(rms, 0.5)
