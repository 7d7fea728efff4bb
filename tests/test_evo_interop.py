"""The README's evo command lines reproduce a run folder's metrics.json."""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bench.runs.job import Job, run_job
from conftest import constant_twist_sequence
from loaders.store import write_store

EVO_BIN = Path(sys.executable).parent


def _evo(tool: str, args: list[str], cwd: Path, stat: str, fmt: str = "tum") -> float:
    exe = EVO_BIN / tool
    if not exe.exists():
        exe = shutil.which(tool)
    out = subprocess.run([str(exe), fmt, f"gt_{fmt}.txt", f"est_{fmt}.txt", *args], cwd=cwd,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return float(re.search(rf"^\s*{stat}\s+([-\d.e]+)", out.stdout, re.M).group(1))


def test_readme_evo_commands_match_metrics(tmp_path):
    # evo is a runtime dependency: its command-line tools come with every install
    assert (EVO_BIN / "evo_rpe").exists() or shutil.which("evo_rpe"), \
        "evo's command-line tools are missing (evo is a dependency: reinstall the package)"
    seq = constant_twist_sequence(n_frames=60, n_points=2000, noise_m=0.02, max_range_m=70)
    store = write_store(seq, tmp_path / "twist.h5")
    outcome = run_job(Job(store=store, method="icp-p2p", seed=True, out_root=tmp_path))
    run = outcome.run_dir
    m = json.loads((run / "metrics.json").read_text())
    rpe = ["-d", "8", "-u", "m", "-t", "0.2", "--all_pairs", "--pairs_from_reference"]
    rel = next(r for r in m["relative_error"] if r["length_m"] == 8.0)
    assert _evo("evo_rpe", ["-r", "trans_part", *rpe], run, "mean") == \
        pytest.approx(rel["trans_m_mean"], rel=1e-5)
    assert _evo("evo_rpe", ["-r", "angle_deg", *rpe], run, "mean") == \
        pytest.approx(rel["rot_deg_mean"], rel=1e-5)
    assert _evo("evo_ape", ["-a"], run, "rmse") == \
        pytest.approx(m["ape"]["trans_rmse_m"], rel=1e-5)
    assert _evo("evo_ape", ["-a", "-r", "angle_deg"], run, "rmse") == \
        pytest.approx(m["ape"]["rot_rmse_deg"], rel=1e-5)
    # the KITTI files are row-aligned: evo pairs them row by row and gets the same APE
    assert _evo("evo_ape", ["-a"], run, "rmse", fmt="kitti") == \
        pytest.approx(m["ape"]["trans_rmse_m"], rel=1e-5)


def _devkit_drift(gt, est, lengths, step=10):
    """KITTI devkit's calcSequenceErrors as its loops (evaluate_odometry.cpp), in double."""
    import math

    import numpy as np

    dist = [0.0]
    for i in range(1, len(gt)):
        dist.append(dist[-1] + float(np.linalg.norm(gt[i, :3, 3] - gt[i - 1, :3, 3])))
    t_err, r_err = [], []
    for first in range(0, len(gt), step):
        for length in lengths:
            last = next((i for i in range(first, len(gt)) if dist[i] > dist[first] + length), -1)
            if last < 0:
                continue
            e = np.linalg.inv(np.linalg.inv(est[first]) @ est[last]) @ \
                (np.linalg.inv(gt[first]) @ gt[last])
            d = 0.5 * (e[0, 0] + e[1, 1] + e[2, 2] - 1.0)
            r_err.append(math.acos(max(min(d, 1.0), -1.0)) / length)
            t_err.append(float(np.linalg.norm(e[:3, 3])) / length)
    return 100 * np.mean(t_err), 100 * np.degrees(np.mean(r_err))


@pytest.mark.parametrize("alignment", ["se3", "sim3", "origin", "none", "first-20"])
def test_evo_python_api_on_the_exported_files_gives_the_harness_numbers(tmp_path, alignment):
    """The run folder's row-aligned exports, read by evo's file_interface and scored by its
    APE / RPE with the alignment recorded in metrics.json, and by the KITTI devkit's definition
    on gt_kitti.txt / est_kitti.txt, agree with metrics.json to 1e-6 relative."""
    import numpy as np
    from evo.core import metrics as em
    from evo.tools import file_interface

    from bench.runs.result import RunResult
    from metrics import Alignment

    seq = constant_twist_sequence(n_frames=160, n_points=1500, noise_m=0.03, max_range_m=70)
    store = write_store(seq, tmp_path / "twist.h5")  # 127 m: KITTI's 100 m segments fit
    run = run_job(Job(store=store, method="icp-p2p", seed=True, out_root=tmp_path,
                      alignment=alignment, kitti_lengths_m=(50.0, 100.0))).run_dir
    res = RunResult.model_validate_json((run / "metrics.json").read_text())
    assert res.ape.requested == Alignment.parse(alignment).name == res.ape.alignment
    gt_tum = file_interface.read_tum_trajectory_file(run / "gt_tum.txt")
    est_tum = file_interface.read_tum_trajectory_file(run / "est_tum.txt")
    np.testing.assert_array_equal(gt_tum.timestamps, est_tum.timestamps)  # the same stamps
    gt_k = file_interface.read_kitti_poses_file(run / "gt_kitti.txt")
    est_k = file_interface.read_kitti_poses_file(run / "est_kitti.txt")
    assert gt_k.num_poses == est_k.num_poses == gt_tum.num_poses == res.frames_scored

    a = Alignment.parse(alignment)
    for relation, ours in ((em.PoseRelation.translation_part, res.ape.trans_rmse_m),
                           (em.PoseRelation.rotation_angle_deg, res.ape.rot_rmse_deg)):
        est = file_interface.read_tum_trajectory_file(run / "est_tum.txt")
        if a.kind in ("se3", "sim3"):
            est.align(gt_tum, correct_scale=a.kind == "sim3", n=a.first_n or -1)
        elif a.kind == "origin":
            est.align_origin(gt_tum)
        metric = em.APE(relation)
        metric.process_data((gt_tum, est))
        assert metric.get_statistic(em.StatisticsType.rmse) == pytest.approx(ours, rel=1e-6)
    for rel in res.relative_error:
        if not rel.n:
            continue
        for relation, ours in ((em.PoseRelation.translation_part, rel.trans_m_mean),
                               (em.PoseRelation.rotation_angle_deg, rel.rot_deg_mean)):
            metric = em.RPE(relation, delta=rel.length_m, delta_unit=em.Unit.meters,
                            all_pairs=True, rel_delta_tol=0.2, pairs_from_reference=True)
            metric.process_data((gt_tum, est_tum))
            assert len(metric.error) == rel.n
            assert metric.get_statistic(em.StatisticsType.mean) == pytest.approx(ours, rel=1e-6)
    t, r = _devkit_drift(np.array(gt_k.poses_se3), np.array(est_k.poses_se3), (50.0, 100.0))
    assert res.kitti.n > 0 and res.kitti.too_long == []
    assert res.kitti.trans_pct == pytest.approx(t, rel=1e-6)
    assert res.kitti.rot_deg_per_100m == pytest.approx(r, rel=1e-6)
