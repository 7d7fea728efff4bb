"""A run's per-unit errors (``metrics.units``), recomputed once from its trajectory files
(``gt_tum.txt`` / ``est_tum.txt``, the scored frames) for the paired comparisons behind a
table's marks (``bench.report.significance``)."""

from __future__ import annotations

from bench.runs.folders import RunRecord
from metrics.units import Units, ape_units, kitti_units, relative_units, velocity_units


class RunUnits:
    """Lazily computed, cached per-unit errors of one run. Each accessor returns what
    ``bench.report.significance.Stat.units`` expects: (scored frames, units, quantity, rmse),
    or None when the run has no trajectory files."""

    def __init__(self, run: RunRecord) -> None:
        self.run = run
        self._cache: dict[tuple, Units | None] = {}

    def _units(self, key: tuple, make) -> Units | None:
        if key not in self._cache:
            try:
                self._cache[key] = make() if self.run.has_gt else None
            except (OSError, ValueError):
                self._cache[key] = None
        return self._cache[key]

    def _out(self, units: Units | None, quantity: str, rmse: bool | None = None
             ) -> tuple | None:
        if units is None:
            return None
        return len(self.run.gt), units, quantity, units.rmse if rmse is None else rmse

    def relative(self, length_m: float, quantity: str) -> tuple | None:
        r = self.run
        return self._out(self._units(("rel", length_m),
                                     lambda: relative_units(r.gt, r.est, length_m)), quantity)

    def kitti(self, lengths_m: tuple, step_frames: int, quantity: str) -> tuple | None:
        r = self.run
        return self._out(self._units(("kitti", lengths_m, step_frames),
                                     lambda: kitti_units(r.gt, r.est, lengths_m, step_frames)),
                         quantity)

    def ape(self, alignment: str, quantity: str) -> tuple | None:
        r = self.run
        return self._out(self._units(("ape", alignment),
                                     lambda: ape_units(r.gt, r.est, alignment)), quantity)

    def velocity(self, window_s: float, quantity: str, rmse: bool = False) -> tuple | None:
        r = self.run
        return self._out(self._units(("vel", window_s),
                                     lambda: velocity_units(r.gt, r.est, r.stamps, window_s)),
                         quantity, rmse)
