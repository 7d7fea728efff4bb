"""Score an estimated trajectory against ground truth the way the paper does."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from loaders.errors import DataError
from loaders.scan import Trajectory
from methods.base import OdometryResult
from metrics import ape, is_diverged, relative_errors, timing_stats
from metrics.relative import DEFAULT_LENGTHS_M, MetricError


def gt_at_stamps(gt: Trajectory, stamps: np.ndarray, tolerance_s: float = 1e-4,
                 name: str = "ground truth") -> np.ndarray:
    """GT poses (N, 4, 4) at the scan stamps: exact stamp matches when every scan has one
    (within ``tolerance_s``), else SE(3) interpolation with a max gap of 3 median GT steps."""
    idx = np.searchsorted(gt.stamps, stamps).clip(0, len(gt) - 1)
    prev = (idx - 1).clip(0)
    best = np.where(np.abs(gt.stamps[prev] - stamps) < np.abs(gt.stamps[idx] - stamps), prev, idx)
    if np.all(np.abs(gt.stamps[best] - stamps) <= tolerance_s):
        return gt.poses[best]
    step = float(np.median(np.diff(gt.stamps))) if len(gt) > 1 else math.inf
    return gt.interpolate(stamps, max_gap_s=3 * step, name=name).poses


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def score(gt_poses: np.ndarray, est_poses: np.ndarray, times_ms: np.ndarray,
          lengths_m=DEFAULT_LENGTHS_M) -> dict:
    """The metric part of ``metrics.json``: diverged, relative_error, ape, time_ms."""
    try:
        rel = relative_errors(gt_poses, est_poses, lengths_m)
    except MetricError as err:
        raise DataError(str(err)) from err
    diverged = bool(is_diverged(est_poses, rel))
    relative = {
        f"{length:g}": {
            "rot_deg_mean": _num(s.rot_deg_mean), "trans_m_mean": _num(s.trans_m_mean),
            "rot_deg_median": _num(s.rot_deg_median), "trans_m_median": _num(s.trans_m_median),
            "n": int(s.n),
        }
        for length, s in rel.items()
    }
    if np.all(np.isfinite(est_poses)):
        a = ape(gt_poses, est_poses, alignment="se3")
        ape_dict = {"trans_rmse_m": _num(a.trans_rmse_m), "rot_rmse_deg": _num(a.rot_rmse_deg)}
    else:
        ape_dict = {"trans_rmse_m": None, "rot_rmse_deg": None}
    t = timing_stats(times_ms)
    return {
        "diverged": diverged,
        "relative_error": relative,
        "ape": ape_dict,
        "time_ms": {k: _num(v) for k, v in t.items()},
    }


@dataclass(frozen=True)
class Evaluation:
    """What a run is scored with: GT at the scan stamps (``T_world_sensor``; None without GT)
    and the metric part of ``metrics.json`` (diverged, relative_error, ape, time_ms)."""

    gt: Trajectory | None
    metrics: dict


def evaluate_run(ground_truth: Trajectory | None, result: OdometryResult,
                 lengths_m=DEFAULT_LENGTHS_M, name: str = "ground truth") -> Evaluation:
    """Score an odometry result against a sequence's ground truth (the one entry point the
    job runner uses)."""
    times = np.array([f.time_ms for f in result.frames])
    if ground_truth is None:
        return Evaluation(None, {"diverged": None, "relative_error": {}, "ape": None,
                                 "time_ms": None})
    gt_poses = gt_at_stamps(ground_truth, result.stamps, name=name)
    return Evaluation(Trajectory(result.stamps, gt_poses),
                      score(gt_poses, result.poses, times, lengths_m))
