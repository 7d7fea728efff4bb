"""Score an estimated trajectory against ground truth the way the paper does.

Ground truth limits the evaluation, not the sequence: the method runs on every scan, and only
the frames that have ground truth are scored.

- Which frames have GT (``loaders.gt.gt_for_frames``): when the ground truth is sampled at the scans
  (every GT stamp is a scan stamp, as in every store the loaders write), a frame is scored iff
  the GT has a pose at its stamp. Otherwise (GT at its own rate) the GT is interpolated at the
  scan stamps between two poses at most 3 median GT steps apart; a longer gap is never bridged.
- Relative errors pair scored frames only; APE is computed over the scored frames (SE(3)
  alignment, with the orientation fallback of ``metrics.ape`` for an estimate that never
  moves); divergence looks at every estimated pose (a non-finite pose anywhere diverges).
- Timing covers every registered frame, with or without ground truth: ``time_ms`` (all
  per-frame work) and ``register_ms`` (the registration call alone) by the method's clock, and
  ``wall_ms`` (the elapsed time of the frame's work); see ``methods.base`` and
  ``methods.timing``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.trajectory import Trajectory
from methods.base import OdometryResult
from metrics import ape, is_diverged, relative_errors, timing_stats
from metrics.relative import DEFAULT_LENGTHS_M, MetricError


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def timing_part(times_ms: np.ndarray) -> dict:
    """``time_ms`` of ``metrics.json``: median, mean, p95 [ms] (None when nothing was timed)."""
    return {k: _num(v) for k, v in timing_stats(times_ms).items()}


def score(gt_poses: np.ndarray, est_poses: np.ndarray, times_ms: np.ndarray,
          lengths_m=DEFAULT_LENGTHS_M, scored: np.ndarray | None = None,
          name: str = "ground truth", timings: dict | None = None) -> dict:
    """The metric part of ``metrics.json``: diverged, relative_error, ape, time_ms,
    frames_scored. ``scored`` (bool per frame, default all) selects the frames with ground
    truth; relative errors and APE use only them."""
    est_poses = np.asarray(est_poses, dtype=np.float64)
    if scored is None:
        scored = np.ones(len(est_poses), dtype=bool)
    idx = np.flatnonzero(scored)
    if len(idx) == 0:
        raise DataError(f"{name}: no frame has ground truth; nothing to score")
    gt_s, est_s = np.asarray(gt_poses, dtype=np.float64)[idx], est_poses[idx]
    try:
        rel = relative_errors(gt_s, est_s, lengths_m)
    except MetricError as err:
        raise DataError(f"{name}: {err} ({len(idx)} frames with ground truth)") from err
    diverged = bool(is_diverged(est_poses, rel))
    relative = {
        f"{length:g}": {
            "rot_deg_mean": _num(s.rot_deg_mean), "trans_m_mean": _num(s.trans_m_mean),
            "rot_deg_median": _num(s.rot_deg_median), "trans_m_median": _num(s.trans_m_median),
            "n": int(s.n),
        }
        for length, s in rel.items()
    }
    if np.all(np.isfinite(est_poses)) and len(idx) >= 2:
        a = ape(gt_s, est_s, alignment="se3")
        ape_dict = {"trans_rmse_m": _num(a.trans_rmse_m), "rot_rmse_deg": _num(a.rot_rmse_deg),
                    "alignment": a.alignment}
    else:
        ape_dict = {"trans_rmse_m": None, "rot_rmse_deg": None, "alignment": None}
    return {
        "diverged": diverged,
        "relative_error": relative,
        "ape": ape_dict,
        **(timings if timings is not None else {"time_ms": timing_part(times_ms)}),
        "frames_scored": int(len(idx)),
    }


@dataclass(frozen=True)
class Evaluation:
    """What a run is scored with: GT at the stamps of the frames that have it
    (``T_world_sensor``; None without GT) and the metric part of ``metrics.json`` (diverged,
    relative_error, ape, time_ms, frames_scored)."""

    gt: Trajectory | None
    metrics: dict


def evaluate_run(ground_truth: Trajectory | None, result: OdometryResult,
                 lengths_m=DEFAULT_LENGTHS_M, name: str = "ground truth",
                 excluded: np.ndarray | None = None) -> Evaluation:
    """Score an odometry result against a sequence's ground truth (the one entry point the
    job runner uses). Without ground truth only the timing is filled in. ``excluded`` (bool
    per frame): frames registered but never scored (those ``bench calibrate`` estimated on),
    chosen by index whatever the GT's rate."""
    times = np.array([f.time_ms for f in result.frames], dtype=np.float64)
    timings = {key: timing_part(np.array([getattr(f, key) for f in result.frames],
                                         dtype=np.float64))
               for key in ("time_ms", "register_ms", "wall_ms")}
    if ground_truth is None:
        return Evaluation(None, {"diverged": None, "relative_error": {}, "ape": None,
                                 **timings, "frames_scored": 0})
    stamps = np.asarray(result.stamps, dtype=np.float64)
    gt_poses, scored = gt_for_frames(ground_truth, stamps, name=name)
    if excluded is not None:
        scored = scored & ~np.asarray(excluded, dtype=bool)
    metrics = score(gt_poses, result.poses, times, lengths_m, scored, name, timings)
    return Evaluation(Trajectory(stamps[scored], gt_poses[scored]), metrics)
