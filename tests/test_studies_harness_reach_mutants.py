"""``bench.studies.harness.phases``: what it hands the run (the method by default, the
parameters, the scoring's lengths and calibration frames) and ``synthetic_scenarios``' small
LiDAR scans: tests reaching the survivors the first mutation pass left."""

from __future__ import annotations

import dataclasses

import numpy as np

from bench.studies import harness
from conftest import constant_twist_sequence
from methods.base import FrameRecord, OdometryResult
from metrics.relative import DEFAULT_LENGTHS_M


class _Method:
    """Stands in for the configured method: the ground truth as its poses, 1 ms a frame."""

    def warm_up(self, seq):
        pass

    def run(self, seq, seed, on_frame=None):
        gt = seq.ground_truth
        frames = [FrameRecord(i, float(t), 1.0, 10, 10, 1, True)
                  for i, t in enumerate(gt.stamps)]
        return OdometryResult(np.asarray(gt.stamps), np.asarray(gt.poses), frames)


def _stubbed(monkeypatch, tmp_path):
    """A tiled 10-frame store (9 m at 10 m/s); ``prepare`` keeps the jobs and swaps the
    method."""
    import bench.runs.job as job

    store = harness.tiled_store(constant_twist_sequence(n_frames=3, n_points=200), 10,
                                tmp_path / "t.h5")
    real_prepare, jobs = job.prepare, []

    def prepare(j):
        jobs.append(j)
        return dataclasses.replace(real_prepare(j), method=_Method())

    monkeypatch.setattr(job, "prepare", prepare)
    monkeypatch.setattr(harness, "read_cost", lambda path, fields, frames=None: {
        "read_ms": 0.0, "read_wall_ms": 0.0, "points": 200})
    return store, jobs


def test_phases_default_method_is_doppler(monkeypatch, tmp_path):
    store, jobs = _stubbed(monkeypatch, tmp_path)
    assert harness.phases(store)["method"] == "doppler"
    assert jobs and {j.method for j in jobs} == {"doppler"}


def test_phases_hands_the_parameters_to_the_job(monkeypatch, tmp_path):
    store, jobs = _stubbed(monkeypatch, tmp_path)
    params = {"max_iterations": 7}
    harness.phases(store, "icp-p2p", params)
    assert jobs and all(j.params == {"max_iterations": 7} for j in jobs)
    assert params == {"max_iterations": 7}  # the caller's dict left as it was


def test_phases_scores_the_jobs_lengths_without_the_calibration_frames(monkeypatch, tmp_path):
    import bench.runs.evaluate as evaluate
    import bench.runs.job as job
    import bench.runs.plan  # noqa: F401  (imported first: it keeps the real calibration_frames)

    store, _ = _stubbed(monkeypatch, tmp_path)
    mask = np.arange(10) < 2
    monkeypatch.setattr(job, "calibration_frames", lambda seq: mask)
    real, calls = evaluate.evaluate_run, []

    def evaluate_run(gt, result, *args, **kwargs):
        calls.append((args, kwargs))
        return real(gt, result, *args, **kwargs)

    monkeypatch.setattr(evaluate, "evaluate_run", evaluate_run)
    harness.phases(store, "icp-p2p")
    # scored twice (the first loads the kernels), both times the same way
    assert len(calls) == 2
    for args, kwargs in calls:
        assert tuple(args) == (tuple(DEFAULT_LENGTHS_M),)
        assert kwargs.keys() == {"excluded"} and kwargs["excluded"] is mask


class _Small:
    """A synthetic LiDAR sequence whose every scan is cut to ``keep`` points."""

    def __init__(self, real, keep):
        self.name, self.sensor, self.ground_truth = real.name, real.sensor, real.ground_truth
        self.scans = [s.select(np.arange(min(keep, len(s)))) for s in real]

    def __iter__(self):
        return iter(self.scans)


def test_synthetic_scenarios_keep_a_scan_with_fewer_points_whole(monkeypatch):
    import loaders.synthetic as synthetic

    real_class = synthetic.SyntheticSequence

    def sequence(scene, sensor, **kwargs):
        real = real_class(scene, sensor, **kwargs)
        return _Small(real, 50) if scene == "campus" else real

    monkeypatch.setattr(synthetic, "SyntheticSequence", sequence)
    (_, _), (name, lidar) = harness.synthetic_scenarios(lidar_points=100, frames=2)
    # 50 points (fewer than the 100 asked for): each scan kept as it is, in its order
    for scan in lidar:
        assert len(scan) == 50
    expected = _Small(real_class("campus", "lidar-dense", frames=2, seed=0, points=160), 50)
    for got, want in zip(lidar, expected, strict=True):
        np.testing.assert_array_equal(got.points, want.points)


def test_read_cost_reads_only_the_fields_asked_for(monkeypatch, tmp_path):
    import bench.studies.harness as h

    store = harness.tiled_store(constant_twist_sequence(n_frames=2, n_points=50), 3,
                                tmp_path / "t.h5")
    opened = []
    real = h.StoreSequence

    def store_sequence(path, **kwargs):
        opened.append(kwargs)
        return real(path, **kwargs)

    monkeypatch.setattr(h, "StoreSequence", store_sequence)
    r = harness.read_cost(store, ("doppler",))
    assert opened == [{"fields": ("doppler",)}] and r["points"] == 50


def test_synthetic_scenarios_subsample_distinct_points():
    (_, _), (_, lidar) = harness.synthetic_scenarios(lidar_points=100, frames=2)
    for scan in lidar:
        # 100 points drawn without replacement: no point twice
        assert len(scan) == 100 == len(np.unique(scan.points, axis=0))


def test_print_whole_run_prints_a_method_name_with_brackets_as_it_is():
    from rich.console import Console

    r = {"method": "plug[v2]", "frames": 4, "wall_s": 1.0, "cpu_s": 1.0, "short_frames": 2,
         "short_wall_s": 0.5, "short_cpu_s": 0.5, "method_ms": 1.0, "marginal_cpu_ms": 1.0,
         "marginal_wall_ms": 1.0, "issue_cpu_ms": 1.0, "issue_wall_ms": 1.0}
    console = Console(record=True, width=1000, color_system=None)
    harness.print_whole_run(r, console)
    assert console.export_text().startswith("bench run --method plug[v2]: 4 frames in ")
