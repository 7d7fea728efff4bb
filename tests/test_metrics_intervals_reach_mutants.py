"""metrics.intervals: a survivor of paired_interval's mutation run, killed with a case built for
it. The paired block is BLOCK_FACTOR times the largest ``block_frames`` of A's series, B's and
their difference's (its docstring's rule); a case where only the difference is strongly
correlated (A = v + noise, B = -v + noise: A - B = 2 v + noise, A + B = noise) shows that the
difference, not the sum, is the third series."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from metrics.intervals import BLOCK_FACTOR, block_frames, paired_interval


def test_the_paired_block_follows_the_difference_of_the_series():
    """(kills paired_interval 66: the block rule read a + b instead of a - b)"""
    n = 400
    anchor = np.arange(n - 2)
    end = anchor + 2  # units spanning two frames: no floor of n / APE_MIN_BLOCKS
    rng = np.random.default_rng(2)
    v = lfilter([1.0], [1.0, -0.95], rng.normal(0.0, 1.0, len(anchor)))  # AR(1), phi 0.95
    a = v + rng.normal(0.0, 3.0, len(anchor))
    b = -v + rng.normal(0.0, 3.0, len(anchor))
    blocks = {name: block_frames(n, 2.0, s) for name, s in
              (("a", a), ("b", b), ("a-b", a - b), ("a+b", a + b))}
    # the case tells the two rules apart: the difference is the most correlated series
    assert blocks["a-b"] > max(blocks["a"], blocks["b"], blocks["a+b"])
    want = min(math.ceil(BLOCK_FACTOR * blocks["a-b"]), n // 2)
    assert paired_interval(n, anchor, end, a, b, reps=50).block_frames == want
