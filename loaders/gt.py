"""Ground truth for real datasets: clean-up, time association with the scan stamps,
interpolation and a sanity report (pose files and extrinsics: ``loaders.posefile``).

Conventions (shared/REFERENCE.md):

- ``gt_stamp + offset_s = sensor clock``: a constant ``offset_s`` moves the ground-truth stamps
  onto the clock of the scan stamps before anything is associated.
- Ground-truth files give ``T_world_body``; the methods see the sensor, so the loaders apply the
  extrinsic: ``T_world_sensor = T_world_body @ T_body_sensor``.
- Ground truth limits the evaluation, not the sequence: scans that the ground truth does not
  cover (outside its span, or inside a gap longer than ``max_gap_s``) stay in the sequence,
  counted and warned about, and are excluded from scoring; when no scan at all is covered a
  ``DataError`` names both files and both time spans. A gap longer than ``max_gap_s`` is never
  interpolated across.
- Ground-truth stamps must increase: exact duplicate rows are dropped with a
  ``GroundTruthWarning``; a repeated stamp with another pose, or a stamp that goes backwards,
  is a ``DataError`` (see ``clean_trajectory``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from loaders.errors import DataError, GroundTruthWarning
from loaders.se3 import interpolate_poses, make_T
from loaders.trajectory import Trajectory

UncoveredPolicy = Literal["keep", "trim", "error"]
AssociationMode = Literal["interpolate", "nearest"]


def clean_trajectory(gt: Trajectory, name: str = "ground truth",
                     tolerance_s: float = 0.0) -> tuple[Trajectory, dict]:
    """Check that ground-truth stamps increase; drop exact duplicate rows.

    - A row that repeats the previous row's stamp *and* pose (within 1e-9) is a duplicate (a
      logger that wrote a message twice): it is dropped with a ``GroundTruthWarning`` naming the
      count. Harmless: no information is lost.
    - A row that repeats the previous stamp with a *different* pose is an error: two poses at
      one instant, and nothing says which one is right.
    - A row whose stamp goes backwards is an error: a file whose time runs backwards is garbled
      or concatenated out of order, and sorting it would silently interleave two trajectories.
      (Bag topics are sorted by their readers before this check: message order is record
      order, not stamp order.)

    Both errors are ``DataError`` naming the file and the pose row (0-based). Returns the
    cleaned trajectory and ``{"duplicate_rows": n}``."""
    s = gt.stamps
    if not np.all(np.isfinite(s)):
        bad = int(np.flatnonzero(~np.isfinite(s))[0])
        raise DataError(f"{name}, pose row {bad}: stamp is not finite ({s[bad]})")
    d = np.diff(s)
    back = np.flatnonzero(d < -tolerance_s)
    if len(back):
        i = int(back[0]) + 1
        raise DataError(
            f"{name}, pose row {i}: stamp {s[i]:.6f} s goes backwards from {s[i - 1]:.6f} s "
            f"({len(back)} such rows); ground-truth rows must be in time order (a garbled or "
            "concatenated file?)"
        )
    same_stamp = np.flatnonzero(np.abs(d) <= tolerance_s)
    same_pose = np.all(np.isclose(gt.poses[same_stamp + 1], gt.poses[same_stamp], rtol=0,
                                  atol=1e-9), axis=(1, 2))
    if not same_pose.all():
        i = int(same_stamp[~same_pose][0]) + 1
        raise DataError(
            f"{name}, pose row {i}: repeats the stamp {s[i]:.6f} s of the previous row with a "
            f"different pose ({int((~same_pose).sum())} such rows); expected one pose per stamp"
        )
    dup = len(same_stamp)
    if dup:
        warnings.warn(
            f"{name}: {dup} rows repeat the previous row's stamp and pose (duplicates dropped)",
            GroundTruthWarning, stacklevel=2,
        )
    keep = np.ones(len(s), dtype=bool)
    keep[same_stamp + 1] = False
    return Trajectory(s[keep], gt.poses[keep]), {"duplicate_rows": dup}


@dataclass
class Association:
    """Result of associating ground truth with scan stamps.

    keep: indices of the scans the sequence keeps, ascending and consecutive: every scan, or with
    ``uncovered="trim"`` every scan from the first to the last covered one. covered: per kept
    scan, True when ground truth is available (the scan is scored). ground_truth:
    ``T_world_sensor`` at the covered kept scans' stamps. uncovered_*: scans without ground
    truth before its span, after it and inside gaps (kept unless trimmed). report: provenance."""

    keep: np.ndarray
    covered: np.ndarray
    ground_truth: Trajectory
    uncovered_before: int = 0
    uncovered_after: int = 0
    uncovered_inside: int = 0
    trimmed: int = 0
    report: dict = field(default_factory=dict)

    @property
    def uncovered(self) -> int:
        return self.uncovered_before + self.uncovered_after + self.uncovered_inside


def time_span(values: np.ndarray) -> str:
    return f"[{values.min():.3f}, {values.max():.3f}] s" if len(values) else "[] s"


#: a clock difference within this of a whole number of hours is taken for a time zone [s]
TIME_ZONE_SLACK_S = 600.0


def offset_hint(gt_stamps: np.ndarray, scan_stamps: np.ndarray) -> str:
    """The time offset to try when ground truth and scans do not overlap (gt_stamp + offset =
    sensor clock): a whole number of hours when the clocks differ by about that (a time zone,
    e.g. GT in UTC+8: --time-offset -28800), else the offset that lines up the first stamps;
    nothing to suggest when either has no stamps or a stamp is not finite."""
    if not (len(gt_stamps) and len(scan_stamps)):
        return "one of them has no stamps"
    diff = float(scan_stamps[0] - gt_stamps[0])
    if not np.isfinite(diff):
        return (f"a stamp or the time offset is not finite ({diff}); expected finite stamps and "
                "offset [s]")
    hours = round(diff / 3600.0)
    if hours and abs(diff - hours * 3600.0) <= TIME_ZONE_SLACK_S:
        side = "ahead of" if hours < 0 else "behind"
        offset = hours * 3600.0
        why = f"the ground truth's clock is {abs(hours)} h {side} the scans'"
    else:
        offset, why = diff, "this lines up the first stamps"
    return (f"set the time offset: try --time-offset {offset:.10g} ({why}; gt_stamp + offset "
            "= sensor clock)")


def associate(
    gt: Trajectory,
    scan_stamps: np.ndarray,
    *,
    offset_s: float = 0.0,
    max_gap_s: float | None = 0.5,
    tolerance_s: float = 0.0,
    mode: AssociationMode = "interpolate",
    T_body_sensor: np.ndarray | None = None,
    T_world_fix: np.ndarray | None = None,
    uncovered: UncoveredPolicy = "keep",
    gt_file: str | Path = "ground truth",
    scan_file: str | Path = "scans",
) -> Association:
    """Associate ground truth with scan stamps and return ``T_world_sensor`` at the covered ones.

    Ground truth limits the evaluation, not the sequence: a scan without ground truth stays in
    the sequence (the methods register consecutive scans) and is only excluded from scoring.

    offset_s: added to the GT stamps (``gt_stamp + offset_s = sensor clock``).
    mode: "interpolate" (SE(3): slerp + linear between the two neighbouring GT poses, which
    must be at most ``max_gap_s`` apart: a longer gap is never bridged, not even for a scan
    just inside it) or "nearest" (the nearest GT pose within ``tolerance_s``; for GT given one
    row per frame).
    tolerance_s: in interpolate mode, scan stamps up to ``tolerance_s`` outside the GT span take
    the end pose (no extrapolation beyond that).
    T_body_sensor: extrinsic applied on the right (``T_world_body @ T_body_sensor``).
    T_world_fix: applied on the left (e.g. to remove a UTM origin).
    uncovered: "keep" (default: every scan is kept; those without GT are counted, warned about
    with a ``GroundTruthWarning`` and excluded from scoring), "trim" (also cut the leading and
    trailing scans without GT; gaps inside are kept unscored) or "error" (raise on any).
    "drop" is an old name of "keep" (scans were dropped, which made the methods register
    non-consecutive scans): it keeps them, with a warning.
    Raises DataError when no scan is covered, naming both files and both time spans.
    """
    q = np.asarray(scan_stamps, dtype=np.float64)
    if uncovered == "drop":
        warnings.warn(
            f"{scan_file}: uncovered='drop' is no longer supported: scans without ground truth "
            "are kept in the sequence and excluded from scoring (uncovered='keep')",
            GroundTruthWarning, stacklevel=2,
        )
        uncovered = "keep"
    if uncovered not in ("keep", "trim", "error"):
        raise DataError(f"uncovered must be 'keep', 'trim' or 'error', got {uncovered!r}")
    if len(gt) == 0:
        raise DataError(f"{gt_file}: ground truth has no poses")
    gt, clean = clean_trajectory(gt, str(gt_file))
    gs = gt.stamps + float(offset_s)
    poses = gt.poses
    n = len(q)
    if mode == "nearest":
        idx, dist = nearest_indices(gs, q)
        covered = dist <= tolerance_s
    elif mode == "interpolate":
        qc = q.copy()
        if tolerance_s > 0:
            lo_ok = (q < gs[0]) & (q >= gs[0] - tolerance_s)
            hi_ok = (q > gs[-1]) & (q <= gs[-1] + tolerance_s)
            qc[lo_ok] = gs[0]
            qc[hi_ok] = gs[-1]
        covered = Trajectory(gs, poses).coverage_mask(qc, max_gap_s)
    else:
        raise DataError(f"association mode must be 'interpolate' or 'nearest', got {mode!r}")

    if not covered.any():
        raise DataError(
            f"ground truth {gt_file} does not overlap the scans of {scan_file}: GT spans "
            f"{time_span(gs)} (offset {offset_s:+.3f} s applied), the {n} scans span "
            f"{time_span(q)}; different clocks? {offset_hint(gs, q)}"
        )
    first, last = (int(i) for i in np.flatnonzero(covered)[[0, -1]])
    before, after = first, n - 1 - last
    inside = int((~covered[first:last + 1]).sum())
    if uncovered == "error" and (before or after or inside):
        bad = int(np.flatnonzero(~covered)[0])
        raise DataError(
            f"{scan_file}, frame {bad}: scan stamp {q[bad]:.3f} s is not covered by {gt_file} "
            f"(GT spans {time_span(gs)}, max gap {max_gap_s} s); {int((~covered).sum())} of {n} "
            "scans uncovered"
        )
    keep = np.arange(first, last + 1) if uncovered == "trim" else np.arange(n)
    kept_covered = covered[keep]
    scored = keep[kept_covered]
    if mode == "nearest":
        out = poses[idx[scored]]
    elif len(gs) == 1:
        out = np.repeat(poses[:1], len(scored), axis=0)
    else:
        out = interpolate_poses(gs, poses, np.clip(qc[scored], gs[0], gs[-1]))
    traj = Trajectory(q[scored], out)
    if T_body_sensor is not None or T_world_fix is not None:
        traj = traj.transformed(T_world_fix, T_body_sensor)
    trimmed = n - len(keep)
    missing = int((~kept_covered).sum())
    if missing or trimmed:
        what = []
        if missing:
            what.append(f"{missing} of the {len(keep)} scans kept have no ground truth in "
                        f"{gt_file} and are excluded from scoring")
        if trimmed:
            what.append(f"{trimmed} scans before/after its span trimmed")
        warnings.warn(
            f"{scan_file}: {'; '.join(what)} ({before} before, {after} after its span, "
            f"{inside} inside gaps > {max_gap_s} s)",
            GroundTruthWarning, stacklevel=2,
        )
    report = {
        "gt_file": str(gt_file),
        "mode": mode,
        "offset_s": float(offset_s),
        "max_gap_s": max_gap_s,
        "tolerance_s": float(tolerance_s),
        "uncovered": uncovered,
        "scans": n,
        "kept": int(len(keep)),
        "with_gt": int(len(scored)),
        "uncovered_before": before,
        "uncovered_after": after,
        "uncovered_inside": inside,
        "trimmed": trimmed,
        **{f"gt_{k}": v for k, v in clean.items()},
    }
    return Association(keep, kept_covered, traj, before, after, inside, trimmed, report)


def nearest_indices(stamps: np.ndarray, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the nearest stamp (sorted ``stamps``) for each query and its distance [s]."""
    s = np.asarray(stamps, dtype=np.float64)
    q = np.asarray(query, dtype=np.float64)
    hi = np.clip(np.searchsorted(s, q), 1, max(len(s) - 1, 1))
    lo = hi - 1
    if len(s) == 1:
        return np.zeros(len(q), dtype=int), np.abs(q - s[0])
    pick_hi = np.abs(s[hi] - q) < np.abs(q - s[lo])
    idx = np.where(pick_hi, hi, lo)
    return idx, np.abs(s[idx] - q)


def remove_origin(gt: Trajectory) -> tuple[Trajectory, np.ndarray]:
    """Subtract the first position from every position (e.g. UTM -> local); returns the shifted
    trajectory and the removed origin (3,)."""
    origin = gt.poses[0, :3, 3].copy()
    return gt.transformed(make_T(np.eye(3), -origin)), origin


#: A scan stamp and a GT stamp closer than this are the same instant [s].
STAMP_TOLERANCE_S = 1e-4
#: GT at its own rate is interpolated across at most this many median GT steps.
MAX_GAP_STEPS = 3.0


def gt_for_frames(gt: Trajectory, stamps: np.ndarray, tolerance_s: float = STAMP_TOLERANCE_S,
                  name: str = "ground truth") -> tuple[np.ndarray, np.ndarray]:
    """GT poses ``T_world_sensor`` (N, 4, 4) at the scan stamps and a mask (N,) of the frames
    that have ground truth; poses of frames without are NaN. Raises ``DataError`` when the GT
    rows are not in time order (see ``loaders.gt.clean_trajectory``)."""
    stamps = np.asarray(stamps, dtype=np.float64)
    n = len(stamps)
    poses = np.full((n, 4, 4), np.nan)
    mask = np.zeros(n, dtype=bool)
    if len(gt) == 0 or n == 0:
        return poses, mask
    gt, _ = clean_trajectory(gt, name)
    s = gt.stamps
    near, dist = nearest_indices(s, stamps)  # nearest GT pose of each scan
    exact = dist <= tolerance_s
    sorted_scans = np.sort(stamps)
    _, gt_to_scan = nearest_indices(sorted_scans, s)  # nearest scan of each GT pose
    inside = (s >= sorted_scans[0] - tolerance_s) & (s <= sorted_scans[-1] + tolerance_s)
    sampled_at_scans = bool(np.all(gt_to_scan[inside] <= tolerance_s))
    if sampled_at_scans or len(s) < 2:
        mask = exact
        poses[mask] = gt.poses[near[mask]]
        return poses, mask
    step = float(np.median(np.diff(s)))
    mask = gt.coverage_mask(stamps, MAX_GAP_STEPS * step, tolerance_s)
    if mask.any():
        # a scan within tolerance_s outside the GT span is covered: it takes the end pose
        query = np.clip(stamps[mask], s[0], s[-1])
        poses[mask] = gt.interpolate(query, name=name).poses
    return poses, mask
