"""The checks of ``bench score`` between reading an estimate and scoring it, in order: its
clock (``clock_check``: index stamps, units, the motion profile), the association
(``match``), a decisive clock misfit, its convention (``conventions``), the coverage of the
scans with ground truth (not the calibration frames: ``bench run`` scores exactly those too)
and a bridged gap. Each refusal is one ``DataError``; warnings are scored anyway.
``check_estimate`` is what ``bench.runs.external.score`` and the false-alarm study
(``bench.studies.score_checks``) both run."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.runs.external.clock_check import check_clock, fit_hint, refuse_misfit
from bench.runs.external.conventions import check_conventions, reread
from bench.runs.external.match import Matched, match_to_scans, rounding_hint
from bench.runs.job import calibration_frames
from loaders.errors import DataError
from loaders.gt import gt_for_frames, time_span
from loaders.trajectory import Trajectory


@dataclass
class Checked:
    """What passed: the estimate at the scans, the coverage report, the scans scored with
    ground truth (``with_gt``: not calibration frames), what the clock and convention checks
    found, and the warnings."""

    matched: Matched
    coverage: dict
    with_gt: np.ndarray
    clock: str
    convention: str
    warnings: list[str] = field(default_factory=list)


def check_estimate(seq, est, spec, T_frame_sensor: np.ndarray, where: str, store: str
                   ) -> Checked:
    """Every check of the contract on ``est`` (``loaders.estimate.Estimate``) against the
    store sequence ``seq`` (its stamps and ground truth) with ``spec``'s options
    (``bench.runs.external.score.ExternalSpec``); ``DataError`` on a refusal."""
    stamps = seq.stamps
    verdict = check_clock(est.trajectory, T_frame_sensor, seq.ground_truth, stamps,
                          spec.time_offset_s, spec.trust_clock, where, store,
                          est.stamp_unit, spec.tolerance_s, est.raw_stamps)
    clock, warned = verdict.line, list(verdict.warnings)
    m = match_to_scans(est.trajectory, stamps, time_offset_s=spec.time_offset_s,
                       tolerance_s=spec.tolerance_s, max_gap_s=spec.max_gap_s,
                       T_frame_sensor=T_frame_sensor, est_name=where, scan_name=store,
                       hint=fit_hint(verdict.fit))
    refuse_misfit(verdict, spec.time_offset_s, spec.tolerance_s, where, store)
    gt_at_scans, has_gt = gt_for_frames(seq.ground_truth, stamps, name=store)
    convention = _conventions(est, spec, stamps, m, gt_at_scans, T_frame_sensor, where)
    calibrated = calibration_frames(seq)
    with_gt = has_gt if calibrated is None else has_gt & ~calibrated
    scored = m.covered & with_gt
    n_gt = int(with_gt.sum())
    warned += _bridged(m.report, stamps, where)
    coverage = {**m.report, "scans_with_gt": n_gt, "scored": int(scored.sum()),
                "share_scored": float(scored.sum() / max(n_gt, 1))}
    if not scored.any():
        raise DataError(f"{where}: none of the {int(m.covered.sum())} scans with an "
                        f"estimate has ground truth in {store}; nothing to score")
    if coverage["share_scored"] < spec.min_coverage:
        rounded = rounding_hint(est.trajectory.stamps + spec.time_offset_s, stamps,
                                spec.tolerance_s)
        advice = rounded or ("A shorter or sparser estimate? " + (
            "--max-gap S interpolates between poses at most S apart; " if spec.max_gap_s
            is None else "") + "--min-coverage 0 scores what it covers")
        raise DataError(
            f"{where} covers {coverage['scored']} of the {n_gt} scans of {store} with ground "
            f"truth ({100 * coverage['share_scored']:.1f} %), below --min-coverage "
            f"{spec.min_coverage:g}: {m.report['matched']} matched within "
            f"{spec.tolerance_s:g} s, {m.report['interpolated']} interpolated; the estimate "
            f"({len(est.trajectory)} poses) spans "
            f"{time_span(est.trajectory.stamps + spec.time_offset_s)}, the scans with ground "
            f"truth {time_span(stamps[with_gt])}. {advice}")
    return Checked(m, coverage, with_gt, clock, convention, warned)


#: interpolating across a gap wider than this many scan periods is warned about
BRIDGE_PERIODS = 3.0


def _bridged(report: dict, stamps: np.ndarray, where: str) -> list[str]:
    """A warning when ``--max-gap`` bridged a gap wider than ``BRIDGE_PERIODS`` periods."""
    period = float(np.median(np.diff(stamps))) if len(stamps) > 1 else 0.0
    wide = report.get("widest_bridged_s", 0.0)
    if not (period > 0 and wide > BRIDGE_PERIODS * period):
        return []
    return [f"{where}: --max-gap {report['max_gap_s']:g} bridged a gap of {wide:.3g} s "
            f"({wide / period:.1f} scan periods) between two of its poses: the scans inside "
            "are scored on poses interpolated across it, not estimated"]


def _conventions(est, spec, stamps: np.ndarray, m, gt_at_scans: np.ndarray,
                 T_frame_sensor: np.ndarray, where: str) -> str:
    """``bench.runs.external.conventions``: the estimate's other readings at the same scans."""
    period = float(np.median(np.diff(stamps))) if len(stamps) > 1 else 0.0

    def match_other(name):
        other = Trajectory(est.trajectory.stamps, reread(est.trajectory.poses, name))
        return match_to_scans(other, stamps, time_offset_s=spec.time_offset_s,
                              tolerance_s=spec.tolerance_s, max_gap_s=spec.max_gap_s,
                              T_frame_sensor=T_frame_sensor).poses

    return check_conventions(est.fmt, m.poses, match_other, gt_at_scans, period, where)


