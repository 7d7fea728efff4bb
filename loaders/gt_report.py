"""A sanity report of a ground-truth trajectory for ``bench inspect``: its rate, gaps, repeated
and jumping poses, and how its span covers the scans (findings in plain words)."""

from __future__ import annotations

import numpy as np

from loaders.gt import time_span
from loaders.trajectory import Trajectory


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
        findings.append(_repeats_finding(same_pose))
    if out["repeated_stamps"]:
        findings.append(f"{out['repeated_stamps']} repeated stamps")
    if out["non_monotonic"]:
        findings.append(f"{out['non_monotonic']} non-monotonic stamps (time goes backwards)")
    if scan_stamps is not None and len(scan_stamps):
        q = np.asarray(scan_stamps, dtype=np.float64)
        good = _sorted_unique(gt)  # a report, not a check: cover what can be covered
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
                f"ground truth covers {pct:.1f} % of the {len(q)} scans (GT {time_span(s)}, "
                f"scans {time_span(q)})"
            )
    out["findings"] = findings
    return out


def _sorted_unique(gt: Trajectory) -> Trajectory:
    """The rows sorted by stamp, the first of each repeated stamp kept (for the report only)."""
    order = np.argsort(gt.stamps, kind="stable")
    s = gt.stamps[order]
    keep = np.ones(len(s), dtype=bool)
    keep[1:] = np.diff(s) > 0
    return Trajectory(s[keep], gt.poses[order[keep]])


def _repeats_finding(same_pose: np.ndarray) -> str:
    """Say what repeated poses look like: scattered single repeats at a steady share (ground
    truth at a lower rate resampled onto the scans, e.g. 10 Hz onto 12 Hz: 1 step in 6) or
    runs of repeats (the ground truth stalled)."""
    n, steps = int(same_pose.sum()), len(same_pose)
    edges = np.diff(np.r_[0, same_pose.astype(np.int8), 0])
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    longest = int(runs.max())
    if longest <= 2:
        return (f"{n} of {steps} steps repeat the previous pose, scattered (1 step in "
                f"{steps / n:.0f}): ground truth at a lower rate resampled onto the scans; "
                "frame-to-frame errors are meaningless, segments of metres are fine")
    return (f"{n} repeated poses, up to {longest} in a row (the ground truth stalled there?)")
