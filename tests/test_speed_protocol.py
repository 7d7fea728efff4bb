"""`bench speed` times every method with a run's protocol (bench/studies/speed.py): the common
warm-up (``Odometry.warm_up``) and then distinct consecutive frames, no pair twice, read as a
run reads them; library pipelines (``--reference``) are driven the same way."""

from __future__ import annotations

import numpy as np
import pytest

from bench.studies import speed
from conftest import constant_twist_sequence
from loaders.store import StoreSequence, write_store
from methods.base import Registration
from methods.registry import METHODS, make_method


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=7, n_points=1500, noise_m=0.01)
    return StoreSequence(write_store(seq, tmp_path_factory.mktemp("speed") / "twist.h5"))


def _recording(method, calls: list):
    """``method`` with every registration call's (source stamp, target stamp) recorded (a
    prepared scan need not carry its stamp: each is remembered as ``preprocess`` returns it)."""
    register, preprocess = method.register, method.preprocess
    stamps, kept = {}, []

    def prepared(scan):
        out = preprocess(scan)
        kept.append(out)
        stamps[id(out)] = round(scan.stamp, 6)
        return out

    def recorded(source, target, init):
        calls.append((stamps[id(source)], stamps[id(target)]))
        return register(source, target, init)

    method.register, method.preprocess = recorded, prepared
    return method


PAIRWISE = [n for n, c in METHODS.items() if issubclass(c, Registration)
            and not n.startswith("test-")]
STATEFUL = [n for n in METHODS if n not in PAIRWISE and not n.startswith("test-")]


@pytest.mark.parametrize("name", PAIRWISE)
def test_a_pairwise_method_registers_each_consecutive_pair_once_after_the_runs_warm_up(
        name, stored):
    calls: list = []
    method = _recording(make_method(name, {}, stored.sensor), calls)
    r = speed.time_frames(method, stored)
    stamps = [round(s, 6) for s in stored.stamps]
    pairs = list(zip(stamps[:-1], stamps[1:], strict=True))
    # Odometry.warm_up: one untimed run on the last pair, then every pair once, in order; a
    # run whose CPU time leaked out of its thread (another thread of this test process busy)
    # is timed again, whole, by the wall clock (bench.runs.timed), and says so
    once = [pairs[-1], *pairs]
    assert calls == (once * 2 if r["clock"] == "wall" else once), r["clock"]
    assert r["repeats"] == len(stored) - 1  # every registered frame is a figure


@pytest.mark.parametrize("name", STATEFUL)
def test_a_stateful_method_runs_the_warm_up_pair_then_the_whole_sequence(name, stored):
    method = make_method(name, {}, stored.sensor)
    runs = []
    run = method.run

    def recorded(sequence, seed, on_frame=None):
        runs.append([round(sequence[i].stamp, 6) for i in range(len(sequence))])
        return run(sequence, seed, on_frame)

    method.run = recorded
    r = speed.time_frames(method, stored)
    stamps = [round(s, 6) for s in stored.stamps]
    assert runs == [stamps[-2:], stamps]
    assert r["repeats"] == len(stored) - 1


def test_a_library_pipeline_is_timed_as_a_run(stored):
    """A reference pipeline (preprocess / register on library objects) goes through the same
    driver: the same pairs, and its prepared scans need not be Scans."""
    calls = []

    class Pipeline:
        threads = 1

        def preprocess(self, scan):
            return {"stamp": scan.stamp, "n": len(scan)}

        def register(self, source, target, init):
            from methods.base import RegistrationResult

            calls.append((source["stamp"], target["stamp"]))
            return RegistrationResult(np.eye(4), source["n"], 1, True)

    r = speed.time_frames(Pipeline(), stored)
    n = len(stored) - 1
    # the warm-up pair, then every pair once; a run whose CPU time leaked out of its thread
    # (another thread of this test process still busy, e.g. a stateful method's thread pool
    # from the test before) is timed again, whole, by the wall clock, and says so
    once = 1 + n
    assert r["clock"] in ("cpu", "wall")
    assert len(calls) == (2 * once if r["clock"] == "wall" else once), r["clock"]
    assert len(set(calls)) == n and r["repeats"] == n


def test_bench_speed_times_what_a_run_records(stored, tmp_path):
    """The figure of ``bench speed`` and the time_ms of a ``bench run`` on the same scans come
    from the same frames: each is a median over the same number of registered frames of the
    same timed work (the command ``bench speed --vs-run`` prints both times)."""
    ours, run = speed.compare_with_run("icp-p2p", stored, tmp_path)
    assert np.isfinite(ours) and np.isfinite(run) and ours > 0 and run > 0
    import json

    metrics = json.loads(next(tmp_path.rglob("metrics.json")).read_text())
    assert metrics["frames"] == len(stored) and metrics["clock"] == "cpu"
    assert metrics["cpu_process_to_thread"] <= 1.05
