"""Survivors left 'not killed' by earlier mutation runs, each killed with a case built for it.

- ``bench.runs.evaluate.score``: a non-default velocity window reaches the trajectory's and the
  method's own velocity intervals and the own velocity's errors (known answers: a jitter of
  +-d repeating every 4 frames, a cubic drive whose centred-window velocity is 3 s^2 + h^2);
  a non-default alignment is recorded for an estimate that cannot be aligned (not finite);
- ``evaluate_run``: without a name its errors say "ground truth";
- ``bench.runs.sweep.sweep_index``: the default recorded for a swept parameter is the one the
  method resolves with the point's other (fixed) parameters, shown with a method defined here
  whose default for ``b`` is twice its ``a``;
- ``bench.report.tables.paper._velocity_cells``: a velocity record with other than three axes
  is refused, not shown shifted by a column."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import BaseModel

from bench.report.tables.paper import _velocity_cells
from bench.runs.evaluate import Scoring, evaluate_run, score
from bench.runs.result import VelocityResult
from bench.runs.sweep import Variant, sweep_index
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import write_store
from loaders.trajectory import Trajectory
from methods import registry
from methods.base import FrameRecord, Odometry, OdometryResult

DT = 0.125  # exact in binary: windows of 1 and 2 frames fall on frames
N = 48


def _poses(x: np.ndarray) -> np.ndarray:
    T = np.tile(np.eye(4), (len(x), 1, 1))
    T[:, 0, 3] = x
    return T


def _cubic_drive():
    """Stamps and the GT poses of x = s^3 (no rotation): the mean velocity over [s - h, s + h]
    is ((s + h)^3 - (s - h)^3) / 2h = 3 s^2 + h^2."""
    stamps = np.arange(N) * DT
    return stamps, _poses(stamps**3)


def test_a_non_default_velocity_window_reaches_every_velocity_figure():
    """(kills score 186, 213, 229: the window dropped from velocity_units,
    own_velocity_errors and own_velocity_units, which then take the default 1 s)"""
    stamps, gt = _cubic_drive()
    d = 0.01
    jitter = d * np.array([1.0, 1.0, -1.0, -1.0] * (N // 4))  # jitter[k + 2] = -jitter[k]
    est = _poses(stamps**3 + jitter)
    own = np.column_stack([3 * stamps**2, np.zeros(N), np.zeros(N)])  # the true velocity
    window = 2 * DT
    out = score(gt, est, np.ones(N), scoring=Scoring((2.0,), (10.0,), "se3", window),
                stamps=stamps, velocity_mps=own)
    # trajectory: windows of 2 frames, each error (jitter[k + 2] - jitter[k]) / 2 DT = 2d / 2 DT
    # in size (over 8 frames, the default 1 s, it would be 0)
    v = out["velocity"]
    assert v["window_s"] == window and v["n"] == N - 2
    np.testing.assert_allclose(v["norm_mean_mps"], 2 * d / window, rtol=1e-6)
    np.testing.assert_allclose(v["norm_mean_mps_ci"], [2 * d / window] * 2, rtol=1e-6)
    # own velocity: error h^2 with h = window / 2 (0.25 with the default window) at every
    # frame whose window stays inside the drive
    o = out["velocity_own"]
    h = window / 2
    assert o["window_s"] == window and o["n"] == N - 2
    np.testing.assert_allclose(o["norm_mean_mps"], h**2, rtol=1e-6)
    np.testing.assert_allclose(o["norm_mean_mps_ci"], [h**2] * 2, rtol=1e-6)


def test_an_estimate_that_cannot_be_aligned_records_the_alignment_asked_for():
    """(kills score 119: ``requested`` left at its default "se3")"""
    stamps, gt = _cubic_drive()
    est = gt.copy()
    est[N // 2, 0, 3] = np.nan
    out = score(gt, est, np.ones(N), scoring=Scoring((2.0,), (10.0,), "sim3"), stamps=stamps)
    assert out["ape"]["requested"] == "sim3"
    assert out["ape"]["trans_rmse_m"] is None


def _result(stamps: np.ndarray, poses: np.ndarray) -> OdometryResult:
    frames = [FrameRecord(i, float(t), 1.0, 10, 5, 1, True) for i, t in enumerate(stamps)]
    return OdometryResult(stamps, poses, frames)


def test_evaluate_run_without_a_name_says_ground_truth():
    """(kills evaluate_run 1, 2: the default name)"""
    stamps, gt = _cubic_drive()
    later = Trajectory(stamps + 100.0, gt)  # GT that covers none of the frames
    with pytest.raises(DataError, match=r"^ground truth: no frame has ground truth"):
        evaluate_run(later, _result(stamps, gt))


class _Derived(Odometry):
    """A method whose default for ``b`` is derived from ``a``: twice it."""

    name = "derived-default-test"
    description = "test method: b defaults to 2 a"

    class Params(BaseModel):
        a: float = 1.0
        b: float | None = None

    def __init__(self, params: Params | None = None):
        self.params = params or self.Params()

    def configured_for(self, sensor):
        p = self.params
        return _Derived(p.model_copy(update={"b": 2 * p.a if p.b is None else p.b}))

    def run(self, sequence, seed, on_frame=None):
        raise NotImplementedError


def test_a_swept_default_derived_from_a_fixed_parameter(monkeypatch, tmp_path):
    """(kills sweep_index 55, 59: the fixed parameters not passed to make_method, so the
    recorded default of b is 2 x a's default 1 instead of 2 x the fixed a = 3)"""
    monkeypatch.setitem(registry.METHODS, _Derived.name, _Derived)
    store = write_store(constant_twist_sequence(n_frames=3, n_points=50), tmp_path / "s.h5")
    out = tmp_path / "out"
    variants = [Variant(f"d b={b}", {"a": 3.0, "b": b}, {"b": b}, "d") for b in (1.0, 9.0)]
    method = SimpleNamespace(name=_Derived.name, variants=lambda: variants)
    exp = SimpleNamespace(name="e", out_dir=out, methods=[method], criterion=None,
                          default_differs=None)
    jobs = [SimpleNamespace(method=_Derived.name, label=v.label, name="s", store=Path(store),
                            seed=None, run_dir_override=out / "s" / v.label.replace(" ", "_"))
            for v in variants]
    index = sweep_index(exp, jobs)
    (sweep,) = index["sweeps"]
    assert sweep["keys"] == ["b"]
    assert sweep["defaults"] == {"s": {"b": 6.0}}


def test_a_velocity_record_with_two_axes_is_refused():
    """(kills _velocity_cells 18, 21, 22: zip not strict, which shows the norm under z)"""
    broken = VelocityResult(window_s=1.0, axis_mean_mps=[0.1, 0.2], norm_mean_mps=0.3,
                            norm_rmse_mps=0.4, n=5)
    with pytest.raises(ValueError):
        _velocity_cells(broken, False, False)
    whole = VelocityResult(window_s=1.0, axis_mean_mps=[0.1, 0.2, 0.05], norm_mean_mps=0.3,
                           norm_rmse_mps=0.4, n=5)
    assert len(_velocity_cells(whole, False, False)) == 5
