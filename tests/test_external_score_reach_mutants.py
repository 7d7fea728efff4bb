"""bench.runs.external.score: the survivors of its mutation run, reached in-process.

- a bag with two pose topics scored under the topic named (``--topic``): the topic reaches
  ``read_estimate`` (without it the bag's two pose topics are refused), and the run is scored
  on that topic's poses, not the other's;
- an experiment entry scored with two warnings says both, each after "; warning: ".

(The third survivor, score_external 406, the replacement warning's stacklevel 2 -> 3, only
moves the line a warning is said of; under mutmut its trampoline adds a frame, so no test it
runs can tell the two apart: judged equivalent.)"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from bench.runs.evaluate import Scoring
from bench.runs.external import score
from bench.runs.external.score import ExternalOutcome, ExternalSpec, score_external
from bench.runs.folders import read_run
from conftest import constant_twist_sequence
from loaders.scan import MemorySequence, SensorInfo
from loaders.store import write_store

N = 30
SCORING = Scoring(lengths_m=(2.0,), kitti_lengths_m=(3.0,), alignment="se3",
                  velocity_window_s=0.5)


def _store(path: Path):
    base = constant_twist_sequence(n_frames=N, n_points=40, w=(0.0, 0.0, 0.0), max_range_m=70)
    seq = MemorySequence("twist", SensorInfo("lidar", 0.1, np.eye(4), "test"), list(base),
                         base.ground_truth)
    return write_store(seq, path), base.ground_truth


def _odometry_bag(path: Path, stamps, topics: dict[str, np.ndarray]) -> Path:
    """A ROS1 bag with one nav_msgs/Odometry topic per entry of ``topics`` (name: poses)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from helpers_bags import odometry_msg

    store = get_typestore(Stores.ROS1_NOETIC)
    msgtype = "nav_msgs/msg/Odometry"
    with Writer(path) as w:
        for name, poses in topics.items():
            conn = w.add_connection(name, msgtype, typestore=store)
            for k, (t, pose) in enumerate(zip(stamps, poses, strict=True)):
                msg = odometry_msg(store, float(t), k, pose)
                w.write(conn, int(1e9 * (1 + t)), store.serialize_ros1(msg, msgtype))
    return path


def test_the_named_topic_of_a_bag_with_two_pose_topics_is_scored(tmp_path):
    """(kills score_external 78: the topic dropped on its way to read_estimate)"""
    store, gt = _store(tmp_path / "s.h5")
    drifted = gt.poses.copy()
    drifted[:, 0, 3] *= 1.5  # 50 % too far along x: relative errors far from zero
    bag = _odometry_bag(tmp_path / "two.bag", gt.stamps, {"/a_drift": drifted, "/b_good": gt.poses})
    spec = ExternalSpec(bag, "good", topic="/b_good", trust_clock=True)
    out = score_external(store, spec, tmp_path / "r", SCORING)
    assert out.status == "done" and out.coverage["matched"] == N
    run = read_run(out.run_dir)
    # the ground truth's own poses: no relative error (the drifted topic's is 50 % of 2 m)
    assert run.result.relative(2.0).trans_m_mean < 1e-6
    assert run.config["external"]["topic"] == "/b_good"
    assert run.config["method"]["description"] == f"external trajectory {bag}:/b_good"
    bad = score_external(store, ExternalSpec(bag, "drift", topic="/a_drift", trust_clock=True),
                         tmp_path / "r", SCORING)
    assert read_run(bad.run_dir).result.relative(2.0).trans_m_mean > 0.5


def test_an_experiment_entry_with_two_warnings_says_both(monkeypatch, tmp_path):
    """(kills score_experiment_external 91: the separator of the warnings joined)"""
    entry = SimpleNamespace(
        name="two", trajectory=tmp_path / "t.tum", store=tmp_path / "s.h5", format="tum",
        stamps=None, topic=None, frame_times=None, time_offset_s=0.0, tolerance_s=0.02,
        max_gap_s=None, pose_frame="sensor", extrinsic=None, stamp_unit="s",
        min_coverage=0.5, trust_clock=True)
    exp = SimpleNamespace(sequences=[], lengths_m=[2.0], kitti_lengths_m=[3.0],
                          alignment="se3", out_dir=tmp_path / "exp", external=[entry])
    run_dir = tmp_path / "exp" / "s" / "two"
    coverage = {"scored": 3, "scans_with_gt": 4, "share_scored": 0.75}

    def scored(store, spec, out, scoring, force, names):
        assert (store, spec.name, out) == (entry.store, "two", exp.out_dir)
        return ExternalOutcome(run_dir, "done", coverage, warnings=["first one", "second one"])

    monkeypatch.setattr(score, "score_external", scored)
    assert score.score_experiment_external(exp) == [(
        "two", "done", f"{run_dir}: 3 of the 4 scans with ground truth scored (75.0 %); "
        "warning: first one; warning: second one")]

