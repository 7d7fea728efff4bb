"""What ``bench calibrate --write`` writes, and where it may write it.

Angles: only those whose interval is narrower than a stated bound (``WRITE_MAX_WIDTH_DEG``,
option ``--max-width``) are applied; the others - not observable, without an interval, or
known only loosely - are left alone (0 in the written rotation), and the command says which
and why. A loose angle applied to the ground truth would move every GT pose by an amount the
data could not fix.

Target: never the input store (not even with ``--force``: a corrected store written over its
source loses the original ground truth); an existing file only with ``--force``, and then
only a store that ``bench calibrate`` itself wrote (its provenance has a calibration), never
another file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from bench.data.calibration.estimate import ANGLES, euler_matrix
from loaders.errors import DataError

#: --write applies an angle only when its interval is narrower than this [deg] (full width,
#: i.e. known to about +-1 deg, against the 2-3 deg tilts it is there to correct); on the real
#: sample it applies pitch and yaw (intervals 0.75-1.23 deg on its halves, 1.07 on all 250
#: frames) and leaves the road plane's roll (2.7-13.9 deg) alone
WRITE_MAX_WIDTH_DEG = 2.0


def select_angles(angles_deg: dict[str, float], interval_deg: dict[str, tuple[float, float]],
                  fitted: dict[str, bool], max_width_deg: float = WRITE_MAX_WIDTH_DEG
                  ) -> tuple[dict[str, float], dict[str, str]]:
    """The angles to apply {angle: deg} and those left alone {angle: why}: an angle is applied
    when it was fitted and its interval is finite and narrower than ``max_width_deg``."""
    applied, left = {}, {}
    for ax in ANGLES:
        lo, hi = interval_deg.get(ax, (np.nan, np.nan))
        width = hi - lo
        if not fitted.get(ax, False):
            left[ax] = "not observable"
        elif not np.isfinite(width):
            left[ax] = "no interval"
        elif width < max_width_deg:
            applied[ax] = float(angles_deg[ax])
        else:
            left[ax] = f"interval {width:.2f} deg wide, not narrower than {max_width_deg:g}"
    return applied, left


def applied_rotation(applied_deg: dict[str, float]) -> np.ndarray:
    """R_gt_sensor = Rz(yaw) Ry(pitch) Rx(roll) of the applied angles, the others 0."""
    return euler_matrix(np.radians([applied_deg.get(ax, 0.0) for ax in ANGLES]))


def describe_selection(applied: dict[str, float], left: dict[str, str],
                       max_width_deg: float, level: float) -> str:
    text = (f"--write applies the angles whose {100 * level:.0f} % interval is narrower than "
            f"{max_width_deg:g} deg (--max-width): ")
    text += ", ".join(f"{ax} {v:+.3f}" for ax, v in applied.items()) if applied else "none"
    if left:
        text += "; left alone (0 in the written rotation): " + ", ".join(
            f"{ax} ({why})" for ax, why in left.items())
    return text


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def check_write_target(store: Path, write_to: Path, force: bool) -> None:
    """DataError unless ``write_to`` may be written (see the module docstring)."""
    store, write_to = Path(store), Path(write_to)
    if _same_file(store, write_to):
        raise DataError(f"--write {write_to}: that is the input store {store}; bench calibrate "
                        "never writes onto its own input (not even with --force): give "
                        "another path")
    if write_to.is_dir():
        raise DataError(f"--write {write_to}: is a folder; give the path of the store to write")
    if not write_to.exists():
        return
    if not force:
        raise DataError(f"--write {write_to}: exists; give another path, or --force to replace "
                        "a store bench calibrate wrote")
    if not written_by_calibrate(write_to):
        raise DataError(f"--write {write_to}: exists and is not a store bench calibrate wrote; "
                        "--force replaces only those: give another path")


def written_by_calibrate(path: Path) -> bool:
    """A store (``bench.guard.is_store``) whose provenance records a calibration: what
    ``calibrate --write --force`` may replace."""
    from bench.guard import is_store

    if not is_store(path):
        return False
    from loaders.store import StoreSequence

    try:
        seq = StoreSequence(path)
    except Exception:  # not a store at all  # noqa: BLE001
        return False
    try:
        return "calibration" in (seq.provenance or {})
    finally:
        seq.close()
