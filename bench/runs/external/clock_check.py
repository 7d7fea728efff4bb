"""The clock checks of ``bench score`` (``bench.runs.external.score``): what is refused, what is
said to fit, and what the data cannot tell, from the motion profiles of
``bench.runs.external.clock``. Each decides on evidence the data can give, never on a point
estimate alone:

- stamps that are frame indices (0, 1, 2, ... a second apart where the scans are not): refused,
  named as such;
- a speed 10^3, 10^6 or 10^9 times off the ground truth's: stamps in another unit, or positions
  in another unit (millimetres ...): both are named, and the path length settles which (a unit
  of the stamps leaves the path's length alone, a unit of the positions scales it);
- stamps that no longer increase once offset (an offset too large for their precision);
- stamps that are the scans' own (one per scan, each within the tolerance of its scan: an
  odometry run on the store or on its export): on the store's clock, never refused; a profile
  that decisively fits elsewhere is then a warning (poses written against the wrong stamps?);
- otherwise a misfit (``clock_misfit``) is refused only when decisive: the block bootstrap's
  interval of the best shift leaves out no shift, the interval of the correlation's gain over
  no shift lies above 0 (``ClockFit.decisive``), and the shift exceeds the association
  tolerance and half a scan period (a smaller clock difference, such as a store's ground truth
  a few hundredths of a second late, is association's business: stated, scored). Every
  ``--time-offset`` the interval cannot tell apart (one scan period apart, for an estimate
  stamped at the scans) is listed. Where the data cannot tell (a flat profile,
  a wide interval), the estimate is scored as given and the check says it could not tell;
- no scan within the tolerance: ``fit_hint`` says the offsets that fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from bench.runs.external.clock import ClockFit, aligned_offset, fit_clock, path_speed
from loaders.errors import DataError
from loaders.estimate import STAMP_UNITS
from loaders.gt import nearest_indices
from loaders.trajectory import Trajectory

UNIT_NAMES = {"s": "seconds", "ms": "milliseconds", "us": "microseconds",
              "ns": "nanoseconds"}
#: a share of the estimate's stamps this high on the scans (within the tolerance) once a fit's
#: offset is applied makes it an estimate stamped at the scans (its alike offsets are a period
#: apart)
ON_SCANS_SHARE = 0.9
#: index stamps: whole numbers this share of whose steps are exactly 1
INDEX_STEP_SHARE = 0.9
#: ... where the scans' period is off 1 s by more than this factor
INDEX_PERIOD_FACTOR = 1.5
#: a ratio within this factor of a power of 1000 is that unit
UNIT_FACTOR = 10.0


@dataclass
class ClockVerdict:
    """The motion-profile fit (None: not fitted), the line saying what was found, whether the
    estimate's stamps are the scans' own, and warnings (scored anyway)."""

    fit: ClockFit | None
    line: str
    on_scans: bool = False
    warnings: list[str] = field(default_factory=list)
    #: the scans' period [s] (a misfit exceeds half of it)
    period_s: float = 0.0


def stamps_are_scans(est_stamps: np.ndarray, scan_stamps: np.ndarray, tolerance_s: float) -> bool:
    """One stamp per scan, each within ``tolerance_s`` of its scan's (in order)."""
    s, q = np.asarray(est_stamps, float), np.asarray(scan_stamps, float)
    return len(s) == len(q) and bool(np.all(np.abs(s - q) <= tolerance_s))


def index_stamps(raw: np.ndarray, period_s: float) -> bool:
    """Stamps that are whole numbers a step of 1 apart (frame indices) where the scans' period
    is not about 1 s."""
    raw = np.asarray(raw, float)
    if len(raw) < 3 or not np.all(raw == np.round(raw)):
        return False
    ones = float(np.mean(np.diff(raw) == 1))
    off = max(period_s, 1e-12)
    return ones >= INDEX_STEP_SHARE and max(off, 1 / off) > INDEX_PERIOD_FACTOR


def _power_of_1000(ratio: float) -> int | None:
    """k when ``ratio`` is within ``UNIT_FACTOR`` of 1000^k (k = -3 .. 3, not 0)."""
    if not ratio > 0:
        return None
    decades = float(np.log10(ratio))
    k = int(np.round(decades / 3))
    if k == 0 or abs(k) > 3 or abs(decades - 3 * k) > np.log10(UNIT_FACTOR):
        return None
    return k


def unit_misfit(est_stamps: np.ndarray, est_xyz: np.ndarray, gt: Trajectory, unit: str,
                where: str, store: str) -> str | None:
    """The refusal for a speed a power of 1000 off the ground truth's (None: none): its cause
    is told by the path length (positions in another unit scale it) against the time span
    (stamps in another unit scale it)."""
    gt_t, gt_xyz = gt.stamps, gt.poses[:, :3, 3]
    s0, s1 = float(est_stamps[0]), float(est_stamps[-1])
    inside = (gt_t >= s0) & (gt_t <= s1)
    if inside.sum() >= 3 and gt_t[inside][-1] - gt_t[inside][0] >= 0.5 * (s1 - s0):
        # the ground truth over the estimate's own span (a part of the drive: its own speed)
        gt_t, gt_xyz = gt_t[inside], gt_xyz[inside]
    gt_speed, est_speed = path_speed(gt_t, gt_xyz), path_speed(est_stamps, est_xyz)
    if gt_speed < 0.1 or est_speed <= 0:
        return None
    k = _power_of_1000(gt_speed / est_speed)
    if k is None:
        return None

    def length(xyz):
        return float(np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum())

    path_k = _power_of_1000(length(est_xyz) / max(length(gt_xyz), 1e-12))
    span_k = _power_of_1000((est_stamps[-1] - est_stamps[0]) / max(gt_t[-1] - gt_t[0], 1e-12))
    seconds = STAMP_UNITS[unit] * 1000.0 ** -k  # what one raw stamp unit looks to be
    # (relative: np.isclose's default absolute 1e-8 would take a picosecond for a nanosecond)
    fits = next((u for u, s in STAMP_UNITS.items()
                 if np.isclose(s, seconds, rtol=1e-6, atol=0.0)), None)
    head = (f"{where}: read in {UNIT_NAMES[unit]}, its stamps move it at {est_speed:.3g} m/s "
            f"where the ground truth of {store} moves at {gt_speed:.3g} m/s "
            f"({1000.0 ** abs(k):g} times {'slower' if k > 0 else 'faster'}): stamps in another "
            f"unit, or positions in another unit? Its path is {length(est_xyz):.4g} (position "
            "units) over "
            f"{est_stamps[-1] - est_stamps[0]:.4g} (stamp units), the ground truth's "
            f"{length(gt_xyz):.4g} m over {gt_t[-1] - gt_t[0]:.4g} s")
    if path_k == -k and span_k is None:
        scale = {1: "millimetres", 2: "micrometres", 3: "nanometres"}.get(-k, "another unit")
        return (f"{head}: the path length settles it: positions in {scale} (the span fits, the "
                f"path is {1000.0 ** -k:g} times too long); write them in metres (a stamp unit "
                "would not help)")
    if span_k == k and path_k is None:
        advice = (f"score it with --stamp-unit {fits}" if fits else
                  f"its seconds look {1000.0 ** k:g} times too long")
        return (f"{head}: the path length settles it: stamps in "
                f"{UNIT_NAMES.get(fits, 'another unit')} (the path fits, the span is "
                f"{1000.0 ** k:g} times too long); {advice} (or --trust-clock to score it as "
                "it is)")
    return (f"{head}: the path length cannot settle which (an estimate of part of the drive, "
            "or of another scale?); check the units the file was written in (or --trust-clock "
            "to score it as it is)")


def alike_offsets(est_stamps: np.ndarray, scan_stamps: np.ndarray, fit: ClockFit,
                  period_s: float, tolerance_s: float) -> tuple[float, ...]:
    """The shifts [s] the fit cannot tell apart, the most likely first: for an estimate stamped
    at the scans, the shifts that line its stamps up with the scans within the fit's interval
    (one scan period apart); else the fit's own shift."""
    best = aligned_offset(est_stamps, scan_stamps, fit.offset_s, period_s)
    s = np.asarray(est_stamps, float) + best
    q = np.asarray(scan_stamps, float)
    inside = (s >= q[0]) & (s <= q[-1])
    if not inside.any() or period_s <= 0:
        return (fit.offset_s,)
    _, dist = nearest_indices(q, s[inside])
    if np.mean(dist <= max(tolerance_s, 1e-9)) < ON_SCANS_SHARE:
        return (fit.offset_s,)
    lo, hi = fit.interval_s or (fit.offset_s, fit.offset_s)
    lo, hi = lo - fit.grid_s, hi + fit.grid_s
    cands = [best + j * period_s for j in range(-50, 51)]
    inside = [c for c in cands if lo <= c <= hi] or [best]
    return tuple(sorted(inside, key=lambda c: abs(c - fit.offset_s)))


def check_clock(est: Trajectory, T_frame_sensor: np.ndarray, gt: Trajectory,
                scan_stamps: np.ndarray, time_offset_s: float, trust_clock: bool, where: str,
                store: str, unit: str = "s", tolerance_s: float = 0.01,
                raw_stamps: np.ndarray | None = None) -> ClockVerdict:
    """The estimate's clock against the ground truth's (see the module docstring): index
    stamps and units are refused here; returns the motion-profile fit and what was found.
    ``raw_stamps``: the stamps as written in the file (the index check)."""
    est_stamps = est.stamps + time_offset_s
    if not np.all(np.diff(est_stamps) > 0):
        raise DataError(f"--time-offset {time_offset_s:g}: the stamps of {where} no longer "
                        "increase once offset (an offset too large for their precision); "
                        "expected an offset of the size of the clocks' difference")
    if trust_clock:
        return ClockVerdict(None, "not checked (--trust-clock)")
    period = float(np.median(np.diff(scan_stamps))) if len(scan_stamps) > 1 else 0.0
    raw = est.stamps if raw_stamps is None else raw_stamps
    on_scans = stamps_are_scans(est_stamps, scan_stamps, tolerance_s)
    if not on_scans and index_stamps(raw, period):
        raise DataError(
            f"{where}: its stamps are frame indices ({raw[0]:.0f}, {raw[1]:.0f}, {raw[2]:.0f}, "
            f"...: whole numbers 1 apart) where the scans of {store} are {period:.4g} s apart: "
            "expected stamps in seconds on the sensor's clock; write each pose's scan stamp "
            "(the scans' stamps are those of the bag `bench export` writes), or "
            "--trust-clock to score it as it is")
    est_poses = est.poses @ T_frame_sensor
    unit_text = unit_misfit(est_stamps, est_poses[:, :3, 3], gt, unit, where, store)
    if unit_text:  # (positions in mm keep the scans' stamps: checked whatever the stamps)
        raise DataError(unit_text)
    fit = fit_clock(est_stamps, est_poses, gt.stamps, gt.poses, period)
    if fit.offset_s is None:
        said = ("on the store's clock (one stamp per scan, each its scan's); " if on_scans
                else "")
        return ClockVerdict(fit, f"{said}the clock could not be checked: {fit.why}; scored "
                                 "as given", on_scans, [] if on_scans else _outside(
                                     est_stamps, scan_stamps, tolerance_s, period, where))
    alike = alike_offsets(est_stamps, scan_stamps, fit, period, tolerance_s)
    fit = replace(fit, suggested_s=time_offset_s + alike[0],
                  alike_s=tuple(time_offset_s + a for a in alike))
    found = _fit_text(fit)
    if on_scans:
        verdict = ClockVerdict(fit, "on the store's clock (one stamp per scan, each its "
                                    f"scan's); {found}", True, period_s=period)
        if clock_misfit(fit, tolerance_s, period):
            verdict.warnings.append(
                f"{where}: its stamps are the scans' own, yet its motion profile fits the "
                f"ground truth's decisively better shifted ({found}): poses written against "
                "the wrong scans' stamps? Scored as given")
        return verdict
    if not fit.decisive:
        lo, hi = fit.interval_s
        why = ("its interval holds no shift" if lo - fit.grid_s <= 0 <= hi + fit.grid_s else
               "the correlation's gain over no shift may be 0")
        return ClockVerdict(fit, f"the clock could not be checked: {found}: the data cannot "
                                 f"tell that shift from none ({why}); scored as given", False,
                            _outside(est_stamps, scan_stamps, tolerance_s, period, where), period)
    if not clock_misfit(fit, tolerance_s, period):
        return ClockVerdict(fit, f"{found}: within half a scan period ({period / 2:.4g} s) of "
                                 "no shift; scored as given", period_s=period)
    return ClockVerdict(fit, found, period_s=period)


def _outside(est_stamps: np.ndarray, scan_stamps: np.ndarray, tolerance_s: float,
             period_s: float, where: str) -> list[str]:
    """A warning when poses lie beyond the scans' span by more than a period (and the
    tolerance): an odometry of these scans has none there, so its clock may be off by about
    that much (or it covers a longer recording than the store)."""
    if len(scan_stamps) == 0:
        return []
    before = float(scan_stamps[0] - est_stamps[0])
    after = float(est_stamps[-1] - scan_stamps[-1])
    margin = max(tolerance_s, period_s)
    if max(before, after) <= margin:
        return []
    n = int(np.sum(est_stamps < scan_stamps[0] - margin) + np.sum(est_stamps > scan_stamps[-1]
                                                                   + margin))
    side = (f"{before:.3g} s before the first scan" if before > after else
            f"{after:.3g} s after the last scan")
    return [f"{where}: {n} of its poses lie beyond the scans' span (up to {side}) and the motion "
            "profile cannot check its clock here: a clock off by about that much (try "
            "--time-offset), or an estimate of a longer recording than the store? Scored as given"]


def _fit_text(fit: ClockFit) -> str:
    lo, hi = fit.interval_s
    return (f"the speed and turn-rate profile fits best shifted by {fit.offset_s + 0.0:+.4f} s "
            f"(95 % interval [{lo + 0.0:+.4f}, {hi + 0.0:+.4f}] s; correlation "
            f"{fit.correlation:.3f}, {fit.correlation_at_zero:.3f} unshifted, gain over no "
            f"shift at least {fit.gain_low:.4f})")


def clock_misfit(fit: ClockFit | None, tolerance_s: float, period_s: float = 0.0) -> bool:
    """The data decisively exclude no shift (``ClockFit.decisive``) and the best shift exceeds
    the association tolerance and half a scan period, either way."""
    if fit is None or fit.offset_s is None:
        return False
    return fit.decisive and abs(fit.offset_s) > max(tolerance_s, 0.5 * period_s)


def offsets_text(fit: ClockFit) -> str:
    first, rest = fit.alike_s[0], fit.alike_s[1:]
    if not rest:
        return f"--time-offset {first:.4f}"
    return (f"--time-offset {first:.4f} (the profile cannot tell it from "
            + ", ".join(f"--time-offset {a:.4f}" for a in rest)
            + ": they fit alike, a scan period apart; try each)")


def fit_hint(fit: ClockFit | None) -> str | None:
    """What fits when no scan is covered (None: ``loaders.gt.offset_hint``'s guess)."""
    if fit is None or fit.offset_s is None or not fit.alike_s:
        return None
    return (f"its speed and turn-rate profile lines up with the ground truth's with "
            f"{offsets_text(fit)} (correlation {fit.correlation:.3f}; est_stamp + offset = "
            "sensor clock)")


def refuse_misfit(verdict: ClockVerdict, time_offset_s: float, tolerance_s: float, where: str,
                  store: str) -> None:
    """``DataError`` for a ``clock_misfit`` of an estimate not stamped at the scans, naming the
    estimate and every offset that fits alike."""
    fit = verdict.fit
    if verdict.on_scans or not clock_misfit(fit, tolerance_s, verdict.period_s):
        return
    unshifted = ("no overlap" if not np.isfinite(fit.correlation_at_zero)
                 else f"{fit.correlation_at_zero:.3f}")
    lo, hi = fit.interval_s
    raise DataError(
        f"{where}: its clock does not fit the scans of {store}: its speed and turn-rate "
        f"profile lines up with the ground truth's only shifted by {fit.offset_s:+.4f} s "
        f"(95 % interval [{lo:+.4f}, {hi:+.4f}] s; correlation {fit.correlation:.3f}, against "
        f"{unshifted} as it is, with --time-offset {time_offset_s:g}); score it with "
        f"{offsets_text(fit)} (est_stamp + offset = sensor clock), or --trust-clock to score "
        "it as it is")
