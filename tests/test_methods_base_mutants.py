"""methods/base.py's driver and timing protocol with a scripted registration: poses chained from
known steps, the seed's constant-velocity guess scaled by the time steps (against scipy's
rotation vectors), replaced steps, frame records, the warm-up pair and the parameters'
validation."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import Field, ValidationError
from scipy.spatial.transform import Rotation

from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import inv_T
from methods import base
from methods.base import (
    FrameRecord,
    MethodParams,
    Registration,
    RegistrationResult,
    run_timed,
    scale_motion,
    uniform_downsample,
)
from methods.timing import Stopwatch


def _T(rotvec, t):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


class _Params(MethodParams):
    num_threads: int = Field(1, ge=1)
    gate: float = Field(1.0, gt=0)


class _Scripted(Registration):
    """Returns the given steps in turn and records the starts it was given."""

    name = "scripted"
    Params = _Params

    def __init__(self, steps=(), params=None, **overrides):
        super().__init__(params, **overrides)
        self.steps = list(steps)
        self.inits = []
        self.pairs = []

    def preprocess(self, scan):
        return uniform_downsample(scan, 2)

    def register(self, source, target, init):
        self.inits.append(init.copy())
        self.pairs.append((source.stamp, target.stamp))
        T = self.steps[len(self.inits) - 1]
        return RegistrationResult(T, 10 * len(self.inits), len(self.inits), True)


def _sequence(stamps, n_points=6):
    scans = [Scan(t, np.full((n_points, 3), float(i)), np.zeros(n_points))
             for i, t in enumerate(stamps)]
    return MemorySequence("s", SensorInfo("lidar", 0.1), scans)


STEPS = [_T([0.0, 0.0, 0.1], [1.0, 0.0, 0.0]), _T([0.02, 0.0, -0.05], [0.5, 0.2, 0.0]),
         _T([0.0, 0.03, 0.0], [0.0, 0.0, 0.3])]


def test_uniform_downsample():
    scan = Scan(0.0, np.arange(30.0).reshape(10, 3), np.arange(10.0))
    assert uniform_downsample(scan, 1) is scan and uniform_downsample(scan, 0) is scan
    kept = uniform_downsample(scan, 3)
    np.testing.assert_array_equal(kept.doppler, [0.0, 3.0, 6.0, 9.0])
    np.testing.assert_array_equal(kept.points, scan.points[::3])


def test_scale_motion_scales_the_rotation_vector_and_translation():
    T = _T([0.02, -0.01, 0.1], [1.0, -0.5, 0.2])
    for ratio in (2.5, 0.5, 1.00001):
        S = scale_motion(T, ratio)
        np.testing.assert_allclose(Rotation.from_matrix(S[:3, :3]).as_rotvec(),
                                   np.array([0.02, -0.01, 0.1]) * ratio, atol=1e-12)
        np.testing.assert_allclose(S[:3, 3], np.array([1.0, -0.5, 0.2]) * ratio, atol=1e-12)
    for ratio in (1.0, 1.0 + 9e-7, 1.0 - 9e-7):
        S = scale_motion(T, ratio)
        assert S is not T
        np.testing.assert_array_equal(S, T)


def test_run_chains_the_inverse_steps():
    m = _Scripted(STEPS)
    result = m.run(_sequence([0.0, 0.1, 0.2, 0.3]), seed=False)
    expected = [np.eye(4)]
    for T in STEPS:
        expected.append(expected[-1] @ inv_T(T))
    np.testing.assert_allclose(result.poses, np.array(expected), atol=1e-12)
    np.testing.assert_array_equal(result.stamps, [0.0, 0.1, 0.2, 0.3])
    assert m.pairs == [(0.0, 0.1), (0.1, 0.2), (0.2, 0.3)]
    for init in m.inits:  # no seed: every step from the identity
        np.testing.assert_array_equal(init, np.eye(4))
    assert result.velocity_mps is None


def test_a_single_scan_is_the_identity_pose():
    result = _Scripted().run(_sequence([5.0]), seed=True)
    np.testing.assert_array_equal(result.poses, [np.eye(4)])
    assert len(result.frames) == 1 and result.frames[0].index == 0


def test_a_seeded_step_starts_from_the_last_motion_scaled_to_its_time():
    m = _Scripted(STEPS)
    m.run(_sequence([0.0, 0.1, 0.3, 0.35]), seed=True)
    np.testing.assert_array_equal(m.inits[0], np.eye(4))  # nothing known yet
    np.testing.assert_allclose(m.inits[1], scale_motion(STEPS[0], 2.0), atol=1e-12)
    np.testing.assert_allclose(m.inits[2], scale_motion(STEPS[1], 0.25), atol=1e-12)
    np.testing.assert_allclose(m.inits[1][:3, 3], [2.0, 0.0, 0.0], atol=1e-12)


def test_a_method_without_a_prior_always_starts_from_the_identity():
    m = _Scripted(STEPS)
    m.uses_initial_guess = False
    m.run(_sequence([0.0, 0.1, 0.2, 0.3]), seed=True)
    for init in m.inits:
        np.testing.assert_array_equal(init, np.eye(4))


def test_frame_records():
    m = _Scripted(STEPS)
    seen = []
    result = m.run(_sequence([0.0, 0.1, 0.2, 0.3]), seed=True, on_frame=seen.append)
    assert seen == [0, 1, 2, 3]
    first, *rest = result.frames
    assert (first.index, first.stamp, first.points, first.correspondences, first.iterations,
            first.converged, first.replaced) == (0, 0.0, 3, 0, 0, True, False)
    assert np.isnan(first.time_ms) and np.isnan(first.register_ms) and np.isnan(first.wall_ms)
    for k, f in enumerate(rest, start=1):
        assert (f.index, f.points, f.correspondences, f.iterations, f.converged,
                f.replaced) == (k, 3, 10 * k, k, True, False)
        assert f.stamp == pytest.approx(0.1 * k)
        assert 0 <= f.register_ms <= f.time_ms and f.time_ms == f.thread_ms
        assert f.wall_ms >= 0 and f.process_ms == f.process_ms and f.compiles == 0


def test_a_non_finite_step_is_replaced_by_its_start():
    bad = STEPS[1].copy()
    bad[0, 3] = np.nan
    m = _Scripted([STEPS[0], bad, STEPS[2]])
    result = m.run(_sequence([0.0, 0.1, 0.2, 0.3]), seed=True)
    guess = scale_motion(STEPS[0], 1.0)
    np.testing.assert_allclose(result.poses[2], result.poses[1] @ inv_T(guess), atol=1e-12)
    f = result.frames[2]
    assert f.replaced and f.converged is False and (f.correspondences, f.iterations) == (20, 2)
    assert not result.frames[1].replaced and not result.frames[3].replaced
    np.testing.assert_allclose(m.inits[2], guess, atol=1e-12)  # the next step's guess: it
    inf = STEPS[0].copy()
    inf[1, 1] = np.inf
    unseeded = _Scripted([inf, STEPS[1]]).run(_sequence([0.0, 0.1, 0.2]), seed=False)
    np.testing.assert_array_equal(unseeded.poses[1], np.eye(4))
    assert unseeded.frames[1].replaced


def _watch(wall, cpu, process, compiles):
    w = Stopwatch()
    w.wall_ms, w.cpu_ms, w.process_ms, w.compiles = wall, cpu, process, compiles
    return w


def test_frame_record_reads_the_methods_clock():
    m = _Scripted()
    total, reg = _watch(9.0, 4.0, 5.0, 2), _watch(3.0, 1.5, 1.6, 0)
    assert m.frame_record(3, 0.3, total, reg, 7, 8, 9, False, True) == FrameRecord(
        3, 0.3, 4.0, 7, 8, 9, False, 1.5, 9.0, 4.0, 5.0, 2, True)
    m.clock_override = "wall"
    assert m.frame_record(3, 0.3, total, reg, 7, 8, 9, True) == FrameRecord(
        3, 0.3, 9.0, 7, 8, 9, True, 3.0, 9.0, 4.0, 5.0, 2, False)
    r = m.frame_record(1, 0.1, total, None, 7, 8, 9, True)
    assert np.isnan(r.register_ms) and r.time_ms == 9.0
    r = m.frame_record(0, 0.0, None, reg, 7, 0, 0, True, replaced=True)
    assert np.isnan(r.time_ms) and r.register_ms == 3.0 and r.replaced
    r = _Scripted().frame_record(0, 0.0, None, reg, 7, 0, 0, True)  # by the CPU clock
    assert r.register_ms == 1.5 and not r.replaced
    assert np.isnan(r.wall_ms) and np.isnan(r.thread_ms) and r.compiles == 0


def test_threads_and_clock():
    assert _Scripted().threads == 1 and _Scripted().clock == "cpu"
    m = _Scripted(num_threads=3)
    assert m.threads == 3 and m.clock == "wall"
    m.clock_override = "cpu"
    assert m.clock == "cpu"

    class NoParams(_Scripted):
        params = None

        def __init__(self):
            pass

    assert NoParams().threads == 1


def test_wall_clock_runs_take_the_lock(monkeypatch):
    seen = []
    real = base.timed_section

    def spy(exclusive=False):
        seen.append(exclusive)
        return real(exclusive)

    monkeypatch.setattr(base, "timed_section", spy)
    _Scripted(STEPS).run(_sequence([0.0, 0.1]), seed=True)
    _Scripted(STEPS, num_threads=2).run(_sequence([0.0, 0.1]), seed=True)
    assert seen == [False, False, True, True]


def test_parameters_are_validated_with_their_overrides():
    params = _Params(gate=2.0)
    assert _Scripted(params=params).params is params
    assert _Scripted().params == _Params()
    m = _Scripted(params=params, num_threads=4)
    assert (m.params.gate, m.params.num_threads) == (2.0, 4)
    with pytest.raises(ValidationError):
        _Scripted(params=params, gate=-1.0)
    with pytest.raises(ValidationError):
        _Params(unknown=1)
    with pytest.raises(ValidationError):
        _Params(gate=float("inf"))
    with pytest.raises(ValidationError):
        params.gate = 3.0  # frozen


@pytest.mark.parametrize("n, pair", [(0, None), (1, None), (2, (0.0, 0.1)), (3, (0.0, 0.1)),
                                     (4, (0.2, 0.3)), (6, (0.4, 0.5))])
def test_the_warm_up_pair(n, pair):
    m = _Scripted(STEPS)
    runs = []
    m.run = lambda sequence, seed, on_frame=None: runs.append(
        ([s.stamp for s in sequence], seed, sequence.name, sequence.sensor))
    seq = _sequence([0.1 * k for k in range(n)])
    m.warm_up(seq)
    if pair is None:
        assert runs == []
    else:
        (stamps, seed, name, sensor), = runs
        np.testing.assert_allclose(stamps, pair)
        assert seed is True and name == "s" and sensor is seq.sensor


def test_run_timed_warms_up_then_runs():
    calls = []
    m = _Scripted(STEPS)
    seq = _sequence([0.0, 0.1])
    m.warm_up = lambda sequence: calls.append(("warm", sequence))
    m.run = lambda sequence, seed, on_frame=None: calls.append(
        ("run", sequence, seed, on_frame)) or 7
    assert run_timed(m, seq, False, print) == 7
    assert calls == [("warm", seq), ("run", seq, False, print)]
