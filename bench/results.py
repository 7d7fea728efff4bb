"""Run folders: what one run (sequence x method x seed option) leaves on disk.

    <out>/<sequence>/<method>[_seed|_noseed]/
        est_tum.txt  est_kitti.txt  gt_tum.txt  frames.csv  config.yaml  meta.json
        metrics.json   (written last: its presence means the run finished)
        failed.json    (instead of metrics.json when the run raised; retried on the next run)

Every file is written atomically (temporary file + rename).
"""

from __future__ import annotations

import csv
import io
import json
import os
import platform
import subprocess
from dataclasses import asdict
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

import yaml

from loaders.fileio import atomic_path, atomic_write_text
from loaders.scan import Trajectory
from methods.base import OdometryResult

FRAME_COLUMNS = ["index", "stamp", "time_ms", "points", "correspondences", "iterations",
                 "converged"]
_PACKAGES = ["doppler-bench", "numpy", "scipy", "h5py", "rosbags", "evo", "kiss-icp",
             "small_gicp", "pandas", "pydantic"]


def run_dir_name(method: str, seed: bool | None) -> str:
    """``doppler`` (method without initial guess), ``icp-p2p_seed`` or ``icp-p2p_noseed``."""
    return method if seed is None else f"{method}_{'seed' if seed else 'noseed'}"


def is_finished(run_dir: Path) -> bool:
    return (run_dir / "metrics.json").exists()


def _git_state() -> dict:
    root = Path(__file__).resolve().parent.parent
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True,
                              timeout=10).stdout.strip()
    try:
        return {"commit": git("rev-parse", "HEAD") or None,
                "dirty": bool(git("status", "--porcelain", "--untracked-files=no"))}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def run_meta() -> dict:
    """Provenance of a run: git commit and dirty flag, package versions, CPU, threads, date."""
    versions = {}
    for name in _PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {
        "git": _git_state(),
        "python": platform.python_version(),
        "packages": versions,
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "threads": {k: os.environ.get(k) for k in
                    ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
        "host": platform.node(),
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
    }


def write_trajectory(path: Path, traj: Trajectory, fmt: str) -> None:
    with atomic_path(path) as tmp:
        traj.write_tum(tmp) if fmt == "tum" else traj.write_kitti(tmp)


def frames_csv(result: OdometryResult) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(FRAME_COLUMNS)
    for f in result.frames:
        row = asdict(f)
        writer.writerow([row["index"], f"{row['stamp']:.9f}", f"{row['time_ms']:.6f}",
                         row["points"], row["correspondences"], row["iterations"],
                         int(row["converged"])])
    return buf.getvalue()


def write_run(run_dir: Path, result: OdometryResult, gt: Trajectory | None,
              config: dict, metrics: dict) -> None:
    """Write every file of a finished run; ``metrics.json`` last."""
    run_dir.mkdir(parents=True, exist_ok=True)
    est = Trajectory(result.stamps, result.poses)
    write_trajectory(run_dir / "est_tum.txt", est, "tum")
    write_trajectory(run_dir / "est_kitti.txt", est, "kitti")
    if gt is not None:
        write_trajectory(run_dir / "gt_tum.txt", gt, "tum")
    atomic_write_text(run_dir / "frames.csv", frames_csv(result))
    atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    atomic_write_text(run_dir / "meta.json", json.dumps(run_meta(), indent=2))
    (run_dir / "failed.json").unlink(missing_ok=True)
    atomic_write_text(run_dir / "metrics.json", json.dumps(metrics, indent=2))


def write_failure(run_dir: Path, config: dict, error: str, trace: str) -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    atomic_write_text(run_dir / "failed.json", json.dumps(
        {"error": error, "traceback": trace,
         "date": datetime.now(UTC).isoformat(timespec="seconds")}, indent=2))


def load_runs(results_dir: Path) -> list[dict]:
    """Every finished run under ``results_dir``: {"dir", "metrics", "config"}."""
    runs = []
    for metrics_path in sorted(Path(results_dir).rglob("metrics.json")):
        run_dir = metrics_path.parent
        config_path = run_dir / "config.yaml"
        config = yaml.safe_load(config_path.read_text()) if config_path.exists() else {}
        runs.append({"dir": run_dir, "metrics": json.loads(metrics_path.read_text()),
                     "config": config})
    return runs
