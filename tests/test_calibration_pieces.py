"""bench calibrate's pieces: a rotation that changes along the range is reported, a constant
one is not (simulated per-frame cues with a known rotation; the end-to-end case through
`bench calibrate` is in tests/test_calibrate.py)."""

from __future__ import annotations

import numpy as np
import pytest
from test_calibration_uncertainty import TRUTH, simulated_cues

from bench.data.calibration.estimate import FrameCues
from bench.data.calibration.pieces import (
    disagreements,
    fit_pieces,
    format_pieces,
    piece_bounds,
)


def test_piece_bounds():
    assert piece_bounds(250) == [(0, 125), (125, 250)]
    assert piece_bounds(500) == [(0, 125), (125, 250), (250, 375), (375, 500)]
    assert piece_bounds(125) == [(0, 62), (62, 125)]  # at least two pieces
    assert piece_bounds(80) == [(0, 40), (40, 80)]
    assert piece_bounds(79) == []  # two pieces would be shorter than 40 frames
    assert piece_bounds(437) == [(0, 146), (146, 291), (291, 437)]


def _joined(first: FrameCues, second: FrameCues) -> FrameCues:
    """``second``'s frames after ``first``'s, as one drive."""
    n = first.n_frames
    return FrameCues(n + second.n_frames, first.period_s,
                     np.r_[first.vel_frame, second.vel_frame + n], np.r_[first.a, second.a],
                     np.r_[first.b, second.b], np.r_[first.road_frame, second.road_frame + n],
                     np.r_[first.normals, second.normals], np.r_[first.ups, second.ups],
                     np.r_[first.heights, second.heights])


def _drive(seed: int, step_deg: float) -> FrameCues:
    """250 frames whose GT pitch against the sensor is TRUTH's for frames 0-124 and
    ``step_deg`` more for frames 125-249 (AR(1) per-frame errors, 5 % outliers)."""
    rng = np.random.default_rng(seed)
    later = {**TRUTH, "pitch": TRUTH["pitch"] + step_deg}
    return _joined(simulated_cues(rng, TRUTH, n=125), simulated_cues(rng, later, n=125))


def test_a_tilt_that_changes_half_way_is_reported_and_a_constant_one_is_not():
    """12 drives of one fixed rotation: the pieces disagree on at most 2 (measured: none; 0 of
    60 such drives); the same drives with the GT pitch 1 deg higher from frame 125: the pieces
    disagree in pitch on at least 10 (measured 11: on one, a piece's residuals stay correlated
    over 27 frames, its blocks leave 1.3 degrees of freedom and its interval spans 2.6 deg),
    each piece's estimate near its own truth."""
    fired, stepped = 0, 0
    for seed in range(12):
        fired += bool(disagreements(fit_pieces(_drive(seed, 0.0), piece_bounds(250),
                                               bootstrap=50, seed=seed)))
        pieces = fit_pieces(_drive(seed, 1.0), piece_bounds(250), bootstrap=50, seed=seed)
        stepped += any(d.angle == "pitch" for d in disagreements(pieces))
        for piece, truth in zip(pieces, (TRUTH["pitch"], TRUTH["pitch"] + 1.0), strict=True):
            assert piece.result.angles_deg["pitch"] == pytest.approx(truth, abs=0.35)
    assert fired <= 2
    assert stepped >= 10


def test_the_message_names_the_pieces_and_their_estimates():
    """Frames numbered in the store (offset 100), both pieces' pitch printed in the verdict;
    a drive without the step says the pieces agree."""
    pieces = fit_pieces(_drive(0, 1.0), piece_bounds(250), bootstrap=50)
    text = "\n".join(format_pieces(pieces, offset=100))
    assert "frames 100-224" in text and "frames 225-349" in text
    assert "THE ROTATION CHANGES ALONG THE RANGE" in text
    a, b = (p.result.angles_deg["pitch"] for p in pieces)
    assert f"pitch {a:+.2f} (frames 100-224) vs {b:+.2f} (frames 225-349)" in text
    same = "\n".join(format_pieces(fit_pieces(_drive(1, 0.0), piece_bounds(250),
                                              bootstrap=50)))
    assert "CHANGES" not in same and "the pieces agree" in same
    assert format_pieces([]) == []


def test_disagreement_is_beyond_the_combined_half_widths():
    """0.5 deg apart with half-widths 0.3 and 0.35 (combined 0.461) disagrees; with 0.3 and
    0.45 (combined 0.541) it does not; an angle one piece does not observe is not compared."""
    from types import SimpleNamespace

    from bench.data.calibration.pieces import Piece

    def piece(pitch, half, source="velocity"):
        cal = SimpleNamespace(
            angles_deg={"roll": 0.0, "pitch": pitch, "yaw": 0.0},
            interval_deg={"roll": (-1, 1), "pitch": (pitch - half, pitch + half),
                          "yaw": (-1, 1)},
            source={"roll": "road plane", "pitch": source, "yaw": "velocity"})
        return Piece(0, 1, cal)

    (d,) = disagreements([piece(-2.0, 0.3), piece(-2.5, 0.35)])
    assert (d.angle, d.first, d.second) == ("pitch", 0, 1)
    assert d.diff_deg == pytest.approx(-0.5) and d.combined_deg == pytest.approx(0.461, abs=1e-3)
    assert disagreements([piece(-2.0, 0.3), piece(-2.5, 0.45)]) == []
    assert disagreements([piece(-2.0, 0.3), piece(-5.0, 0.3, "not observable")]) == []
    assert disagreements([piece(-2.0, 0.3), Piece(1, 2, None, "too slow")]) == []
