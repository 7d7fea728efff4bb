"""bench/runs/result.py, the run record every reader loads: its defaults as metrics.json has
them, the schema-1 reader, the seed's spelling and the readers' helpers (the mutation run of
tools/mutate.py over bench/runs/result.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from pydantic import ValidationError

from bench.runs.result import (
    EXTERNAL_MARK,
    FALLBACK_LIMIT,
    REPORTED_CLOCK,
    SCHEMA,
    ApeResult,
    KittiResult,
    RelativeError,
    RunResult,
    Spread,
    TimingStats,
    VelocityResult,
    nan,
    num,
)
from methods.registry import Seed


def run(**fields) -> RunResult:
    return RunResult(sequence="s", method="m", **fields)


def test_num_keeps_finite_floats_only():
    assert num(None) is None
    assert num(float("nan")) is None
    assert num(float("inf")) is None
    assert num(-math.inf) is None
    value = num(np.float32(2.5))
    assert value == 2.5 and type(value) is float
    assert type(num(3)) is float and num(3) == 3.0
    assert num(0) == 0.0


def test_nan_turns_none_into_nan_and_keeps_numbers():
    assert math.isnan(nan(None))
    assert nan(0.0) == 0.0
    assert type(nan(2)) is float and nan(2) == 2.0


def test_the_constants_readers_rely_on():
    assert SCHEMA == 2
    assert FALLBACK_LIMIT == 0.05
    assert REPORTED_CLOCK == "reported by the method"
    assert EXTERNAL_MARK == "(external)"


def test_models_ignore_unknown_keys_and_are_frozen():
    r = RunResult.model_validate({"sequence": "s", "method": "m", "unknown": 1})
    assert not hasattr(r, "unknown")
    with pytest.raises(ValidationError):
        r.status = "failed"  # type: ignore[misc]
    t = TimingStats.model_validate({"median": 1.0, "other": 2})
    with pytest.raises(ValidationError):
        t.median = 2.0  # type: ignore[misc]


def test_a_new_run_record_has_the_documented_defaults():
    r = run()
    assert r.schema_version == 2
    assert r.status == "done" and r.error is None
    assert r.seed is Seed.NONE
    assert r.label is r.display_name is r.sensor_class is r.frames is None
    assert r.frames_scored == 0 and r.diverged is None
    assert r.relative_error == [] and r.ape is r.kitti is r.velocity is r.velocity_own is None
    for t in (r.time_ms, r.register_ms, r.wall_ms):
        assert (t.median, t.mean, t.p95) == (None, None, None)
    assert r.clock is None and r.threads == 1
    assert r.cpu is r.cpu_process_to_thread is r.cpu_process_to_thread_first is None
    assert r.clock_note is None and r.timing_outliers == {} and r.timing_clean is True
    assert r.notes == [] and r.ci_level == 0.95
    assert r.frames_replaced == 0 and r.frames_unconverged == 0


def test_the_parts_defaults():
    s = Spread()
    assert (s.block_frames, s.n_independent, s.resampled) == (None, None, None)
    rel = RelativeError(length_m=8)
    assert rel.length_m == 8.0 and rel.n == 0
    assert all(getattr(rel, k) is None for k in (
        "rot_deg_mean", "rot_deg_median", "rot_deg_rmse", "trans_m_mean", "trans_m_median",
        "trans_m_rmse", "rot_deg_mean_ci", "trans_m_mean_ci"))
    assert rel.spread == Spread()
    ape = ApeResult()
    assert ape.requested == "se3" and ape.alignment is None and ape.scale == 1.0
    assert all(getattr(ape, k) is None for k in (
        "trans_rmse_m", "trans_mean_m", "trans_median_m", "trans_max_m", "rot_rmse_deg",
        "rot_mean_deg", "trans_rmse_m_ci", "rot_rmse_deg_ci"))
    kitti = KittiResult(lengths_m=[100])
    assert kitti.step_frames == 10 and kitti.n == 0
    assert kitti.trans_pct is kitti.rot_deg_per_100m is None
    assert kitti.per_length == [] and kitti.too_long == []
    assert kitti.trans_pct_ci is kitti.rot_deg_per_100m_ci is None
    vel = VelocityResult(window_s=1.0)
    assert vel.source == "trajectory" and vel.n == 0
    assert vel.axis_mean_mps == [None, None, None] and vel.axis_rmse_mps == [None, None, None]
    assert vel.norm_mean_mps is vel.norm_rmse_mps is vel.norm_mean_mps_ci is None
    with pytest.raises(ValidationError):
        Spread(resampled="frames")


def test_metrics_json_spells_the_schema_and_the_seed_as_documented():
    for option, seed in ((True, Seed.WITH), (False, Seed.WITHOUT), (None, Seed.NONE)):
        r = run(seed=option)
        assert r.seed is seed and r.seed_option is option
        text = r.dump()
        data = json.loads(text)
        assert data["schema"] == SCHEMA and "schema_version" not in data
        assert data["seed"] is option
        assert text.startswith('{\n  "schema"')  # indented by two spaces
        assert RunResult.model_validate(data) == r
    # the in-memory spelling ("with", "without", "none") reads too
    assert run(seed="without").seed is Seed.WITHOUT
    assert run(seed=Seed.WITH).seed is Seed.WITH
    assert RunResult(schema=2, sequence="s", method="m").schema_version == 2


def test_a_schema_1_record_is_read_as_schema_2():
    old = {"sequence": "s", "method": "m", "relative_error": {"8": {"rot_deg_mean": 1.0, "n": 3},
                                                            "16": {"n": 0}},
           "ape": {"alignment": "sim3", "scale": 0.5},
           "time_ms": None, "register_ms": None, "wall_ms": {"mean": 2.0}, "threads": None}
    r = RunResult.model_validate(old)
    assert [x.length_m for x in r.relative_error] == [8.0, 16.0]
    assert r.relative_error[0].rot_deg_mean == 1.0 and r.relative_error[0].n == 3
    assert r.ape.requested == "se3" and r.ape.alignment == "sim3" and r.ape.scale == 0.5
    assert r.time_ms == TimingStats() and r.register_ms == TimingStats()
    assert r.wall_ms.mean == 2.0
    assert r.threads == 1
    # the input itself is left as it was
    assert old["relative_error"] == {"8": {"rot_deg_mean": 1.0, "n": 3}, "16": {"n": 0}}
    assert old["time_ms"] is None
    # schema 1 is what a record without "schema" is
    one = RunResult.model_validate({**old, "schema": 1})
    assert one.schema_version == 1 and r.schema_version == 2
    assert one.model_dump(exclude={"schema_version"}) == r.model_dump(exclude={"schema_version"})
    # a record that gives its threads keeps them; a schema-1 ape keeps its own request
    kept = RunResult.model_validate({**old, "threads": 4, "ape": {"requested": "sim3"}})
    assert kept.threads == 4 and kept.ape.requested == "sim3"


def test_a_schema_2_record_is_read_as_it_is():
    with pytest.raises(ValidationError):  # a dict of relative errors is schema 1 only
        RunResult.model_validate({"schema": 2, "sequence": "s", "method": "m",
                                  "relative_error": {"8": {"n": 1}}})
    with pytest.raises(ValidationError):  # a null time is schema 1 only
        RunResult.model_validate({"schema": 2, "sequence": "s", "method": "m",
                                  "time_ms": None})
    with pytest.raises(ValidationError):  # null threads are schema 1 only
        RunResult.model_validate({"schema": 2, "sequence": "s", "method": "m",
                                  "threads": None})
    assert RunResult.model_validate({"schema": 2, "sequence": "s", "method": "m",
                                     "ape": {"alignment": "sim3", "requested": "sim3"}}
                                    ).ape.requested == "sim3"
    made = run(frames=3)
    assert RunResult.model_validate(made) == made  # a record, not a dict: as it is


def test_finished_and_scored():
    rel = [RelativeError(length_m=8, n=1)]
    assert run().finished and not run(status="failed").finished
    assert run(diverged=False, relative_error=rel).scored
    assert run(diverged=True, relative_error=rel).scored
    assert not run(diverged=None, relative_error=rel).scored
    assert not run(diverged=False).scored
    assert not run(status="failed", diverged=False, relative_error=rel).scored


def test_fallback_share_over_the_registered_frames():
    assert run(frames=11, frames_replaced=2, frames_unconverged=3).fallback_share == 0.5
    assert run(frames=1, frames_replaced=1).fallback_share == 0.0  # nothing registered
    assert run(frames=None, frames_replaced=1).fallback_share == 0.0
    assert run(frames=0).fallback_share == 0.0


def test_fell_back_only_beyond_the_limit():
    # 1 of 20 registered frames: exactly the limit, not beyond it
    assert not run(frames=21, frames_replaced=1).fell_back
    assert run(frames=20, frames_replaced=1).fell_back  # 1 of 19
    assert run(frames=21, frames_unconverged=2).fell_back
    assert not run(frames=21).fell_back


def test_fallback_text_names_the_prior_and_the_counts():
    assert run(frames=250).fallback_text() is None
    assert run(frames=250, frames_replaced=3, frames_unconverged=11).fallback_text() == (
        "3 of 249 frames replaced by the motion prior (no usable registration); "
        "11 of 249 frames not converged (last iterate kept)")
    assert run(frames=10, seed=False, frames_replaced=2).fallback_text() == (
        "2 of 9 frames replaced by the identity (no usable registration)")
    assert run(frames=10, seed=True, frames_replaced=2).fallback_text() == (
        "2 of 9 frames replaced by the motion prior (no usable registration)")
    assert run(frames_unconverged=1).fallback_text() == (
        "1 of 0 frames not converged (last iterate kept)")


def test_timed_by_harness():
    timed = TimingStats(mean=3.0)
    assert run(time_ms=timed).timed_by_harness
    assert run(time_ms=timed, clock="thread").timed_by_harness
    assert not run(time_ms=timed, clock=REPORTED_CLOCK).timed_by_harness
    assert not run().timed_by_harness


def test_relative_and_lengths():
    r = run(relative_error=[RelativeError(length_m=8, n=2, trans_m_mean=0.1),
                            RelativeError(length_m=16, n=0),
                            RelativeError(length_m=24, n=1)])
    assert r.relative(8).trans_m_mean == 0.1
    assert r.relative(16.0).length_m == 16.0
    assert r.relative(32) is None
    assert r.lengths_m == [8.0, 24.0]
