"""An external trajectory brought to a store's scan stamps (``bench score``).

- Clock: ``est_stamp + time_offset_s = sensor clock`` (the ground truth's convention,
  ``loaders.gt``).
- Frame: the estimate gives ``T_world_frame`` of its own body frame; ``T_frame_sensor`` (the
  sensor in that frame; identity when the poses are the sensor's) moves it to the sensor the
  ground truth is given for: ``T_world_sensor = T_world_frame @ T_frame_sensor``. The world
  frame does not matter (relative errors ignore it, APE aligns it).
- Association, as evo's (``DEFAULT_TOLERANCE_S`` = evo's default ``--t_max_diff``): a scan
  whose stamp is within ``tolerance_s`` (``<=``) of an estimated pose takes that pose as it
  is ("matched"), one scan a pose (``one_pose_a_scan``: a pose goes to its nearest scan, a
  scan takes the nearest of its poses), so a pose is never copied onto the scans around it:
  however large the tolerance, the scans beyond the estimate's time range take no pose but
  the end pose's own nearest scan.
- Interpolation, only when ``max_gap_s`` is given: every scan inside the estimate's span takes
  the SE(3) interpolation (slerp + linear) at its own stamp of the two neighbouring poses when
  they are at most ``max_gap_s`` apart (counted "interpolated" unless matched). The others
  have no estimate and are not scored.
- Options: ``time_offset_s`` finite, ``tolerance_s`` finite and >= 0, ``max_gap_s`` finite and
  > 0 (or None: no interpolation); anything else is a ``DataError`` naming the option.
- No scan with an estimate is a ``DataError`` naming both files and both time spans, with what
  would fit (``hint``; default the time offset of ``loaders.gt.offset_hint``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.runs.external import DEFAULT_TOLERANCE_S
from loaders.errors import DataError
from loaders.gt import nearest_indices, offset_hint, time_span
from loaders.se3 import interpolate_poses
from loaders.trajectory import Trajectory


@dataclass(frozen=True)
class Matched:
    """``T_world_sensor`` (N, 4, 4) estimated at each of the N scans (NaN where none), which
    scans are covered and matched, the pose each matched scan took (``pose_index``, -1 for
    the others) and the association's report (counts, tolerance, gap, offset)."""

    poses: np.ndarray
    covered: np.ndarray
    matched: np.ndarray
    report: dict = field(default_factory=dict)
    pose_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))


def check_options(time_offset_s: float, tolerance_s: float, max_gap_s: float | None) -> None:
    """``DataError`` naming the option for a non-finite offset, a negative or non-finite
    tolerance, a gap that is not a positive finite number."""
    if not np.isfinite(time_offset_s):
        raise DataError(f"--time-offset {time_offset_s:g}: expected a finite number of seconds "
                        "(est_stamp + offset = the scans' clock)")
    if not (np.isfinite(tolerance_s) and tolerance_s >= 0):
        raise DataError(f"--tolerance {tolerance_s:g}: expected a finite tolerance >= 0 s")
    if max_gap_s is not None and not (np.isfinite(max_gap_s) and max_gap_s > 0):
        raise DataError(f"--max-gap {max_gap_s:g}: expected a finite gap > 0 s (or no --max-gap: "
                        "no interpolation)")


#: stamps within this of a scan's [s] are that scan's stamp written with few digits
ROUNDING_S = 1e-3
#: ... when this share of the estimate's stamps inside the scans' span are
ROUNDED_SHARE = 0.9


def rounding_hint(est_stamps: np.ndarray, scan_stamps: np.ndarray, tolerance_s: float
                  ) -> str | None:
    """When the estimate's stamps are the scans' written with few digits (within
    ``ROUNDING_S`` of a scan) but some lie beyond ``tolerance_s``: the tolerance that takes
    them; else None."""
    s, q = np.asarray(est_stamps, float), np.asarray(scan_stamps, float)
    inside = s[(s >= q[0] - ROUNDING_S) & (s <= q[-1] + ROUNDING_S)]
    if len(inside) == 0 or len(q) == 0:
        return None
    _, dist = nearest_indices(q, inside)
    near = dist <= ROUNDING_S
    if near.mean() < ROUNDED_SHARE or dist[near].max() <= tolerance_s:
        return None
    worst = float(dist[near].max())
    return (f"{int(near.sum())} of its stamps lie within {worst:.3g} s of a scan's (the scans' "
            f"stamps written with few digits?), {int((dist > tolerance_s).sum())} of them "
            f"beyond --tolerance {tolerance_s:g}: --tolerance {max(worst * 1.01, 1e-6):.2g} "
            "takes them")


def widest_bridged(s: np.ndarray, q: np.ndarray, interpolated: np.ndarray) -> float:
    """The widest gap between two poses [s] an interpolated scan lies in (0: none)."""
    if not interpolated.any() or len(s) < 2:
        return 0.0
    hi = np.clip(np.searchsorted(s, q[interpolated]), 1, len(s) - 1)
    return float((s[hi] - s[hi - 1]).max())


def one_pose_a_scan(est_stamps: np.ndarray, scan_stamps: np.ndarray) -> np.ndarray:
    """Per scan, the index of the pose it takes (-1: none): each pose goes to its nearest scan,
    each scan takes the nearest of the poses that went to it (ties: the earlier one)."""
    to_scan, dist = nearest_indices(scan_stamps, est_stamps)
    order = np.lexsort((dist, to_scan))  # by scan, then distance; stable: earlier pose first
    first = order[np.r_[True, to_scan[order][1:] != to_scan[order][:-1]]]
    out = np.full(len(scan_stamps), -1)
    out[to_scan[first]] = first
    return out


def match_to_scans(est: Trajectory, scan_stamps: np.ndarray, *, time_offset_s: float = 0.0,
                   tolerance_s: float = DEFAULT_TOLERANCE_S, max_gap_s: float | None = None,
                   T_frame_sensor: np.ndarray | None = None, est_name: str = "estimate",
                   scan_name: str = "scans", hint: str | None = None) -> Matched:
    """The estimate at the scan stamps (see the module docstring); ``max_gap_s`` None: no
    interpolation; ``hint``: what would fit, said when no scan is covered."""
    check_options(time_offset_s, tolerance_s, max_gap_s)
    q = np.asarray(scan_stamps, dtype=np.float64)
    s = np.asarray(est.stamps, dtype=np.float64) + float(time_offset_s)
    poses = np.asarray(est.poses, dtype=np.float64)
    if T_frame_sensor is not None:
        poses = poses @ T_frame_sensor
    near = one_pose_a_scan(s, q)
    matched = near >= 0
    matched[matched] = np.abs(s[near[matched]] - q[matched]) <= tolerance_s
    out = np.full((len(q), 4, 4), np.nan)
    out[matched] = poses[near[matched]]
    inside = np.zeros(len(q), dtype=bool)
    if max_gap_s is not None and len(s) >= 2:
        inside = Trajectory(s, poses).coverage_mask(q, float(max_gap_s))
    if inside.any():  # asked: at the scan's own stamp (a matched one's pose, if exactly on it)
        out[inside] = interpolate_poses(s, poses, np.clip(q[inside], s[0], s[-1]))
    interp = inside & ~matched
    covered = matched | interp
    report = {"time_offset_s": float(time_offset_s), "tolerance_s": float(tolerance_s),
              "max_gap_s": None if max_gap_s is None else float(max_gap_s),
              "scans": int(len(q)), "poses": int(len(s)),
              "matched": int(matched.sum()), "interpolated": int(interp.sum()),
              "covered": int(covered.sum()), "widest_bridged_s": widest_bridged(s, q, interp)}
    if not covered.any():
        need = f"a pose within {tolerance_s:g} s" + (
            "" if max_gap_s is None else f", or two poses at most {max_gap_s:g} s apart around it")
        raise DataError(
            f"{est_name} does not overlap the scans of {scan_name}: no scan has {need}; the "
            f"estimate spans {time_span(s)} (offset {time_offset_s:+.3f} s applied), the "
            f"{len(q)} scans span {time_span(q)}; different clocks? "
            + ((rounding_hint(s, q, tolerance_s) or "") + "; " if rounding_hint(
                s, q, tolerance_s) else "")
            + (hint or offset_hint(s, q).replace("gt_stamp", "est_stamp")
               .replace("the ground truth's clock", "the estimate's clock")))
    return Matched(out, covered, matched, report, np.where(matched, near, -1))
