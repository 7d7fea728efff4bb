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


def _evo(tool: str, args: list[str], cwd: Path, stat: str) -> float:
    exe = EVO_BIN / tool
    if not exe.exists():
        exe = shutil.which(tool)
    out = subprocess.run([str(exe), "tum", "gt_tum.txt", "est_tum.txt", *args], cwd=cwd,
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
    rel = m["relative_error"]["8"]
    assert _evo("evo_rpe", ["-r", "trans_part", *rpe], run, "mean") == \
        pytest.approx(rel["trans_m_mean"], rel=1e-5)
    assert _evo("evo_rpe", ["-r", "angle_deg", *rpe], run, "mean") == \
        pytest.approx(rel["rot_deg_mean"], rel=1e-5)
    assert _evo("evo_ape", ["-a"], run, "rmse") == \
        pytest.approx(m["ape"]["trans_rmse_m"], rel=1e-5)
    assert _evo("evo_ape", ["-a", "-r", "angle_deg"], run, "rmse") == \
        pytest.approx(m["ape"]["rot_rmse_deg"], rel=1e-5)
