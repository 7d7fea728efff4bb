"""evaluate_run: frames without ground truth run but are not scored; degenerate estimates are
scored (and diverged); timing survives without ground truth."""

import json
import warnings

import numpy as np
import pytest

from bench.runs.evaluate import evaluate_run
from bench.runs.job import Job, run_job
from bench.runs.result import RelativeError
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.scan import MemorySequence, select_frames
from loaders.store import StoreSequence, write_store
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult
from metrics import ape, relative_errors


def rel_at(metrics: dict, length_m: float):
    """The relative error at ``length_m`` of a metrics dict (bench.runs.result)."""
    return next(RelativeError(**r) for r in metrics["relative_error"]
                if r["length_m"] == length_m)


def result_from(stamps, poses, time_ms=1.0) -> OdometryResult:
    frames = [FrameRecord(i, float(s), float("nan") if i == 0 else time_ms + i, 100, 50, 1, True)
              for i, s in enumerate(stamps)]
    return OdometryResult(np.asarray(stamps), np.asarray(poses), frames)


@pytest.fixture(scope="module")
def twist():
    return constant_twist_sequence(n_frames=80, n_points=400)  # 8 m/s, 0.1 s: 63 m


def noisy(poses, seed=0):
    rng = np.random.default_rng(seed)
    out = poses.copy()
    out[:, :3, 3] += np.cumsum(rng.normal(0, 0.02, (len(poses), 3)), axis=0)
    return out


def test_a_gt_gap_excludes_frames_from_scoring_only(twist):
    gt = twist.ground_truth
    gap = np.r_[30:40]
    gt_gappy = Trajectory(np.delete(gt.stamps, gap), np.delete(gt.poses, gap, axis=0))
    est = noisy(gt.poses)
    ev = evaluate_run(gt_gappy, result_from(gt.stamps, est), (8.0, 16.0), "s.h5")
    assert ev.metrics["frames_scored"] == 70
    np.testing.assert_allclose(ev.gt.stamps, gt_gappy.stamps)
    keep = np.setdiff1d(np.arange(80), gap)
    rel = relative_errors(gt.poses[keep], est[keep], (8.0, 16.0))  # the scored subset
    assert rel_at(ev.metrics, 8).n == rel[8.0].n
    assert rel_at(ev.metrics, 16).trans_m_mean == pytest.approx(
        rel[16.0].trans_m_mean)
    assert ev.metrics["ape"]["trans_rmse_m"] == pytest.approx(
        ape(gt.poses[keep], est[keep]).trans_rmse_m)
    assert ev.metrics["time_ms"]["median"] == pytest.approx(np.median(np.arange(1, 80) + 1.0))


def test_gt_at_its_own_rate_is_interpolated_but_never_across_a_long_gap(twist):
    gt = twist.ground_truth
    fine_t = np.arange(0.0, 7.9 + 1e-9, 0.02)
    fine_t = fine_t[(fine_t < 3.0) | (fine_t > 4.0)]  # a 1 s outage (50 steps)
    from loaders.se3 import interpolate_poses

    fine = Trajectory(fine_t, interpolate_poses(gt.stamps, gt.poses, fine_t))
    poses, mask = gt_for_frames(fine, gt.stamps)
    assert not mask[(gt.stamps > 3.0) & (gt.stamps < 4.0)].any()
    assert mask[(gt.stamps < 3.0) | (gt.stamps > 4.0)].all()
    np.testing.assert_allclose(poses[mask], gt.poses[mask], atol=1e-3)
    assert np.isnan(poses[~mask]).all()


def test_identity_estimate_is_scored_and_diverged(twist):
    gt = twist.ground_truth
    ident = np.tile(np.eye(4), (len(gt), 1, 1))
    ev = evaluate_run(gt, result_from(gt.stamps, ident))
    m = ev.metrics
    assert m["diverged"] is True and m["frames_scored"] == 80
    assert m["ape"]["alignment"] == "se3-orientation"
    assert m["ape"]["trans_rmse_m"] > 10  # a 63 m drive estimated as standing still
    assert rel_at(m, 8).trans_m_mean == pytest.approx(8.0, rel=0.2)


def test_no_ground_truth_keeps_the_timing(twist):
    ev = evaluate_run(None, result_from(twist.stamps, twist.ground_truth.poses, 2.0))
    assert ev.gt is None and ev.metrics["frames_scored"] == 0
    assert ev.metrics["time_ms"]["mean"] == pytest.approx(np.mean(np.arange(1, 80) + 2.0))


def test_no_frame_with_gt_or_gt_going_backwards_is_a_clear_error(twist):
    gt = twist.ground_truth
    late = Trajectory(gt.stamps + 100.0, gt.poses)
    with pytest.raises(DataError, match="s.h5: no frame has ground truth"):
        evaluate_run(late, result_from(gt.stamps, gt.poses), name="s.h5")
    back = gt.stamps.copy()
    back[[10, 11]] = back[[11, 10]]
    with pytest.raises(DataError, match="s.h5, pose row 11: stamp .* goes backwards"):
        evaluate_run(Trajectory(back, gt.poses), result_from(gt.stamps, gt.poses), name="s.h5")


def test_strided_frame_range_scores_only_frames_with_gt(twist):
    gt = twist.ground_truth
    keep = np.setdiff1d(np.arange(80), np.r_[20:24])
    seq = MemorySequence("t", twist.sensor, [twist.scan(i) for i in range(80)],
                         Trajectory(gt.stamps[keep], gt.poses[keep]))
    sub = select_frames(seq, 0, None, 2)
    assert np.all(np.isin(sub.ground_truth.stamps, sub.stamps))
    _, mask = gt_for_frames(sub.ground_truth, sub.stamps)
    assert mask.sum() == 38 and not mask[10] and not mask[11]  # frames 20 and 22


def test_a_store_with_a_gt_gap_runs_every_scan_end_to_end(tmp_path):
    """Store -> `run_job` -> metrics.json: every scan registered, the gap unscored."""
    seq = constant_twist_sequence(n_frames=60, n_points=1500, noise_m=0.01)
    gt = seq.ground_truth
    keep = np.setdiff1d(np.arange(60), np.r_[25:35])
    gappy = MemorySequence("gap", seq.sensor, [seq.scan(i) for i in range(60)],
                           Trajectory(gt.stamps[keep], gt.poses[keep]))
    store = write_store(gappy, tmp_path / "gap.h5")
    assert len(StoreSequence(store)) == 60
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = run_job(Job(store=store, method="doppler", seed=None, out_root=tmp_path / "r"))
    assert out.status == "done", out.message
    run_dir = tmp_path / "r" / "gap" / "doppler"
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["frames"] == 60 and metrics["frames_scored"] == 50
    assert metrics["diverged"] is False and rel_at(metrics, 8).trans_m_mean < 0.2
    # the exported trajectories: the scored frames, row-aligned (evo / KITTI devkit), and
    # every frame's pose in est_all_tum.txt
    assert len(np.loadtxt(run_dir / "est_all_tum.txt")) == 60
    for name in ("est_tum.txt", "gt_tum.txt", "est_kitti.txt", "gt_kitti.txt"):
        assert len(np.loadtxt(run_dir / name)) == 50, name
    np.testing.assert_array_equal(np.loadtxt(run_dir / "est_tum.txt")[:, 0],
                                  np.loadtxt(run_dir / "gt_tum.txt")[:, 0])
