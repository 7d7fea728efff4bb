"""The uncertainty of a rotation fitted to a sequence of frames: a circular block bootstrap of
the frames (``metrics.intervals.block_indices``) with the whole fit - outlier cut included -
redone on every resample, shared by both calibration estimates (``bench.data.calibration``:
Doppler ego velocity and road plane; ``bench.data.hand_eye``: a geometric odometry).

Consecutive frames are not independent (the GT velocity is a central difference over three
frames, a road's bank and an odometry's drift change slowly), so frames are drawn in blocks.
The block length [frames] is the largest of a floor the estimate declares (the frames one
measurement spans, or a stated minimum duration) and the automatic block length of Politis &
White (``metrics.intervals.correlation_length``) of every per-frame residual series the fit
uses (one series per fitted angle, ordered by frame); it is at most half the frames, and when
that cap binds the result says so (two blocks cannot show an error that changes more slowly).

The interval of each angle is the percentile interval of the resampled angles (95 % by
default); ``sd_deg`` is their standard deviation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from metrics.intervals import block_indices, correlation_length

#: the confidence level of the calibration intervals
LEVEL = 0.95


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

    def describe(self, resamples: int, refit: str = "each refitted") -> str:
        text = (f"circular block bootstrap, block {self.frames} frames ({self.seconds:.1f} s), "
                f"{resamples} resamples, {refit}")
        if self.capped:
            text += (f"; the rule asked for {self.wanted} frames, more than half of them: too "
                     "few blocks, the interval may be too narrow")
        return text


def choose_block(n_frames: int, period_s: float, series: list[np.ndarray],
                 floor_frames: int = 1) -> BlockChoice:
    """The block length for ``n_frames`` frames of period ``period_s``: the largest of
    ``floor_frames`` and the correlation length of each residual series, at most
    ``n_frames // 2`` (at least 1)."""
    lengths = tuple(int(correlation_length(s)) for s in series if len(s))
    wanted = max([int(floor_frames), 1, *lengths])
    frames = int(max(1, min(wanted, n_frames // 2)))
    return BlockChoice(frames, frames * float(period_s), wanted, lengths)


@dataclass(frozen=True)
class AngleSpread:
    """Per angle (roll, pitch, yaw): bootstrap standard deviation and ``level`` percentile
    interval [deg] over the resamples that could be fitted."""

    sd_deg: np.ndarray
    low_deg: np.ndarray
    high_deg: np.ndarray
    level: float
    resamples: int


def bootstrap_angles(n_frames: int, block: int, reps: int, seed: int,
                     fit: Callable[[np.ndarray], np.ndarray | None],
                     level: float = LEVEL) -> AngleSpread:
    """Refit on ``reps`` circular block resamples of the frames 0 .. n_frames - 1: ``fit``
    takes the drawn frame indices (with repeats) and returns (roll, pitch, yaw) [deg], or None
    when the resample cannot be fitted (it is left out)."""
    nan = np.full(3, np.nan)
    if reps < 2 or n_frames < 2:
        return AngleSpread(nan, nan, nan, level, 0)
    samples = [fit(idx) for idx in block_indices(n_frames, block, reps, seed)]
    samples = np.array([s for s in samples if s is not None]).reshape(-1, 3)
    if len(samples) < 2:
        return AngleSpread(nan, nan, nan, level, len(samples))
    alpha = 0.5 * (1.0 - level)
    low, high = np.quantile(samples, [alpha, 1.0 - alpha], axis=0)
    return AngleSpread(samples.std(axis=0, ddof=1), low, high, level, len(samples))


def residual_series(fitted: np.ndarray, target: np.ndarray, axes: np.ndarray,
                    order: np.ndarray) -> list[np.ndarray]:
    """Per-row small-angle residuals [rad] of unit-vector pairs under the fit: the components
    of ``fitted x target`` (the rotation taking the fitted vector to its target) on each flagged
    axis, rows ordered by ``order`` (their frame)."""
    if len(fitted) == 0:
        return []
    r = np.cross(fitted, target)[np.argsort(order, kind="stable")]
    return [r[:, k] for k in range(3) if axes[k]]

