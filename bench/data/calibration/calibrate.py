"""``bench calibrate STORE``: the rotation between the sensor frame and the ground truth's frame,
estimated twice on a declared range of frames - from the Doppler ego velocity and road plane
(``bench.data.calibration.estimate``) and, independently of Doppler, by hand-eye alignment of a
geometric
odometry (``bench.data.calibration.hand_eye``, KISS-ICP) - printed side by side with their
difference, and
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

from bench.data.calibration.estimate import (
    ANGLES,
    CalibrationResult,
    CorrectedSequence,
    calibrate_cues,
    collect_cues,
)
from bench.data.calibration.hand_eye import HE_BLOCK_S, HandEyeResult, hand_eye_on
from bench.data.calibration.pieces import fit_pieces, format_pieces, piece_bounds
from bench.data.calibration.verdict import Verdict, summary
from bench.data.calibration.write import (
    WRITE_MAX_WIDTH_DEG,
    applied_rotation,
    check_write_target,
    describe_selection,
    select_angles,
)
from loaders.errors import DataError
from loaders.scan import FrameRange

ESTIMATES = ("doppler", "hand-eye")


#: an interval narrower than this [deg] prints as "narrower than" (3 decimals show no width)
RESOLUTION_DEG = 1e-3
#: an angle whose block leaves fewer degrees of freedom than this gets a line saying why
MIN_DOF = 2.0


def _angle_line(ax: str, angle: float, interval: tuple[float, float], sd: float,
                level: float, source: str, reason: str = "", resamples: int = 0) -> str:
    """One angle: its estimate, interval and sd; no number for an angle not observable (with
    ``reason``), and never a zero-width interval."""
    if source == "not observable":
        return f"  {ax:<5} not observable" + (f": {reason}" if reason else "")
    lo, hi = interval
    head = f"  {ax:<5} {angle:+8.3f} deg  "
    if not np.isfinite(hi - lo):
        return head + f"no interval ({resamples} resamples could be fitted)  ({source})"
    if hi - lo < RESOLUTION_DEG:
        return (head + f"{100 * level:.0f} % interval narrower than {RESOLUTION_DEG:g} deg "
                f"(every resample gives the same angle)  sd < {RESOLUTION_DEG:g}  ({source})")
    return (head + f"{100 * level:.0f} % [{lo:+.3f}, {hi:+.3f}]  sd {sd:.3f}  ({source})")


def _blocks_lines(cal: CalibrationResult) -> list[str]:
    """How the frames were resampled and, when the block leaves fewer than ``MIN_DOF`` degrees
    of freedom or was capped at half the frames, which residuals made it so long and what that
    means for the intervals."""
    b, n = cal.block, cal.frames_total
    lines = ["  uncertainty: " + b.describe(cal.resamples, n,
                                            "each refitted with its own outlier cut")]
    if b.dof(n) >= MIN_DOF and not b.capped:
        return lines
    lengths = dict(zip(cal.fitted, b.correlation, strict=False))
    longest = max(lengths, key=lengths.get) if lengths else "the"
    lines.append(
        f"  few blocks: the {longest} residuals stay correlated over "
        f"{lengths.get(longest, b.wanted // 2)} frames, so the blocks are {b.frames} of the "
        f"{n} frames ({n / b.frames:.1f} blocks, {b.dof(n):.1f} degrees of freedom) and every "
        "interval is wide: the fit's error wanders along the range (the pieces show how far), "
        "it does not mean an angle is unobservable; each is printed with its estimate")
    return lines


def format_result(cal: CalibrationResult) -> list[str]:
    lines = [f"Doppler ego velocity + road plane: R_gt_sensor from {cal.frames_used} frames "
             f"(rotation {cal.total_deg:.3f} deg):"]
    for ax in ANGLES:
        lines.append(_angle_line(ax, cal.angles_deg[ax], cal.interval_deg[ax], cal.std_deg[ax],
                                 cal.level, cal.source[ax], cal.reasons.get(ax, ""),
                                 cal.resamples))
    if cal.block is not None:
        lines += _blocks_lines(cal)
    if cal.not_observable:
        lines.append(f"  not observable: {', '.join(cal.not_observable)} (held at 0 in the "
                     "fit; --write leaves them alone)")
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
    half-widths of their stated intervals, ``sqrt(h_he^2 + h_doppler^2)`` (an angle without
    a finite interval on either side is not apart: ``hand_eye_verdicts`` says the intervals
    cannot tell)."""
    out = []
    for ax in ANGLES:
        if not he.observable[ax] or ax in cal.not_observable:
            continue
        diff = he.angles_deg[ax] - cal.angles_deg[ax]
        width = float(np.hypot(_half_width(he.interval_deg[ax]),
                               _half_width(cal.interval_deg[ax])))
        if np.isfinite(width) and abs(diff) > width:
            out.append(f"{ax} ({diff:+.2f} deg apart, combined +- {width:.2f})")
    return out


def hand_eye_verdicts(he: HandEyeResult, cal: CalibrationResult,
                      resolution_deg: float = WRITE_MAX_WIDTH_DEG) -> list[Verdict]:
    """Per angle both estimates observe: their difference against the combined half-widths
    of their intervals, and what that can tell at ``resolution_deg`` (``--max-width``)."""
    out = []
    for ax in ANGLES:
        if not he.observable[ax] or ax in cal.not_observable:
            continue
        width = float(np.hypot(_half_width(he.interval_deg[ax]),
                               _half_width(cal.interval_deg[ax])))
        out.append(Verdict(ax, he.angles_deg[ax] - cal.angles_deg[ax],
                           width if np.isfinite(width) else float("inf"), resolution_deg))
    return out


def format_hand_eye(he: HandEyeResult, cal: CalibrationResult,
                    resolution_deg: float = WRITE_MAX_WIDTH_DEG) -> list[str]:
    lines = [f"hand-eye alignment of {he.odometry} (no Doppler): R_gt_sensor from "
             f"{he.segments} segments (turn axes first, then displacement directions):"]
    for ax in ANGLES:
        if not he.observable[ax]:
            lines.append(_angle_line(ax, 0.0, (np.nan, np.nan), np.nan, he.level,
                                     "not observable", "neither the turn axes nor the "
                                     "displacement directions spread around it"))
            continue
        line = _angle_line(ax, he.angles_deg[ax], he.interval_deg[ax], he.std_deg[ax],
                           he.level, he.source.get(ax, ""), resamples=he.resamples)
        if ax not in cal.not_observable:
            line += f"  difference to Doppler {he.angles_deg[ax] - cal.angles_deg[ax]:+.3f} deg"
        lines.append(line)
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
        lines += summary(hand_eye_verdicts(he, cal, resolution_deg), "the two estimates",
                         resolution_deg)
    return lines


def calibration_frames(n: int, start: int, frames: int | None) -> tuple[int, int]:
    """[first, stop) of the frames to estimate on: ``frames`` from ``start``, by default the
    first half of the store (the rest stays for scoring)."""
    count = frames if frames is not None else (n - start) // 2
    if start < 0 or count < 5 or start + count > n:
        raise DataError(f"calibration frames start={start}, frames={count}: expected at least "
                        f"5 frames within the store's {n}")
    return start, start + count


def _check_ground_truth(seq, path, first: int, stop: int) -> None:
    """DataError naming the store when no scan of frames first .. stop - 1 has ground truth
    (e.g. a GT on another clock) or the store has none."""
    gt = seq.ground_truth
    if gt is None:
        raise DataError(f"{path}: calibration needs ground truth; this store has none")
    stamps = seq.stamps[first:stop]
    covered = int(gt.coverage_mask(stamps).sum())
    if covered >= 3:
        return
    span = (f"the store's ground truth spans {gt.stamps[0]:.3f}-{gt.stamps[-1]:.3f} s"
            if len(gt.stamps) else "the store's ground truth has no poses")
    what = "no scan" if covered == 0 else f"only {covered} of the {len(stamps)} scans"
    raise DataError(f"{path}: {what} of frames {first}-{stop - 1} has ground truth ({span}, "
                    f"the scans {stamps[0]:.3f}-{stamps[-1]:.3f} s); calibration needs the GT "
                    "velocity at 3 or more scans: check the GT's clock (`bench inspect` shows "
                    "its coverage)")


def calibrate_store(path: str | Path, write_to: Path | None = None, console=None,
                    min_speed_mps: float = 2.0, bootstrap: int = 200, start: int = 0,
                    frames: int | None = None, apply: str = "doppler",
                    hand_eye: bool = True, max_width_deg: float = WRITE_MAX_WIDTH_DEG,
                    force: bool = False) -> CalibrationResult:
    """Estimate on the store's frames ``start`` .. (default: its first half), print both
    estimates and the pieces of the range to ``console`` and, given ``write_to`` (never the
    input; an existing store bench calibrate wrote only with ``force``), write the store with
    its ground truth corrected by the angles of the ``apply`` estimate whose interval is
    narrower than ``max_width_deg``, and the frames used recorded."""
    from bench import guard
    from bench.data.calibration.write import written_by_calibrate
    from loaders.store import StoreSequence

    if apply not in ESTIMATES:
        raise DataError(f"--apply {apply!r}: choose from {', '.join(ESTIMATES)}")
    if not (np.isfinite(max_width_deg) and max_width_deg > 0):
        raise DataError(f"--max-width {max_width_deg}: expected a positive number of degrees")
    if write_to is not None:
        check_write_target(Path(path), Path(write_to), force)
    seq = StoreSequence(path)
    try:
        from bench.data.advice import doppler_refusal

        refusal = doppler_refusal(path, "calibration from Doppler", seq)
        if refusal is not None:  # the words bench run refuses such a store with
            raise DataError(refusal)
        first, stop = calibration_frames(len(seq), start, frames)
        _check_ground_truth(seq, path, first, stop)
        part = FrameRange(seq, first, stop - first)
        say = (lambda line: console.print(line, highlight=False)) if console else (lambda _: 0)
        say(f"{path}: estimating on frames {first}-{stop - 1} of {len(seq)} (runs on a "
            "corrected store score only the others)")
        if stop - first == len(seq):
            say("note: every frame is used, so runs on a corrected store have none to score")
        name = f"{path} frames {first}-{stop - 1}"
        cues = collect_cues(part, min_speed_mps, name)
        cal = calibrate_cues(cues, bootstrap=bootstrap, name=name)
        for line in format_result(cal):
            say(line)
        for line in format_pieces(fit_pieces(cues, piece_bounds(cues.n_frames),
                                             bootstrap=bootstrap, name=name), first,
                                  max_width_deg):
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
                for line in format_hand_eye(he, cal, max_width_deg):
                    say(line)
        chosen = cal if apply == "doppler" else he
        fitted = ({ax: ax not in cal.not_observable for ax in ANGLES} if apply == "doppler"
                  else dict(he.observable))
        applied, left = select_angles(chosen.angles_deg, chosen.interval_deg, fitted,
                                      max_width_deg)
        selection = describe_selection(applied, left, max_width_deg, chosen.level)
        if write_to is None:
            say(selection.replace("--write applies", "--write would apply", 1))
            return cal
        say(selection)
        details = {"applied_estimate": apply, "doppler_rpy_deg": list(cal.angles_deg.values()),
                   "applied_rpy_deg": [applied.get(ax, 0.0) for ax in ANGLES],
                   "left_alone": left, "max_width_deg": float(max_width_deg)}
        if he is not None:
            details["hand_eye_rpy_deg"] = list(he.angles_deg.values())
        # --force replaces a store bench calibrate wrote, never another store nor any file
        guard.replaceable(write_to, force, written_by_calibrate,
                          "a store bench calibrate wrote", "--write", [path])
        guard.write_store(CorrectedSequence(seq, applied_rotation(applied), (first, stop),
                                            details), write_to, written_by_calibrate,
                          "a store bench calibrate wrote")
        say(f"wrote {write_to} (ground truth and extrinsic corrected by the {apply} "
            f"estimate's applied angles, points unchanged; frames {first}-{stop - 1} are not "
            "scored)")
    finally:
        seq.close()
    return cal
