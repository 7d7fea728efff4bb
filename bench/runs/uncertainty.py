"""The intervals of a scored run's figures (``metrics.intervals`` on ``metrics.units``).

Every figure ``bench.runs.evaluate.score`` writes gets, beside it, its confidence interval at
``LEVEL`` (95 %) from a circular block bootstrap over the scored frames and the count of
independent (non-overlapping) units behind it:

- relative error per length: the rotation and translation means, blocks of 1.5 times the
  larger of a segment's span and the errors' correlation length, the percentile interval read
  with the figure's ratio to its long-run mean as the pivot and widened for the few,
  overlapping whole blocks (``metrics.intervals``, its docstring: the rule that makes the
  interval cover its 95 %) and always holding the figure;
- KITTI drift: the translation [%] and rotation [deg/100 m] means over every segment;
- APE: the translation and rotation RMSE, from trajectories re-chained from blocks of the
  estimate's frame-to-frame errors along the same path and aligned as the figure
  (``metrics.drift_intervals``);
- velocity error: the mean error norm over the windows.

The resampling is seeded (``SEED``): the same trajectory gives the same interval, and two runs
on the same frames are resampled with the same blocks. The tables' marks read these intervals
as printed (``bench.report.tables.significance``).
"""

from __future__ import annotations

import numpy as np

from bench.runs.result import Spread, num
from metrics.drift_intervals import ape_intervals
from metrics.intervals import LEVEL, REPS, Interval, unit_intervals
from metrics.units import Units

SEED = 0


def _ci(iv: Interval) -> list | None:
    if not (np.isfinite(iv.low) and np.isfinite(iv.high)):
        return None
    return [num(iv.low), num(iv.high)]


def intervals(units: Units, n_frames: int, keys: dict[str, str], reps: int = REPS) -> dict:
    """The ``*_ci`` fields (``keys``: quantity in ``units`` -> field name) and the ``spread``
    of one figure's units over ``n_frames`` scored frames (``reps`` resamples)."""
    if len(units) == 0:
        return {field: None for field in keys.values()} | {"spread": Spread(n_independent=0)}
    if units.drift is not None:
        ivs = ape_intervals(units.drift, level=LEVEL, reps=reps, seed=SEED)
    else:
        ivs = unit_intervals(n_frames, units.anchor, units.end,
                             {k: units.values[k] for k in keys}, rmse=units.rmse, level=LEVEL,
                             reps=reps, seed=SEED)
    first = next(iter(ivs.values()))
    out = {field: _ci(ivs[key]) for key, field in keys.items()}
    out["spread"] = Spread(block_frames=first.block_frames or None,
                           n_independent=first.n_independent,
                           resampled="step errors" if units.drift is not None else "units")
    return out
