"""Run folders: what one run (sequence x method x seed option) leaves on disk.

    <out>/<sequence>/<method>[_seed|_noseed]/
        est_tum.txt  est_kitti.txt  gt_tum.txt  frames.csv  config.yaml  meta.json
        metrics.json   (written last: its presence means the run finished)
        failed.json    (instead of metrics.json when the run raised; retried on the next run)

Every file is written atomically (temporary file + rename). ``RunRecord`` is a finished run
read back (``read_run``, ``load_runs``).
"""

from __future__ import annotations

import csv
import io
import json
import re
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import cached_property
from pathlib import Path

import numpy as np
import yaml

from bench.runs.provenance import run_meta
from loaders.fileio import atomic_path, atomic_write_text
from loaders.posefile import read_tum, write_kitti, write_tum
from loaders.trajectory import Trajectory
from methods.base import OdometryResult

FRAME_COLUMNS = ["index", "stamp", "time_ms", "register_ms", "wall_ms", "points",
                 "correspondences", "iterations", "converged"]


RUN_RECORDS = ("metrics.json", "failed.json")


def run_dir_name(method: str, seed: bool | None, label: str | None = None) -> str:
    """``doppler`` (method without initial guess), ``icp-p2p_seed`` or ``icp-p2p_noseed``; a
    labelled variant uses its label (made file-name safe) instead of the method name."""
    base = re.sub(r"[^A-Za-z0-9._+-]+", "-", label).strip("-") if label else method
    return base if seed is None else f"{base}_{'seed' if seed else 'noseed'}"


def is_finished(run_dir: Path, key: str | None = None) -> bool:
    """The run in ``run_dir`` finished (and, given ``key``, was made from the same inputs and
    its timing is clean: no compilation inside a timed frame, ``bench.runs.timed``)."""
    if not (run_dir / "metrics.json").exists():
        return False
    if key is None:
        return True
    try:
        config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
        # a run with a compilation inside a timed frame is no clean timing: it runs again
        clean = json.loads((run_dir / "metrics.json").read_text()).get("timing_clean", True)
    except (OSError, ValueError, yaml.YAMLError):
        return False
    return config.get("run_key") == key and clean is not False


def clear_run(run_dir: Path) -> None:
    """Remove a run folder's result records before it is run again, so a failed re-run never
    leaves the old metrics behind."""
    for name in RUN_RECORDS:
        (run_dir / name).unlink(missing_ok=True)


def write_trajectory(path: Path, traj: Trajectory, fmt: str) -> None:
    with atomic_path(path) as tmp:
        write_tum(traj, tmp) if fmt == "tum" else write_kitti(traj, tmp)


def frames_csv(result: OdometryResult) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(FRAME_COLUMNS)
    # attributes, not dataclasses.asdict (which deep-copies every field: it was the largest
    # per-frame cost of writing a run)
    writer.writerows([f.index, f"{f.stamp:.9f}", f"{f.time_ms:.6f}", f"{f.register_ms:.6f}",
                      f"{f.wall_ms:.6f}", f.points, f.correspondences, f.iterations,
                      int(f.converged)] for f in result.frames)
    return buf.getvalue()


def write_run(run_dir: Path, result: OdometryResult, gt: Trajectory | None,
              config: dict, metrics: dict, warnings: list[str] | None = None) -> None:
    """Write every file of a finished run; ``metrics.json`` last."""
    run_dir.mkdir(parents=True, exist_ok=True)
    est = Trajectory(result.stamps, result.poses)
    write_trajectory(run_dir / "est_tum.txt", est, "tum")
    write_trajectory(run_dir / "est_kitti.txt", est, "kitti")
    if gt is not None:
        write_trajectory(run_dir / "gt_tum.txt", gt, "tum")
    atomic_write_text(run_dir / "frames.csv", frames_csv(result))
    atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    atomic_write_text(run_dir / "meta.json",
                      json.dumps({**run_meta(), "warnings": list(warnings or [])}, indent=2))
    (run_dir / "failed.json").unlink(missing_ok=True)
    atomic_write_text(run_dir / "metrics.json", json.dumps(metrics, indent=2))


def write_failure(run_dir: Path, config: dict | None, error: str, trace: str = "",
                  status: str = "failed") -> None:
    """Record a run that did not finish (``status``: failed, interrupted, timeout, crashed)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "metrics.json").unlink(missing_ok=True)
    if config is not None:
        atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    atomic_write_text(run_dir / "failed.json", json.dumps(
        {"status": status, "error": error, "traceback": trace,
         "date": datetime.now(UTC).isoformat(timespec="seconds")}, indent=2))


@dataclass(frozen=True)
class RunRecord:
    """A finished run read back from its folder: the one record tables, figures, compare, the
    notebook API, regress and ``bench run``'s summary read (``read_run`` / ``load_runs``)."""

    dir: Path
    metrics: dict
    config: dict

    @property
    def sequence(self) -> str:
        return self.metrics["sequence"]

    @property
    def display_name(self) -> str:
        return (self.config.get("sequence") or {}).get("display_name") or self.sequence

    @property
    def sensor_class(self) -> str:
        return (self.config.get("sequence") or {}).get("sensor_class") or "4D sensor"

    @property
    def doppler_kind(self) -> str:
        """The store's Doppler kind when the run was made (runs before it was recorded:
        radial)."""
        return (self.config.get("sequence") or {}).get("doppler_kind") or "radial"

    @property
    def method(self) -> str:
        return self.metrics["method"]

    @property
    def seed(self) -> bool | None:
        return self.metrics["seed"]

    @property
    def label(self) -> str | None:
        return self.config.get("label")

    @property
    def diverged(self) -> bool | None:
        return self.metrics.get("diverged")

    @property
    def relative_error(self) -> dict:
        """{length: {rot_deg_mean, trans_m_mean, rot_deg_median, trans_m_median, n}}."""
        return self.metrics.get("relative_error") or {}

    @property
    def ape(self) -> dict:
        return self.metrics.get("ape") or {}

    @property
    def time_ms(self) -> dict:
        """{median, mean, p95} of the total per-frame time [ms] (``methods.base``)."""
        return self.metrics.get("time_ms") or {}

    @property
    def register_ms(self) -> dict:
        """{median, mean, p95} of the registration call alone [ms]."""
        return self.metrics.get("register_ms") or {}

    @property
    def has_gt(self) -> bool:
        return (self.dir / "gt_tum.txt").exists()

    @cached_property
    def _paired(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        gt = read_tum(self.dir / "gt_tum.txt")
        est = read_tum(self.dir / "est_tum.txt")
        idx = np.searchsorted(est.stamps, gt.stamps).clip(0, len(est) - 1)
        keep = np.abs(est.stamps[idx] - gt.stamps) < 1e-6
        return gt.stamps[keep], gt.poses[keep], est.poses[idx[keep]]

    @property
    def stamps(self) -> np.ndarray:
        """Stamps [s] of the scored frames (those with ground truth)."""
        return self._paired[0]

    @property
    def gt(self) -> np.ndarray:
        """(N, 4, 4) ground truth T_world_sensor at ``stamps``."""
        return self._paired[1]

    @property
    def est(self) -> np.ndarray:
        """(N, 4, 4) estimated T_world_sensor at ``stamps``."""
        return self._paired[2]


def read_run(run_dir: Path) -> RunRecord | None:
    """The finished run in ``run_dir`` (None when it has no metrics.json)."""
    run_dir = Path(run_dir)
    metrics_path = run_dir / "metrics.json"
    if not metrics_path.exists():
        return None
    config_path = run_dir / "config.yaml"
    config = (yaml.safe_load(config_path.read_text()) or {}) if config_path.exists() else {}
    return RunRecord(run_dir, json.loads(metrics_path.read_text()), config)


def load_runs(results_dir: Path, only: set[Path] | None = None) -> list[RunRecord]:
    """Every finished run under ``results_dir`` (or only the folders in ``only``), in path
    order."""
    wanted = None if only is None else {Path(p).resolve() for p in only}
    runs = []
    for metrics_path in sorted(Path(results_dir).rglob("metrics.json")):
        if wanted is None or metrics_path.parent.resolve() in wanted:
            runs.append(read_run(metrics_path.parent))
    return runs
