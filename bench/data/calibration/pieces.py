"""Does one rotation fit the whole range? ``bench calibrate`` fits the Doppler estimate
(``bench.data.calibration.estimate``) again on contiguous pieces of its frames, each on its own
with its
own bootstrap interval, and says when two pieces disagree beyond their intervals.

A mount does not move, but a ground truth's frame can tilt along a drive (an INS's attitude
drifts, a GT pipeline re-levels): on one real NTU drive four pieces of 125 frames gave pitch
-2.58, -2.03, (loose) and -3.06 deg. One rotation fitted to the whole range is then an average
of rotations that differ, and its block bootstrap interval (which treats the residuals as
stationary) says nothing about that; the pieces do.

Pieces: about ``PIECE_FRAMES`` frames each, at least two and at least ``MIN_PIECE_FRAMES``
frames each (a range shorter than twice that is not split). Two pieces disagree on an angle
when both fitted it (the same cue) with an interval and their estimates are further apart than
the combined half-widths of their intervals, ``sqrt(h_1^2 + h_2^2)`` - the rule ``bench
calibrate`` also uses between its Doppler and hand-eye estimates - and than ``MIN_CHANGE_DEG``
(0.3 deg: on synthetic drives of one rotation the pieces' estimates differ by up to 0.26 deg
beyond their intervals; a smaller change of the tilt is not reported). Pieces not apart *agree* on
an angle only when those combined half-widths are at most ``--max-width``; wider, the intervals
cannot tell, and the message says so (``bench.data.calibration.verdict``). On 60 simulated drives of
250 frames and one fixed rotation (AR(1) per-frame errors with lag-one correlation 0.8, 5 %
outliers; the cues of tests/test_calibration_uncertainty.py) it fired on none, for any angle;
with the pitch 1 deg higher from the middle on, on 11 of 12 (tests/test_calibration_pieces.py).
On the simulated scans of ``loaders.synthetic`` and the sample: ``bench.studies.
calibrate_checks_study`` (docs/results.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.data.calibration.estimate import ANGLES, CalibrationResult, FrameCues, calibrate_cues
from bench.data.calibration.verdict import AGREE, CANNOT_TELL, Verdict, summary
from bench.data.calibration.write import WRITE_MAX_WIDTH_DEG
from loaders.errors import DataError

#: the length of a piece the range is split into [frames] (125: 10 s at 12.5 Hz)
PIECE_FRAMES = 125
#: no piece shorter than this [frames]; a shorter range is not split
MIN_PIECE_FRAMES = 40
#: two pieces are apart on an angle only when their estimates differ by more than this [deg]
#: as well as by more than the combined half-widths. Tuned on synthetic drives (issue 47): on 17
#: correct ones (straight-wall radar-sparse flat seeds 0-9, straight-wall radar-eagle 0-3,
#: campus radar-frgen21 0-2, 250 frames) the half-width rule alone called 9 pairs apart on 7
#: drives, by 0.03-0.26 deg (the bootstrap intervals are narrower than the pieces' real
#: spread); the sample's pieces were never apart (bench.studies.calibrate_checks_study)
MIN_CHANGE_DEG = 0.3


def piece_bounds(n_frames: int, piece_frames: int = PIECE_FRAMES,
                 min_frames: int = MIN_PIECE_FRAMES) -> list[tuple[int, int]]:
    """[first, stop) of contiguous pieces covering frames 0 .. n_frames - 1: about
    ``piece_frames`` long, at least two, none shorter than ``min_frames``; empty when the
    range cannot hold two."""
    count = min(max(2, round(n_frames / piece_frames)), n_frames // min_frames)
    if count < 2:
        return []
    edges = np.linspace(0, n_frames, count + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


@dataclass
class Piece:
    """One piece's frames [first, stop) of the range and its own fit (None, with ``error``,
    when the piece cannot be fitted)."""

    first: int
    stop: int
    result: CalibrationResult | None
    error: str = ""


@dataclass
class Disagreement:
    """Two pieces (indices into the list) whose estimates of ``angle`` are ``diff_deg`` apart
    [deg], beyond the combined half-widths ``combined_deg`` of their intervals."""

    angle: str
    first: int
    second: int
    diff_deg: float
    combined_deg: float


def fit_pieces(cues: FrameCues, bounds: list[tuple[int, int]], **options) -> list[Piece]:
    """Each piece of ``cues`` fitted on its own (``calibrate_cues`` with ``options``)."""
    pieces = []
    for first, stop in bounds:
        try:
            pieces.append(Piece(first, stop, calibrate_cues(cues.piece(first, stop),
                                                            **options)))
        except DataError as err:
            pieces.append(Piece(first, stop, None, str(err)))
    return pieces


def _half_width(cal: CalibrationResult, ax: str) -> float:
    lo, hi = cal.interval_deg[ax]
    return 0.5 * (hi - lo)


def disagreements(pieces: list[Piece]) -> list[Disagreement]:
    """Every pair of pieces and angle where both fitted the angle from the same cue, with a
    finite interval, and the estimates lie further apart than ``sqrt(h_1^2 + h_2^2)`` and than
    ``MIN_CHANGE_DEG``."""
    out = []
    for i, j, ax, diff, combined in _compared(pieces):
        if np.isfinite(combined) and abs(diff) > max(combined, MIN_CHANGE_DEG):
            out.append(Disagreement(ax, i, j, diff, combined))
    return out


def _compared(pieces: list[Piece]):
    """(i, j, angle, difference piece j - piece i [deg], combined half-width [deg]) for every
    pair of fitted pieces and every angle both fitted from the same cue."""
    for i, p in enumerate(pieces):
        for j in range(i + 1, len(pieces)):
            q = pieces[j]
            if p.result is None or q.result is None:
                continue
            for ax in ANGLES:
                if p.result.source[ax] == "not observable" or \
                        p.result.source[ax] != q.result.source[ax]:
                    continue
                combined = float(np.hypot(_half_width(p.result, ax), _half_width(q.result, ax)))
                yield i, j, ax, q.result.angles_deg[ax] - p.result.angles_deg[ax], combined


def _cell(cal: CalibrationResult, ax: str) -> str:
    if cal.source[ax] == "not observable":
        return f"{ax} not observable"
    lo, hi = cal.interval_deg[ax]
    if not np.isfinite(hi - lo):
        return f"{ax} {cal.angles_deg[ax]:+.2f} (no interval)"
    return f"{ax} {cal.angles_deg[ax]:+.2f} [{lo:+.2f}, {hi:+.2f}]"


def verdicts(pieces: list[Piece], resolution_deg: float = WRITE_MAX_WIDTH_DEG
             ) -> list[Verdict]:
    """Per angle compared (both pieces fitted it from the same cue), the pair that says least:
    the one the intervals cannot tell with the widest combined half-width, else the agreeing
    pair with the widest; angles with a pair apart are left to ``disagreements``."""
    by_angle: dict[str, list[Verdict]] = {}
    for _, _, ax, diff, width in _compared(pieces):
        by_angle.setdefault(ax, []).append(Verdict(
            ax, diff, width if np.isfinite(width) else float("inf"), resolution_deg,
            MIN_CHANGE_DEG))
    out = []
    for found in by_angle.values():
        cannot = [v for v in found if v.kind == CANNOT_TELL]
        agree = [v for v in found if v.kind == AGREE]
        if len(cannot) + len(agree) < len(found):
            continue  # apart somewhere: said by ``disagreements``
        out.append(max(cannot or agree, key=lambda v: v.combined_deg))
    return out


def format_pieces(pieces: list[Piece], offset: int = 0,
                  resolution_deg: float = WRITE_MAX_WIDTH_DEG) -> list[str]:
    """The per-piece estimates (frames numbered from ``offset``) and the verdict: apart, agree
    or cannot tell (``resolution_deg``: ``--max-width``)."""
    if not pieces:
        return []
    level = next((p.result.level for p in pieces if p.result is not None), 0.95)
    label = [f"frames {offset + p.first}-{offset + p.stop - 1}" for p in pieces]
    lines = [f"pieces of the range, each fitted on its own ({100 * level:.0f} % intervals):"]
    for name, p in zip(label, pieces, strict=True):
        body = p.error if p.result is None else "  ".join(_cell(p.result, ax) for ax in ANGLES)
        lines.append(f"  {name:<16} {body}")
    apart = disagreements(pieces)
    if not apart:
        said = verdicts(pieces, resolution_deg)
        lines += summary(said, "the pieces", resolution_deg)
        if said and all(v.kind == AGREE for v in said):
            lines.append("  one rotation fits the range on every angle compared")
        elif not said:
            lines.append("  no angle is fitted by two pieces from the same cue: nothing to "
                         "compare")
        return lines
    said = []
    for d in apart:
        a, b = pieces[d.first].result, pieces[d.second].result
        said.append(f"{d.angle} {a.angles_deg[d.angle]:+.2f} ({label[d.first]}) vs "
                    f"{b.angles_deg[d.angle]:+.2f} ({label[d.second]}), {abs(d.diff_deg):.2f} "
                    f"deg apart against combined half-widths {d.combined_deg:.2f}")
    lines.append(
        "  THE ROTATION CHANGES ALONG THE RANGE: the pieces disagree beyond their intervals in "
        + "; ".join(said) + ". The GT frame's tilt (or the mount) is not the same over the "
        "whole range: the estimate above is an average over it, and a store written with it "
        "is corrected by that average on every frame")
    return lines
