"""What two estimates of one angle can say about each other: apart, agree, or cannot tell.

Two estimates are *apart* when they differ by more than the combined half-widths of their
intervals, ``sqrt(h_1^2 + h_2^2)``. Otherwise they are not shown apart, which is not the same
as agreeing: with intervals of +-6 deg, two estimates 3 deg apart are "not apart" only because
the intervals could not have told them apart. So they *agree* only when the intervals were
narrow enough to show a difference that matters: the combined half-width at most the
resolution asked for (``bench calibrate --max-width``, the widest interval it applies). Wider
than that, the verdict is *cannot tell*, with the widths that made it so.

A verdict may carry a floor (``floor_deg``): then *apart* also needs the difference to exceed
it. The pieces of one range use ``MIN_CHANGE_DEG`` (``bench.data.calibration.pieces``); the
Doppler and hand-eye estimates use none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

APART, AGREE, CANNOT_TELL = "apart", "agree", "cannot tell"


@dataclass
class Verdict:
    """One angle of two estimates: their difference, the combined half-width of their
    intervals, the resolution asked for and what these can tell (``kind``)."""

    angle: str
    diff_deg: float
    combined_deg: float
    resolution_deg: float
    floor_deg: float = 0.0

    @property
    def kind(self) -> str:
        if math.isfinite(self.combined_deg) and \
                abs(self.diff_deg) > max(self.combined_deg, self.floor_deg):
            return APART
        if math.isfinite(self.combined_deg) and self.combined_deg <= self.resolution_deg:
            return AGREE
        return CANNOT_TELL

    def why(self) -> str:
        """Why the intervals cannot tell: the difference against the combined half-width."""
        width = (f"+-{self.combined_deg:.2f}" if math.isfinite(self.combined_deg)
                 else "no finite interval")
        return (f"{self.angle} {abs(self.diff_deg):.2f} deg apart, combined half-widths "
                f"{width} deg")


def combined(half_1: float, half_2: float) -> float:
    return float(math.hypot(half_1, half_2))


def summary(verdicts: list[Verdict], what: str, resolution_deg: float) -> list[str]:
    """The sentences for angles not apart: those that agree (with the widths that could
    have shown a difference) and those the intervals cannot tell (and why)."""
    lines = []
    agree = [v for v in verdicts if v.kind == AGREE]
    cannot = [v for v in verdicts if v.kind == CANNOT_TELL]
    if agree:
        widest = max(v.combined_deg for v in agree)
        floor = max(v.floor_deg for v in agree)
        below = (f" (or by less than {floor:g} deg, not called a change)"
                 if any(abs(v.diff_deg) > v.combined_deg for v in agree) else "")
        lines.append(f"  {what} agree on {', '.join(dict.fromkeys(v.angle for v in agree))}: "
                     f"within combined half-widths of at most +-{widest:.2f} deg{below}, narrow "
                     f"enough to show a difference above --max-width {resolution_deg:g} deg")
    if cannot:
        lines.append(f"  CANNOT TELL whether {what} agree on "
                     f"{', '.join(dict.fromkeys(v.angle for v in cannot))}: the intervals are "
                     f"wider than the differences they test and than --max-width "
                     f"{resolution_deg:g} deg (" + "; ".join(v.why() for v in cannot)
                     + "): not shown apart, but not shown to agree either")
    return lines
