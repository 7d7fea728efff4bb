"""The rules of bench calibrate's pieces (bench.data.calibration.pieces) on hand-made piece
fits: how a range is split, which pairs are compared, the 0.3 deg floor and the half-width rule
at their boundaries, and what the printed lines say. Each expectation follows from the
module's definitions (the docstrings), not from its output."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import bench.data.calibration.pieces as pieces_mod
from bench.data.calibration.pieces import (
    MIN_CHANGE_DEG,
    Piece,
    disagreements,
    fit_pieces,
    format_pieces,
    piece_bounds,
    verdicts,
)
from bench.data.calibration.verdict import AGREE, CANNOT_TELL
from loaders.errors import DataError

SOURCES = {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}


def fit(pitch=-2.0, half=0.1, *, roll=0.5, yaw=0.2, source=None, level=0.95, halves=None):
    """A piece's fit: the angles, +-``half`` intervals (``halves`` per angle overrides)."""
    angles = {"roll": roll, "pitch": pitch, "yaw": yaw}
    halves = {**dict.fromkeys(angles, half), **(halves or {})}
    return SimpleNamespace(
        angles_deg=angles,
        interval_deg={a: (v - halves[a], v + halves[a]) for a, v in angles.items()},
        source={**SOURCES, **(source or {})}, level=level)


def piece(first, stop, cal, error=""):
    return Piece(first, stop, cal, error)


# ---------------------------------------------------------------- piece_bounds


def test_piece_bounds_cover_the_range_with_pieces_of_about_the_asked_length():
    """Explicit lengths: 300 frames of pieces of 100 -> three; a minimum of 160 leaves room for
    one only -> no split; round(n / piece) decides the count (349/100 -> 3, 351/100 -> 4)."""
    assert piece_bounds(300, piece_frames=100, min_frames=40) == [(0, 100), (100, 200),
                                                                  (200, 300)]
    assert piece_bounds(300, piece_frames=100, min_frames=160) == []
    assert piece_bounds(300, piece_frames=100, min_frames=150) == [(0, 150), (150, 300)]
    assert len(piece_bounds(349, piece_frames=100, min_frames=10)) == 3
    assert len(piece_bounds(351, piece_frames=100, min_frames=10)) == 4
    # the defaults: 125 frames, at least 40 per piece
    assert piece_bounds(1000) == [(125 * k, 125 * (k + 1)) for k in range(8)]
    assert piece_bounds(81) == [(0, 40), (40, 81)] and piece_bounds(79) == []
    assert all(isinstance(x, int) for b in piece_bounds(437) for x in b)


# ---------------------------------------------------------------- fit_pieces


def test_fit_pieces_fits_each_piece_alone_and_keeps_the_error_of_one_that_cannot(monkeypatch):
    """Each piece gets its own frames (cues.piece(first, stop)) and the options; a piece whose
    fit raises DataError is kept with the message and no result."""
    calls = []

    class Cues:
        def piece(self, first, stop):
            return (first, stop)

    def fake(cues, **options):
        calls.append((cues, options))
        if cues == (40, 80):
            raise DataError("only 3 frames faster than 2 m/s")
        return f"fit of {cues}"

    monkeypatch.setattr(pieces_mod, "calibrate_cues", fake)
    out = fit_pieces(Cues(), [(0, 40), (40, 80), (80, 120)], bootstrap=7, seed=3)
    assert calls == [((0, 40), {"bootstrap": 7, "seed": 3}), ((40, 80), {"bootstrap": 7,
                                                                         "seed": 3}),
                     ((80, 120), {"bootstrap": 7, "seed": 3})]
    assert [(p.first, p.stop) for p in out] == [(0, 40), (40, 80), (80, 120)]
    assert out[0].result == "fit of (0, 40)" and out[0].error == ""
    assert out[1].result is None and out[1].error == "only 3 frames faster than 2 m/s"
    assert out[2].result == "fit of (80, 120)"


# ---------------------------------------------------------------- disagreements


def test_the_floor_decides_when_the_half_widths_are_narrow():
    """Half-widths 0.1 and 0.1 (combined 0.141): apart only beyond MIN_CHANGE_DEG = 0.3
    deg - 0.31 deg apart is reported, 0.29 deg is not, in either direction."""
    assert MIN_CHANGE_DEG == 0.3
    (d,) = disagreements([piece(0, 50, fit(-2.0)), piece(50, 100, fit(-2.31))])
    assert (d.angle, d.first, d.second) == ("pitch", 0, 1)
    assert d.diff_deg == pytest.approx(-0.31)
    assert d.combined_deg == pytest.approx(np.hypot(0.1, 0.1))
    (d,) = disagreements([piece(0, 50, fit(-2.0)), piece(50, 100, fit(-1.69))])
    assert d.diff_deg == pytest.approx(0.31)
    assert disagreements([piece(0, 50, fit(-2.0)), piece(50, 100, fit(-2.29))]) == []
    assert disagreements([piece(0, 50, fit(-2.0)), piece(50, 100, fit(-1.71))]) == []


def test_exactly_at_the_floor_or_the_half_widths_is_not_apart():
    """"Further apart than": a difference of exactly MIN_CHANGE_DEG (half-widths 0.125,
    combined 0.177) is not apart, nor one of exactly the combined half-widths (0.375 and 0.5
    combine to 0.625, all exact in binary)."""
    assert disagreements([piece(0, 50, fit(0.0, 0.125)),
                          piece(50, 100, fit(MIN_CHANGE_DEG, 0.125))]) == []
    assert disagreements([piece(0, 50, fit(0.0, halves={"pitch": 0.375})),
                          piece(50, 100, fit(0.625, halves={"pitch": 0.5}))]) == []
    (d,) = disagreements([piece(0, 50, fit(0.0, halves={"pitch": 0.375})),
                          piece(50, 100, fit(0.6875, halves={"pitch": 0.5}))])
    assert d.combined_deg == 0.625


def test_the_half_widths_decide_when_they_are_wider_than_the_floor():
    """Half-widths 0.6 and 0.8 (combined exactly 1.0): 1.05 deg apart disagrees, 0.95 does
    not; the other angles, equal, are never reported."""
    (d,) = disagreements([piece(0, 50, fit(-2.0, halves={"pitch": 0.6})),
                          piece(50, 100, fit(-3.05, halves={"pitch": 0.8}))])
    assert d.angle == "pitch" and d.combined_deg == pytest.approx(1.0)
    assert disagreements([piece(0, 50, fit(-2.0, halves={"pitch": 0.6})),
                          piece(50, 100, fit(-2.95, halves={"pitch": 0.8}))]) == []


def test_no_finite_interval_is_never_apart():
    """A piece without an interval (NaN bounds) cannot show a change, however far apart."""
    nan = fit(-9.0)
    nan.interval_deg["pitch"] = (float("nan"), float("nan"))
    assert disagreements([piece(0, 50, fit(-2.0)), piece(50, 100, nan)]) == []


def test_every_pair_is_compared_not_only_neighbours():
    """Three pieces, the first and last 1 deg apart, the middle one between with a wide
    interval on pitch: the pair (0, 2) is the one reported; a failed piece in the middle does
    not stop the comparison of the others."""
    mid = fit(-2.5, halves={"pitch": 3.0})
    found = disagreements([piece(0, 50, fit(-2.0)), piece(50, 100, mid),
                           piece(100, 150, fit(-3.0))])
    assert [(d.angle, d.first, d.second) for d in found] == [("pitch", 0, 2)]
    found = disagreements([piece(0, 50, fit(-2.0)), piece(50, 100, None, "too slow"),
                           piece(100, 150, fit(-3.0))])
    assert [(d.angle, d.first, d.second) for d in found] == [("pitch", 0, 2)]
    # the failed piece first: the others are still compared
    found = disagreements([piece(0, 50, None, "too slow"), piece(50, 100, fit(-2.0)),
                           piece(100, 150, fit(-3.0))])
    assert [(d.first, d.second) for d in found] == [(1, 2)]


def test_only_angles_fitted_from_the_same_cue_are_compared():
    """Roll from the road plane in one piece and the velocity in the other: not compared,
    however far apart; roll not observable in both: not compared either; yaw, later in the
    angle order, is still compared."""
    a = fit(-2.0, roll=0.0, yaw=0.0)
    b = fit(-2.0, roll=5.0, yaw=1.0, source={"roll": "velocity"})
    assert [d.angle for d in disagreements([piece(0, 50, a), piece(50, 100, b)])] == ["yaw"]
    c = fit(-2.0, roll=0.0, source={"roll": "not observable"})
    d = fit(-2.0, roll=5.0, source={"roll": "not observable"})
    assert disagreements([piece(0, 50, c), piece(50, 100, d)]) == []
    assert [v.angle for v in verdicts([piece(0, 50, c), piece(50, 100, d)])] == ["pitch", "yaw"]


# ---------------------------------------------------------------- verdicts


def test_verdicts_keep_the_pair_that_says_least():
    """Per angle, the pair the intervals cannot tell with the widest combined half-width, else
    the widest agreeing pair; an angle apart somewhere gets no verdict here; the floor is
    MIN_CHANGE_DEG and the resolution the one asked for."""
    p = [piece(0, 50, fit(-2.0, 0.1, halves={"roll": 1.0})),
         piece(50, 100, fit(-2.05, 0.2, halves={"roll": 2.0})),
         piece(100, 150, fit(-2.1, 0.3, halves={"roll": 0.5}))]
    got = {v.angle: v for v in verdicts(p, 2.0)}
    assert set(got) == {"roll", "pitch", "yaw"}
    # pitch and yaw agree; the widest agreeing pair is (1, 2): hypot(0.2, 0.3)
    assert got["pitch"].kind == AGREE
    assert got["pitch"].combined_deg == pytest.approx(np.hypot(0.2, 0.3))
    assert got["pitch"].diff_deg == pytest.approx(-0.05)
    assert got["pitch"].resolution_deg == 2.0 and got["pitch"].floor_deg == MIN_CHANGE_DEG
    # roll: pairs (0,1) 2.24 and (1,2) 2.06 cannot tell, (0,2) 1.12 agrees -> the widest
    assert got["roll"].kind == CANNOT_TELL
    assert got["roll"].combined_deg == pytest.approx(np.hypot(1.0, 2.0))
    # with pitch apart between the first and last piece: no verdict on pitch
    q = [piece(0, 50, fit(-2.0)), piece(50, 100, fit(-2.1)), piece(100, 150, fit(-3.0))]
    assert sorted(v.angle for v in verdicts(q, 2.0)) == ["roll", "yaw"]


def test_verdicts_default_resolution_is_the_write_bound_and_no_interval_cannot_tell():
    """Default resolution: WRITE_MAX_WIDTH_DEG (2 deg) - a combined half-width of 1.9 agrees,
    2.1 cannot tell; an angle without a finite interval cannot tell (infinite width)."""
    h = 1.9 / np.sqrt(2)
    (v,) = [v for v in verdicts([piece(0, 50, fit(-2.0, h)), piece(50, 100, fit(-2.0, h))])
            if v.angle == "pitch"]
    assert v.kind == AGREE and v.resolution_deg == 2.0
    h = 2.1 / np.sqrt(2)
    (v,) = [v for v in verdicts([piece(0, 50, fit(-2.0, h)), piece(50, 100, fit(-2.0, h))])
            if v.angle == "pitch"]
    assert v.kind == CANNOT_TELL
    nan = fit(-2.0)
    nan.interval_deg["pitch"] = (float("nan"), float("nan"))
    (v,) = [v for v in verdicts([piece(0, 50, fit(-2.0)), piece(50, 100, nan)])
            if v.angle == "pitch"]
    assert v.kind == CANNOT_TELL and v.combined_deg == float("inf")


# ---------------------------------------------------------------- format_pieces


def test_the_table_names_each_piece_its_frames_and_each_angle():
    """Frames first..stop-1 numbered from the offset, the level as a percentage, each angle
    with its estimate and interval; an unseen angle says so and prints no number; an angle
    without an interval says so; a failed piece prints its error."""
    a = fit(-2.0, 0.25, level=0.9, source={"roll": "not observable"})
    b = fit(-2.1, 0.25, source={"roll": "not observable"})
    b.interval_deg["yaw"] = (float("nan"), float("nan"))
    lines = format_pieces([piece(0, 50, a), piece(50, 100, b), piece(100, 150, None,
                                                                     "too slow here")],
                          offset=10)
    assert lines[0] == "pieces of the range, each fitted on its own (90 % intervals):"
    assert lines[1] == ("  frames 10-59     roll not observable  pitch -2.00 [-2.25, -1.75]"
                        "  yaw +0.20 [-0.05, +0.45]")
    assert lines[2].startswith("  frames 60-109    roll not observable  pitch -2.10 ")
    assert lines[2].endswith("yaw +0.20 (no interval)")
    assert lines[3] == "  frames 110-159   too slow here"


def test_the_level_comes_from_the_first_fitted_piece_or_95():
    """The first piece failed: the level is the second's; none fitted: 95 %."""
    lines = format_pieces([piece(0, 50, None, "x"), piece(50, 100, fit(level=0.8))])
    assert "(80 % intervals)" in lines[0]
    lines = format_pieces([piece(0, 50, None, "x"), piece(50, 100, None, "y")])
    assert "(95 % intervals)" in lines[0]
    # frames numbered from 0 by default
    assert lines[1] == "  frames 0-49      x" and lines[2] == "  frames 50-99     y"
    assert "no angle is fitted by two pieces from the same cue: nothing to compare" in lines[-1]


def test_agreeing_pieces_say_one_rotation_fits_and_a_floor_note_when_beyond_the_intervals():
    """Narrow intervals 0.2 deg apart (combined 0.141, below the 0.3 deg floor): they agree,
    with the note that a difference under 0.3 deg is not called a change; one rotation
    fits."""
    text = "\n".join(format_pieces([piece(0, 50, fit(-2.0)), piece(50, 100, fit(-2.2))]))
    assert "the pieces agree on roll, pitch, yaw" in text
    assert "or by less than 0.3 deg, not called a change" in text
    assert "  one rotation fits the range on every angle compared" in text.splitlines()
    assert "CHANGES" not in text
    # one angle cannot tell: not "one rotation fits"
    wide = "\n".join(format_pieces([piece(0, 50, fit(-2.0, halves={"roll": 3.0})),
                                    piece(50, 100, fit(-2.2))], resolution_deg=2.0))
    assert "CANNOT TELL whether the pieces agree on roll" in wide
    assert "one rotation fits" not in wide
    assert "--max-width 2 deg" in wide
    # the resolution passed through: --max-width 5 lets roll agree
    loose = "\n".join(format_pieces([piece(0, 50, fit(-2.0, halves={"roll": 3.0})),
                                     piece(50, 100, fit(-2.2))], resolution_deg=5.0))
    assert "one rotation fits" in loose and "--max-width 5 deg" in loose


def test_a_change_names_the_angle_both_estimates_pieces_and_numbers():
    """Pitch 1 deg apart against combined half-widths 0.14: the line names the pieces (with the
    offset), both estimates, the difference and the combined half-width."""
    lines = format_pieces([piece(0, 125, fit(-2.0)), piece(125, 250, fit(-3.0)),
                           piece(250, 375, fit(-2.0))], offset=100)
    last = lines[-1]
    assert last.startswith("  THE ROTATION CHANGES ALONG THE RANGE: the pieces disagree")
    assert ("pitch -2.00 (frames 100-224) vs -3.00 (frames 225-349), 1.00 deg apart against "
            "combined half-widths 0.14") in last
    assert ("pitch -3.00 (frames 225-349) vs -2.00 (frames 350-474), 1.00 deg apart") in last
    assert ("1.00 deg apart against combined half-widths 0.14; pitch -3.00 (frames 225-349)"
            in last)
    # what the change means for the estimate and a store written with it
    assert last.endswith(". The GT frame's tilt (or the mount) is not the same over the whole "
                         "range: the estimate above is an average over it, and a store written "
                         "with it is corrected by that average on every frame")
    assert not any("pieces agree" in line or "CANNOT TELL" in line for line in lines)
