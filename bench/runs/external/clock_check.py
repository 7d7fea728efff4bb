"""The clock checks of ``bench score`` (``bench.runs.external.score``): what is refused and what is
said to fit, from the motion profiles of ``bench.runs.external.clock``.

- stamps that look like another unit (ms / us / ns read as s, s read as ms ...): refused
  naming the ``--stamp-unit`` that fits;
- stamps that no longer increase once offset (an offset too large for their precision);
- a misfit (``clock_misfit``): the profiles line up only shifted by more than
  ``CLOCK_MAX_SHIFT_S``, or fit more than ``CLOCK_FIT_MARGIN`` better at another shift than
  unshifted: refused naming the ``--time-offset`` that fits (``aligned_offset``: one that lines
  the stamps up too), even when every stamp matches;
- no scan within the tolerance: ``fit_hint`` says the offset that fits.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.runs.external.clock import ClockFit, aligned_offset, fit_clock, stamp_scale
from loaders.errors import DataError
from loaders.estimate import STAMP_UNITS
from loaders.trajectory import Trajectory

#: a shift beyond this [s] is a misfit whatever the correlations (the profiles of a real
#: odometry are broad: on the NTU sample its own runs fit within 0.07 s of no shift, and their
#: correlation unshifted is within 0.02 of the best for shifts up to 0.4 s)
CLOCK_MAX_SHIFT_S = 0.2
#: below that, a misfit only where the best correlation exceeds the one unshifted by more
#: than this (on the NTU sample a copy of its ground truth 0.05 s off: by 0.008, passes; 0.1 s
#: off: by 0.022, refused; the harness's own runs: by < 0.001)
CLOCK_FIT_MARGIN = 0.01
UNIT_NAMES = {"s": "seconds", "ms": "milliseconds", "us": "microseconds",
              "ns": "nanoseconds"}


def check_clock(est: Trajectory, T_frame_sensor: np.ndarray, gt: Trajectory,
                scan_stamps: np.ndarray, time_offset_s: float, trust_clock: bool, where: str,
                store: str, unit: str = "s") -> tuple[ClockFit | None, str]:
    """The estimate's clock against the ground truth's (``bench.runs.external.clock``):
    stamps in another unit (``unit``: the one they were read in) are refused here; returns the
    motion-profile fit (None with ``trust_clock``) and a line saying what was found."""
    est_stamps = est.stamps + time_offset_s
    if not np.all(np.diff(est_stamps) > 0):
        raise DataError(f"--time-offset {time_offset_s:g}: the stamps of {where} no longer "
                        "increase once offset (an offset too large for their precision); "
                        "expected an offset of the size of the clocks' difference")
    if trust_clock:
        return None, "not checked (--trust-clock)"
    est_poses = est.poses @ T_frame_sensor
    scale = stamp_scale(est_stamps, est_poses[:, :3, 3], gt.stamps, gt.poses[:, :3, 3])
    if scale is not None:
        factor, est_speed, gt_speed = scale
        seconds = STAMP_UNITS[unit] / factor  # what one raw stamp unit looks to be
        fits = next((u for u, s in STAMP_UNITS.items() if np.isclose(s, seconds)), None)
        advice = (f"score it with --stamp-unit {fits}" if fits else
                  f"its seconds look {factor:g} times too long")
        raise DataError(
            f"{where}: its stamps read in {UNIT_NAMES[unit]} move it at {est_speed:.3g} m/s "
            f"where the ground truth of {store} moves at {gt_speed:.3g} m/s: stamps in "
            f"{UNIT_NAMES.get(fits, 'another unit')}? {advice} (or --trust-clock to score it "
            "as it is)")
    period = float(np.median(np.diff(scan_stamps))) if len(scan_stamps) > 1 else 0.0
    fit = fit_clock(est_stamps, est_poses, gt.stamps, gt.poses, period)
    if fit.offset_s is not None:  # suggest an offset that lines the stamps up too
        fit = replace(fit, suggested_s=time_offset_s + aligned_offset(
            est_stamps, scan_stamps, fit.offset_s, period))
    if fit.offset_s is None:
        return fit, f"inconclusive: {fit.why}"
    shift = round(fit.offset_s, 4) + 0.0
    return fit, (f"speed and turn-rate profile fits best shifted by {shift:+.4f} s (correlation"
                 f" {fit.correlation:.3f}; {fit.correlation_at_zero:.3f} unshifted)")


def clock_misfit(fit: ClockFit) -> bool:
    """The motion profiles line up at a shift beyond ``CLOCK_MAX_SHIFT_S``, or clearly better
    at another shift than unshifted (see the constants)."""
    if fit.offset_s is None:
        return False
    if abs(fit.offset_s) > CLOCK_MAX_SHIFT_S or not np.isfinite(fit.correlation_at_zero):
        return True
    return fit.correlation - fit.correlation_at_zero > CLOCK_FIT_MARGIN


def fit_hint(fit: ClockFit | None) -> str | None:
    """What fits when no scan is covered (None: ``loaders.gt.offset_hint``'s guess)."""
    if fit is None or fit.offset_s is None:
        return None
    return (f"its speed and turn-rate profile lines up with the ground truth's with "
            f"--time-offset {fit.suggested_s:.4f} (correlation {fit.correlation:.3f}; "
            "est_stamp + offset = sensor clock)")


def refuse_misfit(fit: ClockFit, time_offset_s: float, where: str, store: str) -> None:
    """``DataError`` for a ``clock_misfit``, naming the estimate and the offset that fits."""
    if clock_misfit(fit):
        unshifted = ("no overlap" if not np.isfinite(fit.correlation_at_zero)
                     else f"{fit.correlation_at_zero:.3f}")
        raise DataError(
            f"{where}: its clock does not fit the scans of {store}: its speed and turn-rate "
            f"profile lines up with the ground truth's only shifted by {fit.offset_s:+.4f} s "
            f"(correlation {fit.correlation:.3f}, against {unshifted} as it is, with "
            f"--time-offset {time_offset_s:g}); score it with --time-offset "
            f"{fit.suggested_s:.4f} (est_stamp + offset = sensor clock), or --trust-clock to "
            "score it as it is")
