"""The uncertainty of a rotation fitted to a sequence of frames: a circular block bootstrap of
the frames (``metrics.intervals.block_indices``) with the whole fit - outlier cut included -
redone on every resample, shared by both calibration estimates (``bench.data.calibration.estimate``:
Doppler ego velocity and road plane; ``bench.data.calibration.hand_eye``: a geometric odometry).

Consecutive frames are not independent (the GT velocity is a central difference over three
frames, a road's bank and an odometry's drift change slowly), so frames are drawn in blocks.
The block length [frames] is the larger of a floor the estimate declares (the frames one
measurement spans, or a stated minimum duration) and ``BLOCKS_PER_CORRELATION`` times the
longest automatic block length of Politis & White (``metrics.intervals.correlation_length``)
of the per-frame residual series the fit uses (one series per fitted angle, ordered by frame);
at most half the frames, and when that cap binds the result says so.

A range of 10 s holds only a few such blocks, so the bootstrap standard deviation is itself
uncertain and biased low. The interval is therefore a t interval: ``estimate +- t(k - 1) * sd *
sqrt(n / (n - b))`` with ``k = n / b`` blocks (the degrees of freedom of a batch-means variance)
and the circular bootstrap's ``1 - b / n`` variance deficit undone. On simulated drives with
AR(1) per-frame errors (lag-one correlation 0.8; tests/test_calibration_uncertainty.py) the
Politis-White block with percentile intervals covered the truth 65-82 % of the time; twice that
block with the t interval about 95 %.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.stats import t as student_t

from metrics.intervals import block_indices, correlation_length

#: the confidence level of the calibration intervals
LEVEL = 0.95
#: the block is this many times the longest Politis-White length of the residuals
BLOCKS_PER_CORRELATION = 2


@dataclass(frozen=True)
class BlockChoice:
    """The block length used [frames] and [s], the one the rule asked for before the cap at
    half the frames, and the per-series correlation lengths it came from."""

    frames: int
    seconds: float
    wanted: int
    correlation: tuple[int, ...]

    @property
    def capped(self) -> bool:
        return self.wanted > self.frames

    def dof(self, n_frames: int) -> float:
        """Degrees of freedom of the interval: blocks in the range minus one (at least 1)."""
        return max(1.0, n_frames / self.frames - 1.0)

    def describe(self, resamples: int, n_frames: int, refit: str = "each refitted") -> str:
        text = (f"circular block bootstrap, block {self.frames} frames ({self.seconds:.1f} s), "
                f"{resamples} resamples, {refit}; intervals estimate +- t * sd with "
                f"{self.dof(n_frames):.1f} degrees of freedom")
        if self.capped:
            text += (f"; the rule asked for {self.wanted} frames, more than half of them: too "
                     "few blocks, even this interval may be too narrow")
        return text


def choose_block(n_frames: int, period_s: float, series: list[np.ndarray],
                 floor_frames: int = 1) -> BlockChoice:
    """The block length for ``n_frames`` frames of period ``period_s``: the largest of
    ``floor_frames`` and ``BLOCKS_PER_CORRELATION`` x the correlation length of each residual
    series, at most ``n_frames // 2`` (at least 1)."""
    lengths = tuple(int(correlation_length(s)) for s in series if len(s))
    wanted = max([int(floor_frames), 1, *(BLOCKS_PER_CORRELATION * n for n in lengths)])
    frames = int(max(1, min(wanted, n_frames // 2)))
    return BlockChoice(frames, frames * float(period_s), wanted, lengths)


@dataclass(frozen=True)
class AngleSpread:
    """Per angle (roll, pitch, yaw): bootstrap standard deviation and the ``level`` t interval
    [deg] around the estimate, over the resamples that could be fitted."""

    sd_deg: np.ndarray
    low_deg: np.ndarray
    high_deg: np.ndarray
    level: float
    resamples: int


def bootstrap_angles(n_frames: int, block: BlockChoice, reps: int, seed: int,
                     fit: Callable[[np.ndarray], np.ndarray | None], estimate_deg: np.ndarray,
                     level: float = LEVEL) -> AngleSpread:
    """Refit on ``reps`` circular block resamples of the frames 0 .. n_frames - 1: ``fit``
    takes the drawn frame indices (with repeats) and returns (roll, pitch, yaw) [deg], or None
    when the resample cannot be fitted (it is left out). The interval: ``estimate_deg +- t *
    sd * sqrt(n / (n - b))`` (see the module docstring)."""
    nan = np.full(3, np.nan)
    if reps < 2 or n_frames < 2:
        return AngleSpread(nan, nan, nan, level, 0)
    samples = [fit(idx) for idx in block_indices(n_frames, block.frames, reps, seed)]
    samples = np.array([s for s in samples if s is not None]).reshape(-1, 3)
    if len(samples) < 2:
        return AngleSpread(nan, nan, nan, level, len(samples))
    sd = samples.std(axis=0, ddof=1)
    deficit = n_frames / max(n_frames - block.frames, 1)
    half = student_t.ppf(0.5 + 0.5 * level, block.dof(n_frames)) * sd * np.sqrt(deficit)
    est = np.asarray(estimate_deg, dtype=float)
    return AngleSpread(sd, est - half, est + half, level, len(samples))


def residual_series(fitted: np.ndarray, target: np.ndarray, axes: np.ndarray,
                    order: np.ndarray) -> list[np.ndarray]:
    """Per-row small-angle residuals [rad] of unit-vector pairs under the fit: the components
    of ``fitted x target`` (the rotation taking the fitted vector to its target) on each flagged
    axis, rows ordered by ``order`` (their frame)."""
    if len(fitted) == 0:
        return []
    r = np.cross(fitted, target)[np.argsort(order, kind="stable")]
    return [r[:, k] for k in range(3) if axes[k]]

