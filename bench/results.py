"""Run folders: what one run (sequence x method x seed option) leaves on disk.

    <out>/<sequence>/<method>[_seed|_noseed]/
        est_tum.txt  est_kitti.txt  gt_tum.txt  frames.csv  config.yaml  meta.json
        metrics.json   (written last: its presence means the run finished)
        failed.json    (instead of metrics.json when the run raised; retried on the next run)

Every file is written atomically (temporary file + rename).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import platform
import re
import subprocess
import sys
from dataclasses import asdict
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

import yaml

from loaders.errors import DataError
from loaders.fileio import atomic_path, atomic_write_text
from loaders.scan import Trajectory
from methods.base import OdometryResult
from methods.timing import TIMING_LOCK_ENV

FRAME_COLUMNS = ["index", "stamp", "time_ms", "points", "correspondences", "iterations",
                 "converged"]
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
_PACKAGES = ["doppler-bench", "numpy", "scipy", "h5py", "rosbags", "evo", "kiss-icp",
             "small_gicp", "open3d-cpu", "numba", "pandas", "pydantic"]


RUN_RECORDS = ("metrics.json", "failed.json")
_store_hashes: dict[str, str] = {}


def run_dir_name(method: str, seed: bool | None, label: str | None = None) -> str:
    """``doppler`` (method without initial guess), ``icp-p2p_seed`` or ``icp-p2p_noseed``; a
    labelled variant uses its label (made file-name safe) instead of the method name."""
    base = re.sub(r"[^A-Za-z0-9._+-]+", "-", label).strip("-") if label else method
    return base if seed is None else f"{base}_{'seed' if seed else 'noseed'}"


def _hash_cache_file() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "doppler-bench" / "store-sha256.json"


def store_identity(path: Path) -> str:
    """SHA-256 of a store's bytes (its content identity). Cached in memory and in
    ~/.cache/doppler-bench/store-sha256.json by resolved path, size, mtime and inode (a store
    rewritten by an atomic rename has a new inode), so an unchanged store is hashed once."""
    st = Path(path).stat()
    cache_key = f"{Path(path).resolve()}|{st.st_size}|{st.st_mtime_ns}|{st.st_ino}"
    if cache_key in _store_hashes:
        return _store_hashes[cache_key]
    cache_file = _hash_cache_file()
    try:
        cached = json.loads(cache_file.read_text())
    except (OSError, ValueError):
        cached = {}
    digest = cached.get(cache_key) if isinstance(cached, dict) else None
    if not isinstance(digest, str):
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        digest = h.hexdigest()
        cached = cached if isinstance(cached, dict) else {}
        live = {k: v for k, v in cached.items() if Path(k.split("|")[0]).exists()}
        try:  # best effort: a read-only home only costs re-hashing next time
            cache_file.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(cache_file, json.dumps({**live, cache_key: digest}))
        except (OSError, DataError):
            pass
    _store_hashes[cache_key] = digest
    return digest


_ROOT = Path(__file__).resolve().parent.parent
_code_hash: list[str] = []


def code_identity() -> str:
    """SHA-256 of the code that determines a result (methods/, metrics/, the scoring in
    bench/evaluate.py): a change there re-runs every run, so no result of older code is
    shown as current."""
    if not _code_hash:
        h = hashlib.sha256()
        files = sorted([*(_ROOT / "methods").glob("*.py"), *(_ROOT / "metrics").glob("*.py"),
                        _ROOT / "bench" / "evaluate.py"])
        for path in files:
            h.update(path.name.encode())
            h.update(path.read_bytes())
        _code_hash.append(h.hexdigest()[:16])
    return _code_hash[0]


def run_key(identity: dict) -> str:
    """A short key of everything that determines a run's result (``identity``: store content,
    method, resolved parameters, seed option, evaluation settings)."""
    text = json.dumps(identity, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def is_finished(run_dir: Path, key: str | None = None) -> bool:
    """The run in ``run_dir`` finished (and, given ``key``, was made from the same inputs)."""
    if not (run_dir / "metrics.json").exists():
        return False
    if key is None:
        return True
    try:
        config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
    except (OSError, yaml.YAMLError):
        return False
    return config.get("run_key") == key


def clear_run(run_dir: Path) -> None:
    """Remove a run folder's result records before it is run again, so a failed re-run never
    leaves the old metrics behind."""
    for name in RUN_RECORDS:
        (run_dir / name).unlink(missing_ok=True)


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
        "threads": {k: os.environ.get(k) for k in THREAD_VARS},
        # what numba actually uses (read when it was imported, which may precede the pinning)
        "numba_threads": (sys.modules["numba"].config.NUMBA_NUM_THREADS
                          if "numba" in sys.modules else None),
        "timing_lock": os.environ.get(TIMING_LOCK_ENV),
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


def load_runs(results_dir: Path, only: set[Path] | None = None) -> list[dict]:
    """Every finished run under ``results_dir`` (or only the folders in ``only``):
    {"dir", "metrics", "config"}."""
    runs = []
    wanted = None if only is None else {Path(p).resolve() for p in only}
    for metrics_path in sorted(Path(results_dir).rglob("metrics.json")):
        run_dir = metrics_path.parent
        if wanted is not None and run_dir.resolve() not in wanted:
            continue
        config_path = run_dir / "config.yaml"
        config = yaml.safe_load(config_path.read_text()) if config_path.exists() else {}
        runs.append({"dir": run_dir, "metrics": json.loads(metrics_path.read_text()),
                     "config": config})
    return runs
