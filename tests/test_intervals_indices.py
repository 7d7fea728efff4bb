"""metrics.intervals.block_indices: the frames of each circular block resample."""

from __future__ import annotations

import numpy as np

from metrics.intervals import block_counts, block_indices


def test_block_indices_are_wrapped_runs_of_the_block_length():
    n, b = 23, 5  # 23 = 4 full blocks + 3 frames of a fifth: the last block is cut
    idx = block_indices(n, b, reps=50, seed=3)
    assert idx.shape == (50, n) and idx.dtype.kind == "i"
    assert idx.min() >= 0 and idx.max() < n
    for row in idx:
        for k in range(0, n, b):
            run = row[k:k + b]
            np.testing.assert_array_equal(run, (run[0] + np.arange(len(run))) % n)
    # some block wraps around the end of the sequence (frame n - 1 followed by frame 0)
    steps = np.diff(idx.reshape(50, -1)[:, :b * 4].reshape(-1, b), axis=1)
    assert np.any(steps == 1 - n)


def test_block_indices_draw_what_block_counts_counts():
    n, b, reps = 40, 7, 30
    idx = block_indices(n, b, reps, seed=11)
    counts = np.stack([np.bincount(row, minlength=n) for row in idx])
    np.testing.assert_array_equal(counts, block_counts(n, b, reps, seed=11))
    assert not np.array_equal(idx, block_indices(n, b, reps, seed=12))


def test_every_frame_is_drawn_once_per_resample_on_average():
    # circular blocks: no frame is favoured, not even the first and last (a moving-block
    # bootstrap without wrapping draws the ends less often)
    n, b = 30, 8
    idx = block_indices(n, b, reps=4000, seed=0)
    mean = np.stack([np.bincount(row, minlength=n) for row in idx]).mean(axis=0)
    assert np.all(np.abs(mean - 1.0) < 0.1), mean
    assert block_indices(n, 1, reps=1, seed=0).shape == (1, n)
    # a block longer than the sequence: every resample is the whole circle from a random start
    whole = block_indices(n, 100, reps=3, seed=0)
    np.testing.assert_array_equal(whole[:, 1:], (whole[:, :-1] + 1) % n)


def test_block_sums_are_the_counts_times_the_per_frame_values():
    """The prefix-sum resampling (each resample costs its blocks) draws what block_counts
    counts: the same sums up to rounding, for a cut last block and blocks of half the frames."""
    from metrics.intervals import block_sums

    rng = np.random.default_rng(5)
    for n, b in ((103, 10), (40, 20), (9, 1), (50, 50)):
        x = rng.normal(size=(n, 3))
        got = block_sums(n, b, x, reps=40, seed=2)
        np.testing.assert_allclose(got, block_counts(n, b, 40, seed=2) @ x, rtol=0, atol=1e-10)
    y = rng.normal(size=103)
    assert not np.allclose(block_sums(103, 10, y, 5, seed=1), block_sums(103, 10, y, 5, seed=2))


def test_resampled_unit_statistics_equal_the_frame_count_weighting():
    """metrics.intervals._resampled from block sums equals the weighted statistic of the units
    by how often their anchor frame was drawn (the rule before the block sums), mean and RMSE,
    several units per anchor and anchors without units."""
    from metrics.intervals import _resampled

    rng = np.random.default_rng(8)
    n, b, reps = 300, 17, 60
    anchor = np.sort(rng.integers(0, n - 40, 500))  # the last 40 frames anchor nothing
    v = rng.exponential(size=500)
    w = block_counts(n, b, reps, seed=4)[:, anchor]
    for rmse in (False, True):
        (got,) = _resampled(n, b, reps, 4, anchor, [v], rmse)
        want = (w @ (v**2 if rmse else v)) / w.sum(axis=1)
        np.testing.assert_allclose(got, np.sqrt(want) if rmse else want, rtol=1e-12)


def test_block_starts_drawn_in_chunks_are_the_starts_drawn_at_once():
    """block_start_chunks (what block_sums and the APE kernel use, so that memory stays flat
    in the number of resamples) gives block_starts' draws: the generator draws row after row,
    whatever the chunk, also for chunks that do not divide the resamples."""
    from metrics.intervals import block_start_chunks, block_starts

    for n, b, reps, chunk in ((1999, 7, 250, 32), (40, 3, 33, 5), (10, 10, 9, 4)):
        parts = [s for _, s in block_start_chunks(n, b, reps, seed=6, chunk=chunk)]
        np.testing.assert_array_equal(np.concatenate(parts), block_starts(n, b, reps, seed=6))
        assert max(len(p) for p in parts) == min(chunk, reps)
