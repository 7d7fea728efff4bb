"""``bench calibrate STORE``: print the sensor-to-GT rotation (``bench.data.calibration``) and
optionally write a store with the ground truth corrected."""

from __future__ import annotations

from pathlib import Path

from bench.data.calibration import ANGLES, CalibrationResult, CorrectedSequence, calibrate_sequence


def format_result(cal: CalibrationResult) -> list[str]:
    lines = [f"R_gt_sensor from {cal.frames_used} frames (rotation {cal.total_deg:.3f} deg):"]
    for ax in ANGLES:
        lines.append(f"  {ax:<5} {cal.angles_deg[ax]:+8.3f} deg  +- {cal.std_deg[ax]:.3f}  "
                     f"({cal.source[ax]})")
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


def calibrate_store(path: str | Path, write_to: Path | None = None, console=None,
                    min_speed_mps: float = 2.0, bootstrap: int = 200) -> CalibrationResult:
    """Calibrate the store at ``path``; print the result to ``console`` (a rich Console) and,
    given ``write_to``, write a corrected store there (ground truth corrected, see above)."""
    from loaders.store import StoreSequence, write_store

    seq = StoreSequence(path)
    cal = calibrate_sequence(seq, min_speed_mps=min_speed_mps, bootstrap=bootstrap)
    if console is not None:
        for line in format_result(cal):
            console.print(line, highlight=False)
    if write_to is not None:
        write_store(CorrectedSequence(seq, cal.R_gt_sensor), write_to)
        if console is not None:
            console.print(f"wrote {write_to} (ground truth and extrinsic corrected, points "
                          "unchanged)", highlight=False)
    return cal
