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
