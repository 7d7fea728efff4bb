"""An external trajectory brought to a store's scan stamps (``bench score``).

- Clock: ``est_stamp + time_offset_s = sensor clock`` (the ground truth's convention,
  ``loaders.gt``).
- Frame: the estimate gives ``T_world_frame`` of its own body frame; ``T_frame_sensor`` (the
  sensor in that frame; identity when the poses are the sensor's) moves it to the sensor the
  ground truth is given for: ``T_world_sensor = T_world_frame @ T_frame_sensor``. The world
  frame does not matter (relative errors ignore it, APE aligns it).
- Association: a scan whose stamp is within ``tolerance_s`` of an estimated pose takes that
  pose as it is ("matched"); any other scan inside the estimate's span takes the SE(3)
  interpolation (slerp + linear) of the two neighbouring poses when they are at most
  ``max_gap_s`` apart ("interpolated"); the others have no estimate and are not scored.
- No scan with an estimate is a ``DataError`` naming both files and both time spans, with the
  time offset to try (``loaders.gt.offset_hint``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from loaders.errors import DataError
from loaders.gt import MAX_GAP_STEPS, STAMP_TOLERANCE_S, nearest_indices, offset_hint, time_span
from loaders.se3 import interpolate_poses
from loaders.trajectory import Trajectory


@dataclass(frozen=True)
class Matched:
    """``T_world_sensor`` (N, 4, 4) estimated at each of the N scans (NaN where none) and the
    association's report (counts, tolerance, gap, offset)."""

    poses: np.ndarray
    covered: np.ndarray
    matched: np.ndarray
    report: dict = field(default_factory=dict)


def default_max_gap_s(stamps: np.ndarray) -> float:
    """``MAX_GAP_STEPS`` median steps of the estimate (as for ground truth at its own rate)."""
    steps = np.diff(np.asarray(stamps, dtype=np.float64))
    return float(MAX_GAP_STEPS * np.median(steps)) if len(steps) else 0.0


def match_to_scans(est: Trajectory, scan_stamps: np.ndarray, *, time_offset_s: float = 0.0,
                   tolerance_s: float = STAMP_TOLERANCE_S, max_gap_s: float | None = None,
                   T_frame_sensor: np.ndarray | None = None, est_name: str = "estimate",
                   scan_name: str = "scans") -> Matched:
    """The estimate at the scan stamps (see the module docstring); ``max_gap_s`` None:
    ``default_max_gap_s``."""
    if tolerance_s < 0:
        raise DataError(f"--tolerance {tolerance_s}: expected a tolerance >= 0 s")
    q = np.asarray(scan_stamps, dtype=np.float64)
    s = np.asarray(est.stamps, dtype=np.float64) + float(time_offset_s)
    poses = np.asarray(est.poses, dtype=np.float64)
    if T_frame_sensor is not None:
        poses = poses @ T_frame_sensor
    gap = default_max_gap_s(s) if max_gap_s is None else float(max_gap_s)
    near, dist = nearest_indices(s, q)
    matched = dist <= tolerance_s
    out = np.full((len(q), 4, 4), np.nan)
    out[matched] = poses[near[matched]]
    inside = Trajectory(s, poses).coverage_mask(q, gap) if len(s) >= 2 else \
        np.zeros(len(q), dtype=bool)
    interp = inside & ~matched
    if interp.any():
        out[interp] = interpolate_poses(s, poses, np.clip(q[interp], s[0], s[-1]))
    covered = matched | interp
    report = {"time_offset_s": float(time_offset_s), "tolerance_s": float(tolerance_s),
              "max_gap_s": gap, "scans": int(len(q)), "poses": int(len(s)),
              "matched": int(matched.sum()), "interpolated": int(interp.sum()),
              "covered": int(covered.sum())}
    if not covered.any():
        raise DataError(
            f"{est_name} does not overlap the scans of {scan_name}: the estimate spans "
            f"{time_span(s)} (offset {time_offset_s:+.3f} s applied), the {len(q)} scans span "
            f"{time_span(q)} (a scan needs a pose within {tolerance_s:g} s, or two poses at most "
            f"{gap:g} s apart around it); different clocks? "
            + offset_hint(s, q).replace("gt_stamp", "est_stamp")
            .replace("the ground truth's clock", "the estimate's clock"))
    return Matched(out, covered, matched, report)
