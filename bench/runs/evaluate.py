"""Score an estimated trajectory against ground truth the way the paper does.

Ground truth limits the evaluation, not the sequence: the method runs on every scan, and only
the frames that have ground truth are scored.

- Which frames have GT (``loaders.gt.gt_for_frames``): when the ground truth is sampled at the scans
  (every GT stamp is a scan stamp, as in every store the loaders write), a frame is scored iff
  the GT has a pose at its stamp. Otherwise (GT at its own rate) the GT is interpolated at the
  scan stamps between two poses at most 3 median GT steps apart; a longer gap is never bridged.
- Relative errors pair scored frames only; APE is computed over the scored frames after the
  stated alignment (``Scoring.alignment``, default SE(3), with the orientation fallback of
  ``metrics.ape`` for an estimate that never moves); KITTI drift over ``kitti_lengths_m``
  (100-800 m) on the scored frames; the ego-velocity error over ``velocity_window_s`` windows
  (``metrics.velocity``: the window, not frame to frame, because a GT nearest-matched to the
  scans makes frame-to-frame GT velocities mostly artefact); for a method that reports its own
  Doppler velocity (``OdometryResult.velocity_mps``) its error too. Divergence looks at every
  estimated pose (a non-finite pose anywhere diverges).
- Timing covers every registered frame, with or without ground truth: ``time_ms`` (all
  per-frame work) and ``register_ms`` (the registration call alone) by the method's clock, and
  ``wall_ms`` (the elapsed time of the frame's work); see ``methods.base`` and
  ``methods.timing``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.runs.result import (
    ApeResult,
    KittiLength,
    KittiResult,
    RelativeError,
    VelocityResult,
    num,
)
from bench.runs.uncertainty import intervals
from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.trajectory import Trajectory
from methods.base import OdometryResult
from metrics import Alignment, is_diverged, kitti_drift, timing_stats
from metrics.ape import ape_with_errors
from metrics.kitti import KITTI_LENGTHS_M, STEP_FRAMES
from metrics.relative import (
    DEFAULT_LENGTHS_M,
    MetricError,
    SegmentErrors,
    relative_segments,
    stats_from_segments,
)
from metrics.units import (
    ape_units,
    kitti_units,
    own_velocity_units,
    relative_units,
    segment_units,
    velocity_units,
)
from metrics.velocity import DEFAULT_WINDOW_S, own_velocity_errors, velocity_errors


@dataclass(frozen=True)
class Scoring:
    """How a run is scored (part of its run key): the relative-error lengths [m], the KITTI
    lengths [m], the APE alignment (``metrics.Alignment`` spec) and the velocity window [s]."""

    lengths_m: tuple[float, ...] = DEFAULT_LENGTHS_M
    kitti_lengths_m: tuple[float, ...] = KITTI_LENGTHS_M
    alignment: str = "se3"
    velocity_window_s: float = DEFAULT_WINDOW_S

    def __post_init__(self) -> None:
        object.__setattr__(self, "lengths_m", tuple(float(x) for x in self.lengths_m))
        object.__setattr__(self, "kitti_lengths_m", tuple(float(x) for x in self.kitti_lengths_m))
        object.__setattr__(self, "alignment", Alignment.parse(self.alignment).name)


def fallbacks(result: OdometryResult) -> dict:
    """``frames_replaced`` / ``frames_unconverged`` of ``metrics.json``: registered frames
    (all but the first) whose step was replaced by the motion prior, and those that did not
    converge (and were not replaced)."""
    registered = result.frames[1:]
    replaced = sum(bool(getattr(f, "replaced", False)) for f in registered)
    unconverged = sum((not f.converged) and not getattr(f, "replaced", False)
                      for f in registered)
    return {"frames_replaced": int(replaced), "frames_unconverged": int(unconverged)}


def _num(x: float) -> float | None:
    return num(x)


def timing_part(times_ms: np.ndarray) -> dict:
    """``time_ms`` of ``metrics.json``: median, mean, p95 [ms] (None when nothing was timed)."""
    return {k: _num(v) for k, v in timing_stats(times_ms).items()}


def _velocity(stats, source: str, spread: dict | None = None) -> dict:
    return VelocityResult(
        source=source, window_s=stats.window_s, axis_mean_mps=[num(x) for x in
                                                               stats.axis_mean_mps],
        axis_rmse_mps=[num(x) for x in stats.axis_rmse_mps], norm_mean_mps=num(stats.norm_mean_mps),
        norm_rmse_mps=num(stats.norm_rmse_mps), n=stats.n, **(spread or {})).model_dump()


def _kitti(gt_s: np.ndarray, est_s: np.ndarray, scoring: Scoring) -> dict:
    """The KITTI part (lengths the path is too short for are listed in ``too_long``; the plan
    says so once per sequence, ``bench.runs.plan``)."""
    k = kitti_drift(gt_s, est_s, scoring.kitti_lengths_m, STEP_FRAMES)
    spread = intervals(kitti_units(gt_s, est_s, scoring.kitti_lengths_m, STEP_FRAMES),
                       len(gt_s), {"trans_pct": "trans_pct_ci",
                                   "rot_deg_per_100m": "rot_deg_per_100m_ci"})
    return KittiResult(
        lengths_m=list(scoring.kitti_lengths_m), step_frames=STEP_FRAMES,
        trans_pct=num(k.trans_pct), rot_deg_per_100m=num(k.rot_deg_per_100m), n=k.n,
        per_length=[KittiLength(length_m=L, trans_pct=num(t), rot_deg_per_100m=num(r), n=n)
                    for L, (t, r, n) in k.per_length.items()],
        too_long=list(k.too_long), **spread).model_dump()


def relative_part(gt_s: np.ndarray, est_s: np.ndarray, rel: dict,
                  segments: dict[float, SegmentErrors] | None = None) -> list[RelativeError]:
    """The relative-error figures with their intervals, from ``metrics.relative_errors`` of
    the scored frames' GT and estimate (``rel``: length -> its statistics; ``segments``:
    length -> the segments they summarise, when already computed)."""
    def units(length):
        if segments is not None and length in segments:
            return segment_units(segments[length])
        return relative_units(gt_s, est_s, length)

    return [RelativeError(
        length_m=length, rot_deg_mean=num(s.rot_deg_mean), rot_deg_median=num(s.rot_deg_median),
        rot_deg_rmse=num(s.rot_deg_rmse), trans_m_mean=num(s.trans_m_mean),
        trans_m_median=num(s.trans_m_median), trans_m_rmse=num(s.trans_m_rmse), n=int(s.n),
        **intervals(units(length), len(gt_s),
                    {"rot_deg": "rot_deg_mean_ci", "trans_m": "trans_m_mean_ci"}),
    ) for length, s in rel.items()]


def score(gt_poses: np.ndarray, est_poses: np.ndarray, times_ms: np.ndarray,
          lengths_m=DEFAULT_LENGTHS_M, scored: np.ndarray | None = None,
          name: str = "ground truth", timings: dict | None = None,
          scoring: Scoring | None = None, stamps: np.ndarray | None = None,
          velocity_mps: np.ndarray | None = None) -> dict:
    """The metric part of ``metrics.json`` (``bench.runs.result.RunResult``'s fields):
    diverged, relative_error, ape, kitti, velocity (with ``stamps``), velocity_own (with a
    method's own ``velocity_mps``), time_ms, frames_scored. ``scored`` (bool per frame,
    default all) selects the frames with ground truth; every error uses only them."""
    scoring = scoring or Scoring(tuple(lengths_m))
    est_poses = np.asarray(est_poses, dtype=np.float64)
    if scored is None:
        scored = np.ones(len(est_poses), dtype=bool)
    idx = np.flatnonzero(scored)
    if len(idx) == 0:
        raise DataError(f"{name}: no frame has ground truth; nothing to score")
    gt_s, est_s = np.asarray(gt_poses, dtype=np.float64)[idx], est_poses[idx]
    try:
        segments = relative_segments(gt_s, est_s, scoring.lengths_m)
    except MetricError as err:
        raise DataError(f"{name}: {err} ({len(idx)} frames with ground truth)") from err
    rel = {length: stats_from_segments(seg) for length, seg in segments.items()}
    diverged = bool(is_diverged(est_poses, rel))
    relative = [r.model_dump() for r in relative_part(gt_s, est_s, rel, segments)]
    finite = bool(np.all(np.isfinite(est_poses)))
    if finite and len(idx) >= 2:
        a, *errors = ape_with_errors(gt_s, est_s, alignment=scoring.alignment)
        ape_part = ApeResult(
            requested=scoring.alignment, alignment=a.alignment, trans_rmse_m=num(a.trans_rmse_m),
            trans_mean_m=num(a.trans_mean_m), trans_median_m=num(a.trans_median_m),
            trans_max_m=num(a.trans_max_m), rot_rmse_deg=num(a.rot_rmse_deg),
            rot_mean_deg=num(a.rot_mean_deg), scale=num(a.scale),
            **intervals(ape_units(gt_s, est_s, scoring.alignment, tuple(errors)), len(idx),
                        {"trans_m": "trans_rmse_m_ci", "rot_deg": "rot_rmse_deg_ci"}),
        ).model_dump()
    else:
        ape_part = ApeResult(requested=scoring.alignment, scale=None).model_dump()
    out = {
        "diverged": diverged,
        "relative_error": relative,
        "ape": ape_part,
        "kitti": _kitti(gt_s, est_s, scoring),
        **(timings if timings is not None else {"time_ms": timing_part(times_ms)}),
        "frames_scored": int(len(idx)),
    }
    if stamps is not None and len(idx) >= 2:
        st = np.asarray(stamps, dtype=np.float64)[idx]
        out["velocity"] = _velocity(
            velocity_errors(gt_s, est_s, st, scoring.velocity_window_s), "trajectory",
            intervals(velocity_units(gt_s, est_s, st, scoring.velocity_window_s), len(idx),
                      {"norm_mps": "norm_mean_mps_ci"}))
        if velocity_mps is not None:
            own = np.asarray(velocity_mps, dtype=np.float64)[idx]
            out["velocity_own"] = _velocity(
                own_velocity_errors(gt_s, st, own, scoring.velocity_window_s), "doppler",
                intervals(own_velocity_units(gt_s, st, own, scoring.velocity_window_s),
                          len(idx), {"norm_mps": "norm_mean_mps_ci"}))
    return out


@dataclass(frozen=True)
class Evaluation:
    """What a run is scored with: GT at the stamps of the frames that have it
    (``T_world_sensor``; None without GT) and the metric part of ``metrics.json``
    (``RunResult``'s fields: diverged, relative_error, ape, kitti, velocity, time_ms ...)."""

    gt: Trajectory | None
    metrics: dict
    scored: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))


def evaluate_run(ground_truth: Trajectory | None, result: OdometryResult,
                 lengths_m=DEFAULT_LENGTHS_M, name: str = "ground truth",
                 scoring: Scoring | None = None,
                 excluded: np.ndarray | None = None) -> Evaluation:
    """Score an odometry result against a sequence's ground truth (the one entry point the
    job runner uses). Without ground truth only the timing is filled in. ``excluded`` (bool
    per frame): frames registered but never scored (those ``bench calibrate`` estimated on),
    chosen by index whatever the GT's rate."""
    scoring = scoring or Scoring(tuple(lengths_m))
    times = np.array([f.time_ms for f in result.frames], dtype=np.float64)
    timings = {key: timing_part(np.array([getattr(f, key) for f in result.frames],
                                         dtype=np.float64))
               for key in ("time_ms", "register_ms", "wall_ms")}
    timings |= fallbacks(result)
    if ground_truth is None:
        return Evaluation(None, {"diverged": None, "relative_error": [], "ape": None,
                                 **timings, "frames_scored": 0})
    stamps = np.asarray(result.stamps, dtype=np.float64)
    gt_poses, scored = gt_for_frames(ground_truth, stamps, name=name)
    if excluded is not None:
        scored = scored & ~np.asarray(excluded, dtype=bool)
    metrics = score(gt_poses, result.poses, times, scored=scored, name=name, timings=timings,
                    scoring=scoring, stamps=stamps,
                    velocity_mps=getattr(result, "velocity_mps", None))
    return Evaluation(Trajectory(stamps[scored], gt_poses[scored]), metrics, scored)

