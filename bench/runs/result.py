"""One typed result per run: what evaluation writes (``metrics.json``) and what every reader
loads (tables, figures, compare, regress, fidelity, the pandas API, the viewer).

A new metric is its function in ``metrics/`` plus one field here (filled in
``bench.runs.evaluate.score``); see the README's "Adding a metric".

``metrics.json`` is ``RunResult.model_dump_json()``: lengths are floats (``length_m``), the
seed option is written as true / false / null (``methods.registry.Seed`` in memory), missing
statistics as null. Older files (``schema`` 1: ``relative_error`` keyed by "8", no KITTI or
velocity part) are read by ``_legacy``; ``bench.runs.folders`` re-scores them from their
trajectory files.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    field_serializer,
    field_validator,
    model_validator,
)

from methods.registry import Seed

#: the version of metrics.json this module writes
SCHEMA = 2
#: a run where more than this share of registered frames fell back (replaced by the motion
#: prior, or not converged) is marked in every table and the report
FALLBACK_LIMIT = 0.05

Num = float | None  # a statistic; None = no value (NaN / infinite / nothing to measure)
#: ``RunResult.clock`` of a run whose per-frame times its method reported (an external
#: trajectory scored by ``bench score``): shown, never ranked against the harness's clock
REPORTED_CLOCK = "reported by the method"
#: the end of an external run's label ("NAME (external)", ``bench.runs.external.score``)
EXTERNAL_MARK = "(external)"


def num(x) -> float | None:
    """A finite float or None."""
    return None if x is None or not math.isfinite(float(x)) else float(x)


def nan(x: float | None) -> float:
    """None -> NaN (for arithmetic and ranking)."""
    return math.nan if x is None else float(x)


class _Model(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)


class TimingStats(_Model):
    """Per-frame times [ms]: median, mean, 95th percentile."""

    median: Num = None
    mean: Num = None
    p95: Num = None


Ci = list[Num] | None  # a confidence interval [low, high] of the statistic beside it


class Spread(_Model):
    """How sure a figure is: its intervals come from a circular block bootstrap with blocks of
    ``block_frames`` frames at ``RunResult.ci_level``; behind it stand ``n_independent``
    independent pieces. ``resampled``: "units" - the figure's segments or windows, drawn by the
    frame they start at (``metrics.intervals``; the pieces are non-overlapping units); "step
    errors" (APE) - the estimate's frame-to-frame errors, re-chained along the GT path and
    scored again (``metrics.drift_intervals``; the pieces are whole blocks). A figure with
    fewer than two pieces is never ranked."""

    block_frames: int | None = None
    n_independent: int | None = None
    resampled: Literal["units", "step errors"] | None = None


class RelativeError(_Model):
    """Relative error over segments of ``length_m`` (``metrics.relative``): rotation [deg],
    translation [m]; ``n`` segments (0: none, statistics None); the means' intervals
    (``*_ci``) and their ``spread``."""

    length_m: float
    rot_deg_mean: Num = None
    rot_deg_median: Num = None
    rot_deg_rmse: Num = None
    trans_m_mean: Num = None
    trans_m_median: Num = None
    trans_m_rmse: Num = None
    n: int = 0
    rot_deg_mean_ci: Ci = None
    trans_m_mean_ci: Ci = None
    spread: Spread = Spread()


class ApeResult(_Model):
    """APE after ``alignment`` (``metrics.ape``): the one asked for (``requested``) and the one
    used (``alignment``; "se3-orientation" for the degenerate fallback); Sim(3) ``scale``."""

    requested: str = "se3"
    alignment: str | None = None
    trans_rmse_m: Num = None
    trans_mean_m: Num = None
    trans_median_m: Num = None
    trans_max_m: Num = None
    rot_rmse_deg: Num = None
    rot_mean_deg: Num = None
    scale: Num = 1.0
    trans_rmse_m_ci: Ci = None
    rot_rmse_deg_ci: Ci = None
    spread: Spread = Spread()


class KittiLength(_Model):
    length_m: float
    trans_pct: Num = None
    rot_deg_per_100m: Num = None
    n: int = 0


class KittiResult(_Model):
    """KITTI drift (``metrics.kitti``): translation [%] and rotation [deg/100 m] over every
    segment of ``lengths_m``; ``too_long``: lengths the path is too short for."""

    lengths_m: list[float]
    step_frames: int = 10
    trans_pct: Num = None
    rot_deg_per_100m: Num = None
    n: int = 0
    per_length: list[KittiLength] = Field(default_factory=list)
    too_long: list[float] = Field(default_factory=list)
    trans_pct_ci: Ci = None
    rot_deg_per_100m_ci: Ci = None
    spread: Spread = Spread()


class VelocityResult(_Model):
    """Ego-velocity error (``metrics.velocity``) over windows of ``window_s`` [s]: per axis
    x, y, z of the sensor frame mean |error| and RMSE, the error norm's mean and RMSE [m/s]."""

    source: str = "trajectory"  # "trajectory" or "doppler" (the method's own estimate)
    window_s: float
    axis_mean_mps: list[Num] = Field(default_factory=lambda: [None, None, None])
    axis_rmse_mps: list[Num] = Field(default_factory=lambda: [None, None, None])
    norm_mean_mps: Num = None
    norm_rmse_mps: Num = None
    n: int = 0
    norm_mean_mps_ci: Ci = None
    spread: Spread = Spread()


class RunResult(_Model):
    """A run's result. ``status`` "done" for a finished run; a run that did not finish
    ("failed", "interrupted", "timeout", "crashed") has its ``error`` and no metrics."""

    schema_version: int = Field(SCHEMA, alias="schema")
    status: str = "done"
    error: str | None = None
    sequence: str
    method: str
    seed: Seed = Seed.NONE
    label: str | None = None
    display_name: str | None = None
    sensor_class: str | None = None
    frames: int | None = None
    frames_scored: int = 0
    diverged: bool | None = None
    relative_error: list[RelativeError] = Field(default_factory=list)
    ape: ApeResult | None = None
    kitti: KittiResult | None = None
    velocity: VelocityResult | None = None
    velocity_own: VelocityResult | None = None
    time_ms: TimingStats = TimingStats()
    register_ms: TimingStats = TimingStats()
    wall_ms: TimingStats = TimingStats()
    clock: str | None = None
    threads: int = 1
    #: how the times were taken (``bench.runs.timed``): the CPU model, the process's CPU time
    #: over the timed thread's (1.00: all work on the timed thread), a note when the run fell
    #: back to the wall clock, frames that were not steady work, and whether no compilation
    #: landed in a timed frame (an unclean run is not reused)
    cpu: str | None = None
    cpu_process_to_thread: Num = None
    cpu_process_to_thread_first: Num = None
    clock_note: str | None = None
    timing_outliers: dict[str, str] = Field(default_factory=dict)
    timing_clean: bool = True
    notes: list[str] = Field(default_factory=list)
    #: the confidence level of every ``*_ci`` interval (``bench.runs.uncertainty``)
    ci_level: float = 0.95
    #: registered frames (every frame but the first) whose registration gave no usable
    #: transform and whose step was replaced by the motion prior (the identity without a
    #: seed), and frames whose registration stopped before converging (its last iterate kept)
    frames_replaced: int = 0
    frames_unconverged: int = 0

    model_config = ConfigDict(extra="ignore", frozen=True, populate_by_name=True)

    @field_validator("seed", mode="before")
    @classmethod
    def _seed(cls, v: Any) -> Seed:
        return Seed.of(v) if not isinstance(v, str) else Seed(v)

    @field_serializer("seed")
    def _seed_out(self, v: Seed) -> bool | None:
        return v.option

    @model_validator(mode="before")
    @classmethod
    def _legacy(cls, data: Any) -> Any:
        """metrics.json of schema 1: relative_error {"8": {...}}, ape without ``requested``."""
        if not isinstance(data, dict) or data.get("schema", 1) >= SCHEMA:
            return data
        data = dict(data)
        rel = data.get("relative_error") or {}
        if isinstance(rel, dict):
            data["relative_error"] = [{"length_m": float(k), **v} for k, v in rel.items()]
        if isinstance(data.get("ape"), dict):
            data["ape"] = {"requested": "se3", **data["ape"]}
        for key in ("time_ms", "register_ms", "wall_ms"):
            if data.get(key) is None:
                data.pop(key, None)
        data["threads"] = data.get("threads") or 1
        return data

    # ---- readers' helpers -------------------------------------------------------------------
    @property
    def finished(self) -> bool:
        return self.status == "done"

    @property
    def scored(self) -> bool:
        """Finished with ground truth (has relative errors)."""
        return self.finished and self.diverged is not None and bool(self.relative_error)

    @property
    def fallback_share(self) -> float:
        """The share of registered frames replaced or not converged (0 with none)."""
        registered = max(0, (self.frames or 0) - 1)
        bad = self.frames_replaced + self.frames_unconverged
        return bad / registered if registered else 0.0

    @property
    def fell_back(self) -> bool:
        """More than ``FALLBACK_LIMIT`` of the registered frames fell back."""
        return self.fallback_share > FALLBACK_LIMIT

    def fallback_text(self) -> str | None:
        """"3 of 249 frames replaced by the motion prior, 11 not converged" (None: none)."""
        parts = []
        registered = max(0, (self.frames or 0) - 1)
        if self.frames_replaced:
            prior = "the identity" if self.seed is Seed.WITHOUT else "the motion prior"
            parts.append(f"{self.frames_replaced} of {registered} frames replaced by {prior} "
                         "(no usable registration)")
        if self.frames_unconverged:
            parts.append(f"{self.frames_unconverged} of {registered} frames not converged "
                         "(last iterate kept)")
        return "; ".join(parts) or None

    @property
    def timed_by_harness(self) -> bool:
        """Its times were measured by the harness (not an external run's: not timed, or
        ``REPORTED_CLOCK``), so its CPU model matters beside the others'."""
        return self.clock != REPORTED_CLOCK and self.time_ms.mean is not None

    @property
    def seed_option(self) -> bool | None:
        return self.seed.option

    def relative(self, length_m: float) -> RelativeError | None:
        """The relative error at ``length_m`` (None when not scored at that length)."""
        return next((r for r in self.relative_error if r.length_m == float(length_m)), None)

    @property
    def lengths_m(self) -> list[float]:
        """The lengths with at least one segment."""
        return [r.length_m for r in self.relative_error if r.n]

    def dump(self) -> str:
        """The metrics.json text."""
        return self.model_dump_json(indent=2, by_alias=True)
