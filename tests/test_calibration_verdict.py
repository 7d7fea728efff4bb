"""Words no stronger than the intervals (bench.data.calibration.verdict): two estimates not
shown apart "agree" only when their intervals could have shown a difference above --max-width;
wider, `bench calibrate` says it cannot tell, and why - for the pieces of the range and for the
Doppler and hand-eye estimates."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bench.data.calibration.calibrate import format_hand_eye, hand_eye_verdicts
from bench.data.calibration.hand_eye import HandEyeResult
from bench.data.calibration.pieces import Piece, format_pieces, verdicts
from bench.data.calibration.verdict import AGREE, APART, CANNOT_TELL, Verdict


@pytest.mark.parametrize(("diff", "combined", "resolution", "kind"), [
    (2.8, 6.0, 2.0, CANNOT_TELL),   # the halves: +-6 deg cannot tell 2.8 deg
    (0.3, 1.5, 2.0, AGREE),         # would have shown anything above 1.5 deg
    (0.3, 2.5, 2.0, CANNOT_TELL),   # not shown apart, but a 2.2 deg change would not show
    (2.5, 1.0, 2.0, APART),
    (0.0, float("inf"), 2.0, CANNOT_TELL),
])
def test_the_three_verdicts(diff, combined, resolution, kind):
    assert Verdict("pitch", diff, combined, resolution).kind == kind


def _piece(first, roll, pitch, half):
    cal = SimpleNamespace(
        angles_deg={"roll": roll, "pitch": pitch, "yaw": 0.0},
        interval_deg={"roll": (roll - half, roll + half), "pitch": (pitch - half, pitch + half),
                      "yaw": (-0.1, 0.1)},
        source={"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}, level=0.95)
    return Piece(first, first + 125, cal)


def test_pieces_with_wide_intervals_cannot_tell_and_never_say_one_rotation_fits():
    """The issue's case: the halves' pitch 2.8 deg and roll 3.1 deg apart, every interval
    +-6 deg: no "agree", no "one rotation fits", a "cannot tell" naming both angles."""
    pieces = [_piece(0, -1.0, -2.0, 6.0), _piece(125, 2.1, -4.8, 6.0)]
    text = "\n".join(format_pieces(pieces, resolution_deg=2.0))
    assert "CANNOT TELL" in text and "roll" in text.split("CANNOT TELL")[1]
    assert "pitch 2.80 deg apart, combined half-widths +-8.49 deg" in text
    assert "one rotation fits" not in text
    (agree,) = [line for line in text.splitlines() if line.startswith("  the pieces agree")]
    # yaw's +-0.1 intervals could tell: that angle agrees, and only that one
    assert agree.startswith("  the pieces agree on yaw:")
    # narrow intervals: the same small difference now agrees, on every angle
    narrow = [_piece(0, -1.0, -2.0, 0.5), _piece(125, -0.8, -2.2, 0.5)]
    kinds = {v.angle: v.kind for v in verdicts(narrow, 2.0)}
    assert kinds == {"roll": AGREE, "pitch": AGREE, "yaw": AGREE}
    assert "one rotation fits the range" in "\n".join(format_pieces(narrow))
    # a looser --max-width lets the wide pair agree: the words follow the stated resolution
    assert verdicts(pieces, 10.0)[0].kind == AGREE


def test_doppler_and_hand_eye_cannot_tell_with_wide_intervals():
    """Rotations 4.3 deg apart whose hand-eye intervals are +-7 deg and wider: the message says
    it cannot tell on those angles, and agrees only on the angle with narrow intervals."""
    angles = {"roll": 1.1, "pitch": -6.2, "yaw": -0.29}
    he = HandEyeResult(np.eye(3), angles, dict.fromkeys(angles, 0.5),
                       dict.fromkeys(angles, True), 125, "kiss-icp",
                       {"roll": "turn axes", "pitch": "turn axes",
                        "yaw": "displacement directions"},
                       {"roll": (-5.8, 8.1), "pitch": (-21.7, 9.4), "yaw": (-1.26, 0.68)})
    cal = SimpleNamespace(angles_deg={"roll": -1.26, "pitch": -2.58, "yaw": -0.28},
                          not_observable=[], R_gt_sensor=np.eye(3),
                          interval_deg={"roll": (-2.58, 0.07), "pitch": (-2.95, -2.20),
                                        "yaw": (-0.41, -0.15)})
    kinds = {v.angle: v.kind for v in hand_eye_verdicts(he, cal, 2.0)}
    assert kinds == {"roll": CANNOT_TELL, "pitch": CANNOT_TELL, "yaw": AGREE}
    text = "\n".join(format_hand_eye(he, cal, 2.0))
    assert "CANNOT TELL whether the two estimates agree on roll, pitch" in text
    (agree,) = [line for line in text.splitlines() if line.startswith("  the two estimates agree")]
    assert agree.startswith("  the two estimates agree on yaw:")


def test_combined_half_width_is_the_root_sum_of_squares():
    """The module's rule sqrt(h_1^2 + h_2^2): a 3-4-5 triangle, and each half counts."""
    from bench.data.calibration.verdict import combined
    assert combined(3.0, 4.0) == pytest.approx(5.0)
    assert combined(6.0, 6.0) == pytest.approx(6.0 * np.sqrt(2.0))
    assert combined(0.0, 2.0) == pytest.approx(2.0)
    assert combined(2.0, 0.0) == pytest.approx(2.0)


def test_summary_lists_every_angle_and_every_reason_in_full():
    """Two angles agree, two cannot tell (one with no finite interval): each sentence names
    all its angles comma-separated and gives every reason, separated by "; "."""
    from bench.data.calibration.verdict import summary
    vs = [Verdict("roll", 0.1, 1.0, 2.0), Verdict("pitch", -0.2, 1.5, 2.0),
          Verdict("yaw", 2.8, 6.0, 2.0), Verdict("x", -1.0, float("inf"), 2.0)]
    agree, cannot = summary(vs, "the pieces", 2.0)
    assert agree.startswith("  the pieces agree on roll, pitch: within combined half-widths "
                            "of at most +-1.50 deg")
    assert cannot == ("  CANNOT TELL whether the pieces agree on yaw, x: the intervals are "
                      "wider than the differences they test and than --max-width 2 deg "
                      "(yaw 2.80 deg apart, combined half-widths +-6.00 deg; "
                      "x 1.00 deg apart, combined half-widths no finite interval deg): "
                      "not shown apart, but not shown to agree either")
