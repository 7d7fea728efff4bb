"""Each metric's errors as *units* anchored at frames, for intervals and paired comparisons.

A figure of a table is a statistic (a mean, or for APE an RMSE) over units: relative-error
segments (``metrics.relative``), KITTI segments (``metrics.kitti``), aligned per-frame errors
(``metrics.ape``), velocity windows (``metrics.velocity``). Each unit starts at frame
``anchor`` and ends at frame ``end`` (``anchor + 1`` for a single frame); ``metrics.intervals``
resamples blocks of frames and takes every unit whose anchor was drawn. APE, a figure of the
accumulated drift, is resampled by its frame-to-frame errors instead
(``metrics.drift_intervals``; ``Units.drift``). Two runs scored on the
same frames have the same units, so their per-unit differences can be paired.

The statistic of each ``Units`` reproduces the figure of the metric's summary exactly (tested):
``mean`` of ``rot_deg`` / ``trans_m`` is the relative error's mean, ``rmse`` of APE's
``trans_m`` / ``rot_deg`` its RMSE, the mean of KITTI's ``trans_pct`` / ``rot_deg_per_100m``
its drift, the mean of velocity's ``norm_mps`` its mean error norm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from metrics.ape import ape_errors
from metrics.drift_intervals import Drift
from metrics.kitti import KITTI_LENGTHS_M, STEP_FRAMES, kitti_segments
from metrics.relative import SegmentErrors, segment_errors
from metrics.velocity import DEFAULT_WINDOW_S, own_velocity_series, velocity_series


@dataclass(frozen=True)
class Units:
    """Per-unit errors of one metric: unit k starts at frame ``anchor[k]`` and ends at frame
    ``end[k]``; ``values`` maps a quantity to its per-unit values; the statistic is the RMSE
    when ``rmse`` else the mean. ``drift`` (APE): the figure's interval comes from resampling
    the estimate's frame-to-frame errors, not the units."""

    anchor: np.ndarray
    end: np.ndarray
    values: dict[str, np.ndarray]
    rmse: bool = False
    drift: Drift | None = None

    def statistic(self, key: str) -> float:
        v = self.values[key]
        if v.size == 0:
            return float("nan")
        return float(np.sqrt(np.mean(v**2))) if self.rmse else float(np.mean(v))

    def __len__(self) -> int:
        return int(self.anchor.size)


def relative_units(gt_poses: np.ndarray, est_poses: np.ndarray, length_m: float,
                   tolerance: float = 0.2) -> Units:
    """The relative-error segments of ``length_m``: ``rot_deg``, ``trans_m``."""
    return segment_units(segment_errors(gt_poses, est_poses, length_m, tolerance))


def segment_units(seg: SegmentErrors) -> Units:
    """Units of segments already computed (``metrics.relative.segment_errors``)."""
    return Units(seg.start_idx, seg.end_idx, {"rot_deg": seg.rot_deg, "trans_m": seg.trans_m})


def kitti_units(gt_poses: np.ndarray, est_poses: np.ndarray, lengths_m=KITTI_LENGTHS_M,
                step_frames: int = STEP_FRAMES) -> Units:
    """Every KITTI segment of ``lengths_m``: ``trans_pct`` [%] and ``rot_deg_per_100m``."""
    seg = kitti_segments(gt_poses, est_poses, lengths_m, step_frames)
    return Units(seg.start_idx, seg.end_idx,
                 {"trans_pct": 100.0 * seg.trans_per_m,
                  "rot_deg_per_100m": 100.0 * np.degrees(seg.rot_rad_per_m)})


def ape_units(gt_poses: np.ndarray, est_poses: np.ndarray, alignment="se3",
              errors: tuple[np.ndarray, np.ndarray] | None = None) -> Units:
    """Per-frame APE after ``alignment`` (fitted once on the whole trajectory): ``trans_m``,
    ``rot_deg``; the statistic is the RMSE; resampled by its drift. ``errors``: the per-frame
    (translation, rotation) errors when already computed (``metrics.ape.ape_with_errors``)."""
    trans, rot = errors if errors is not None else ape_errors(gt_poses, est_poses, alignment)
    anchor = np.arange(trans.size)
    return Units(anchor, anchor + 1, {"trans_m": trans, "rot_deg": rot}, rmse=True,
                 drift=Drift(gt_poses, est_poses, alignment))


def velocity_units(gt_poses: np.ndarray, est_poses: np.ndarray, stamps: np.ndarray,
                   window_s: float = DEFAULT_WINDOW_S) -> Units:
    """The velocity windows: ``norm_mps``, the norm of each window's velocity error, and
    ``x_abs_mps`` / ``y_abs_mps`` / ``z_abs_mps``, its absolute value per axis."""
    series = velocity_series(gt_poses, est_poses, stamps, window_s)
    err = series.error_mps
    return Units(series.start_idx, series.end_idx,
                 {"norm_mps": np.linalg.norm(err, axis=1), "x_abs_mps": np.abs(err[:, 0]),
                  "y_abs_mps": np.abs(err[:, 1]), "z_abs_mps": np.abs(err[:, 2])})


def own_velocity_units(gt_poses: np.ndarray, stamps: np.ndarray, est_mps: np.ndarray,
                       window_s: float = DEFAULT_WINDOW_S) -> Units:
    """A method's own velocity estimate per frame against the GT window around it:
    ``norm_mps``."""
    series = own_velocity_series(gt_poses, stamps, est_mps, window_s)
    return Units(series.start_idx, np.maximum(series.end_idx, series.start_idx + 1),
                 {"norm_mps": np.linalg.norm(series.error_mps, axis=1)})
