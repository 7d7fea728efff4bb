"""Ground truth for real datasets: clean-up, time association with the scan stamps,
interpolation, extrinsic application and a sanity report.

Conventions (shared/REFERENCE.md):

- ``gt_stamp + offset_s = sensor clock``: a constant ``offset_s`` moves the ground-truth stamps
  onto the clock of the scan stamps before anything is associated.
- Ground-truth files give ``T_world_body``; the methods see the sensor, so the loaders apply the
  extrinsic: ``T_world_sensor = T_world_body @ T_body_sensor``.
- Scans that the ground truth does not cover (outside its span, or inside a gap longer than
  ``max_gap_s``) are dropped with an explicit count; when no scan at all is covered a
  ``DataError`` names both files and both time spans.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from loaders.errors import DataError
from loaders.scan import Trajectory
from loaders.se3 import interpolate_poses, make_T

UncoveredPolicy = Literal["drop", "trim", "error"]
AssociationMode = Literal["interpolate", "nearest"]


def parse_extrinsic(text: str | list | tuple | np.ndarray | None) -> np.ndarray:
    """A 4x4 extrinsic from "x y z qx qy qz qw" (TUM order), 7 numbers, 16 numbers (row-major
    4x4) or a 4x4 array; ``None`` gives the identity."""
    if text is None:
        return np.eye(4)
    if isinstance(text, str):
        try:
            values = [float(v) for v in text.replace(",", " ").split()]
        except ValueError as err:
            raise DataError(
                f"extrinsic {text!r}: expected numbers 'x y z qx qy qz qw' ({err})"
            ) from None
    else:
        values = np.asarray(text, dtype=np.float64).ravel().tolist()
    v = np.asarray(values, dtype=np.float64)
    if v.size == 16:
        T = v.reshape(4, 4)
        if not np.allclose(T[3], [0, 0, 0, 1]) or not np.allclose(
            T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5
        ):
            raise DataError(f"extrinsic {values}: the 4x4 matrix is not a rigid transform")
        return T
    if v.size == 3:
        return make_T(np.eye(3), v)
    if v.size != 7:
        raise DataError(
            f"extrinsic {values}: expected 7 numbers 'x y z qx qy qz qw', 3 (translation only) "
            f"or 16 (row-major 4x4), got {v.size}"
        )
    q = v[3:]
    if not np.isclose(np.linalg.norm(q), 1.0, atol=1e-3):
        raise DataError(f"extrinsic {values}: quaternion (qx qy qz qw) is not unit length")
    from scipy.spatial.transform import Rotation

    return make_T(Rotation.from_quat(q / np.linalg.norm(q)).as_matrix(), v[:3])


def clean_trajectory(gt: Trajectory, name: str = "ground truth") -> tuple[Trajectory, dict]:
    """Sort by stamp and drop rows with a repeated stamp (the first is kept).

    Returns the cleaned trajectory and counts ``{"reordered": bool, "duplicate_stamps": n}``;
    a ``warnings.warn`` reports any change (never silently)."""
    stamps = gt.stamps
    order = np.argsort(stamps, kind="stable")
    reordered = bool(np.any(order != np.arange(len(order))))
    s = stamps[order]
    keep = np.ones(len(s), dtype=bool)
    keep[1:] = np.diff(s) > 0
    dup = int((~keep).sum())
    if reordered or dup:
        warnings.warn(
            f"{name}: stamps were {'not monotonic (sorted); ' if reordered else ''}"
            f"{dup} rows with a repeated stamp dropped",
            stacklevel=2,
        )
    idx = order[keep]
    return Trajectory(gt.stamps[idx], gt.poses[idx]), {"reordered": reordered,
                                                      "duplicate_stamps": dup}


@dataclass
class Association:
    """Result of associating ground truth with scan stamps.

    keep: indices of the scans that are covered (ascending). ground_truth: ``T_world_sensor`` at
    the kept scan stamps. dropped_*: scans dropped before the GT span, after it, and inside it
    (GT gaps). report: a dict for provenance."""

    keep: np.ndarray
    ground_truth: Trajectory
    dropped_before: int = 0
    dropped_after: int = 0
    dropped_inside: int = 0
    report: dict = field(default_factory=dict)

    @property
    def dropped(self) -> int:
        return self.dropped_before + self.dropped_after + self.dropped_inside


def _span(values: np.ndarray) -> str:
    return f"[{values.min():.3f}, {values.max():.3f}] s" if len(values) else "[] s"


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
    uncovered: UncoveredPolicy = "drop",
    gt_file: str | Path = "ground truth",
    scan_file: str | Path = "scans",
) -> Association:
    """Associate ground truth with scan stamps and return ``T_world_sensor`` at the covered ones.

    offset_s: added to the GT stamps (``gt_stamp + offset_s = sensor clock``).
    mode: "interpolate" (SE(3): slerp + linear between the two neighbouring GT poses, which
    must be at most ``max_gap_s`` apart) or "nearest" (the nearest GT pose within
    ``tolerance_s``; for GT given one row per frame).
    tolerance_s: in interpolate mode, scan stamps up to ``tolerance_s`` outside the GT span take
    the end pose (no extrapolation beyond that).
    T_body_sensor: extrinsic applied on the right (``T_world_body @ T_body_sensor``).
    T_world_fix: applied on the left (e.g. to remove a UTM origin).
    uncovered: "drop" (drop every uncovered scan, counted), "trim" (drop leading/trailing
    uncovered scans only; an uncovered scan inside raises) or "error" (raise on any).
    Raises DataError when no scan is covered, naming both files and both time spans.
    """
    q = np.asarray(scan_stamps, dtype=np.float64)
    if len(gt) == 0:
        raise DataError(f"{gt_file}: ground truth has no poses")
    gt, clean = clean_trajectory(gt, str(gt_file))
    gs = gt.stamps + float(offset_s)
    poses = gt.poses
    n = len(q)
    if mode == "nearest":
        idx, dist = nearest_indices(gs, q)
        covered = dist <= tolerance_s
        src = poses[idx]
    elif mode == "interpolate":
        qc = q.copy()
        if tolerance_s > 0:
            lo_ok = (q < gs[0]) & (q >= gs[0] - tolerance_s)
            hi_ok = (q > gs[-1]) & (q <= gs[-1] + tolerance_s)
            qc[lo_ok] = gs[0]
            qc[hi_ok] = gs[-1]
        if len(gs) == 1:
            covered = np.abs(qc - gs[0]) <= 1e-9
        else:
            covered = Trajectory(gs, poses).coverage_mask(qc, max_gap_s)
        src = None
    else:
        raise DataError(f"association mode must be 'interpolate' or 'nearest', got {mode!r}")

    if not covered.any():
        raise DataError(
            f"ground truth {gt_file} does not overlap the scans of {scan_file}: GT spans "
            f"{_span(gs)} (offset {offset_s:+.3f} s applied), the {n} scans span {_span(q)}; "
            "different clocks? set the time offset (gt_stamp + offset = sensor clock)"
        )
    first, last = np.flatnonzero(covered)[[0, -1]]
    before, after = int(first), int(n - 1 - last)
    inside = int((~covered[first:last + 1]).sum())
    if uncovered == "error" and (before or after or inside):
        bad = int(np.flatnonzero(~covered)[0])
        raise DataError(
            f"{scan_file}, frame {bad}: scan stamp {q[bad]:.3f} s is not covered by {gt_file} "
            f"(GT spans {_span(gs)}, max gap {max_gap_s} s); {int((~covered).sum())} of {n} "
            "scans uncovered"
        )
    if uncovered == "trim" and inside:
        bad = int(first + np.flatnonzero(~covered[first:last + 1])[0])
        raise DataError(
            f"{scan_file}, frame {bad}: scan stamp {q[bad]:.3f} s falls in a ground-truth gap "
            f"longer than {max_gap_s} s in {gt_file} ({inside} scans inside gaps); use "
            "uncovered='drop' or a larger max gap"
        )
    if uncovered not in ("drop", "trim", "error"):
        raise DataError(f"uncovered must be 'drop', 'trim' or 'error', got {uncovered!r}")
    keep = np.flatnonzero(covered)
    if mode == "nearest":
        out = src[keep]
    else:
        if len(gs) == 1:
            out = np.repeat(poses[:1], len(keep), axis=0)
        else:
            out = interpolate_poses(gs, poses, np.clip(qc[keep], gs[0], gs[-1]))
    traj = Trajectory(q[keep], out)
    if T_body_sensor is not None or T_world_fix is not None:
        traj = traj.transformed(T_world_fix, T_body_sensor)
    dropped = before + after + inside
    if dropped:
        warnings.warn(
            f"{scan_file}: {dropped} of {n} scans not covered by ground truth {gt_file} were "
            f"dropped ({before} before, {after} after its span, {inside} inside gaps > "
            f"{max_gap_s} s)",
            stacklevel=2,
        )
    report = {
        "gt_file": str(gt_file),
        "mode": mode,
        "offset_s": float(offset_s),
        "max_gap_s": max_gap_s,
        "tolerance_s": float(tolerance_s),
        "scans": n,
        "kept": int(len(keep)),
        "dropped_before": before,
        "dropped_after": after,
        "dropped_inside": inside,
        **{f"gt_{k}": v for k, v in clean.items()},
    }
    return Association(keep, traj, before, after, inside, report)


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


def gt_sanity_report(
    gt: Trajectory, scan_stamps: np.ndarray | None = None, gap_factor: float = 3.0
) -> dict:
    """Findings about a ground-truth trajectory, for ``bench inspect``.

    Keys: poses, span_s, median_step_s, gaps (list of {index, t, gap_s} where the step exceeds
    ``gap_factor`` x the median step), largest_gap_s, repeated_poses (consecutive rows with the
    same pose), repeated_stamps, non_monotonic (steps <= 0 that are not repeats), path_length_m,
    scan_coverage_pct (share of the scan stamps inside the span and not in a gap), and
    ``findings``: human-readable lines for each problem (empty when clean).
    """
    s = np.asarray(gt.stamps, dtype=np.float64)
    out: dict = {"poses": int(len(s))}
    findings: list[str] = []
    if len(s) == 0:
        out["findings"] = ["ground truth has no poses"]
        return out
    d = np.diff(s)
    pos_steps = d[d > 0]
    median = float(np.median(pos_steps)) if len(pos_steps) else float("nan")
    out["span_s"] = [float(s.min()), float(s.max())]
    out["median_step_s"] = median
    gaps = []
    if len(pos_steps):
        for i in np.flatnonzero(d > gap_factor * median):
            gaps.append({"index": int(i), "t": float(s[i]), "gap_s": float(d[i])})
    out["gaps"] = gaps
    out["largest_gap_s"] = float(d.max()) if len(d) else 0.0
    same_pose = np.all(np.isclose(gt.poses[1:], gt.poses[:-1], atol=1e-9, rtol=0), axis=(1, 2))
    out["repeated_poses"] = int(same_pose.sum())
    out["repeated_stamps"] = int((d == 0).sum())
    out["non_monotonic"] = int((d < 0).sum())
    out["path_length_m"] = gt.path_length_m()
    if gaps:
        findings.append(
            f"{len(gaps)} gaps longer than {gap_factor:g} x the median step {median:.4f} s "
            f"(largest {max(g['gap_s'] for g in gaps):.3f} s at t={gaps[0]['t']:.3f} s first)"
        )
    if out["repeated_poses"]:
        findings.append(f"{out['repeated_poses']} consecutive repeated poses (GT stalled?)")
    if out["repeated_stamps"]:
        findings.append(f"{out['repeated_stamps']} repeated stamps")
    if out["non_monotonic"]:
        findings.append(f"{out['non_monotonic']} non-monotonic stamps (time goes backwards)")
    if scan_stamps is not None and len(scan_stamps):
        q = np.asarray(scan_stamps, dtype=np.float64)
        good, _ = clean_trajectory_quiet(gt)
        if len(good) >= 2:
            max_gap = gap_factor * median if np.isfinite(median) else None
            cov = good.coverage_mask(q, max_gap)
        else:
            cov = np.isclose(q, s[0])
        pct = 100.0 * float(cov.mean())
        out["scan_coverage_pct"] = pct
        out["scan_span_s"] = [float(q.min()), float(q.max())]
        if pct < 100.0:
            findings.append(
                f"ground truth covers {pct:.1f} % of the {len(q)} scans (GT {_span(s)}, "
                f"scans {_span(q)})"
            )
    out["findings"] = findings
    return out


def clean_trajectory_quiet(gt: Trajectory) -> tuple[Trajectory, dict]:
    """``clean_trajectory`` without the warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return clean_trajectory(gt)


def detect_pose_format(path: str | Path) -> str:
    """"kitti" when the first numeric row has 12 values, else "tum"."""
    with open(path) as f:
        for line in f:
            parts = line.replace(",", " ").split()
            if not parts or parts[0].startswith("#"):
                continue
            try:
                [float(p) for p in parts]
            except ValueError:
                continue
            return "kitti" if len(parts) == 12 else "tum"
    return "tum"


def read_gt_file(path: str | Path, fmt: str = "auto", stamps: np.ndarray | None = None
                 ) -> Trajectory:
    """Read a TUM (8 columns) or KITTI (12 columns) pose file; ``fmt`` "auto" decides from the
    first numeric row. KITTI rows get ``stamps`` (default: the row index)."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: ground-truth file not found")
    if fmt == "auto":
        fmt = detect_pose_format(path)
    if fmt == "tum":
        return Trajectory.read_tum(path)
    if fmt == "kitti":
        return Trajectory.read_kitti(path, stamps)
    raise DataError(f"{path}: unknown ground-truth format {fmt!r} (expected tum or kitti)")
