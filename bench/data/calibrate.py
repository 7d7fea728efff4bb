"""``bench calibrate STORE``: the rotation between the sensor frame and the ground truth's frame,
estimated twice on a declared range of frames - from the Doppler ego velocity and road plane
(``bench.data.calibration``) and, independently of Doppler, by hand-eye alignment of a geometric
odometry (``bench.data.hand_eye``, KISS-ICP) - printed side by side with their difference, and
optionally a store with the ground truth corrected by one of them.

The frames used are written into the corrected store (``provenance.calibration.frames``); runs
on that store score only the other frames (``bench.runs.job``), and tables name the store
"GT calibrated on frames a-b, not scored": such results are a labelled analysis, never the
headline (the rotation was fitted to the data a method also measures).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from bench.data.calibration import (
    ANGLES,
    CalibrationResult,
    CorrectedSequence,
    calibrate_sequence,
)
from bench.data.hand_eye import HE_BLOCK_S, HandEyeResult, hand_eye_on
from loaders.errors import DataError
from loaders.scan import FrameRange

ESTIMATES = ("doppler", "hand-eye")


def _angle_line(ax: str, angle: float, interval: tuple[float, float], sd: float,
                level: float) -> str:
    lo, hi = interval
    return (f"  {ax:<5} {angle:+8.3f} deg  {100 * level:.0f} % [{lo:+.3f}, {hi:+.3f}]  "
            f"sd {sd:.3f}")


def format_result(cal: CalibrationResult) -> list[str]:
    lines = [f"Doppler ego velocity + road plane: R_gt_sensor from {cal.frames_used} frames "
             f"(rotation {cal.total_deg:.3f} deg):"]
    for ax in ANGLES:
        lines.append(_angle_line(ax, cal.angles_deg[ax], cal.interval_deg[ax], cal.std_deg[ax],
                                 cal.level) + f"  ({cal.source[ax]})")
    if cal.block is not None:
        lines.append("  uncertainty: " + cal.block.describe(
            cal.resamples, cal.frames_total, "each refitted with its own outlier cut"))
    if cal.not_observable:
        lines.append(f"  not observable: {', '.join(cal.not_observable)} (reported as 0)")
    r = cal.road
    if r:
        lines.append(
            f"road plane ({int(r['frames'])} frames): sensor {r['height_m']:.2f} m above it; "
            f"road tilt in the sensor frame pitch {r['road_pitch_in_sensor_deg']:+.2f} / roll "
            f"{r['road_roll_in_sensor_deg']:+.2f} deg, world up in the GT frame pitch "
            f"{r['up_pitch_in_gt_deg']:+.2f} / roll {r['up_roll_in_gt_deg']:+.2f} deg")
    else:
        lines.append("road plane: not found (too few points below the sensor)")
    return lines


def _half_width(interval: tuple[float, float]) -> float:
    return 0.5 * (interval[1] - interval[0])


def disagreements(he: HandEyeResult, cal: CalibrationResult) -> list[str]:
    """The angles both estimates observe on which their difference exceeds the combined
    half-widths of their stated intervals, ``sqrt(h_he^2 + h_doppler^2)``."""
    out = []
    for ax in ANGLES:
        if not he.observable[ax] or ax in cal.not_observable:
            continue
        diff = he.angles_deg[ax] - cal.angles_deg[ax]
        width = float(np.hypot(_half_width(he.interval_deg[ax]),
                               _half_width(cal.interval_deg[ax])))
        if not abs(diff) <= width:
            out.append(f"{ax} ({diff:+.2f} deg apart, combined +- {width:.2f})")
    return out


def format_hand_eye(he: HandEyeResult, cal: CalibrationResult) -> list[str]:
    lines = [f"hand-eye alignment of {he.odometry} (no Doppler): R_gt_sensor from "
             f"{he.segments} segments (turn axes first, then displacement directions):"]
    for ax in ANGLES:
        how = he.source.get(ax, "") if he.observable[ax] else "not observable"
        lines.append(_angle_line(ax, he.angles_deg[ax], he.interval_deg[ax], he.std_deg[ax],
                                 he.level)
                     + f"  difference to Doppler {he.angles_deg[ax] - cal.angles_deg[ax]:+.3f} "
                     f"deg  ({how})")
    if he.block is not None:
        lines.append("  uncertainty: " + he.block.describe(
            he.resamples, he.frames_total,
            f"both stages refitted on each; blocks of at least {HE_BLOCK_S:g} s asked"))
    between = Rotation.from_matrix(he.R_gt_sensor @ cal.R_gt_sensor.T).magnitude()
    lines.append(f"  the two rotations differ by {np.degrees(between):.3f} deg in all")
    apart = disagreements(he, cal)
    if apart:
        lines.append(
            f"  DISAGREE beyond their stated uncertainties in {', '.join(apart)}: at least "
            "one estimate is biased (Doppler: the GT's own velocity and the road plane; "
            "hand-eye: the odometry's drift and the lever arm), so neither is exact; check "
            "with `bench inspect` before applying one")
    else:
        lines.append("  the two agree within their combined intervals on every angle both "
                     "observe")
    return lines


def calibration_frames(n: int, start: int, frames: int | None) -> tuple[int, int]:
    """[first, stop) of the frames to estimate on: ``frames`` from ``start``, by default the
    first half of the store (the rest stays for scoring)."""
    count = frames if frames is not None else (n - start) // 2
    if start < 0 or count < 5 or start + count > n:
        raise DataError(f"calibration frames start={start}, frames={count}: expected at least "
                        f"5 frames within the store's {n}")
    return start, start + count


def calibrate_store(path: str | Path, write_to: Path | None = None, console=None,
                    min_speed_mps: float = 2.0, bootstrap: int = 200, start: int = 0,
                    frames: int | None = None, apply: str = "doppler",
                    hand_eye: bool = True) -> CalibrationResult:
    """Estimate on the store's frames ``start`` .. (default: its first half), print both
    estimates to ``console`` and, given ``write_to``, write the store with its ground truth
    corrected by the ``apply`` estimate and the frames used recorded."""
    from bench import guard
    from loaders.store import StoreSequence, write_store

    if apply not in ESTIMATES:
        raise DataError(f"--apply {apply!r}: choose from {', '.join(ESTIMATES)}")
    seq = StoreSequence(path)
    try:
        first, stop = calibration_frames(len(seq), start, frames)
        part = FrameRange(seq, first, stop - first)
        say = (lambda line: console.print(line, highlight=False)) if console else (lambda _: 0)
        say(f"{path}: estimating on frames {first}-{stop - 1} of {len(seq)} (runs on a "
            "corrected store score only the others)")
        if stop - first == len(seq):
            say("note: every frame is used, so runs on a corrected store have none to score")
        cal = calibrate_sequence(part, min_speed_mps=min_speed_mps, bootstrap=bootstrap)
        for line in format_result(cal):
            say(line)
        he = None
        if hand_eye or apply == "hand-eye":
            try:
                he = hand_eye_on(part, bootstrap=bootstrap)
            except DataError as err:
                if apply == "hand-eye":
                    raise
                say(f"hand-eye alignment (no Doppler): not possible here: {err}")
            if he is not None:
                for line in format_hand_eye(he, cal):
                    say(line)
        if write_to is not None:
            R = cal.R_gt_sensor if apply == "doppler" else he.R_gt_sensor
            details = {"applied_estimate": apply, "doppler_rpy_deg": list(cal.angles_deg.values())}
            if he is not None:
                details["hand_eye_rpy_deg"] = list(he.angles_deg.values())
            guard.replaceable(write_to, None, guard.is_store, "a store", "--write", [path])
            write_store(CorrectedSequence(seq, R, (first, stop), details), write_to)
            say(f"wrote {write_to} (ground truth and extrinsic corrected by the {apply} "
                f"estimate, points unchanged; frames {first}-{stop - 1} are not scored)")
    finally:
        seq.close()
    return cal
